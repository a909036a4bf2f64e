"""Racks (pamkin.robot.rack) and the rack layout (pamkin.optimize.rack_layout): a rack changes no moment arm
and no PAM length; two toy PAMs whose routes coincide end on racks apart by the gap; a toy body keeps the gap
from a toy bone; the capstan factor by hand."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
import trimesh

from pamkin.audit.assembly import BODY_GAP_M, body_distances, body_radius, bone_clearance
from pamkin.human.bones import BoneSet
from pamkin.opensim.model_file import PathPoint
from pamkin.optimize.rack_layout import candidates, layout
from pamkin.robot.biped import PamRobot, placements, robot_skeleton
from pamkin.robot.design import Design, load_design
from pamkin.robot.pam_body import pam_capsules
from pamkin.robot.rack import RackMount, capstan_efficiency, has_rack, rack_pam, turn_angle


@pytest.fixture(scope="module")
def skel():
    return robot_skeleton()


def _poses(skel, n: int, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = np.tile(skel.default_q, (n, 1))
    for c, lo, hi in (("knee_angle_r", -1.5, 0.0), ("ankle_angle_r", -0.5, 0.35), ("hip_flexion_r", -0.3, 1.2),
                      ("subtalar_angle_r", -0.3, 0.3)):
        q[:, skel.coordinates.index(c)] = rng.uniform(lo, hi, n)
    return q


def test_a_rack_changes_no_moment_arm_and_no_pam_length(skel):
    """Tibialis anterior of the thesis design hung on a rack on the tibia: at 40 random poses its route is
    longer by the two constant pieces, its PAM length, strain and torques about every coordinate are equal to
    1e-12; the body lies on the anchor–guide piece from the anchor."""
    des = load_design("thesis")
    pam = des.pam(16)
    g = np.asarray(pam.points[0].location)
    span = pam.resting_length_m + 2 * des.fitting_length_m + 0.02
    mount = RackMount("origin", "tibia_r", tuple(g + [0.04, -0.01 - span, 0.0]), tuple(g + [0.04, -0.01, 0.0]))
    racked = rack_pam(pam, mount)
    assert has_rack(racked) and racked.pam_on == "rack.anchor->rack.guide" and racked.pam_at == "origin"
    extra = span + math.hypot(0.04, 0.01)
    assert racked.tendon_length_m == pytest.approx(pam.tendon_length_m + extra, abs=1e-15)
    q = _poses(skel, 40)
    a = PamRobot(Design("a", (pam,)), skel, sides=("r",)).evaluate(q)
    b = PamRobot(Design("b", (racked,)), skel, sides=("r",)).evaluate(q)
    np.testing.assert_allclose(b.lengths - a.lengths, extra, atol=1e-12)
    np.testing.assert_allclose(b.pam_lengths, a.pam_lengths, atol=1e-12)
    np.testing.assert_allclose(b.torques, a.torques, atol=1e-9)
    place, pts, _ = placements(Design("b", (racked,)), skel, q)[0]
    assert place.segment == 0 and place.side == "origin" and place.on_one_segment
    with pytest.raises(ValueError, match="already hangs on a rack"):
        rack_pam(racked, mount)
    with pytest.raises(ValueError, match="not a fixed point of 'femur_r'"):
        rack_pam(pam, dataclasses.replace(mount, host="femur_r"))


def test_capstan_by_hand():
    """A right-angle turn: π/2; e^(−0.1·π/2) = 0.8546 at μ = 0.1; straight: 1."""
    assert turn_angle([0, 0, 0], [1, 0, 0], [1, 1, 0]) == pytest.approx(math.pi / 2)
    assert capstan_efficiency(math.pi / 2, 0.1) == pytest.approx(0.854636, abs=1e-6)
    assert capstan_efficiency(0.0, 0.3) == 1.0
    with pytest.raises(ValueError):
        capstan_efficiency(1.0, -0.1)


def _toy_bone():
    """A 20 mm radius cylinder of bone along the tibia's y axis, 0.35 m long, centred 0.2 m below the knee."""
    cyl = trimesh.creation.cylinder(radius=0.02, height=0.35, sections=48)
    cyl.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    cyl.apply_translation([0.0, -0.2, 0.0])
    return cyl


