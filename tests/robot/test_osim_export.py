"""``pamkin export-osim``: a design written as an OpenSim 4.x model, checked with OpenSim 4.6.

OpenSim runs in a child process (it cannot share a process with CasADi): the child loads the
exported file, sets random configurations by coordinate name and reads every PathActuator's
path length; the lengths must equal pamkin's route lengths to round-off.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from pamkin.robot import festo
from pamkin.cli import main
from pamkin.robot.design import load_design, mirror_point
from pamkin.robot.detour import insert_via
from pamkin.errors import DataFileError, RangeWarning
from pamkin.opensim.functions import Constant, LinearFunction, MultiplierFunction, PolynomialFunction, SimmSpline
from pamkin.opensim.model_file import ConditionalPathPoint, MovingPathPoint, PathPoint, load_osim_file
from pamkin.robot.osim_export import OsimExportError, coordinate_range, design_to_osim
from pamkin.robot.rollers import Roller
from pamkin.human.rom import load_rom
from pamkin.human.urdf import GAIT2392_DATA, load_model_data

N_RANDOM = 60
TOL = 1e-9

# Child process: load each model with OpenSim 4.6, set q by coordinate name, read path lengths.
CHILD = r"""
import json, sys
import numpy as np
import opensim as osim

osim.Logger.setLevelString("Error")
req = np.load(sys.argv[1], allow_pickle=False)
names = [str(n) for n in req["coordinates"]]
q = req["q"]
out = {}
for k, path in enumerate(req["osim"]):
    model = osim.Model(str(path))
    state = model.initSystem()
    cs = model.getCoordinateSet()
    coords = [cs.get(n) for n in names]
    acts = model.getActuators()
    pas = [osim.PathActuator.safeDownCast(acts.get(i)) for i in range(acts.getSize())]
    L = np.empty((q.shape[0], len(pas)))
    for i in range(q.shape[0]):
        for c, v in zip(coords, q[i]):
            c.setValue(state, float(v), False)
        model.realizePosition(state)
        for j, pa in enumerate(pas):
            L[i, j] = pa.getGeometryPath().getLength(state)
    out[f"lengths{k}"] = L
    out[f"meta{k}"] = np.array(json.dumps({
        "actuators": [pa.getName() for pa in pas],
        "classes": [pa.getConcreteClassName() for pa in pas],
        "optimal_force": [pa.getOptimalForce() for pa in pas],
        "n_points": [pa.getGeometryPath().getPathPointSet().getSize() for pa in pas],
        "coordinates": {cs.get(i).getName(): [cs.get(i).getRangeMin(), cs.get(i).getRangeMax(),
                                              cs.get(i).getDefaultValue()] for i in range(cs.getSize())},
        "bodies": [model.getBodySet().get(i).getName() for i in range(model.getBodySet().getSize())],
        "joints": [model.getJointSet().get(i).getConcreteClassName() for i in range(model.getJointSet().getSize())],
    }))
