"""Benchmark: the default attachment-point optimisation (every actuator of the seed design) on the built-in data.

Goals (issue 12): the default run (the optimiser-v2 defaults since 0.1.0-dev) in under 10 minutes on this 2-core
machine (issue 6 asked < 5 minutes of the earlier fast fit, which ``--config examples/optimize_fast.toml``
still runs), and a re-run warm-started from a run in under 2 minutes. Prints wall time, the solve time, the
before/after summary (from the run's summary.json) and the audit figures of the result (``pamkin audit``,
full unless --quick-audit). The warm re-run is timed as a user meets it: ``python -m pamkin optimize
--warm-start RUN`` in a fresh process, with its imports and its quick audits of both designs.

Usage: python benchmarks/bench_optimize.py [--config run.toml] [--out DIR] [--and-warm]
       python benchmarks/bench_optimize.py --warm-start RUN [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

GOAL_SECONDS = 600.0
WARM_GOAL_SECONDS = 120.0


def warm_rerun(run_dir: Path, out: Path, config: str | None) -> float:
    """Time ``python -m pamkin optimize [config] --warm-start run_dir --out out`` (a fresh process) and print
    it against the goal with the quick audit's count of failed limits; returns the wall time [s]."""
    import json
    import subprocess

    cmd = [sys.executable, "-m", "pamkin", "optimize", *([config] if config else []),
           "--warm-start", str(run_dir), "--out", str(out), "--quiet"]
    import os

    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    t = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t
    if done.returncode != 0:
        raise SystemExit(f"warm re-run failed ({' '.join(cmd)}):\n{done.stderr[-2000:]}")
    audit = json.loads((out / "audit.json").read_text())
    print(f"warm re-run from {run_dir}: {wall:.1f} s wall with imports and quick audits "
          f"(goal < {WARM_GOAL_SECONDS:.0f} s: {'met' if wall < WARM_GOAL_SECONDS else 'NOT met'}); "
          f"quick audit: {len(audit['failed'])} limits failed ({', '.join(audit['failed'])}); run folder {out}")
    return wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", help="TOML run description (default: defaults)")
    ap.add_argument("--out", help="run folder (default: a temporary folder)")
    ap.add_argument("--quick-audit", action="store_true", help="audit the result with --quick (default: full)")
    ap.add_argument("--warm-start", metavar="RUN", help="time only a re-run warm-started from RUN (goal < 2 min)")
    ap.add_argument("--and-warm", action="store_true",
                    help="after the default run and its audit, time a re-run warm-started from it (OUT/warm)")
    args = ap.parse_args()
    if args.warm_start:
        out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="pamkin-bench-warm-"))
        warm_rerun(Path(args.warm_start), out, args.config)
        return 0
    from pamkin.optimize.config import load_config
    from pamkin.optimize.pipeline import run

    cfg = load_config(args.config)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="pamkin-bench-"))
    t = time.perf_counter()
    s = run(cfg, out)
    wall = time.perf_counter() - t
    rows = s["actuators"]
    print(f"default optimisation of {len(rows)} actuators, {cfg.workers} workers: {wall:.1f} s wall "
          f"(goal < {GOAL_SECONDS:.0f} s: {'met' if wall < GOAL_SECONDS else 'NOT met'}); solves {s['solve_seconds']} s")
    print(f"median NRMSE {s['median_nrmse_before']:.3f} -> {s['median_nrmse_after']:.3f}; "
          f"{s['n_within_0.20_after']}/{len(rows)} within 0.20; {s['n_halved']} halved; "
          f"all buildable {s['all_buildable']}; all clear of bone {s['all_clear_bone']}; run folder {out}")
    from pamkin.audit.measure import AuditOptions, audit_design

    t = time.perf_counter()
    res = audit_design(out, options=AuditOptions.quick() if args.quick_audit else AuditOptions())
    print(f"audit of the result ({'quick' if args.quick_audit else 'full'}, {time.perf_counter() - t:.0f} s): "
          f"{len(res.failed)} of {sum(1 for c in res.criteria if c['passed'] is not None)} limits failed")
    for c in res.criteria:
        print(f"    {c['name']:42s} {c['value']!s:>22}  {'-' if c['passed'] is None else 'pass' if c['passed'] else 'FAIL'}")
    if args.and_warm:
        warm_rerun(out, out / "warm", args.config)
    return 0


if __name__ == "__main__":
    sys.exit(main())