def _toy_pair(skel, rom: str | None = None):
    """The toy tibia (:func:`_toy_bone`) as the only bone, and two 20 mm PAMs on one route from 25 mm off it to
    the calcaneus (their bodies coincide on it): ``(bones, design)``."""
    cyl = _toy_bone()
    bones = BoneSet.from_meshes(skel, {"tibia_r": [(cyl.vertices, cyl.faces)]})
    route = (PathPoint("p1", "tibia_r", (0.025, -0.12, 0.0)), PathPoint("p2", "calcn_r", (0.1, 0.03, 0.0)))
    base = load_design("thesis").pam(16)
    pams = tuple(dataclasses.replace(base, id=i, name=f"toy {i}", points=route, resting_length_m=0.15,
                                     tendon_length_m=0.2, rollers=(), pam_on=None, pam_at=None) for i in (1, 2))
    kw = {"rom": rom} if rom else {}
    return bones, Design("toy", pams, fitting_length_m=0.0125, **kw)


def test_two_toy_pams_forced_together_end_apart(skel):
    """Two 20 mm PAMs with the same route (tibia → calcaneus, both starting 25 mm off a toy tibia): on their
    routes their bodies coincide. The layout hangs both on racks: at every pose their bodies are ≥ 5 mm
    apart and ≥ 5 mm from the toy bone (measured with the audit's own functions), their brackets within
    50 mm of it, and their torques unchanged."""
    bones, des = _toy_pair(skel)
    q = _poses(skel, 30)
    before = placements(des, skel, q)
    caps = [pam_capsules(pts, pl.segment, L + 0.025, pl.side) for pl, pts, L in before]
    r = body_radius(20)
    assert np.min(body_distances(caps[0], caps[1], r, r)) < 0           # forced into each other
    new, rep = layout(des, skel, bones, q, q[:0], angles=12, time_limit=30)
    assert sorted(rep.placed) == [1, 2] and rep.unplaced == []
    after = placements(new, skel, q)
    st = skel.kinematics.forward(q, warn_range=False)
    caps = [pam_capsules(pts, pl.segment, L + 0.025, pl.side) for pl, pts, L in after]
    assert all(pl.on_one_segment for pl, _, _ in after)
    assert np.min(body_distances(caps[0], caps[1], r, r)) >= BODY_GAP_M - 1e-9
    for c in caps:
        clear, _ = bone_clearance(bones, st, c, r, step=0.002, reach=0.05)
        assert np.min(clear) >= BODY_GAP_M - 1e-9
    for p in new.pams:
        for pt in p.points[:2]:
            d = bones.body_signed_distance("tibia_r", np.array([pt.location]))[0]
            assert 0 < d <= 0.05
    a = PamRobot(des, skel, sides=("r",)).evaluate(q)
    b = PamRobot(new, skel, sides=("r",)).evaluate(q)
    np.testing.assert_allclose(b.torques, a.torques, atol=1e-9)


def test_a_body_that_cannot_clear_the_bone_gets_no_candidate(skel):
    """Brackets at most 10 mm from the toy bone cannot hold a 15 mm-radius body 5 mm clear of it: no
    candidate; at 50 mm there are some, every one clear of the bone by the gap."""
    cyl = _toy_bone()
    bones = BoneSet.from_meshes(skel, {"tibia_r": [(cyl.vertices, cyl.faces)]})
    route = (PathPoint("p1", "tibia_r", (0.025, -0.12, 0.0)), PathPoint("p2", "calcn_r", (0.1, 0.03, 0.0)))
    pam = dataclasses.replace(load_design("thesis").pam(16), points=route, resting_length_m=0.15, rollers=())
    assert candidates(0, pam, "origin", bones, 0.0125, bracket_max=0.010) == []
    got = candidates(0, pam, "origin", bones, 0.0125, bracket_max=0.05)
    assert got
    for c in got:
        t = np.linspace(0, 1, 50)[:, None]
        d = bones.body_signed_distance("tibia_r", c.a + t * (c.b - c.a))
        assert np.min(d) >= c.radius + BODY_GAP_M


