"""Visual checks: .vtp bone meshes, the meshcat page (rendered in headless Chromium) and the
torque-surface report."""

from __future__ import annotations

import base64
import re
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import pamkin
from pamkin.cli import main
from pamkin.errors import ConfigurationError, DataFileError, PamkinError
from pamkin.opensim.model_file import ConditionalPathPoint
from pamkin.viz.torque_report import CURVE_PX, SURFACE_PX, torque_report
from pamkin.robot.biped import thesis_robot
from pamkin.human.rom import load_rom
from pamkin.viz.meshcat_view import HEADER_PX, build_view, screenshot, sweep_frames
from pamkin.opensim.vtp import MeshWarning, body_meshes, read_vtp
from locations import ROOT

GEOMETRY = ROOT.parent / "shared" / "opensim-models" / "Geometry"
CHROMIUM = Path("/usr/bin/chromium")
needs_geometry = pytest.mark.skipif(not GEOMETRY.is_dir(), reason=f"OpenSim Geometry folder not found at {GEOMETRY}")
needs_chromium = pytest.mark.skipif(not CHROMIUM.exists(),
                                    reason="/usr/bin/chromium not installed (CI: apt-get install -y chromium)")


@pytest.fixture(scope="module")
def human():
    return pamkin.gait2392()


@pytest.fixture(scope="module")
def robot():
    return thesis_robot()


# ----------------------------------------------------------------------------- .vtp reader
def _text_counts(text: str) -> dict:
    """Counts and arrays parsed from a .vtp file's text with regular expressions (not XML)."""
    n_points = int(re.search(r'NumberOfPoints="(\d+)"', text).group(1))
    n_polys = int(re.search(r'NumberOfPolys="(\d+)"', text).group(1))
    points = re.search(r"<Points>\s*<DataArray[^>]*>(.*?)</DataArray>", text, re.DOTALL).group(1).split()
    polys = re.search(r"<Polys>(.*?)</Polys>", text, re.DOTALL).group(1)
    conn = [int(x) for x in re.search(r'Name="connectivity"[^>]*>(.*?)</DataArray>', polys, re.DOTALL).group(1).split()]
    offsets = [int(x) for x in re.search(r'Name="offsets"[^>]*>(.*?)</DataArray>', polys, re.DOTALL).group(1).split()]
    return {"n_points": n_points, "n_polys": n_polys, "points": [float(x) for x in points], "conn": conn,
            "offsets": offsets}


@needs_geometry
@pytest.mark.parametrize("name", ["femur_r.vtp", "bofoot.vtp", "hat_spine.vtp", "treadmill.vtp"])
def test_read_vtp_matches_the_file_text(name):
    path = GEOMETRY / name
    t = _text_counts(path.read_text())
    mesh = read_vtp(path)
    assert len(mesh.vertices) == t["n_points"]
    assert len(t["offsets"]) == t["n_polys"]
    corners = np.diff([0, *t["offsets"]])
    assert len(mesh.faces) == int(np.sum(corners - 2))            # fans: k corners -> k - 2 triangles
    pts = np.array(t["points"]).reshape(-1, 3)
    assert np.array_equal(mesh.vertices[:3], pts[:3])             # first and last points, as written
    assert np.array_equal(mesh.vertices[-1], pts[-1])
    assert list(mesh.faces[0]) == t["conn"][:3]                   # first triangle = first polygon's first corners
    assert mesh.faces.max() < t["n_points"]


