"""OpenSim bone meshes: ASCII VTK XML PolyData (``.vtp``) → :class:`trimesh.Trimesh`.

OpenSim's ``Geometry`` folders hold ``.vtp`` files written by VTK in its ASCII form: a
``<Piece>`` with ``<Points>`` and ``<Polys>`` (``connectivity`` + ``offsets`` arrays),
sometimes ``<Strips>`` and optional point ``Normals``. Polygons with more than three
corners are split into fans of triangles and strips into their triangles; vertices and
lines carry no surface and are ignored. Binary, appended and compressed data arrays are
refused with a :class:`~pamkin.errors.DataFileError` naming the file (convert them with
VTK, e.g. ``vtkXMLPolyDataWriter.SetDataModeToAscii()``).

:func:`body_meshes` places a model's meshes (``Body.meshes``: file, scale factors, frame)
in their body frames.
"""

from __future__ import annotations

import os
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from pamkin.errors import DataFileError

__all__ = ["MeshWarning", "body_meshes", "read_vtp"]


class MeshWarning(UserWarning):
    """A mesh file named by the model is missing or unreadable; the mesh is skipped."""


def _array(path: Path, parent: ET.Element, name: str | None, dtype, what: str) -> np.ndarray:
    """The ASCII ``DataArray`` of ``parent`` (the one called ``name``, or the first)."""
    arrays = parent.findall("DataArray")
    if name is not None:
        arrays = [a for a in arrays if a.get("Name") == name]
    if not arrays:
        raise DataFileError(str(path), f"<{parent.tag}> has no DataArray{f' {name!r}' if name else ''} ({what})")
    a = arrays[0]
    fmt = a.get("format", "ascii")
    if fmt != "ascii":
        raise DataFileError(str(path), f"{what}: DataArray format={fmt!r} is not supported; only ASCII .vtp files "
                                       "are read (convert with VTK: vtkXMLPolyDataWriter.SetDataModeToAscii())")
    try:
        return np.array((a.text or "").split(), dtype=dtype)
    except ValueError as e:
        raise DataFileError(str(path), f"{what}: not a list of numbers ({e})") from None


def _cells(path: Path, piece: ET.Element, tag: str, n_expected: int, n_points: int):
    """(offsets, connectivity) of a cell block (``Polys``/``Strips``), checked; None if absent."""
    el = piece.find(tag)
    if el is None:
        if n_expected:
            raise DataFileError(str(path), f"Number{'Of' + tag}={n_expected} but there is no <{tag}> element")
        return None
    conn = _array(path, el, "connectivity", np.int64, f"{tag} connectivity")
    offs = _array(path, el, "offsets", np.int64, f"{tag} offsets")
    if len(offs) != n_expected:
        raise DataFileError(str(path), f"NumberOf{tag}={n_expected} but {len(offs)} {tag} offsets")
    if len(offs) and (np.any(np.diff(np.concatenate([[0], offs])) < 0) or offs[-1] != len(conn)):
        raise DataFileError(str(path), f"{tag} offsets do not match the {len(conn)} connectivity entries")
    if len(conn) and (conn.min() < 0 or conn.max() >= n_points):
        raise DataFileError(str(path), f"{tag} connectivity refers to points outside 0..{n_points - 1}")
    return offs, conn


