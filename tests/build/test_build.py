"""pamkin build: the build sheet's coordinates rebuild the design's routes exactly, its brackets are the bone
distances, its parts and mass add up, and the command keeps what a user has."""

from __future__ import annotations

import csv
import dataclasses
import json

import numpy as np
import pytest

from pamkin.build.documents import rollers_from_sheet, routes_from_sheet
from pamkin.build.sheet import build_sheet, festo_designation
from pamkin.cli import main
from pamkin.errors import DataFileError
from pamkin.human.bones import BoneSet
from pamkin.human.paths import PathSet
from pamkin.opensim.model_file import ConditionalPathPoint, MovingPathPoint
from pamkin.robot.biped import robot_skeleton
from pamkin.robot.design import load_design, pams_mass, save_design
from pamkin.robot.rollers import Roller


@pytest.fixture(scope="module")
def design_file(tmp_path_factory):
    """The thesis design with one via point made conditional (every kind of point in one design)."""
    des = load_design("thesis")
    pam = des.pams[3]                               # biceps femoris long head: p2 on the tibia
    p = pam.points[1]
    cond = ConditionalPathPoint(p.name, p.body, p.location, "knee_angle_r", (-2.0, 0.1))
    pams = list(des.pams)
    pams[3] = dataclasses.replace(pam, points=(pam.points[0], cond, *pam.points[2:]))
    path = tmp_path_factory.mktemp("design") / "design.yaml"
    save_design(dataclasses.replace(des, pams=tuple(pams)), path)
    return path


@pytest.fixture(scope="module")
def built(design_file, tmp_path_factory):
    out = tmp_path_factory.mktemp("build") / "sheet"
    try:
        code = main(["build", str(design_file), "--out", str(out)])
    except DataFileError as e:
        pytest.skip(f"no bone meshes here: {e}")
    assert code == 0
    return out


def test_build_sheet_rebuilds_the_routes_exactly(design_file, built):
    """Every attachment of every PAM read back from build_sheet.json: same names, bodies and kinds, the
    coordinates to round-off (0.1 µm), moving and conditional points with their definitions — and the rebuilt
    routes' lengths equal the design's at random poses."""
    des = load_design(design_file)
    sheet = json.loads((built / "build_sheet.json").read_text())
    routes = routes_from_sheet(sheet)
    assert sorted(routes) == sorted(p.id for p in des.pams)
    kinds = set()
    for pam in des.pams:
        got = routes[pam.id]
        assert [(p.name, p.body, type(p)) for p in got] == [(p.name, p.body, type(p)) for p in pam.points]
        for a, b in zip(got, pam.points):
            kinds.add(type(b).__name__)
            if isinstance(b, MovingPathPoint):
                assert a == b
            else:
                np.testing.assert_allclose(a.location, b.location, rtol=0, atol=1e-7)
            if isinstance(b, ConditionalPathPoint):
                assert (a.coordinate, a.range) == (b.coordinate, b.range)
    assert kinds == {"PathPoint", "ConditionalPathPoint", "MovingPathPoint"}

    skel = robot_skeleton()
    rng = np.random.default_rng(1)
    q = np.tile(skel.default_q, (8, 1))
    for c in ("hip_flexion_r", "knee_angle_r", "ankle_angle_r"):
        lo, hi = skel.coordinate_ranges[skel.coordinates.index(c)]
        q[:, skel.coordinates.index(c)] = rng.uniform(lo, hi, 8)
    st = skel.kinematics.forward(q, warn_range=False)
    ids = [p.id for p in des.pams]
    L_design = PathSet(skel.kinematics, [str(i) for i in ids], [p.points for p in des.pams]).evaluate(st).lengths
    L_sheet = PathSet(skel.kinematics, [str(i) for i in ids], [routes[i] for i in ids]).evaluate(st).lengths
    np.testing.assert_allclose(L_sheet, L_design, rtol=0, atol=5e-7)


