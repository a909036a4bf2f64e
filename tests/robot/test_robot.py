"""The PAM robot: design files, robot URDF (mirrored left side), PAM forces and the comparison."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

from pamkin.robot import festo
from pamkin.cli import main
from pamkin.audit.compare import compare_design, torque_match
from pamkin.robot.design import THESIS_DESIGN, load_design, save_design
from pamkin.errors import DataFileError
from pamkin.robot.biped import robot_skeleton, thesis_robot
from pamkin.human.urdf import ROBOT_URDF
from locations import ROOT



@pytest.fixture(scope="module")
def robot():
    return thesis_robot()


def test_robot_urdf_kinematics_equal_gait2392(gait2392):
    import pinocchio as pin
    import yourdfpy

    skel = robot_skeleton()
    q = gait2392.random_q(50, seed=41)
    a, b = gait2392.forward(q), skel.forward(q)
    assert np.abs(a.body_p - b.body_p).max() < 1e-15      # mirrored left leg == Gait2392's left leg
    _, p = skel.kinematics.pinocchio_placements(q)
    assert np.abs(p - a.body_p).max() < 1e-12
    model = pin.buildModelFromUrdf(str(ROBOT_URDF))
    hip_flex = model.getJointId("hip_r_rotation1")
    idx = model.joints[hip_flex].idx_q
    assert np.degrees(model.lowerPositionLimit[idx]) == pytest.approx(-15)
    assert np.degrees(model.upperPositionLimit[idx]) == pytest.approx(110)
    assert yourdfpy.URDF.load(str(ROBOT_URDF), load_meshes=False).base_link == "ground"


def test_pam_frames_in_urdf_are_the_design_points(robot):
    import pinocchio as pin

    skel = robot.model
    q = skel.random_q(1, seed=42)
    v, _ = skel.kinematics.joint_values(q)
    data = skel.pin_model.createData()
    pin.framesForwardKinematics(skel.pin_model, data, v[0])
    X, _ = robot.paths.point_positions(skel.forward(q))
    for key in ("pam04_r", "pam04_l", "pam25_l", "pam20_r"):
        k = robot.names.index(key)
        side = key[-1]
        fid = skel.pin_model.getFrameId(f"{key[:5]}_{side}_point1")
        assert np.allclose(data.oMf[fid].translation, X[0, robot.paths._path_start[k]], atol=1e-14)


def test_left_side_mirrors_right(robot):
    skel = robot.model
    q = skel.random_q(20, seed=43)
    qm = q.copy()
    for i, c in enumerate(skel.coordinates):   # give the left leg the right leg's angles
        if c.endswith("_l"):
            qm[:, i] = q[:, skel.coordinates.index(c[:-2] + "_r")]
    for c in ("pelvis_list", "pelvis_rotation", "lumbar_bending", "lumbar_rotation"):
        qm[:, skel.coordinates.index(c)] = 0.0
    st = robot.evaluate(qm)
    n = len(robot.design.pams)
    assert np.allclose(st.lengths[:, :n], st.lengths[:, n:], atol=1e-12)
    knee_r, knee_l = skel.coordinates.index("knee_angle_r"), skel.coordinates.index("knee_angle_l")
    assert np.allclose(st.moment_arms[:, :n, knee_r], st.moment_arms[:, n:, knee_l], atol=1e-12)


def test_pam_force_and_strain_by_hand(robot):
    q = robot.model.default_q
    st = robot.evaluate(q)
    k = robot.names.index("pam12_r")  # soleus, 40 mm
    p = robot.design.pam(12)
    L = st.lengths[0, k]
    pam_len = L - 2 * 0.0125 - p.tendon_length_m
    eps = (p.resting_length_m - pam_len) / p.resting_length_m
    assert st.strain[0, k] == pytest.approx(eps, abs=1e-15)
    F = festo.force(eps, p.resting_length_m, 620e3, 40, model="v3")
    assert st.forces[0, k] == pytest.approx(float(F), rel=1e-14)
    ankle = robot.coordinates.index("ankle_angle_r")
    assert st.torques[0, k, ankle] == pytest.approx(float(F) * st.moment_arms[0, k, ankle], rel=1e-14)
    assert st.torques[0, k, ankle] < 0     # plantarflexor


def test_torque_match_metrics_by_hand():
    human = np.array([1.0, 2.0, -1.0, 0.0])
    robot = np.array([1.0, 1.0, 1.0, 0.0])
    m = torque_match(human, robot, np.array([True, True, False, True]), "c", "1-D")
    assert m.nrmse == pytest.approx(np.sqrt((0 + 1 + 4 + 0) / 4) / 2)
    assert m.peak_ratio == pytest.approx(0.5)
    assert m.sign_agreement == pytest.approx(2 / 3)   # the zero sample is below 1 % of the peak
    assert m.dead_zone_fraction == pytest.approx(0.25)


def test_thesis_baseline_reproduces_the_labs_findings(robot, gait2392):
    """The lab measured (in OpenSim) 3 PAMs pushing the wrong way at the knee and 7 that cannot fit."""
    rows = compare_design(robot, gait2392, "r", n=21, n2=7)
    wrong_knee = sorted(r.id for r in rows if r.primary.coordinate == "knee_angle_r"
                        and r.primary.sign_agreement < 0.5)
    assert wrong_knee == [5, 6, 9]            # semimembranosus, sartorius, gracilis
    assert sorted(r.id for r in rows if not r.buildable) == [2, 3, 4, 6, 8, 11, 24]


# ----------------------------------------------------------------------------- bad input
def _design_dict():
    return yaml.safe_load(THESIS_DESIGN.read_text())


@pytest.mark.parametrize("change,match", [
    (lambda d: d["pams"][3].update(diameter_mm=25), r"id 4.*diameter_mm 25"),
    (lambda d: d["pams"][0].update(resting_length_m=-0.2), r"id 1.*resting_length_m must be a positive"),
    (lambda d: d["pams"][1]["points"][0].update(body="humerus_r"), r"id 2.*unknown body 'humerus_r'"),
    (lambda d: d["pams"][2].pop("tendon_length_m"), r"id 3.*missing field\(s\) \['tendon_length_m'\]"),
    (lambda d: d["pams"][5].update(primary_coordinate="elbow_r"), r"id 6.*unknown coordinate"),
])
def test_bad_design_files(tmp_path, change, match):
    d = _design_dict()
    change(d)
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(d))
    skel = robot_skeleton()
    with pytest.raises(DataFileError, match=f"bad.yaml: .*{match}"):
        load_design(f, bodies=skel.bodies, coordinates=skel.coordinates)


def test_malformed_yaml(tmp_path):
    f = tmp_path / "broken.yaml"
    f.write_text("pams: [ {id: 1, name: x\n")
    with pytest.raises(DataFileError, match="broken.yaml: not valid YAML"):
        load_design(f)


def test_save_is_atomic(tmp_path, monkeypatch):
    design = load_design()
    target = tmp_path / "design.yaml"
    save_design(design, target)
    before = target.read_text()
    import pamkin.human.urdf as ub

    def boom(*a, **k):
        raise OSError("disk full")
    monkeypatch.setattr(ub.os, "replace", boom)
    with pytest.raises(OSError):
        save_design(design.replace_pam(design.pams[0]), target)
    assert target.read_text() == before
    assert list(tmp_path.iterdir()) == [target]    # no temporary file left behind


def test_size_and_compare_cli_json(capsys):
    assert main(["size", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["pams"]) == 27
    assert sorted(r["id"] for r in out["pams"] if not r["feasible"]) == [2, 3, 4, 6, 8, 11, 24]
    assert main(["size", "--method", "constrained", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for r in out["pams"]:
        if r["feasible"]:
            assert r["tendon_length_m"] >= 0
    assert main(["compare", "--json", "-n", "11"]) == 0

    def not_strict(name):
        raise AssertionError(f"{name} in the JSON output")

    out = json.loads(capsys.readouterr().out, parse_constant=not_strict)     # strict JSON: no NaN / Infinity
    assert out["summary"]["n"] == 27 and "uni_hip_r" in out["groups"] and "knee_angle_r" in out["joints"]


def test_compare_summary_counts_an_undefined_error_as_failing():
    """A PAM whose human muscles give no torque about its primary coordinate (NRMSE nan) counts as infinite in
    the median — as in the audit — instead of dropping out of it, and is named; strict JSON keeps it as null."""
    from types import SimpleNamespace

    from pamkin.audit.compare import finite_or_none, summary_line

    rows = [SimpleNamespace(id=i, buildable=True,
                            primary=SimpleNamespace(nrmse=e, sign_agreement=1.0, dead_zone_fraction=0.0))
            for i, e in ((1, 0.1), (2, 0.3), (3, float("nan")))]
    s = summary_line(rows)
    assert s["median_nrmse"] == 0.3          # of [0.1, 0.3, inf]; dropping the nan gave 0.2
    assert s["within_0.25"] == 1 and s["undefined_nrmse"] == [3]
    assert summary_line(rows[:2])["median_nrmse"] == pytest.approx(0.2) and summary_line(rows[:2])["undefined_nrmse"] == []
    assert json.loads(json.dumps(finite_or_none({"a": np.inf, "b": [np.nan, 1.0], "c": (2,)}), allow_nan=False)) == \
        {"a": None, "b": [None, 1.0], "c": [2]}


def test_cli_bad_design_file(tmp_path, capsys):
    f = tmp_path / "d.yaml"
    f.write_text("name: x\n")
    assert main(["compare", "--design", str(f)]) == 2
    assert "d.yaml: not a design file" in capsys.readouterr().err


@pytest.mark.needs_shared
def test_builtin_design_is_not_stale():
    if not (ROOT.parent / "shared" / "bipedal-robot").exists():
        pytest.skip("../shared/bipedal-robot not found")
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "import_thesis_design.py"), "--check"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_mirror_point_keeps_conditions():
    from pamkin.robot.design import mirror_point
    from pamkin.opensim.model_file import ConditionalPathPoint

    p = ConditionalPathPoint("c", "tibia_r", (0.01, -0.02, 0.03), coordinate="knee_angle_r", range=(-1.0, 0.1))
    m = mirror_point(p)
    assert isinstance(m, ConditionalPathPoint)
    assert (m.body, m.location, m.coordinate, m.range) == ("tibia_l", (0.01, -0.02, -0.03), "knee_angle_l", (-1.0, 0.1))


@pytest.mark.needs_shared
def test_bone_capsules_are_not_stale():
    if not (ROOT.parent / "shared" / "opensim-models" / "Geometry").exists():
        pytest.skip("../shared/opensim-models/Geometry not found")
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "fit_bone_capsules.py"), "--check"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_examples_run():
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / "library_use.py")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "semimembranosus PAM strain range" in proc.stdout
    from pamkin.optimize.config import load_config

    assert load_config(ROOT / "examples" / "knee_pams.toml").actuators == [4, 5, 6, 9, 10, 11]