def test_rack_config_section():
    from pamkin.errors import DataFileError
    from pamkin.optimize.config import RunConfig

    cfg = RunConfig()
    assert cfg.rack.enabled and cfg.rack.gap_m == 0.005 and cfg.rack.bracket_max_m == 0.05     # on by default
    assert RunConfig().replace({"rack.enabled": True, "rack.angles": 8}).rack.angles == 8
    with pytest.raises(DataFileError, match="rack.angles"):
        RunConfig().replace({"rack.angles": 2})


def test_the_pipeline_stage_racks_the_toy_pams(skel):
    """The declared stage (last before the check, on by default, ``[rack] enabled``) on the two toy PAMs as a
    run's results: both come back on racks on the tibia, and the report says so."""
    import io
    from types import SimpleNamespace

    from pamkin.human.rom import load_rom
    from pamkin.optimize.config import RunConfig
    from pamkin.optimize.pipeline import STAGES
    from pamkin.optimize.results import ActuatorResult
    from pamkin.optimize.stages import rack as stage

    names = [s.name for s in STAGES]
    assert names[-1] == "rack"
    on = RunConfig().replace({"rack.enabled": True, "rack.poses": 10, "rack.check_poses": 40, "rack.gait": False,
                              "rack.angles": 8})
    assert STAGES[-1].enabled(on) and STAGES[-1].enabled(RunConfig())
    assert not STAGES[-1].enabled(RunConfig().replace({"rack.enabled": False}))
    assert not STAGES[-1].enabled(RunConfig().replace({"bone_rounds.enabled": False}))     # needs the meshes
    bones, seed = _toy_pair(skel, rom="robot_thesis")
    results = [ActuatorResult(p.id, p.name, p, "Solve_Succeeded", True) for p in seed.pams]
    ctx = SimpleNamespace(cfg=on, seed_design=seed, human=skel, rom=load_rom(seed.rom, "r"), bones=bones,
                          stream=io.StringIO(), rack=[])
    out = stage.run(ctx, results)
    assert all(has_rack(r.pam) for r in out)
    assert ctx.rack[0].startswith("rack: 2 of 2 PAMs hung on racks") and "left on their routes: none" in ctx.rack[0]
    for line, r in zip(ctx.rack[1:], out):
        m = re.fullmatch(rf"rack: actuator {r.id} toy {r.id} on tibia_r at its origin, bracket [0-9.]+ mm; cable "
                         r"turns ([0-9]+) deg at the guide and up to ([0-9]+) deg at the route's end: capstan factor "
                         r"([0-9.]+) at mu = 0.03, in its force \(cable_efficiency\)", line)
        assert m, line
        turns = np.radians(int(m[1]) + int(m[2]))
        assert float(m[3]) == pytest.approx(np.exp(-0.03 * turns), abs=2e-3)       # capstan, by hand
        assert r.pam.cable_efficiency == pytest.approx(float(m[3]), abs=1e-3) and r.pam.cable_efficiency < 1
    # the route's tension (and so every torque) is the PAM's force times it
    q = _poses(skel, 5)
    plain = PamRobot(Design("p", tuple(dataclasses.replace(r.pam, cable_efficiency=1.0) for r in out)), skel,
                     sides=("r",)).evaluate(q)
    with_loss = PamRobot(Design("f", tuple(r.pam for r in out)), skel, sides=("r",)).evaluate(q)
    np.testing.assert_allclose(with_loss.torques, plain.torques * np.array([r.pam.cable_efficiency for r in out])
                               [None, :, None], rtol=1e-12, atol=1e-12)


def test_only_the_movable_pams_move_and_the_others_are_obstacles(skel):
    """Two toy PAMs on one route; only the second may move: it ends on a rack ≥ 5 mm from the first one's body,
    which stays on its route."""
    bones, des = _toy_pair(skel)
    q = _poses(skel, 20)
    new, rep = layout(des, skel, bones, q, q[:0], angles=12, time_limit=30, movable={2})
    assert list(rep.placed) == [2] and rep.unplaced == [] and not has_rack(new.pam(1)) and has_rack(new.pam(2))
    caps = [pam_capsules(pts, pl.segment, L + 0.025, pl.side) for pl, pts, L in placements(new, skel, q)]
    r = body_radius(20)
    assert np.min(body_distances(caps[0], caps[1], r, r)) >= BODY_GAP_M - 1e-9


