"""``pamkin size`` and ``pamkin compare``: the PAM robot's sizing table and torque comparison."""

from __future__ import annotations

import argparse
import json
import warnings

import numpy as np

from pamkin.outputs import strict_json


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "size", help="PAM sizing table (diameter, resting length, tendon; totals per diameter, both sides)",
        description="Size every PAM of a design from its route's path lengths over the PAM's primary and "
                    "secondary coordinates in the design's range of motion (15 samples each), like thesis "
                    "Table 5. --method thesis reproduces the thesis Size() (its 5*delta fallback flagged); "
                    "--method constrained states and checks the limits (contraction <= kmax at the shortest "
                    "path, pretension within Festo's limit at the longest, fittings and a non-negative "
                    "tendon) and reports infeasible PAMs; --method design prints the design file's sizes.")
    s.add_argument("--design", help="design file, or 'thesis' for the thesis design robot/data/thesis_design.yaml "
                                    "(default: the robot's design robot/data/thesis_design.yaml)")
    s.add_argument("--method", choices=("thesis", "constrained", "design"), default="thesis",
                   help="thesis: the thesis Size() algorithm; constrained: stated and checked limits; design: the "
                        "design file's own sizes (default: thesis)")
    s.add_argument("--json", action="store_true", help="machine-readable output (default: a table)")
    s.set_defaults(func=cmd_size)

    s = sub.add_parser(
        "compare", help="robot vs human torques per PAM, per thesis group and per joint",
        description="Compare each PAM's torque with the summed torque of the human muscles it replaces "
                    "(Gait2392, full activation) over the design's range of motion: NRMSE (RMS error / human "
                    "peak), peak ratio, sign agreement and dead-zone fraction, on a 1-D sweep of the primary "
                    "coordinate (others 0) and 2-D grids primary x secondary; then thesis groups and joint "
                    "capacity envelopes.")
    s.add_argument("--design", help="design file, 'thesis' (the thesis design), 'split_gluteal', 'v2_seed' or 'merged_seed' (default: the robot's "
                                    "design robot/data/thesis_design.yaml)")
    s.add_argument("--side", choices=("r", "l"), default="r", help="leg side (default: r)")
    s.add_argument("-n", type=int, default=41, help="samples of the 1-D sweeps, 2..1001 (default: 41)")
    s.add_argument("--json", action="store_true", help="machine-readable output (default: a table)")
    s.set_defaults(func=cmd_compare)


def _robot(design_path: str | None):
    from pamkin.robot.biped import design_robot  # noqa: PLC0415

    return design_robot(design_path)


def sizing_rows(robot, method: str) -> list[dict]:
    """One row per PAM (right side) with the sizing of ``method``."""
    import pamkin  # noqa: PLC0415
    from pamkin.human.rom import load_rom  # noqa: PLC0415
    from pamkin.robot.sizing import SizingFallbackWarning, size_pam, thesis_size  # noqa: PLC0415

    human = pamkin.gait2392()
    rom = load_rom(robot.design.rom, "r")
    rows = []
    for k, p in enumerate(robot.pams):
        if robot.sides[k] != "r":
            continue
        coords = [p.primary_coordinate, *p.secondary_coordinates]
        if "hip_adduction_r" in coords and "hip_flexion_r" not in coords:
            coords.append("hip_flexion_r")
        q, _ = robot.model.grid(coords, 15, rom=rom, base={c: 0.0 for c in robot.coordinates})
        L = robot.paths.evaluate(robot.model.kinematics.forward(q, warn_range=False), moment_arms=False).lengths[:, k]
        mif = float(sum(human.osim.muscles[human.muscles.index(m)].params["max_isometric_force"]
                        for m in p.human_muscles))
        row = {"id": p.id, "name": p.name, "motion": coords, "human_max_isometric_force_N": mif,
               "path_length_min_m": float(L.min()), "path_length_max_m": float(L.max())}
        if method == "design":
            row.update(diameter_mm=p.diameter_mm, n_parallel=p.n_parallel, resting_length_m=p.resting_length_m,
                       tendon_length_m=p.tendon_length_m, transmission=p.transmission, feasible=p.tendon_length_m >= 0,
                       note=("" if p.tendon_length_m >= 0 else "negative tendon: PAM longer than its route")
                       + (f"on a {p.transmission}:1 pulley block" if p.transmission != 1 else ""))
        elif method == "thesis":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", SizingFallbackWarning)
                s = thesis_size(L, mif)
            row.update(diameter_mm=s.diameter_mm, n_parallel=1, resting_length_m=s.rest_length,
                       tendon_length_m=s.tendon_length, feasible=not s.fallback,
                       note="thesis 5*delta fallback: does not fit" if s.fallback else "")
        else:
            s = size_pam(L, mif)
            row.update(diameter_mm=s.diameter_mm, n_parallel=s.n_parallel, resting_length_m=s.rest_length,
                       tendon_length_m=s.tendon_length, feasible=s.feasible, note=s.reason if not s.feasible else "")
        if method != "design" and p.transmission != 1:
            row["note"] = (row["note"] + "; " if row["note"] else "") + f"sized as a direct PAM (the design has a {p.transmission}:1 block)"
        rows.append(row)
    return rows