def test_brackets_parts_and_mass(design_file, built):
    """A bracket's length is its point's distance from its own bone, its foot lies on the bone surface that
    distance back along its direction; the CSVs carry the JSON's rows; parts count PAM units and brackets of
    both sides; the mass is the audit's (assumed Festo weights)."""
    des = load_design(design_file)
    sheet = json.loads((built / "build_sheet.json").read_text())
    bones = BoneSet(robot_skeleton())
    fixed = [a for a in sheet["attachments"] if a["role"] != "moving point"]
    for a in fixed[::7]:
        P = np.array([[a["x_mm"], a["y_mm"], a["z_mm"]]]) / 1000.0
        d = float(bones.body_signed_distance(a["body"], P)[0])
        assert a["bracket_mm"] == pytest.approx(1000 * d, abs=0.006)
        foot = P[0] - d * np.array(a["bracket_direction"])
        np.testing.assert_allclose(1000 * foot, a["bracket_foot_mm"], atol=0.05)
        assert abs(float(bones.body_signed_distance(a["body"], np.asarray(a["bracket_foot_mm"])[None] / 1000)[0])) < 1e-4
    inside = [a for a in sheet["attachments"] if a.get("bracket_mm", 1) < 0]
    assert inside and all("inside the bone" in a["note"] for a in inside)
    parts = {(p["part"], p["what"]): p["count"] for p in sheet["parts"]}
    assert sum(n for (k, _), n in parts.items() if k == "PAM (Festo DMSP)") == 2 * sum(p.n_parallel for p in des.pams)
    assert sum(n for (k, _), n in parts.items() if k == "bracket") == 2 * len(fixed)
    assert sheet["mass"]["total_kg"] == pytest.approx(pams_mass(des.pams), abs=1e-3)
    with open(built / "attachments.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(sheet["attachments"])
    assert float(rows[0]["x_mm"]) == pytest.approx(sheet["attachments"][0]["x_mm"])
    with open(built / "pams.csv", newline="") as f:
        pams = list(csv.DictReader(f))
    assert [r["designation"] for r in pams] == [festo_designation(p.diameter_mm, p.resting_length_m) for p in des.pams]
    assert festo_designation(20, 0.4004) == "DMSP-20-400N-RM-CM"
    assert (built / "assembly.html").stat().st_size > 100_000
    md = (built / "build_sheet.md").read_text()
    assert "## Attachments" in md and "DMSP-" in md and "negative tendon" in md


def test_build_refuses_existing_output_and_bad_input(built, tmp_path, capsys):
    """An existing folder is refused before any work (exit 2, its files untouched); a bad design names the file."""
    before = (built / "build_sheet.md").read_bytes()
    assert main(["build", "thesis", "--out", str(built)]) == 2
    assert (built / "build_sheet.md").read_bytes() == before
    assert "holds files already" in capsys.readouterr().err
    assert main(["build", str(tmp_path / "nope.yaml"), "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()
    with pytest.raises(DataFileError, match="not a pamkin build sheet"):
        routes_from_sheet({"pams": []})
    with pytest.raises(DataFileError, match=r"attachments\[0\]"):
        routes_from_sheet({"format": "pamkin.build_sheet/1", "attachments": [{"pam_id": 1}]})


def test_sheet_of_a_design_on_one_segment_splits_its_cable():
    """A hand-made PAM on the second segment of a route whose first segment lies in one bone (pelvis to pelvis,
    50 mm, constant): its body sits at that segment's origin end, so its cable is 50 mm before the body (by
    hand) and the rest of the design's tendon after it."""
    from pamkin.opensim.model_file import PathPoint
    from pamkin.robot.design import Design, Pam

    pts = (PathPoint("a", "pelvis", (-0.10, 0.0, 0.08)), PathPoint("b", "pelvis", (-0.10, -0.05, 0.08)),
           PathPoint("c", "tibia_r", (-0.02, -0.05, 0.0)))
    pam = Pam(4, "Biceps Femoris Long Head", ("bifemlh_r",), "knee_angle_r", (), 20, 1, 0.25, 0.10, pts)
    sheet = build_sheet(Design("hand", (pam,), rom="robot_thesis"))
    p = sheet["pams"][0]
    assert p["on_one_segment"] and p["mount_segment"] == "b->c" and p["pam_at"] == "origin"
    assert p["cable"]["before_body_mm"] == pytest.approx(50.0, abs=1e-6)
    assert p["cable"]["before_body_mm"] + p["cable"]["after_body_mm"] == pytest.approx(100.0, abs=1e-6)
    assert p["designation"] == "DMSP-20-250N-RM-CM" and "warning" not in p
    roles = [a["role"] for a in sheet["attachments"]]
    assert roles == ["origin anchor", "via guide", "insertion anchor"]


def test_rollers_rebuild_from_the_sheet():
    """A PAM with a roller on the femur: the JSON's roller definitions rebuild the roller exactly, it is listed
    among the PAM's guides and the parts (one per side)."""
    from pamkin.build.documents import _pam_rows
    from pamkin.opensim.model_file import PathPoint
    from pamkin.outputs import strict_json
    from pamkin.robot.design import Design, Pam

    pts = (PathPoint("p1", "femur_r", (0.0, -0.043, 0.042)), PathPoint("p2", "femur_r", (0.057, -0.216, 0.029)),
           PathPoint("p3", "tibia_r", (0.03, -0.03, 0.0)))
    roller = Roller("p2->p3", "femur_r", (0.06, -0.38, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 0.008, 0.04)
    pam = Pam(11, "Vasti", ("vas_int_r",), "knee_angle_r", (), 20, 1, 0.12, 0.15, pts, rollers=(roller,))
    sheet = json.loads(strict_json(build_sheet(Design("roller", (pam,), rom="robot_thesis"))))
    assert rollers_from_sheet(sheet) == {11: (roller,)}
    assert "roller on p2->p3 (femur_r, r 8 mm)" in _pam_rows(sheet)[0]["guides"]
    assert [p["count"] for p in sheet["parts"] if p["part"] == "roller"] == [2]
    bad = json.loads(json.dumps(sheet))
    bad["pams"][0]["rollers"][0]["definition"]["segment"] = "p9->p10"
    with pytest.raises(DataFileError, match="PAM 11: roller"):
        rollers_from_sheet(bad)


def test_guide_roles_by_point_kind_and_name():
    """Intermediate points are named by what the optimiser made them: eyelets (``p1.p2.e``, ``p1.p2.e1``), detour
    guides (``p3.p4.1``), other via points; the route's ends are its anchors."""
    from pamkin.build.sheet import _role
    from pamkin.opensim.model_file import PathPoint
    from pamkin.robot.design import Pam

    names = ["p1", "p1.p2.e", "p1.p2.e1", "p2", "p2.p3.1", "p2.p3.e.1", "p3"]
    pts = tuple(PathPoint(n, "femur_r", (0.0, -0.01 * i, 0.0)) for i, n in enumerate(names))
    pam = Pam(1, "x", ("vas_int_r",), "knee_angle_r", (), 20, 1, 0.1, 0.1, pts)
    assert [_role(pam, i) for i in range(len(names))] == [
        "origin anchor", "eyelet", "eyelet", "via guide", "detour guide", "detour guide", "insertion anchor"]
