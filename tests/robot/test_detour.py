"""Detours (:mod:`pamkin.robot.detour`): via points that carry a same-body segment round its bone — clear of it,
on brackets, and with every PAM length, moment arm and torque unchanged (the added length on the tendon)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pamkin
from pamkin.audit.measure import random_poses
from pamkin.human.bones import BoneSet
from pamkin.robot.design import Design, load_design
from pamkin.robot.detour import (BRACKET, CLEARANCE, PIECE_CLEARANCE, detour, detour_length, detour_pam, insert_via,
                           remove_via, same_body_segments)
from pamkin.opensim.model_file import PathPoint
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.human.rom import load_rom

RADIUS = 0.02


def sphere(P: np.ndarray) -> np.ndarray:
    """Signed distance to a ball of radius ``RADIUS`` at the origin."""
    return np.linalg.norm(P, axis=1) - RADIUS


def dense_min(pts: list[np.ndarray], distance) -> float:
    """Smallest distance along the polyline, sampled every 0.1 mm (ten times finer than the search)."""
    out = np.inf
    for a, b in zip(pts[:-1], pts[1:]):
        t = np.linspace(0.0, 1.0, max(2, int(np.linalg.norm(b - a) / 1e-4) + 1))[:, None]
        out = min(out, float(distance(a + t * (b - a)).min()))
    return out


@settings(max_examples=25, deadline=None)
@given(st.floats(-0.015, 0.015), st.floats(-0.015, 0.015), st.floats(0.03, 0.06), st.floats(0.0, np.pi))
def test_detour_round_a_ball_clears_it_on_brackets(y, z, reach, angle):
    """A segment through a ball (hand geometry): the via points lie 3..18 mm off its surface, every piece
    outside it by the piece clearance (checked ten times finer than the search), and the detour is no
    shorter than the way round the ball's great circle would allow (>= the straight segment)."""
    e = np.array([np.cos(angle), np.sin(angle), 0.0])
    off = np.array([0.0, 0.0, 1.0]) * z + np.cross(e, [0.0, 0.0, 1.0]) * y
    A, B = -reach * e + off, reach * e + off
    if dense_min([A, B], sphere) >= 0:
        assert detour(A, B, sphere) == []
        return
    via = detour(A, B, sphere)
    assert via, "no detour round a ball"
    dv = sphere(np.array(via))
    assert np.all(dv >= CLEARANCE - 1e-12) and np.all(dv <= BRACKET + 1e-12)
    assert dense_min([A, *via, B], sphere) >= PIECE_CLEARANCE - 1e-4     # (the search samples every 1 mm)
    assert detour_length(A, B, via) > 0


def test_a_segment_outside_the_bone_gets_no_detour_and_an_impossible_one_none():
    A, B = np.array([-0.05, 0.03, 0.0]), np.array([0.05, 0.03, 0.0])
    assert detour(A, B, sphere) == []
    # inside a ball far larger than any bracket: no via point can be both outside and within 18 mm of it
    # once the ends are buried in it
    big = lambda P: np.linalg.norm(P, axis=1) - 0.2  # noqa: E731
    assert detour(np.array([-0.05, 0.0, 0.0]), np.array([0.05, 0.0, 0.0]), big) is None


@pytest.fixture(scope="module")
def model():
    return pamkin.gait2392()


@pytest.fixture(scope="module")
def bones(model):
    return BoneSet(model)


def _through_tibia(model):
    """Sartorius of the v2 seed with its two tibia points moved so that the segment between them runs
    through the tibia (as its fit without the tibia's rows does: 9.7 mm deep)."""
    pam = load_design("v2_seed", bodies=model.bodies).pam(6)
    pts = list(pam.points)
    pts[2] = dataclasses.replace(pts[2], location=(-0.0414, -0.0715, 0.0008))
    pts[3] = dataclasses.replace(pts[3], location=(0.0097, -0.0115, -0.0129))
    return dataclasses.replace(pam, points=tuple(pts))


