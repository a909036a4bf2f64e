"""Reports of fitted paths (:mod:`pamkin.human.path_fit`): an error table (CSV, Markdown) and a plot."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from pamkin.human.path_fit import PathFit
from pamkin.outputs import strict_json, write_figure, write_file

_COLUMNS = ("muscle", "coordinates", "order", "terms", "length_rms_mm", "length_max_mm", "moment_arm_rms_mm",
            "moment_arm_max_mm", "passed")


def table_csv(fit: PathFit) -> str:
    """The per-muscle error table as CSV (errors in millimetres)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=_COLUMNS, lineterminator="\n")
    w.writeheader()
    for row in fit.table():
        w.writerow({k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in row.items()})
    return buf.getvalue()


def table_markdown(fit: PathFit) -> str:
    """The per-muscle error table as Markdown, with the tolerance and a summary line."""
    t = fit.tolerance
    rows = fit.table()
    lines = [f"Poses uniform over {fit.ranges}. Held-out random poses: {fit.n_test}; fitting poses: "
             f"{fit.n_samples}; fit time {fit.seconds:.1f} s. "
             f"Tolerance: length RMS ≤ {1e3 * t.length_rms:g} mm, max ≤ {1e3 * t.length_max:g} mm, "
             f"moment-arm RMS ≤ {1e3 * t.moment_arm_rms:g} mm. Within it: {len(rows) - len(fit.missed)} of "
             f"{len(rows)} muscles.", "",
             "| muscle | coordinates | order | terms | length RMS [mm] | length max [mm] | moment-arm RMS [mm] "
             "| moment-arm max [mm] | within |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['muscle']} | {r['coordinates']} | {r['order']} | {r['terms']} | "
                     f"{r['length_rms_mm']:.3f} | {r['length_max_mm']:.3f} | {r['moment_arm_rms_mm']:.3f} | "
                     f"{r['moment_arm_max_mm']:.3f} | {'yes' if r['passed'] else '**no**'} |")
    return "\n".join(lines) + "\n"


def error_figure(fit: PathFit, title: str = ""):
    """Bar chart of each muscle's length and moment-arm errors (log scale) with the tolerances."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    rows = fit.table()
    x = np.arange(len(rows))
    fig, axes = plt.subplots(2, 1, figsize=(max(8.0, 0.16 * len(rows) + 2), 7), sharex=True)
    t = fit.tolerance
    for ax, keys, tols, label in (
            (axes[0], ("length_rms_mm", "length_max_mm"), (t.length_rms, t.length_max), "length error [mm]"),
            (axes[1], ("moment_arm_rms_mm", "moment_arm_max_mm"), (t.moment_arm_rms,), "moment-arm error [mm]")):
        for k, key in enumerate(keys):
            ax.bar(x + (k - 0.5) * 0.4, [max(r[key], 1e-6) for r in rows], width=0.4,
                   label=key.replace("_mm", "").replace("_", " "))
        for tol, style in zip(tols, ("--", ":")):
            ax.axhline(1e3 * tol, color="k", ls=style, lw=1, label=f"tolerance {1e3 * tol:g} mm")
        ax.set_yscale("log")
        ax.set_ylabel(label)
        ax.legend(fontsize=8, ncol=3)
        ax.grid(alpha=0.3, which="both")
    axes[1].set_xticks(x, [r["muscle"] for r in rows], rotation=90, fontsize=7)
    axes[0].set_title(title or "fitted path errors on held-out random poses")
    fig.tight_layout()
    return fig


def write_report(fit: PathFit, folder: Path, title: str = "") -> list[Path]:
    """``errors.csv``, ``errors.md``, ``errors.png`` and ``fit.json`` in ``folder``."""
    import matplotlib.pyplot as plt  # noqa: PLC0415

    folder = Path(folder)
    fig = error_figure(fit, title)
    try:
        png = write_figure(fig, folder / "errors.png", dpi=110)
    finally:
        plt.close(fig)
    summary = {"ranges": fit.ranges, "n_samples": fit.n_samples, "n_test": fit.n_test, "seconds": fit.seconds,
               "tolerance_m": {"length_rms": fit.tolerance.length_rms, "length_max": fit.tolerance.length_max,
                               "moment_arm_rms": fit.tolerance.moment_arm_rms},
               "missed": [m.name for m in fit.missed], "skipped": fit.skipped, "muscles": fit.table()}
    return [write_file(folder / "errors.csv", table_csv(fit)), write_file(folder / "errors.md", table_markdown(fit)),
            png, write_file(folder / "fit.json", strict_json(summary))]
