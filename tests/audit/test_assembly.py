"""The audit's assembly figures on hand-made geometry: gaps between toy PAM bodies, a toy body beside a toy
bone, the joint-capacity sums by hand, and the thesis design's figures as the issue measured them."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from pamkin.audit.assembly import body_distances, body_radius, bone_clearance, pair_gap
from pamkin.audit.capacity import joint_capacity
from pamkin.audit.measure import AuditOptions, audit_design
from pamkin.audit.scorecard import capacity_side_by_side, scorecard_text
from pamkin.human.bones import BoneSet
from pamkin.robot import festo
from pamkin.robot.biped import robot_skeleton


def _piece(A, B, valid=None):
    A, B = np.asarray(A, float), np.asarray(B, float)
    return A, B, np.ones(len(A), bool) if valid is None else np.asarray(valid, bool)


def test_two_toy_bodies_at_known_distances():
    """Two parallel bodies 30 mm apart (axes), radii 7.5 and 15 mm: 7.5 mm between the surfaces; moved to
    20 mm apart at the second sample: −2.5 mm (overlap), at the third 42 mm apart: 19.5 mm. A body of two
    pieces counts its nearer piece; an absent piece counts nowhere."""
    S = 3
    y = np.array([0.03, 0.02, 0.042])
    a = [_piece(np.zeros((S, 3)), np.tile([0, 0, 0.2], (S, 1)))]
    b = [_piece(np.stack([np.zeros(S), y, np.zeros(S)], 1), np.stack([np.zeros(S), y, np.full(S, 0.2)], 1))]
    d = body_distances(a, b, 0.0075, 0.015)
    np.testing.assert_allclose(d, [0.0075, -0.0025, 0.0195], atol=1e-12)
    g = pair_gap(a, b, 0.0075, 0.015, gap=0.005)
    assert g.distance_m == pytest.approx(-0.0025) and g.sample == 1
    assert g.closer_fraction == pytest.approx(1 / 3) and g.overlap_fraction == pytest.approx(1 / 3)
    g = pair_gap(a, b, 0.0075, 0.015, gap=0.010)          # 7.5 mm counts as closer than 10 mm
    assert g.closer_fraction == pytest.approx(2 / 3)
    # a second piece of b, 100 mm off, present only at sample 2; b's first piece absent there
    far = _piece(np.tile([0.1, 0, 0], (S, 1)), np.tile([0.1, 0, 0.2], (S, 1)), [False, False, True])
    b2 = [(b[0][0], b[0][1], np.array([True, True, False])), far]
    np.testing.assert_allclose(body_distances(a, b2, 0.0075, 0.015), [0.0075, -0.0025, 0.1 - 0.0225], atol=1e-12)
    gone = [(b[0][0], b[0][1], np.zeros(S, bool))]
    assert np.all(np.isinf(body_distances(a, gone, 0.0075, 0.015)))
    assert pair_gap(a, gone, 0.0075, 0.015).sample == -1


def test_toy_body_beside_a_toy_bone():
    """A 100 mm cube of bone on the femur; a body of 15 mm radius (a 20 mm PAM) parallel to one face with its
    axis 40, 20, 10 mm and −5 mm (inside) from the face at four poses: clearance 25, 5, −5 and −20 mm; the
    nearest bone is the femur; nothing within reach: +inf and no bone."""
    skel = robot_skeleton()
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    bones = BoneSet.from_meshes(skel, {"femur_r": [(box.vertices, box.faces)]})
    q = np.tile(skel.default_q, (5, 1))
    st = skel.kinematics.forward(q, warn_range=False)
    b = skel.bodies.index("femur_r")
    off = np.array([0.04, 0.02, 0.01, -0.005, 0.5])          # axis distance from the face x = 0.05
    local_a = np.stack([0.05 + off, np.full(5, -0.03), np.full(5, -0.02)], 1)
    local_b = local_a + [0.0, 0.06, 0.04]
    A = st.body_p[:, b] + np.einsum("sij,sj->si", st.body_R[:, b], local_a)
    B = st.body_p[:, b] + np.einsum("sij,sj->si", st.body_R[:, b], local_b)
    r = body_radius(20)
    assert r == pytest.approx(festo.outer_diameter(20) / 2) and r == pytest.approx(0.015)
    c, near = bone_clearance(bones, st, [_piece(A, B)], r, step=0.004, reach=0.03)
    np.testing.assert_allclose(c[:4], [0.025, 0.005, -0.005, -0.02], atol=1e-9)
    assert c[4] == np.inf and near[4] == -1
    assert all(bones.bodies[i] == "femur_r" for i in near[:4])
    # a body absent at a pose has no clearance there
    c, _ = bone_clearance(bones, st, [_piece(A, B, [True, False, True, True, True])], r, step=0.004,
                          reach=0.03)
    assert c[1] == np.inf and c[0] == pytest.approx(0.025)


def test_capacity_sums_by_hand():
    """Two PAMs and three muscles about two coordinates at three poses: the summed positive and negative
    torques, their ratio and the share of poses where the robot reaches the human, by hand."""
    names = ["a", "b"]
    robot = np.array([[[10.0, 1.0], [-4.0, 2.0]],
                      [[5.0, -1.0], [6.0, -2.0]],
                      [[-3.0, 0.0], [2.0, 0.0]]])            # (S=3, PAMs=2, coordinates=2)
    human = np.array([[[8.0, 0.0], [-5.0, 0.0], [1.0, 0.0]],
                      [[12.0, 0.0], [-1.0, 0.0], [0.0, 0.0]],
                      [[1.0, 0.0], [0.0, 0.0], [-2.0, 0.0]]])
    rows = joint_capacity(robot, human, ["a", "b"], names, fraction=0.6)
    plus, minus = rows[0], rows[1]
    # coordinate a, +: robot 10, 11, 2; human 9, 12, 1 -> ratios 10/9, 11/12, 2; robot >= human at 2 of 3
    assert plus["robot_median_Nm"] == pytest.approx(10.0) and plus["human_median_Nm"] == pytest.approx(9.0)
    assert plus["ratio_median"] == pytest.approx(10 / 9) and plus["ratio_min"] == pytest.approx(11 / 12)
    assert plus["fraction_robot_ge_human"] == pytest.approx(2 / 3) and plus["met"]
    # coordinate a, −: robot 4, 0, 3; human 5, 1, 2 -> 1 of 3
    assert minus["robot_median_Nm"] == pytest.approx(3.0) and minus["human_median_Nm"] == pytest.approx(2.0)
    assert minus["ratio_min"] == pytest.approx(0.0) and minus["fraction_robot_ge_human"] == pytest.approx(1 / 3)
    assert not minus["met"]
    # coordinate b: the human has no torque; poses where it has none count as met, and no ratio is defined
    assert rows[2]["fraction_robot_ge_human"] == 1.0 and np.isnan(rows[2]["ratio_median"])
    assert [r["direction"] for r in rows] == ["+", "-", "+", "-"]


@pytest.mark.needs_shared
def test_thesis_design_assembly_figures():
    """The thesis design as the issue measured it (its bodies with the same radii): every body runs into bone,
    its same-side bodies overlap in well over a hundred pairs, and the robot reaches the human's joint capacity
    on >= 90 % of random poses in 11 of the 20 coordinate-directions (issue: 11 / 20). The scorecard and the
    optimiser's comparison table name the figures."""
    res = audit_design("thesis", options=AuditOptions.quick(n_random=300, gait_ik=None, gait_plan=False,
                                                            n_geometry=40, n_sweep=5, n_grid=3))
    s = res.summary
    assert s["capacity_directions"] == 20
    assert 10 <= s["capacity_directions_met"] <= 12
    assert s["pam_bodies_near_bone"] == s["pam_bodies_into_bone"] == 27
    assert s["pam_body_pairs_closer_than_gap"] >= s["pam_body_pairs_overlapping"] >= 100
    assert s["pam_body_pairs_closer_than_gap"] == len(res.assembly["pairs_closer_than_gap"])
    assert s["pam_body_pairs_overlapping"] == s["pam_pairs_intersecting"]     # the coal-based count agrees
    assert res.assembly["body_radii_m"] == {"10": 0.0075, "20": 0.015, "40": 0.03}
    hip_ext = next(r for r in res.capacity if r["coordinate"] == "hip_flexion_r" and r["direction"] == "-")
    assert hip_ext["motion"] == "extension" and hip_ext["met"]
    text = scorecard_text(res)
    assert "joint capacity" in text and "body pairs closer than 5 mm (same side)" in text
    table = capacity_side_by_side([res, res], ["thesis", "again"])
    assert table.count("\n") == 22 and "hip_flexion_r - extension" in table


