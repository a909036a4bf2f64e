"""Torque-surface report: every PAM's torque against the human muscles it replaces, as figures.

For each PAM of one side (27 in the thesis design) the report draws, like the thesis's
Figs. 8–18:

* ``pamNN_surfaces.png``: torque surfaces over a grid of the PAM's primary coordinate × a
  partner coordinate (its first secondary coordinate, else :data:`DEFAULT_PARTNER`), in the
  design's range of motion with every other coordinate 0; row 1 the torque about the primary
  coordinate, row 2 about the partner; columns human (sum of its Gait2392 muscles, full
  activation), robot (the PAM), robot − human. Human and robot share one colour scale per row.
  Hatching marks dead zones: samples where the PAM's strain is outside Festo's range
  (``PamState.in_range`` False).
* ``pamNN_curve.png``: the 1-D torque curves about the primary coordinate (others 0), dead
  zones shaded, with the PAM's strain on a second axis.
* ``index.html`` linking every figure, with the 1-D and 2-D NRMSE and dead-zone fractions of
  :func:`pamkin.audit.compare.torque_match`.

Angles are shown in degrees (computed in radians); torques in N·m.
"""

from __future__ import annotations

import html as _html
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pamkin.audit.compare import TorqueMatch, torque_match
from pamkin.errors import ConfigurationError
from pamkin.human.rom import load_rom
from pamkin.outputs import write_figure, write_file

__all__ = [
    "CURVE_PX",
    "DEFAULT_PARTNER",
    "SURFACE_PX",
    "PamFigures",
    "Report",
    "partner_coordinate",
    "torque_report",
]

#: Second grid coordinate of a PAM without secondary coordinates, by primary (side-less names).
DEFAULT_PARTNER = {
    "knee_angle": "hip_flexion", "ankle_angle": "knee_angle", "hip_flexion": "hip_adduction",
    "hip_adduction": "hip_flexion", "hip_rotation": "hip_flexion", "subtalar_angle": "ankle_angle",
    "mtp_angle": "ankle_angle", "lumbar_extension": "lumbar_bending", "lumbar_bending": "lumbar_extension",
    "lumbar_rotation": "lumbar_extension",
}
#: Pixel sizes (width, height) of the figures.
SURFACE_PX = (1500, 840)
CURVE_PX = (900, 500)
_DPI = 100


@dataclass(frozen=True)
class PamFigures:
    """The figures and numbers of one PAM.

    Attributes:
        id: Actuator number.
        key: ``pamNN``.
        name: PAM name.
        side: ``r`` or ``l``.
        human_muscles: The Gait2392 muscles it replaces.
        diameter_mm: Festo diameter.
        primary: Primary coordinate.
        partner: Second grid coordinate.
        surfaces: ``pamNN_surfaces.png``.
        curve: ``pamNN_curve.png``.
        primary_match: 1-D comparison about the primary coordinate.
        grid_matches: 2-D comparisons about the primary and the partner coordinate.
    """

    id: int
    key: str
    name: str
    side: str
    human_muscles: tuple[str, ...]
    diameter_mm: int
    primary: str
    partner: str
    surfaces: Path
    curve: Path
    primary_match: TorqueMatch
    grid_matches: tuple[TorqueMatch, ...] = field(default=())


@dataclass(frozen=True)
class Report:
    """A written report: its folder, index page and per-PAM figures."""

    folder: Path
    index: Path
    pams: tuple[PamFigures, ...]

    @property
    def files(self) -> list[Path]:
        """Every figure file."""
        return [f for p in self.pams for f in (p.surfaces, p.curve)]


def _base(coordinate: str) -> tuple[str, str]:
    for s in ("_r", "_l"):
        if coordinate.endswith(s):
            return coordinate[:-2], s
    return coordinate, ""


def partner_coordinate(robot, k: int) -> str:
    """The second grid coordinate of PAM column ``k``: its first secondary coordinate, else
    :data:`DEFAULT_PARTNER` of its primary."""
    pam = robot.pams[k]
    if pam.secondary_coordinates:
        return robot.side_coordinate(k, pam.secondary_coordinates[0])
    base, suffix = _base(robot.side_coordinate(k, pam.primary_coordinate))
    if base not in DEFAULT_PARTNER:
        raise ConfigurationError(f"{pam.key}: no secondary coordinate and no default partner for {base!r}; "
                                 "give one with partner=")
    partner = DEFAULT_PARTNER[base]
    return partner if partner.startswith("lumbar") else partner + (suffix or "_r")


