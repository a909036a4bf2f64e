"""The assembled robot as a meshcat page: both legs' bone meshes at the default pose, every route as a thin
cable, every PAM body where the audit places it at its largest outer radius (inflated, with its fittings,
:func:`pamkin.audit.assembly.body_radius`), rollers, and each bracket from its foot on the bone to its
attachment point (the build sheet's, :mod:`pamkin.build.sheet`)."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from pamkin.audit.assembly import body_radius
from pamkin.errors import RangeWarning
from pamkin.human.bones import BoneSet
from pamkin.outputs import write_file
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.robot.design import mirror_name
from pamkin.robot.pam_body import pam_capsules, route_positions
from pamkin.viz.meshcat_view import StaticWindow, _cylinder_frames, _frame_camera, _translation, roller_transforms

__all__ = ["ASPECT", "SCREENSHOT_SIZE", "assembly_view"]

#: Width / height of the page's picture (:data:`SCREENSHOT_SIZE`).
ASPECT = 0.8
#: Size of the page's screenshot [px] (a standing robot: taller than wide).
SCREENSHOT_SIZE = (800, 1000)
#: Colours of the PAM bodies by Festo size (10, 20, 40 mm).
BODY_COLORS = {10: 0x2CA02C, 20: 0x1F77B4, 40: 0xD62728}


def _cylinder(vis, g, node: str, A: np.ndarray, B: np.ndarray, radius: float, color: int, opacity: float = 1.0):
    L = float(np.linalg.norm(B - A))
    if L < 1e-9:
        return
    T = _cylinder_frames(A[None], B[None])[0][0]
    vis[node].set_object(g.Cylinder(L, radius), g.MeshLambertMaterial(color=color, opacity=opacity,
                                                                      transparent=opacity < 1))
    vis[node].set_transform(T)


def assembly_view(design, path: str | os.PathLike, placements: list, brackets: list[dict] | None = None,
                  geometry_dir: str | None = None, title: str = "") -> Path:
    """Write the assembled robot's page to ``path``.

    Args:
        design: The design (right side; the left is drawn mirrored).
        path: The ``.html`` file.
        placements: One :class:`pamkin.robot.pam_body.Placement` per PAM (where each body sits).
        brackets: Attachment rows of a build sheet (``body``, ``x_mm``.., ``bracket_foot_mm``); each drawn as
            a thin grey rod from its foot to its point on both sides (None: none).
        geometry_dir: Folder of the bone meshes.
        title: Page header (HTML).
    """
    import meshcat  # noqa: PLC0415
    import meshcat.geometry as g  # noqa: PLC0415

    skel = robot_skeleton()
    robot = PamRobot(design, skel)
    n = len(design.pams)
    q0 = skel.default_q[None, :].copy()
    q0[0, skel.coordinates.index("pelvis_ty")] = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st = skel.kinematics.forward(q0, warn_range=False)
        ps = robot.evaluate(q0)
    bones = BoneSet(skel, geometry_dir)
    vis = meshcat.Visualizer(window=StaticWindow(f"pamkin build {design.name}", title))
    for node in ("/Grid", "/Axes"):
        vis[node].set_property("visible", False)
    seen = []
    for body in bones.bodies:
        b = skel.bodies.index(body)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = st.body_R[0, b], st.body_p[0, b]
        for i, m in enumerate(bones.meshes[body]):
            vis[f"pamkin/bones/{body}/{i}"].set_object(g.TriangularMeshGeometry(m.vertices, m.faces),
                                                       g.MeshLambertMaterial(color=0xE8E0D0))
            vis[f"pamkin/bones/{body}/{i}"].set_transform(T)
            if body != "torso":            # frame the legs and the pelvis (the trunk's PAMs are framed below)
                seen.append((T[:3, :3] @ m.vertices[::25].T).T + T[:3, 3])
    fit = 2 * design.fitting_length_m
    for c in range(2 * n):
        k, side = c % n, "r" if c < n else "l"
        pam = design.pams[k]
        for j, (A, B) in enumerate(p for piece in robot.route_pieces(st, c) for p in piece):
            _cylinder(vis, g, f"pamkin/cables/{side}/{pam.key}/{j}", A[0], B[0], 0.0012, 0x444444)
        pts = route_positions(robot.paths, st, c)
        seen.append(pts[0])
        pieces = pam_capsules(pts, placements[k].segment, ps.pam_lengths[:, c] + fit, placements[k].side)
        for j, (A, B, valid) in enumerate(pieces):
            if valid[0]:
                _cylinder(vis, g, f"pamkin/bodies/{side}/{pam.key}/{j}", A[0], B[0], body_radius(pam.diameter_mm, pam.n_parallel),
                          BODY_COLORS.get(pam.diameter_mm, 0x7F7F7F), opacity=0.85)
        for i, r in enumerate(robot.rollers[c]):
            b = skel.kinematics.frames.index(r.body)
            vis[f"pamkin/rollers/{side}/{pam.key}/{i}"].set_object(g.Cylinder(r.length_m, r.radius_m),
                                                                   g.MeshLambertMaterial(color=0x555555))
            vis[f"pamkin/rollers/{side}/{pam.key}/{i}"].set_transform(
                roller_transforms(r, st.body_R[:1, b], st.body_p[:1, b])[0])
    for i, a in enumerate(brackets or []):
        if "bracket_foot_mm" not in a:
            continue
        for side, zs in (("r", 1.0), ("l", -1.0)):
            body = a["body"] if side == "r" else mirror_name(a["body"])
            b = skel.bodies.index(body)
            R, p = st.body_R[0, b], st.body_p[0, b]
            m = np.array([1.0, 1.0, zs])
            foot = R @ (np.asarray(a["bracket_foot_mm"]) * m / 1000.0) + p
            point = R @ (np.array([a["x_mm"], a["y_mm"], a["z_mm"]]) * m / 1000.0) + p
            _cylinder(vis, g, f"pamkin/brackets/{side}/{i}", foot, point, 0.0015, 0x888888)
            vis[f"pamkin/points/{side}/{i}"].set_object(g.Sphere(0.003), g.MeshLambertMaterial(color=0x111111))
            vis[f"pamkin/points/{side}/{i}"].set_transform(_translation(point))
    _frame_camera(vis, np.vstack(seen), aspect=ASPECT)
    vis["/Background"].set_property("top_color", [1.0, 1.0, 1.0])
    vis["/Background"].set_property("bottom_color", [1.0, 1.0, 1.0])
    path = Path(path)
    write_file(path, vis.static_html())
    return path
