"""Rollers (cable guides, :mod:`pamkin.robot.rollers`): design files, lengths by hand, moment arms against via
points at the tangent points, the audit's bone checks over the pieces, the viewer.

That the wrapped lengths equal OpenSim 4.6's (the export's WrapCylinders) is tested in
``tests/test_osim_export.py``.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
import yaml

from pamkin.robot.design import Design, Pam, design_from_dict, load_design, save_design
from pamkin.errors import DataFileError, RangeWarning
from pamkin.opensim.model_file import PathPoint
from pamkin.robot.pam_body import placement, route_positions, segment_options
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.robot.rollers import Roller, roller_frame


@pytest.fixture(scope="module")
def skel():
    return robot_skeleton()


def _pam(points, rollers=(), rest=0.05, tendon=0.0, pid=1):
    return Pam(pid, "toy", ("bifemsh_r",), "knee_angle_r", (), 20, 1, rest, tendon, tuple(points), rollers=rollers)


# ----------------------------------------------------------------------------- design files
def test_design_file_round_trips_rollers_and_names_bad_ones(tmp_path, skel):
    roller = {"segment": "a->b", "body": "pelvis", "centre": [0.0, -0.005, 0.0], "axis": [0, 0, 2],
              "side": [0, 1, 0], "radius_m": 0.01}
    pam = {"id": 1, "name": "toy", "human_muscles": ["bifemsh_r"], "primary_coordinate": "knee_angle_r",
           "diameter_mm": 20, "resting_length_m": 0.05, "tendon_length_m": 0.0,
           "points": [{"name": "a", "body": "pelvis", "location": [-0.05, 0, 0]},
                      {"name": "b", "body": "pelvis", "location": [0.05, 0, 0]},
                      {"name": "c", "body": "femur_r", "location": [0.0, -0.1, 0]}],
           "rollers": [roller]}
    des = design_from_dict({"pams": [pam]}, "toy.yaml", skel.bodies, skel.coordinates)
    r = des.pams[0].rollers[0]
    assert r.axis == (0.0, 0.0, 1.0) and r.length_m == 0.04          # normalised; the default length
    save_design(des, tmp_path / "d.yaml")
    again = load_design(tmp_path / "d.yaml", bodies=skel.bodies)
    assert again.pams[0].rollers == des.pams[0].rollers

    def bad(change, message, pam_change=None):
        p = yaml.safe_load(yaml.safe_dump(pam))
        p["rollers"][0].update(change)
        p.update(pam_change or {})
        with pytest.raises(DataFileError, match=message) as e:
            design_from_dict({"pams": [p]}, "bad.yaml", skel.bodies, skel.coordinates)
        assert "bad.yaml" in str(e.value) and "'toy'" in str(e.value)

    bad({"segment": "a->c"}, r"segment must name a segment of its route \['a->b', 'b->c'\]")
    bad({"body": "femur"}, "unknown body 'femur'")
    bad({"side": [0, 0.5, 0.5]}, "side must be perpendicular to axis")
    bad({"axis": [0, 0, 0]}, "axis must be a non-zero direction")
    bad({"radius_m": -0.01}, "radius_m and length_m must be positive")
    bad({"centre": [0, 0]}, "centre must be 3 finite numbers")
    bad({}, "at most one roller per segment", {"rollers": [roller, roller]})
    bad({}, "pam_on 'a->b' has a roller", {"pam_on": "a->b"})


# ----------------------------------------------------------------------------- lengths and moment arms
def test_length_over_a_roller_by_hand(skel):
    """Both ends and the roller on the pelvis, in a plane across the roller's axis: the straight line passes
    5 mm from the axis (inside the 10 mm radius), so the cable goes over the roller's +y side: two tangents
    of sqrt(d² − r²) and an arc r·φ, φ = the angle between the ends seen from the axis less the two tangent
    angles acos(r/d)."""
    r, h = 0.01, 0.005
    pts = (PathPoint("a", "pelvis", (-0.05, 0.0, 0.0)), PathPoint("b", "pelvis", (0.05, 0.0, 0.0)))
    rol = Roller("a->b", "pelvis", (0.0, -h, 0.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), r)
    robot = PamRobot(Design("toy", (_pam(pts, (rol,)),)), skel, sides=("r", "l"))
    d = math.hypot(0.05, h)
    phi = (math.pi - 2 * math.atan2(h, 0.05)) - 2 * math.acos(r / d)
    expect = 2 * math.sqrt(d * d - r * r) + r * phi
    q = np.zeros((3, len(skel.coordinates)))
    q[1, skel.coordinates.index("pelvis_tilt")] = 0.4
    q[2, skel.coordinates.index("pelvis_ty")] = 0.3
    st = robot.evaluate(q)
    np.testing.assert_allclose(st.lengths, expect, rtol=0, atol=1e-12)    # both sides, any pelvis pose
    assert np.all(st.moment_arms == 0)                                       # nothing moves relative
    # the pieces: tangent points on the roller's surface, the straight pieces tangent to it there
    ks = skel.kinematics.forward(q)
    (A, T1), (T2, B) = robot.route_pieces(ks, 0)[0]
    b = skel.kinematics.frames.index("pelvis")
    R = ks.body_R[:, b] @ roller_frame(rol)
    c = ks.body_p[:, b] + ks.body_R[:, b] @ np.array(rol.centre)
    for T, P in ((T1, A), (T2, B)):
        loc = np.einsum("sji,sj->si", R, T - c)
        np.testing.assert_allclose(np.hypot(loc[:, 0], loc[:, 1]), r, atol=1e-12)
        radial = np.einsum("sij,sj->si", R, loc * [1, 1, 0])
        assert np.all(np.abs(np.einsum("si,si->s", radial, P - T)) < 1e-12)
        assert np.all(loc[:, 0] > 0)                                          # on the roller's side
    np.testing.assert_allclose(robot.segment_lengths(ks, 0)[:, 0], expect, atol=1e-12)


def test_roller_off_the_line_changes_nothing(skel):
    """A roller the straight cable passes on its side without touching leaves length and moment arms
    exactly as without it."""
    des = load_design("v2_seed", bodies=skel.bodies)
    bflh = des.pam(4)
    far = Roller("p1->p2", "femur_r", (0.30, -0.1, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0), 0.005)
    with_roller = des.replace_pam(dataclasses.replace(bflh, rollers=(far,), pam_on=None))
    q = _random_q(skel, des, 40)
    a, b = (PamRobot(d, skel).evaluate(q) for d in (des, with_roller))
    np.testing.assert_allclose(a.lengths, b.lengths, rtol=0, atol=1e-14)    # summed in another order
    np.testing.assert_allclose(a.moment_arms, b.moment_arms, atol=1e-9)


def _random_q(skel, des, n, seed=5):
    from pamkin.audit.measure import random_poses
    from pamkin.human.rom import load_rom

    return random_poses(skel, load_rom(des.rom, "r"), n, seed)


def test_moment_arms_are_those_of_via_points_at_the_tangent_points(skel):
    """A route over a roller is, to first order, the route through two via points fixed in the roller's
    body at the tangent points (the contact's own motion changes the length only to second order): the
    roller's moment arms (central differences of OpenSim's wrapped lengths) against the analytic moment
    arms of that via-point route, at poses where the cable wraps (biceps femoris long head over a roller
    behind the femur)."""
    des = load_design("v2_seed", bodies=skel.bodies)
    bflh = des.pam(4)
    rol = Roller("p1->p2", "femur_r", (-0.06, -0.1, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0), 0.01)
    one = Design("toy", (dataclasses.replace(bflh, rollers=(rol,), pam_on=None),), rom=des.rom)
    robot = PamRobot(one, skel, sides=("r",))
    q = _random_q(skel, des, 200)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st = robot.evaluate(q)
        ks = skel.kinematics.forward(q, warn_range=False)
    _, T1, T2 = (lambda p: (p[0][0], p[0][1], p[1][0]))(robot.route_pieces(ks, 0)[0])
    _, _, wrapped, arc = robot._rolled(ks, 0)[1][0]
    assert 0.2 < wrapped.mean() < 0.9                              # both states among the poses
    straight = PamRobot(Design("toy", (dataclasses.replace(bflh, pam_on=None),), rom=des.rom), skel, sides=("r",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st0 = straight.evaluate(q)
    np.testing.assert_allclose(st.moment_arms[~wrapped], st0.moment_arms[~wrapped], atol=1e-9)
    fem = skel.kinematics.frames.index("femur_r")
    worst = 0.0
    for s in np.flatnonzero(wrapped)[:12]:
        to_local = lambda X: ks.body_R[s, fem].T @ (X[s] - ks.body_p[s, fem])   # noqa: E731
        via = (bflh.points[0], PathPoint("t1", "femur_r", tuple(to_local(T1))),
               PathPoint("t2", "femur_r", tuple(to_local(T2))), *bflh.points[1:])
        vr = PamRobot(Design("via", (dataclasses.replace(bflh, points=via, pam_on=None),), rom=des.rom), skel,
                      sides=("r",))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            sv = vr.evaluate(q[s:s + 1])
        chord = float(np.linalg.norm(T2[s] - T1[s]))        # the via route cuts the arc: shorter by arc - chord
        assert sv.lengths[0, 0] == pytest.approx(st.lengths[s, 0] - (arc[s] - chord), abs=1e-12)
        worst = max(worst, float(np.max(np.abs(sv.moment_arms[0, 0] - st.moment_arms[s, 0]))))
    print(f"\nroller moment arms vs via points at the tangent points: max |difference| {worst:.2e} m")
    assert worst < 2e-4, worst          # metres; moment arms here are 10-60 mm


# ----------------------------------------------------------------------------- the PAM body and the audit
def test_pam_body_never_sits_on_a_segment_with_a_roller(skel):
    """The longer segment has a roller: placement and segment_options use the other one."""
    pts = (PathPoint("a", "femur_r", (0.0, -0.05, 0.03)), PathPoint("b", "femur_r", (0.0, -0.35, 0.03)),
           PathPoint("c", "tibia_r", (0.0, -0.15, 0.03)))
    rol = Roller("a->b", "femur_r", (0.0, -0.2, 0.028), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.005)   # the line 2 mm off its axis
    pam = _pam(pts, (rol,), rest=0.10, tendon=0.0)
    robot = PamRobot(Design("toy", (pam,), rom="robot_thesis"), skel, sides=("r",))
    q = _random_q(skel, Design("toy", (pam,), rom="robot_thesis"), 30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        ks = skel.kinematics.forward(q, warn_range=False)
    pts_w = route_positions(robot.paths, ks, 0)
    lengths = robot.segment_lengths(ks, 0)
    assert np.all(lengths[:, 0] > np.linalg.norm(pts_w[:, 1] - pts_w[:, 0], axis=1) + 1e-5)   # it wraps
    pam_len = np.full(len(q), 0.10)
    place = placement(pts_w, pam, pam_len, 0.0125, lengths)
    assert place.segment == 1 and place.side == "origin" and place.on_one_segment
    assert segment_options(pts_w, pam, pam_len, 0.0125, lengths) == [(1, "origin"), (1, "insertion")]
    # without the roller the PAM body would sit on the longer segment a->b
    plain = dataclasses.replace(pam, rollers=())
    assert placement(pts_w, plain, pam_len, 0.0125).segment == 0


def _femur_toy(skel, with_roller: bool) -> Design:
    """Two points 6 mm off the femoral shaft, lateral and medial of its front at one height: the straight
    line between them cuts through the shaft; a 6 mm roller 4 mm in front of the bone carries it around."""
    from pamkin.human.bones import BoneSet

    bones = BoneSet(skel)
    y = -0.25
    ang = np.linspace(0, 2 * np.pi, 36, endpoint=False)
    _, C, _ = bones.body_closest("femur_r", np.stack([0.1 * np.cos(ang), np.full(36, y), 0.1 * np.sin(ang)], 1))
    centre = np.array([C[:, 0].mean(), y, C[:, 2].mean()])

    def surface(v, dist):
        v = np.asarray(v, float) / np.linalg.norm(v)
        _, Cs, Ns = bones.body_closest("femur_r", (centre + 0.1 * v)[None])
        return Cs[0] + dist * Ns[0], Ns[0]

    p1, _ = surface([0.2, 0, 1], 0.006)
    p2, _ = surface([0.2, 0, -1], 0.006)
    front, n = surface([1, 0, 0], 0.0)
    axis = np.array([0.0, 1.0, 0.0])
    side = (n - (n @ axis) * axis) / np.linalg.norm(n - (n @ axis) * axis)
    def f(v):
        return tuple(float(x) for x in v)

    rollers = (Roller("a->b", "femur_r", f(front + 0.010 * n), f(axis), f(side), 0.006),) if with_roller else ()
    pts = (PathPoint("a", "femur_r", f(p1)), PathPoint("b", "femur_r", f(p2)))
    return Design("femur_toy", (_pam(pts, rollers, rest=0.02, tendon=0.0),), rom="robot_thesis")


def test_audit_checks_the_pieces_around_a_roller_and_the_roller_itself(skel):
    """The audit samples a segment with a roller along its straight pieces (not through the roller) and
    counts the roller as an attachment: its surface outside bone, within a bracket of it. Without the
    roller the toy's segment is 8 mm inside the femur at every pose; with it, clear."""
    from pamkin.audit.measure import AuditOptions, audit_design

    opts = AuditOptions(n_random=12, gait_ik=None, gait_plan=False, n_geometry=12, n_sweep=5, n_grid=3,
                        segment_step_m=0.001)
    rows = [audit_design(_femur_toy(skel, w), options=opts).pams[0] for w in (False, True)]
    bare, rolled = rows
    assert bare["segments"][0]["penetration_m"] > 0.007 and bare["segments"][0]["poses_over_limit_fraction"] == 1.0
    assert bare["rollers"] == []
    assert rolled["segments"][0]["penetration_m"] == 0.0
    (r,) = rolled["rollers"]
    assert r["segment"] == "a->b" and r["body"] == "femur_r"
    assert 0.0 < r["own_bone_distance_m"] < 0.005              # 4 mm off the bone (less the mesh's curvature)
    assert rolled["points_inside_own_bone"] == 0 and rolled["points_over_bracket"] == 0
    assert rolled["max_bracket_m"] >= r["own_bone_distance_m"]