SMALL_VTP = """<?xml version="1.0"?>
<VTKFile type="PolyData" version="0.1" byte_order="LittleEndian" compressor="vtkZLibDataCompressor">
  <PolyData>
    <Piece NumberOfPoints="9" NumberOfVerts="0" NumberOfLines="0" NumberOfStrips="1" NumberOfPolys="2">
      <PointData Normals="Normals">
        <DataArray type="Float32" Name="Normals" NumberOfComponents="3" format="ascii">
          0 0 1 0 0 1 0 0 1 0 0 1 0 0 1 0 0 1 0 0 1 0 0 1 0 0 1
        </DataArray>
      </PointData>
      <Points>
        <DataArray type="Float32" NumberOfComponents="3" format="{fmt}">
          0 0 0  1 0 0  1 1 0  0 1 0
          2 0 0  3 0 0  2 1 0  3 1 0  2.5 1.5 0
        </DataArray>
      </Points>
      <Strips>
        <DataArray type="Int32" Name="connectivity" format="ascii">4 5 6 7</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">4</DataArray>
      </Strips>
      <Polys>
        <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3  6 7 8</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">{offsets}</DataArray>
      </Polys>
    </Piece>
  </PolyData>
</VTKFile>
"""


def test_read_vtp_polygons_strips_and_normals(tmp_path):
    f = tmp_path / "small.vtp"
    f.write_text(SMALL_VTP.format(fmt="ascii", offsets="4 7"))
    mesh = read_vtp(f)
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [6, 7, 8], [4, 5, 6], [6, 5, 7]]   # strips as VTK splits them
    # areas by hand: unit square 1, triangle (2,1)-(3,1)-(2.5,1.5) 0.25, strip = square 2..3 x 0..1
    assert mesh.area == pytest.approx(1.0 + 0.25 + 1.0)
    assert np.all(mesh.face_normals[:, 2] > 0.99)                  # every triangle wound counter-clockwise
    assert np.allclose(mesh.vertex_normals, [0, 0, 1])


def test_read_vtp_refuses_binary_appended_and_corrupt_files(tmp_path):
    cases = {
        "binary.vtp": (SMALL_VTP.format(fmt="binary", offsets="4 7"), "binary"),
        "appended.vtp": (SMALL_VTP.format(fmt="appended", offsets="4 7").replace(
            "</PolyData>", '</PolyData><AppendedData encoding="raw">_</AppendedData>'), "appended"),
        "truncated.vtp": (SMALL_VTP.format(fmt="ascii", offsets="4 7")[:700], "not a VTK XML file"),
        "offsets.vtp": (SMALL_VTP.format(fmt="ascii", offsets="4 9"), "offsets"),
        "count.vtp": (SMALL_VTP.format(fmt="ascii", offsets="4 7").replace('NumberOfPoints="9"',
                                                                           'NumberOfPoints="10"'), "NumberOfPoints"),
        "number.vtp": (SMALL_VTP.format(fmt="ascii", offsets="4 7").replace("2.5 1.5", "2.5 x"),
                       "not a list of numbers"),
        "index.vtp": (SMALL_VTP.format(fmt="ascii", offsets="4 7").replace("6 7 8</", "6 7 9</"), "outside"),
        "unstructured.vtp": ('<VTKFile type="UnstructuredGrid"></VTKFile>', "not VTK PolyData"),
    }
    for name, (text, words) in cases.items():
        f = tmp_path / name
        f.write_text(text)
        with pytest.raises(DataFileError, match=words) as e:
            read_vtp(f)
        assert str(f) in str(e.value), name
    with pytest.raises(DataFileError, match="cannot read"):
        read_vtp(tmp_path / "missing.vtp")


@needs_geometry
def test_body_meshes(tmp_path, human):
    with pytest.raises(DataFileError, match="geometry folder not found") as e:
        body_meshes(human, tmp_path / "nope")
    assert str(tmp_path / "nope") in str(e.value)
    folder = tmp_path / "Geometry"
    folder.mkdir()
    for f in GEOMETRY.glob("*.vtp"):
        if f.name != "talus.vtp":
            (folder / f.name).symlink_to(f)
    with pytest.warns(MeshWarning, match="talus.vtp"):
        meshes = body_meshes(human, folder)
    assert set(meshes) == set(human.bodies)
    assert meshes["talus_r"] == [] and len(meshes["talus_l"]) == 1
    assert len(meshes["torso"]) == 4 and len(meshes["tibia_r"]) == 2
    # identity frames and unit scale factors in Gait2392: vertices as in the file
    assert np.array_equal(meshes["femur_r"][0].vertices, read_vtp(GEOMETRY / "femur_r.vtp").vertices)