def test_the_choice_by_hand():
    """Three PAMs, four candidates, two conflicts that forbid placing all three: the integer program places two
    with the lower brackets (PAM 0 on its 10 mm candidate, PAM 2); the greedy fallback places two without a
    conflict; a candidate in conflict with its own mirror image is never chosen."""
    from pamkin.optimize.rack_layout import Candidate, _greedy, choose

    m = RackMount("origin", "tibia_r", (0, 0, 0), (0, 0, 0.1))
    z = np.zeros(3)
    cands = [Candidate(0, m, 0.01, z, z, 0.010), Candidate(0, m, 0.01, z, z, 0.020),
             Candidate(1, m, 0.01, z, z, 0.030), Candidate(2, m, 0.01, z, z, 0.030)]
    pairs = np.array([[0, 2], [1, 3]])
    pick = choose(cands, pairs, 3)
    assert set(pick) == {0, 2} and pick[0] is cands[0]
    g = _greedy(cands, pairs, np.ones(4))
    chosen = {id(c) for c in g.values()}
    assert len(g) == 2 and not any(id(cands[a]) in chosen and id(cands[b]) in chosen for a, b in pairs)
    pick = choose(cands, np.array([[0, 2], [1, 3], [3, 3]]), 3)     # candidate 3 hits its mirror image
    assert set(pick) == {0, 1} and pick[0] is cands[1] and pick[1] is cands[2]


def test_the_report_says_why_a_pam_is_left_on_its_route(skel):
    """The toy pair with brackets of at most 10 mm: no place for either body on the toy tibia, and the report
    says so per PAM; the reasons of the later filters by hand."""
    from pamkin.optimize.rack_layout import why_left

    bones, des = _toy_pair(skel)
    q = _poses(skel, 10)
    new, rep = layout(des, skel, bones, q, q[:0], bracket_max=0.010, time_limit=30)
    assert rep.placed == {} and rep.unplaced == [1, 2] and new == des
    assert rep.reasons == {i: "no place on the bones of its route's ends (too long or too thick for their room)"
                           for i in (1, 2)}
    assert why_left((30, 0, 0, 0)) == "30 places on its bones, none clear of the other bones at every pose"
    assert why_left((30, 12, 0, 0)) == "12 places clear of bone, none clear of the bodies left on their routes"
    assert why_left((30, 12, 5, 0)) == "5 places, none clear of the other bones at the check poses"
    assert why_left((30, 12, 5, 3)) == "3 places, each in conflict with a chosen rack"


def test_rack_turns_by_hand():
    """A rack at the origin: anchor (0,0,0) → guide (1,0,0) → route end (1,1,0) → next point: the cable turns
    90° at the guide and, at the route end, 90° (next (2,1,0)) or 45° (next (2,2,0)); the same route with the
    rack at its insertion (points reversed) gives the same angles; a PAM without a rack is refused."""
    from pamkin.robot.rack import rack_turns

    mount = RackMount("origin", "tibia_r", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    base = load_design("thesis").pam(16)
    pam = dataclasses.replace(base, points=(PathPoint("g", "tibia_r", (1.0, 1.0, 0.0)),
                                            PathPoint("n", "calcn_r", (2.0, 1.0, 0.0))), rollers=(), pam_on=None)
    racked = rack_pam(pam, mount)
    pts = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 1, 0]], [[0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 2, 0]]], float)
    guide, end = rack_turns(racked, pts)
    assert guide == pytest.approx(math.pi / 2) and end == pytest.approx([math.pi / 2, math.pi / 4])
    at_insertion = dataclasses.replace(racked, points=racked.points[::-1])
    g2, e2 = rack_turns(at_insertion, pts[:, ::-1])
    assert g2 == pytest.approx(guide) and e2 == pytest.approx(end)
    with pytest.raises(ValueError, match="hangs on no rack"):
        rack_turns(pam, pts)


