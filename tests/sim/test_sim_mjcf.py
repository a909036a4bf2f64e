"""The MuJoCo conversion (pamkin.sim): MJCF that MuJoCo loads, body placements and tendon geometry equal to
pamkin's (which equal OpenSim 4.6's) where the construct is exact, approximations within their stated bounds."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from locations import SHARED
from pamkin.human.model import gait2392, load_osim
from pamkin.robot.biped import design_robot
from pamkin.sim.convert import convert_model, convert_robot
from pamkin.sim.geometry import MjGeometry, compare
from pamkin.sim.joints import CoordinateMap
from pamkin.sim.measure import band_poses, exact_constructs
from pamkin.sim.mjcf import safe
from pamkin.opensim.model_file import load_osim_file

ARM26 = SHARED / "opensim-models" / "Models" / "Arm26" / "arm26.osim"
POSES = 24           # seeded held-out poses (the docs measure 1000)


@pytest.fixture(scope="module")
def g2392():
    return convert_model(gait2392())


@pytest.fixture(scope="module")
def robot():
    return convert_robot(design_robot())


def _errors(conv, seed=7):
    q = conv.model.random_q(POSES, seed=seed)
    L, R = MjGeometry(conv.compile(), conv.cmap, conv.paths).evaluate(q)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        Lr, Rr = conv.reference(q)
    return np.abs(L - Lr).max(axis=0), np.abs(R - Rr).max(axis=(0, 2))


def test_mjcf_loads_with_meshes_masses_and_joints(g2392):
    m = mujoco.MjModel.from_xml_string(g2392.mjcf(), g2392.meshes)
    osim = g2392.model.osim
    assert m.nmesh == len(g2392.meshes) > 10
    ties = sum(bool(j.terms) for j in g2392.cmap.joints)      # composed ties: one fixed tendon each
    assert m.ntendon - ties == len(osim.muscles) == 92
    knee = [j.name for j in g2392.cmap.joints if j.terms and j.body in {b.name for b in osim.bodies}]
    assert sorted(knee) == [f"knee_{s}_translation{k}" for s in "lr" for k in (1, 2)]
    for b in osim.bodies:
        i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, safe(b.name))
        assert m.body_mass[i] == pytest.approx(b.mass, rel=1e-12)
        assert np.allclose(m.body_ipos[i], b.mass_center, atol=1e-12)
    # every variable axis is one joint: 23 coordinates + 4 knee translations + the moving points' slides
    assert sum(j.body in {b.name for b in osim.bodies} for j in g2392.cmap.joints) == 27


def test_body_placements_equal_pamkin(g2392):
    """Every body frame in MuJoCo (tied joints at their polynomial) against pamkin's kinematics: exact except
    through the knee's spline translations (bounded by the polynomial's deviation)."""
    model = g2392.model
    q = model.random_q(POSES, seed=3)
    geo = MjGeometry(g2392.compile(), g2392.cmap, [])
    T = model.body_transforms(q)
    knee_err = max(j.error for j in g2392.cmap.joints if j.name.startswith("knee"))
    qpos = g2392.cmap.qpos(q)
    for n in range(POSES):
        geo.set_pose(qpos[n])
        for b in model.bodies:
            i = mujoco.mj_name2id(geo.model, mujoco.mjtObj.mjOBJ_BODY, safe(b))
            dp = np.abs(geo.data.xpos[i] - T[b][n, :3, 3]).max()
            dR = np.abs(geo.data.xmat[i].reshape(3, 3) - T[b][n, :3, :3]).max()
            below_knee = b in ("tibia_r", "talus_r", "calcn_r", "toes_r", "tibia_l", "talus_l", "calcn_l",
                               "toes_l")
            assert dR < 1e-12
            assert dp < (2 * knee_err if below_knee else 1e-12), b


def test_gait2392_exact_constructs_and_stated_bounds(g2392):
    dL, dR = _errors(g2392)
    exact = exact_constructs(g2392)
    assert exact.sum() == 62
    assert dL[exact].max() < 1e-6 and dR[exact].max() < 1e-6
    # muscles whose only approximation is the knee's composed coupling: lengths within 0.01 mm, moment arms
    # within 0.1 mm (the degree-4 polynomial of the quartic couplings: 0.2 mm and 1.8 mm)
    knee_only = np.array([not ex and not ch.conditional and not any(j.name.startswith(f"{ch.name}-")
                                                                    for j in g2392.cmap.joints)
                          for ex, ch in zip(exact, g2392.choices)])
    assert knee_only.sum() == 8            # bifemsh, the four lower-leg muscles crossing only the knee ...
    assert dL[knee_only].max() <= 1e-5 and dR[knee_only].max() <= 1e-4
    # conditional points as steps, patella points composed: the goal of 0.5 mm length away from the steps' bands
    # (rect_fem's conditional point has no fixed neighbour on its body: a small wrap geom, 0.5 mm)
    assert dL.max() <= 0.6e-3


def test_conditional_steps_exact_outside_their_band(g2392):
    """Psoas's pelvic-brim point (off outside −90°..45° hip flexion) as a step: MuJoCo's length equals pamkin's
    to 1e-9 m away from the switch, and in the band stays between OpenSim's two lengths (±1 mm)."""
    k = g2392.paths.index("psoas_r")
    step = g2392.choices[k].steps["psoas_r-P3"]
    assert step["switches"] == pytest.approx([-1.5708 - 1e-5, 0.785398 + 1e-5], abs=1e-9)
    assert g2392.summary()["paths"][k]["conditional_steps"]["psoas_r-P3"]["band"] == 2e-3   # conversion.json
    model = g2392.model
    c = model.coordinates.index("hip_flexion_r")
    q = np.repeat(model.random_q(1, seed=4), 7, axis=0)
    q[:, c] = [-1.9, -1.0, 0.3, 0.785398 + 1e-5 - 0.01, 1.2, 0.785398 + 1e-5, 0.785398 + 1e-5 + 4e-4]
    L, _ = MjGeometry(g2392.compile(), g2392.cmap, ["psoas_r"]).evaluate(q, moment_arms=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        Lr = conv_lengths(g2392, q)[:, k]
    assert np.abs(L[:5, 0] - Lr[:5]).max() < 1e-9
    on, off = Lr[3], Lr[4]             # the path with and without the point (hip angles 0.01 rad apart)
    assert abs(on - off) > 5e-3
    for n in (5, 6):                   # at the switch (site half-way) and 4e-4 rad past it (inside the band)
        assert min(on, off) - 1e-3 <= L[n, 0] <= max(on, off) + 1e-3
    # the measurement's band mask: the last two poses are inside psoas_r's band, the others outside
    inside = band_poses(g2392, q)[:, k]
    assert inside.tolist() == [False] * 5 + [True] * 2
    err = compare(["psoas_r"], L, np.zeros((7, 1, q.shape[1])), Lr[:, None], np.zeros((7, 1, q.shape[1])),
                  outside=~inside[:, None])
    assert err.length_max_out[0] < 1e-9 < err.length_max[0] and err.band_poses[0] == 2


def test_conditional_step_onto_a_neighbour_on_another_body(g2392):
    """Rectus femoris's femur point (on below −83.7° knee angle) collapses onto its neighbour, the moving patella
    point on the tibia: the step slides by activity × offset, products of exact ties ((a+b)² − (a−b)²)/4."""
    k = g2392.paths.index("rect_fem_r")
    step = g2392.choices[k].steps["rect_fem_r-P2"]
    assert step["switches"] == pytest.approx([-1.45997 + 1e-5], abs=1e-9) and step["offset_fit_error_m"] < 1e-5
    model = g2392.model
    q = np.repeat(model.random_q(1, seed=6), 4, axis=0)
    q[:, model.coordinates.index("knee_angle_r")] = [-2.0, -1.7, -1.2, 0.0]     # on, on, off, off
    L, _ = MjGeometry(g2392.compile(), g2392.cmap, ["rect_fem_r"]).evaluate(q, moment_arms=False)
    assert np.abs(L[:, 0] - conv_lengths(g2392, q)[:, k]).max() < 0.05e-3


def conv_lengths(conv, q):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return conv.reference(q)[0]


def test_mujoco_equalities_hold_at_the_evaluated_poses(g2392):
    """What the measurement sets (CoordinateMap.qpos: chains evaluated in Python) is what MuJoCo's joint and
    tendon equalities hold: every equality residual ≈ 0."""
    m = g2392.compile()
    d = mujoco.MjData(m)
    geo = MjGeometry(m, g2392.cmap, [])
    for row in g2392.cmap.qpos(g2392.model.random_q(5, seed=9)):
        d.qpos[geo.qadr] = row
        mujoco.mj_forward(m, d)
        eq = d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        assert eq.sum() > 100 and np.abs(d.efc_pos[eq]).max() < 1e-9


def test_quartic_couplings_option(g2392):
    """--couplings quartic: one degree-4 joint equality per spline, no auxiliary joints (the former construct;
    knee lengths within 0.5 mm, moment arms within 2 mm)."""
    conv = convert_model(g2392.model, couplings="quartic")
    assert not conv.cmap.aux_bodies and all(not j.terms for j in conv.cmap.joints)
    dL, dR = _errors(conv)
    knee_only = [conv.paths.index(n) for n in ("bifemsh_r", "tfl_r", "sar_l")]
    assert dL[knee_only].max() <= 0.5e-3 and dR[knee_only].max() <= 2e-3
    with pytest.raises(ValueError, match="couplings"):
        CoordinateMap(g2392.model.osim, "cubic")


def test_robot_design_routes(robot):
    m = robot.compile()
    assert m.ntendon - sum(bool(j.terms) for j in robot.cmap.joints) == len(robot.paths) and all(n.endswith(("_r", "_l")) for n in robot.paths)
    dL, dR = _errors(robot, seed=11)
    exact = exact_constructs(robot)
    assert exact.sum() >= 20
    assert dL[exact].max() < 1e-6 and dR[exact].max() < 1e-6
    assert dL.max() <= 1.5e-3


def test_wrap_cylinder_and_ellipsoid_stand_ins():
    """Arm26: cylinders as MuJoCo wrap geoms (OpenSim's lengths within 0.01 mm), ellipsoids by a sphere or a
    cylinder (measured, within the stated bound)."""
    conv = convert_model(load_osim(ARM26))
    dL, _ = _errors(conv, seed=5)
    names = conv.paths
    assert dL[names.index("BICshort")] < 1e-9                      # sites only
    for n in ("TRIlat", "TRImed", "BRA"):                          # one WrapCylinder
        assert dL[names.index(n)] < 5e-5
    assert dL.max() < 15e-3                                        # TRIlong: an ellipsoid and two cylinders


def test_spline_and_coupler_ties():
    """Gait2392's knee translations are tied to knee angle's joint (composed: deviation below 0.01 mm, quartic
    0.3 mm); Rajagopal2016's
    patella, whose coordinate is coupled to knee angle, is tied to knee angle's joint through the coupler."""
    model = gait2392()
    cmap = CoordinateMap(model.osim)
    knee = [j for j in cmap.joints if j.name == "knee_r_translation1"][0]
    assert 0 < knee.error < 1e-5 and knee.terms
    quartic = CoordinateMap(model.osim, "quartic").joints[cmap.joint_index("knee_r_translation1")]
    assert 0.25e-3 < quartic.error < 0.35e-3
    assert cmap.joints[cmap.primary["knee_angle_r"][0]].name == "knee_r_rotation1"
    q = model.random_q(5, seed=2)
    x = cmap.qpos(q)
    ref = knee.value(q[:, model.coordinates.index("knee_angle_r")])
    assert np.abs(x[:, cmap.joint_index("knee_r_translation1")] - ref).max() <= knee.error
    raj = CoordinateMap(load_osim_file(SHARED / "opensim-models" / "Models" / "Rajagopal" / "Rajagopal2016.osim"))
    pat = [j for j in raj.joints if j.name.startswith("patellofemoral_r")]
    assert len(pat) == 3 and all(j.coordinate == "knee_angle_r" and not j.primary for j in pat)
    assert "knee_angle_r_beta" not in raj.primary
    coupler = [k for k in raj.osim.couplers if k.dependent == "knee_angle_r_beta"][0]
    axis = [a for j in raj.osim.joints if j.name == "patellofemoral_r" for a in j.axes if a.name == "rotation1"][0]
    qk = np.linspace(*raj.ranges["knee_angle_r"], 7)
    expected = axis.function.value(coupler.value(qk))        # the patella angle OpenSim gives
    rot = [j for j in pat if j.name.endswith("rotation1")][0]
    assert np.allclose(rot.value(qk), expected, atol=1e-15)
    assert 0 < rot.error < 0.03                              # the polynomial's deviation [rad], stated


TWO_BODY = __import__("locations").DATA / "two_body.osim"
_AXES = "".join(
    f'<TransformAxis name="{n}"><coordinates>{c}</coordinates><axis>{a}</axis>{f}</TransformAxis>'
    for n, c, a, f in (
        ("rotation1", "angle", "0 0 1", '<SimmSpline name="function"><x> -1.5 0 1.5</x><y> -1 0 2</y></SimmSpline>'),
        ("rotation2", "", "1 0 0", '<Constant name="function"><value>0</value></Constant>'),
        ("rotation3", "", "0 1 0", '<Constant name="function"><value>0</value></Constant>'),
        ("translation1", "", "1 0 0", '<Constant name="function"><value>0</value></Constant>'),
        ("translation2", "", "0 1 0", '<Constant name="function"><value>0</value></Constant>'),
        ("translation3", "", "0 0 1", '<Constant name="function"><value>0</value></Constant>')))


def test_weld_and_pin_joints_convert_exactly():
    conv = convert_model(load_osim(TWO_BODY))
    model = conv.model
    q = model.random_q(5, seed=1)
    geo = MjGeometry(conv.compile(), conv.cmap, [])
    T = model.body_transforms(q)
    for n, qpos in enumerate(conv.cmap.qpos(q)):
        geo.set_pose(qpos)
        i = mujoco.mj_name2id(geo.model, mujoco.mjtObj.mjOBJ_BODY, "arm")
        assert np.abs(geo.data.xpos[i] - T["arm"][n, :3, 3]).max() < 1e-12


def test_a_coordinate_without_a_linear_axis_is_refused(tmp_path, capsys):
    """A coordinate that moves its only axis through a spline has no MuJoCo joint to stand for it: a clear error
    naming the component (exit 2 from the command line), nothing written."""
    from pamkin.cli import main
    from pamkin.errors import UnsupportedFeatureError

    text = TWO_BODY.read_text()
    start, end = text.index("<PinJoint"), text.index("</PinJoint>") + len("</PinJoint>")
    pin = text[start:end].replace("<PinJoint", "<CustomJoint").replace("</PinJoint>", "</CustomJoint>")
    pin = pin.replace("<frames>", f"<SpatialTransform>{_AXES}</SpatialTransform><frames>")
    bad = tmp_path / "spline_only.osim"
    bad.write_text(text[:start] + pin + text[end:])
    with pytest.raises(UnsupportedFeatureError, match="elbow_rotation1"):
        CoordinateMap(load_osim_file(bad))
    assert main(["mjcf", "--osim", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "spline_only.osim" in err and "angle" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_unphysical_inertias_are_adjusted_and_stated(tmp_path):
    """A zero inertia and one violating A + B >= C (both occur in OpenSim's example models) compile, and the
    conversion lists what it changed."""
    text = TWO_BODY.read_text()
    text = text.replace("<Body name=\"base\"><mass>1</mass><mass_center>0 0 0</mass_center><inertia>0.01 0.01 0.01 0 0 0",
                        "<Body name=\"base\"><mass>1</mass><mass_center>0 0 0</mass_center><inertia>0 0 0 0 0 0")
    text = text.replace("<Body name=\"arm\"><mass>1</mass><mass_center>0 -0.2 0</mass_center><inertia>0.01 0.01 0.01",
                        "<Body name=\"arm\"><mass>1</mass><mass_center>0 -0.2 0</mass_center><inertia>0.01 0.01 0.05")
    path = tmp_path / "odd_inertia.osim"
    path.write_text(text)
    conv = convert_model(load_osim(path))
    m = conv.compile()
    assert m.nbody == 3
    issues = {i["body"]: i["change"] for i in conv.summary()["inertia_adjusted"]}
    assert set(issues) == {"base", "arm"}
    assert "raised" in issues["base"] and "balanced" in issues["arm"]
