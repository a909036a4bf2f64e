"""Before/after figure of an optimisation run: 1-D torque curves of every actuator."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from pamkin.human.model import gait2392
from pamkin.human.rom import load_rom
from pamkin.outputs import write_file
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.robot.design import Design


def before_after_plot(seed: Design, new: Design, path: Path, n: int = 61, seed_label: str | None = None) -> Path:
    """Human, seed-design and optimised-design torque about each PAM's primary coordinate (others 0).

    ``seed_label`` names the seed's curves in the legend and title (default: the seed design's name; a warm-started
    run passes the run folder it started from)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415


    human = gait2392()
    skel = robot_skeleton()
    rb, ra = PamRobot(seed, skel, sides=("r",)), PamRobot(new, skel, sides=("r",))
    rom = load_rom(new.rom, "r")
    ids = [p.id for p in new.pams]
    label = seed_label or seed.name
    cols = 6
    rows = int(np.ceil(len(ids) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.0 * cols, 2.4 * rows), squeeze=False)
    for ax in axes.ravel()[len(ids):]:
        ax.axis("off")
    for ax, pid in zip(axes.ravel(), ids):
        k = ids.index(pid)
        pam = ra.pams[k]
        c = pam.primary_coordinate
        q, _ = human.grid([c], n, rom=rom, base={x: 0.0 for x in human.coordinates})
        ci = human.coordinates.index(c)
        idx = [human.muscles.index(m) for m in pam.human_muscles]
        x = np.degrees(q[:, ci])
        ax.plot(x, human.torques(q)[:, idx, ci].sum(1), "k-", lw=2, label="human (Gait2392)")
        ax.plot(x, rb.evaluate(q).torques[:, k, ci], "C3--", label=label)
        ax.plot(x, ra.evaluate(q).torques[:, k, ci], "C0-", label="optimised")
        title = f"{pid} {pam.name}"
        wrap = len(title) > 30
        ax.set_title(textwrap.fill(title, 30) if wrap else title, fontsize=8 if wrap else 9)
        ax.set_xlabel(f"{c} [deg]", fontsize=8)
        ax.set_ylabel("torque [N·m]", fontsize=8)
        ax.tick_params(labelsize=7)
    axes.ravel()[0].legend(fontsize=7)
    fig.suptitle(f"Torque about each PAM's primary coordinate: human vs {label} vs optimised", fontsize=12)
    fig.tight_layout()
    import io  # noqa: PLC0415

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=70)
    plt.close(fig)
    write_file(Path(path), buf.getvalue())
    return Path(path)
