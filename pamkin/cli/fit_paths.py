"""``pamkin fit-paths``: polynomial path functions (OpenSim FunctionBasedPaths) fitted from exact paths."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "fit-paths", help="fit polynomial path functions to a model's muscles; write an .osim with FunctionBasedPaths",
        description="Fit each muscle's length as a multivariate polynomial of the independent coordinates it spans "
                    "(OpenSim's MultivariatePolynomialFunction), by least squares on pamkin's exact lengths and "
                    "moment arms (wrapping included) at random poses uniform over the coordinate ranges; the order "
                    "rises until the muscle meets the tolerance on validation poses, and its errors are measured on "
                    "held-out poses neither the fit nor that choice saw. Writes the "
                    "model with a FunctionBasedPath in place of each fitted GeometryPath (OpenSim 4.6 loads and "
                    "simulates it). If a muscle misses the tolerance, its name and errors are printed and nothing "
                    "is written (exit 1) unless --keep-unfitted keeps its exact path.")
    s.add_argument("osim", metavar="MODEL", help="an .osim file (OpenSim 4.x)")
    s.add_argument("--out", metavar="FILE",
                   help="the fitted model (default: <MODEL stem>_fitted.osim in the current folder)")
    s.add_argument("--report", metavar="DIR", help="folder for errors.csv, errors.md, errors.png and fit.json, "
                                                   "written whole (refused if it holds files unless --force; "
                                                   "default: no report)")
    s.add_argument("--force", action="store_true", help="replace an existing --report folder (default: refuse)")
    s.add_argument("--muscles", metavar="A,B,...", help="fit only these muscles (default: every muscle with points)")
    s.add_argument("--max-order", type=int, default=8, help="highest polynomial order tried (1-12, default 8)")
    s.add_argument("--samples", type=int, default=4000, help="random fitting poses (100-200000, default 4000)")
    s.add_argument("--test-poses", type=int, default=1000, help="held-out random poses, and as many validation poses (10-200000, default 1000)")
    s.add_argument("--rom", metavar="NAME", help="draw the poses from this range of motion of robot/data/rom.yaml "
                                                 "(robot_thesis, robot_2026, human_thesis; side-less names apply "
                                                 "to both legs) (default: the model's coordinate ranges)")
    s.add_argument("--seed", type=int, default=0, help="seed of the fitting poses (held-out: seed + 1, validation: seed + 2; "
                                                            "default 0)")
    s.add_argument("--length-rms", type=float, default=0.1, help="tolerance: length RMS [mm] (default 0.1)")
    s.add_argument("--length-max", type=float, default=0.5, help="tolerance: largest length error [mm] (default 0.5)")
    s.add_argument("--moment-arm-rms", type=float, default=1.0, help="tolerance: moment-arm RMS [mm] (default 1)")
    s.add_argument("--keep-unfitted", action="store_true",
                   help="write the model anyway, muscles that miss the tolerance keeping their exact GeometryPath "
                        "(default: write nothing and exit 1)")
    s.set_defaults(func=cmd_fit_paths)


def _check(args: argparse.Namespace) -> None:
    from pamkin.errors import ParameterError  # noqa: PLC0415

    for name, lo, hi in (("max_order", 1, 12), ("samples", 100, 200_000), ("test_poses", 10, 200_000)):
        v = getattr(args, name)
        if not lo <= v <= hi:
            raise ParameterError(f"--{name.replace('_', '-')} must lie in [{lo}, {hi}], got {v}")
    for name in ("length_rms", "length_max", "moment_arm_rms"):
        v = getattr(args, name)
        if not 0 < v < 1000:
            raise ParameterError(f"--{name.replace('_', '-')} must be a positive number of millimetres "
                                 f"below 1000, got {v}")


def cmd_fit_paths(args: argparse.Namespace) -> int:
    import pamkin  # noqa: PLC0415
    from pamkin.errors import ParameterError  # noqa: PLC0415
    from pamkin.human.path_fit import FitTolerance, fit_paths  # noqa: PLC0415
    from pamkin.opensim.function_path_xml import with_function_paths  # noqa: PLC0415
    from pamkin.outputs import check_output_file, check_output_folder, output_folder, write_file  # noqa: PLC0415
    from pamkin.viz.path_fit_report import write_report  # noqa: PLC0415

    _check(args)
    out = Path(args.out) if args.out else Path.cwd() / f"{Path(args.osim).stem}_fitted.osim"
    check_output_file(out)                              # before any work
    if out.exists() and Path(args.osim).exists() and out.resolve() == Path(args.osim).resolve():
        raise ParameterError(f"--out {out} is the model file itself: the fitted model is written beside it, "
                             "never over it")
    if args.report:
        check_output_folder(args.report, args.force)
    model = pamkin.load_osim(args.osim)
    muscles = [m.strip() for m in args.muscles.split(",") if m.strip()] if args.muscles else None
    if muscles:
        unknown = [m for m in muscles if m not in model.muscles]
        if unknown:
            raise ParameterError(f"--muscles: {args.osim} has no muscle {', '.join(map(repr, unknown))}")
    tol = FitTolerance(args.length_rms * 1e-3, args.length_max * 1e-3, args.moment_arm_rms * 1e-3)
    rom = ()
    if args.rom:
        from pamkin.human.rom import load_rom  # noqa: PLC0415

        rom = (load_rom(args.rom, "r"), load_rom(args.rom, "l"))
    fit = fit_paths(model, muscles, args.max_order, args.samples, args.test_poses, tol, args.seed, rom=rom)
    if not fit.muscles:
        raise ParameterError(f"{args.osim}: no muscle path to fit (muscles with points that span a coordinate: "
                             f"none{'; spanning none: ' + ', '.join(fit.skipped) if fit.skipped else ''})")
    print(f"fitted {len(fit.muscles)} muscles in {fit.seconds:.1f} s ({fit.n_samples} fitting poses, "
          f"{fit.n_test} held-out, over {fit.ranges}); within tolerance: {len(fit.muscles) - len(fit.missed)}")
    if args.report:
        with output_folder(args.report, args.force) as tmp:
            write_report(fit, tmp, title=f"{model.osim.name}: fitted path errors")
        print(f"wrote {args.report}/errors.csv, errors.md, errors.png, fit.json")
    for m in fit.missed:
        print(f"  misses: {m.name}: order {m.order}, length RMS {1e3 * m.length_rms:.3f} mm, max "
              f"{1e3 * m.length_max:.3f} mm, moment-arm RMS {1e3 * m.moment_arm_rms:.3f} mm")
    if fit.missed and not args.keep_unfitted:
        print(f"{len(fit.missed)} muscle(s) miss the tolerance: nothing written (--keep-unfitted keeps their "
              "exact paths)")
        return 1
    paths = fit.paths(only_passed=True)
    write_file(out, with_function_paths(args.osim, model.osim, paths))
    kept = f"; {len(fit.missed)} keep their GeometryPath" if fit.missed else ""
    print(f"wrote {out}: {len(paths)} FunctionBasedPaths{kept}")
    return 0