np.savez(sys.argv[2], **out)
"""


def opensim_lengths(paths: list[Path], coordinates: list[str], q: np.ndarray, tmp: Path):
    """Path lengths and model facts read by OpenSim 4.6 in a child process."""
    req, res = tmp / "request.npz", tmp / "result.npz"
    np.savez(req, osim=np.array([str(p) for p in paths]), coordinates=np.array(coordinates), q=q)
    proc = subprocess.run([sys.executable, "-c", CHILD, str(req), str(res)], capture_output=True, text=True,
                          timeout=900, cwd=tmp)
    if proc.returncode != 0:
        raise RuntimeError(f"OpenSim child process failed:\n{proc.stdout}\n{proc.stderr}")
    with np.load(res, allow_pickle=False) as data:
        return [(data[f"lengths{k}"], json.loads(str(data[f"meta{k}"]))) for k in range(len(paths))]


@pytest.fixture(scope="module")
def skeleton():
    return load_model_data(GAIT2392_DATA)


@pytest.fixture(scope="module")
def robot_model():
    from pamkin.robot.biped import robot_skeleton

    return robot_skeleton()


def _all_functions_design(design):
    """The thesis design with routes that use every function and point type the exporter writes:
    a MovingPathPoint with a non-constant z (its mirror is a MultiplierFunction), LinearFunction,
    PolynomialFunction and MultiplierFunction components, and a ConditionalPathPoint."""
    vasti = design.pam(11)
    patella = vasti.points[-1]
    assert isinstance(patella, MovingPathPoint)
    fx, fy, _ = patella.functions
    moving = MovingPathPoint("patella", "tibia_r",
                             (MultiplierFunction(fx, 1.0), fy,
                              SimmSpline((-2.0944, -1.0, 0.0, 0.2), (0.001, 0.004, 0.002, 0.0035))),
                             ("knee_angle_r", "knee_angle_r", "knee_angle_r"))
    design = design.replace_pam(dataclasses.replace(vasti, points=vasti.points[:-1] + (moving,)))
    soleus = design.pam(12)
    calc = soleus.points[-1]
    odd = MovingPathPoint("heel", calc.body, (LinearFunction(0.01, calc.location[0]),
                                              PolynomialFunction((0.003, -0.002, calc.location[1])),
                                              Constant(calc.location[2])),
                          ("ankle_angle_r", "ankle_angle_r", ""))
    cond = ConditionalPathPoint("wrap", "tibia_r", (0.03, -0.38, 0.0), coordinate="ankle_angle_r",
                                range=(-0.2, 0.1))
    design = design.replace_pam(dataclasses.replace(soleus, points=(soleus.points[0], cond, odd)))
    # rollers (WrapCylinders): one on biceps femoris long head (wraps at about half the poses), two on
    # gracilis (OpenSim's passes over several wraps; one wraps at nearly every pose)
    bflh, gracilis = design.pam(4), design.pam(9)
    design = design.replace_pam(dataclasses.replace(bflh, rollers=(
        Roller("p1->p2", "femur_r", (-0.06, -0.1, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0), 0.008),)))
    design = design.replace_pam(dataclasses.replace(gracilis, rollers=(
        Roller("p1->p2", "femur_r", (0.0, -0.1, -0.03), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0), 0.008),
        Roller("p3->p4", "femur_r", (0.0, -0.42, -0.04), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0), 0.01, 0.05))))
    # a detour (pamkin.robot.detour): a via point inserted on sartorius' tibia segment, its name dotted
    sar = design.pam(6)
    a, b = (np.array(sar.points[k].location) for k in (4, 5))
    design = design.replace_pam(insert_via(sar, {4: [(a + b) / 2 + np.array([0.0, 0.0, -0.012])]}))
    assert design.pam(6).points[5].name == "P3_0.P4_0.1"
    return dataclasses.replace(design, name="all_functions")


@pytest.mark.opensim
def test_opensim_path_lengths_match_pamkin(tmp_path, skeleton, robot_model):
    from pamkin.robot.biped import PamRobot

    thesis = load_design("thesis")
    rom = load_rom(thesis.rom, "r")
    designs = [thesis, _all_functions_design(thesis)]
    files = [design_to_osim(d, skeleton, tmp_path / f"{d.name}.osim", rom=rom) for d in designs]

    names = robot_model.coordinates
    ranges = np.array([coordinate_range(skeleton.coordinate(c), rom) for c in names])
    rng = np.random.default_rng(2392)
    q = ranges[:, 0] + rng.random((N_RANDOM, len(names))) * (ranges[:, 1] - ranges[:, 0])
    q = np.vstack([q, ranges[:, 0], ranges[:, 1], np.zeros(len(names))])

    results = opensim_lengths(files, names, q, tmp_path)
    # the modified routes really differ, and the conditional point is both in and out of the path
    changed = ~np.isclose(results[0][0], results[1][0], rtol=0, atol=1e-6).all(axis=0)
    assert sorted(np.flatnonzero(changed)) == [3, 5, 8, 10, 11, 30, 32, 35, 37, 38]   # pam04, 06, 09, 11, 12, both sides
    ankle = q[:, names.index("ankle_angle_r")]
    assert ((ankle > -0.2) & (ankle < 0.1)).any() and ((ankle < -0.2) | (ankle > 0.1)).any()
    for design, (L_os, meta) in zip(designs, results):
        robot = PamRobot(design, robot_model)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)   # the robot's range is not the human one
            L_pk = robot.evaluate(q).lengths
        assert meta["actuators"] == robot.names
        assert set(meta["classes"]) == {"PathActuator"}
        err = float(np.max(np.abs(L_os - L_pk)))
        print(f"\n{design.name}: {L_pk.shape[1]} PathActuators x {q.shape[0]} configurations, "
              f"max |L_OpenSim - L_pamkin| = {err:.3e} m")
        assert err <= TOL
        # forces, point counts, coordinates and bodies as OpenSim reads them
        expect_f = [float(festo.f620(p.resting_length_m, p.diameter_mm)) * p.n_parallel for p in robot.pams]
        np.testing.assert_allclose(meta["optimal_force"], expect_f, rtol=1e-15)
        assert meta["n_points"] == [len(p.points) for p in robot.pams]
        assert list(meta["coordinates"]) == [c.name for c in skeleton.coordinates]
        for c in skeleton.coordinates:
            lo, hi, default = meta["coordinates"][c.name]
            assert (lo, hi) == coordinate_range(c, rom)
            assert default == c.default_value
        assert meta["bodies"] == [b.name for b in skeleton.bodies]
        assert set(meta["joints"]) == {"CustomJoint"}


def _without_forces(path: Path, out: Path) -> Path:
    tree = ET.parse(path)
    model = tree.getroot().find("Model")
    model.remove(model.find("ForceSet"))
    tree.write(out)
    return out


def test_exported_skeleton_reimports_identically(tmp_path, skeleton):
    """Bodies, meshes, joints (frames and functions) and coordinates read back unchanged."""
    path = design_to_osim(load_design("thesis"), skeleton, tmp_path / "thesis.osim")
    back = load_osim_file(_without_forces(path, tmp_path / "skeleton.osim"))
    assert back.bodies == skeleton.bodies
    assert back.coordinates == skeleton.coordinates
    assert len(back.joints) == len(skeleton.joints)
    for a, b in zip(back.joints, skeleton.joints):
        assert (a.name, a.kind, a.parent_frame, a.child_frame, a.coordinates) == \
               (b.name, b.kind, b.parent_frame, b.child_frame, b.coordinates)
        for x, y in zip(a.axes, b.axes):
            assert (x.name, x.coordinates, x.function) == (y.name, y.coordinates, y.function)
            np.testing.assert_allclose(x.axis, y.axis, rtol=0, atol=1e-15)


def test_ranges_from_rom_and_actuators(tmp_path, skeleton):
    design = load_design("thesis")
    rom = load_rom("robot_thesis", "r")
    path = design_to_osim(design, skeleton, tmp_path / "t.osim", rom=rom)
    model = ET.parse(path).getroot().find("Model")
    assert ET.parse(path).getroot().get("Version") == "40000"
    ranges = {c.get("name"): tuple(float(v) for v in c.findtext("range").split()) for c in model.iter("Coordinate")}
    deg = np.degrees
    # box limits on both sides; hip adduction: the envelope of the flexion-dependent limits
    for side in "rl":
        np.testing.assert_allclose(deg(ranges[f"hip_flexion_{side}"]), (-15, 110))
        np.testing.assert_allclose(deg(ranges[f"hip_adduction_{side}"]), (-60, 20))
        np.testing.assert_allclose(deg(ranges[f"knee_angle_{side}"]), (-120, 10))
    np.testing.assert_allclose(deg(ranges["lumbar_extension"]), (-20, 15))
    assert ranges["pelvis_ty"] == skeleton.coordinate("pelvis_ty").range
    acts = model.findall("ForceSet/objects/PathActuator")
    assert [a.get("name") for a in acts] == [f"{p.key}_{s}" for s in "rl" for p in design.pams]
    # left side: mirrored points, '_l' bodies and coordinates
    vasti_l = model.find("ForceSet/objects/PathActuator[@name='pam11_l']")
    mp = vasti_l.find(".//MovingPathPoint")
    assert mp.findtext("socket_parent_frame") == "/bodyset/tibia_l"
    # the z component is a constant in pamkin (no coordinate); OpenSim gets the knee socket
    assert mp.findtext("socket_z_coordinate") == "/jointset/knee_l/knee_angle_l"
    assert float(mp.findtext("z_location/Constant/value")) == -0.002
    first = design.pam(11).points[0]
    left = mirror_point(first)
    pp = vasti_l.find(".//PathPoint")
    assert tuple(float(v) for v in pp.findtext("location").split()) == left.location
    assert isinstance(left, PathPoint) and left.location[2] == -first.location[2]
    # a description of the PAM
    text = path.read_text()
    start = text.index('<PathActuator name="pam11_l">')
    assert "<!-- PAM 11 'Vasti' (left, mirrored side): Festo DMSP 40 mm, resting length 0.428522 m" in \
        text[start:text.index("</PathActuator>", start)]
    # bone meshes under their original file names
    meshes = {m.findtext("mesh_file") for m in model.iter("Mesh")}
    assert {"femur_r.vtp", "tibia_l.vtp", "sacrum.vtp"} <= meshes


def test_cli_export(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["export-osim", "thesis"]) == 0
    out = tmp_path / "thesis_2019.osim"
    assert out.exists() and "wrote" in capsys.readouterr().out
    assert main(["export-osim", "thesis", "--out", str(tmp_path / "sub" / "x.osim"), "--rom", "robot_2026"]) == 0
    model = ET.parse(tmp_path / "sub" / "x.osim").getroot().find("Model")
    hip = model.find(".//Coordinate[@name='hip_adduction_l']")
    np.testing.assert_allclose(np.degrees([float(v) for v in hip.findtext("range").split()]), (-45, 20))


def test_bad_design_file(tmp_path, skeleton, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: broken\npams:\n  - id: 1\n    name: x\n")
    with pytest.raises(DataFileError, match="missing field"):
        load_design(bad)
    out = tmp_path / "bad.osim"
    assert main(["export-osim", str(bad), "--out", str(out)]) == 2
    assert "missing field" in capsys.readouterr().err
    assert not out.exists()
    bad.write_text("pams: [\n")
    assert main(["export-osim", str(bad), "--out", str(out)]) == 2
    assert not out.exists()
    # a route on a body the skeleton lacks (design loaded without the skeleton check)
    design = load_design("thesis")
    p = design.pam(1)
    wrong = design.replace_pam(dataclasses.replace(p, points=(PathPoint("p1", "humerus_r", (0, 0, 0)),) + p.points[1:]))
    with pytest.raises(DataFileError, match="humerus_r"):
        design_to_osim(wrong, skeleton, out)
    assert not out.exists()


def test_unwritable_output_leaves_nothing(tmp_path, skeleton):
    design = load_design("thesis")
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(OsimExportError, match="cannot write"):
        design_to_osim(design, skeleton, blocker / "x.osim")
    folder = tmp_path / "folder.osim"
    folder.mkdir()
    with pytest.raises(OsimExportError, match="cannot write"):
        design_to_osim(design, skeleton, folder)
    assert sorted(os.listdir(tmp_path)) == ["file", "folder.osim"]
    assert os.listdir(folder) == []
    assert main(["export-osim", "thesis", "--out", str(blocker / "x.osim")]) == 2


def test_moving_point_on_two_coordinates_is_refused(tmp_path, skeleton):
    """OpenSim needs a MovingPathPoint's x, y and z to depend on one coordinate; pamkin does not."""
    design = load_design("thesis")
    p = design.pam(12)
    two = MovingPathPoint("heel", "calcn_r", (LinearFunction(0.01, 0.0), LinearFunction(0.01, 0.03), Constant(0.0)),
                          ("ankle_angle_r", "subtalar_angle_r", ""))
    design = design.replace_pam(dataclasses.replace(p, points=(p.points[0], two)))
    with pytest.raises(OsimExportError, match="one coordinate"):
        design_to_osim(design, skeleton, tmp_path / "x.osim")
    assert not (tmp_path / "x.osim").exists()