def torque_report(robot, human, out_dir: str | os.PathLike, *, side: str = "r", n: int = 25, n1: int = 101,
                  pams: list[int] | None = None, partner: str | None = None, progress=None) -> Report:
    """Write the torque-surface report of ``robot`` against ``human`` into ``out_dir``.

    Args:
        robot: A :class:`pamkin.robot.biped.PamRobot`.
        human: The human :class:`pamkin.Model` (Gait2392).
        out_dir: Output folder (created).
        side: ``r`` or ``l``.
        n: Grid points per coordinate of the surfaces.
        n1: Samples of the 1-D curves.
        pams: Actuator ids to draw (default: all).
        partner: Second grid coordinate for every PAM (default: :func:`partner_coordinate`).
        progress: Called as ``progress(done, total, pam_key, pam_name)`` after each PAM's figures.

    Raises:
        pamkin.errors.ConfigurationError: Unknown coordinates or PAM ids, or a partner equal to a
            PAM's primary coordinate.
    """

    if side not in ("r", "l"):
        raise ConfigurationError(f"side must be 'r' or 'l', not {side!r}")
    if n < 2 or n1 < 2:
        raise ConfigurationError("grids need at least 2 points per coordinate")
    cols = [k for k in range(len(robot.pams)) if robot.sides[k] == side]
    if pams is not None:
        unknown = sorted(set(pams) - {robot.pams[k].id for k in cols})
        if unknown:
            raise ConfigurationError(f"unknown PAM id(s) {unknown}; design {robot.design.name!r} has "
                                     f"{sorted(robot.pams[k].id for k in cols)}")
        cols = [k for k in cols if robot.pams[k].id in pams]
    if partner is not None and partner not in human.coordinates:
        raise ConfigurationError(f"unknown coordinate {partner!r}; valid: {human.coordinates}")
    rom = load_rom(robot.design.rom, side)
    zero = {c: 0.0 for c in human.coordinates}
    folder = Path(out_dir)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k in cols:
        pam = robot.pams[k]
        prim = robot.side_coordinate(k, pam.primary_coordinate)
        second = partner or partner_coordinate(robot, k)
        if second == prim:
            raise ConfigurationError(f"{pam.key}: the partner coordinate {second!r} is its primary coordinate")
        q2, shape = human.grid([prim, second], n, rom=rom, base=zero)
        q1, _ = human.grid([prim], n1, rom=rom, base=zero)
        idx = [human.muscles.index(m) for m in robot.human_muscles(k)]
        ci, cj = human.coordinates.index(prim), human.coordinates.index(second)
        T2 = human.torques(q2)[:, idx][:, :, [ci, cj]].sum(axis=1)     # (N, 2)
        T1 = human.torques(q1)[:, idx, ci].sum(axis=1)
        r2, r1 = robot.evaluate(q2), robot.evaluate(q1)
        R2 = r2.torques[:, k][:, [ci, cj]]
        R1 = r1.torques[:, k, ci]
        m1 = torque_match(T1, R1, r1.in_range[:, k], prim, f"1-D {prim}")
        m2 = tuple(torque_match(T2[:, j], R2[:, j], r2.in_range[:, k], c, f"2-D {prim} x {second}")
                   for j, c in enumerate((prim, second)))
        title = f"{pam.key} {pam.name} ({side}), {pam.diameter_mm} mm; human: {', '.join(robot.human_muscles(k))}"
        surfaces = folder / f"{pam.key}_surfaces.png"
        curve = folder / f"{pam.key}_curve.png"
        X = np.degrees(q2[:, ci]).reshape(shape)
        Y = np.degrees(q2[:, cj]).reshape(shape)
        _surface_figure(surfaces, title, prim, second, X, Y, T2.reshape(*shape, 2), R2.reshape(*shape, 2),
                        ~r2.in_range[:, k].reshape(shape))
        _curve_figure(curve, title, prim, np.degrees(q1[:, ci]), T1, R1, r1.strain[:, k], ~r1.in_range[:, k])
        out.append(PamFigures(pam.id, pam.key, pam.name, side, robot.human_muscles(k), pam.diameter_mm, prim, second,
                              surfaces, curve, m1, m2))
        if progress is not None:
            progress(len(out), len(cols), pam.key, pam.name)
    index = folder / "index.html"
    _write_index(index, robot, rom.name, n, n1, out)
    return Report(folder, index, tuple(out))


