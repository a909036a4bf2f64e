"""``pamkin optimize``: relocate PAM attachment points so robot torques match the human's."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "optimize", help="optimise PAM routes, sizes and parallel counts (CasADi + IPOPT) against Gait2392",
        description="Solve one CasADi/IPOPT problem per actuator (in parallel): route points within boxes "
                    "around the seed design's, resting and tendon lengths, with an outer loop over Festo "
                    "diameter and number of parallel PAMs, so that the PAM torque matches the torque of the "
                    "human muscles it replaces over the range of motion, within the PAMs' strain limits and "
                    "clear of the bone shafts. Writes a run folder (design.yaml, summary.json, log.txt, "
                    "before_after.png); --apply also writes the design into robot/data/pam_biped.yaml and "
                    "regenerates urdf/pam_biped.urdf (atomically; only when every actuator is feasible).")
    s.add_argument("config", nargs="?", help="TOML run description (see optimize/config.py; default: defaults)")
    s.add_argument("--out", help="run folder (default: runs/<date-time>)")
    s.add_argument("--apply", action="store_true", help="write the result into the robot data and URDF")
    s.add_argument("--actuators", help="comma-separated actuator ids (overrides the config)")
    s.add_argument("--workers", type=int, help="worker processes (overrides the config)")
    s.add_argument("--warm-start", help="run folder whose design.yaml seeds the routes (overrides the config)")
    s.add_argument("--design", help="seed design file or 'thesis' (overrides the config; default robot design)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_optimize)


def cmd_optimize(args: argparse.Namespace) -> int:
    from pamkin.optimize.config import load_config  # noqa: PLC0415
    from pamkin.optimize.run import InfeasibleError, run  # noqa: PLC0415

    from .errors import ConfigurationError  # noqa: PLC0415

    cfg = load_config(args.config)
    if args.actuators:
        try:
            cfg.actuators = [int(a) for a in args.actuators.split(",")]
        except ValueError:
            raise ConfigurationError(f"--actuators must be comma-separated integers, got {args.actuators!r}") from None
    if args.workers:
        cfg.workers = args.workers
    if args.warm_start:
        cfg.warm_start = args.warm_start
    if args.design:
        cfg.design = args.design
    cfg.validate()
    out = Path(args.out) if args.out else Path("runs") / time.strftime("%Y%m%d-%H%M%S")
    stream = open("/dev/null", "w") if args.quiet else sys.stderr  # noqa: SIM115
    try:
        summary = run(cfg, out, apply=args.apply, stream=stream)
    except InfeasibleError as e:
        print(f"pamkin optimize: {e}\nnothing was written into the robot data; see {out}", file=sys.stderr)
        return 3
    print(f"\nRun folder {out} ({summary['total_seconds']} s)")
    print(f"{'id':>3} {'PAM':26s} {'d':>3} {'n':>2} {'rest m':>7} {'tendon':>7} {'NRMSE before':>12} "
          f"{'after':>6} {'2-D':>6} {'sign':>5} {'dead':>5} {'clear mm':>8}")
    for a in summary["actuators"]:
        two = "-" if a["nrmse_2d_after"] is None else f"{a['nrmse_2d_after']:.3f}"
        print(f"{a['id']:3d} {a['name'][:26]:26s} {a['diameter_mm']:3d} {a['n_parallel']:2d} "
              f"{a['resting_length_m']:7.3f} {a['tendon_length_m']:7.3f} {a['nrmse_before']:12.3f} "
              f"{a['nrmse_after']:6.3f} {two:>6} {a['sign_agreement']:5.2f} {a['dead_zone_fraction']:5.2f} "
              f"{1000 * a['min_bone_clearance_m']:8.1f}")
    print(f"median NRMSE {summary['median_nrmse_before']:.3f} -> {summary['median_nrmse_after']:.3f}; "
          f"{summary['n_within_0.20_after']} of {len(summary['actuators'])} within 0.20; "
          f"{summary['n_halved']} halved; all buildable: {summary['all_buildable']}; "
          f"all clear of bone: {summary['all_clear_bone']}"
          + ("; applied to robot/data/pam_biped.yaml" if summary.get("applied") else ""))
    return 0
