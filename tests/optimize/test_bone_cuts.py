"""Bone-mesh clearance in the optimiser (optimize.bone_cuts): closest points and normals of the bone
meshes, and the sequentially linearised constraints that keep a toy route out of a toy mesh."""

from __future__ import annotations


import numpy as np
import pytest
import trimesh

import pamkin
from pamkin.human.bones import BoneSet
from pamkin.robot.design import Design, Pam
from pamkin.optimize.bone_cuts import POINT_MAX, POINT_MIN, BoneCuts, bone_stage, push_out
from pamkin.optimize.config import FAST_FIT, RunConfig
from pamkin.optimize.problem import ActuatorProblem
from pamkin.optimize.samples import actuator_data
from pamkin.opensim.model_file import PathPoint
from pamkin.robot.biped import PamRobot
from pamkin.human.rom import RangeOfMotion
from toy_route import INSERTION_BLOCK, ORIGIN_BLOCK, box, toy_problem
from locations import DATA



def test_closest_point_and_normal_are_the_distance_gradient():
    """Outward normals equal central differences of the signed distance (inside and outside a closed
    mesh); closest points lie at distance |d| along the normal."""
    model = pamkin.load_osim(DATA / "two_body.osim")
    s = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    bones = BoneSet.from_meshes(model, {"base": [(s.vertices, s.faces)]})
    rng = np.random.default_rng(1)
    P = rng.normal(size=(40, 3))
    P *= (rng.uniform(0.01, 0.09, 40) / np.linalg.norm(P, axis=1))[:, None]   # inside and outside
    P = P[np.abs(np.linalg.norm(P, axis=1) - 0.048) > 0.006]                    # off the surface
    d, c, n = bones.body_closest("base", P)
    assert (d < 0).any() and (d > 0).any()
    h = 1e-6
    grad = np.stack([(bones.body_signed_distance("base", P + h * e) - bones.body_signed_distance("base", P - h * e))
                     / (2 * h) for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(n, grad, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(P, c + d[:, None] * n, atol=1e-12)


def test_exit_point_leaves_overlapping_meshes():
    """A point inside two crossing plates (a bone of overlapping meshes, like the pelvis halves and
    sacrum): the move along the nearest surface's normal lands inside the other plate; ``exit_point``
    finds the way out, as short as the analytic one (to the corner (5 + t, 5 + t) mm) within its ray
    spacing."""
    from pamkin.optimize.bone_cuts import exit_point

    model = pamkin.load_osim(DATA / "two_body.osim")
    plate_a = box([-0.05, -0.005, -0.05], [0.05, 0.005, 0.05])     # |y| < 5 mm
    plate_b = box([-0.005, -0.05, -0.05], [0.005, 0.05, 0.05])     # |x| < 5 mm
    bones = BoneSet.from_meshes(model, {"base": [plate_a, plate_b]})
    x = np.array([0.004, 0.0045, 0.0])
    d, c, n = bones.body_closest("base", x[None])
    assert d[0] < 0
    along_normal = c[0] + POINT_MIN * n[0]
    assert bones.body_signed_distance("base", along_normal[None])[0] < 0           # still inside
    out = exit_point(bones, "base", x, POINT_MIN)
    inside = lambda p: abs(p[1]) < 0.005 or abs(p[0]) < 0.005                       # noqa: E731
    assert out is not None and not inside(out)
    assert min(abs(out[0]), abs(out[1])) - 0.005 >= POINT_MIN - 1e-9                # independent distance
    shortest = np.hypot(0.005 + POINT_MIN - x[0], 0.005 + POINT_MIN - x[1])
    assert shortest - 1e-9 <= np.linalg.norm(out - x) <= shortest + 0.001
    assert exit_point(bones, "base", np.array([0.0, 0.0, 0.0]), 0.1) is None       # no way out in reach


def test_pull_in_puts_points_on_the_band_and_off_the_midline():
    """``pull_in`` with ``zmin``: a point 40 mm from a sphere and below its z bound ends within the
    3-18 mm band of the sphere (independent distance: |x| - radius) and at z >= zmin; one already
    within both is left alone; without ``zmin`` only the band applies."""
    model = pamkin.load_osim(DATA / "two_body.osim")
    ball = trimesh.creation.icosphere(subdivisions=4, radius=0.05)
    bones = BoneSet.from_meshes(model, {"base": [(ball.vertices, ball.faces)]})
    route = (PathPoint("o", "base", (0.09, 0.0, -0.02)), PathPoint("i", "arm", (0.05, -0.12, 0.0)))
    pam = Pam(1, "toy", (), "angle", (), 10, 1, 0.25, 0.0, route)
    q, _ = model.grid(["angle"], 3, rom=RangeOfMotion({"angle": (-0.2, 0.2)}))
    cuts = BoneCuts(pam, model, bones, q)
    loc = np.array([[0.09, 0.0, -0.02], [0.05, -0.12, 0.0]])
    zmin = np.array([0.01, -np.inf])
    out = cuts.pull_in(loc, reach=0.0, zmin=zmin)
    radius_at = np.linalg.norm(out[0]) - 0.05            # the icosphere's faces lie within 0.1 mm of the sphere
    assert POINT_MIN - 2e-4 <= radius_at <= POINT_MAX + 2e-4 and out[0][2] >= zmin[0]
    np.testing.assert_array_equal(out[1], loc[1])        # no mesh on the arm: unchanged
    assert np.array_equal(cuts.pull_in(out, reach=0.0, zmin=zmin), out)    # already on both: unchanged
    band_only = cuts.pull_in(loc, reach=0.0)
    assert band_only[0][2] < 0 and POINT_MIN - 2e-4 <= np.linalg.norm(band_only[0]) - 0.05 <= POINT_MAX + 2e-4


def test_mesh_rows_keep_a_toy_route_out_of_a_toy_mesh(monkeypatch):
    """Two bodies, one pin joint; each attachment point stands 30 mm off its bone (a block), and the
    straight route passes through a bump of the base's bone. After the bone-mesh rounds,
    measured independently on a dense grid of the joint angle: the route clears the meshes (the
    segment's centre line at most 2 mm into bone, the audit's limit; the rows ask for +1 mm at the
    check poses) and both points sit outside their bones within 20 mm; the fit stays close."""
    model, rom, seed, cfg, data, seed_points, regions = toy_problem(0.06)
    bump = box((0.038, -0.22, -0.015), (0.06, -0.18, 0.015))
    bones = BoneSet.from_meshes(model, {"base": [box(*ORIGIN_BLOCK), bump], "arm": [box(*INSERTION_BLOCK)]})
    prob = ActuatorProblem(data, cfg, 10, seed_points, regions)
    sol = prob.solve(prob.initial_guess(seed_points, None, None), 1)
    assert sol.success, sol.status
    q_check, _ = model.grid(["angle"], 11, rom=rom)
    cuts = BoneCuts(seed, model, bones, q_check)
    assert cuts.measure(np.array(seed_points)).segment_depth[0] > 0.005     # the seed route hits the bump
    before = cuts.measure(np.array(sol.points))
    assert before.violation() > 0.01                        # the fitted route ignores the meshes
    best, measure, info = bone_stage(prob, sol, cuts, rounds=12)
    assert best.success and best is not sol, info

    # independent check: dense angles, 1 mm steps along the segment, both bodies' meshes
    fitted = Pam(1, "fit", (), "angle", (), 10, 1, best.rest_length, best.tendon_length,
                 tuple(PathPoint(p.name, p.body, tuple(loc)) for p, loc in zip(seed.points, best.points)))
    robot = PamRobot(Design("fit", (fitted,)), model, sides=("r",))
    q, _ = model.grid(["angle"], 201, rom=rom)
    st = model.kinematics.forward(q)
    X, _ = robot.paths.point_positions(st)
    t = np.linspace(0, 1, 400)
    P = X[:, :1] + t[None, :, None] * (X[:, 1:2] - X[:, :1])
    d, _ = bones.signed_distance(st, P, margin=None)
    print(f"deepest point of the segment: {-d.min() * 1e3:.2f} mm into bone (before: "
          f"{before.segment_depth.max() * 1e3:.1f} mm); rounds: {[(r['violation_mm'], round(r['objective'], 4)) for r in info]}")
    assert d.min() >= -0.002
    own = [bones.body_signed_distance(p.body, np.array([loc]))[0] for p, loc in zip(seed.points, best.points)]
    assert all(POINT_MIN - 1e-4 <= x <= POINT_MAX + 1e-4 for x in own), own
    assert measure.violation() == 0.0
    assert best.objective <= 1.5 * sol.objective + 1e-3     # the fit stays close to the unconstrained one

    # out of rounds while clear and still gaining: up to EXTRA_CLEAR_ROUNDS more, never a worse result.
    # From the clear route, round 1 is accepted (the first always is) and clear: with rounds=1 a second
    # round runs, unless the extension is switched off
    import pamkin.optimize.bone_cuts as bc

    ext, m_ext, info_ext = bone_stage(prob, best, cuts, rounds=1)
    monkeypatch.setattr(bc, "EXTRA_CLEAR_ROUNDS", 0)
    one, m_one, info_one = bone_stage(prob, best, cuts, rounds=1)
    assert info_one[1]["accepted"] and info_one[1]["violation_mm"] == 0.0 and len(info_one) == 2, info_one
    assert len(info_ext) >= 3, info_ext
    assert bc.stage_key(m_ext, ext) <= bc.stage_key(m_one, one)
    monkeypatch.undo()

    # the second start (optimize.actuator.seed_start): from the seed route moved onto the bands; its result
    # replaces a worse one (here the unconstrained fit, in bone) and is itself clear of bone
    from pamkin.optimize.actuator import seed_start

    lines: list[str] = []
    kept, m_kept, _ = seed_start(prob, sol, before, [], cuts, cfg, lines)
    assert kept is not sol and kept.success and m_kept.violation() == 0.0, lines
    assert lines[0] == "  bone rounds from the seed route:" and lines[-1].startswith("  kept the seed-route result")
    assert cuts.measure(np.array(kept.points)).violation() == 0.0          # measured again, independently of m_kept

    # a warm start (the cleared route, taken as given): kept unless a round lowers its merit
    start = prob.evaluate(best.z, 1)
    again, m_again, _ = bone_stage(prob, start, cuts, rounds=8, keep_start=True)
    assert m_again.violation() == 0.0 and again.objective <= start.objective + 1e-12
    # a warm start in bone is still moved out of it
    moved, m_moved, _ = bone_stage(prob, prob.evaluate(sol.z, 1), cuts, rounds=12, keep_start=True)
    assert m_moved.violation() < 0.2 * before.violation()

    # push_out: a cleared route with its insertion put 1 mm inside its block is moved back out, exactly to
    # POINT_MIN along the normal (independent distance), when the problem's own constraints allow it
    z = best.z.copy()
    d, c, n = bones.body_closest("arm", np.array([best.points[1]]))
    z[3:6] = c[0] - 0.001 * n[0]
    inside = prob.evaluate(z, 1)
    assert bones.body_signed_distance("arm", np.array([inside.points[1]]))[0] == pytest.approx(-0.001, abs=1e-9)
    out, m_out, names, outcome = push_out(prob, inside, cuts)
    assert names == ["i"] and out.success and outcome == f"moved out to {1e3 * POINT_MIN:g} mm"
    assert bones.body_signed_distance("arm", np.array([out.points[1]]))[0] == pytest.approx(POINT_MIN, abs=1e-9)
    assert m_out.violation() <= cuts.measure(np.array(inside.points)).violation()
    same, _, none, _ = push_out(prob, best, cuts)           # nothing inside: unchanged
    assert same is best and none == []
    # a move the problem's constraints refuse (0.3 m out: far past the strain limits) falls back to the
    # next distance; with none left the point stays and the outcome says why
    import pamkin.optimize.bone_cuts as bc
    monkeypatch.setattr(bc, "PUSH_TARGETS", (0.3, POINT_MIN))
    out2, _, names2, outcome2 = push_out(prob, inside, cuts)
    assert names2 == ["i"] and outcome2 == f"moved out to {1e3 * POINT_MIN:g} mm"
    assert bones.body_signed_distance("arm", np.array([out2.points[1]]))[0] == pytest.approx(POINT_MIN, abs=1e-9)
    monkeypatch.setattr(bc, "PUSH_TARGETS", (0.3,))
    kept, _, names3, outcome3 = push_out(prob, inside, cuts)
    assert kept is inside and names3 == ["i"] and outcome3.startswith("not moved out (even to 300 mm: ")
    monkeypatch.undo()
    # the third attempt: where the moved point alone and the re-solved lengths both fail (forced here), the
    # other points are re-solved within PUSH_REACH with the moved point held
    import dataclasses

    real = prob.solve_with_rows
    calls = []

    def lengths_only_fails(z0, n, W, *args, **kw):
        s, slack = real(z0, n, W, *args, **kw)
        calls.append(len(W))
        return (dataclasses.replace(s, success=False) if len(calls) == 1 else s), slack

    real_evaluate = prob.evaluate
    monkeypatch.setattr(prob, "evaluate", lambda z, n=1: dataclasses.replace(real_evaluate(z, n), success=False))
    monkeypatch.setattr(prob, "solve_with_rows", lengths_only_fails)
    out4, m4, names4, outcome4 = push_out(prob, inside, cuts)
    assert len(calls) == 2 and names4 == ["i"] and outcome4 == f"moved out to {1e3 * POINT_MIN:g} mm", (calls, outcome4)
    assert out4.success and m4.violation() <= cuts.measure(np.array(inside.points)).violation()
    assert bones.body_signed_distance("arm", np.array([out4.points[1]]))[0] == pytest.approx(POINT_MIN, abs=1e-9)
    assert np.abs(np.array(out4.points[0]) - np.array(inside.points[0])).max() <= bc.PUSH_REACH + 1e-7   # IPOPT bound relaxation


def _fit_and_clear(model, bones, seed, rom, cfg, target, rounds: int):
    """Fit the toy actuator ``seed`` (10 mm, one PAM) to ``target`` and run the bone rounds at 11 angles of
    ``rom``: (problem, fitted solution, cuts, cleared solution, its measure)."""
    data = actuator_data(seed, model, rom, cfg, 0.0125, target=target)
    pts = [np.array(p.location) for p in seed.points]
    prob = ActuatorProblem(data, cfg, 10, pts, [np.array(cfg.region(1, p.name)) for p in seed.points])
    sol = prob.solve(prob.initial_guess(pts, None, None), 1)
    q_check, _ = model.grid(["angle"], 11, rom=rom)
    cuts = BoneCuts(seed, model, bones, q_check)
    best, measure, _ = bone_stage(prob, sol, cuts, rounds=rounds)
    return prob, sol, cuts, best, measure


def test_bone_mesh_config_keys(tmp_path):
    from pamkin.errors import DataFileError
    from pamkin.optimize.config import load_config

    f = tmp_path / "c.toml"
    f.write_text("[bone_rounds]\nenabled = true\nrounds = 4\n")
    cfg = load_config(f)
    assert cfg.bone_rounds.enabled and cfg.bone_rounds.rounds == 4
    f.write_text("[bone_rounds]\nrounds = 0\n")
    with pytest.raises(DataFileError, match="bone_rounds"):
        load_config(f)


def test_pam_rows_move_a_toy_route_off_another_pam_body():
    """The toy route clear of its bones, then a second PAM body (a fixed capsule of radius 10 mm)
    placed 12 mm beside it: with the PAM–PAM rows the route (radius 7.5 mm) moves clear of it, still
    clear of bone."""
    from pamkin.optimize.pam_clearance import Body

    model = pamkin.load_osim(DATA / "two_body.osim")
    rom = RangeOfMotion({"angle": (-0.2, 0.2)})
    bones = BoneSet.from_meshes(model, {"base": [box((0.0, -0.08, -0.03), (0.02, -0.02, 0.03))],
                                        "arm": [box((0.0, -0.15, -0.03), (0.02, -0.09, 0.03))]})
    route = (PathPoint("o", "base", (0.03, -0.05, 0.0)), PathPoint("i", "arm", (0.03, -0.12, 0.0)))
    seed = Pam(1, "toy", (), "angle", (), 10, 1, 0.25, 0.0, route)
    seed_robot = PamRobot(Design("seed", (seed,)), model, sides=("r",))

    def target(q):
        return seed_robot.evaluate(q).torques[:, 0, :]

    cfg = RunConfig().replace({**FAST_FIT, "bone_rounds.enabled": True, "weights.regularization": 0.0, "limits.bone_clearance": False, "samples.primary": 21, "regions": {"1": [0.05, 0.05, 0.05]}})
    prob, sol, cuts, first, m1 = _fit_and_clear(model, bones, seed, rom, cfg, target, rounds=8)
    assert m1.violation() == 0.0
    X = cuts.world(np.array(first.points))                 # (S, 2, 3): the other body runs 12 mm beside
    other = Body(2, [(X[:, 0] + [0.0, 0.0, 0.012], X[:, 1] + [0.0, 0.0, 0.012], np.ones(len(X), bool))], 0.010, 0)
    cuts.set_obstacles([other], 0.0075, 0)
    before = cuts.measure(np.array(first.points))
    assert before.pam_clearance[2] < -0.005
    best, m2, info = bone_stage(prob, prob.evaluate(first.z, 1), cuts, rounds=8)
    print("PAM clearance before/after [mm]:", 1e3 * before.pam_clearance[2], 1e3 * m2.pam_clearance[2],
          [(r["violation_mm"], round(r["objective"], 4)) for r in info])
    assert m2.pam_clearance[2] >= -1e-4
    assert m2.violation() == 0.0


def test_bone_mesh_run_is_clear_on_held_out_poses(tmp_path, capsys):
    """`pamkin optimize` with bone_mesh on one actuator (the short head of biceps femoris), checked
    independently: its saved route's fixed points lie outside their bone within 20 mm, and on the audit's
    held-out random poses (another random stream) no segment goes more than 2 mm into any bone."""
    import json
    import warnings

    from pamkin.audit.measure import random_poses
    from pamkin.cli import main
    from pamkin.robot.design import load_design
    from pamkin.robot.rack import ANCHOR, GUIDE
    from pamkin.errors import RangeWarning
    from pamkin.robot.biped import robot_skeleton
    from pamkin.human.rom import load_rom

    cfg = tmp_path / "bone.toml"
    cfg.write_text("[first_fit]\nmultistart = 0\ndiameters_mm = [20]\nmax_parallel = 1\n[bone_rounds]\nenabled = true\n")
    out = tmp_path / "run"
    assert main(["optimize", str(cfg), "--actuators", "10", "--workers", "1", "--no-audit", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["bone_mesh"]["10"]["clear"], summary["bone_mesh"]
    skel = robot_skeleton()
    pam = load_design(out / "design.yaml", bodies=skel.bodies, coordinates=skel.coordinates).pam(10)
    bones = BoneSet(skel)
    for pt in pam.points:            # (a rack's brackets, pamkin.robot.rack, stand up to 50 mm out)
        d = bones.body_signed_distance(pt.body, np.array([pt.location]))[0]
        assert 0.0 <= d <= (0.050 if pt.name in (ANCHOR, GUIDE) else 0.020), (pt.name, d)
    robot = PamRobot(Design("one", (pam,)), skel, sides=("r",))
    q = random_poses(skel, load_rom("robot_thesis", "r"), 300, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st = skel.kinematics.forward(q, warn_range=False)
    X, _ = robot.paths.point_positions(st)
    t = np.linspace(0, 1, 60)
    right = [b for b in bones.bodies if not b.endswith("_l")]
    for a in range(X.shape[1] - 1):
        P = X[:, a:a + 1] + t[None, :, None] * (X[:, a + 1:a + 2] - X[:, a:a + 1])
        d, _ = bones.signed_distance(st, P, margin=0.0, bodies=right)
        assert d.min() >= -0.002, (a, d.min())


def test_point_contact_poses_find_a_point_that_meets_another_bone():
    """A pelvis attachment point low on the ischium (where a default run put the erector spinae's
    origin): the femur reaches it at a few of 2000 random poses. Every pose returned brings it within
    3 mm of a bone other than the pelvis, checked independently in the femur's frame; the iliac-crest
    point of the same route meets no other bone."""
    from pamkin.optimize.bone_cuts import POINT_CHECK_ADD, SEGMENT_CLEARANCE, point_contact_poses
    from pamkin.human.rom import load_rom

    human = pamkin.gait2392()
    bones = BoneSet(human)
    rom = load_rom("robot_thesis", "r")
    low = PathPoint("p1", "pelvis", (-0.1296, -0.1010, 0.0846))
    crest = PathPoint("p2", "pelvis", (-0.1425, 0.0291, 0.0436))
    top = PathPoint("p3", "torso", (-0.0915, 0.2220, 0.0310))
    pam = Pam(1, "toy", (), "lumbar_extension", (), 40, 1, 0.3, 0.0, (low, crest, top))
    q = point_contact_poses(human, bones, rom, pam, seed=0)
    assert 1 <= len(q) <= POINT_CHECK_ADD
    st = human.kinematics.forward(q, warn_range=False)
    b, f = human.bodies.index("pelvis"), human.bodies.index("femur_r")
    x = st.body_p[:, b] + np.einsum("sij,j->si", st.body_R[:, b], np.array(low.location))
    in_femur = np.einsum("sji,sj->si", st.body_R[:, f], x - st.body_p[:, f])
    d = bones.body_signed_distance("femur_r", in_femur)
    assert np.all(d < SEGMENT_CLEARANCE), d
    assert len(point_contact_poses(human, bones, rom, Pam(1, "toy", (), "lumbar_extension", (), 40, 1, 0.3, 0.0,
                                                          (crest, top)), seed=0)) == 0



def _mount_toy(mount_cost: float):
    """A three-point toy route (two_body.osim; o and v on "base", i on "arm") fitted to 0.6 of its own torque
    over ±0.4 rad with its points free by 20 mm, blocks 10 mm behind each point, and the bone rounds run:
    (model, rom, seed, cfg, prob, best, cuts, bones)."""
    model = pamkin.load_osim(DATA / "two_body.osim")
    bones = BoneSet.from_meshes(model, {"base": [box((0.005, 0.03, -0.01), (0.02, 0.07, 0.01)),
                                                 box((0.01, -0.14, -0.01), (0.025, -0.10, 0.01))],
                                        "arm": [box((0.0, -0.05, -0.01), (0.01, -0.01, 0.01))]})
    rom = RangeOfMotion({"angle": (-0.4, 0.4)})
    route = (PathPoint("o", "base", (0.03, 0.05, 0.0)), PathPoint("v", "base", (0.035, -0.12, 0.0)),
             PathPoint("i", "arm", (0.02, -0.03, 0.0)))
    seed = Pam(1, "toy", (), "angle", (), 10, 1, 0.3, 0.0, route)
    seed_robot = PamRobot(Design("seed", (seed,)), model, sides=("r",))

    def target(q):
        return 0.6 * seed_robot.evaluate(q).torques[:, 0, :]

    cfg = RunConfig().replace({**FAST_FIT, "limits.rated_force": True, "bone_rounds.enabled": True, "mount.cost": mount_cost, "weights.regularization": 0.0, "limits.bone_clearance": False, "samples.primary": 21, "limits.min_point_distance_m": 0.0, "regions": {"1": [0.02, 0.02, 0.0]}})
    prob, _, cuts, best, measure = _fit_and_clear(model, bones, seed, rom, cfg, target, rounds=12)
    assert best.success and measure.violation() == 0.0
    return model, rom, seed, cfg, prob, best, cuts, bones


def test_mount_rounds_put_a_pam_on_its_segment_with_the_points_free():
    """optimize.mount.mount_rounds: a toy PAM spanning a via point costs fit to mount on its fixed route
    (reason "fit cost"); with the points free — bone rounds with the one-segment rows — it is mounted at a
    smaller cost, and measured independently (pamkin.robot.biped on 201 poses, the blocks on a dense grid) it
    fits on the segment, keeps its strain limits and clears the blocks within its brackets. A mount cost
    the rounds cannot meet is refused and named; one far below the fixed route's cost is not tried."""

    from pamkin.robot import festo
    from pamkin.optimize.mount import mount_rounds, mount_stage, mounted_segment
    from pamkin.optimize.results import solution_pam

    model, rom, seed, cfg, prob, best, cuts, bones = _mount_toy(10.0)
    assert mounted_segment(prob, best.z) is None          # it spans both segments
    _, free = mount_stage(prob, best, seed, cfg, model, rom, solution_pam)
    c1 = free["cost"]                                      # the fixed route's cost of mounting
    assert free["mounted"] and c1 > 0.005, free
    cfg_m = cfg.replace({"mount.cost": 0.999 * c1})
    kept, info = mount_stage(prob, best, seed, cfg_m, model, rom, solution_pam)
    assert kept is best and info["reason"] == "fit cost"
    mounted, p1, out = mount_rounds(prob, best, info, seed, cfg_m, cuts, model, rom, solution_pam)
    assert out["mounted"] and out["rounds"]["kept"], out
    j = p1.mount
    assert p1 is not prob and mounted_segment(p1, mounted.z) == j and out["segment"] == ["o->v", "v->i"][j]
    assert out["cost"] <= cfg_m.mount.cost and out["cost"] < c1
    assert np.abs(np.array(mounted.points) - np.array(best.points)).max() > 1e-4      # the points moved
    assert out["line"].startswith(f"on one straight segment {out['segment']} with its points moved")

    # independent checks: the PAM body on its segment, the strain limits, the blocks and brackets
    pam = solution_pam(seed, p1.finalize(mounted))
    q, _ = model.grid(["angle"], 201, rom=rom)
    robot = PamRobot(Design("m", (pam,)), model, sides=("r",))
    st = model.kinematics.forward(q)
    X, _ = robot.paths.point_positions(st)
    ev = robot.evaluate(q)
    seg = np.linalg.norm(X[:, j + 1] - X[:, j], axis=1)
    assert (seg - np.maximum(pam.resting_length_m, ev.pam_lengths[:, 0]) - 2 * 0.0125).min() >= -1e-6
    eps = ev.strain[:, 0]
    assert eps.max() <= min(festo.kmax(pam.resting_length_m, 10), festo.max_contraction(10)) + 1e-6
    assert eps.min() >= -festo.max_pretension(10) - 1e-6
    t = np.linspace(0, 1, 400)
    for a in range(2):
        P = X[:, a:a + 1] + t[None, :, None] * (X[:, a + 1:a + 2] - X[:, a:a + 1])
        d, _ = bones.signed_distance(st, P, margin=None)
        assert d.min() >= -0.002
    own = [bones.body_signed_distance(p.body, np.array([loc]))[0] for p, loc in zip(seed.points, mounted.points)]
    assert all(0.0 <= x <= POINT_MAX + 1e-4 for x in own), own

    # a mount cost the rounds cannot meet, within the rule's reach: tried, refused and named
    cfg_x = cfg.replace({"mount.cost": 0.9 * out["cost"]})
    assert c1 <= 2 * cfg_x.mount.cost
    _, info_x = mount_stage(prob, best, seed, cfg_x, model, rom, solution_pam)
    same, p_x, out_x = mount_rounds(prob, best, info_x, seed, cfg_x, cuts, model, rom, solution_pam)
    assert same is best and p_x is prob and not out_x["mounted"] and not out_x["rounds"]["kept"]
    assert "not kept, fit cost" in out_x["line"]
    # mount_failing / mount_passing: the same rounds' result is kept at that cost where the run's rule gives a
    # reason (asked with the spanning PAM and the mounted one), and the line names it
    asked = []

    def failing(spanning, mounted_pam):
        asked.append((spanning, mounted_pam))
        return "its fit fails both audit fit limits already (test)"

    got, p_f, out_f = mount_rounds(prob, best, info_x, seed, cfg_x, cuts, model, rom, solution_pam, failing)
    assert out_f["mounted"] and out_f["rounds"]["kept"] and out_f["failing_fit"].endswith("(test)")
    assert f"> mount_cost {cfg_x.mount.cost:g}, accepted: its fit fails both" in out_f["line"]
    assert asked and asked[0][0] == solution_pam(seed, prob.finalize(best))
    assert mounted_segment(p_f, got.z) == p_f.mount
    # infeasible on the fixed route: tried only where the PAM overran the segment alone, by <= 10 mm
    for missed, tried in (({"PAM on one segment": 0.004}, True), ({"PAM on one segment": 0.02}, False),
                          ({"PAM on one segment": 0.004, "contraction <= kmax": 0.001}, False), ({}, False)):
        inf = dict(info_x, reason="infeasible", missed=missed)
        _, _, out_i = mount_rounds(prob, best, inf, seed, cfg_x, cuts, model, rom, solution_pam)
        assert ("rounds" in out_i) == tried, missed
    # far below the fixed route's cost: not tried
    cfg_y = cfg.replace({"mount.cost": 0.4 * c1})
    _, info_y = mount_stage(prob, best, seed, cfg_y, model, rom, solution_pam)
    same, p_y, out_y = mount_rounds(prob, best, info_y, seed, cfg_y, cuts, model, rom, solution_pam)
    assert same is best and p_y is prob and "rounds" not in out_y


@pytest.mark.parametrize("case", ["warm", "warm over a limit", "not warm"])
def test_a_warm_start_is_not_traded_for_a_route_over_a_limit(case, monkeypatch):
    """optimize.actuator.bone_rounds: a warm start taken as given (status "given") that keeps every strain and force
    limit at the held-out limit-check poses stays when the rounds' continuation ends over a limit there (and is
    no deeper in bone); a warm start itself over a limit there (check poses beyond its training range), or a
    start that is not a warm one, gives way to the rounds' result as before. The limit check is the real one
    (pamkin.robot.biped at the check poses); the rounds are stubbed to return the route with a PAM stretched past
    Festo's limit."""
    import dataclasses

    from pamkin.optimize import actuator
    from pamkin.optimize.context import RunContext
    from pamkin.optimize.limit_check import limit_excess
    from pamkin.optimize.results import solution_pam

    model, rom, seed, cfg, prob, best, cuts, bones = _mount_toy(10.0)
    q, _ = model.grid(["angle"], 41, rom=rom)
    if case == "warm over a limit":       # check poses far beyond the range it was fitted on
        q, _ = model.grid(["angle"], 41, rom=RangeOfMotion({"angle": (-1.5, 1.5)}))
    start = dataclasses.replace(best, status="given" if case.startswith("warm") else best.status)
    over = best.z.copy()
    over[-2] *= 1.25                      # a longer PAM on the same route: stretched past Festo's pretension
    bad = prob.evaluate(over, best.n_parallel)
    assert limit_excess(solution_pam(seed, prob.finalize(bad)), model, q, cfg, 0.0125)
    assert bool(limit_excess(solution_pam(seed, prob.finalize(start)), model, q, cfg, 0.0125)) == (case == "warm over a limit")

    # (optimize.actuator imports these from optimize.bone_cuts and optimize.limit_check: stubbed where it calls them)
    monkeypatch.setattr(actuator, "bone_check_poses", lambda *a, **k: (q[::4], len(q[::4])))
    monkeypatch.setattr(actuator, "point_contact_poses", lambda *a, **k: np.zeros((0, q.shape[1])))
    monkeypatch.setattr(actuator, "bone_stage", lambda p, s, c, *a, **k: (bad, c.measure(np.array(bad.points)), []))
    monkeypatch.setattr(actuator, "check_poses", lambda *a, **k: q)
    ctx = RunContext(cfg, None, model, rom, bones=bones)
    out, bone, _ = actuator.bone_rounds(ctx, prob, start, seed, cfg.replace({"bone_rounds.seed_start": False}))
    log = "\n".join(bone["log"])
    assert "still exceeded" in log
    if case == "warm":
        assert out is start and "kept the warm start as given" in log
    else:
        assert out is bad and "kept the warm start" not in log
