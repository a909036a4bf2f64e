"""Benchmark: pamkin vs OpenSim 4.6 on models with wrap objects (Arm26, Rajagopal2016), same run.

Prints configurations per second for (a) all lengths and (b) lengths + the spanned moment arms, for
pamkin (wrapped paths: lengths as OpenSim computes them, moment arms by central differences) and for
the real OpenSim 4.6 (``benchmarks/opensim_speed.py`` in a child process: ``getLength`` and
``computeMomentArm`` after ``setValue`` + ``realizePosition``), and the ratios.

Goal (issue 10): Rajagopal2016 (b) >= 1000x OpenSim.

Usage: python benchmarks/bench_wrapping.py [--n 400]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT.parent / "shared" / "opensim-models" / "Models"
CASES = {"Arm26": (MODELS / "Arm26" / "arm26.osim", (2000, 400)),
         "Rajagopal2016": (MODELS / "Rajagopal" / "Rajagopal2016.osim", (400, 20))}


def best_rate(fn, n: int, repeats: int = 3) -> float:
    best = 0.0
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = max(best, n / (time.perf_counter() - t))
    return best


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=2000, help="configurations for pamkin (default 2000)")
    args = ap.parse_args()

    import pamkin
    from pamkin.opensim.model_file import SkippedComponentsWarning

    print(f"pamkin on {args.n} random configurations (best of 3); OpenSim 4.6 from Python in a child process")
    print(f"{'model':14s} {'quantity':24s} {'pamkin /s':>11s} {'OpenSim /s':>11s} {'ratio':>8s}   goal")
    for name, (path, (n_len, n_ma)) in CASES.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SkippedComponentsWarning)
            model = pamkin.load_osim(path)
        q = model.random_q(args.n, seed=1)
        model.path_result(q[:10])                 # compile (numba caches to disk)
        rates = {"lengths": best_rate(lambda: model.path_result(q, moment_arms=False), len(q)),  # noqa: B023
                 "lengths_moment_arms": best_rate(lambda: model.path_result(q), len(q))}  # noqa: B023
        with tempfile.TemporaryDirectory() as tmp:
            qfile = Path(tmp) / "q.npy"
            np.save(qfile, q[: max(n_len, n_ma)])
            proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "opensim_speed.py"), str(path),
                                   str(qfile), str(n_len), str(n_ma), "1"], check=False, capture_output=True,
                                  text=True)
            if proc.returncode != 0:
                print(proc.stderr, file=sys.stderr)
                return 1
            osim_rates = json.loads(proc.stdout.strip().splitlines()[-1])
        wrapped = len(model.wrapping.indices) if model.wrapping else 0
        for key, label in (("lengths", "(a) lengths"), ("lengths_moment_arms", "(b) lengths+moment arms")):
            ratio = rates[key] / osim_rates[key]
            goal = ""
            if name == "Rajagopal2016" and key == "lengths_moment_arms":
                goal = f">= 1000x {'met' if ratio >= 1000 else 'NOT met'}"
            print(f"{name:14s} {label:24s} {rates[key]:11,.0f} {osim_rates[key]:11,.1f} {ratio:8,.1f}x   {goal}")
        print(f"{'':14s} ({wrapped} of {len(model.muscles)} paths wrapped, {len(model.pairs)} moment arms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