def test_audit_counts_a_roller_inside_bone(skel):
    des = _femur_toy(skel, True)
    pam = des.pams[0]
    sunk = dataclasses.replace(pam.rollers[0], radius_m=0.02)        # a 20 mm roller reaches into the femur
    from pamkin.audit.measure import AuditOptions, audit_design

    opts = AuditOptions(n_random=4, gait_ik=None, gait_plan=False, n_geometry=4, n_sweep=5, n_grid=3,
                        segment_step_m=0.002)
    row = audit_design(des.replace_pam(dataclasses.replace(pam, rollers=(sunk,))), options=opts).pams[0]
    assert row["rollers"][0]["own_bone_distance_m"] < 0 and row["points_inside_own_bone"] == 1


def test_view_draws_the_roller_and_the_cable_over_it(skel):
    """pamkin.viz.meshcat_view: a cylinder per roller at its place in its bone (the page's transforms against the
    roller's pose), and the route drawn through the tangent points."""
    import base64
    import re

    import umsgpack

    import pamkin
    from pamkin.viz.meshcat_view import build_view

    human = pamkin.gait2392()
    des = _femur_toy(skel, True)
    robot = PamRobot(des, skel)
    html = build_view(human, robot).html()
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in re.findall(r'^"([A-Za-z0-9+/=]+)",?$', html, re.MULTILINE)]
    tf = {c["path"]: np.array(c["matrix"], float).reshape(4, 4).T for c in cmds if c.get("type") == "set_transform"}
    objs = {c["path"] for c in cmds if c.get("type") == "set_object"}
    node = "/meshcat/pamkin/robot/pams/pam01_r/roller1"
    assert node in objs and node in tf
    ks = skel.kinematics.forward(np.zeros((1, len(skel.coordinates))))
    fem = skel.kinematics.frames.index("femur_r")
    rol = des.pams[0].rollers[0]
    np.testing.assert_allclose(tf[node][:3, 3], ks.body_p[0, fem] + ks.body_R[0, fem] @ np.array(rol.centre), atol=2e-6)
    np.testing.assert_allclose(tf[node][:3, 1], ks.body_R[0, fem] @ np.array(rol.axis), atol=2e-6)
    line = robot.polylines(ks)[0][0]
    (A, T1), (T2, B) = robot.route_pieces(ks, 0)[0]
    np.testing.assert_allclose(line, np.stack([A[0], T1[0], T2[0], B[0]]))