# ----------------------------------------------------------------------------- figures
def _symmetric(*arrays: np.ndarray) -> float:
    v = max(float(np.max(np.abs(a))) for a in arrays)
    return v if v > 1e-9 else 1.0


def _save(fig, path: Path) -> None:
    write_figure(fig, path, dpi=_DPI)


def _surface_figure(path: Path, title: str, prim: str, second: str, X, Y, H, R, dead) -> None:
    from matplotlib.figure import Figure  # noqa: PLC0415
    from matplotlib.patches import Patch  # noqa: PLC0415
    from matplotlib.ticker import MaxNLocator  # noqa: PLC0415

    fig = Figure(figsize=(SURFACE_PX[0] / _DPI, SURFACE_PX[1] / _DPI))
    axes = fig.subplots(2, 3,   # same data limits everywhere; no axis sharing (slow to draw)
                        gridspec_kw={"left": 0.05, "right": 0.96, "bottom": 0.08, "top": 0.86, "wspace": 0.2,
                                     "hspace": 0.2})
    for row, about in enumerate((prim, second)):
        h, r = H[..., row], R[..., row]
        vmax, dmax = _symmetric(h, r), _symmetric(r - h)
        drawn = []
        panels = ((h, "human", vmax), (r, "robot", vmax), (r - h, "robot − human", dmax))
        for col, (z, label, lim) in enumerate(panels):
            ax = axes[row, col]
            ax.set_title(f"{label}: torque about {about}", fontsize=10)
            if row == 1:
                ax.set_xlabel(f"{prim} [deg]")
            if col == 0:
                ax.set_ylabel(f"{second} [deg]")
            if not np.any(np.abs(z) > 1e-9):
                ax.set_facecolor("0.95")
                ax.text(0.5, 0.5, f"zero everywhere:\n{'neither spans' if col == 2 else 'does not span'} {about}"
                        if np.allclose(h, 0) and np.allclose(r, 0) else "zero everywhere",
                        transform=ax.transAxes, ha="center", va="center", fontsize=10, color="0.3")
                drawn.append(None)
                continue
            levels = MaxNLocator(nbins=20, symmetric=True).tick_values(-lim, lim)
            drawn.append(ax.contourf(X, Y, z, levels=levels, cmap="RdBu_r", extend="both"))
            ax.contour(X, Y, z, levels=[0.0], colors="k", linewidths=0.6)
            if col > 0 and dead.any():
                ax.contourf(X, Y, dead.astype(float), levels=[0.5, 1.5], colors="none", hatches=["///"])
        # one colour bar for human and robot (same scale), one for the difference
        if drawn[0] is not None or drawn[1] is not None:
            cb = fig.colorbar(drawn[1] or drawn[0], ax=list(axes[row, :2]), fraction=0.04, pad=0.02)
            cb.set_label("torque [N·m]")
        if drawn[2] is not None:
            cb = fig.colorbar(drawn[2], ax=axes[row, 2], fraction=0.08, pad=0.03)
            cb.set_label("difference [N·m]")
    for ax in axes.flat:
        ax.set_xlim(X.min(), X.max())
        ax.set_ylim(Y.min(), Y.max())
        ax.label_outer()
    fig.suptitle(f"{title}\nrows: torque about {prim} / {second}; other coordinates 0; black line: zero torque",
                 fontsize=11)
    if dead.any():
        fig.legend(handles=[Patch(facecolor="none", hatch="///", label="dead zone (PAM strain outside Festo's range)")],
                   loc="upper right", fontsize=9)
    _save(fig, path)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges [a, b] of the True runs of a 1-D mask."""
    runs, start = [], None
    for i, v in enumerate(mask):
        if v and start is None:
            start = i
        if not v and start is not None:
            runs.append((start, i - 1))
            start = None
    if start is not None:
        runs.append((start, len(mask) - 1))
    return runs


def _curve_figure(path: Path, title: str, prim: str, x, human, robot, strain, dead) -> None:
    from matplotlib.figure import Figure  # noqa: PLC0415

    fig = Figure(figsize=(CURVE_PX[0] / _DPI, CURVE_PX[1] / _DPI))
    ax = fig.subplots(gridspec_kw={"left": 0.09, "right": 0.9, "bottom": 0.11, "top": 0.88})
    dx = 0.5 * (x[1] - x[0]) if len(x) > 1 else 0.5
    for i, (a, b) in enumerate(_runs(dead)):
        ax.axvspan(x[a] - dx, x[b] + dx, color="0.85",
                   label="dead zone (strain outside Festo's range)" if i == 0 else None)
    ax.plot(x, human, color="C0", lw=2, label="human (sum of its muscles)")
    ax.plot(x, robot, color="C3", lw=2, label="robot PAM")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel(f"{prim} [deg]")
    ax.set_ylabel(f"torque about {prim} [N·m]")
    ax.set_xlim(x[0], x[-1])
    ax2 = ax.twinx()
    ax2.plot(x, strain, color="0.4", ls="--", lw=1, label="PAM strain (right axis)")
    ax2.set_ylabel("PAM strain (rest − length)/rest [-]")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="best")
    ax.set_title(f"{title}\n1-D sweep of {prim}, other coordinates 0", fontsize=10)
    _save(fig, path)


def _num(x: float) -> str:
    return "–" if not np.isfinite(x) else f"{x:.2f}"


def _write_index(path: Path, robot, rom: str, n: int, n1: int, pams: list[PamFigures]) -> None:
    e = _html.escape
    rows = []
    for p in pams:
        g = " / ".join(_num(m.nrmse) for m in p.grid_matches)
        dz = f"{p.primary_match.dead_zone_fraction:.2f} / {p.grid_matches[0].dead_zone_fraction:.2f}"
        rows.append(
            f"<tr><td>{p.id}</td><td>{e(p.name)}</td><td>{e(', '.join(p.human_muscles))}</td><td>{p.diameter_mm}</td>"
            f"<td>{e(p.primary)} × {e(p.partner)}</td><td>{_num(p.primary_match.nrmse)}</td><td>{g}</td>"
            f"<td>{dz}</td>"
            + "".join(f'<td><a href="{e(f.name)}"><img src="{e(f.name)}" height="90" alt="{e(p.key)} {kind}"></a></td>'
                      for f, kind in ((p.surfaces, "surfaces"), (p.curve, "curve")))
            + "</tr>")
    page = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>pamkin torque report: {e(robot.design.name)}</title>
<style>body {{ font-family: sans-serif; margin: 1em; }} table {{ border-collapse: collapse; }}
td, th {{ border: 1px solid #ccc; padding: 3px 6px; font-size: 13px; }} th {{ background: #eee; }}</style></head>
<body>
<h1>Robot vs human torques: design {e(robot.design.name)}</h1>
<p>Each PAM's torque against the summed torque of the Gait2392 muscles it replaces (full activation, static
equilibrium), over range of motion {e(rom)} with every other coordinate 0: surfaces on a {n} × {n} grid of the
primary × partner coordinate (torque about each), and a 1-D sweep of the primary coordinate ({n1} samples).
NRMSE = RMS(robot − human) / human peak (– where the human torque is zero). Dead zone: the PAM's strain is
outside Festo's range (hatched / grey).
Angles in degrees, torques in N·m.</p>
<table>
<tr><th>id</th><th>PAM</th><th>human muscles</th><th>d [mm]</th><th>grid</th><th>NRMSE 1-D</th>
<th>NRMSE 2-D (primary / partner)</th><th>dead-zone fraction 1-D / 2-D</th><th>surfaces</th><th>curve</th></tr>
{chr(10).join(rows)}
</table>
</body></html>
"""
    write_file(path, page)
