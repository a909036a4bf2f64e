"""A PAM with a 2:1 or 3:1 pulley block (``transmission: 2`` or ``3``): the design file, the robot's lengths and forces
against virtual work and finite differences, the optimiser (a known optimum, CasADi = numpy, the
one-segment stage's reach), the limit check, walking plans, OpenSim export, the audit and the config."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

import pamkin
from pamkin.robot import festo
from pamkin.robot.design import Design, Pam, design_from_dict, load_design, pam_unit_mass, save_design
from pamkin.errors import DataFileError
from pamkin.optimize.config import FAST_FIT, RunConfig, load_config
from pamkin.optimize.limit_check import limit_excess
from pamkin.optimize.problem import ActuatorProblem
from pamkin.optimize.samples import actuator_data
from pamkin.opensim.model_file import PathPoint
from pamkin.robot.biped import PamRobot
from pamkin.human.rom import RangeOfMotion
from locations import DATA, EXAMPLES

FIT = 0.0125


@pytest.fixture(scope="module")
def toy():
    """two_body.osim (one pin joint "angle"; "arm" hangs 0.3 m below "base"'s origin) and a three-point
    route: o and v on "base" (a 0.15 m body-fixed segment), i on "arm" 50 mm below the joint."""
    model = pamkin.load_osim(DATA / "two_body.osim")
    route = (PathPoint("o", "base", (0.03, -0.12, 0.0)), PathPoint("v", "base", (0.03, -0.27, 0.0)),
             PathPoint("i", "arm", (0.03, -0.05, 0.0)))
    return model, route


def _robot(model, pam: Pam) -> PamRobot:
    return PamRobot(Design("t", (pam,)), model, sides=("r",))


def test_pam_length_and_tendon_are_inverse():
    from pamkin.robot.design import pam_length, tendon_for

    L = np.linspace(0.3, 0.9, 7)
    for k in (1, 2, 3):
        t = tendon_for(L, 0.2, k, FIT)
        np.testing.assert_allclose(pam_length(L, t, k, FIT), 0.2, atol=1e-15)
        np.testing.assert_allclose(k * (pam_length(L, 0.05, k, FIT) + 2 * FIT) + 0.05, L, atol=1e-15)
    assert pam_length(0.5, 0.1, 1, FIT) == 0.5 - 2 * FIT - 0.1         # the k = 1 form, to the bit


def test_design_file_round_trip_and_bad_values(tmp_path):
    des = load_design("thesis")
    p4 = dataclasses.replace(des.pam(4), transmission=2)
    out = save_design(des.replace_pam(p4), tmp_path / "d.yaml")
    again = load_design(out)
    assert again.pam(4).transmission == 2 and again.pam(5).transmission == 1
    d = again.to_dict()
    assert d["pams"][3]["transmission"] == 2 and "transmission" not in d["pams"][4]   # 1 is not written
    d["pams"][3]["transmission"] = 3
    assert design_from_dict(d, "three.yaml").pam(4).transmission == 3
    for bad in (4, 0, "2", 1.5, True):
        d["pams"][3]["transmission"] = bad
        with pytest.raises(DataFileError, match=r"id 4.*transmission must be one of \(1, 2, 3\)"):
            design_from_dict(d, "bad.yaml")


@pytest.mark.parametrize("k", [2, 3])
def test_block_lengths_forces_by_virtual_work_and_finite_differences(toy, k):
    """With a k:1 block the PAM's length is (L − tendon)/k − 2 fittings; the route's tension is n F / k, which
    is what virtual work gives (tension · dL = n F · dl_pam); torques are −tension · dL/dq by central
    differences; the moment arms do not depend on k."""
    model, route = toy
    q, _ = model.grid(["angle"], 41, rom=RangeOfMotion({"angle": (-1.2, 1.2)}))
    direct = _robot(model, Pam(1, "d", (), "angle", (), 20, 2, 0.25, 0.05, route))
    block = _robot(model, Pam(1, "b", (), "angle", (), 20, 2, 0.25, 0.05, route, transmission=k))
    s1, s2 = direct.evaluate(q), block.evaluate(q)
    L = s1.lengths[:, 0]
    np.testing.assert_array_equal(s2.lengths, s1.lengths)
    np.testing.assert_allclose(s2.moment_arms, s1.moment_arms, atol=0)
    np.testing.assert_allclose(s2.pam_lengths[:, 0], (L - 0.05) / k - 2 * FIT, atol=1e-15)
    np.testing.assert_allclose(s2.strain[:, 0], (0.25 - s2.pam_lengths[:, 0]) / 0.25, atol=1e-15)
    F = festo.force(s2.strain[:, 0], 0.25, 620e3, 20)
    np.testing.assert_allclose(s2.unit_forces[:, 0], F, rtol=1e-13)
    np.testing.assert_allclose(s2.forces[:, 0], 2 * F / k, rtol=1e-13)
    np.testing.assert_allclose(s1.unit_forces[:, 0] * 2, s1.forces[:, 0], rtol=1e-13)   # k = 1: n F
    # virtual work and the torque, by central differences of the route and PAM lengths
    h = 1e-6
    sp, sm = block.evaluate(q + h), block.evaluate(q - h)
    dL = (sp.lengths[:, 0] - sm.lengths[:, 0]) / (2 * h)
    dl = (sp.pam_lengths[:, 0] - sm.pam_lengths[:, 0]) / (2 * h)
    np.testing.assert_allclose(s2.forces[:, 0] * dL, 2 * s2.unit_forces[:, 0] * dl, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(s2.torques[:, 0, 0], -s2.forces[:, 0] * dL, rtol=1e-6, atol=1e-6)
    # the block's mass is added to the PAM's (an assumption, festo.transmission_mass)
    p = block.pams[0]
    assert pam_unit_mass(p) == pytest.approx(float(festo.pam_mass(0.25, 20) + festo.transmission_mass(0.25, 20, k)))
    assert pam_unit_mass(direct.pams[0]) == pytest.approx(float(festo.pam_mass(0.25, 20)))
    # the assumed block mass: k − 1 pulleys and a frame along the PAM (festo_models.json)
    assert float(festo.transmission_mass(0.25, 20, k)) == pytest.approx((k - 1) * 0.12 + 0.30 * 0.25)
    assert float(festo.transmission_mass(0.25, 20, 1)) == 0.0


def test_walking_forces_and_export_follow_the_block(toy):
    from pamkin.gait.plan import _pam_forces, force_coefficients
    from pamkin.robot.osim_export import pam_optimal_force

    model, route = toy
    q, _ = model.grid(["angle"], 11, rom=RangeOfMotion({"angle": (-1.0, 1.0)}))
    direct = _robot(model, Pam(1, "d", (), "angle", (), 20, 1, 0.25, 0.05, route))
    block = _robot(model, Pam(1, "b", (), "angle", (), 20, 1, 0.25, 0.05, route, transmission=2))
    eps = block.evaluate(q).strain
    np.testing.assert_allclose(_pam_forces(block, eps, 4e5), _pam_forces(direct, eps, 4e5) / 2, rtol=1e-14)
    np.testing.assert_allclose(_pam_forces(block, eps, 620e3), block.evaluate(q).forces, rtol=1e-12)
    a1, b1 = force_coefficients(direct, eps)[:2]
    a2, b2 = force_coefficients(block, eps)[:2]
    np.testing.assert_allclose(a2, a1 / 2, rtol=1e-12)
    np.testing.assert_allclose(b2, b1 / 2, rtol=1e-12)
    assert pam_optimal_force(block.pams[0]) == pytest.approx(pam_optimal_force(direct.pams[0]) / 2)


def _fit(model, route, k: int, rom, cfg, target):
    seed = Pam(1, "toy", (), "angle", (), 10, 1, 0.12, 0.0, route, transmission=k)
    data = actuator_data(seed, model, rom, cfg, FIT, target=target)
    pts = [np.array(p.location) for p in seed.points]
    prob = ActuatorProblem(data, cfg, 10, pts, [np.array(cfg.region(1, p.name)) for p in seed.points])
    return seed, prob, prob.solve(prob.initial_guess(pts, None, None), 1)


def test_optimiser_recovers_a_block_pam_and_agrees_with_the_numpy_pipeline(toy):
    """The target is a 2:1-block PAM's own torque: the optimiser (lengths free) recovers it, and its CasADi
    strains and torques equal pamkin.robot.biped's on the saved PAM."""
    from pamkin.optimize.results import solution_pam

    model, route = toy
    route = (PathPoint("o", "base", (0.03, 0.10, 0.0)), *route[1:])     # a 0.37 m body-fixed segment
    rom = RangeOfMotion({"angle": (-0.8, 0.8)})
    q, _ = model.grid(["angle"], 61, rom=rom)
    L = _robot(model, Pam(1, "t", (), "angle", (), 10, 1, 0.1, 0.0, route)).evaluate(q).lengths[:, 0]
    rest = 0.2
    truth = Pam(1, "truth", (), "angle", (), 10, 1, rest, L.max() - 2 * (rest + 2 * FIT), route, transmission=2)
    truth_robot = _robot(model, truth)
    assert truth.tendon_length_m > 0 and truth_robot.evaluate(q).strain.max() < 0.12      # within kmax

    def target(qq):
        return truth_robot.evaluate(qq).torques[:, 0, :]

    cfg = RunConfig().replace({**FAST_FIT, "weights.regularization": 0.0, "limits.bone_clearance": False, "samples.primary": 31, "limits.min_point_distance_m": 0.0, "regions": {"1": [0.0, 0.0, 0.0]}})
    seed, prob, sol = _fit(model, route, 2, rom, cfg, target)
    assert sol.success, sol.status
    assert sol.rest_length == pytest.approx(rest, abs=1e-4)
    assert sol.tendon_length == pytest.approx(truth.tendon_length_m, abs=2e-4)
    fitted = _robot(model, solution_pam(seed, prob.finalize(sol)))
    assert fitted.pams[0].transmission == 2
    for c, rows, _, _, label in prob.data.objective:
        tn = fitted.evaluate(prob.data.q[rows]).torques[:, 0, 0]
        np.testing.assert_allclose(sol.torque_samples[label], tn, atol=1e-9)
    np.testing.assert_allclose(fitted.evaluate(q).torques[:, 0, 0], truth_robot.evaluate(q).torques[:, 0, 0],
                               atol=1e-3 * np.abs(target(q)[:, 0]).max())
    # the held-out limit check measures the same strains as pamkin.robot.biped
    over = dataclasses.replace(fitted.pams[0], resting_length_m=1.3 * fitted.pams[0].resting_length_m)
    excess = limit_excess(over, model, q, cfg, FIT)
    eps = _robot(model, over).evaluate(q).strain[:, 0]
    kmax = float(festo.kmax(over.resting_length_m, 10))
    name = next(k for k in excess if "kmax" in k)
    assert excess[name] == pytest.approx(eps.max() - (cfg.limits.kmax_scale * kmax - 0.005), abs=1e-12)


def test_block_puts_an_out_of_reach_pam_on_one_segment(toy):
    """The toy's excursion needs a resting length beyond what its 0.15 m body-fixed segment holds (a 0.128 m one
    before it, on the same body, makes the route long enough for a block): the
    one-segment stage names it out of reach with a direct PAM; with the 2:1 block (half the stroke) it is
    mounted, and pamkin.robot.biped on 201 poses confirms the body on that segment and the strain limits."""
    from pamkin.optimize.mount import mount_stage, reach_bound
    from pamkin.optimize.results import solution_pam

    model, route = toy
    route = (PathPoint("a", "base", (0.13, -0.20, 0.0)), *route)   # 0.128 m more, on the same body
    rom = RangeOfMotion({"angle": (-0.6, 0.6)})
    direct = _robot(model, Pam(1, "t", (), "angle", (), 10, 1, 0.1, 0.0, route))

    def target(q):
        return 0.5 * direct.evaluate(q).torques[:, 0, :]

    cfg = RunConfig().replace({**FAST_FIT, "limits.rated_force": True, "mount.cost": 10.0, "weights.regularization": 0.0, "limits.bone_clearance": False, "samples.primary": 31, "limits.min_point_distance_m": 0.0, "regions": {"1": [0.0, 0.0, 0.0]}})
    L = direct.evaluate(model.grid(["angle"], 201, rom=rom)[0]).lengths[:, 0]
    need1, most = reach_bound(L, 0.15, 10, cfg, FIT, 1)
    need2, _ = reach_bound(L, 0.15, 10, cfg, FIT, 2)
    assert need2 == pytest.approx(need1 / 2) and need2 < most < need1
    seed1, prob1, sol1 = _fit(model, route, 1, rom, cfg, target)
    assert sol1.success
    _, info1 = mount_stage(prob1, sol1, seed1, cfg, model, rom, solution_pam)
    assert info1["reason"] == "out of reach", info1
    seed2, prob2, sol2 = _fit(model, route, 2, rom, cfg, target)
    assert sol2.success
    mounted, info2 = mount_stage(prob2, sol2, seed2, cfg, model, rom, solution_pam)
    assert info2["mounted"] and info2["segment"] == "o->v", info2
    pam = solution_pam(seed2, prob2.finalize(mounted))
    q, _ = model.grid(["angle"], 201, rom=rom)
    ev = _robot(model, pam).evaluate(q)
    room = 0.15 - np.maximum(pam.resting_length_m, ev.pam_lengths[:, 0]) - 2 * FIT
    assert room.min() >= -1e-6
    eps = ev.strain[:, 0]
    assert eps.max() <= min(festo.kmax(pam.resting_length_m, 10), festo.max_contraction(10)) + 1e-6
    assert eps.min() >= -festo.max_pretension(10) - 1e-6
    assert ev.unit_forces.max() <= festo.F_MAX_THEORETICAL[10] + 1e-6


@pytest.mark.parametrize("k0,k", [(1, 2), (1, 3), (2, 3)])
def test_block_start_keeps_the_pam_strain(toy, k0, k):
    """optimize.actuator.block_start: a k0:1 solution's decision vector as the start of a k:1 problem — the same
    route, resting length l0·k0/k, tendon t + 2·fitting·(k0 − k) — gives the same PAM strain at every route
    length (pamkin.robot.biped, 41 poses); a tendon that would go negative is clipped at 0, and so are the bounds."""
    from types import SimpleNamespace

    from pamkin.optimize.actuator import block_start

    model, route = toy
    q, _ = model.grid(["angle"], 41, rom=RangeOfMotion({"angle": (-1.0, 1.0)}))
    z = np.array([0.1, 0.2, 0.3, 0.24, 0.09])
    wide = SimpleNamespace(lbx=np.full(5, -np.inf), ubx=np.full(5, np.inf))
    z2 = block_start(wide, z, k0, k, FIT)
    np.testing.assert_array_equal(z2[:3], z[:3])
    assert z2[3] == pytest.approx(0.24 * k0 / k) and z2[4] == pytest.approx(0.09 + 2 * FIT * (k0 - k))
    strain = [_robot(model, Pam(1, "t", (), "angle", (), 20, 1, float(zz[3]), float(zz[4]), route, transmission=kk))
              .evaluate(q).strain[:, 0] for zz, kk in ((z, k0), (z2, k))]
    np.testing.assert_allclose(strain[1], strain[0], rtol=0, atol=1e-12)
    z[4] = 0.01
    assert block_start(wide, z, k0, k, FIT)[4] == 0.0
    tight = SimpleNamespace(lbx=np.zeros(5), ubx=np.full(5, 0.05))
    assert block_start(tight, z, k0, k, FIT)[3] == 0.05


def _out_of_reach(model, route, diameters: list[int]):
    """The out-of-reach toy of the block tests: its range, its direct PAM, half that PAM's torque as the
    target and a run configuration with blocks on (a lenient mount cost)."""
    rom = RangeOfMotion({"angle": (-0.6, 0.6)})
    direct = _robot(model, Pam(1, "t", (), "angle", (), 10, 1, 0.1, 0.0, route))

    def target(q):
        return 0.5 * direct.evaluate(q).torques[:, 0, :]

    cfg = RunConfig().replace({**FAST_FIT, "limits.rated_force": True, "mount.cost": 10.0, "weights.regularization": 0.0, "mount.blocks": True, "limits.bone_clearance": False, "samples.primary": 31, "limits.min_point_distance_m": 0.0, "regions": {"1": [0.0, 0.0, 0.0]}, "first_fit.diameters_mm": diameters})
    return rom, direct, target, cfg


def test_one_segment_stage_tries_a_block_on_the_fixed_route(toy):
    """optimize.mount.mount_block: the direct PAM out of reach of its 0.15 m segment is put on a 2:1 block
    on the same route (the points unchanged) and checked independently (pamkin.robot.biped, 201 poses); with a
    mount cost it cannot meet, it is left as it was and the log says what was tried; switched off, not tried."""
    from pamkin.optimize.mount import mount_block, mount_stage
    from pamkin.optimize.results import solution_pam

    model, route = toy
    route = (PathPoint("a", "base", (0.13, -0.20, 0.0)), *route)
    rom, direct, target, cfg = _out_of_reach(model, route, [10, 20])
    seed, prob, sol = _fit(model, route, 1, rom, cfg, target)
    _, info = mount_stage(prob, sol, seed, cfg, model, rom, solution_pam)
    assert info["reason"] == "out of reach"
    got, p2, out = mount_block(prob, sol, info, seed, cfg, model, rom, solution_pam)
    assert out["mounted"] and out["transmission"] == 2 and p2.k == 2 and out["segment"] == "o->v", out
    assert out["line"].startswith("on one straight segment o->v with a 2:1 pulley block")
    np.testing.assert_allclose(np.array(got.points), np.array(sol.points), atol=0)     # the route is unchanged
    pam = solution_pam(dataclasses.replace(seed, transmission=2), p2.finalize(got))
    q, _ = model.grid(["angle"], 201, rom=rom)
    ev = _robot(model, pam).evaluate(q)
    assert (0.15 - np.maximum(pam.resting_length_m, ev.pam_lengths[:, 0]) - 2 * FIT).min() >= -1e-6
    d = pam.diameter_mm
    assert ev.strain.max() <= min(festo.kmax(pam.resting_length_m, d), festo.max_contraction(d)) + 1e-6
    assert ev.strain.min() >= -festo.max_pretension(d) - 1e-6
    assert ev.unit_forces.max() <= festo.F_MAX_THEORETICAL[d] + 1e-6
    # a mount cost the block cannot meet: the direct PAM stays, and the log names the tries
    strict = copy.deepcopy(cfg)                        # (the block fits this target better than direct;
    strict.mount.cost = -10.0                          # below the range a run description may set)
    kept, p3, out2 = mount_block(prob, sol, info, seed, strict, model, rom, solution_pam)
    assert kept is sol and p3 is prob and not out2.get("mounted")
    assert "with a 2:1 pulley block on the same route: 10 mm:" in out2["line"]
    # every diameter fit the 2:1 block at a fit cost: a 3:1 block (a third of the force) is not tried
    assert out2["block_tried"] == ["with a 2:1 pulley block on the same route: 10 mm: fit cost (root +0.000), "
                                   "20 mm: fit cost (root +0.000)"]
    # mount_passing: a reason to accept the cost (the run's: the mounted PAM still passes the audit's fit
    # limits) is asked with the spanning start and the mounted PAM on the block, and mounts it at that cost
    asked = []

    def passing(spanning, mounted):
        asked.append((spanning.transmission, mounted.transmission))
        return "on one segment it still passes both audit fit limits (test)"

    got3, p4, out4 = mount_block(prob, sol, info, seed, strict, model, rom, solution_pam, frozenset(), passing)
    assert out4["mounted"] and out4["transmission"] == 2 and p4.k == 2 and asked and set(asked) == {(2, 2)}
    assert out4["failing_fit"].endswith("(test)")
    np.testing.assert_allclose(np.array(got3.points), np.array(sol.points), atol=0)
    off = cfg.replace({"mount.blocks": False})
    assert mount_block(prob, sol, info, seed, off, model, rom, solution_pam)[2] is info
    # tried where the stage found the PAM infeasible at 1:1 too (a block halves the stroke the limits see),
    # not where it fits at 1:1 at a fit cost
    infeasible = dict(info, reason="infeasible")
    got2, _, out3 = mount_block(prob, sol, infeasible, seed, cfg, model, rom, solution_pam)
    assert out3["mounted"] and "; infeasible at 1:1)" in out3["line"] and got2.objective == got.objective
    cost = dict(info, reason="fit cost")
    assert mount_block(prob, sol, cost, seed, cfg, model, rom, solution_pam)[2] is cost


def test_block_goes_to_three_to_one_where_two_to_one_is_out_of_reach(toy):
    """Segments of at most 0.10 m: the toy's excursion needs a resting length (reach_bound) beyond what they
    hold at 1:1 and at 2:1, within it at 3:1. mount_block tries 2:1 (at every diameter of the run: 10 mm here), then 3:1, and keeps
    the first that mounts; pamkin.robot.biped on 201 poses confirms the PAM body on the segment, the strain and
    rated-force limits and a route tension of a third of the PAM's force."""
    from pamkin.optimize.mount import BLOCKS, mount_block, mount_stage, reach_bound
    from pamkin.optimize.results import solution_pam
    from pamkin.robot.pam_body import route_positions, segment_names

    model, route = toy
    route = (PathPoint("a", "base", (0.084, -0.192, 0.0)), route[0], PathPoint("v", "base", (0.03, -0.22, 0.0)),
             route[2])
    rom, direct, target, cfg = _out_of_reach(model, route, [10])
    L = direct.evaluate(model.grid(["angle"], 201, rom=rom)[0]).lengths[:, 0]
    need = {k: reach_bound(L, 0.10, 10, cfg, FIT, k) for k in (1, 2, 3)}
    assert BLOCKS == (2, 3) and need[2][0] > need[2][1] > need[3][0]
    seed, prob, sol = _fit(model, route, 1, rom, cfg, target)
    _, info = mount_stage(prob, sol, seed, cfg, model, rom, solution_pam)
    assert info["reason"] == "out of reach"
    got, p3, out = mount_block(prob, sol, info, seed, cfg, model, rom, solution_pam)
    assert out["mounted"] and out["transmission"] == 3 and p3.k == 3, out
    assert out["block_tried"][0] == "with a 2:1 pulley block on the same route: 10 mm: out of reach"
    assert out["line"].startswith(f"on one straight segment {out['segment']} with a 3:1 pulley block")
    assert "out of reach at 1:1, on a 2:1 pulley block on the same route: 10 mm: out of reach" in out["line"]
    np.testing.assert_allclose(np.array(got.points), np.array(sol.points), atol=0)
    pam = solution_pam(dataclasses.replace(seed, transmission=3), p3.finalize(got))
    assert pam.transmission == 3
    q, _ = model.grid(["angle"], 201, rom=rom)
    robot = _robot(model, pam)
    ev = robot.evaluate(q)
    pts = route_positions(robot.paths, model.kinematics.forward(q), 0)
    j = segment_names(pam).index(out["segment"])
    seg = np.linalg.norm(pts[:, j + 1] - pts[:, j], axis=1)
    assert seg.min() < need[2][0] + 2 * FIT         # a 2:1 PAM would not fit on it
    assert (seg - np.maximum(pam.resting_length_m, ev.pam_lengths[:, 0]) - 2 * FIT).min() >= -1e-6
    d = pam.diameter_mm
    assert ev.strain.max() <= min(festo.kmax(pam.resting_length_m, d), festo.max_contraction(d)) + 1e-6
    assert ev.strain.min() >= -festo.max_pretension(d) - 1e-6
    assert ev.unit_forces.max() <= festo.F_MAX_THEORETICAL[d] + 1e-6
    np.testing.assert_allclose(ev.forces[:, 0], ev.unit_forces[:, 0] / 3, rtol=1e-13)
    # the run keeps the direct PAM beside the 3:1 block, so the mass budget can take the block off again
    from pamkin.optimize import actuator
    from pamkin.optimize.context import RunContext

    ctx = RunContext(cfg, None, model, rom)
    got2, _, info2, direct = actuator.mount_actuator(ctx, prob, sol, seed, cfg.replace({"mount.enabled": True}))
    assert info2["transmission"] == 3 and got2.objective == got.objective
    assert direct is not None and direct[0] is sol and direct[2]["reason"] == "out of reach"


def test_config_transmission_table(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text('[transmission]\n"4" = 2\n')
    cfg = load_config(f)
    thesis = load_design("thesis")
    des = cfg.apply_transmission(thesis)
    assert des.pam(4).transmission == 2 and des.pam(5) == thesis.pam(5)
    # the converted seed keeps the PAM's strain at every pose (the same Festo model, half the stroke)
    p = dataclasses.replace(thesis.pam(12), tendon_length_m=0.1)
    f.write_text('[transmission]\n"12" = 2\n')
    one = thesis.replace_pam(p)
    two = load_config(f).apply_transmission(one)
    assert two.pam(12).resting_length_m == pytest.approx(p.resting_length_m / 2)
    q = np.zeros((3, len(PamRobot(one, sides=("r",)).coordinates)))
    q[:, PamRobot(one, sides=("r",)).coordinates.index("ankle_angle_r")] = [-0.3, 0.0, 0.3]
    s1 = PamRobot(Design("1", (one.pam(12),)), sides=("r",)).evaluate(q).strain
    s2 = PamRobot(Design("2", (two.pam(12),)), sides=("r",)).evaluate(q).strain
    np.testing.assert_allclose(s2, s1, atol=1e-12)
    f.write_text('[transmission]\n"4" = 3\n')
    assert load_config(f).apply_transmission(thesis).pam(4).transmission == 3
    f.write_text('[transmission]\n"4" = 4\n')
    with pytest.raises(DataFileError, match=r"transmission\.4: must be one of \(1, 2, 3\)"):
        load_config(f)
    f.write_text('[transmission]\n"p4" = 2\n')
    with pytest.raises(DataFileError, match=r"transmission\.p4: keys are actuator ids"):
        load_config(f)
    f.write_text('[transmission]\n"99" = 2\n')
    with pytest.raises(DataFileError, match=r"transmission\.99: names no actuator"):
        load_config(f).check_design(load_design("thesis"))


def test_example_config_loads_and_fits_the_default_seed():
    cfg = load_config(EXAMPLES / "pulley_blocks.toml")
    seed = load_design(cfg.design)
    cfg.check_design(seed)
    des = cfg.apply_transmission(seed)
    assert [p.id for p in des.pams if p.transmission == 2] == [5, 24]


def test_audit_reports_unit_force_and_block_mass():
    """The audit's force per PAM is the PAM's own force (twice the route's tension with the block), its
    mass includes the block, and the row names the transmission."""
    from pamkin.audit.measure import AuditOptions, audit_design

    pts = (PathPoint("a", "torso", (0.03, -0.05, 0.03)), PathPoint("b", "femur_r", (0.0, -0.05, 0.0)))
    pam = Pam(27, "Psoas", ("psoas_r",), "hip_flexion_r", (), 20, 1, 0.12, 0.02, pts, transmission=2)
    des = Design("block", (pam,), rom="robot_thesis")
    opts = AuditOptions(n_random=60, gait_ik=None, gait_plan=False, n_geometry=10, n_sweep=11, n_grid=5,
                        segment_step_m=0.02)
    res = audit_design(des, options=opts)
    row = res.pams[0]
    robot = PamRobot(des, sides=("r",))
    ev = robot.evaluate(res.details["q_rand"])        # no walking trial: the random poses are every sample
    assert row["transmission"] == 2
    assert row["peak_force_per_unit_N"] == pytest.approx(ev.unit_forces[:, 0].max(), rel=1e-12)
    assert row["peak_force_per_unit_N"] == pytest.approx(2 * ev.forces[:, 0].max(), rel=1e-12)
    assert row["mass_kg"] == pytest.approx(pam_unit_mass(pam))
    from pamkin.audit.scorecard import scorecard_text

    assert any(line.split()[:4] == ["27", "Psoas", "20/2", "1"] for line in scorecard_text(res).splitlines())