def test_optimize_refuses_a_seed_with_rollers(tmp_path, skel, capsys):
    """pamkin optimize does not model rollers yet: a seed design with one ends with a clear error (exit 2)
    naming the file and the PAM, and writes nothing."""
    from pamkin.cli import main

    des = _femur_toy(skel, True)
    path = save_design(dataclasses.replace(des, name="rolled"), tmp_path / "rolled.yaml")
    assert main(["optimize", "--design", str(path), "--out", str(tmp_path / "run"), "--no-audit"]) == 2
    err = capsys.readouterr().err
    assert "rolled.yaml" in err and "PAM(s) [1] have rollers" in err
    assert not (tmp_path / "run").exists()


def test_exported_rollers_load_back_into_pamkin(tmp_path, skel):
    """export-osim then pamkin.load_osim: the routes come back as wrapped paths (the rollers as WrapCylinders
    on their bodies) with the design's lengths and moment arms, both sides."""
    import pamkin
    from pamkin.robot.osim_export import design_to_osim
    from pamkin.human.urdf import GAIT2392_DATA, load_model_data

    des = load_design("v2_seed", bodies=skel.bodies)
    rol = Roller("p1->p2", "femur_r", (-0.06, -0.1, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0), 0.01)
    des = des.replace_pam(dataclasses.replace(des.pam(4), rollers=(rol,), pam_on=None))
    path = design_to_osim(des, load_model_data(GAIT2392_DATA), tmp_path / "rolled.osim")
    back = pamkin.load_osim(path)
    assert back.wrapping is not None
    robot = PamRobot(des, skel)
    q = _random_q(skel, des, 30)
    qm = np.zeros((len(q), len(back.coordinates)))
    for i, c in enumerate(skel.coordinates):
        qm[:, back.coordinates.index(c)] = q[:, i]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st = robot.evaluate(q)
        L = back.lengths(qm)
        R = back.moment_arms(qm)
    cols = [back.muscles.index(n) for n in robot.names]
    np.testing.assert_allclose(L[:, cols], st.lengths, rtol=0, atol=1e-12)
    ci = [back.coordinates.index(c) for c in skel.coordinates]
    np.testing.assert_allclose(R[:, cols][:, :, ci], st.moment_arms, rtol=0, atol=1e-8)
    wrapped = [robot.names.index("pam04_r"), robot.names.index("pam04_l")]
    assert np.any(np.abs(st.lengths[:, wrapped] - PamRobot(load_design("v2_seed", bodies=skel.bodies), skel)
                         .evaluate(q).lengths[:, wrapped]) > 1e-6)
