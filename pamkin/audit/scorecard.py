"""Outputs of ``pamkin audit``: the scorecard text, the criteria figure and a meshcat page that
highlights offending attachment points and route segments."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
from pamkin.outputs import write_figure


def _fmt(v, nd: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return f"{v:.{nd}g}"


def _limit_text(lim: dict | None) -> str:
    if not lim:
        return "(off)"
    parts = []
    if "min" in lim:
        parts.append(f">= {_fmt(lim['min'])}")
    if "max" in lim:
        parts.append(f"<= {_fmt(lim['max'])}")
    return " and ".join(parts)


def _one_segment(row: dict) -> str:
    """``yes/o`` or ``yes/i`` (the end of its segment the PAM sits at), or ``no``."""
    if not row["on_one_segment"]:
        return "no"
    return "yes/" + {"origin": "o", "insertion": "i"}.get(row.get("pam_at") or "", "?")


def scorecard_text(res) -> str:
    """The human-readable scorecard: one row per PAM and one line per criterion (PASS/FAIL)."""
    thr = res.thresholds
    s = res.samples
    lines = [f"pamkin audit of design {res.design!r} ({res.source})",
             f"held-out samples: {s['random_poses']} random poses (seed {s['random_seed']}, stream {s['random_stream']}, "
             f"{len(s['random_coordinates'])} right-leg/lumbar coordinates, range of motion {s['rom']}), "
             f"{s['gait_frames']} walking-trial frames, 1-D sweeps ({s['sweep_points']}) and 2-D grids "
             f"({s['grid_points_per_axis']}²); bones and PAM-PAM checks on {s['geometry_random_poses']} random poses "
             "+ the walking trial",
             "",
             "Legend: d = Festo diameter [mm] (/k: on a k:1 pulley block); NRMSE = RMS(robot - human) / human peak about the primary coordinate, random poses; "
             "worst = largest such error over every coordinate crossed (÷ the same peak); dz = dead-zone % of random "
             "poses/gait frames; bracket = distance of the farthest fixed attachment point (or roller surface) from its own bone [mm] "
             "(negative: inside); seg = deepest route segment into any bone [mm]; 1seg = PAM fits on one straight "
             "segment (o/i: at its origin/insertion end, pam_at); F/rated = peak force per unit / Festo rated force; sens = primary-torque change for a 1 mm "
             "attachment error [% of human peak]; x = actuators whose PAM bodies it intersects.",
             "",
             f"{'id':>3} {'PAM':26s} {'d':>4} {'n':>2} {'NRMSE':>6} {'worst (coordinate)':>28} {'dz%':>9} "
             f"{'bracket':>8} {'seg':>6} {'1seg':>5} {'F/rated':>7} {'sens%':>6}  x"]
    for r in res.pams:
        worst = f"{r['random_worst_coordinate_error']:.3f} ({r['random_worst_coordinate']})"
        dz = f"{100 * r['random_dead_zone_fraction']:.0f}/{100 * max(r.get('gait_dead_zone_fraction', 0), r.get('gait_dead_zone_fraction_left', 0)):.0f}"
        br = "-" if r["max_bracket_m"] is None else f"{1000 * r['max_bracket_m']:.1f}"
        d = f"{r['diameter_mm']}" + (f"/{r['transmission']}" if r.get("transmission", 1) != 1 else "")
        lines.append(f"{r['id']:>3} {r['name'][:26]:26s} {d:>4} {r['n_parallel']:>2} "
                     f"{r['random_nrmse']:>6.3f} {worst:>28} {dz:>9} {br:>8} "
                     f"{1000 * r['max_segment_penetration_m']:>6.1f} {_one_segment(r):>5} "
                     f"{r['force_ratio']:>7.2f} {r['sensitivity_pct']:>6.1f}  "
                     f"{','.join(str(i) for i in r['intersects']) or '-'}")
    lines += ["", f"{'criterion':47s} {'value':>10} {'limit':>14}  result"]
    for c in res.criteria:
        verdict = {True: "pass", False: "FAIL", None: "-"}[c["passed"]]
        lines.append(f"{c['name']:47s} {_fmt(c['value'], 4):>10} {_limit_text(c['limit']):>14}  {verdict}")
    sm = res.summary
    lines += ["", "informational: "
              f"sweep NRMSE median {_fmt(sm['sweep_nrmse_median'])}, gait NRMSE median {_fmt(sm['gait_nrmse_median'])}, "
              f"force model extrapolated for {sm['pams_force_model_extrapolated']} PAMs (resting length outside the "
              f"measured range, or 40 mm), kmax assumed for {sm['pams_kmax_assumed']} (20/40 mm), "
              f"max bracket {_fmt(1000 * sm['max_bracket_m'])} mm, max force ratio {_fmt(sm['max_force_ratio'])}, "
              f"total PAM length {_fmt(sm['total_pam_length_m'])} m, air {_fmt(sm['air_volume_l'])} l, "
              f"mass {_fmt(sm['mass_kg'])} kg (assumed Festo weights)",
              *force_level_lines(res.pams, thr["nrmse_good"], thr["worst_coordinate_error_good"]),
              *(["cable off a roller's end (the route shorter than over open-ended rollers: a guide that loses its "
                 "cable) at a share of the random poses: " + ", ".join(
                     f"{r['id']} {r['name']} {100 * r['roller_cable_off_fraction']:.1f} %" for r in res.pams
                     if r.get("roller_cable_off_fraction"))]
                if any(r.get("roller_cable_off_fraction") for r in res.pams) else []),
              *(["pam_at not possible (the route on that side of the mount segment changes length, or the PAM is "
                 "not on one segment), ignored: " + ", ".join(
                     f"{r['id']} {r['name']} ({r['pam_at_not_possible']})" for r in res.pams if r.get("pam_at_not_possible"))]
                if any(r.get("pam_at_not_possible") for r in res.pams) else []),
              *(["pam_on not possible (the PAM body does not fit on that segment with a constant tendon), the "
                 "segment that holds it best used: " + ", ".join(
                     f"{r['id']} {r['name']} ({r['pam_on_not_possible']})" for r in res.pams if r.get("pam_on_not_possible"))]
                if any(r.get("pam_on_not_possible") for r in res.pams) else []),
              *([f"gait: frames within {thr['gait_residual_pct']:g} % per limiting coordinate: " +
                 ", ".join(f"{c} {100 * f:.0f} %" for c, f in sm["gait_limiting_coordinates"].items())]
                if sm.get("gait_limiting_coordinates") else []),
              *assembly_lines(res),
              "",
              *capacity_lines(res.capacity, thr.get("capacity_pose_fraction", 0.9)),
              "",
              f"thresholds: {json.dumps(thr)}",
              f"{'PASSED' if res.passed else 'FAILED'}: {len(res.failed)} of "
              f"{sum(1 for c in res.criteria if c['passed'] is not None)} limits failed"
              + (f" ({', '.join(res.failed)})" if res.failed else ""),
              f"({res.seconds:.0f} s)"]
    return "\n".join(lines) + "\n"


def force_level_lines(rows: list[dict], limit: float, worst_limit: float = float("inf")) -> list[str]:
    """The scorecard's line on the PAMs over the NRMSE ``limit``: the force scale that would fit each best
    (``random_best_force_scale``), the NRMSE there and, where the audit has it, the worst coordinate error
    there (the same scale multiplies every coordinate's torque) — a miss within ``limit`` and ``worst_limit``
    there is the PAM's force level (size, count, pressure); one that is not is the shape of its torque over
    the poses or across its coordinates (route, force-length). Empty where none is over the limit (or the
    audit predates these numbers)."""
    def num(v) -> float:               # audit.json writes an undefined number as null
        return float("nan") if v is None else float(v)

    over = [r for r in rows if not num(r.get("random_nrmse")) <= limit and "random_best_force_scale" in r]
    if not over:
        return []

    def at_scale(r: dict) -> str:
        if "random_worst_at_best_scale" not in r:
            return _fmt(r["random_nrmse_at_best_scale"])
        return (f"{_fmt(r['random_nrmse_at_best_scale'])}; worst {_fmt(r['random_worst_at_best_scale'])} "
                f"{r.get('random_worst_coordinate_at_best_scale') or ''}".rstrip())

    level = [r for r in over if num(r.get("random_nrmse_at_best_scale")) <= limit
             and not num(r.get("random_worst_at_best_scale", 0.0)) > worst_limit]
    both = f" and worst within {worst_limit:g}" if np.isfinite(worst_limit) else ""
    return [f"force level of the {len(over)} PAMs over the NRMSE limit (torque x s fits the primary coordinate "
            "best; NRMSE and worst coordinate error at s): "
            + ", ".join(f"{r['id']} {r['name']} x{_fmt(r['random_best_force_scale'])} ({at_scale(r)})" for r in over)
            + f"; within {limit:g}{both} at s: {len(level)}"
            + (" (" + ", ".join(str(r["id"]) for r in level) + ")" if level else "")]


def assembly_lines(res) -> list[str]:
    """The scorecard's lines on the PAM bodies as placed: their radii and source, the pairs closer than the
    gap (same side; left–right over the gait) and each body's clearance from bone. Empty for an audit that
    predates these figures."""
    a = getattr(res, "assembly", None) or {}
    if not a:
        return []
    gap = 1000 * a["gap_m"]
    radii = ", ".join(f"{d} mm: {1000 * r:.1f} mm" for d, r in a["body_radii_m"].items())
    out = ["", f"PAM bodies as placed: capsules of the largest outer radius ({radii}; source: "
           f"{a['body_radius_source']}) along the PAM length + both fittings ({1000 * a['fitting_length_m']:.0f} mm "
           "each) from the anchored end of the mount segment"]

    def pair(p: dict) -> str:
        return (f"{p['a']}-{p['b']} {1000 * p['distance_m']:.1f} mm ({100 * p['closer_fraction']:.0f} % of poses "
                f"< {gap:g} mm)")
    for key, what in (("pairs_closer_than_gap", "same side"),
                      ("pairs_closer_than_gap_left_right_gait", "left-right, walking trial")):
        ps = sorted(a[key], key=lambda p: p["distance_m"])
        out.append(f"body pairs closer than {gap:g} mm ({what}): {len(ps)}"
                   + (": " + ", ".join(pair(p) for p in ps[:12]) + (" ..." if len(ps) > 12 else "") if ps else ""))
    bone = [r for r in res.pams if r.get("body_bone_clearance_m") is not None]
    if bone:
        near = sorted(bone, key=lambda r: r["body_bone_clearance_m"])
        out.append(f"body-bone clearance (< {1000 * a['bone_gap_m']:g} mm fails; negative: into bone) [mm]: "
                   + ", ".join(f"{r['id']} {_fmt(1000 * r['body_bone_clearance_m'], 3)} ({r['body_bone_nearest'] or '-'})"
                               for r in near))
    return out


def capacity_lines(rows: list[dict], fraction: float = 0.9) -> list[str]:
    """The joint-capacity table: per coordinate and direction the robot's and human's median summed torque,
    the median and least ratio and the share of poses where robot >= human (``*``: under ``fraction``)."""
    if not rows:
        return []
    out = [f"joint capacity (every PAM at the design's pressure vs every human muscle at activation 1, summed per "
           f"direction; random poses): {sum(r['met'] for r in rows)} of {len(rows)} coordinate-directions with "
           f"robot >= human on >= {100 * fraction:g} % of the poses",
           f"{'coordinate':18s} {'direction':20s} {'robot Nm':>9} {'human Nm':>9} {'ratio':>6} {'min':>6} {'robot>=human':>13}"]
    for r in rows:
        out.append(f"{r['coordinate']:18s} {r['direction'] + ' ' + r['motion']:20s} {_fmt(r['robot_median_Nm'], 4):>9} "
                   f"{_fmt(r['human_median_Nm'], 4):>9} {_fmt(r['ratio_median'], 3):>6} {_fmt(r['ratio_min'], 2):>6} "
                   f"{100 * r['fraction_robot_ge_human']:>11.1f} %{'' if r['met'] else '*'}")
    return out


def capacity_side_by_side(results: list, labels: list[str]) -> str:
    """The joint-capacity figures of several designs in one table: per coordinate-direction the median ratio
    robot ÷ human and the share of poses where robot >= human (``*``: not met). Empty where an audit has none."""
    if not all(getattr(r, "capacity", None) for r in results):
        return ""
    lines = ["joint capacity: median ratio robot/human; share of poses robot >= human",
             f"{'coordinate-direction':36s}" + "".join(f" {lab[:18]:>18}" for lab in labels)]
    for k, row in enumerate(results[0].capacity):
        cells = [f"{_fmt(r.capacity[k]['ratio_median'], 3)}; {100 * r.capacity[k]['fraction_robot_ge_human']:.0f} %"
                 f"{' ' if r.capacity[k]['met'] else '*'}" for r in results]
        lines.append(f"{row['coordinate'] + ' ' + row['direction'] + ' ' + row['motion']:36s}"
                     + "".join(f" {c:>18}" for c in cells))
    return "\n".join(lines) + "\n"


def side_by_side(results: list, labels: list[str]) -> str:
    """Audit summaries of several designs in one table: one line per limit, a column per design
    (``*`` marks a failed limit)."""
    head = f"{'criterion':47s} {'limit':>14}" + "".join(f" {lab[:16]:>16}" for lab in labels)
    lines = [head]
    for k, c in enumerate(results[0].criteria):
        cells = []
        for r in results:
            cr = r.criteria[k]
            cells.append(f"{_fmt(cr['value'], 4)}{'*' if cr['passed'] is False else ' '}")
        lines.append(f"{c['name']:47s} {_limit_text(c['limit']):>14}" + "".join(f" {x:>16}" for x in cells))
    lines.append(f"{'limits failed (*)':47s} {'':>14}" + "".join(f" {len(r.failed):>15} " for r in results))
    return "\n".join(lines) + "\n"


def plot_criteria(res, path: str | os.PathLike) -> Path:
    """One bar chart per per-PAM criterion with its threshold line; offending PAMs in red."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    thr = res.thresholds
    rows = res.pams
    ids = [r["id"] for r in rows]
    panels = [
        ("primary NRMSE, random poses", [r["random_nrmse"] for r in rows], thr["nrmse_good"], False),
        ("worst all-coordinate error", [r["random_worst_coordinate_error"] for r in rows],
         thr["worst_coordinate_error_good"], False),
        ("dead zone, random / gait [%]", [100 * max(r["random_dead_zone_fraction"], r.get("gait_dead_zone_fraction", 0))
                                          for r in rows], 0.0, False),
        ("farthest attachment from own bone [mm]", [1000 * (r["max_bracket_m"] or 0) for r in rows],
         1000 * thr["bracket_max_m"], False),
        ("deepest segment into bone [mm]", [1000 * r["max_segment_penetration_m"] for r in rows],
         1000 * thr["segment_penetration_max_m"], False),
        ("peak force / Festo rated", [r["force_ratio"] for r in rows], 1.0, False),
        ("1 mm attachment error [% human peak]", [r["sensitivity_pct"] for r in rows], thr["sensitivity_max_pct"], True),
        ("intersecting PAMs (count)", [len(r["intersects"]) for r in rows], 0.0, False),
        ("fits on one segment: margin [mm]", [1000 * r["mount_margin_m"] for r in rows], 0.0, None),
    ]
    fig, axes = plt.subplots(3, 3, figsize=(15, 10))
    for ax, (title, vals, lim, logy) in zip(axes.ravel(), panels):
        v = np.asarray(vals, float)
        bad = v < lim if logy is None else v > lim
        ax.bar(range(len(v)), v, color=np.where(bad, "#d62728", "#2ca02c"))
        ax.axhline(lim, color="k", lw=1, ls="--")
        ax.set_title(title, fontsize=10)
        ax.set_xticks(range(len(v)))
        ax.set_xticklabels(ids, fontsize=6)
        if logy:
            ax.set_yscale("symlog", linthresh=1.0)
        ax.grid(axis="y", alpha=0.3)
    verdict = "every limit passed" if res.passed else f"{len(res.failed)} limits failed (see scorecard.txt)"
    fig.suptitle(f"pamkin audit: {res.design} ({verdict})", fontsize=11)
    fig.supxlabel("PAM id (red: beyond the threshold, dashed)")
    fig.tight_layout()
    try:
        return write_figure(fig, path, dpi=80)
    finally:
        plt.close(fig)
