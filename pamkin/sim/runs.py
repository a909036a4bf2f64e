"""A simulation's run folder: time series (CSV, NPZ), summary, plots and a meshcat animation page.

Files (written whole or not at all, :func:`pamkin.outputs.output_folder`): ``timeseries.csv`` (time, every
coordinate simulated and reference [deg or m], pressures [kPa], harness force [N], pelvis position [m]),
``timeseries.npz`` (the same arrays in SI units, with the PAM and coordinate names), ``summary.json``,
``tracking.png`` (hip, knee and ankle angles against the reference, harness load or pelvis height),
``pressures.png`` (every PAM's pressure over time) and ``animation.html`` (the motion with the bones,
self-contained meshcat page).
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from pamkin.outputs import output_folder, strict_json, write_figure, write_file
from pamkin.sim.convert import Conversion
from pamkin.sim.simulate import ANIMATION_FPS, TRACKED, SimResult
from pamkin.viz.meshcat_view import StaticWindow


def timeseries_csv(res: SimResult) -> str:
    """CSV of the time series (angles in degrees, translations in metres, pressures in kPa)."""
    rot = [not c.startswith("pelvis_t") for c in res.coordinates]
    cols = ["t_s"]
    data = [res.times[:, None]]
    for tag, Q in (("", res.q), ("ref_", res.q_ref)):
        cols += [f"{tag}{c}_{'deg' if r else 'm'}" for c, r in zip(res.coordinates, rot)]
        data.append(np.where(rot, np.degrees(Q), Q))
    cols += [f"p_{n}_kPa" for n in res.pam_names] + ["harness_x_N", "harness_y_N", "harness_z_N",
                                                      "pelvis_x_m", "pelvis_y_m", "pelvis_z_m"]
    data += [res.pressures / 1e3, res.harness, res.pelvis]
    out = io.StringIO()
    np.savetxt(out, np.hstack(data), delimiter=",", header=",".join(cols), comments="", fmt="%.6g")
    return out.getvalue()


def tracking_figure(res: SimResult, weight_N: float | None = None):
    """Hip flexion, knee and ankle angles (both sides) against the reference; harness load or pelvis height."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    for ax, joint in zip(axes[:3], ("hip_flexion", "knee_angle", "ankle_angle")):
        for side, color in (("r", "tab:blue"), ("l", "tab:red")):
            c = f"{joint}_{side}"
            if c not in res.coordinates:
                continue
            i = res.coordinates.index(c)
            rms = np.degrees(np.sqrt(np.mean((res.q[:, i] - res.q_ref[:, i]) ** 2)))
            ax.plot(res.times, np.degrees(res.q[:, i]), color=color, label=f"{c} simulated (RMS {rms:.1f}°)")
            ax.plot(res.times, np.degrees(res.q_ref[:, i]), "--", color=color, lw=1, label=f"{c} reference")
        ax.set_ylabel(f"{joint} [deg]")
        ax.legend(fontsize=7, loc="best")
        ax.grid(alpha=0.3)
    if res.kind == "harness_walk" and weight_N:
        axes[3].plot(res.times, res.harness[:, 1] / weight_N, color="k")
        axes[3].axhline(0.2, color="tab:green", ls="--", lw=1, label="goal: mean ≤ 0.2")
        axes[3].set_ylabel("harness vertical load / weight")
        axes[3].legend(fontsize=7)
    else:
        axes[3].plot(res.times, res.pelvis[:, 1], color="k")
        axes[3].set_ylabel("pelvis height [m]")
    axes[3].set_xlabel("time [s]")
    axes[3].grid(alpha=0.3)
    axes[0].set_title(f"{res.kind}: simulated (solid) vs reference (dashed)")
    fig.tight_layout()
    return fig


def pressures_figure(res: SimResult):
    """Every PAM's pressure [kPa] over time (image: PAMs by row)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, ax = plt.subplots(figsize=(10, 8))
    im = ax.imshow(res.pressures.T / 1e3, aspect="auto", origin="lower", cmap="viridis", vmin=0, vmax=620,
                   extent=(res.times[0], res.times[-1], -0.5, len(res.pam_names) - 0.5), interpolation="nearest")
    ax.set_yticks(range(len(res.pam_names)))
    ax.set_yticklabels(res.pam_names, fontsize=5)
    ax.set_xlabel("time [s]")
    ax.set_title(f"{res.kind}: PAM pressures (first-order lag behind the commands)")
    fig.colorbar(im, ax=ax, label="pressure [kPa]")
    fig.tight_layout()
    return fig


def animation_page(conv: Conversion, res: SimResult, title: str) -> str:
    """A self-contained meshcat page playing the recorded body placements (bones from the conversion's
    meshes; OpenSim's Y-up turned to meshcat's Z-up)."""
    import meshcat  # noqa: PLC0415
    import meshcat.geometry as g  # noqa: PLC0415
    import trimesh  # noqa: PLC0415
    from meshcat.animation import Animation  # noqa: PLC0415

    vis = meshcat.Visualizer(window=StaticWindow(title, f"<b>{title}</b>"))
    up = np.eye(4)
    up[1:3, 1:3] = [[0.0, -1.0], [1.0, 0.0]]
    vis["sim"].set_transform(up)
    anim = Animation(default_framerate=ANIMATION_FPS)
    for body, items in conv.spec.meshes.items():
        poses = res.body_poses.get(body)
        if poses is None or not len(poses):
            continue
        for k, (_, rel, R, p, scale) in enumerate(items):
            m = trimesh.load(io.BytesIO(conv.meshes[rel]), file_type="stl")
            v = np.asarray(m.vertices) * np.asarray(scale)
            node = vis[f"sim/{body}/mesh{k}"]
            node.set_object(g.TriangularMeshGeometry(v, np.asarray(m.faces)),
                            g.MeshLambertMaterial(color=0xE3D9C9))
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, p
            node.set_transform(T)
        vis[f"sim/{body}"].set_transform(poses[0])
        for f in range(len(poses)):
            with anim.at_frame(vis, f) as frame:
                frame[f"sim/{body}"].set_transform(poses[f])
    vis.set_animation(anim, play=True, repetitions=0)
    return vis.static_html()


def write_run(conv: Conversion, res: SimResult, folder: str | os.PathLike, force: bool = False,
              weight_N: float | None = None) -> Path:
    """Write the run folder (module docstring)."""
    with output_folder(folder, force) as tmp:
        write_file(tmp / "timeseries.csv", timeseries_csv(res))
        buf = io.BytesIO()
        np.savez_compressed(buf, t=res.times, q=res.q, q_ref=res.q_ref, pressures=res.pressures,
                            commands=res.commands, tensions=res.tensions, harness=res.harness, pelvis=res.pelvis,
                            coordinates=np.array(res.coordinates), pams=np.array(res.pam_names))
        write_file(tmp / "timeseries.npz", buf.getvalue())
        write_file(tmp / "summary.json", strict_json({"kind": res.kind, "tracked_coordinates": list(TRACKED),
                                                      **res.summary}))
        write_figure(tracking_figure(res, weight_N), tmp / "tracking.png", dpi=90)
        write_figure(pressures_figure(res), tmp / "pressures.png", dpi=90)
        write_file(tmp / "animation.html", animation_page(conv, res, f"pamkin simulate: {conv.name}, {res.kind}"))
    return Path(folder)
