"""Bone meshes in the URDFs: files, yourdfpy and Pinocchio loading, rendered pictures, load_osim."""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from pamkin.human.meshes import MAX_FACES, find_geometry_dir, render_urdf, stl_bytes, urdf_configuration
from pamkin.human.urdf import GAIT2392_URDF, ROBOT_URDF
from locations import ROOT

URDFS = [GAIT2392_URDF, ROBOT_URDF]


@pytest.fixture(scope="module")
def pose():
    """URDF joint values of the upright pose (every coordinate 0; knee translations follow knee angle)."""
    import pamkin

    return urdf_configuration(pamkin.gait2392())


def _visual_meshes(urdf: Path) -> list[str]:
    root = ET.parse(urdf).getroot()
    return [m.get("filename") for m in root.iter("mesh")]


@pytest.mark.parametrize("urdf", URDFS, ids=lambda p: p.stem)
def test_every_body_link_has_its_bones(urdf):
    root = ET.parse(urdf).getroot()
    with_visual = {link.get("name") for link in root.iter("link") if link.find("visual") is not None}
    # Gait2392's bones: pelvis (3 meshes), femurs, tibias (tibia + fibula), tali, feet, toes, torso (4 meshes)
    assert {"pelvis", "femur_r", "femur_l", "tibia_r", "tibia_l", "talus_r", "calcn_l", "toes_r",
            "torso"} <= with_visual
    files = _visual_meshes(urdf)
    assert len(files) == 19 and all(f.startswith("meshes/") and f.endswith(".stl") for f in files)
    for f in files:
        assert (urdf.parent / f).is_file(), f


def test_committed_meshes_are_small_binary_and_credited():
    folder = GAIT2392_URDF.parent / "meshes"
    stls = sorted(folder.glob("*.stl"))
    total = sum(f.stat().st_size for f in stls)
    assert 0 < total < 5e6, f"{total} bytes"
    for f in stls:
        data = f.read_bytes()
        n = int.from_bytes(data[80:84], "little")
        assert len(data) == 84 + 50 * n and 0 < n <= MAX_FACES, f.name   # binary STL, decimated
        assert not data[:5].lower() == b"solid"
    credit = (folder / "README.md").read_text()
    assert "Gait2392" in credit and "Delp" in credit and "CC BY 3.0" in credit


def test_stl_writer_round_trips_through_trimesh(tmp_path):
    import trimesh

    box = trimesh.creation.box()
    path = tmp_path / "box.stl"
    path.write_bytes(stl_bytes(box.vertices, box.faces, "solid header is escaped"))
    back = trimesh.load(path)
    assert len(back.faces) == 12 and np.isclose(back.volume, box.volume)


@pytest.mark.parametrize("urdf", URDFS, ids=lambda p: p.stem)
def test_yourdfpy_loads_every_mesh(urdf, pose):
    import yourdfpy

    robot = yourdfpy.URDF.load(str(urdf), build_scene_graph=True, load_meshes=True)
    geoms = robot.scene.geometry
    assert len(robot.scene.graph.nodes_geometry) == len(_visual_meshes(urdf))
    assert all(len(g.faces) > 0 for g in geoms.values())
    robot.update_cfg({k: v for k, v in pose.items() if k in robot.actuated_joint_names})
    lo, hi = robot.scene.bounds
    assert 1.6 < hi[1] - lo[1] < 1.9        # Gait2392 standing, top of the skull to the heels [m]


@pytest.mark.parametrize("urdf", URDFS, ids=lambda p: p.stem)
def test_pinocchio_builds_the_visual_model(urdf):
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(urdf))
    visual = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.VISUAL, package_dirs=[str(urdf.parent)])
    assert visual.ngeoms == len(_visual_meshes(urdf))
    assert all(Path(g.meshPath).is_file() for g in visual.geometryObjects)


@pytest.mark.parametrize("urdf", URDFS, ids=lambda p: p.stem)
def test_rendering_shows_the_skeleton(urdf, tmp_path, pose):
    import matplotlib.image as mpimg

    png = render_urdf(urdf, tmp_path / "view.png", size=(600, 500), configuration=pose)
    img = mpimg.imread(png)[..., :3]
    ink = np.any(img < 0.9, axis=2)                      # non-white pixels
    assert 0.05 < ink.mean() < 0.6, ink.mean()
    left, right = ink[:, : ink.shape[1] // 2], ink[:, ink.shape[1] // 2:]
    assert left.mean() > 0.03 and right.mean() > 0.03    # front and side views both drawn
    rows = np.flatnonzero(left.mean(axis=1) > 0.005)
    assert rows[-1] - rows[0] > 0.6 * ink.shape[0]      # tall: head to feet
    bone = (img[..., 0] > img[..., 2] + 0.03) & ink      # bone colour (warm grey), not just text
    assert bone.mean() > 0.03


def test_the_documentation_shows_the_pictures():
    """Every URDF's picture is on the documentation's visual-checks page (and the file is there)."""
    text = (ROOT / "docs" / "visual-checks.md").read_text()
    for urdf in URDFS:
        name = f"urdf_{urdf.stem}.png"
        assert f"]({name})" in text and (ROOT / "docs" / name).is_file()


def test_find_geometry_dir_as_opensim(tmp_path):
    model = tmp_path / "models" / "m.osim"
    model.parent.mkdir()
    model.write_text("<OpenSimDocument/>")
    assert find_geometry_dir(model) is None
    (tmp_path / "Geometry").mkdir()
    (tmp_path / "Geometry" / "a.vtp").write_text("")
    assert find_geometry_dir(model) == tmp_path / "Geometry"          # ../Geometry (opensim-models layout)
    (model.parent / "Geometry").mkdir()
    (model.parent / "Geometry" / "a.vtp").write_text("")
    assert find_geometry_dir(model) == model.parent / "Geometry"       # Geometry/ beside the model first


@pytest.mark.needs_shared
def test_load_osim_gives_bones_when_geometry_is_beside_the_model(gait2392_path, tmp_path, monkeypatch):
    import yourdfpy

    import pamkin

    monkeypatch.setenv("PAMKIN_CACHE", str(tmp_path / "cache"))
    model = pamkin.load_osim(gait2392_path)                       # ../Geometry beside the model folder
    assert str(model.urdf_path).startswith(str(tmp_path / "cache"))
    assert len(_visual_meshes(model.urdf_path)) == 19
    robot = yourdfpy.URDF.load(str(model.urdf_path), load_meshes=True)
    assert len(robot.scene.graph.nodes_geometry) == 19
    # the same model without its Geometry folder: a URDF without visuals (and another cache entry)
    alone = tmp_path / "alone" / gait2392_path.name
    alone.parent.mkdir()
    shutil.copy(gait2392_path, alone)
    bare = pamkin.load_osim(alone)
    assert _visual_meshes(bare.urdf_path) == [] and bare.urdf_path != model.urdf_path
    # an explicit geometry folder
    with_geom = pamkin.load_osim(alone, geometry=find_geometry_dir(gait2392_path))
    assert len(_visual_meshes(with_geom.urdf_path)) == 19