@pytest.mark.opensim
def test_human_capacity_against_opensim(gait2392_path):
    """The human half of the joint-capacity table (every Gait2392 muscle at activation 1, summed per direction)
    at four of the audit's random poses equals the same sum of OpenSim 4.6's tendon forces x moment arms
    (computed in a child process)."""
    import warnings

    import pamkin
    from opensim_ref import opensim_reference

    from pamkin.audit.capacity import direction_capacity
    from pamkin.audit.measure import audit_coordinates, random_poses
    from pamkin.errors import RangeWarning
    from pamkin.human.rom import load_rom

    human = pamkin.gait2392()
    rom = load_rom("robot_thesis", "r")
    q = random_poses(human, rom, 4, seed=3)
    ref = opensim_reference(gait2392_path, q, what=("moment_arms", "tendon_forces"))
    T_ref = np.zeros((len(q), len(human.muscles), len(human.coordinates)))
    for k, (m, c) in enumerate(ref["pairs"]):
        T_ref[:, m, c] = ref["tendon_forces"][:, m] * ref["moment_arms"][:, k]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        T = human.torques(q)
    cols = [human.coordinates.index(c) for c in audit_coordinates(rom)]
    assert len(cols) == 10
    for sign in (1.0, -1.0):
        ours = direction_capacity(T, sign)[:, cols]
        theirs = direction_capacity(T_ref, sign)[:, cols]
        assert theirs.min() > 0.5                          # every direction has human muscles acting
        np.testing.assert_allclose(ours, theirs, rtol=1e-4, atol=1e-3)


def test_a_bundle_of_parallel_pams_is_the_capsule_around_it():
    """Two (three) PAMs side by side on one route: the circle around two (three) touching circles of radius r
    has radius 2r ((1 + 2/√3) r), by hand; a bundle size outside 1..3 is named."""
    r = body_radius(10)
    assert body_radius(10, 1) == r
    assert body_radius(10, 2) == pytest.approx(2 * r, rel=1e-15)
    # three centres on an equilateral triangle of side 2r: circumradius 2r/√3, plus r
    assert body_radius(10, 3) == pytest.approx(2 * r / np.sqrt(3) + r, rel=1e-15)
    with pytest.raises(ValueError, match="not 4"):
        body_radius(10, 4)