# ----------------------------------------------------------------------------- paths as polylines
def test_polylines_are_the_paths_in_effect(human):
    paths = human.paths
    q = human.random_q(40, seed=3)
    k = human.coordinates.index("knee_angle_r")
    m = human.muscles.index("semimem_r")
    cond = [pt for pt in human.osim.muscles[m].points if isinstance(pt, ConditionalPathPoint)]
    assert cond and cond[0].coordinate == "knee_angle_r"
    lo, hi = cond[0].range
    q[:4, k] = [lo - 1e-3, lo + 1e-3, hi - 1e-3, hi + 1e-3]       # either side of both switches
    st = human.kinematics.forward(q, warn_range=False)
    L = paths.evaluate(st, moment_arms=False).lengths
    for j in range(len(q)):
        lines = paths.polylines(st, j)
        assert len(lines) == len(human.muscles)
        lengths = [np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in lines]
        assert np.abs(np.array(lengths) - L[j]).max() < 1e-12
    n_all = len(human.osim.muscles[m].points)
    assert [len(paths.polylines(st, j)[m]) for j in range(4)] == [n_all - 1, n_all, n_all, n_all - 1]


# ----------------------------------------------------------------------------- the meshcat page
def _commands(html: str) -> list[dict]:
    import umsgpack

    blobs = re.findall(r'^"([A-Za-z0-9+/=]+)",?$', html, re.MULTILINE)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def test_view_page_is_self_contained_and_animated(human, robot):
    view = build_view(human, robot, sweep="knee_angle_r", n=5)
    html = view.html()
    assert "<script src" not in html and "MeshCat.Viewer" in html
    assert f"<title>{view.title}</title>" in html and "force [N]" in html
    cmds = _commands(html)
    assert cmds[-1]["type"] == "set_animation"                    # loaded after every object exists
    clips = {a["path"]: a["clip"] for a in cmds[-1]["animations"]}
    F = len(view.frames)
    assert F == 8
    st = human.kinematics.forward(view.frames)
    for body in ("tibia_r", "talus_r"):
        tracks = {t["name"]: t for t in clips[f"/meshcat/pamkin/human/bones/{body}"]["tracks"]}
        pos = np.array([key["value"] for key in tracks[".position"]["keys"]])
        assert np.abs(pos - st.body_p[:, human.bodies.index(body)]).max() < 1e-6   # float32 in the page
    assert "/meshcat/pamkin/human/bones/torso" not in clips                       # does not move
    colored = [p for p, c in clips.items() if any(t["name"] == ".material.color" for t in c["tracks"])]
    assert any("/human/muscles/vas_int_r/" in p for p in colored)
    assert any("/robot/pams/pam11_r/pam/" in p for p in colored)
    # sweep = range of motion forth and back
    k = human.coordinates.index("knee_angle_r")
    assert np.allclose(view.frames[:, k], np.radians([-120, -87.5, -55, -22.5, 10, -22.5, -55, -87.5]))


def test_view_names_pams_on_a_pulley_block(human, robot):
    """A PAM on a 2:1 block is drawn at its own length ((route − tendon)/2 − fittings) and named in the header."""
    import dataclasses

    from pamkin.robot.design import Design
    from pamkin.robot.biped import PamRobot

    des = robot.design.replace_pam(dataclasses.replace(robot.design.pam(5), transmission=2))
    blocked = PamRobot(Design(des.name, des.pams, des.pressure_Pa, des.force_model, des.fitting_length_m, des.rom),
                       robot.model)
    html = build_view(human, blocked).html()
    assert "on a 2:1 pulley block" in html and "pam05" in html.split("on a 2:1 pulley block")[1][:200]
    assert "on a 2:1 pulley block" not in build_view(human, robot).html()


