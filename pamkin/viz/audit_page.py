"""The audit's meshcat page: the design's robot at its default pose with the offending attachment points
and route segments of a :class:`pamkin.audit.measure.AuditResult` highlighted."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from pamkin.human.bones import BoneSet
from pamkin.outputs import write_file
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.robot.festo import outer_diameter
from pamkin.robot.pam_body import pam_capsules, route_positions
from pamkin.viz.meshcat_view import (
    StaticWindow,
    _frame_camera,
    _translation,
    roller_transforms,
)


def audit_view(res, path: str | os.PathLike, geometry_dir: str | None = None) -> Path:
    """A meshcat page of the design at the default pose on the bone meshes: route segments deeper
    than the threshold into bone in red (others green), attachment points inside bone or farther
    than the bracket threshold from their bone as red spheres (others blue), and each PAM body (its
    assumed outer diameter, where the audit puts it on its route) translucent: orange where it
    intersects another PAM's body at some audited pose, grey otherwise."""
    import meshcat  # noqa: PLC0415
    import meshcat.geometry as g  # noqa: PLC0415


    thr = res.thresholds
    des = res.details["design"]
    skel = robot_skeleton()
    robot = PamRobot(des, skel, sides=("r",))
    q0 = skel.default_q[None, :].copy()
    q0[0, skel.coordinates.index("pelvis_ty")] = 0.0
    st = skel.kinematics.forward(q0, warn_range=False)
    bones = BoneSet(skel, geometry_dir or res.samples.get("geometry_dir"))
    bad_pts = sum(r["points_inside_own_bone"] + r["points_over_bracket"] for r in res.pams)
    bad_seg = res.summary["segments_over_2mm"]
    crowded = sum(1 for r in res.pams if r["intersects"])
    header = (f"<b>pamkin audit: {res.design}</b> &nbsp; red segments: deeper than "
              f"{1000 * thr['segment_penetration_max_m']:.0f} mm into bone at some pose ({bad_seg}); red points: inside "
              f"their bone or farther than {1000 * thr['bracket_max_m']:.0f} mm from it ({bad_pts}); orange PAM "
              f"bodies: intersect another PAM's at some pose ({crowded}); default pose")
    vis = meshcat.Visualizer(window=StaticWindow(f"pamkin audit {res.design}", header))
    vis["/Grid"].set_property("visible", False)
    vis["/Axes"].set_property("visible", False)
    allpts = []
    for body in bones.bodies:
        if body.endswith("_l"):
            continue
        b = skel.bodies.index(body)
        T = np.eye(4)
        T[:3, :3] = st.body_R[0, b]
        T[:3, 3] = st.body_p[0, b]
        for i, m in enumerate(bones.meshes[body]):
            vis[f"pamkin/bones/{body}/{i}"].set_object(
                g.TriangularMeshGeometry(m.vertices, m.faces),
                g.MeshLambertMaterial(color=0xE8E0D0, opacity=0.55, transparent=True))
            vis[f"pamkin/bones/{body}/{i}"].set_transform(T)
            allpts.append((T[:3, :3] @ m.vertices[::20].T).T + T[:3, 3])
    X, _ = robot.paths.point_positions(st)
    for k, (pam, row) in enumerate(zip(des.pams, res.pams)):
        a = robot.paths._path_start[k]
        pieces = robot.route_pieces(st, k)          # over a roller: the pieces before and after it
        for j, seg in enumerate(row["segments"]):
            bad = seg["penetration_m"] > thr["segment_penetration_max_m"]
            for i, (PA, PB) in enumerate(pieces[j]):
                A, B = PA[0], PB[0]
                L = float(np.linalg.norm(B - A))
                if L < 1e-9:
                    continue
                y = (B - A) / L
                x = np.cross(y, [0.0, 0.0, 1.0]) if abs(y[2]) < 0.9 else np.cross(y, [1.0, 0.0, 0.0])
                x /= np.linalg.norm(x)
                T = np.eye(4)
                T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, np.cross(x, y), 0.5 * (A + B)
                node = f"pamkin/pams/{pam.key}/s{j}" + (f"_{i}" if i else "")
                vis[node].set_object(g.Cylinder(L, 0.004 if bad else 0.0025),
                                     g.MeshLambertMaterial(color=0xD62728 if bad else 0x2CA02C))
                vis[node].set_transform(T)
        for r, info in zip(robot.rollers[k], row.get("rollers", [])):   # rollers: red where bad, as points
            own = info["own_bone_distance_m"]
            bad = own < 0 or own > thr["bracket_max_m"]
            b = skel.kinematics.frames.index(r.body)
            T = roller_transforms(r, st.body_R[:1, b], st.body_p[:1, b])[0]
            node = f"pamkin/points/{pam.key}/roller_{r.segment.replace('->', '_')}"
            vis[node].set_object(g.Cylinder(r.length_m, r.radius_m),
                                 g.MeshLambertMaterial(color=0xD62728 if bad else 0x1F77B4))
            vis[node].set_transform(T)
        for i, p in enumerate(row["points"]):
            own = p["own_bone_distance_m"]
            bad = own is not None and (own < 0 or own > thr["bracket_max_m"])
            node = f"pamkin/points/{pam.key}/p{i}"
            vis[node].set_object(g.Sphere(0.008 if bad else 0.005),
                                 g.MeshLambertMaterial(color=0xD62728 if bad else 0x1F77B4))
            vis[node].set_transform(_translation(X[0, a + i]))
            allpts.append(X[0, a + i][None])
    # PAM bodies at the default pose, where the audit puts them (mount segment and end over its poses)

    mounts = res.details.get("mounts") or []
    ps = robot.evaluate(q0)
    for k, (pam, row) in enumerate(zip(des.pams, res.pams)):
        if k >= len(mounts):
            break
        pts = route_positions(robot.paths, st, k)
        length = ps.pam_lengths[:, k] + 2 * des.fitting_length_m
        color = 0xFF7F0E if row["intersects"] else 0x7F7F7F
        for j, (A, B, valid) in enumerate(pam_capsules(pts, mounts[k].segment, length, mounts[k].side)):
            L = float(np.linalg.norm(B[0] - A[0]))
            if not valid[0] or L < 1e-9:
                continue
            y = (B[0] - A[0]) / L
            x = np.cross(y, [0.0, 0.0, 1.0]) if abs(y[2]) < 0.9 else np.cross(y, [1.0, 0.0, 0.0])
            x /= np.linalg.norm(x)
            T = np.eye(4)
            T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, np.cross(x, y), 0.5 * (A[0] + B[0])
            node = f"pamkin/bodies/{pam.key}/s{j}"
            vis[node].set_object(g.Cylinder(L, outer_diameter(pam.diameter_mm) / 2),
                                 g.MeshLambertMaterial(color=color, opacity=0.35, transparent=True))
            vis[node].set_transform(T)
    _frame_camera(vis, np.vstack(allpts))
    path = Path(path)
    write_file(path, vis.static_html())
    return path