def test_detour_of_a_real_route_keeps_every_torque(model, bones):
    """Sartorius with a tibia-tibia segment 9.7 mm inside the tibia: the detour puts via points on the tibia's
    brackets, the detoured segment clears the tibia by the piece clearance, and on 300 random poses the
    route is longer by the same constant (1e-12 m), which is on the tendon: PAM lengths, forces and every
    torque equal those of the straight route (1e-9)."""
    pam = _through_tibia(model)
    assert 2 in same_body_segments(pam)
    dist = lambda P: bones.body_closest("tibia_r", P)[0]  # noqa: E731
    A, B = np.array(pam.points[2].location), np.array(pam.points[3].location)
    assert dense_min([A, B], dist) < -0.009
    new, outcome = detour_pam(pam, bones)
    assert outcome[2].endswith(("via point", "via points"))
    added = [p for p in new.points if p.name.startswith("p3.p4.")]
    assert added and all(p.body == "tibia_r" and type(p) is PathPoint for p in added)
    via = [np.array(p.location) for p in added]
    dv = dist(np.array(via))
    assert np.all(dv >= CLEARANCE - 1e-12) and np.all(dv <= BRACKET + 1e-12)
    assert dense_min([A, *via, B], dist) >= PIECE_CLEARANCE - 2e-4
    names = [p.name for p in new.points]
    assert names[names.index("p3") + 1:names.index("p4")] == [p.name for p in added]
    extra = new.tendon_length_m - pam.tendon_length_m         # every detour of the route (p4->p5's too)
    assert extra >= detour_length(A, B, via) > 0
    skel = robot_skeleton()
    q = random_poses(skel, load_rom("robot_thesis", "r"), 300, 11)
    a = PamRobot(Design("a", (pam,)), skel, sides=("r",)).evaluate(q)
    b = PamRobot(Design("b", (new,)), skel, sides=("r",)).evaluate(q)
    np.testing.assert_allclose(b.lengths - a.lengths, extra, atol=1e-12)
    np.testing.assert_allclose(b.pam_lengths, a.pam_lengths, atol=1e-12)
    np.testing.assert_allclose(b.moment_arms, a.moment_arms, atol=1e-9, rtol=0)
    np.testing.assert_allclose(b.torques, a.torques, atol=1e-9, rtol=0)
    # and back: the via points off, the tendon as it was
    back = remove_via(new, {p.name for p in pam.points})
    assert [p.name for p in back.points] == [p.name for p in pam.points]
    assert back.tendon_length_m == pytest.approx(pam.tendon_length_m, abs=1e-15)


def test_insert_and_remove_via_round_trip_and_refuse_foreign_points():
    pam = load_design("v2_seed").pam(6)
    v = {2: [np.array([0.0, -0.05, -0.05]), np.array([0.01, -0.05, -0.055])]}
    new = insert_via(pam, v)
    assert [p.name for p in new.points] == ["p1", "p2", "p3", "p3.p4.1", "p3.p4.2", "p4", "p5"]
    assert remove_via(new, {p.name for p in pam.points}) == pam
    with pytest.raises(ValueError, match="not via points of a detour between p1 and p3"):
        remove_via(pam, {"p1", "p3", "p4", "p5"})      # p2 is on the femur, p1 on the pelvis