def cmd_size(args: argparse.Namespace) -> int:
    robot = _robot(args.design)
    rows = sizing_rows(robot, args.method)
    totals = {}
    for d in (10, 20, 40):
        sel = [r for r in rows if r["diameter_mm"] == d and r["feasible"]]
        totals[d] = 2 * float(sum(r["resting_length_m"] * r["n_parallel"] for r in sel))
    if args.json:
        print(strict_json({"design": robot.design.name, "method": args.method, "rom": robot.design.rom,
                           "pams": rows, "total_length_both_sides_m": totals}))
        return 0
    print(f"Sizing of design {robot.design.name!r} ({args.method}; range of motion {robot.design.rom}, "
          f"fittings 2 x {robot.design.fitting_length_m} m)")
    print(f"{'id':>3} {'PAM':26s} {'d mm':>4} {'n':>2} {'rest m':>8} {'tendon m':>9}  {'motion':44s} note")
    for r in rows:
        d = "-" if r["diameter_mm"] is None else str(r["diameter_mm"])
        rest, ten = (f"{v:.4f}" if v is not None and np.isfinite(v) else "-"
                     for v in (r["resting_length_m"], r["tendon_length_m"]))
        print(f"{r['id']:3d} {r['name'][:26]:26s} {d:>4} {r['n_parallel'] or '-':>2} {rest:>8} {ten:>9}  "
              f"{', '.join(r['motion'])[:44]:44s} {r['note']}")
    print("Total resting length, both sides (feasible PAMs): " +
          ", ".join(f"{d} mm: {t:.3f} m" for d, t in totals.items()))
    bad = [r["id"] for r in rows if not r["feasible"]]
    if bad:
        print(f"Not buildable / infeasible: {bad}")
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    import pamkin  # noqa: PLC0415
    from pamkin.audit.compare import (  # noqa: PLC0415
        compare_design,
        compare_groups,
        compare_joints,
        finite_or_none,
        summary_line,
    )
    from pamkin.cli.bounds import check_count  # noqa: PLC0415

    check_count("-n", args.n, 2, 1001)
    robot = _robot(args.design)
    human = pamkin.gait2392()
    rows = compare_design(robot, human, args.side, n=args.n)
    groups = compare_groups(robot, human, args.side)
    joints = compare_joints(robot, human, args.side)
    summary = summary_line(rows)
    if args.json:
        print(json.dumps(finite_or_none({"design": robot.design.name, "rom": robot.design.rom, "side": args.side,
                                         "summary": summary, "pams": [r.to_dict() for r in rows], "groups": groups,
                                         "joints": joints}), indent=2, allow_nan=False))
        return 0
    print(f"Design {robot.design.name!r} vs Gait2392 (activation 1), {robot.design.rom} range of motion, "
          f"side {args.side}. NRMSE = RMS(robot - human) / human peak.")
    print(f"{'id':>3} {'PAM':24s} {'d':>3} {'fits':>4} | {'primary (1-D sweep)':22s} {'nrmse':>6} {'peak':>5} "
          f"{'sign':>5} {'dead':>5} | secondary (2-D) nrmse")
    for r in rows:
        p = r.primary
        sec = ", ".join(f"{m.coordinate.removesuffix('_' + args.side)} {m.nrmse:.2f}" for m in r.secondary)
        print(f"{r.id:3d} {r.name[:24]:24s} {r.diameter_mm:3d} {'yes' if r.buildable else 'NO':>4} | "
              f"{p.coordinate:22s} {p.nrmse:6.2f} {p.peak_ratio:5.2f} {p.sign_agreement:5.2f} "
              f"{p.dead_zone_fraction:5.2f} | {sec}")
    print(f"\nMedian primary NRMSE {summary['median_nrmse']:.3f}; {summary['within_0.25']} of {summary['n']} PAMs "
          f"within 0.25; sign agreement < 0.5: {summary['sign_agreement_below_half']}; not buildable: "
          f"{summary['not_buildable']}; with dead zones: {summary['with_dead_zones']}"
          + (f"; undefined NRMSE (no human torque about the primary coordinate; counted as infinite): "
             f"{summary['undefined_nrmse']}" if summary["undefined_nrmse"] else ""))
    print("\nThesis groups (robot sum vs human group), NRMSE per coordinate:")
    for key, g in groups.items():
        print(f"  {key:16s} PAMs {g['pams']}: " + "; ".join(
            f"{c} {m['nrmse']:.2f} (peak {m['peak_ratio']:.2f})" for c, m in g["coordinates"].items()))
    print("\nJoint capacity envelopes [N·m] (1-D sweeps): human +/-, robot +/-")
    for c, v in joints.items():
        print(f"  {c:18s} human {v['human_max_positive_Nm']:7.1f} {v['human_min_negative_Nm']:8.1f}   robot "
              f"{v['robot_max_positive_Nm']:7.1f} {v['robot_min_negative_Nm']:8.1f}")
    return 0
