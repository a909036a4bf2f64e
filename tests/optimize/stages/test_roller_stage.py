"""The optimiser's rollers (:mod:`optimize.roller_model`, :mod:`optimize.rollers`): the smooth segment length
against OpenSim's wrapping (the library's), the problem's torques against the numpy pipeline, placement, and
the stage in a run."""

from __future__ import annotations

import dataclasses
import io
import json
import warnings

import numpy as np
import pytest

import pamkin
from pamkin.audit.measure import random_poses
from pamkin.robot.design import Design, load_design
from pamkin.errors import DataFileError, RangeWarning
from pamkin.optimize.config import FAST_FIT, RunConfig
from pamkin.optimize.context import RunContext
from pamkin.optimize.problem import ActuatorProblem
from pamkin.optimize.results import ActuatorResult
from pamkin.optimize.stages import detours as detour_stage
from pamkin.optimize.stages import rollers as roller_stage
from pamkin.optimize.roller_model import roller_length_numeric
from pamkin.optimize.rollers import depths, place, roller_data
from pamkin.optimize.samples import actuator_data
from pamkin.robot.pam_body import route_positions
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.robot.rollers import Roller, roller_frame
from pamkin.human.rom import load_rom

#: A roller behind the femur on biceps femoris long head's pelvis-tibia segment (thesis route): the cable
#: wraps at most random poses (not all).
BFLH_ROLLER = Roller("p1->p2", "femur_r", (-0.06, -0.1, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0), 0.008, 0.06)


@pytest.fixture(scope="module")
def skel():
    return robot_skeleton()


