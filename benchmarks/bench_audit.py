"""Benchmark of ``pamkin audit`` (goals: full audit < 2 min, ``--quick`` < 30 s on 2 cores).

Usage: ``python benchmarks/bench_audit.py [DESIGN]`` (default: the thesis design). Times one full
and one quick audit in this process after a warm-up (numba kernels compiled and cached), and
prints each phase's time and the ratio to its goal.
"""

from __future__ import annotations

import sys
import time

from pamkin.audit.measure import AuditOptions, audit_design


def run(design: str, options: AuditOptions, label: str, goal: float) -> None:
    t = [time.perf_counter()]
    phases = []

    def progress(msg: str) -> None:
        now = time.perf_counter()
        phases.append((msg, now - t[0]))
        t[0] = now

    t0 = time.perf_counter()
    res = audit_design(design, options=options, progress=progress)
    total = time.perf_counter() - t0
    print(f"{label}: {total:.1f} s (goal < {goal:.0f} s: {'met' if total < goal else 'NOT met'}, "
          f"{total / goal:.2f} of the budget); {res.samples['random_poses']} random poses, "
          f"{res.samples['gait_frames']} gait frames")
    for (msg, _), (_, dt) in zip(phases, phases[1:] + [("end", time.perf_counter() - t[0])]):
        print(f"    {dt:6.1f} s  {msg}")


def main() -> None:
    design = sys.argv[1] if len(sys.argv) > 1 else "thesis"
    audit_design(design, options=AuditOptions.quick(n_random=50, gait_plan=False, n_geometry=5))  # warm-up
    run(design, AuditOptions.quick(), "quick audit", 30.0)
    run(design, AuditOptions(), "full audit", 120.0)


if __name__ == "__main__":
    main()