def test_bone_rows_leave_a_short_same_body_segment_to_the_detour(model, bones):
    """The optimiser's bone rows (:class:`optimize.bone_cuts.BoneCuts`): with ``detour_below`` longer than the
    tibia-tibia segment, its own bone no longer counts (no depth, hence no row: rows are built from the same distances; other bones still count); off
    (0) the rows' 10 mm samples find it 8.8 mm in, and the other segments are measured the same either way."""
    from pamkin.optimize.bone_cuts import BoneCuts

    pam = _through_tibia(model)
    q = random_poses(model, load_rom("robot_thesis", "r"), 40, 5)
    loc = np.array([p.location for p in pam.points])
    cuts = BoneCuts(pam, model, bones, q)
    m0 = cuts.measure(loc)
    assert m0.segment_depth[2] > 0.008 and m0.segment_bone[2] == "tibia_r"
    seg_len = float(np.linalg.norm(loc[3] - loc[2]))
    cuts.detour_below = seg_len + 1e-6
    lengths = np.linalg.norm(np.diff(loc, axis=0), axis=1)
    free = cuts.detoured(loc)
    assert free == [a for a in (2, 3) if lengths[a] < seg_len + 1e-6] and 2 in free   # p1-p2, p2-p3 cross joints
    m1, (W, w0) = cuts.measure(loc, with_rows=True)
    # what is left of those segments' depth is another bone's (here the femur's condyles, at flexed knees)
    assert all(m1.segment_bone[a] != "tibia_r" for a in free)
    np.testing.assert_array_equal(np.delete(m1.segment_depth, free), np.delete(m0.segment_depth, free))
    cuts.detour_below = float(lengths[[2, 3]].min()) - 1e-6
    assert cuts.detoured(loc) == []


#: Sartorius as the default config's rounds leave it with the detours on (0.1.0-dev, before its
#: detours): p3->p4 on the tibia 10.2 mm inside it; the femur's condyles pass near at flexed knees.
SARTORIUS = {
    "id": 6, "name": "Sartorius", "human_muscles": ["sar_r"], "primary_coordinate": "knee_angle_r",
    "secondary_coordinates": ["hip_flexion_r"], "diameter_mm": 20, "n_parallel": 1, "transmission": 3,
    "resting_length_m": 0.227111107673874, "tendon_length_m": 0.0,
    "points": [{"name": "p1", "body": "pelvis", "location": [-0.02951, -0.03944, 0.08896]},
               {"name": "p2", "body": "femur_r", "location": [1e-05, -0.39708, -0.05504]},
               {"name": "p3", "body": "tibia_r", "location": [-0.0448, -0.06625, -0.00128]},
               {"name": "p4", "body": "tibia_r", "location": [0.03333, -0.02863, -0.02866]},
               {"name": "p5", "body": "tibia_r", "location": [0.04463, -0.134, 0.0248]}]}


def test_detour_pass_carries_a_result_round_its_bone(model, bones, monkeypatch):
    """The run's detour pass on that result: its tibia segments get via points clear of the femur too (a
    detour round the tibia alone left one piece 1.5 mm in the femur at a flexed knee), the route is then clear
    of every bone at its bone-check poses (the exact check, the result's bone summary), its validation error
    is the same to 1e-9 (every torque unchanged), and the progress line says so; a clear result is left
    alone."""
    import io

    from pamkin.robot.design import design_from_dict
    from pamkin.optimize.config import RunConfig
    from pamkin.optimize.context import RunContext
    from pamkin.optimize.results import ActuatorResult, bone_line
    from pamkin.optimize.samples import actuator_data
    from pamkin.optimize.stages import detours
    from pamkin.optimize.validation import validation_error

    rom = load_rom("robot_thesis", "r")
    seed_design = load_design("v2_seed", bodies=model.bodies)
    final = design_from_dict({"pams": [SARTORIUS]}, "sar", model.bodies).pams[0]
    cfg = RunConfig().replace({"workers": 1})
    data = [actuator_data(seed_design.pam(6), model, rom, cfg, seed_design.fitting_length_m)]
    ctx = RunContext(cfg, seed_design, model, rom, data=data, validation=None, bones=bones)
    given = ActuatorResult(6, final.name, final, "given", True, z=np.zeros(1), bone={"log": [], "clear": True})
    progress = io.StringIO()
    ctx.stream = progress
    out = detours.run(ctx, [given])[0]
    assert set(out.bone["detours"]) == {"p3->p4", "p4->p5"}
    assert all(v.endswith(("via point", "via points")) for v in out.bone["detours"].values()), out.bone["detours"]
    assert "detours of actuator 6 Sartorius: p3->p4: 2 via points; p4->p5: 1 via point" in progress.getvalue()
    assert len(out.pam.points) > len(final.points) and out.pam.tendon_length_m > final.tendon_length_m
    assert out.bone["clear"] and bone_line(out.bone).startswith("clear"), bone_line(out.bone)
    # round the tibia alone (no poses given) the same segments end up in the femur at a flexed knee
    from pamkin.optimize.bone_cuts import BoneCuts, bone_check_poses

    own_only, _ = detour_pam(final, bones)
    q, n_right = bone_check_poses(model, rom, seed_design.pam(6), cfg.seed, crossed=data[0].crossed)
    m = BoneCuts(own_only, model, bones, q, n_right).measure(np.array([p.location for p in own_only.points]))
    assert m.violation() > 0 and "femur_r" in m.segment_bone, (m.segment_depth, m.segment_bone)
    qv, Tv = ctx.validation_set()
    crossed = list(data[0].crossed)
    np.testing.assert_allclose(validation_error(out.pam, model, qv, Tv, crossed, seed_design),
                               validation_error(final, model, qv, Tv, crossed, seed_design), atol=1e-9)
    assert detours.run(ctx, [out])[0] is out


