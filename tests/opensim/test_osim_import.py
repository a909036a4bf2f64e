"""Import of .osim files, the generated URDF, and clear errors on bad input."""

from __future__ import annotations

import re

import numpy as np
import pytest

import pamkin
from pamkin.errors import ConfigurationError, OsimError, RangeWarning, UnsupportedFeatureError
from pamkin.opensim.model_file import ConditionalPathPoint, MovingPathPoint, load_osim_file
from pamkin.human.urdf import GAIT2392_URDF, build_gait2392, load_model_data, GAIT2392_DATA


def test_gait2392_contents(gait2392_path):
    m = load_osim_file(gait2392_path)
    assert len(m.bodies) == 12 and len(m.joints) == 12
    assert len(m.coordinates) == 23 and len(m.muscles) == 92
    assert {j.kind for j in m.joints} == {"CustomJoint"}
    knee = m.coordinate("knee_angle_r")
    assert knee.range == (-2.0943950999999998, 0.17453293)
    assert m.coordinate("pelvis_ty").default_value == 0.95
    assert not m.coordinate("pelvis_tx").rotational and m.coordinate("ankle_angle_l").rotational
    kinds = {type(p).__name__ for mu in m.muscles for p in mu.points}
    assert kinds == {"PathPoint", "ConditionalPathPoint", "MovingPathPoint"}
    semimem = next(mu for mu in m.muscles if mu.name == "semimem_r")
    cond = [p for p in semimem.points if isinstance(p, ConditionalPathPoint)]
    assert cond[0].coordinate == "knee_angle_r" and cond[0].range == (-0.558505, 0.174533)
    assert semimem.params["max_isometric_force"] == 1288.0
    assert sum(isinstance(p, MovingPathPoint) for mu in m.muscles for p in mu.points) == 8


def test_millard_model_imports_with_same_paths(gait2392_path, millard_path):
    a, b = load_osim_file(gait2392_path), load_osim_file(millard_path)
    assert {m.kind for m in b.muscles} == {"Millard2012EquilibriumMuscle"}
    assert [m.name for m in a.muscles] == [m.name for m in b.muscles]


def test_urdf_loads_in_pinocchio_and_yourdfpy():
    import pinocchio as pin
    import yourdfpy

    model = pin.buildModelFromUrdf(str(GAIT2392_URDF))
    assert model.nq == 27  # 23 coordinates; the knees add 2 coupled translations each
    robot = yourdfpy.URDF.load(str(GAIT2392_URDF), load_meshes=False)
    assert robot.base_link == "ground"
    assert len(robot.actuated_joint_names) == 27
    for body in ("pelvis", "femur_r", "toes_l", "torso"):
        assert body in robot.link_map


def test_committed_urdf_is_not_stale(gait2392_path):
    stale = build_gait2392(gait2392_path, check=True)
    assert stale == [], f"regenerate with `pamkin urdf`: stale {stale}"


def test_model_data_round_trip(gait2392_path):
    a = load_osim_file(gait2392_path)
    b = load_model_data(GAIT2392_DATA)
    assert [m.name for m in a.muscles] == [m.name for m in b.muscles]
    assert a.coordinates == b.coordinates
    assert a.joints == b.joints
    assert [m.points for m in a.muscles] == [m.points for m in b.muscles]
    assert [m.params for m in a.muscles] == [m.params for m in b.muscles]


def test_builtin_model_equals_imported(gait2392):
    builtin = pamkin.gait2392()
    q = gait2392.random_q(20, seed=5)
    assert np.array_equal(builtin.lengths(q), gait2392.lengths(q))


# ----------------------------------------------------------------------------- bad input
@pytest.fixture()
def osim_text(gait2392_path):
    return gait2392_path.read_text()