def test_view_bad_input(human, robot, tmp_path, capsys):
    with pytest.raises(ConfigurationError, match="layout"):
        build_view(human, robot, layout="stacked")
    with pytest.raises(ConfigurationError, match="color"):
        build_view(human, robot, color="pressure")
    with pytest.raises(ConfigurationError, match="unknown grid coordinate"):
        sweep_frames(robot, "knee_flexion_r", 5, np.zeros(23))
    with pytest.raises(ConfigurationError, match="no range of motion for 'pelvis_tx'"):
        sweep_frames(robot, "pelvis_tx", 5, np.zeros(23))
    html = tmp_path / "v.html"
    assert main(["view", "--html", str(html), "--geometry", str(tmp_path / "nope")]) == 2
    assert f"{tmp_path / 'nope'}: geometry folder not found" in capsys.readouterr().err
    assert main(["view", "--html", str(html), "--no-meshes", "--sweep", "knee"]) == 2
    assert "unknown grid coordinate(s) ['knee']" in capsys.readouterr().err
    assert main(["view", "--html", str(html), "--no-meshes", "--set", "knee_angle_r=abc"]) == 2
    assert "not a number" in capsys.readouterr().err
    bad = tmp_path / "Geometry"
    bad.mkdir()
    (bad / "sacrum.vtp").write_text("<VTKFile type='PolyData'><PolyData><Piece NumberOfPoints='1'>")
    assert main(["view", "--html", str(html), "--geometry", str(bad)]) == 2
    assert f"{bad / 'sacrum.vtp'}: not a VTK XML file" in capsys.readouterr().err
    assert not html.exists()


def _near(img: np.ndarray, colors: np.ndarray, tol: float) -> np.ndarray:
    """Mask of pixels within ``tol`` (0-255 units, max over channels) of any of ``colors``."""
    c = np.unique(np.round(colors * 255), axis=0)
    d = np.abs(img[:, :, None, :3].astype(float) - c[None, None]).max(axis=-1)
    return (d <= tol).any(axis=-1)


