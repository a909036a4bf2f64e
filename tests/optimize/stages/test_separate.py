"""The separate stage on hand-made toys: two PAMs forced into each other end at least 5 mm apart, a PAM body
against a toy bone ends at least 5 mm from it — measured with the audit's own body geometry — and the stage
keeps each PAM's place and length; its config section is validated."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from pamkin.audit.assembly import body_distances, body_radius, bone_clearance
from pamkin.human.bones import BoneSet
from pamkin.opensim.model_file import PathPoint
from pamkin.optimize.config import RunConfig
from pamkin.optimize.separation import closest_points, separate
from pamkin.errors import DataFileError
from pamkin.robot.biped import PamRobot, placements, robot_skeleton
from pamkin.robot.design import Design, Pam
from pamkin.robot.pam_body import pam_capsules


@pytest.fixture(scope="module")
def skel():
    return robot_skeleton()


def _poses(skel) -> np.ndarray:
    q = np.tile(skel.default_q, (3, 1))
    q[:, skel.coordinates.index("knee_angle_r")] = [0.0, -0.5, -1.0]
    q[:, skel.coordinates.index("hip_flexion_r")] = [0.0, 0.3, 0.6]
    return q


def _bodies(design, skel, q):
    out = []
    for place, pts, length in placements(design, skel, q):
        out.append(pam_capsules(pts, place.segment, length + 2 * design.fitting_length_m, place.side))
    return out


def _pam(pid: int, name: str, muscle: str, a, b) -> Pam:
    pts = (PathPoint(f"{name}1", "pelvis", a), PathPoint(f"{name}2", "tibia_r", b))
    return Pam(pid, name, (muscle,), "knee_angle_r", (), 20, 1, 0.25, 0.15, pts)


def test_closest_points_of_two_segments_by_hand():
    p, q = closest_points(np.zeros(3), np.array([1.0, 0, 0]), np.array([0.5, 1.0, -1.0]), np.array([0.5, 1.0, 1.0]))
    np.testing.assert_allclose(p, [0.5, 0, 0]) and np.testing.assert_allclose(q, [0.5, 1.0, 0])
    p, q = closest_points(np.zeros(3), np.array([1.0, 0, 0]), np.array([2.0, 1.0, 0]), np.array([3.0, 1.0, 0]))
    np.testing.assert_allclose(p, [1, 0, 0]) and np.testing.assert_allclose(q, [2, 1, 0])


def test_two_pams_forced_into_each_other_end_5mm_apart(skel):
    """Two 20 mm PAMs (bodies of 15 mm radius) from the pelvis to the tibia with their points 10 mm apart: their
    bodies overlap by 20 mm at every pose; separated, they are >= 5 mm apart at every pose, each keeps its mount
    segment, end and PAM length, and the points moved by about half the missing 25 mm each."""
    a = _pam(4, "a", "bifemlh_r", (-0.05, -0.02, 0.08), (0.0, -0.05, 0.0))
    b = _pam(5, "b", "semimem_r", (-0.05, -0.02, 0.09), (0.0, -0.05, 0.01))
    des = Design("toy", (a, b), rom="robot_thesis")
    q = _poses(skel)
    before = _bodies(des, skel, q)
    r = body_radius(20)
    assert np.max(body_distances(before[0], before[1], r, r)) < -0.015
    new, rep = separate(des, skel, q, None)
    after = _bodies(new, skel, q)
    assert np.min(body_distances(after[0], after[1], r, r)) >= 0.005
    assert (rep.pairs_before, rep.pairs_after) == (1, 0)
    assert all(0.012 <= m["displacement_m"] <= 0.02 for m in rep.moved.values())
    for p in new.pams:
        assert (p.pam_on, p.pam_at) == (f"{p.name}1->{p.name}2", "origin")
    L0 = PamRobot(des, skel, sides=("r",)).evaluate(q).pam_lengths
    L1 = PamRobot(new, skel, sides=("r",)).evaluate(q).pam_lengths
    np.testing.assert_allclose(L1.mean(axis=0), L0.mean(axis=0), atol=1e-12)


def test_a_body_against_a_toy_bone_ends_5mm_from_it(skel):
    """A 20 mm cube of bone on the femur whose surface lies 5 mm inside a PAM body at the default pose: the
    separated body clears it by >= 5 mm at every pose; a move limit too small to get there leaves the contact
    counted."""
    pam = _pam(4, "a", "bifemlh_r", (-0.05, -0.02, 0.08), (0.0, -0.05, 0.0))
    des = Design("toy", (pam,), rom="robot_thesis")
    q = _poses(skel)
    kin = skel.kinematics.forward(q, warn_range=False)
    body = _bodies(des, skel, q)[0]
    A, B, _ = body[0]
    f = skel.bodies.index("femur_r")
    mid = kin.body_R[0, f].T @ (0.5 * (A[0] + B[0]) - kin.body_p[0, f])
    box = trimesh.creation.box(extents=(0.02, 0.02, 0.02))
    box.apply_translation(mid + [0.0, 0.0, 0.02])
    bones = BoneSet.from_meshes(skel, {"femur_r": [(box.vertices, box.faces)]})
    r = body_radius(20)
    c0, _ = bone_clearance(bones, kin, body, r, 0.002, reach=0.05)
    assert c0[0] == pytest.approx(-0.005, abs=2e-4)
    new, rep = separate(des, skel, q, bones)
    c1, _ = bone_clearance(bones, kin, _bodies(new, skel, q)[0], r, 0.002, reach=0.05)
    assert np.min(c1) >= 0.005 and (rep.bone_before, rep.bone_after) == (1, 0)
    _, stuck = separate(des, skel, q, bones, max_shift=0.002)
    assert stuck.bone_after == 1 and all(m["displacement_m"] <= 0.002 + 1e-12 for m in stuck.moved.values())


def test_separate_config_section():
    cfg = RunConfig()
    assert not cfg.separate.enabled and cfg.separate.gap_m == 0.005
    assert RunConfig().replace({"separate.enabled": True, "separate.max_shift_m": 0.03}).separate.max_shift_m == 0.03
    with pytest.raises(DataFileError, match="separate.rounds"):
        RunConfig().replace({"separate.rounds": 0})


def test_the_pipeline_stage_separates_the_toy_pams(skel):
    """The declared stage (after pam_ends, switched on by ``[separate] enabled``) run on the two toy PAMs as a
    run's results: both results come back separated, and the report names the counts."""
    import io
    from types import SimpleNamespace

    from pamkin.human.rom import load_rom
    from pamkin.optimize.pipeline import STAGES
    from pamkin.optimize.results import ActuatorResult
    from pamkin.optimize.stages import separate as stage

    names = [s.name for s in STAGES]
    assert names.index("separate") == names.index("pam_ends") + 1
    st = STAGES[names.index("separate")]
    on = RunConfig().replace({"separate.enabled": True, "separate.poses": 20})
    assert st.enabled(on) and not st.enabled(RunConfig())
    a = _pam(4, "a", "bifemlh_r", (-0.05, -0.02, 0.08), (0.0, -0.05, 0.0))
    b = _pam(5, "b", "semimem_r", (-0.05, -0.02, 0.09), (0.0, -0.05, 0.01))
    seed = Design("toy", (a, b), rom="robot_thesis")
    results = [ActuatorResult(p.id, p.name, p, "Solve_Succeeded", True) for p in seed.pams]
    ctx = SimpleNamespace(cfg=on, seed_design=seed, human=skel, rom=load_rom(seed.rom, "r"), bones=None,
                          stream=io.StringIO(), separation=[])
    out = stage.run(ctx, results)
    new = Design("toy", tuple(r.pam for r in out), rom="robot_thesis")
    q = _poses(skel)
    r = body_radius(20)
    bodies = _bodies(new, skel, q)
    assert np.min(body_distances(bodies[0], bodies[1], r, r)) >= 0.005 - 1e-3   # enforced at the stage's poses
    assert "body pairs closer than 5 mm 1 -> 0" in ctx.separation[0]
