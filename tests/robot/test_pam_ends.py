"""Where a PAM sits on its route (``pam_at``, ``pam_on``): the design file, the audit's PAM bodies and the
optimiser's choice of segments and ends (optimize.pam_clearance.choose_ends) on PAMs side by side on the femur."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import pamkin
from pamkin.audit.measure import AuditOptions, audit_design
from pamkin.robot.design import Design, Pam, design_from_dict, load_design, save_design
from pamkin.errors import DataFileError
from pamkin.opensim.model_file import PathPoint
from pamkin.human.rom import load_rom


def _pam(i: int, x: float, pam_at: str | None = None) -> Pam:
    """A 20 mm PAM on a femur-fixed route: 0.30 m then 0.05 m down the thigh, 10 mm apart in x per PAM;
    its body (0.10 m PAM + 2 × 12.5 mm fittings) sits at the top or the bottom of the first segment."""
    pts = (PathPoint("a", "femur_r", (x, -0.05, 0.03)), PathPoint("b", "femur_r", (x, -0.35, 0.03)),
           PathPoint("c", "femur_r", (x, -0.40, 0.03)))
    return Pam(i, f"toy {i}", ("vas_med_r",), "knee_angle_r", (), 20, 1, 0.10, 0.35 - 0.025 - 0.10, pts,
               pam_at=pam_at)


def test_design_file_keeps_pam_at(tmp_path):
    des = load_design("thesis")
    p = dataclasses.replace(des.pam(12), pam_at="insertion")
    again = load_design(save_design(des.replace_pam(p), tmp_path / "d.yaml"))
    assert again.pam(12).pam_at == "insertion" and again.pam(13).pam_at is None
    d = again.to_dict()
    assert d["pams"][11]["pam_at"] == "insertion" and "pam_at" not in d["pams"][12]
    d["pams"][11]["pam_at"] = "middle"
    with pytest.raises(DataFileError, match=r"id 12.*pam_at must be one of \('origin', 'insertion'\)"):
        design_from_dict(d, "bad.yaml")


def _pairs(des: Design) -> int:
    from pamkin.audit.scorecard import scorecard_text

    opts = AuditOptions(n_random=40, gait_ik=None, gait_plan=False, n_geometry=40, n_sweep=5, n_grid=3,
                        segment_step_m=0.05)
    res = audit_design(des, options=opts)
    assert all(r["on_one_segment"] and r["mount_segment"] == "a->b" for r in res.pams)
    rows = {int(line.split()[0]): line for line in scorecard_text(res).splitlines()
            if " toy " in line and line.split()[0].isdigit()}     # the PAM table's rows
    for r in res.pams:                    # the scorecard's 1seg column names the end
        assert f" yes/{r['pam_at'][0]} " in rows[r["id"]]
    return res.summary["pam_pairs_intersecting"], [r["pam_at"] for r in res.pams]


def test_audit_puts_the_body_at_its_end_and_choose_ends_separates_the_pair():
    """Both bodies at the top of the thigh (the default, origin end: both ends of a->b are fixed, the route
    being on one bone) lie 10 mm apart with 15 mm radii: the audit counts the pair. choose_ends moves one
    to the bottom end (the bodies 0.05 m apart along the thigh): the audit counts none; asking for the
    insertion end by hand gives the same bodies."""
    from pamkin.optimize.pam_clearance import choose_ends

    both = Design("toy", (_pam(1, 0.0), _pam(2, 0.01)), rom="robot_thesis")
    assert _pairs(both) == (1, ["origin", "origin"])
    chosen, lines = choose_ends(both, pamkin.gait2392(), load_rom("robot_thesis", "r"), seed=0, n_random=20)
    sides = sorted(p.pam_at for p in chosen.pams)
    assert sides == ["insertion", "origin"], lines
    assert lines[-1].startswith("PAM ends: intersecting pairs at the run's check poses: same side 1 -> 0")
    moved = next(p for p in chosen.pams if p.pam_at == "insertion")
    assert any(f"actuator {moved.id} toy {moved.id} anchored at the insertion end" in s for s in lines)
    assert _pairs(chosen)[0] == 0
    by_hand = Design("toy", (_pam(1, 0.0), _pam(2, 0.01, "insertion")), rom="robot_thesis")
    assert _pairs(by_hand) == (0, ["origin", "insertion"])
    # the routes, sizes and so the torques do not change
    q = np.zeros((3, len(pamkin.gait2392().coordinates)))
    from pamkin.robot.biped import PamRobot
    np.testing.assert_array_equal(PamRobot(chosen, sides=("r",)).evaluate(q).torques,
                                  PamRobot(both, sides=("r",)).evaluate(q).torques)


def test_view_draws_the_pam_at_its_end():
    """pamkin.viz.meshcat_view draws the PAM (fittings excluded) where the audit puts its body: on a->b from the top
    (origin end) for PAM 1, ending one fitting above b (insertion end) for PAM 2 — the set_transform of each
    cylinder in the page against the route points by hand (float32 in the page)."""
    import base64
    import re

    import umsgpack

    from pamkin.robot.biped import PamRobot
    from pamkin.viz.meshcat_view import build_view

    human = pamkin.gait2392()
    des = Design("toy", (_pam(1, 0.0), _pam(2, 0.01, "insertion")), rom="robot_thesis")
    robot = PamRobot(des, human)
    html = build_view(human, robot).html()
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in re.findall(r'^"([A-Za-z0-9+/=]+)",?$', html, re.MULTILINE)]
    tf = {c["path"]: np.array(c["matrix"], float).reshape(4, 4).T for c in cmds if c.get("type") == "set_transform"}
    X, _ = robot.paths.point_positions(human.kinematics.forward(np.zeros((1, len(human.coordinates)))))
    fit, pam_len = des.fitting_length_m, 0.10                       # at rest at q = 0 (tendon chosen so)
    for k, (start, name) in enumerate(((fit, "pam01_r"), (0.30 - fit - pam_len, "pam02_r"))):
        A, B = X[0, 3 * k], X[0, 3 * k + 1]
        u = (B - A) / np.linalg.norm(B - A)
        T = tf[f"/meshcat/pamkin/robot/pams/{name}/pam/s0"]
        np.testing.assert_allclose(T[:3, 3], A + (start + pam_len / 2) * u, atol=2e-6)
        assert np.linalg.norm(T[:3, 1]) == pytest.approx(pam_len, abs=2e-6)      # length scale on the y axis


def test_audit_names_an_end_the_route_does_not_allow():
    """pam_at: insertion on a PAM whose route goes on over the knee after its mount segment (a->b on the
    femur, then to the tibia): no constant tendon keeps it at b, so the audit puts it at a and says so."""
    from pamkin.audit.scorecard import scorecard_text

    from pamkin.robot.biped import PamRobot

    p = _pam(1, 0.0, "insertion")
    pts = (*p.points[:2], PathPoint("c", "tibia_r", (0.0, -0.05, 0.03)))
    q0 = np.zeros((1, len(pamkin.gait2392().coordinates)))
    L0 = PamRobot(Design("t", (dataclasses.replace(p, points=pts),)), sides=("r",)).evaluate(q0).lengths[0, 0]
    p = dataclasses.replace(p, points=pts, tendon_length_m=float(L0) - 0.025 - 0.10)   # at rest at q = 0
    opts = AuditOptions(n_random=40, gait_ik=None, gait_plan=False, n_geometry=40, n_sweep=5, n_grid=3,
                        segment_step_m=0.05)
    res = audit_design(Design("toy", (p,), rom="robot_thesis"), options=opts)
    row = res.pams[0]
    assert row["on_one_segment"] and row["mount_segment"] == "a->b"
    assert row["pam_at"] == "origin" and row["pam_at_not_possible"] == "insertion"
    assert "pam_at not possible (the route on that side of the mount segment changes length, or the PAM is not " \
           "on one segment), ignored: 1 toy 1 (insertion)" in scorecard_text(res)


def test_audit_view_draws_the_pam_bodies_where_the_audit_puts_them(tmp_path):
    """pamkin.viz.audit_page.audit_view: a translucent cylinder per PAM body at the default pose, of the assumed
    outer radius, centred where the audit's body lies (PAM 1 from a, PAM 2 ending at b), orange where the
    PAM intersects another (here PAM 1 with a PAM 3 beside it), grey otherwise."""
    import base64
    import re

    import umsgpack

    from pamkin.robot import festo
    from pamkin.viz.audit_page import audit_view
    from pamkin.robot.biped import PamRobot, robot_skeleton

    des = Design("toy", (_pam(1, 0.0), _pam(2, 0.03, "insertion"), _pam(3, -0.01)), rom="robot_thesis")
    opts = AuditOptions(n_random=40, gait_ik=None, gait_plan=False, n_geometry=40, n_sweep=5, n_grid=3,
                        segment_step_m=0.05)
    res = audit_design(des, options=opts)
    assert [r["intersects"] for r in res.pams] == [[3], [], [1]]
    html = audit_view(res, tmp_path / "view.html").read_text()
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in re.findall(r'^"([A-Za-z0-9+/=]+)",?$', html, re.MULTILINE)]
    objs = {c["path"]: c for c in cmds if c.get("type") == "set_object"}
    tf = {c["path"]: np.array(c["matrix"], float).reshape(4, 4).T for c in cmds if c.get("type") == "set_transform"}
    skel = robot_skeleton()
    q0 = skel.default_q[None, :].copy()
    q0[0, skel.coordinates.index("pelvis_ty")] = 0.0
    X, _ = PamRobot(des, skel, sides=("r",)).paths.point_positions(skel.kinematics.forward(q0))
    body = 0.10 + 2 * des.fitting_length_m                         # each PAM at rest at the default pose
    for k, (start, color) in enumerate(((0.0, 0xFF7F0E), (0.30 - body, 0x7F7F7F), (0.0, 0xFF7F0E))):
        path = f"/meshcat/pamkin/bodies/pam{k + 1:02d}/s0"
        geom = objs[path]["object"]["geometries"][0]
        assert geom["type"] == "CylinderGeometry" and geom["height"] == pytest.approx(body, abs=1e-6)
        assert geom["radiusTop"] == pytest.approx(festo.outer_diameter(20) / 2)
        assert objs[path]["object"]["materials"][0]["color"] == color
        A, B = X[0, 3 * k], X[0, 3 * k + 1]
        u = (B - A) / np.linalg.norm(B - A)
        np.testing.assert_allclose(tf[path][:3, 3], A + (start + body / 2) * u, atol=2e-6)


def _two_segment_pair(pam_on: str | None = None) -> Design:
    """PAM 1 on a femur-fixed route a -> b -> c (0.15 m then 0.20 m down the thigh): its body (0.10 m PAM
    + 2 x 12.5 mm fittings) fits on both segments, best (most room) on b->c. PAM 2, 10 mm beside it, on
    d -> e at 0.25–0.40 m: its body lies beside b->c at either end, never beside a->b."""
    p1 = Pam(1, "toy 1", ("vas_med_r",), "knee_angle_r", (), 20, 1, 0.10, 0.35 - 0.025 - 0.10,
             (PathPoint("a", "femur_r", (0.0, -0.05, 0.03)), PathPoint("b", "femur_r", (0.0, -0.20, 0.03)),
              PathPoint("c", "femur_r", (0.0, -0.40, 0.03))), pam_on=pam_on)
    p2 = Pam(2, "toy 2", ("vas_med_r",), "knee_angle_r", (), 20, 1, 0.10, 0.15 - 0.025 - 0.10,
             (PathPoint("d", "femur_r", (0.01, -0.25, 0.03)), PathPoint("e", "femur_r", (0.01, -0.40, 0.03))))
    return Design("toy", (p1, p2), rom="robot_thesis")


def _audit_toy(des: Design):
    opts = AuditOptions(n_random=40, gait_ik=None, gait_plan=False, n_geometry=40, n_sweep=5, n_grid=3,
                        segment_step_m=0.05)
    return audit_design(des, options=opts)


def test_design_file_keeps_pam_on(tmp_path):
    des = _two_segment_pair("a->b")
    again = load_design(save_design(des, tmp_path / "d.yaml"))
    assert again.pam(1).pam_on == "a->b" and again.pam(2).pam_on is None
    d = again.to_dict()
    assert d["pams"][0]["pam_on"] == "a->b" and "pam_on" not in d["pams"][1]
    d["pams"][0]["pam_on"] = "a->c"
    with pytest.raises(DataFileError, match=r"id 1.*pam_on must name a segment of its route \['a->b', 'b->c'\]"):
        design_from_dict(d, "bad.yaml")


def test_choose_ends_moves_a_body_to_its_other_segment():
    """By default PAM 1's body sits on b->c (more room), beside PAM 2's: the audit counts the pair at either
    end of either body. choose_ends moves PAM 1 to a->b (no end of b->c separates them) and writes pam_on;
    the audit puts the body there (50 mm above PAM 2's) and counts none; the torques are unchanged."""
    from pamkin.optimize.pam_clearance import choose_ends
    from pamkin.robot.biped import PamRobot

    des = _two_segment_pair()
    res = _audit_toy(des)
    assert [r["mount_segment"] for r in res.pams] == ["b->c", "d->e"]
    assert res.summary["pam_pairs_intersecting"] == 1
    chosen, lines = choose_ends(des, pamkin.gait2392(), load_rom("robot_thesis", "r"), seed=0, n_random=20)
    assert chosen.pam(1).pam_on == "a->b" and chosen.pam(2).pam_on == "d->e", lines
    assert any(s.startswith("PAM ends: actuator 1 toy 1 anchored at the ") and "end of segment a->b (default "
               "origin end of b->c)" in s for s in lines), lines
    assert lines[-1].startswith("PAM ends: intersecting pairs at the run's check poses: same side 1 -> 0")
    res2 = _audit_toy(chosen)
    assert [r["mount_segment"] for r in res2.pams] == ["a->b", "d->e"]
    assert res2.summary["pam_pairs_intersecting"] == 0 and all(r["on_one_segment"] for r in res2.pams)
    assert not any(r["pam_on_not_possible"] for r in res2.pams)
    q = np.zeros((3, len(pamkin.gait2392().coordinates)))
    np.testing.assert_array_equal(PamRobot(chosen, sides=("r",)).evaluate(q).torques,
                                  PamRobot(des, sides=("r",)).evaluate(q).torques)


def test_audit_names_a_segment_the_body_does_not_fit_on():
    """pam_on: a->b on PAM 1 with a 0.15 m PAM (body 0.175 m): it does not fit on the 0.15 m a->b, so the
    audit puts it on b->c and says so."""
    from pamkin.audit.scorecard import scorecard_text

    des = _two_segment_pair("a->b")
    p1 = dataclasses.replace(des.pam(1), resting_length_m=0.15, tendon_length_m=0.35 - 0.025 - 0.15)
    res = _audit_toy(des.replace_pam(p1))
    row = res.pams[0]
    assert row["mount_segment"] == "b->c" and row["on_one_segment"] and row["pam_on_not_possible"] == "a->b"
    assert "pam_on not possible (the PAM body does not fit on that segment with a constant tendon), the segment " \
           "that holds it best used: 1 toy 1 (a->b)" in scorecard_text(res)


def test_choose_ends_keeps_a_racked_body_on_its_rack():
    """The pair of the first test with PAM 1 hung on a rack whose body lies 10 mm beside PAM 2's at the top of
    the thigh: the choice of ends leaves the racked PAM where its rack holds it (pam_on on the rack's piece,
    no line for it) and separates the pair by moving PAM 2 to the bottom end of its segment."""
    from pamkin.optimize.pam_clearance import choose_ends
    from pamkin.robot.rack import ANCHOR, GUIDE, RackMount, rack_pam

    mount = RackMount("origin", "femur_r", (0.02, -0.05, 0.03), (0.02, -0.36, 0.03))
    racked = rack_pam(_pam(1, 0.0), mount)
    des = Design("toy", (racked, _pam(2, 0.01)), rom="robot_thesis")
    chosen, lines = choose_ends(des, pamkin.gait2392(), load_rom("robot_thesis", "r"), seed=0, n_random=20)
    assert chosen.pam(1).pam_on == f"{ANCHOR}->{GUIDE}" and chosen.pam(1).pam_at == "origin"
    assert chosen.pam(1).points == racked.points
    assert not any("actuator 1 toy 1 anchored" in s for s in lines), lines
    assert chosen.pam(2).pam_at == "insertion", lines
    assert lines[-1].startswith("PAM ends: intersecting pairs at the run's check poses: same side 1 -> 0"), lines
