"""Bone meshes of URDFs: OpenSim ``.vtp`` files → decimated binary STL, and pictures of a URDF.

The URDF generator (:mod:`pamkin.human.urdf`) gives every body link a ``<visual>`` per mesh the
OpenSim model attaches to the body (``Body.meshes``: file, scale factors, frame), referencing a
binary STL written beside the URDF (``meshes/<name>.stl``, a path relative to the URDF file).
Meshes above :data:`MAX_FACES` triangles are decimated (quadric decimation, ``fast-simplification``),
deterministically, so that ``pamkin urdf --check`` can compare regenerated files byte for byte.

:func:`find_geometry_dir` looks for the ``.vtp`` files where OpenSim does: beside the model file,
in its ``Geometry`` subfolder, and in ``../Geometry`` (the opensim-models layout).
:func:`render_urdf` draws a URDF's meshes (matplotlib, no display or GPU needed).
"""

from __future__ import annotations

import math
import os
import struct
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from pamkin.errors import DataFileError
from pamkin.outputs import write_figure
from pamkin.opensim.vtp import MeshWarning, read_vtp

__all__ = ["MAX_FACES", "MESH_SUBDIR", "find_geometry_dir", "mesh_sources", "render_urdf", "stl_bytes",
           "stl_name", "bone_stl", "urdf_configuration"]

#: Meshes with more triangles are decimated to this many (Gait2392: the spine, ribs, skull).
MAX_FACES = 3000
#: Folder of the meshes, relative to the URDF that references them.
MESH_SUBDIR = "meshes"


def urdf_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (R = Rz(yaw)·Ry(pitch)·Rx(roll)) of a rotation matrix [rad]."""
    pitch = math.asin(max(-1.0, min(1.0, -float(R[2, 0]))))
    roll = math.atan2(float(R[2, 1]), float(R[2, 2]))
    yaw = math.atan2(float(R[1, 0]), float(R[0, 0]))
    return (roll, pitch, yaw)


def find_geometry_dir(model_path: str | os.PathLike) -> Path | None:
    """The folder of a model's ``.vtp`` meshes, searched as OpenSim does; None if there is none.

    Candidates, in order: ``<model folder>/Geometry``, the model folder itself, and
    ``<model folder>/../Geometry``; the first holding a ``.vtp`` file wins.
    """
    here = Path(model_path).resolve().parent
    for folder in (here / "Geometry", here, here.parent / "Geometry"):
        if folder.is_dir() and any(folder.glob("*.vtp")):
            return folder
    return None


def stl_name(mesh_file: str) -> str:
    """Path of the STL of an OpenSim mesh file, relative to the URDF (``meshes/femur_r.stl``)."""
    return f"{MESH_SUBDIR}/{Path(mesh_file).stem}.stl"


def mesh_sources(model, geometry_dir: str | os.PathLike | None) -> dict[str, Path]:
    """``{mesh_file: .vtp path}`` of every mesh of the model's bodies found in ``geometry_dir``.

    Mesh files named by the model but missing from the folder are skipped with a
    :class:`~pamkin.opensim.vtp.MeshWarning`; without a folder the result is empty.
    """
    if geometry_dir is None:
        return {}
    folder = Path(geometry_dir)
    if not folder.is_dir():
        raise DataFileError(str(folder), "geometry folder not found (it should hold the model's .vtp bone meshes)")
    out: dict[str, Path] = {}
    for body in model.bodies:
        for g in body.meshes:
            f = folder / g.mesh_file
            if f.is_file():
                out[g.mesh_file] = f
            elif g.mesh_file not in out:
                warnings.warn(f"{f}: mesh of body {body.name!r} not found; the link gets no visual",
                              MeshWarning, stacklevel=2)
    return out


def stl_bytes(vertices: np.ndarray, faces: np.ndarray, header: str = "") -> bytes:
    """A binary STL file (80-byte header, little endian) of a triangle mesh."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    rec = np.zeros(len(f), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"] = n
    rec["v"] = tri
    head = header.encode("ascii", "replace")[:80].ljust(80, b" ")
    if head.lower().startswith(b"solid"):  # readers would take it for ASCII STL
        head = b"#" + head[:79]
    return head + struct.pack("<I", len(f)) + rec.tobytes()


def bone_stl(vtp_path: str | os.PathLike, max_faces: int = MAX_FACES) -> bytes:
    """Binary STL of a ``.vtp`` mesh, decimated to ``max_faces`` triangles when it has more."""
    import trimesh  # noqa: PLC0415

    m = read_vtp(vtp_path)
    faces = m.faces
    vertices = m.vertices
    if len(faces) > max_faces:
        try:
            d = trimesh.Trimesh(vertices, faces, process=False).simplify_quadric_decimation(face_count=max_faces)
        except ImportError as e:  # trimesh needs fast-simplification for this
            raise DataFileError(str(vtp_path), f"decimating needs the fast-simplification package "
                                               f"(pip install fast-simplification): {e}") from None
        vertices, faces = d.vertices, d.faces
    return stl_bytes(vertices, faces, f"pamkin bone mesh from {Path(vtp_path).name}")


def mesh_files(model, geometry_dir: str | os.PathLike | None) -> dict[str, bytes]:
    """``{path relative to the URDF: STL bytes}`` of every mesh of ``model`` found in ``geometry_dir``."""
    return {stl_name(name): bone_stl(src) for name, src in mesh_sources(model, geometry_dir).items()}