def test_pin_and_weld_joints(tmp_path, skeleton):
    """A PinJoint is written as the equivalent CustomJoint (unused rotation axes not parallel to
    its z axis); a WeldJoint stays a WeldJoint."""
    from pamkin.opensim.model_file import TransformAxis

    joints = list(skeleton.joints)
    names = [j.name for j in joints]
    i = names.index("mtp_r")
    joints[i] = dataclasses.replace(joints[i], kind="PinJoint", axes=(
        TransformAxis("rotation1", ("mtp_angle_r",), (0.0, 0.0, 1.0), LinearFunction(1.0, 0.0)),))
    i = names.index("mtp_l")
    joints[i] = dataclasses.replace(joints[i], kind="WeldJoint", axes=(), coordinates=())
    sk = dataclasses.replace(skeleton, joints=tuple(joints),
                             coordinates=tuple(c for c in skeleton.coordinates if c.name != "mtp_angle_l"))
    design = load_design("thesis")
    design = dataclasses.replace(design, pams=tuple(p for p in design.pams
                                                    if not any(pt.body.startswith("toes") for pt in p.points)))
    path = design_to_osim(design, sk, tmp_path / "pinweld.osim")
    back = load_osim_file(_without_forces(path, tmp_path / "skeleton.osim"))
    pin = next(j for j in back.joints if j.name == "mtp_r")
    assert pin.kind == "CustomJoint" and pin.coordinates == ("mtp_angle_r",)
    axes = {a.name: a for a in pin.axes}
    assert axes["rotation1"].axis == (0.0, 0.0, 1.0) and axes["rotation1"].function == LinearFunction(1.0, 0.0)
    for k in ("rotation2", "rotation3"):
        assert axes[k].function == Constant(0.0) and axes[k].axis[2] == 0.0
    weld = next(j for j in back.joints if j.name == "mtp_l")
    assert weld.kind == "WeldJoint" and weld.coordinates == ()
    assert (weld.parent_frame, weld.child_frame) == (joints[i].parent_frame, joints[i].child_frame)
