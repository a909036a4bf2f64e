"""``pamkin mjcf``: an OpenSim model or a robot design as a MuJoCo model (MJCF + meshes), measured."""

from __future__ import annotations

import argparse
import re
from pathlib import Path


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "mjcf", help="write a MuJoCo model (MJCF + bone meshes) of an OpenSim model or a robot design",
        description="Convert an OpenSim model (default: the built-in Gait2392) or a robot design (both sides, "
                    "PAM routes as tendons) to a MuJoCo model: bodies with the model's masses and inertias, one "
                    "hinge or slide per variable joint axis, spline axes and moving path points as slide/hinge "
                    "joints tied to their coordinate's joint (--couplings), muscles or PAM routes as spatial "
                    "tendons through sites, wrap cylinders and spheres as wrap geoms (ellipsoids: a sphere or "
                    "cylinder; conditional path points with a fixed neighbour on their body: a site sliding onto "
                    "it by a sharp step of the coordinate (composed), else always, never or a small wrap geom "
                    "through the point, whichever fits pamkin's lengths best on 300 fit poses). Writes model.xml, meshes/*.stl and "
                    "conversion.json; with --measure N also errors.csv, errors.png and errors.json: tendon "
                    "lengths and moment arms against pamkin's on N held-out random poses.")
    src = s.add_mutually_exclusive_group()
    src.add_argument("--osim", metavar="FILE", help="an .osim model (default: the built-in Gait2392)")
    src.add_argument("--design", metavar="NAME|FILE",
                     help="a robot design: a design file, 'thesis' or 'robot' (robot/data/thesis_design.yaml) "
                          "(default: none; the --osim model is converted)")
    s.add_argument("--geometry", metavar="DIR", help="folder of the .vtp bone meshes (default: found beside the "
                                                     "model, else pamkin's built-in Gait2392 meshes)")
    s.add_argument("--out", metavar="DIR", help="output folder (default: <model name>_mjcf in the current folder)")
    s.add_argument("--force", action="store_true", help="replace an existing output folder whole (default: refuse)")
    s.add_argument("--measure", type=int, default=0, metavar="N",
                   help="measure lengths and moment arms against pamkin on N random poses (default 0: no)")
    s.add_argument("--seed", type=int, default=None, help="seed of the measurement poses (default 2026)")
    s.add_argument("--couplings", choices=("composed", "quartic"), default="composed",
                   help="composed (default): splines as least-squares sums of auxiliary joints chained by exact "
                        "degree-4 ties, conditional path points as sharp smoothstep slides; quartic: one degree-4 "
                        "joint equality per spline, conditional points always/never/a small wrap geom")
    s.set_defaults(func=cmd_mjcf)


def cmd_mjcf(args: argparse.Namespace) -> int:
    from pamkin.errors import ParameterError  # noqa: PLC0415
    from pamkin.outputs import check_output_folder  # noqa: PLC0415
    from pamkin.sim import convert as sc  # noqa: PLC0415
    from pamkin.sim import measure as sm  # noqa: PLC0415
    from pamkin.sim.files import write_conversion  # noqa: PLC0415

    if args.measure < 0:
        raise ParameterError(f"--measure must be >= 0 poses, got {args.measure}")
    conv = None
    if args.out:
        out = Path(args.out)
        check_output_folder(out, args.force)               # before any work
    if args.design:
        from pamkin.robot.biped import design_robot  # noqa: PLC0415

        robot = design_robot(None if args.design == "robot" else args.design)
        conv = sc.convert_robot(robot, couplings=args.couplings)
    else:
        import pamkin  # noqa: PLC0415

        model = pamkin.load_osim(args.osim) if args.osim else pamkin.gait2392()
        conv = sc.convert_model(model, geometry=args.geometry, couplings=args.couplings)
    if not args.out:
        out = Path.cwd() / f"{re.sub(r'[^A-Za-z0-9_.-]', '_', conv.name)}_mjcf"
        check_output_folder(out, args.force)
    errors = sm.measure(conv, args.measure, sm.MEASURE_SEED if args.seed is None else args.seed) \
        if args.measure else None
    write_conversion(conv, out, args.force, errors, args.measure)
    m = conv.compile()
    print(f"wrote {out}/model.xml: {m.nbody - 1} bodies, {m.njnt} joints ({sum(not j.primary for j in conv.cmap.joints)} "
          f"tied by polynomials, {len(conv.cmap.aux_bodies)} of them auxiliary), {m.ntendon} tendons, {len(conv.meshes)} meshes; converted in {conv.seconds:.2f} s")
    if errors is not None:
        s = sm.summary(errors, sm.exact_constructs(conv))
        print(f"measured on {args.measure} poses: {s['exact']}/{s['paths']} paths with exact constructs (largest error "
              f"{s['exact_length_max_m']:.1e} m length, {s['exact_arm_max_m']:.1e} m moment arm); "
              f"{s['length_within_goal']} within 0.5 mm length, {s['arm_within_goal']} within 1 mm moment arm "
              f"(p99: {s['arm_p99_within_goal']}); worst {s['length_max_m'] * 1e3:.2f} mm length, "
              f"{s['arm_max_m'] * 1e3:.2f} mm moment arm (errors.csv, errors.png)")
        if s["band_poses"]:
            print(f"outside the conditional steps' bands ({s['band_poses']} path-poses inside them): "
                  f"{s['length_within_goal_outside_bands']} within 0.5 mm length, "
                  f"{s['arm_within_goal_outside_bands']} within 1 mm moment arm")
    return 0