def urdf_configuration(model, q=None) -> dict[str, float]:
    """URDF joint values ``{joint: value}`` of an OpenSim configuration of ``model``.

    Every variable TransformAxis is one URDF joint whose value is its function of the coordinate
    (the knee translations are splines of knee angle), so a URDF viewer shows OpenSim's pose only
    with these values, not with all joints at 0.

    Args:
        model: A :class:`pamkin.Model`.
        q: A configuration (default: every coordinate 0, the upright neutral pose).
    """
    q = model.kinematics.as_q(np.zeros(len(model.coordinates)) if q is None else q, warn_range=False)
    v, _ = model.kinematics.joint_values(q[:1])
    return {name: float(x) for name, x in zip(list(model.pin_model.names)[1:], v[0])}


def _world_mesh(urdf_path: str | os.PathLike, configuration: dict[str, float] | None = None):
    """Every visual mesh of a URDF at a configuration, concatenated, in the root frame; and the
    PAM routes (``{pamNN_s: (K, 3)}`` through the ``pamNN_s_pointK`` frames), if any."""
    import re  # noqa: PLC0415

    import trimesh  # noqa: PLC0415
    import yourdfpy  # noqa: PLC0415

    urdf = yourdfpy.URDF.load(str(urdf_path), build_scene_graph=True, load_meshes=True)
    if configuration:
        names = set(urdf.actuated_joint_names)
        urdf.update_cfg({k: v for k, v in configuration.items() if k in names})
    points: dict[str, list] = {}
    for link in urdf.link_map:
        m = re.fullmatch(r"(pam\d+_[rl])_point(\d+)", link)
        if m:
            points.setdefault(m.group(1), []).append((int(m.group(2)), urdf.get_transform(link)[:3, 3]))
    routes = {k: np.array([p for _, p in sorted(v, key=lambda t: t[0])]) for k, v in sorted(points.items())}
    meshes = []
    for node in urdf.scene.graph.nodes_geometry:
        T, geom = urdf.scene.graph.get(node)
        m = urdf.scene.geometry[geom].copy()
        m.apply_transform(T)
        meshes.append(m)
    if not meshes:
        raise DataFileError(str(urdf_path), "the URDF has no visual meshes to draw")
    return trimesh.util.concatenate(meshes), routes


def render_urdf(urdf_path: str | os.PathLike, png: str | os.PathLike, size: tuple[int, int] = (900, 700),
                title: str | None = None, configuration: dict[str, float] | None = None) -> Path:
    """Draw a URDF's visual meshes, front and side views, into a PNG.

    A flat-shaded orthographic projection of every triangle (matplotlib, painter's order): works
    without a display or GPU. OpenSim axes: x forward, y up, z to the right. Route points of PAMs
    (links ``pamNN_r_pointK`` of the robot URDF) are joined by red lines, drawn over the bones.

    Args:
        configuration: URDF joint values (:func:`urdf_configuration`); joints not named are 0.

    Returns:
        The PNG path.
    """
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415
    from matplotlib.collections import PolyCollection  # noqa: PLC0415

    mesh, routes = _world_mesh(urdf_path, configuration)
    tri = mesh.vertices[mesh.faces]
    normals = mesh.face_normals
    dpi = 100
    fig, axes = plt.subplots(1, 2, figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
    # (horizontal axis, vertical axis, viewing direction towards the viewer)
    views = (("front (x towards the viewer)", 2, 1, np.array([1.0, 0.0, 0.0])),
             ("side (z towards the viewer)", 0, 1, np.array([0.0, 0.0, 1.0])))
    for ax, (label, h, v, toward) in zip(axes, views):
        depth = tri @ toward
        order = np.argsort(depth.mean(axis=1))
        light = toward + np.array([0.0, 0.5, 0.0]) + 0.3 * np.cross(toward, [0.0, 1.0, 0.0])
        lam = np.abs(normals[order] @ (light / np.linalg.norm(light)))
        shade = 0.3 + 0.65 * lam
        colors = np.stack([0.93 * shade, 0.89 * shade, 0.80 * shade, np.ones_like(shade)], axis=1)
        polys = tri[order][:, :, [h, v]]
        if h == 2:          # front view: the model's right (+z) on the viewer's left
            polys = polys * np.array([-1.0, 1.0])
        ax.add_collection(PolyCollection(polys, facecolors=colors, edgecolors="none"))
        for route in routes.values():   # PAM route points (fixed frames of the robot URDF)
            xy = route[:, [h, v]] * (np.array([-1.0, 1.0]) if h == 2 else 1.0)
            ax.plot(xy[:, 0], xy[:, 1], "-", color="#c0392b", lw=1.2, alpha=0.8, zorder=3)
        lo, hi = polys.reshape(-1, 2).min(axis=0), polys.reshape(-1, 2).max(axis=0)
        pad = 0.05 * float((hi - lo).max())
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_axis_off()
        ax.set_title(label, fontsize=9)
    fig.suptitle(title or f"{Path(urdf_path).name}: bone meshes"
                 + (f", {len(routes)} PAM routes (through their route points)" if routes else ""), fontsize=11)
    fig.tight_layout()
    try:
        return write_figure(fig, png, facecolor="white")
    finally:
        plt.close(fig)


def visual_specs(model, available: Iterable[str]) -> dict[str, list[dict]]:
    """``{body: [visual, ...]}`` for the URDF data: mesh path, origin (xyz, rpy) and scale."""

    available = set(available)
    out: dict[str, list[dict]] = {}
    for body in model.bodies:
        vis = []
        for g in body.meshes:
            if g.mesh_file not in available:
                continue
            T = g.frame.transform()
            vis.append({"mesh": stl_name(g.mesh_file), "xyz": [float(x) for x in T[:3, 3]],
                        "rpy": [float(x) for x in urdf_rpy(T[:3, :3])],
                        "scale": [float(s) for s in g.scale_factors]})
        out[body.name] = vis
    return out