def _ends_in_roller_frame(skel, pam, roller, q):
    robot = PamRobot(Design("t", (dataclasses.replace(pam, rollers=()),)), skel, sides=("r",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        ks = skel.kinematics.forward(q, warn_range=False)
    pts = route_positions(robot.paths, ks, 0)
    b = skel.kinematics.frames.index(roller.body)
    Rw = np.einsum("sij,jk->sik", ks.body_R[:, b], roller_frame(roller))
    c = ks.body_p[:, b] + ks.body_R[:, b] @ np.asarray(roller.centre)
    return np.einsum("sik,si->sk", Rw, pts[:, 0] - c), np.einsum("sik,si->sk", Rw, pts[:, 1] - c), ks, pts


def test_smooth_length_matches_opensim_wrapping(skel):
    """The optimiser's geodesic over the roller against OpenSim's WrapCylinder (the library's lengths) on 500
    random poses: the same poses wrap but for a few at the roller's ends (OpenSim's tangent points are its own
    construction), and where both wrap the lengths agree to 0.05 mm; unwrapped, exactly."""
    pam = load_design("thesis").pam(4)
    q = random_poses(skel, load_rom("robot_thesis", "r"), 500, 3)
    a, b, ks, pts = _ends_in_roller_frame(skel, pam, BFLH_ROLLER, q)
    model = roller_length_numeric(a, b, BFLH_ROLLER.radius_m, BFLH_ROLLER.length_m)
    lib = PamRobot(Design("t", (dataclasses.replace(pam, rollers=(BFLH_ROLLER,)),)), skel, sides=("r",))
    opensim = lib.segment_lengths(ks, 0)[:, 0]
    straight = np.linalg.norm(pts[:, 1] - pts[:, 0], axis=1)
    w_os, w_model = opensim > straight + 1e-12, model > straight + 1e-12
    assert 0.2 < w_os.mean() < 0.95 and (~w_os).sum() > 25
    assert np.mean(w_os != w_model) < 0.02
    both = w_os & w_model
    print(f"\nsmooth roller length vs OpenSim's: {np.mean(w_os != w_model):.1%} of poses wrap in one only; "
          f"where both wrap max |difference| {np.max(np.abs(model[both] - opensim[both])):.2e} m")
    assert np.max(np.abs(model[both] - opensim[both])) < 5e-5
    np.testing.assert_allclose(model[~w_os & ~w_model], straight[~w_os & ~w_model], atol=1e-12)


def test_problem_with_a_roller_matches_the_numpy_pipeline(skel):
    """The CasADi problem with a roller — its route length and moment arms (−∂L/∂q through the roller's own
    motion; torque ÷ force) — against the library's (OpenSim's wrapping, central differences) at every
    objective sample of biceps femoris long head: the same where the cable does not wrap, within the two
    lengths' small difference where it does."""
    import casadi as ca

    human = pamkin.gait2392()
    pam = load_design("thesis").pam(4)
    cfg = RunConfig().replace({**FAST_FIT})
    data = actuator_data(pam, human, load_rom("robot_thesis", "r"), cfg, 0.0125)
    seed = [np.array(p.location) for p in pam.points]
    regions = [np.array(cfg.region(4, p.name)) for p in pam.points]
    roller = dataclasses.replace(BFLH_ROLLER, centre=(-0.045, -0.05, 0.0045))     # wraps at a third of them
    prob = ActuatorProblem(data, cfg, 20, seed, regions, rollers=[roller_data(data, human, roller, 0)])
    z = prob.initial_guess(seed, pam.resting_length_m, pam.tendon_length_m)
    sol = prob._solution(z, 0.0, "check", True, 0.0, 1)
    L = np.asarray(ca.Function("L", [prob.z], [prob.L])(z)).ravel()
    F = np.asarray(ca.Function("F", [prob.z, prob.npar], [prob.force])(z, 1)).ravel()
    robot = PamRobot(Design("t", (dataclasses.replace(pam, rollers=(roller,)),)), skel, sides=("r",))
    plain = PamRobot(Design("t", (pam,)), skel, sides=("r",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st, st0 = robot.evaluate(data.q), plain.evaluate(data.q)
    wraps = np.abs(st.lengths[:, 0] - st0.lengths[:, 0]) > 1e-12
    assert wraps.sum() > 20 and (~wraps).sum() > 50
    np.testing.assert_allclose(L[~wraps], st.lengths[~wraps, 0], atol=1e-12)
    assert np.max(np.abs(L[wraps] - st.lengths[wraps, 0])) < 5e-5
    worst_free, worst = 0.0, 0.0
    for c, rows, _, _, label in data.objective:
        ci = robot.coordinates.index(c)
        ok = np.abs(F[rows]) > 1.0
        r_casadi = sol.torque_samples[label][ok] / F[rows][ok]
        diff = np.abs(r_casadi - st.moment_arms[rows, 0, ci][ok])
        worst_free = max(worst_free, float(diff[~wraps[rows][ok]].max(initial=0.0)))
        worst = max(worst, float(diff.max(initial=0.0)))
    print(f"\nCasADi roller moment arms vs the library's: unwrapped {worst_free:.1e} m, all {worst:.1e} m")
    assert worst_free < 1e-8            # metres
    assert worst < 2e-4, worst


def test_placement_lifts_a_route_off_the_bone(skel):
    """A straight line through the femoral shaft (both ends on the femur): the roller placed at its deepest
    point carries it clear of the bone, on the bone, within a bracket of it."""
    from pamkin.human.bones import BoneSet
    from pamkin.robot.design import Pam
    from pamkin.opensim.model_file import PathPoint

    bones = BoneSet(skel)
    pam = Pam(1, "toy", ("bifemsh_r",), "knee_angle_r", (), 20, 1, 0.02, 0.0,
              (PathPoint("a", "femur_r", (0.025, -0.20, 0.03)), PathPoint("b", "femur_r", (0.025, -0.30, -0.03))))
    q = np.zeros((1, len(skel.coordinates)))
    des = Design("toy", (pam,))
    before = depths(pam, skel, bones, q, des)
    assert before.segment_depth[0] > 0.003
    rol = place(bones, skel, q, pam, 0, before.deepest[0])
    assert rol is not None and rol.segment == "a->b" and rol.body == "femur_r"
    after = depths(dataclasses.replace(pam, rollers=(rol,)), skel, bones, q, des)
    assert after.segment_depth[0] < before.segment_depth[0]
    assert 0.0 <= after.roller_bone[0] <= 0.005


def test_bone_cuts_leave_out_the_segments_a_roller_guides(skel):
    """BoneCuts.skip: a skipped segment has no samples, no rows and no depth; the others are measured as
    before (the straight femur toy through the shaft, followed by a clear segment)."""
    from pamkin.human.bones import BoneSet
    from pamkin.robot.design import Pam
    from pamkin.optimize.bone_cuts import BoneCuts
    from pamkin.opensim.model_file import PathPoint

    bones = BoneSet(skel)
    pts = (PathPoint("a", "femur_r", (0.025, -0.20, 0.03)), PathPoint("b", "femur_r", (0.025, -0.30, -0.03)),
           PathPoint("c", "femur_r", (0.06, -0.30, -0.03)))
    pam = Pam(1, "toy", ("bifemsh_r",), "knee_angle_r", (), 20, 1, 0.02, 0.0, pts)
    cuts = BoneCuts(pam, skel, bones, np.zeros((2, len(skel.coordinates))))
    loc = np.array([p.location for p in pts])
    m, (W, _) = cuts.measure(loc, with_rows=True)
    assert m.segment_depth[0] > 0.003
    cuts.skip = {0}
    m2, (W2, _) = cuts.measure(loc, with_rows=True)
    assert m2.segment_depth[0] < 0 and m2.segment_depth[1] == pytest.approx(m.segment_depth[1])
    segment_rows = W2[cuts.n_point_rows:]
    assert len(segment_rows) < len(W) - cuts.n_point_rows
    assert not np.any(segment_rows[:, 0:3])          # no row moves point a (only segment a->b touches it)
    cuts.skip = {0, 1}                               # every segment guided: the points' rows only
    m3, (W3, _) = cuts.measure(loc, with_rows=True)
    assert np.all(m3.segment_depth < 0) and len(W3) == cuts.n_point_rows


#: Internal oblique as the default run (0.1.0-dev) left it: clear of bone, NRMSE / worst 0.19 / 0.28 on the
#: optimiser's validation poses (both audit fit limits failed).
INTERNAL_OBLIQUE = {
    "id": 2, "name": "Internal Oblique", "human_muscles": ["intobl_r"], "primary_coordinate": "lumbar_extension",
    "secondary_coordinates": ["lumbar_bending"], "diameter_mm": 20, "n_parallel": 2,
    "resting_length_m": 0.2579140425458323, "tendon_length_m": 0.0,
    "points": [{"type": "PathPoint", "name": "p1", "body": "pelvis",
                "location": [-0.07903907909827204, 0.0445910310939152, 0.06190036330941283]},
               {"type": "PathPoint", "name": "p2", "body": "torso",
                "location": [0.0961037602067311, 0.21000000689523302, 0.01599999013826773]}]}


def _stage(stage, ctx: RunContext, results: list, cfg: RunConfig, stream) -> list:
    """``stage.run`` on ``results`` with the run's config ``cfg`` and progress on ``stream`` (read from ``ctx``)."""
    ctx.cfg, ctx.stream = cfg, stream
    return stage.run(ctx, results)


def _internal_oblique_result(monkeypatch):
    """The run's context for the roller stage of internal oblique alone (default config with rollers, one
    worker) and its finished result (:data:`INTERNAL_OBLIQUE`) as a given result: (run context, cfg, result,
    human model, seed design, actuator data)."""
    from pamkin.human.bones import BoneSet
    from pamkin.robot.design import design_from_dict

    human = pamkin.gait2392()
    rom = load_rom("robot_thesis", "r")
    seed_design = load_design("v2_seed", bodies=human.bodies)
    final = design_from_dict({"pams": [INTERNAL_OBLIQUE]}, "io", human.bodies).pams[0]
    cfg = RunConfig().replace({"rollers.enabled": True, "workers": 1})
    data = [actuator_data(seed_design.pam(2), human, rom, cfg, seed_design.fitting_length_m)]
    ctx = RunContext(cfg, seed_design, human, rom, data=data, validation=None, bones=BoneSet(human))
    seed, regions = ctx.route_box(seed_design.pam(2))
    prob = ActuatorProblem(data[0], cfg, 20, seed, regions)
    z = prob.initial_guess([np.array(p.location) for p in final.points], final.resting_length_m,
                           final.tendon_length_m)
    given = ActuatorResult(2, final.name, final, "given", True, z=z, relaxed=["one_segment"], n_parallel=2,
                           bone={"log": []})
    return ctx, cfg, given, human, seed_design, data


def test_roller_stage_on_internal_oblique(skel, monkeypatch, tmp_path):
    """The stage on internal oblique's finished result (the default config's problem, one worker): its fit
    without the bone rows passes 3 mm through the pelvis, so a roller goes there; open-ended in the fit, the
    roller must then be 80 mm long to keep the cable at every check pose, which puts it 5.5 mm into the
    pelvis, and moved out the fit is lost: the result stays without a roller, saying why (0.1.0-dev; before,
    a 30 mm roller whose cable slipped off its end at 29 % of random poses was kept for a gain that was
    mostly that slip). A result that passes both fit limits is left alone; in a warm re-run, one its warm
    start's run tried without a gain is not tried again (and the outcome carried on), and a broken warm
    summary is a clear error; a roller that leaves the route in bone and fits no better gets no second
    placement round."""
    ctx, cfg, given, human, seed_design, data = _internal_oblique_result(monkeypatch)
    progress = io.StringIO()
    out = _stage(roller_stage, ctx, [given], cfg, progress)[0]
    assert "rollers: 1 actuators fail a fit limit" in progress.getvalue()
    log = out.bone["log"]
    assert log[-3].endswith("deepest piece 0.0 mm, rollers -5.5 mm off bone, 80 mm long"), log
    assert log[-1] == "    kept without rollers: no clear route with rollers" and out.pam is given.pam
    assert out.bone["roller_stage"] == "without rollers: no clear route with rollers"
    # a result that passes both fit limits is not tried
    import pamkin.optimize.context as context_mod
    strict = context_mod.load_limits
    loose = strict()
    loose["thresholds"] = dict(loose["thresholds"], nrmse_good=1.0, worst_coordinate_error_good=1.0)
    monkeypatch.setattr(context_mod, "load_limits", lambda *a, **k: loose)
    assert _stage(roller_stage, ctx, [given], cfg, progress)[0] is given
    monkeypatch.setattr(context_mod, "load_limits", strict)
    # a warm re-run: what the warm start's run did with it decides (tried there without a gain: not again)
    assert roller_stage.warm_roller_outcomes(tmp_path) == {}                       # no summary: as a cold run
    (tmp_path / "summary.json").write_text(json.dumps({"bone_mesh": {"2": {"roller_stage": "kept"}}}))
    assert roller_stage.warm_roller_outcomes(tmp_path) == {2: "kept"}
    why = "without rollers: no clear route with rollers"
    (tmp_path / "summary.json").write_text(json.dumps({"bone_mesh": {"2": {"roller_stage": why}, "3": {}}}))
    assert roller_stage.warm_roller_outcomes(tmp_path) == {2: why}
    warm_cfg = RunConfig().replace({"rollers.enabled": True, "workers": 1, "warm_start": str(tmp_path)})
    ctx.warm_ids = {2}
    progress = io.StringIO()
    again = _stage(roller_stage, ctx, [given], warm_cfg, progress)[0]
    assert "not tried again (the warm start's run tried them without a gain): 2 Internal Oblique" in \
        progress.getvalue() and "trying rollers" not in progress.getvalue()
    assert again.pam is given.pam and again.bone["roller_stage"] == why and "not tried again" in again.bone["log"][-1]
    ctx.warm_ids = set()                                               # not a warm-started actuator: tried
    (tmp_path / "summary.json").write_text("{not json")
    with pytest.raises(DataFileError, match="summary.json"):
        roller_stage.warm_roller_outcomes(tmp_path)
    # a roller that leaves the route in bone and fits no better than the result without it: no second round
    import pamkin.optimize.rollers as rollers_mod
    real = rollers_mod.depths

    def deeper(pam, *a, **k):          # every piece 5 mm deeper than it is where the route has rollers
        d = real(pam, *a, **k)
        return dataclasses.replace(d, segment_depth=d.segment_depth + 0.005) if pam.rollers else d

    monkeypatch.setattr(rollers_mod, "depths", deeper)
    worse = _stage(roller_stage, ctx, [dataclasses.replace(given, objective=0.05)], cfg, io.StringIO())[0]
    assert not worse.pam.rollers and worse.bone["log"][-2].endswith("round 1: objective 0.06073, deepest piece "
                                                                    "5.0 mm, rollers -5.5 mm off bone, 80 mm long"), \
        worse.bone["log"]
    assert worse.bone["roller_stage"] == ("without rollers: with rollers the route is not clear and fits no better "
                                          "(objective 0.05 -> 0.06073)")


#: Internal oblique as the 0.1.0-dev default run left it, with the 30 mm roller that run kept.
INTERNAL_OBLIQUE_ROLLED = {
    **INTERNAL_OBLIQUE, "resting_length_m": 0.24646414314348644, "tendon_length_m": 1.2305198846033187e-06,
    "points": [{"type": "PathPoint", "name": "p1", "body": "pelvis",
                "location": [-0.08572310464362938, 0.04273938110192771, 0.05685518766042528]},
               {"type": "PathPoint", "name": "p2", "body": "torso",
                "location": [0.08949312835033706, 0.20307784434036322, 0.01600053089388801]}],
    "rollers": [{"segment": "p1->p2", "body": "pelvis",
                 "centre": [-0.07062969414115322, 0.07214076162387521, 0.06443033662732293],
                 "axis": [-0.45461476876856516, 0.11513930178919912, -0.8832147831648879],
                 "side": [0.8827652958842764, -0.07372193523569882, -0.46399408255650115],
                 "radius_m": 0.005, "length_m": 0.03}]}


def test_size_rollers_keeps_the_cable_on_the_roller():
    """The 0.1.0-dev default run's internal oblique roller (30 mm): along lumbar extension (others 0) the cable
    slips off its end at 5.1 deg (OpenSim's rule: no wrap once both tangent points lie beyond the ends), a step
    of 0.68 mm in the route and of 28 -> 23 mm in the moment arm; on random poses the route is shorter than
    over an open roller at many of them. size_rollers gives it the shortest length that keeps the cable
    (50 mm, measured): the route is then the open roller's at every pose, without the step."""
    from pamkin.robot.design import design_from_dict
    from pamkin.optimize.rollers import size_rollers
    from pamkin.robot.rollers import OPEN_LENGTH_M

    human = pamkin.gait2392()
    rom = load_rom("robot_thesis", "r")
    des = load_design("v2_seed", bodies=human.bodies)
    pam = design_from_dict({"pams": [INTERNAL_OBLIQUE_ROLLED]}, "io", human.bodies).pams[0]

    def lengths(p, q):
        d = Design("x", (p,), des.pressure_Pa, des.force_model, des.fitting_length_m, des.rom)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            return PamRobot(d, human, sides=("r",)).evaluate(q).lengths[:, 0]

    c = human.coordinates.index("lumbar_extension")
    q = np.zeros((201, len(human.coordinates)))
    q[:, c] = np.radians(np.linspace(0.0, 10.0, 201))
    steps = np.abs(np.diff(lengths(pam, q)))
    assert steps.max() == pytest.approx(6.8e-4, abs=0.5e-4) and 1e3 * steps.max() > 20 * np.median(steps) * 1e3
    qr = random_poses(human, rom, 300, 11)
    open_ = dataclasses.replace(pam, rollers=(dataclasses.replace(pam.rollers[0], length_m=OPEN_LENGTH_M),))
    slipped = np.abs(lengths(pam, qr) - lengths(open_, qr)) > 1e-9
    assert 0.1 < slipped.mean() < 0.5
    sized = size_rollers(pam, human, np.concatenate([q, qr]), des)
    assert sized.rollers[0].length_m == 0.05 and sized.rollers[0].centre == pam.rollers[0].centre
    assert np.abs(lengths(sized, qr) - lengths(open_, qr)).max() <= 1e-9
    assert np.abs(np.diff(lengths(sized, q))).max() < 3 * np.median(np.abs(np.diff(lengths(sized, q))))


def test_detour_pass_measures_a_rollered_segment_round_its_roller(monkeypatch):
    """The detour pass re-checks a route after its detours against every bone: a segment with a roller is
    measured on its straight pieces round the roller (as the roller stage's exact check), not as the straight
    line the roller lifts out of the bone. The femoral-shaft toy with its roller; a stand-in detour that
    changes nothing makes the pass measure it."""
    from pamkin.human.bones import BoneSet
    from pamkin.robot.design import Pam
    from pamkin.optimize.bone_cuts import bone_check_poses
    from pamkin.opensim.model_file import PathPoint

    human = pamkin.gait2392()
    rom = load_rom("robot_thesis", "r")
    seed_design = load_design("v2_seed", bodies=human.bodies)
    cfg = RunConfig().replace({"workers": 1})
    data = [actuator_data(seed_design.pam(10), human, rom, cfg, seed_design.fitting_length_m)]
    bones = BoneSet(human)
    ctx = RunContext(cfg, seed_design, human, rom, data=data, bones=bones)
    pam = Pam(10, "toy", ("bifemsh_r",), "knee_angle_r", (), 20, 1, 0.02, 0.0,
              (PathPoint("a", "femur_r", (0.025, -0.20, 0.03)), PathPoint("b", "femur_r", (0.025, -0.30, -0.03))))
    q, n_right = bone_check_poses(human, rom, data[0].pam, cfg.seed, crossed=data[0].crossed)
    straight = depths(pam, human, bones, q, seed_design, n_right).segment_depth[0]
    rol = place(bones, human, q[:1], pam, 0, depths(pam, human, bones, q[:1], seed_design).deepest[0])
    rolled = dataclasses.replace(pam, rollers=(rol,))
    guided = depths(rolled, human, bones, q, seed_design, n_right).segment_depth[0]
    assert straight > 0.003 and guided < 0.5 * straight           # the roller lifts it most of the way out
    # (the detour stage imports these from pamkin.robot.detour: stubbed where it calls them)
    monkeypatch.setattr(detour_stage, "same_body_segments", lambda p: [0])
    monkeypatch.setattr(detour_stage, "detour_pam", lambda p, *a, **k: (p, {0: "stand-in"}))
    given = ActuatorResult(10, "toy", rolled, "given", True, z=np.zeros(1), bone={"log": []})
    out = _stage(detour_stage, ctx, [given], cfg, io.StringIO())[0]
    assert out.bone["detours"] == {"a->b": "stand-in"}
    assert out.bone["max_segment_penetration_mm"] == pytest.approx(1e3 * guided, abs=0.5)


def test_audit_names_a_roller_that_loses_its_cable():
    """The audit compares each rollered route with the same route over open-ended rollers at its random poses:
    the 0.1.0-dev internal oblique roller (30 mm) loses the cable at a share of them, named on the scorecard;
    sized to 50 mm it never does (no line)."""
    from pamkin.audit.measure import AuditOptions, audit_design
    from pamkin.audit.scorecard import scorecard_text as scorecard
    from pamkin.robot.design import design_from_dict

    human = pamkin.gait2392()
    pam = design_from_dict({"pams": [INTERNAL_OBLIQUE_ROLLED]}, "io", human.bodies).pams[0]
    opts = AuditOptions(n_random=200, gait_ik=None, gait_plan=False, n_geometry=10, n_sweep=5, n_grid=3,
                        segment_step_m=0.01)
    res = audit_design(Design("io", (pam,), rom="robot_thesis"), options=opts)
    share = res.pams[0]["roller_cable_off_fraction"]
    assert 0.1 < share < 0.5
    assert "cable off a roller's end" in scorecard(res) and f"2 Internal Oblique {100 * share:.1f} %" in scorecard(res)
    long = dataclasses.replace(pam, rollers=(dataclasses.replace(pam.rollers[0], length_m=0.05),))
    res = audit_design(Design("io", (long,), rom="robot_thesis"), options=opts)
    assert res.pams[0]["roller_cable_off_fraction"] == 0.0 and "cable off a roller" not in scorecard(res)


def test_roller_stage_keeps_a_roller_that_clears_and_fits_better(skel, monkeypatch):
    """The stage's "kept" path, on internal oblique's result: with the exact bone check made to report the
    rollered route clear (pieces, points and roller within their limits) and the roller left at its placed
    30 mm, the route re-solved over it fits the validation poses better than the result (NRMSE + worst falls by
    more than MIN_GAIN), so the result is the rollered one: its PAM carries the roller on the segment the fit
    put into bone, its route is the re-solved one, its bone summary names the roller, and the log ends with the
    gain. (No actuator of the default run keeps a roller since 0.1.0-dev; this checks the bookkeeping.)"""
    import pamkin.optimize.rollers as rollers_mod
    from pamkin.optimize.validation import validation_error

    ctx, cfg, given, human, seed_design, data = _internal_oblique_result(monkeypatch)
    real = rollers_mod.depths

    def clear(pam, *a, **k):           # the rollered route reported clear of bone, its roller 5 mm off it
        d = real(pam, *a, **k)
        if not pam.rollers:
            return d
        return dataclasses.replace(d, segment_depth=np.zeros_like(d.segment_depth),
                                   point_bone=np.clip(d.point_bone, 0.003, 0.018),
                                   roller_bone=np.full(len(pam.rollers), 0.005))

    monkeypatch.setattr(rollers_mod, "depths", clear)
    monkeypatch.setattr(rollers_mod, "size_rollers", lambda pam, *a, **k: pam)
    out = _stage(roller_stage, ctx, [given], cfg, io.StringIO())[0]
    log = out.bone["log"]
    assert log[-1] == "    kept with rollers", log
    assert out.bone["roller_stage"] == "kept" and out.bone["rollers"] == ["p1->p2"]
    (rol,) = out.pam.rollers
    assert rol.segment == "p1->p2" and rol.body == "pelvis" and rol.length_m == rollers_mod.LENGTH
    assert out.pam.resting_length_m != given.pam.resting_length_m or \
        any(a.location != b.location for a, b in zip(out.pam.points, given.pam.points))
    assert out.attempts[-1]["start"] == "roller stage" and out.attempts[-1]["feasible"]
    # the gain the log reports is the validation error's, recomputed independently
    q, T = ctx.validation_set()
    before = validation_error(given.pam, human, q, T, list(data[0].crossed), seed_design)
    after = validation_error(out.pam, human, q, T, list(data[0].crossed), seed_design)
    assert sum(after) < sum(before) - rollers_mod.MIN_GAIN
    assert log[-2] == (f"    validation NRMSE / worst {before[0]:.3f} / {before[1]:.3f} -> {after[0]:.3f} / "
                       f"{after[1]:.3f} with rollers")