def _write(tmp_path, text, name="bad.osim"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_truncated_file(tmp_path, osim_text):
    p = _write(tmp_path, osim_text[: len(osim_text) // 2])
    with pytest.raises(OsimError, match=r"bad\.osim: not a well-formed"):
        load_osim_file(p)


def test_missing_file(tmp_path):
    with pytest.raises(OsimError, match="file not found"):
        pamkin.load_osim(tmp_path / "nope.osim")


def test_missing_body_reference(tmp_path, osim_text):
    text = osim_text.replace("<socket_parent>/bodyset/femur_r</socket_parent>",
                             "<socket_parent>/bodyset/femur_x</socket_parent>", 1)
    with pytest.raises(OsimError, match=r'<CustomJoint name="hip_r">.*femur_x'):
        load_osim_file(_write(tmp_path, text))


def test_path_point_on_unknown_body(tmp_path, osim_text):
    text = osim_text.replace("<socket_parent_frame>/bodyset/tibia_r</socket_parent_frame>",
                             "<socket_parent_frame>/bodyset/tibia_q</socket_parent_frame>", 1)
    with pytest.raises(OsimError, match="unknown body/frame 'tibia_q'"):
        load_osim_file(_write(tmp_path, text))


def test_unknown_joint_type(tmp_path, osim_text):
    text = re.sub(r"<CustomJoint name=\"knee_l\">(.*?)</CustomJoint>",
                  r'<EllipsoidJoint name="knee_l">\1</EllipsoidJoint>', osim_text, count=1, flags=re.S)
    with pytest.raises(UnsupportedFeatureError, match=r'bad\.osim: <EllipsoidJoint name="knee_l">: joint type'):
        load_osim_file(_write(tmp_path, text))


def test_obstacle_wrap_is_rejected(tmp_path, osim_text):
    wrap = ('<objects><WrapDoubleCylinderObst name="femur_wrap"><radiusUcyl>0.01</radiusUcyl>'
            '</WrapDoubleCylinderObst></objects>')
    i = osim_text.index('<Body name="femur_r">')
    j = osim_text.index("<objects />", i)
    text = osim_text[:j] + wrap + osim_text[j + len("<objects />"):]
    with pytest.raises(UnsupportedFeatureError, match=r'WrapDoubleCylinderObst name="femur_wrap".*femur_r'):
        load_osim_file(_write(tmp_path, text))


def test_unsupported_muscle_class(tmp_path, osim_text):
    text = osim_text.replace('<Thelen2003Muscle name="glut_med1_r">', '<RigidTendonMuscle name="glut_med1_r">', 1)
    text = text.replace("</Thelen2003Muscle>", "</RigidTendonMuscle>", 1)
    # other muscle classes load as paths (lengths, moment arms); their forces are refused
    model = pamkin.load_osim(_write(tmp_path, text))
    with pytest.raises(UnsupportedFeatureError, match=r'<RigidTendonMuscle name="glut_med1_r">'):
        model.tendon_forces(model.default_q)
    text = text.replace('<RigidTendonMuscle name="glut_med1_r">', '<FancyMuscle name="glut_med1_r">', 1)
    text = text.replace("</RigidTendonMuscle>", "</FancyMuscle>", 1)
    with pytest.raises(UnsupportedFeatureError, match=r'<FancyMuscle name="glut_med1_r">'):
        load_osim_file(_write(tmp_path, text))


def test_unsupported_function(tmp_path, osim_text):
    i = osim_text.index("<SimmSpline name=\"function\">")
    j = osim_text.index("</SimmSpline>", i) + len("</SimmSpline>")
    text = osim_text[:i] + '<StepFunction name="function"><start_time>0</start_time></StepFunction>' + osim_text[j:]
    with pytest.raises(UnsupportedFeatureError, match="StepFunction"):
        load_osim_file(_write(tmp_path, text))


def test_nan_configuration(gait2392):
    q = gait2392.default_q
    q[9] = np.nan
    with pytest.raises(ConfigurationError, match="knee_angle_r"):
        gait2392.body_transforms(q)


def test_wrong_length_configuration(gait2392):
    with pytest.raises(ConfigurationError, match=r"shape \(22,\); expected \(N, 23\)"):
        gait2392.body_transforms(np.zeros(22))


def test_unknown_coordinate_name(gait2392):
    with pytest.raises(ConfigurationError, match="knee_angle_x"):
        gait2392.body_transforms({"knee_angle_x": 0.1})


def test_out_of_range_is_flagged_not_clamped(gait2392):
    q = gait2392.default_q
    q[9] = 0.5  # knee hyperextension beyond 0.1745
    with pytest.warns(RangeWarning, match="knee_angle_r"):
        T = gait2392.body_transforms(q)
    with np.errstate(all="ignore"):
        Tin = gait2392.kinematics.body_transforms(np.where(np.arange(23) == 9, 0.17453293, q))
    assert not np.allclose(T["tibia_r"], Tin["tibia_r"])