def test_conflicts_agree_with_every_pair_at_every_pose(skel):
    """The pairwise conflicts (same-host pairs checked once in the host frame, the others at every pose after a
    bounding-sphere test; right against the mirrored left) are exactly those of a brute-force check of every
    pair at every pose with the audit's segment distance."""
    from pamkin.human.bones import segment_distances
    from pamkin.optimize.rack_layout import Candidate, conflicts, mirror_candidate, world

    rng = np.random.default_rng(7)
    hosts = ["femur_r", "tibia_r", "pelvis", "calcn_r"]
    cands = []
    for k in range(40):
        a = rng.uniform(-0.15, 0.15, 3)
        b = a + rng.normal(size=3) * 0.08
        cands.append(Candidate(k % 9, RackMount("origin", hosts[k % 4], tuple(a), tuple(b)), 0.008 + 0.01 * rng.random(),
                               a, b, 0.02))
    q = _poses(skel, 12)
    st = skel.kinematics.forward(q, warn_range=False)
    pairs = conflicts(cands, [st], skel.kinematics, mirrored=(st, mirror_candidate))
    got = {tuple(p) for p in pairs}
    rad = np.array([c.radius for c in cands])
    A, B = world(cands, st, skel.kinematics)
    Al, Bl = world([mirror_candidate(c) for c in cands], st, skel.kinematics)
    want = set()
    for x in range(len(cands)):
        for y in range(len(cands)):
            lim = rad[x] + rad[y] + BODY_GAP_M
            if x < y and cands[x].pam != cands[y].pam:
                d = segment_distances(A[:, x], B[:, x], A[:, y], B[:, y])
                if np.min(d) < lim:
                    want.add((x, y))
    right_left = set()
    for x in range(len(cands)):
        for y in range(len(cands)):
            d = segment_distances(A[:, x], B[:, x], Al[:, y], Bl[:, y])
            if np.min(d) < rad[x] + rad[y] + BODY_GAP_M:
                right_left.add((x, y))
    assert len(want) > 10 and len(right_left) > 0
    assert got == want | right_left and len(pairs) == len(want) + len(right_left)


def test_the_stage_checks_racks_at_the_range_edges_too(skel):
    """The stage's poses: ``n`` uniform ones and ``n // 2`` at the range's edges, where about a third of each varied
    coordinate sits at its lower and a third at its upper limit (uniform samples almost never do); the other
    coordinates where the uniform poses have them."""
    from types import SimpleNamespace

    from pamkin.audit.measure import audit_coordinates
    from pamkin.human.rom import load_rom
    from pamkin.optimize.config import RunConfig
    from pamkin.optimize.stages.rack import RACK_STREAM, stage_poses

    rom = load_rom("robot_thesis", "r")
    ctx = SimpleNamespace(cfg=RunConfig(), human=skel, rom=rom)
    q = stage_poses(ctx, 600, RACK_STREAM)
    assert q.shape == (900, len(skel.coordinates))
    assert stage_poses(ctx, 0, RACK_STREAM).shape == (0, len(skel.coordinates))
    uniform, edge = q[:600], q[600:]
    for c in ("hip_flexion_r", "knee_angle_r", "lumbar_extension"):
        k = skel.coordinates.index(c)
        lo, hi = rom.bounds(c)
        at_limit = np.isclose(edge[:, k], lo, atol=1e-12) | np.isclose(edge[:, k], hi, atol=1e-12)
        assert 0.55 < at_limit.mean() < 0.78                          # two thirds at a limit
        assert not (np.isclose(uniform[:, k], lo, atol=1e-9) | np.isclose(uniform[:, k], hi, atol=1e-9)).any()
        assert lo - 1e-12 <= edge[:, k].min() and edge[:, k].max() <= hi + 1e-12
    varied = set(audit_coordinates(rom))
    for k, c in enumerate(skel.coordinates):
        if c not in varied and "adduction" not in c:
            np.testing.assert_array_equal(edge[:, k], uniform[0, k])
