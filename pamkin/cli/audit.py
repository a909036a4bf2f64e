"""``pamkin audit``: the scorecard of a design on held-out samples (exit 1 when a limit fails)."""

from __future__ import annotations

import argparse
import json
import os
import sys


def add_parsers(sub) -> None:
    from pamkin.audit.measure import GAIT_IK, LIMITS_FILE  # noqa: PLC0415

    s = sub.add_parser(
        "audit", help="measure what a design is really worth: held-out poses, every coordinate, bones, buildability",
        description="Audit a design on samples no optimiser trains on: 2000 seeded random poses of every right-leg "
                    "and lumbar coordinate within the design's range of motion, every frame of a walking trial, and "
                    "the 1-D sweeps / 2-D grids. Measures each PAM's torque about every coordinate it crosses against "
                    "its human muscles (Gait2392, full activation), dead zones, attachment points and route segments "
                    "against the real bone meshes (signed distances, libigl), PAM-PAM clearance (coal), whether each "
                    "PAM fits on one straight segment, forces against Festo's ratings, the sensitivity to a 1 mm "
                    "attachment error, bulk (count, length, air, assumed mass) and the gait pressure plan's "
                    "feasible-frame fraction (pamkin gait). Prints a scorecard; exits 1 when a limit fails "
                    f"(limits: {LIMITS_FILE}), 2 on bad input.")
    s.add_argument("design", nargs="?", default=None,
                   help="design file, a `pamkin optimize` run folder, 'thesis', 'split_gluteal', 'v2_seed' or 'merged_seed' (default: the robot's design "
                        "robot/data/thesis_design.yaml)")
    s.add_argument("--json", action="store_true", help="print one JSON object (pams, summary, criteria) instead of the scorecard (default: the scorecard)")
    s.add_argument("--out", help="folder for audit.json, scorecard.txt, criteria.png and view.html, written whole or "
                                 "not at all; refused if it holds files unless --force (default: write nothing)")
    s.add_argument("--force", action="store_true",
                   help="replace an existing --out folder whole (default: refuse)")
    s.add_argument("--quick", action="store_true",
                   help="fewer samples (500 random poses, 150 of them for bone/PAM geometry, every 3rd gait frame, "
                        "4 mm segment steps, 21-point sweeps); default: 2000 poses, 1000 for geometry, every frame, "
                        "2 mm steps, 41-point sweeps")
    s.add_argument("--limits", help=f"YAML file overriding thresholds/limits (default: {LIMITS_FILE})")
    s.add_argument("--seed", type=int, default=0, help="seed of the random poses (default 0)")
    s.add_argument("--random", type=int, default=None, metavar="N",
                   help="number of random poses (default 2000; 500 with --quick)")
    s.add_argument("--ik", default=str(GAIT_IK),
                   help="walking trial IK angles .mot ('none': no gait samples; default: the shared subject01 trial)")
    s.add_argument("--geometry", help="folder of the model's .vtp bone meshes (default: found beside the model, "
                                      "$PAMKIN_GEOMETRY, or ../shared/opensim-models/Geometry)")
    s.add_argument("--no-gait-plan", action="store_true",
                   help="skip the gait pressure plan (its feasible-frame fraction then shows '-'; default: run it)")
    s.add_argument("--screenshot", action="store_true",
                   help="with --out: also render view.html to view.png with headless Chromium (default: no)")
    s.set_defaults(func=cmd_audit)


def cmd_audit(args: argparse.Namespace) -> int:
    from pathlib import Path  # noqa: PLC0415

    from pamkin.audit.measure import AuditOptions, audit_design, load_limits  # noqa: PLC0415
    from pamkin.audit.scorecard import plot_criteria, scorecard_text  # noqa: PLC0415
    from pamkin.cli.bounds import check_count  # noqa: PLC0415
    from pamkin.outputs import check_output_folder, output_folder, write_file  # noqa: PLC0415
    from pamkin.viz.audit_page import audit_view  # noqa: PLC0415

    if args.random is not None:
        check_count("--random", args.random, 1, 100000)
    ik = None if str(args.ik).lower() == "none" else args.ik
    kw = {"seed": args.seed, "gait_ik": ik, "geometry_dir": args.geometry, "gait_plan": not args.no_gait_plan}
    if args.random is not None:
        kw["n_random"] = args.random
    opt = AuditOptions.quick(**kw) if args.quick else AuditOptions(**kw)
    limits = load_limits(args.limits)
    if args.out:
        check_output_folder(args.out, args.force)    # before the audit's minutes of work

    def progress(msg: str) -> None:
        if not args.json:
            print(f"  audit: {msg}", file=sys.stderr, flush=True)

    res = audit_design(args.design, options=opt, limits=limits, progress=progress)
    text = scorecard_text(res)
    written = []
    if args.out:
        out = Path(args.out)
        with output_folder(out, args.force) as tmp:        # the audit folder appears complete or not at all
            write_file(tmp / "audit.json", json.dumps(res.to_dict(), indent=1, default=float, allow_nan=False))
            write_file(tmp / "scorecard.txt", text)
            plot_criteria(res, tmp / "criteria.png")
            audit_view(res, tmp / "view.html", args.geometry)
            names = ["audit.json", "scorecard.txt", "criteria.png", "view.html"]
            if args.screenshot:
                from pamkin.viz.meshcat_view import screenshot  # noqa: PLC0415

                screenshot(tmp / "view.html", tmp / "view.png")
                names.append("view.png")
        written += [out / n for n in names]
    code = 0 if res.passed else 1              # 1: a limit failed (also when the reader closes the pipe early)
    try:
        _print_result(args, res, text, written)
    except BrokenPipeError:
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115  (nothing more reaches a closed pipe)
    return code


def _print_result(args, res, text: str, written: list) -> None:
    from pamkin.outputs import strict_json  # noqa: PLC0415

    if args.json:
        d = res.to_dict()
        d["written"] = [str(w) for w in written]
        print(strict_json(d, indent=1))
    else:
        print(text, end="")
        for w in written:
            print(f"wrote {w}")
        if not res.passed:
            print("next: fix the failed criteria (pamkin optimize, or edit the design) and re-run pamkin audit")
    sys.stdout.flush()
