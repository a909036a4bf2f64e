"""Benchmark: fitted path functions (``pamkin fit-paths``) against OpenSim 4.6, same run.

1. Fit: pamkin's fit (exact paths, one QR per coordinate set) beside OpenSim 4.6's ``PolynomialPathFitter``
   (``benchmarks/opensim_path_fitter.py`` in a child process) on the same model, the same coordinate ranges and
   the same number of random poses; fit times and their ratio; both fits' errors against pamkin's exact paths
   (which equal OpenSim's) on the same held-out random poses.
2. Speed: lengths + moment arms of the fitted model (every muscle fitted) in configurations per second, beside
   OpenSim 4.6's exact evaluation of the original model (``benchmarks/opensim_speed.py``) and pamkin's exact one.

Goals (issue "fast paths for wrapped models"): the fitted Rajagopal2016 >= 1000x OpenSim's exact evaluation;
pamkin's fit at least as accurate as OpenSim's and >= 10x faster.

Usage: python benchmarks/bench_fitted_paths.py [--models gait10dof18musc,Rajagopal2016] [--samples 4000]
       [--order 6] [--skip-opensim-fitter] [--table FILE.md]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
from bench_wrapping import best_rate  # the same best-of-n timing as the wrapping benchmark

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT.parent / "shared" / "opensim-models" / "Models"
CASES = {"gait10dof18musc": MODELS / "Gait10dof18musc" / "gait10dof18musc.osim",
         "Rajagopal2016": MODELS / "Rajagopal" / "Rajagopal2016.osim"}


def _load(path):
    import pamkin
    from pamkin.opensim.model_file import SkippedComponentsWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        return pamkin.load_osim(path)


def _errors(exact, fitted, qt, names):
    """Per muscle (length RMS, length max, moment-arm RMS) [mm] of ``fitted`` against ``exact``."""
    a, b = exact.path_result(qt), fitted.path_result(qt)
    Ra, Rb = a.dense_moment_arms(len(exact.coordinates)), b.dense_moment_arms(len(fitted.coordinates))
    out = {}
    for n in names:
        i, j = exact.muscles.index(n), fitted.muscles.index(n)
        e = b.lengths[:, j] - a.lengths[:, i]
        cols = sorted({int(c) for m, c in exact.pairs if m == i})
        er = Rb[:, j, cols] - Ra[:, i, cols]
        out[n] = (1e3 * np.sqrt(np.mean(e ** 2)), 1e3 * np.abs(e).max(), 1e3 * np.sqrt(np.mean(er ** 2)))
    return out


def _summary(label, errs, tol=(0.1, 0.5, 1.0)):
    E = np.array(list(errs.values()))
    within = int(np.sum((E[:, 0] <= tol[0]) & (E[:, 1] <= tol[1]) & (E[:, 2] <= tol[2])))
    return (f"| {label} | {np.median(E[:, 0]):.3f} | {np.median(E[:, 1]):.3f} | {E[:, 1].max():.2f} | "
            f"{np.median(E[:, 2]):.3f} | {within} / {len(E)} |")


def _opensim_fit(path, samples, order, tmp):
    frames = 4
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "opensim_path_fitter.py"), str(path), str(tmp),
                           str(frames), str(samples // frames), str(order)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])["seconds"], Path(tmp) / "fitted.osim"


def _opensim_exact_rate(path, q, n_ma):
    with tempfile.TemporaryDirectory() as tmp:
        np.save(Path(tmp) / "q.npy", q[:n_ma])
        proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "opensim_speed.py"), str(path),
                               str(Path(tmp) / "q.npy"), "1", str(n_ma), "1"], capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(proc.stderr[-2000:])
        return json.loads(proc.stdout.strip().splitlines()[-1])["lengths_moment_arms"]


def bench(name, path, args, lines):
    from pamkin.human.path_fit import fit_paths, uniform_poses
    from pamkin.opensim.function_path_xml import with_function_paths

    model = _load(path)
    fit = fit_paths(model, max_order=args.order, n_samples=args.samples, n_test=args.test)
    qt = uniform_poses(model, args.test, 1)
    with tempfile.TemporaryDirectory() as tmp:
        mine = Path(tmp) / "pamkin_fitted.osim"
        mine.write_text(with_function_paths(path, model.osim, fit.paths(only_passed=False)))
        fitted = _load(mine)
        names = [m.name for m in fit.muscles]
        lines.append(f"\n**{name}** ({len(names)} muscles, {args.samples} fitting poses, {args.test} held-out "
                     f"poses, maximum order {args.order})\n")
        lines.append("| fit | length RMS median [mm] | length max median [mm] | length max worst [mm] | "
                     "moment-arm RMS median [mm] | muscles within 0.1 / 0.5 / 1 mm |")
        lines.append("|---|---|---|---|---|---|")
        lines.append(_summary(f"pamkin ({fit.seconds:.1f} s)", _errors(model, fitted, qt, names)))
        if not args.skip_opensim_fitter:
            secs, theirs = _opensim_fit(path, args.samples, args.order, Path(tmp) / "opensim")
            lines.append(_summary(f"OpenSim PolynomialPathFitter ({secs:.1f} s)",
                                  _errors(model, _load(theirs), qt, names)))
            lines.append(f"\nfit time: pamkin {fit.seconds:.1f} s, OpenSim {secs:.1f} s: "
                         f"{secs / fit.seconds:.1f}x faster (goal >= 10x)")
        q = model.random_q(2000, seed=1)
        fitted.path_result(q[:10])
        r_fit = best_rate(lambda: fitted.path_result(q), len(q))
        r_exact = best_rate(lambda: model.path_result(q), len(q), 1)
        r_osim = _opensim_exact_rate(path, q, 20 if model.wrapping is not None else 200)
        goal = f" (goal >= 1000x: {'met' if r_fit / r_osim >= 1000 else 'NOT met'})" if name == "Rajagopal2016" else ""
        lines.append(f"\nlengths + moment arms [configurations/s]: fitted {r_fit:,.0f}; pamkin exact {r_exact:,.0f}; "
                     f"OpenSim 4.6 exact {r_osim:,.1f}; fitted / OpenSim exact = {r_fit / r_osim:,.0f}x{goal}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", default=",".join(CASES), help=f"comma-separated, of {', '.join(CASES)}")
    ap.add_argument("--samples", type=int, default=4000, help="fitting poses (default 4000)")
    ap.add_argument("--test", type=int, default=1000, help="held-out poses (default 1000)")
    ap.add_argument("--order", type=int, default=6,
                    help="maximum polynomial order of both fits (default 6: the PolynomialPathFitter's default)")
    ap.add_argument("--skip-opensim-fitter", action="store_true", help="time and score only pamkin's fit")
    ap.add_argument("--table", help="also write the Markdown lines to this file")
    args = ap.parse_args()
    lines: list[str] = []
    for name in args.models.split(","):
        bench(name, CASES[name], args, lines)
        print("\n".join(lines), flush=True)
        print("-" * 60)
    if args.table:
        Path(args.table).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
