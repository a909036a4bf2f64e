"""The ``pamkin`` command line: one entry point with subcommands, one module each
(``pamkin.cli.<command>``: torques, robot (size, compare), optimize, export, visual (view, report),
gait, audit, build, fit_paths, mjcf, simulate; ``info`` and ``urdf`` live here).

Run ``pamkin --help`` for the list and ``pamkin COMMAND --help`` for each command.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pamkin._resources import DEFAULT_OSIM  # re-exported: pamkin.cli.DEFAULT_OSIM
from pamkin.errors import PamkinError
from pamkin.outputs import strict_json


def _load(osim: str | None):
    import pamkin  # noqa: PLC0415

    return pamkin.load_osim(osim) if osim else pamkin.gait2392()


def cmd_urdf(args: argparse.Namespace) -> int:
    from pamkin.human.urdf import build_gait2392  # noqa: PLC0415

    osim = Path(args.osim) if args.osim else DEFAULT_OSIM
    files = build_gait2392(osim, check=args.check, geometry_dir=args.geometry)
    if args.check:
        if files:
            print("stale (regenerate with `pamkin urdf`): " + ", ".join(str(f) for f in files))
            return 1
        print("robot/data/gait2392.yaml, urdf/gait2392.urdf, urdf/pam_biped.urdf and the bone meshes "
              "urdf/meshes/*.stl are up to date")
        return 0
    for f in files:
        print(f"wrote {f}")
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    model = _load(args.osim)
    info = {
        "model": model.osim.name,
        "source": model.osim.path,
        "bodies": model.bodies,
        "coordinates": {c: list(r) for c, r in zip(model.coordinates, model.coordinate_ranges.tolist())},
        "muscles": model.muscles,
        "spanned_pairs": int(len(model.pairs)),
    }
    if args.json:
        print(strict_json(info))
        return 0
    print(f"{info['model']} ({info['source']})")
    print(f"{len(model.bodies)} bodies: {', '.join(model.bodies)}")
    print(f"{len(model.coordinates)} coordinates (range; rotations in degrees, translations in metres):")
    for c, (lo, hi) in info["coordinates"].items():
        if model.osim.coordinate(c).rotational:
            print(f"  {c:20s} [{np.degrees(lo):8.1f}, {np.degrees(hi):8.1f}] deg")
        else:
            print(f"  {c:20s} [{lo:8.3f}, {hi:8.3f}] m")
    spans: dict[int, list[str]] = {}
    for m, c in model.pairs.tolist():
        spans.setdefault(m, []).append(model.coordinates[c])
    print(f"{len(model.muscles)} muscles ({info['spanned_pairs']} muscle-coordinate pairs with a moment arm): "
          "name, kind, max isometric force [N], optimal fibre length [m], tendon slack length [m], "
          "coordinates spanned")
    kw = max([len(m.kind) for m in model.osim.muscles] + [4])
    for i, m in enumerate(model.osim.muscles):
        p = m.params
        num = " ".join(f"{p[k]:8.4g}" if k in p else f"{'-':>8}"
                       for k in ("max_isometric_force", "optimal_fiber_length", "tendon_slack_length"))
        print(f"  {m.name:16s} {m.kind:{kw}s} {num}  {', '.join(spans.get(i, []))}")
    print("JSON (--json): coordinate ranges in radians / metres, as OpenSim stores them")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pamkin",
        description="Design PAM-actuated bipedal robots against OpenSim's Gait2392 human model. "
                    "Without --osim, commands use the built-in Gait2392 data (installed with pamkin). "
                    "Run 'pamkin COMMAND --help' for a command's options and defaults.")
    p.add_argument("--version", action="version", version=f"pamkin {_version()}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("urdf", help="regenerate the built-in data, bone meshes and URDFs from Gait2392's .osim",
                       description="Import OpenSim's Gait2392 .osim, write the project data file "
                                   "robot/data/gait2392.yaml and the bone meshes urdf/meshes/*.stl (from the "
                                   "model's .vtp files, decimated) and render urdf/gait2392.urdf and the robot's "
                                   "urdf/pam_biped.urdf (robot/data/thesis_design.yaml design) with xacro. Needs the "
                                   "OpenSim model files (not part of an installed pamkin).")
    s.add_argument("--osim", metavar="FILE", help=f"the .osim file (default: {DEFAULT_OSIM})")
    s.add_argument("--geometry", metavar="DIR",
                   help="folder of the .vtp bone meshes (default: Geometry/ beside the model, its folder or "
                        "../Geometry, as OpenSim looks)")
    s.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 if the files are stale (default: regenerate them)")
    s.set_defaults(func=cmd_urdf)

    s = sub.add_parser("info", help="list a model's bodies, coordinates (with units) and muscles",
                       description="List a model's bodies, its coordinates with their ranges (degrees for "
                                   "rotations, metres for translations) and its muscles with their main "
                                   "parameters and the coordinates they span.")
    s.add_argument("--osim", metavar="FILE", help="an .osim file (default: the built-in Gait2392)")
    s.add_argument("--json", action="store_true", help="machine-readable output, SI units (default: a table)")
    s.set_defaults(func=cmd_info)

    from pamkin.cli import robot as cli_robot  # noqa: PLC0415
    from pamkin.cli import torques as cli_torques
    from pamkin.cli import visual as cli_visual

    cli_torques.add_parsers(sub)
    cli_robot.add_parsers(sub)
    from pamkin.cli import optimize as cli_optimize  # noqa: PLC0415

    cli_optimize.add_parsers(sub)
    from pamkin.cli import export as cli_export  # noqa: PLC0415

    cli_export.add_parsers(sub)
    cli_visual.add_parsers(sub)
    from pamkin.cli import gait as cli_gait  # noqa: PLC0415

    cli_gait.add_parsers(sub)
    from pamkin.cli import audit as cli_audit  # noqa: PLC0415

    cli_audit.add_parsers(sub)
    from pamkin.cli import build as cli_build  # noqa: PLC0415

    cli_build.add_parsers(sub)
    from pamkin.cli import fit_paths as cli_fit_paths  # noqa: PLC0415

    cli_fit_paths.add_parsers(sub)
    from pamkin.cli import mjcf as cli_mjcf  # noqa: PLC0415

    cli_mjcf.add_parsers(sub)
    from pamkin.cli import simulate as cli_simulate  # noqa: PLC0415

    cli_simulate.add_parsers(sub)
    return p


def _version() -> str:
    from pamkin import __version__  # noqa: PLC0415

    return __version__


def _quiet_broken_pipe() -> int:
    """stdout was closed by the reader (``pamkin ... | head``): leave quietly, as Unix tools do."""
    import os  # noqa: PLC0415

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())   # the interpreter's final flush must not fail again
    except (OSError, ValueError):
        pass
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit code (0 ok, 1 stale/--check, 2 error, 3 infeasible)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code = int(args.func(args) or 0)
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        return _quiet_broken_pipe()
    except PamkinError as e:
        print(f"pamkin {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
