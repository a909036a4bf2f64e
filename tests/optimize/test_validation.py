"""optimize.validation: the run's held-out error equals the audit's per-PAM numbers on the same poses, and
its poses are like the audit's but never the audit's."""

from __future__ import annotations

import numpy as np
import pytest

import pamkin
from pamkin.audit.measure import AuditOptions, audit_design
from pamkin.robot.design import load_design
from pamkin.optimize.validation import N_VALIDATION, validation_error, validation_poses
from pamkin.human.rom import load_rom


def test_validation_error_is_the_audits_nrmse_and_worst_error():
    human = pamkin.gait2392()
    des = load_design("v2_seed")
    res = audit_design(des, options=AuditOptions(n_random=80, gait_ik=None, gait_plan=False, n_geometry=5,
                                                 n_sweep=5, n_grid=3, segment_step_m=0.1))
    q = res.details["q_rand"]
    T = human.torques(q)
    for k in (0, 3, 8, 23):
        row = res.pams[k]
        nrmse, worst = validation_error(des.pams[k], human, q, T, row["coordinates_crossed"], des)
        assert nrmse == pytest.approx(row["random_nrmse"], rel=1e-9)
        assert worst == pytest.approx(row["random_worst_coordinate_error"], rel=1e-9)


def test_validation_poses_like_the_audits_not_the_audits():
    from pamkin.audit.measure import random_poses

    human = pamkin.gait2392()
    rom = load_rom("robot_thesis", "r")
    q = validation_poses(human, rom)
    assert q.shape == (N_VALIDATION, len(human.coordinates))
    audit = random_poses(human, rom, N_VALIDATION)
    varied = lambda x: {c for i, c in enumerate(human.coordinates) if np.ptp(x[:, i]) > 0}  # noqa: E731
    assert varied(q) == varied(audit)
    assert not np.isclose(q[:, None, :], audit[None, :, :]).all(axis=2).any()    # no audit pose among them
    np.testing.assert_array_equal(q, validation_poses(human, rom))                # reproducible


def test_validation_error_uses_the_designs_pressure():
    """At 400 kPa (the run's pressure, carried by its seed design) the error is the audit's of that design,
    not the 620 kPa one."""
    import dataclasses

    human = pamkin.gait2392()
    des = dataclasses.replace(load_design("v2_seed"), pressure_Pa=400e3)
    res = audit_design(des, options=AuditOptions(n_random=60, gait_ik=None, gait_plan=False, n_geometry=5,
                                                 n_sweep=5, n_grid=3, segment_step_m=0.1))
    q = res.details["q_rand"]
    T = human.torques(q)
    row = res.pams[11]
    got = validation_error(des.pams[11], human, q, T, row["coordinates_crossed"], des)
    assert got[0] == pytest.approx(row["random_nrmse"], rel=1e-9)
    assert got[0] != pytest.approx(validation_error(des.pams[11], human, q, T, row["coordinates_crossed"])[0], rel=1e-3)


def test_an_undefined_validation_error_is_the_worst():
    """No human torque about the primary coordinate (psoas about lumbar extension: Gait2392's psoas_r starts
    on the pelvis): both errors count as infinite, as in the audit, instead of nan (which no comparison
    would ever rank)."""
    import dataclasses

    human = pamkin.gait2392()
    des = load_design("v2_seed")
    pam = dataclasses.replace(des.pam(27), primary_coordinate="lumbar_extension")
    q = validation_poses(human, load_rom(des.rom, "r"), n=20)
    got = validation_error(pam, human, q, human.torques(q), ["hip_flexion_r", "lumbar_extension"], des)
    assert got == (np.inf, np.inf)
    ok = validation_error(des.pam(27), human, q, human.torques(q), ["hip_flexion_r"], des)
    assert all(np.isfinite(ok))


def test_the_runs_check_counts_an_undefined_nrmse_as_the_worst(tmp_path):
    """optimize.verify.summarize (the run's independent numpy check, summary.json's "check"): a PAM whose human
    muscles have no torque about its primary coordinate (psoas about lumbar extension) has an undefined 1-D
    NRMSE; it is named, counts as infinite in the median (not nan, not dropped), and summary.json stays strict
    JSON (``null``)."""
    import dataclasses
    import json
    from types import SimpleNamespace

    from pamkin.audit.compare import finite_or_none
    from pamkin.optimize.verify import summarize
    from pamkin.optimize.config import load_config
    from pamkin.optimize.pipeline import _write_summary

    des = load_design("v2_seed")
    odd = dataclasses.replace(des.pam(27), primary_coordinate="lumbar_extension", secondary_coordinates=())
    new = dataclasses.replace(des, pams=(des.pam(26), odd, des.pam(10)))
    results = [SimpleNamespace(id=p.id, name=p.name, sample_q={}, torque_samples={}, nrmse_samples={},
                               status="Solve_Succeeded", success=True, seconds=0.0) for p in new.pams]
    s = summarize(new, new, results, load_config(None))
    rows = {r["id"]: r for r in s["actuators"]}
    assert np.isnan(rows[27]["nrmse_after"]) and s["undefined_nrmse"] == [27]
    finite = sorted(rows[i]["nrmse_after"] for i in (26, 10))
    assert all(np.isfinite(finite))
    assert s["median_nrmse_after"] == pytest.approx(finite[1])          # the middle of (a, b, inf)
    _write_summary(tmp_path, {"check": s})
    back = json.loads((tmp_path / "summary.json").read_text(),
                      parse_constant=lambda c: pytest.fail(f"non-standard JSON constant {c}"))
    assert back["check"]["actuators"][1]["nrmse_after"] is None and back == finite_or_none({"check": s})
