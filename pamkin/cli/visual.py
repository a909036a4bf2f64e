"""``pamkin view`` and ``pamkin report``: meshcat pages and torque-surface figures."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from pamkin.cli.bounds import check_count
from pamkin.errors import ConfigurationError
from pamkin.outputs import check_output_file, check_output_folder, output_folder


def add_parsers(sub) -> None:
    from pamkin.viz.meshcat_view import DEFAULT_GEOMETRY  # noqa: PLC0415

    s = sub.add_parser(
        "view", help="meshcat page: skeleton, human muscles and robot PAMs (optionally a range-of-motion sweep)",
        description="Write a self-contained web page (meshcat, opens offline) showing the Gait2392 skeleton "
                    "with bone meshes (or simple shapes without a geometry folder), the human muscles as thin "
                    "cylinders and the robot's PAMs as cylinders of their Festo diameter along their routes "
                    "(fittings and artificial tendon thin, dark grey), coloured by force or strain; a PAM in a "
                    "dead zone is magenta. --sweep animates one coordinate over the design's range of motion "
                    "(forth and back); other coordinates are 0 unless set with --set.")
    s.add_argument("--html", required=True, metavar="FILE", help="the page to write")
    s.add_argument("--design", help="design file, 'thesis' (the thesis design), 'split_gluteal', 'v2_seed' or 'merged_seed' (default: the robot's design "
                                    "robot/data/thesis_design.yaml)")
    s.add_argument("--geometry", metavar="DIR",
                   help=f"folder of the .vtp bone meshes (default: {DEFAULT_GEOMETRY} if it exists, else "
                        "simple shapes); an explicit folder that does not exist is an error")
    s.add_argument("--no-meshes", action="store_true",
                   help="draw simple shapes instead of bone meshes (default: meshes when the folder exists)")
    s.add_argument("--layout", choices=("side", "overlay"), default="side",
                   help="side: robot beside the human (default); overlay: both on one skeleton")
    s.add_argument("--color", choices=("force", "strain"), default="force",
                   help="colour muscles and PAMs by force [N] (default) or by contraction strain [-]")
    s.add_argument("--sweep", metavar="COORD",
                   help="animate this coordinate over the design's range of motion (default: a still picture)")
    s.add_argument("-n", type=int, default=21, help="samples of the sweep, 2..1001 (default 21; played forth and back)")
    s.add_argument("--set", action="append", default=[], metavar="COORD=VALUE",
                   help="set a coordinate of the shown configuration, degrees (metres for pelvis_tx/ty/tz); "
                        "repeatable (default: every coordinate 0)")
    s.add_argument("--screenshot", metavar="PNG",
                   help="also render the page with headless Chromium (/usr/bin/chromium) into this PNG "
                        "(default: no screenshot)")
    s.add_argument("--size", default="1000x700", help="screenshot size WIDTHxHEIGHT in pixels (default 1000x700)")
    s.set_defaults(func=cmd_view)

    s = sub.add_parser(
        "report", help="torque-surface report: robot vs human torque figures for every PAM, with an HTML index",
        description="For every PAM of one side: torque surfaces (human, robot, robot - human) over its primary "
                    "coordinate x a partner coordinate (its first secondary coordinate, else a default such as "
                    "hip_flexion for a knee PAM), torque about both; and the 1-D torque curves of the primary "
                    "coordinate with the dead zones (PAM strain outside Festo's range) shaded. Range of motion "
                    "of the design, other coordinates 0. Writes PNG files and index.html into --out.")
    s.add_argument("--design", help="design file, 'thesis' (the thesis design), 'split_gluteal', 'v2_seed' or 'merged_seed' (default: the robot's design "
                                    "robot/data/thesis_design.yaml)")
    s.add_argument("--out", default="pamkin-report", metavar="DIR",
                   help="output folder, written whole or not at all; refused if it holds files unless --force "
                        "(default: pamkin-report)")
    s.add_argument("--force", action="store_true",
                   help="replace an existing --out folder whole (no stale files of the old report) (default: refuse)")
    s.add_argument("--side", choices=("r", "l"), default="r", help="leg side (default: r)")
    s.add_argument("-n", type=int, default=25, help="grid points per coordinate of the surfaces, 2..201 (default 25)")
    s.add_argument("--n1", type=int, default=101, help="samples of the 1-D curves, 2..10001 (default 101)")
    s.add_argument("--pams", metavar="IDS", help="comma-separated actuator ids (default: all)")
    s.add_argument("--partner", metavar="COORD", help="second grid coordinate for every PAM (default: per PAM)")
    s.add_argument("--quiet", action="store_true", help="no progress lines on stderr (default: progress shown)")
    s.set_defaults(func=cmd_report)


def _configuration(model, items: list[str]) -> np.ndarray:
    """Configuration with every coordinate 0 except ``COORD=VALUE`` items (degrees or metres)."""
    q = np.zeros(len(model.coordinates))
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in model.coordinates:
            raise ConfigurationError(f"--set {item!r}: expected COORD=VALUE with COORD one of {model.coordinates}")
        try:
            v = float(value)
        except ValueError:
            raise ConfigurationError(f"--set {item!r}: {value!r} is not a number") from None
        q[model.coordinates.index(name)] = np.radians(v) if model.osim.coordinate(name).rotational else v
    return q


def cmd_view(args: argparse.Namespace) -> int:
    import pamkin  # noqa: PLC0415
    from pamkin.cli.robot import _robot  # noqa: PLC0415
    from pamkin.opensim.vtp import body_meshes  # noqa: PLC0415
    from pamkin.viz.meshcat_view import DEFAULT_GEOMETRY, build_view, screenshot  # noqa: PLC0415

    try:
        width, height = (int(x) for x in args.size.lower().split("x"))
    except ValueError:
        raise ConfigurationError(f"--size {args.size!r}: expected WIDTHxHEIGHT, e.g. 1000x700") from None
    check_count("-n", args.n, 2, 1001)
    check_output_file(args.html)            # before any work: not a folder, its folder not a file
    if args.screenshot:
        check_output_file(args.screenshot)
    human = pamkin.gait2392()
    robot = _robot(args.design)
    meshes = None
    if not args.no_meshes:
        folder = Path(args.geometry) if args.geometry else DEFAULT_GEOMETRY
        if args.geometry or folder.is_dir():
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                meshes = body_meshes(human, folder)
            for w in caught:
                print(f"warning: {w.message}")
        else:
            print(f"no geometry folder at {folder}: simple shapes instead of bone meshes (--geometry DIR)")
    view = build_view(human, robot, meshes=meshes, layout=args.layout, color=args.color,
                      q=_configuration(human, args.set), sweep=args.sweep, n=args.n)
    path = view.save(args.html)
    print(f"wrote {path} ({view.scale.label}: {view.scale.vmin:g} .. {view.scale.vmax:g}"
          f"{f'; {len(view.frames)} animation frames' if len(view.frames) > 1 else ''})")
    if args.screenshot:
        print(f"wrote {screenshot(path, args.screenshot, size=(width, height))}")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    import pamkin  # noqa: PLC0415
    from pamkin.cli.robot import _robot  # noqa: PLC0415
    from pamkin.viz.torque_report import torque_report  # noqa: PLC0415

    pams = None
    if args.pams:
        try:
            pams = [int(x) for x in args.pams.split(",") if x.strip()]
        except ValueError:
            raise ConfigurationError(f"--pams {args.pams!r}: expected comma-separated actuator ids") from None
    def progress(done: int, total: int, key: str, name: str) -> None:
        bar = "#" * int(30 * done / total)
        print(f"[{bar:30s}] {done:2d}/{total}  {key} {name}", file=sys.stderr, flush=True)

    check_count("-n", args.n, 2, 201)
    check_count("--n1", args.n1, 2, 10001)
    check_output_folder(args.out, args.force)        # before any work
    with output_folder(args.out, args.force) as tmp:   # the report appears complete or not at all
        rep = torque_report(_robot(args.design), pamkin.gait2392(), tmp, side=args.side, n=args.n, n1=args.n1,
                            pams=pams, partner=args.partner, progress=None if args.quiet else progress)
    print(f"wrote {len(rep.files)} figures and {Path(args.out) / Path(rep.index).name}")
    return 0
