"""``pamkin gait``: PAM pressure plans of a design over a recorded walking trial."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pamkin.outputs import strict_json


def add_parsers(sub) -> None:
    from pamkin.gait.plan import DEFAULT_GRF, DEFAULT_ID, DEFAULT_IK  # noqa: PLC0415

    s = sub.add_parser(
        "gait", help="can the robot walk like the human? PAM pressures reproducing a walking trial's moments",
        description="Mount every PAM of a design (both legs, the left mirrored, and the trunk) on the Gait2392 "
                    "skeleton at each frame of an OpenSim walking trial (IK angles; ID moments interpolated onto "
                    "the IK frames inside the ID time range) and choose, per frame, pressures in [0, P_max] that "
                    "reproduce the 17 non-pelvis moments: first the least residual (normalised by each "
                    "coordinate's peak moment), then the least effort sum (P/P_max)^2 (two QPs, ProxQP through "
                    "qpsolvers, warm-started). Reports RMS and max residual per coordinate (N·m and % of peak), "
                    "the fraction of frames where every residual is below 5 % of its peak, pressures per PAM, "
                    "saturated PAMs, dead zones and supply air per stride. The moments are those of OpenSim's "
                    "scaled subject01 (about 72 kg), used as given.")
    s.add_argument("design", nargs="?", default=None,
                   help="design file, a `pamkin optimize` run folder, 'thesis', 'split_gluteal', 'v2_seed' or 'merged_seed' (default: the robot's design "
                        "robot/data/thesis_design.yaml)")
    s.add_argument("--ik", default=str(DEFAULT_IK), help="IK angles .mot (default: the shared subject01 trial)")
    s.add_argument("--id", default=str(DEFAULT_ID), help="ID moments .sto (default: the shared subject01 trial)")
    s.add_argument("--grf", default=str(DEFAULT_GRF),
                   help="ground reaction forces .mot for the gait phases ('none': no phases; air per window; "
                        "default: the shared subject01 trial)")
    s.add_argument("--p-max", type=float, default=None,
                   help="pressure limit [kPa], at most 800 (default: the design's operating pressure, pressure_Pa)")
    s.add_argument("--tolerance", type=float, default=5.0,
                   help="feasible frame: every residual below this %% of its coordinate's peak (default 5)")
    s.add_argument("--solver", default="proxqp", help="qpsolvers backend (default proxqp; daqp, osqp)")
    s.add_argument("--out", help="folder for gait.json, pressures.csv, moments.csv and pressures.png, written whole or "
                                 "not at all; refused if it holds files unless --force (default: write nothing)")
    s.add_argument("--force", action="store_true", help="replace an existing --out folder whole (default: refuse)")
    s.add_argument("--json", action="store_true", help="print one JSON object (summary, coordinates, pams) (default: a table)")
    s.set_defaults(func=cmd_gait)


def cmd_gait(args: argparse.Namespace) -> int:
    from pamkin.errors import ParameterError  # noqa: PLC0415
    from pamkin.gait.plan import gait_plan, write_outputs  # noqa: PLC0415
    from pamkin.outputs import check_output_folder, output_folder  # noqa: PLC0415
    from pamkin.robot.design import load_design  # noqa: PLC0415

    if not 0 < args.tolerance < 100:
        raise ParameterError(f"--tolerance must be a percentage in (0, 100), got {args.tolerance}")
    if args.p_max is None:                  # the design's own operating pressure
        design = args.design if args.design not in (None, "robot") else None
        args.p_max = (load_design(design) if design else load_design()).pressure_Pa / 1e3
    if not 0 < args.p_max <= 800:
        raise ParameterError(f"--p-max must be a pressure in (0, 800] kPa, got {args.p_max}")
    if args.out:
        check_output_folder(args.out, args.force)             # before any work
    grf = None if str(args.grf).lower() == "none" else args.grf
    plan = gait_plan(args.design, ik=args.ik, id=args.id, grf=grf, p_max=args.p_max * 1e3,
                     tolerance=args.tolerance / 100, solver=args.solver)
    files = []
    if args.out:
        with output_folder(args.out, args.force) as tmp:       # complete or not at all
            files = [Path(args.out) / f.name for f in write_outputs(plan, tmp)]
    if args.json:
        d = plan.to_dict()
        d["written"] = [str(f) for f in files]
        print(strict_json(d))
        return 0
    s = plan.summary()
    print(f"Design {plan.design!r} ({plan.design_path}) over {plan.trial.ik_path}")
    print(f"{s['frames']} frames {s['time_range_s'][0]:.3f}-{s['time_range_s'][1]:.3f} s, {s['n_pams']} PAMs, "
          f"P_max {s['p_max_kPa']:.0f} kPa; moments of the scaled subject01 (~72 kg) as given.")
    print(f"\n{'coordinate':18s} {'peak N·m':>9} {'RMS N·m':>8} {'RMS %':>6} {'max N·m':>8} {'max %':>6} "
          f"{'within':>7}")
    for c in plan.coordinate_results:
        print(f"{c.name:18s} {c.peak_moment_Nm:9.2f} {c.rms_residual_Nm:8.3f} {c.rms_residual_pct:6.2f} "
              f"{c.max_residual_Nm:8.3f} {c.max_residual_pct:6.2f} {c.within_tolerance_fraction:7.2f}")
    print(f"\nFeasible frames (every residual < {100 * plan.tolerance:g} % of its peak): "
          f"{100 * s['feasible_frame_fraction']:.1f} % of {s['frames']}")
    print(f"Pressure: peak {s['peak_pressure_kPa']:.0f} kPa, mean {s['mean_pressure_kPa']:.0f} kPa; supply air "
          f"{s['air_per_stride_NL']:.1f} NL per stride (all PAMs)")
    print(f"Saturated at P_max: {', '.join(s['saturated_pams']) or 'none'}")
    print(f"In a dead zone: {', '.join(s['dead_zone_pams']) or 'none'}")
    if s["frames_outside_robot_rom"]:
        print("Frames outside the robot's range of motion: " +
              ", ".join(f"{k} {v}" for k, v in s["frames_outside_robot_rom"].items()))
    if s["effort_fallback_frames"]:
        print(f"Effort QP fell back to the residual solution at {s['effort_fallback_frames']} frame(s)")
    print(f"\n{'PAM':8s} {'name':26s} {'d×n':>7} {'peak kPa':>8} {'mean kPa':>8} {'sat %':>6} {'dead %':>6} "
          f"{'slack %':>7} {'air NL':>7}")
    for p in plan.pam_results:
        dn = f"{p.diameter_mm}×{p.n_parallel}" + (f"/{p.transmission}" if p.transmission != 1 else "")
        print(f"{p.name:8s} {p.label[:26]:26s} {dn:>7} {p.peak_pressure_kPa:8.0f} "
              f"{p.mean_pressure_kPa:8.0f} {100 * p.saturated_fraction:6.0f} {100 * p.dead_zone_fraction:6.0f} "
              f"{100 * p.slack_fraction:7.0f} {p.air_per_stride_NL:7.2f}")
    print(f"\nSolved in {s['timings_s']['solve']:.2f} s ({plan.solver}); total {s['timings_s']['total']:.2f} s")
    for f in files:
        print(f"wrote {f}", file=sys.stderr)
    return 0