def _fans(offs: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """Triangles (T, 3) of polygons, in file order: a fan from each polygon's first corner."""
    starts = np.concatenate([[0], offs[:-1]]).astype(np.int64)
    n_tri = np.maximum(offs - starts - 2, 0)
    poly = np.repeat(np.arange(len(offs)), n_tri)
    j = np.arange(int(n_tri.sum())) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
    s = starts[poly]
    return np.stack([conn[s], conn[s + j], conn[s + j + 1]], axis=1).reshape(-1, 3)


def _strips(offs: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """Triangles (T, 3) of triangle strips (every other triangle flipped to keep the winding)."""
    tris = []
    start = 0
    for end in offs:
        s = conn[start:end]
        for j in range(len(s) - 2):
            tris.append((s[j], s[j + 1], s[j + 2]) if j % 2 == 0 else (s[j + 1], s[j], s[j + 2]))
        start = end
    return np.array(tris, dtype=np.int64).reshape(-1, 3)


def read_vtp(path: str | os.PathLike):
    """Read an ASCII VTK XML PolyData file into a triangle mesh.

    Args:
        path: The ``.vtp`` file.

    Returns:
        A :class:`trimesh.Trimesh` with the file's points as vertices (same order and count,
        nothing merged) and its polygons and strips as triangles; point normals when given.

    Raises:
        pamkin.errors.DataFileError: The file cannot be read, is not PolyData, uses binary,
            appended or compressed data arrays, or its arrays are inconsistent.
    """
    import trimesh  # noqa: PLC0415

    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except OSError as e:
        raise DataFileError(str(path), f"cannot read: {e.strerror or e}") from None
    except ET.ParseError as e:
        raise DataFileError(str(path), f"not a VTK XML file: {e}") from None
    if root.tag != "VTKFile" or root.get("type") != "PolyData":
        raise DataFileError(str(path), f"not VTK PolyData (root <{root.tag} type={root.get('type')!r}>)")
    if root.find("AppendedData") is not None:
        raise DataFileError(str(path), "appended (binary) data is not supported; only ASCII .vtp files are read")
    pieces = root.findall("PolyData/Piece")
    if len(pieces) != 1:
        raise DataFileError(str(path), f"expected one <Piece>, found {len(pieces)}")
    piece = pieces[0]
    try:
        counts = {k: int(piece.get(f"NumberOf{k}", "0")) for k in ("Points", "Polys", "Strips")}
    except ValueError as e:
        raise DataFileError(str(path), f"<Piece> counts are not integers ({e})") from None
    pts_el = piece.find("Points")
    if pts_el is None:
        raise DataFileError(str(path), "no <Points> element")
    pts = _array(path, pts_el, None, np.float64, "Points")
    n = counts["Points"]
    if pts.size != 3 * n:
        raise DataFileError(str(path), f"NumberOfPoints={n} but <Points> holds {pts.size} numbers (expected {3 * n})")
    vertices = pts.reshape(n, 3)
    if not np.all(np.isfinite(vertices)):
        raise DataFileError(str(path), "<Points> holds non-finite numbers")
    faces = [np.zeros((0, 3), dtype=np.int64)]
    polys = _cells(path, piece, "Polys", counts["Polys"], n)
    if polys is not None:
        faces.append(_fans(*polys))
    strips = _cells(path, piece, "Strips", counts["Strips"], n)
    if strips is not None:
        faces.append(_strips(*strips))
    faces = np.concatenate(faces)
    normals = None
    pd = piece.find("PointData")
    if pd is not None and any(a.get("Name") == "Normals" for a in pd.findall("DataArray")):
        nrm = _array(path, pd, "Normals", np.float64, "PointData Normals")
        if nrm.size == 3 * n:
            normals = nrm.reshape(n, 3)
    return trimesh.Trimesh(vertices=vertices, faces=faces, vertex_normals=normals, process=False)


def body_meshes(model, geometry_dir: str | os.PathLike) -> dict[str, list]:
    """Every body's meshes, scaled and placed in the body frame.

    Args:
        model: A :class:`pamkin.Model` (uses ``model.osim.bodies[i].meshes``).
        geometry_dir: Folder holding the ``.vtp`` files (OpenSim's ``Geometry`` folder).

    Returns:
        ``{body: [trimesh.Trimesh, ...]}`` for every body of the model (an empty list where
        a body has no mesh), vertices in the body frame [m].

    Raises:
        pamkin.errors.DataFileError: ``geometry_dir`` is not a folder, or a mesh file is corrupt.

    A mesh file that does not exist is skipped with a :class:`MeshWarning`.
    """
    folder = Path(geometry_dir)
    if not folder.is_dir():
        raise DataFileError(str(folder), "geometry folder not found (it should hold the model's .vtp bone meshes, "
                                         "e.g. opensim-models/Geometry)")
    out: dict[str, list] = {}
    for body in model.osim.bodies:
        meshes = []
        for g in body.meshes:
            f = folder / g.mesh_file
            if not f.is_file():
                warnings.warn(f"{f}: mesh of body {body.name!r} not found; skipped", MeshWarning, stacklevel=2)
                continue
            m = read_vtp(f)
            m.apply_transform(g.frame.transform() @ np.diag([*g.scale_factors, 1.0]))
            meshes.append(m)
        out[body.name] = meshes
    return out
