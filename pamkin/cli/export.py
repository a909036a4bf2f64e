"""``pamkin export-osim``: write a robot design as an OpenSim 4.x model."""

from __future__ import annotations

import argparse
import re
from pathlib import Path


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "export-osim", help="write a robot design as an OpenSim 4.x .osim model (PAMs as PathActuators)",
        description="Write the Gait2392 skeleton (bodies with their bone meshes, CustomJoints, coordinates) and "
                    "every PAM of a design, both sides (the left mirrored), as an OpenSim 4.x model: each PAM "
                    "is a PathActuator pamNN_r / pamNN_l whose optimal_force is its maximum force at 620 kPa "
                    "(F620 x n_parallel, divided by k for a PAM on a k:1 pulley block); each roller (cable guide) a "
                    "WrapCylinder on its bone with a PathWrap over its segment. Coordinate ranges are the robot's range of motion (a coupled hip "
                    "adduction limit as its envelope). Point OpenSim at a Geometry folder to see the bones.")
    s.add_argument("design", metavar="DESIGN",
                   help="a design file, 'thesis' (robot/data/thesis_design.yaml) or 'robot' "
                        "(robot/data/thesis_design.yaml)")
    s.add_argument("--out", metavar="FILE", help="output .osim (default: <design name>.osim in the current folder)")
    s.add_argument("--rom", metavar="NAME", help="range of motion in robot/data/rom.yaml for the coordinate "
                                                 "ranges (default: the design's rom)")
    s.set_defaults(func=cmd_export_osim)


def cmd_export_osim(args: argparse.Namespace) -> int:
    from pamkin.human.rom import load_rom  # noqa: PLC0415
    from pamkin.human.urdf import GAIT2392_DATA, load_model_data  # noqa: PLC0415
    from pamkin.robot.design import ROBOT_DESIGN, load_design  # noqa: PLC0415
    from pamkin.robot.osim_export import design_to_osim  # noqa: PLC0415

    skeleton = load_model_data(GAIT2392_DATA)
    src = ROBOT_DESIGN if args.design == "robot" else args.design
    design = load_design(src, bodies=[b.name for b in skeleton.bodies],
                         coordinates=[c.name for c in skeleton.coordinates])
    rom_name = args.rom or design.rom
    rom = load_rom(rom_name, "r")
    out = Path(args.out) if args.out else Path.cwd() / f"{re.sub(r'[^A-Za-z0-9_.-]', '_', design.name)}.osim"
    path = design_to_osim(design, skeleton, out, rom=rom, name=design.name)
    print(f"wrote {path}: {2 * len(design.pams)} PathActuators (design {design.name!r}, both sides), "
          f"{len(skeleton.bodies)} bodies, {len(skeleton.coordinates)} coordinates (ranges: {rom_name}, both sides)")
    return 0
