"""Path wrapping against OpenSim 4.6: lengths at random configurations and moment arms against central
differences of OpenSim's own lengths (OpenSim's computeMomentArm is off with wrapping; its gap is printed).

Models: Arm26 (WrapCylinder, WrapEllipsoid, three wraps on one path), Rajagopal2016 (WrapCylinder, couplers,
locked coordinates) and a small two-link arm written here with every wrap type (cylinder, sphere, ellipsoid,
torus), quadrant, method and ranges.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import yaml
from opensim_ref import SHARED, opensim_reference

import pamkin
from pamkin.human.model import Model
from pamkin.errors import OsimError, UnsupportedFeatureError
from pamkin.opensim.model_file import (
    SkippedComponentsWarning,
    load_osim_file,
    model_from_dict,
    model_to_dict,
)

MODELS = SHARED / "opensim-models" / "Models"
ARM26 = MODELS / "Arm26" / "arm26.osim"
RAJAGOPAL = MODELS / "Rajagopal" / "Rajagopal2016.osim"

pytestmark = [pytest.mark.needs_shared, pytest.mark.opensim]

H = 1e-6           # central-difference step of the reference (pamkin uses Model.WRAP_STEP)


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        return pamkin.load_osim(path)


def compare_with_opensim(path, n: int, seed: int = 0, label: str = ""):
    """Lengths and moment arms of the wrapped model at ``n`` random configurations against OpenSim 4.6.

    Returns:
        (length error, moment-arm error away from switches, fraction of pairs kept, OpenSim computeMomentArm gap
        as (gap, muscle, coordinate) sorted largest first).
    """
    model = _load(path)
    q = model.random_q(n, seed=seed)
    res = model.path_result(q)
    ref = opensim_reference(path, q, ("lengths", "moment_arms"))
    assert list(ref["muscles"]) == model.muscles
    err_L = np.abs(res.lengths - ref["lengths"]).max()
    # central differences of OpenSim's lengths (steps H and 10 H: pairs where they disagree straddle a switch);
    # OpenSim's Coordinate.setValue leaves a locked coordinate unchanged: no reference about those
    locked = [i for i, c in enumerate(model.osim.coordinates) if c.locked]
    keep = ~np.isin(res.pairs[:, 1], locked)
    pairs, res_R = res.pairs[keep], res.moment_arms[:, keep]
    coords = sorted({int(c) for c in pairs[:, 1]})
    Q = []
    for c in coords:
        for step in (H, -H, 10 * H, -10 * H):
            qq = q.copy()
            qq[:, c] += step
            Q.append(model.kinematics.fill_dependent(qq))
    Lr = opensim_reference(path, np.concatenate(Q), ("lengths",))["lengths"].reshape(len(coords), 4, n, -1)
    ci = np.array([coords.index(c) for c in pairs[:, 1]])
    fd = -(Lr[ci, 0, :, pairs[:, 0]] - Lr[ci, 1, :, pairs[:, 0]]).T / (2 * H)
    fd10 = -(Lr[ci, 2, :, pairs[:, 0]] - Lr[ci, 3, :, pairs[:, 0]]).T / (20 * H)
    smooth = np.abs(fd - fd10) < 1e-6
    err_R = np.abs(res_R - fd)[smooth].max()
    index = {(int(m), int(c)): k for k, (m, c) in enumerate(ref["pairs"])}
    gap = []
    for k, (m, c) in enumerate(pairs):
        if (int(m), int(c)) in index:
            g = np.abs(ref["moment_arms"][:, index[(int(m), int(c))]] - fd[:, k])[smooth[:, k]]
            if g.size:
                gap.append((float(g.max()), model.muscles[m], model.coordinates[c]))
    gap.sort(reverse=True)
    print(f"\n{label or path.name}: {n} configurations, lengths max |pamkin - OpenSim| = {err_L:.2e} m, "
          f"moment arms max |pamkin - central difference of OpenSim lengths| = {err_R:.2e} m "
          f"({smooth.mean():.1%} of pairs away from switches); OpenSim computeMomentArm vs -dL/dq: "
          + ", ".join(f"{mu}/{co} {g * 100:.3f} cm" for g, mu, co in gap[:4]))
    return err_L, err_R, smooth.mean(), gap


def test_arm26_matches_opensim():
    err_L, err_R, kept, gap = compare_with_opensim(ARM26, 30, seed=1)
    assert err_L < 1e-7 and err_R < 1e-6 and kept > 0.8
    assert gap[0][1] == "TRIlong" and gap[0][0] > 1e-3     # OpenSim's own moment arm is off by ~1 cm
    # Thelen2003 tendon forces on the wrapped lengths
    model = _load(ARM26)
    q = model.random_q(30, seed=1)
    ref = opensim_reference(ARM26, q, ("tendon_forces",))["tendon_forces"]
    F = model.tendon_forces(q)
    assert (np.abs(F - ref) / np.maximum(1.0, np.abs(ref))).max() < 1e-4


def test_rajagopal_matches_opensim():
    err_L, err_R, kept, _ = compare_with_opensim(RAJAGOPAL, 12, seed=2)
    assert err_L < 1e-7 and err_R < 1e-6 and kept > 0.8


# ----------------------------------------------------------------------------- a small arm with every wrap type
def _wrap(kind, name, dims, quadrant="all", rotation="0 0 0", translation="0 -0.3 0", active="true"):
    props = {"WrapCylinder": "<radius>{}</radius><length>{}</length>", "WrapSphere": "<radius>{}</radius>",
             "WrapEllipsoid": "<dimensions>{} {} {}</dimensions>",
             "WrapTorus": "<inner_radius>{}</inner_radius><outer_radius>{}</outer_radius>"}[kind].format(*dims)
    return (f'<{kind} name="{name}"><active>{active}</active><xyz_body_rotation>{rotation}</xyz_body_rotation>'
            f"<translation>{translation}</translation><quadrant>{quadrant}</quadrant>{props}</{kind}>")


def _muscle(name, points, wraps):
    """A Thelen2003Muscle; points are (body, location) or raw XML of other path point types."""
    pts = "".join(pt if isinstance(pt, str) else
                  f'<PathPoint name="{name}-P{i + 1}"><socket_parent_frame>{"/ground" if pt[0] == "ground" else "/bodyset/" + pt[0]}'
                  f"</socket_parent_frame><location>{pt[1]}</location></PathPoint>" for i, pt in enumerate(points))
    pws = "".join(f'<PathWrap name="{name}-w{i}"><wrap_object>{w}</wrap_object><method>{m}</method>'
                  f"<range>{r}</range></PathWrap>" for i, (w, m, r) in enumerate(wraps))
    return (f'<Thelen2003Muscle name="{name}"><GeometryPath name="path"><PathPointSet><objects>{pts}</objects>'
            f"</PathPointSet><PathWrapSet><objects>{pws}</objects></PathWrapSet></GeometryPath>"
            "<max_isometric_force>100</max_isometric_force><optimal_fiber_length>0.1</optimal_fiber_length>"
            "<tendon_slack_length>0.2</tendon_slack_length><pennation_angle_at_optimal>0</pennation_angle_at_optimal>"
            "</Thelen2003Muscle>")


def _pin(name, parent, child, coord, rng, at):
    return (f'<PinJoint name="{name}"><socket_parent_frame>{parent}_offset</socket_parent_frame>'
            f"<socket_child_frame>{child}_offset</socket_child_frame><coordinates>"
            f'<Coordinate name="{coord}"><default_value>0</default_value><range>{rng}</range><clamped>false</clamped>'
            f"<locked>false</locked></Coordinate></coordinates><frames>"
            f'<PhysicalOffsetFrame name="{parent}_offset"><socket_parent>{"/ground" if parent == "ground" else "/bodyset/" + parent}'
            f"</socket_parent><translation>{at}</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>"
            f'<PhysicalOffsetFrame name="{child}_offset"><socket_parent>/bodyset/{child}</socket_parent>'
            f"<translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>"
            f"</frames></PinJoint>")


def _body(name, wraps="", components=""):
    return (f'<Body name="{name}"><mass>1</mass><mass_center>0 -0.15 0</mass_center>'
            f"<inertia>0.01 0.01 0.01 0 0 0</inertia><components>{components}</components>"
            f"<WrapObjectSet><objects>{wraps}</objects></WrapObjectSet></Body>")


# a wrap object on an offset frame of the lower arm
PAD_FRAME = ('<PhysicalOffsetFrame name="pad_frame"><socket_parent>..</socket_parent><translation>0.002 -0.15 0.001'
             "</translation><orientation>0.1 -0.05 0.3</orientation><WrapObjectSet><objects>"
             + _wrap("WrapCylinder", "pad", (0.012, 0.05), translation="0 0 0.002") + "</objects></WrapObjectSet>"
             "</PhysicalOffsetFrame>")


ELBOW_WRAPS = "".join([
    _wrap("WrapCylinder", "cyl", (0.02, 0.1)),
    _wrap("WrapCylinder", "cyl_mx", (0.02, 0.1), "-x", rotation="0.1 -0.05 0"),
    _wrap("WrapCylinder", "cyl_px", (0.015, 0.1), "+x", translation="-0.015 -0.29 0"),
    _wrap("WrapSphere", "sph", (0.022,)),
    _wrap("WrapSphere", "sph_mx", (0.022,), "-x"),
    _wrap("WrapEllipsoid", "ell", (0.03, 0.02, 0.025), rotation="0.3 0.2 0.1"),
    _wrap("WrapEllipsoid", "ell_mx", (0.03, 0.02, 0.025), "-x", rotation="0.3 0.2 0.1"),
    _wrap("WrapEllipsoid", "ell_y", (0.025, 0.02, 0.03), "y", rotation="-0.2 0.1 0.4"),
    _wrap("WrapCylinder", "off", (0.02, 0.1), active="false"),
    _wrap("WrapTorus", "ring", (0.01, 0.05), rotation="1.5707963 0 0", translation="0 -0.2 0"),
    _wrap("WrapTorus", "ring_mx", (0.012, 0.035), "-x", rotation="1.5707963 0.3 0", translation="0.01 -0.22 0"),
])
SHOULDER_WRAPS = _wrap("WrapSphere", "gsph", (0.02,), translation="0 0 0")
BACK = [("upper", "-0.025 -0.15 0.01"), ("lower", "-0.02 -0.08 -0.012")]     # behind the elbow
FRONT = [("upper", "0.02 -0.12 0.005"), ("lower", "0.015 -0.07 -0.01")]
COND = ('<ConditionalPathPoint name="cond"><socket_parent_frame>/bodyset/upper</socket_parent_frame>'
        "<location>-0.03 -0.27 0</location><range>0.8 1.6</range>"
        "<socket_coordinate>/jointset/elbow/q2</socket_coordinate></ConditionalPathPoint>")
MOVING = ('<MovingPathPoint name="moving"><socket_parent_frame>/bodyset/lower</socket_parent_frame>'
          "<x_location><LinearFunction><coefficients>0.01 -0.03</coefficients></LinearFunction></x_location>"
          "<y_location><Constant><value>-0.08</value></Constant></y_location>"
          "<z_location><Constant><value>-0.01</value></Constant></z_location>"
          "<socket_x_coordinate>/jointset/elbow/q2</socket_x_coordinate>"
          "<socket_y_coordinate>/jointset/elbow/q2</socket_y_coordinate>"
          "<socket_z_coordinate>/jointset/elbow/q2</socket_z_coordinate></MovingPathPoint>")
TWO_LINK_MUSCLES = [
    ("cyl_all", BACK, [("cyl", "hybrid", "-1 -1")]),
    ("cyl_mx", BACK, [("cyl_mx", "hybrid", "-1 -1")]),
    ("cyl_px", BACK, [("cyl_px", "hybrid", "-1 -1")]),
    ("sph_all", BACK, [("sph", "hybrid", "-1 -1")]),
    ("sph_mx", BACK, [("sph_mx", "hybrid", "-1 -1")]),
    ("ell_hybrid", BACK, [("ell", "hybrid", "-1 -1")]),
    ("ell_midpoint", BACK, [("ell", "midpoint", "-1 -1")]),
    ("ell_axial", BACK, [("ell", "axial", "-1 -1")]),
    ("ell_mx", BACK, [("ell_mx", "hybrid", "-1 -1")]),
    ("ell_y", BACK, [("ell_y", "midpoint", "-1 -1")]),
    ("inactive", BACK, [("off", "hybrid", "-1 -1")]),
    # ground → upper → lower with a wrap at each joint, each limited to its own segment by its range
    ("two_ranges", [("ground", "-0.03 0.05 0.01"), ("upper", "-0.03 -0.1 0.005"), ("lower", "-0.02 -0.1 0")],
     [("gsph", "hybrid", "1 2"), ("cyl_mx", "hybrid", "2 3")]),
    # two wraps on one segment: OpenSim's iteration between them
    ("cyl_ell", BACK, [("cyl", "hybrid", "-1 -1"), ("ell_mx", "hybrid", "-1 -1")]),
    ("sph_cyl", BACK, [("sph", "hybrid", "-1 -1"), ("cyl_mx", "hybrid", "-1 -1")]),
    ("torus", [("upper", "-0.07 -0.1 0.01"), ("lower", "-0.02 -0.08 -0.012")], [("ring", "hybrid", "-1 -1")]),
    ("torus_mx", [("upper", "-0.05 -0.1 0.01"), ("lower", "-0.02 -0.08 -0.012")], [("ring_mx", "hybrid", "-1 -1")]),
    # a conditional point inside the wrap's range (range scans to the next/previous active point) and a
    # moving point
    ("cond_range23", [("upper", "-0.025 -0.15 0.01"), COND, MOVING], [("cyl", "hybrid", "2 3")]),
    ("cond_range12", [("upper", "-0.025 -0.15 0.01"), COND.replace("-0.03 -0.27 0", "-0.02 -0.35 0.005"), MOVING],
     [("ell", "hybrid", "1 2")]),
    ("cond_all", [("upper", "-0.025 -0.15 0.01"), COND, MOVING], [("ell", "midpoint", "-1 -1")]),
    ("offset_frame", [("upper", "-0.025 -0.15 0.01"), ("lower", "-0.005 -0.25 0")], [("pad", "hybrid", "-1 -1")]),
]


def two_link_arm(path, muscles=TWO_LINK_MUSCLES):
    text = ('<?xml version="1.0" encoding="UTF-8" ?><OpenSimDocument Version="40000"><Model name="wraparm">'
            f'<Ground name="ground"><WrapObjectSet><objects>{SHOULDER_WRAPS}</objects></WrapObjectSet></Ground>'
            f"<BodySet><objects>{_body('upper', ELBOW_WRAPS)}{_body('lower', components=PAD_FRAME)}</objects></BodySet>"
            f"<JointSet><objects>{_pin('shoulder', 'ground', 'upper', 'q1', '-1 1', '0 0 0')}"
            f"{_pin('elbow', 'upper', 'lower', 'q2', '0 2.4', '0 -0.3 0')}</objects></JointSet>"
            f"<ForceSet><objects>{''.join(_muscle(*m) for m in muscles)}</objects></ForceSet>"
            "</Model></OpenSimDocument>")
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def arm_path(tmp_path_factory):
    return two_link_arm(tmp_path_factory.mktemp("wrap") / "wraparm.osim")


def test_two_link_arm_every_wrap_type(arm_path):
    err_L, err_R, kept, _ = compare_with_opensim(arm_path, 40, seed=3, label="two-link arm")
    assert err_L < 1e-7 and err_R < 1e-6 and kept > 0.8
    # the wraps do something: each wrapped path differs from its straight line somewhere, except the inactive one
    model = _load(arm_path)
    q = model.random_q(40, seed=3)
    straight = model.paths.evaluate(model.kinematics.forward(q), moment_arms=False).lengths
    wrapped = model.lengths(q)
    differs = np.abs(wrapped - straight).max(axis=0) > 1e-4
    assert differs.tolist() == [m != "inactive" for m in model.muscles]


def test_wraps_survive_the_data_round_trip():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        m = load_osim_file(ARM26)
    back = model_from_dict(yaml.safe_load(yaml.safe_dump(model_to_dict(m))), m.path)
    assert back.muscles == m.muscles and all(a.wraps == b.wraps for a, b in zip(back.muscles, m.muscles))
    assert sum(len(x.wraps) for x in back.muscles) == 7


def test_compiled_loop_equals_python_loop(arm_path):
    for path in (arm_path, ARM26):
        model = _load(path)
        q = model.random_q(60, seed=4)
        W = model.wrapping
        assert W.compiled
        fast = model.path_result(q)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SkippedComponentsWarning)
            slow = pamkin.load_osim(path, engine="numpy")
        assert not slow.wrapping.compiled
        state = model.kinematics.forward(q)
        assert np.array_equal(slow.wrapping.lengths(state), W.lengths(state))   # the loops agree exactly
        ref = slow.path_result(q)
        assert np.array_equal(ref.pairs, fast.pairs)
        # round-off of the engines' kinematics, relative: the two-link arm's pathological sph_cyl path is 11 m long
        # with 120 m moment arms (central differences divide the round-off by 2e-6)
        assert (np.abs(ref.lengths - fast.lengths) / np.maximum(1.0, np.abs(ref.lengths))).max() < 1e-11
        assert (np.abs(ref.moment_arms - fast.moment_arms) / np.maximum(1.0, np.abs(ref.moment_arms))).max() < 1e-6
        chunked = model.path_result(q, chunk=7)                          # bounded-memory chunks: same numbers
        assert np.array_equal(chunked.lengths, fast.lengths) and np.array_equal(chunked.moment_arms, fast.moment_arms)


def test_compiled_moment_arms_equal_central_differences_of_the_lengths(arm_path):
    """The compiled pass (:mod:`pamkin.human.wrapping_compiled`: straight segments analytic, the wrapped segment or the
    multi-wrap path differenced along the point and frame velocities) equals central differences of the
    wrapped lengths about each coordinate, couplers included (Rajagopal's knees), on every wrap type."""
    for path in (arm_path, ARM26, RAJAGOPAL):
        model = _load(path)
        assert model._fastwrap is not None
        q = model.random_q(40, seed=7)
        res = model.path_result(q)
        W = model.wrapping
        cols = {m: k for k, m in enumerate(W.indices)}
        h = Model.WRAP_STEP
        for c in sorted({int(c) for c in res.pairs[:, 1]}):
            qp, qm = q.copy(), q.copy()
            qp[:, c] += h
            qm[:, c] -= h
            Lp = model.lengths(model.kinematics.fill_dependent(qp))
            Lm = model.lengths(model.kinematics.fill_dependent(qm))
            for k in np.nonzero(res.pairs[:, 1] == c)[0]:
                m = int(res.pairs[k, 0])
                if m not in cols:
                    continue
                fd = -(Lp[:, m] - Lm[:, m]) / (2 * h)
                err = np.abs(res.moment_arms[:, k] - fd) / np.maximum(1.0, np.abs(fd))
                # away from wrap on/off switches (one sample in a few hundred straddles one at this step)
                assert np.mean(err < 1e-7) >= 0.95, (path.name, model.muscles[m], model.coordinates[c], err.max())
                assert np.median(err) < 1e-8


def test_obstacle_wraps_and_bad_wrap_settings_are_refused(tmp_path):
    p = two_link_arm(tmp_path / "a.osim")
    text = p.read_text()
    p.write_text(text.replace("WrapSphere name=\"gsph\"", "WrapCylinderObst name=\"gsph\"").replace(
        "<radius>0.02</radius></WrapSphere>", "<radius>0.02</radius></WrapCylinderObst>"))
    with pytest.raises(UnsupportedFeatureError, match=r"WrapCylinderObst"):
        pamkin.load_osim(p)
    for old, new, what in [("<quadrant>-x</quadrant>", "<quadrant>sideways</quadrant>", "quadrant"),
                           ("<method>midpoint</method>", "<method>spline</method>", "wrap method"),
                           ("<wrap_object>sph</wrap_object>", "<wrap_object>nothing</wrap_object>", "unknown wrap object"),
                           ("<range>1 2</range>", "<range>1 7</range>", "wrap range")]:
        p.write_text(text.replace(old, new, 1))
        with pytest.raises(OsimError, match=what):
            pamkin.load_osim(p)
