"""Measure a conversion against pamkin on held-out random poses: per-path error tables and a figure.

The poses are uniform over the model's coordinate ranges (:meth:`pamkin.human.model.Model.random_q`) with a
seed other than the fit poses' (:data:`pamkin.sim.tendons.FIT_SEED`). A path is *exact* when MuJoCo's
construct is (sites only, linear joint ties): its errors are round-off; the others are approximations whose
errors the table states. Conditional points built as steps (:mod:`pamkin.sim.tendons`) are exact outside a
band around each switch, where OpenSim's length jumps: the table adds the maxima over the poses outside those
bands and the number of poses inside them.
"""

from __future__ import annotations

import io
import warnings

import numpy as np

from pamkin.errors import RangeWarning
from pamkin.sim.convert import Conversion
from pamkin.sim.geometry import GeometryErrors, MjGeometry, compare

#: Seed of the measurement poses (held out: the fit poses use :data:`pamkin.sim.tendons.FIT_SEED`).
MEASURE_SEED = 2026
#: Goals of issue 45 for Gait2392's muscles: length and moment-arm errors [m].
LENGTH_GOAL = 0.5e-3
ARM_GOAL = 1e-3


def measure(conv: Conversion, n: int = 1000, seed: int = MEASURE_SEED) -> GeometryErrors:
    """Errors of the MuJoCo model's tendon lengths and moment arms against pamkin's at ``n`` poses."""
    q = conv.model.random_q(n, seed=seed)
    geo = MjGeometry(conv.compile(), conv.cmap, conv.paths)
    L, R = geo.evaluate(q)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        Lr, Rr = conv.reference(q)
    return compare(conv.paths, L, R, Lr, Rr, outside=~band_poses(conv, q))


def band_poses(conv: Conversion, q: np.ndarray) -> np.ndarray:
    """(N, n_paths) True where pose q[n] lies within half a band of a switch of one of the path's conditional
    steps (where OpenSim's length jumps and MuJoCo's passes continuously)."""
    out = np.zeros((len(q), len(conv.paths)), bool)
    for k, ch in enumerate(conv.choices):
        for st in ch.steps.values():
            c = conv.cmap.coordinates.index(st["coordinate"])
            for s in st["switches"]:
                out[:, k] |= np.abs(q[:, c] - s) <= st["band"] / 2
    return out