def test_a_split_mount_segment_is_no_longer_named():
    """A design's ``pam_on`` naming a segment a detour splits is dropped (the body then sits where it fits
    best); one naming another segment is kept, both ways."""
    pam = dataclasses.replace(load_design("v2_seed").pam(6), pam_on="p3->p4")
    v = {2: [np.array([0.0, -0.05, -0.05])]}
    assert insert_via(pam, v).pam_on is None
    kept = dataclasses.replace(pam, pam_on="p1->p2")
    new = insert_via(kept, v)
    assert new.pam_on == "p1->p2" and remove_via(new, {p.name for p in pam.points}).pam_on == "p1->p2"


def test_a_warm_start_drops_the_detours_it_was_given():
    """``pamkin optimize --warm-start RUN`` starts from RUN's routes without their via points (the run places
    them again): the seed's point names, the tendon back to its length before the detour; the other PAMs of
    the warm design as they are."""
    from pamkin.optimize.stages.seed import warm_seed

    seed = load_design("v2_seed")
    sar = seed.pam(6)
    detoured = insert_via(sar, {2: [np.array([0.0, -0.05, -0.05])], 3: [np.array([0.04, -0.08, 0.0])]})
    warm = seed.replace_pam(detoured)
    out, ids = warm_seed(seed, warm)
    assert ids == {p.id for p in seed.pams}
    assert [p.name for p in out.pam(6).points] == [p.name for p in sar.points]
    assert out.pam(6).tendon_length_m == pytest.approx(sar.tendon_length_m, abs=1e-15)
    assert out.pam(9) == seed.pam(9)


def test_a_warm_start_from_another_seed_is_a_clear_error():
    """A warm design whose route has points the seed's does not have, on another body than a detour's, is
    refused naming the file and the points (not a traceback)."""
    from pamkin.errors import DataFileError
    from pamkin.optimize.stages.seed import warm_seed

    seed = load_design("v2_seed")
    sar = seed.pam(6)
    odd = dataclasses.replace(sar, points=(sar.points[0], PathPoint("x", "femur_r", (0.0, -0.1, 0.0)),
                                           *sar.points[1:]))
    warm = dataclasses.replace(seed.replace_pam(odd), path="runs/other/design.yaml")
    with pytest.raises(DataFileError, match=r"runs/other/design.yaml.*\['x'\].*not a run of this seed design"):
        warm_seed(seed, warm)