@needs_chromium
def test_page_renders_in_headless_chromium(human, robot, tmp_path):
    from PIL import Image

    t0 = time.perf_counter()
    if GEOMETRY.is_dir():
        with warnings.catch_warnings():
            warnings.simplefilter("error", MeshWarning)
            meshes = body_meshes(human, GEOMETRY)
    else:
        meshes = None
    q = np.zeros(len(human.coordinates))
    q[human.coordinates.index("knee_angle_r")] = np.radians(-40)
    view = build_view(human, robot, meshes=meshes, q=q)
    page = view.save(tmp_path / "view.html")
    png = screenshot(page, tmp_path / "view.png", size=(800, 600), budget_ms=3000)
    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape == (600, 800, 3)
    scene = img[HEADER_PX + 2:]                                   # below the page header (title, legend)
    background = (scene.astype(int).min(axis=-1) > 245)
    assert 1.0 - background.mean() > 0.04, "almost nothing rendered"
    # the canvas is the pane (window less header), so the framed scene is whole: nothing at the pane's edges
    # (meshcat alone sizes the canvas to the window height, which cut the feet off below the pane)
    assert background[-6:].all() and background[:6, : int(0.65 * background.shape[1])].all()   # (right: controls)
    # human muscles are unlit (MeshBasicMaterial): their exact colours appear, mostly on the left half
    # (thin blue PAMs on the right may match a few of them)
    muscles = _near(scene, view.human_rgb[0], 6)
    assert muscles.sum() > 400
    w = scene.shape[1]
    assert muscles[:, : w // 2].sum() > 0.75 * muscles.sum()
    found = [c for c in np.unique(np.round(view.human_rgb[0] * 255), axis=0)
             if _near(scene[:, : w // 2], c[None] / 255, 3).sum() > 20]
    assert len(found) >= 5, "too few distinct muscle colours rendered"
    # PAMs are shaded (Lambert): pixels of their hue, saturated, on the right half
    sat = scene.astype(int).max(axis=-1) - scene.astype(int).min(axis=-1) > 80
    right = sat[:, w // 2:].sum()
    assert right > 1500, "no PAM colours on the robot side"
    # bones: light ivory / grey-blue, unsaturated but not background
    bones = ~background & ~sat
    assert bones.sum() > 5000
    assert time.perf_counter() - t0 < 90


@needs_chromium
def test_screenshot_reports_page_errors(tmp_path):
    page = tmp_path / "broken.html"
    page.write_text("<html><body><script>throw new Error('boom')</script></body></html>")
    with pytest.raises(PamkinError, match="Uncaught Error: boom"):
        screenshot(page, tmp_path / "broken.png", size=(200, 100), budget_ms=500)


# ----------------------------------------------------------------------------- report
@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    """The full report of the built-in design (≈ 20 s: 54 figures) and its CPU time (not wall-clock time:
    the goal, < 60 s, should not depend on other processes on the machine)."""
    out = tmp_path_factory.mktemp("report")
    t0 = time.process_time()
    assert main(["report", "--out", str(out)]) == 0
    return out, time.process_time() - t0


@pytest.mark.slow
def test_report_writes_every_figure_and_index(report_dir):
    from PIL import Image

    from pamkin.cli.robot import _robot

    out, cpu_seconds = report_dir
    assert cpu_seconds < 60
    design = _robot(None).design
    expected = {f"{p.key}_{kind}.png" for p in design.pams for kind in ("surfaces", "curve")}
    assert len(expected) == 2 * len(design.pams)
    written = {f.name for f in out.glob("*.png")}
    assert written == expected
    for name in expected:
        f = out / name
        assert f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        with Image.open(f) as im:
            assert im.size == (SURFACE_PX if "surfaces" in name else CURVE_PX)
            assert np.asarray(im.convert("L")).std() > 10        # not blank
    index = (out / "index.html").read_text()
    assert set(re.findall(r'href="([^"]+)"', index)) == expected
    assert set(re.findall(r'src="([^"]+)"', index)) == expected


def test_report_torques_are_the_human_muscle_sums(human, robot, tmp_path):
    rep = torque_report(robot, human, tmp_path, pams=[4, 11], n=5, n1=11)
    assert [p.key for p in rep.pams] == ["pam04", "pam11"]
    assert rep.pams[1].partner == "hip_flexion_r"                  # uniarticular knee PAM: default partner
    for p in rep.pams:
        k = robot.names.index(f"{p.key}_r")
        q, _ = human.grid([p.primary], 11, rom=load_rom(robot.design.rom, "r"),
                          base={c: 0.0 for c in human.coordinates})
        c = human.coordinates.index(p.primary)
        idx = [human.muscles.index(m) for m in robot.human_muscles(k)]
        th = human.torques(q)[:, idx, c].sum(axis=1)
        tr = robot.evaluate(q).torques[:, k, c]
        assert p.primary_match.human_peak_Nm == pytest.approx(np.abs(th).max(), rel=1e-12)
        assert p.primary_match.robot_peak_Nm == pytest.approx(np.abs(tr).max(), rel=1e-12)
        assert p.surfaces.is_file() and p.curve.is_file()


def test_report_bad_input(robot, human, tmp_path, capsys):
    assert main(["report", "--out", str(tmp_path), "--partner", "hip_flex"]) == 2
    assert "unknown coordinate 'hip_flex'" in capsys.readouterr().err
    assert main(["report", "--out", str(tmp_path), "--pams", "99"]) == 2
    assert "unknown PAM id(s) [99]" in capsys.readouterr().err
    with pytest.raises(ConfigurationError, match="is its primary coordinate"):
        torque_report(robot, human, tmp_path, pams=[4], partner="knee_angle_r")
    assert not list(tmp_path.glob("*.png"))


def test_docs_pictures_are_small():
    for name in ("view.png", "report_knee.png"):
        f = ROOT / "docs" / name
        assert f.is_file() and f.stat().st_size < 300_000, name
