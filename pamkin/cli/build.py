"""``pamkin build``: the build sheet of a design (Markdown, CSV, JSON and an assembled 3-D view)."""

from __future__ import annotations

import argparse
import sys


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "build", help="write a design's build sheet: Festo parts, cables, guides, brackets, mass, a 3-D view",
        description="Write what a workshop needs to build a design into one folder (whole or not at all): "
                    "build_sheet.md, pams.csv, attachments.csv, parts.csv and build_sheet.json — per PAM the Festo "
                    "DMSP designation with its nominal length, parallel count, fittings, pulley block, cable "
                    "(artificial tendon) length, mount segment and guides; per attachment the bone, coordinates in "
                    "the bone's frame [mm] and the bracket (length, direction, foot on the bone); parts and mass "
                    "totals for both sides — and assembly.html, the assembled robot with PAM bodies at their "
                    "inflated size (assembly.png with --screenshot).")
    s.add_argument("design", nargs="?", default=None,
                   help="a `pamkin optimize` run folder, a design file, 'thesis', 'split_gluteal', 'v2_seed' or 'merged_seed' "
                        "(default: the robot's design robot/data/thesis_design.yaml)")
    s.add_argument("--out", help="output folder (default: build-<design name> in the current folder); refused if "
                                 "it exists unless --force")
    s.add_argument("--force", action="store_true", help="replace an existing output folder whole (default: refuse)")
    s.add_argument("--geometry", help="folder of the model's .vtp bone meshes (default: found beside the model, "
                                      "$PAMKIN_GEOMETRY, or ../shared/opensim-models/Geometry)")
    s.add_argument("--screenshot", action="store_true",
                   help="also render assembly.html to assembly.png with headless Chromium (default: no)")
    s.add_argument("--json", action="store_true", help="print the build sheet as JSON (default: a summary)")
    s.set_defaults(func=cmd_build)


def cmd_build(args: argparse.Namespace) -> int:
    from pathlib import Path  # noqa: PLC0415

    from pamkin.build.documents import write_build_sheet  # noqa: PLC0415
    from pamkin.build.sheet import build_sheet  # noqa: PLC0415
    from pamkin.outputs import check_output_folder, strict_json  # noqa: PLC0415
    from pamkin.robot.biped import robot_skeleton  # noqa: PLC0415
    from pamkin.robot.design import load_design  # noqa: PLC0415

    skel = robot_skeleton()
    des = load_design(args.design, bodies=skel.bodies, coordinates=skel.coordinates)
    out = Path(args.out or f"build-{des.name}")
    check_output_folder(out, args.force)          # before the work
    sheet = build_sheet(des, args.geometry)
    files = write_build_sheet(sheet, des, out, force=args.force, geometry_dir=args.geometry,
                              screenshot_png=args.screenshot)
    if args.json:
        print(strict_json(sheet, indent=1))
    else:
        m = sheet["mass"]
        bad = [p for p in sheet["pams"] if not p["on_one_segment"]]
        inside = [a for a in sheet["attachments"] if (a.get("bracket_mm") or 0) < 0]
        print(f"build sheet of {des.name}: {len(sheet['pams'])} PAMs per side, {m['pam_units_both_sides']} PAM units, "
              f"{m['total_kg']:.2f} kg (assumed Festo weights), {len(sheet['attachments'])} attachments per side")
        if bad:
            print(f"warning: {len(bad)} PAMs do not fit on one straight segment: "
                  + ", ".join(f"{p['id']} {p['name']}" for p in bad))
        if inside:
            print(f"warning: {len(inside)} attachment points lie inside their bone")
        for f in files:
            print(f"wrote {f}")
    sys.stdout.flush()
    return 0