def exact_constructs(conv: Conversion) -> np.ndarray:
    """(n_paths,) True where MuJoCo's construct of the path is exact: sites only (no conditional or moving
    point, no wrap) and every joint tie of the coordinates it spans linear (so its errors are round-off)."""
    q = conv.model.random_q(8, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        _, R = conv.reference(q)
    spanned = np.any(np.abs(R) > 0, axis=0)                  # (paths, coordinates)
    inexact = {j.coordinate for j in conv.cmap.joints if not j.primary and j.error > 1e-12
               and j.body in {b.name for b in conv.cmap.bodies}}
    bad = np.array([c in inexact for c in conv.cmap.coordinates])
    out = []
    for k, name in enumerate(conv.paths):
        ch = conv.choices[k]
        out.append(not ch.conditional and not ch.wraps and not ch.omitted and construct(conv, name) == "sites"
                   and not np.any(spanned[k] & bad))
    return np.array(out, dtype=bool)


def errors_csv(errors: GeometryErrors, conv: Conversion) -> str:
    """CSV: path, length max/p99 [mm], moment-arm max/p99 [mm], the maxima outside the conditional steps' bands
    [mm] and the poses inside them, exact, construct."""
    out = io.StringIO()
    out.write("path,length_max_mm,length_p99_mm,arm_max_mm,arm_p99_mm,length_max_outside_bands_mm,"
              "arm_max_outside_bands_mm,band_poses,exact_construct,construct\n")
    exact = exact_constructs(conv)
    for k, (row, ch, ex) in enumerate(zip(errors.rows(), conv.choices, exact)):
        out.write(f"{row['path']},{row['length_max_m'] * 1e3:.6g},{row['length_p99_m'] * 1e3:.6g},"
                  f"{row['arm_max_m'] * 1e3:.6g},{row['arm_p99_m'] * 1e3:.6g},"
                  f"{errors.length_max_out[k] * 1e3:.6g},{errors.arm_max_out[k] * 1e3:.6g},"
                  f"{int(errors.band_poses[k])},{int(ex)},{construct(conv, ch.name)}\n")
    return out.getvalue()


def construct(conv: Conversion, path: str) -> str:
    """What stands for the path's inexact parts (``sites`` when nothing does), ``;``-separated."""
    ch = conv.choices[conv.paths.index(path)]
    parts = []
    for point, how in ch.conditional.items():
        parts.append(f"conditional {point}: " + ("always" if how is True else "never" if how is False else how))
    moving = {j.name.rsplit("-", 1)[0] for j in conv.cmap.joints if not j.primary and not j.aux
              and j.name.startswith(f"{path}-") and "-step" not in j.name}
    how = "composed" if conv.cmap.couplings == "composed" else "polynomial"
    parts += [f"moving point {m.split('-', 2)[-1]}: {how}" for m in sorted(moving)]
    parts += [f"wrap {g}" for g in ch.wraps if g not in str(ch.conditional)]
    parts += [f"left out {w}" for w in ch.omitted]
    if not parts:
        q = conv.model.random_q(8, seed=1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            R = conv.reference(q)[1][:, conv.paths.index(path)]
        spans = {conv.cmap.coordinates[c] for c in np.nonzero(np.any(np.abs(R) > 0, axis=0))[0]}
        tied = sorted({j.name for j in conv.cmap.joints if not j.primary and j.error > 1e-12
                       and j.coordinate in spans and "-" not in j.name})
        parts += [f"joint {'composed' if conv.cmap.joints[conv.cmap.joint_index(t)].terms else 'polynomial'} {t}"
                  for t in tied]
    return "; ".join(parts) if parts else "sites"


def summary(errors: GeometryErrors, exact: np.ndarray) -> dict:
    """Counts and worst values of an error table (``exact``: :func:`exact_constructs`)."""
    return {"paths": len(errors.names), "exact": int(exact.sum()),
            "length_within_goal": int((errors.length_max <= LENGTH_GOAL).sum()),
            "arm_within_goal": int((errors.arm_max <= ARM_GOAL).sum()),
            "arm_p99_within_goal": int((errors.arm_p99 <= ARM_GOAL).sum()),
            "exact_length_max_m": float(errors.length_max[exact].max()) if exact.any() else 0.0,
            "exact_arm_max_m": float(errors.arm_max[exact].max()) if exact.any() else 0.0,
            "length_max_m": float(errors.length_max.max(initial=0.0)),
            "arm_max_m": float(errors.arm_max.max(initial=0.0)),
            "length_within_goal_outside_bands": int((errors.length_max_out <= LENGTH_GOAL).sum()),
            "arm_within_goal_outside_bands": int((errors.arm_max_out <= ARM_GOAL).sum()),
            "band_poses": int(errors.band_poses.sum())}


def error_figure(errors: GeometryErrors, title: str):
    """Bar chart per path (sorted): largest and p99 length and moment-arm errors [mm], log scale, goals drawn."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    order = np.argsort(-errors.length_max)
    x = np.arange(len(order))
    fig, axes = plt.subplots(2, 1, figsize=(max(8.0, 0.12 * len(order) + 2), 7), sharex=True)
    floor = 1e-12
    banded = errors.band_poses[order] > 0
    for ax, (mx, p99, out, goal, what) in zip(axes, (
            (errors.length_max, errors.length_p99, errors.length_max_out, LENGTH_GOAL, "length"),
            (errors.arm_max, errors.arm_p99, errors.arm_max_out, ARM_GOAL, "moment arm"))):
        ax.bar(x, np.maximum(mx[order], floor) * 1e3, color="tab:orange", label="max")
        ax.bar(x, np.maximum(p99[order], floor) * 1e3, color="tab:blue", width=0.5, label="p99")
        if banded.any():
            ax.plot(x[banded], np.maximum(out[order][banded], floor) * 1e3, "k_", ms=9, mew=2,
                    label="max outside the steps' bands")
        ax.axhline(goal * 1e3, color="k", ls="--", lw=1, label=f"goal {goal * 1e3:g} mm")
        ax.set_yscale("log")
        ax.set_ylabel(f"{what} error [mm]")
        ax.grid(True, which="major", axis="y", alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[1].set_xticks(x)
    axes[1].set_xticklabels([errors.names[i] for i in order], rotation=90, fontsize=6)
    axes[0].set_title(title)
    fig.tight_layout()
    return fig
