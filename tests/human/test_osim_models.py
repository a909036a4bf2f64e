"""OpenSim's other shipped models (../shared/opensim-models/Models): lenient import, every joint type,
CoordinateCouplerConstraints, path points on ground, models without muscles — against OpenSim 4.6."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import pamkin
from opensim_ref import SHARED, opensim_reference
from pamkin.errors import OsimError, PamkinError, UnsupportedFeatureError
from pamkin.opensim.model_file import SkippedComponentsWarning, load_osim_file

MODELS = SHARED / "opensim-models" / "Models"
GAIT2392 = SHARED / "opensim-models" / "Gait2392_Simbody" / "gait2392_thelen2003muscle.osim"

pytestmark = pytest.mark.needs_shared


def _load(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        return pamkin.load_osim(path, **kw)


def _joint_variants(tmp_path):
    """Gait2392 with hip_r as a BallJoint, hip_l as a GimbalJoint and back as a UniversalJoint."""
    text = GAIT2392.read_text()

    def convert(text, name, kind, drop=()):
        m = re.search(rf'<CustomJoint name="{name}">(.*?)</CustomJoint>', text, flags=re.S)
        body = re.sub(r"<SpatialTransform>.*?</SpatialTransform>", "", m.group(1), flags=re.S)
        for c in drop:
            body = re.sub(rf'<Coordinate name="{c}">.*?</Coordinate>', "", body, flags=re.S)
        return text[:m.start()] + f'<{kind} name="{name}">{body}</{kind}>' + text[m.end():]

    text = convert(text, "hip_r", "BallJoint")
    text = convert(text, "hip_l", "GimbalJoint")
    text = convert(text, "back", "UniversalJoint", drop=("lumbar_rotation",))
    p = tmp_path / "gait2392_joints.osim"
    p.write_text(text)
    return p


# (model file, compare forces) — small models, or few configurations
CASES = {
    "tug_of_war": ("Tug_of_War/Tug_of_War.osim", True),          # SliderJoint, path points on ground
    "leg39": ("Leg39/leg39.osim", True),                          # 5 couplers (SimmSpline), locked coordinate
    "soccer": ("SoccerKick/SoccerKickingModel.osim", True),       # FreeJoint, coupler, contact skipped
    "walker": ("WalkerModel/WalkerModel.osim", False),            # PlanarJoint, no muscles
    "wrist": ("WristModel/wrist.osim", False),                    # 4 couplers, Schutte1993 paths
}


@pytest.fixture(scope="module")
def joints_path(tmp_path_factory):
    return _joint_variants(tmp_path_factory.mktemp("joints"))


@pytest.mark.opensim
@pytest.mark.parametrize("case", [*CASES, "ball_gimbal_universal"])
def test_matches_opensim(case, joints_path):
    if case == "ball_gimbal_universal":
        path, forces = joints_path, True
    else:
        path, forces = MODELS / CASES[case][0], CASES[case][1]
    model = _load(path)
    q = model.random_q(12, seed=3)
    what = ("transforms", "lengths", "moment_arms") + (("tendon_forces",) if forces else ())
    ref = opensim_reference(path, q, what)
    assert list(ref["coordinates"]) == model.coordinates
    T = model.body_transforms(q)
    for i, b in enumerate(ref["bodies"]):
        assert np.abs(T[str(b)][:, :3, :3] - ref["R"][:, i]).max() < 1e-9, b
        assert np.abs(T[str(b)][:, :3, 3] - ref["p"][:, i]).max() < 1e-9, b
    if not model.muscles:
        assert model.lengths(q).shape == (12, 0) and model.tendon_forces(q).shape == (12, 0)
        return
    assert np.abs(model.lengths(q) - ref["lengths"]).max() < 1e-9
    R = model.moment_arms(q)
    pairs = ref["pairs"]
    dep = model.kinematics.dependent
    indep = ~dep[pairs[:, 1]]
    checked = indep.copy()
    # a BallJoint's generalized speeds are angular velocities, not the Euler angles' rates, so OpenSim's
    # computeMomentArm about its coordinates is not -dL/dq: compare those with central differences of
    # OpenSim's own lengths
    ball = [c.name for j in model.osim.joints if j.kind == "BallJoint" for c in model.osim.coordinates
            if c.joint == j.name]
    for name in ball:
        c, h = model.coordinates.index(name), 1e-6
        qp, qm = q.copy(), q.copy()
        qp[:, c] += h
        qm[:, c] -= h
        Lp = opensim_reference(path, qp, ("lengths",))["lengths"]
        Lm = opensim_reference(path, qm, ("lengths",))["lengths"]
        fd = -(Lp - Lm) / (2 * h)
        assert np.abs(R[:, :, c] - fd).max() < 1e-8, name
        checked &= pairs[:, 1] != c
    mine = R[:, pairs[checked, 0], pairs[checked, 1]]
    assert np.abs(mine - ref["moment_arms"][:, checked]).max() < 1e-8
    # about a dependent coordinate pamkin reports 0; OpenSim's number is the independent one / slope
    if (~indep).any():
        assert np.all(R[:, pairs[~indep, 0], pairs[~indep, 1]] == 0.0)
        G = model.kinematics.dependent_derivatives(model.kinematics.as_q(q))
        root = model.kinematics.root_of[pairs[~indep, 1]]
        slope = G[:, pairs[~indep, 1]]
        ok = np.abs(slope) > 1e-3
        expect = R[:, pairs[~indep, 0], root] / np.where(ok, slope, 1.0)
        scale = np.maximum(1.0, np.abs(expect))
        err = (np.abs(expect - ref["moment_arms"][:, ~indep]) / scale)[ok]
        assert err.size == 0 or err.max() < 1e-6
    if forces:
        F = model.tendon_forces(q)
        err = np.abs(F - ref["tendon_forces"]) / np.maximum(1.0, np.abs(ref["tendon_forces"]))
        assert err.max() < 1e-4


@pytest.mark.opensim
def test_point_jacobian_is_total_derivative():
    model = _load(MODELS / "Leg39" / "leg39.osim")
    q = model.random_q(5, seed=2)
    J = model.point_jacobian(q, "patella_r", [0.01, 0.02, 0.0])
    k, h = model.coordinates.index("knee_angle_r"), 1e-6
    qp, qm = q.copy(), q.copy()
    qp[:, k] += h
    qm[:, k] -= h
    T1, T0 = model.body_transforms(qp)["patella_r"], model.body_transforms(qm)["patella_r"]
    x = lambda T: T[:, :3, 3] + T[:, :3, :3] @ np.array([0.01, 0.02, 0.0])  # noqa: E731
    assert np.abs(J[:, :, k] - (x(T1) - x(T0)) / (2 * h)).max() < 1e-8
    assert np.all(J[:, :, model.coordinates.index("pat_angle_r")] == 0.0)


def test_dependent_coordinates_api():
    model = _load(MODELS / "Leg39" / "leg39.osim")
    assert model.dependent_coordinates == {c: "knee_angle_r" for c in
                                           ("tib_tx_r", "tib_ty_r", "pat_tx_r", "pat_ty_r", "pat_angle_r")}
    assert "knee_angle_r" in model.independent_coordinates and "tib_tx_r" not in model.independent_coordinates
    q = model.default_q
    q[model.coordinates.index("tib_tx_r")] = 3.0     # ignored: follows the coupler
    a = model.lengths(q)
    assert np.array_equal(a, model.lengths(model.default_q))


def test_every_shared_model_loads_or_is_refused_for_a_reason():
    reasons = {"BouncingBlock/bouncing_block.osim": "PointOnLineConstraint"}
    for path in sorted(MODELS.glob("*/*.osim")):
        rel = f"{path.parent.name}/{path.name}"
        if rel in reasons:
            with pytest.raises(UnsupportedFeatureError, match=reasons[rel]):
                load_osim_file(path)
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", SkippedComponentsWarning)
                assert load_osim_file(path).bodies


def test_skipped_components_one_warning():
    with pytest.warns(SkippedComponentsWarning) as rec:
        m = load_osim_file(MODELS / "ToyLanding" / "ToyLandingModel.osim")   # tags with '::'
    assert len(rec) == 1
    msg = str(rec[0].message)
    for what in ("HuntCrossleyForce", "BushingForce", "CoordinateLimitForce", "ContactSphere",
                 "ToyReflexController", "PrescribedController"):
        assert what in msg
    assert len(m.muscles) == 70 and "HuntCrossleyForce 'foot_r'" in " ".join(m.skipped)


def test_path_actuator_and_path_only_muscles_load_as_paths():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        m = load_osim_file(MODELS / "Gait10dof18musc" / "subject01_metabolics_path_actuator.osim")
    pa = [x for x in m.muscles if x.kind == "PathActuator"]
    assert len(pa) == 1 and pa[0].params["min_control"] == -np.inf
    wrist = _load(MODELS / "WristModel" / "wrist.osim")
    assert {x.kind for x in wrist.osim.muscles} == {"Schutte1993Muscle_Deprecated"}
    with pytest.raises(UnsupportedFeatureError, match="Schutte1993Muscle_Deprecated"):
        wrist.tendon_forces(wrist.default_q)


def test_model_without_muscles():
    m = _load(MODELS / "WalkerModel" / "WalkerModel.osim")
    q = m.random_q(4)
    assert m.lengths(q).shape == (4, 0)
    assert m.moment_arms(q).shape == (4, 0, len(m.coordinates))
    assert m.tendon_forces(q).shape == (4, 0)
    assert m.torques(q).shape == (4, 0, len(m.coordinates))


def test_path_points_on_ground():
    m = _load(MODELS / "Tug_of_War" / "Tug_of_War.osim")
    assert {m.osim.muscles[0].points[0].body} == {"ground"}
    L = m.lengths(m.random_q(3))
    assert np.all(np.isfinite(L)) and np.all(L > 0)


def test_pre_4_file_says_how_to_convert(tmp_path):
    text = GAIT2392.read_text().replace('<OpenSimDocument Version="40000">', '<OpenSimDocument Version="30000">')
    p = tmp_path / "old.osim"
    p.write_text(text)
    with pytest.raises(UnsupportedFeatureError, match=r"old\.osim.*predates OpenSim 4\.0.*opensim-cmd update-file"):
        load_osim_file(p)


def test_ignore_tendon_compliance_is_refused_like_opensim(tmp_path):
    text = (MODELS / "Tug_of_War" / "Tug_of_War.osim").read_text()
    text = text.replace("<ignore_tendon_compliance>false</ignore_tendon_compliance>",
                        "<ignore_tendon_compliance>true</ignore_tendon_compliance>", 1)
    p = tmp_path / "rigid.osim"
    p.write_text(text)
    with pytest.raises(UnsupportedFeatureError, match=r'rigid\.osim: <Thelen2003Muscle name="muscle1">: '
                                                      r"ignore_tendon_compliance"):
        load_osim_file(p)


def test_unsupported_constraint_names_file_element_component():
    with pytest.raises(UnsupportedFeatureError,
                       match=r'bouncing_block\.osim: <PointOnLineConstraint name="lock_block_to_y_axis">'):
        load_osim_file(MODELS / "BouncingBlock" / "bouncing_block.osim")


def test_errors_are_pamkin_errors(tmp_path):
    assert issubclass(OsimError, PamkinError)
    p = tmp_path / "bad.osim"
    p.write_text(GAIT2392.read_text().replace("<BodySet", "<BodySetX", 1).replace("</BodySet>", "</BodySetX>", 1))
    with pytest.raises(PamkinError):
        load_osim_file(p)


def _sub(text, pattern, repl):
    new, n = re.subn(pattern, repl, text, count=1, flags=re.S)
    assert n == 1, pattern
    return new


def _extra_coupler(text):
    """A coupler that makes knee_angle_r follow tib_tx_r, which already follows knee_angle_r."""
    m = re.search(r'<CoordinateCouplerConstraint name="knee_tx_r">.*?</CoordinateCouplerConstraint>', text, flags=re.S)
    block = m.group(0).replace('name="knee_tx_r"', 'name="loop"')
    block = re.sub(r"<independent_coordinate_names>\s*knee_angle_r\s*</independent_coordinate_names>",
                   "<independent_coordinate_names>tib_tx_r</independent_coordinate_names>", block)
    block = re.sub(r"<dependent_coordinate_name>\s*tib_tx_r\s*</dependent_coordinate_name>",
                   "<dependent_coordinate_name>knee_angle_r</dependent_coordinate_name>", block)
    return text[:m.end()] + block + text[m.end():]


def _second_joint(text):
    m = re.search(r'<SliderJoint name="ground_block">.*?</SliderJoint>', text, flags=re.S)
    twin = m.group(0).replace('name="ground_block"', 'name="twin"').replace('name="block_tz"', 'name="twin_tz"')
    return text[:m.end()] + twin + text[m.end():]


# Every reason the importer refuses a file, one case each (file-level reasons tested elsewhere: pre-4.0 files,
# ignore_tendon_compliance and PointOnLineConstraint above; joint types, muscle classes, function types and
# not well-formed files in test_osim_import.py; obstacle-set wraps and wrap settings in test_wrapping.py).
# (base model, mutation, error class, message pattern)
TUG, LEG = "Tug_of_War/Tug_of_War.osim", "Leg39/leg39.osim"
REFUSALS = {
    "model component": (TUG, lambda t: _sub(t, r'(<BodySet name="bodyset">)', r'<components><Bogus name="bog" /></components>\1'),
                        UnsupportedFeatureError, r'<Bogus name="bog">: model component <Bogus> is not supported'),
    "frame component": (TUG, lambda t: _sub(t, r"(<components>)", r'\1<Bogus name="bog" />'),
                        UnsupportedFeatureError, r"<Bogus> component of Ground"),
    "BodySet entry": (TUG, lambda t: _sub(t, r'(<BodySet name="bodyset">\s*<objects>)', r'\1<Bogus name="bog" />'),
                      UnsupportedFeatureError, r"<Bogus> in BodySet is not supported"),
    "joint frame": (TUG, lambda t: _sub(t, r"(<frames>)", r'\1<Bogus name="bog" />'),
                    UnsupportedFeatureError, r"<Bogus> joint frame is not supported"),
    "coordinates entry": (TUG, lambda t: _sub(t, r"(<coordinates>)", r'\1<Bogus name="bog" />'),
                          UnsupportedFeatureError, r"<Bogus> in coordinates"),
    "prescribed coordinate": (TUG, lambda t: _sub(t, r"<prescribed>false</prescribed>", "<prescribed>true</prescribed>"),
                              UnsupportedFeatureError, r'<Coordinate name="block_tz">: prescribed coordinates'),
    "closed loop": (TUG, _second_joint, OsimError, r"child of two joints"),
    "no BodySet": (TUG, lambda t: t.replace("<BodySet", "<BodySetX").replace("</BodySet>", "</BodySetX>"),
                   OsimError, r"no <BodySet><objects>"),
    "no JointSet": (TUG, lambda t: t.replace("<JointSet", "<JointSetX").replace("</JointSet>", "</JointSetX>"),
                    OsimError, r"no <JointSet><objects>"),
    "coupler of two coordinates": (LEG, lambda t: _sub(t, r"<independent_coordinate_names>knee_angle_r<",
                                                       "<independent_coordinate_names>knee_angle_r hip_angle_r<"),
                                   UnsupportedFeatureError, r'name="knee_tx_r">: coupler with 2 independent'),
    "coupler cycle": (LEG, _extra_coupler, OsimError, r"couplers form a cycle"),
    "axis of two coordinates": (LEG, lambda t: _sub(t, r"<coordinates>hip_angle_r</coordinates>",
                                                    "<coordinates>hip_angle_r pelvis_tilt</coordinates>"),
                                UnsupportedFeatureError, r"depends on 2 coordinates"),
    "coordinate of another joint": (LEG, lambda t: _sub(t, r"<coordinates>hip_angle_r</coordinates>",
                                                        "<coordinates>pelvis_tilt</coordinates>"),
                                    UnsupportedFeatureError, r"uses coordinate 'pelvis_tilt' of another joint"),
    "parallel rotation axes": (LEG, lambda t: _sub(
        t, r'(<TransformAxis name="rotation2">\s*<!--[^>]*-->\s*<coordinates></coordinates>\s*<!--[^>]*-->\s*)'
           r'<axis>0 1 0</axis>(\s*<!--[^>]*-->\s*<Constant name="function">\s*<value>)0<',
        r"\1<axis>0 0 1</axis>\g<2>0.1<"),
        UnsupportedFeatureError, r'<CustomJoint name="ground_pelvis">: rotation1 and rotation2 are parallel'),
    "not an OpenSim model": (TUG, lambda t: _sub(t, r"<Model name=(.*)</Model>", r"<Mode name=\1</Mode>"),
                             OsimError, r"no <OpenSimDocument><Model> element"),
}


@pytest.mark.parametrize("reason", REFUSALS)
def test_each_refusal_reason_names_file_element_component(reason, tmp_path):
    base, mutate, error, pattern = REFUSALS[reason]
    p = tmp_path / "refused.osim"
    p.write_text(mutate((MODELS / base).read_text()))
    with pytest.raises(error, match=pattern) as info:
        load_osim_file(p)
    assert str(info.value).startswith(str(p))
