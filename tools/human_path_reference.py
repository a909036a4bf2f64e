"""What a PAM on the human muscle's own path would give: the Festo force-length alone against the muscle's.

Usage: python tools/human_path_reference.py [DESIGN_OR_RUN] [--audit RUN/audit.json] [--out FILE.json]

For each actuator of a design (default: the robot's current design), a PAM is put on each of its human
muscles' exact Gait2392 paths in turn (wrapping surfaces, via and moving points included: what a robot
copying the human geometry exactly would have); its diameter (10/20/40 mm), parallel count (1-3), resting
length and tendon are chosen by grid search for the least torque error (primary NRMSE² + the sum of the
squared errors about every coordinate the group crosses, normalised as the audit does) on 400 random poses
of the audit's kind (their own seed), within the optimiser's strain and force limits (contraction <= kmax
and Festo's 25 % less 0.005, stretch <= Festo's limit less 0.005, force per PAM <= 98 % of the rating), at
620 kPa with the v3 model; then graded on the quick audit's 500 random poses (seed 0). Where no PAM meets
the limits on any of the group's paths the actuator is named with its muscle-tendon excursion and length.

Why: the optimiser's routes (straight segments between points within 18 mm of bone) do not copy the
human's wrapping paths; this measures whether copying them would be enough. Printed per actuator next to
the audited NRMSE of the design (``--audit``, e.g. a run folder's audit.json) where given.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

import pamkin
from pamkin.robot import festo
from pamkin.audit.measure import random_poses
from pamkin.robot.design import load_design
from pamkin.robot.biped import robot_skeleton
from pamkin.human.rom import load_rom

PRESSURE = 620e3
MARGIN = 0.005


def _limits(l0: float, d: int) -> tuple[float, float]:
    """(largest contraction, largest stretch) allowed for a PAM of resting length l0 [m], diameter d."""
    c = min(float(festo.kmax(l0, d)), festo.max_contraction(d)) - MARGIN
    return c, festo.max_pretension(d) - MARGIN


def best_pam(L: np.ndarray, R: np.ndarray, T: np.ndarray, prim: int, coords: list[int], fitting: float):
    """Grid search of (diameter, count, resting length, strain at the longest path) for a PAM on a path of
    lengths ``L`` (S,) and moment arms ``R`` (S, C) against the torques ``T`` (S, C): the least
    primary NRMSE² + Σ coordinate errors², or None when no size meets the limits."""
    peak = float(np.abs(T[:, prim]).max())
    best = None
    for d in festo.DIAMETERS_MM:
        lo, hi = festo.nominal_length_range(d)
        for l0 in np.linspace(lo, min(hi, L.max()), 60):
            cmax, smax = _limits(l0, d)
            for emin in np.linspace(-smax, cmax, 40):
                t = L.max() - 2 * fitting - l0 * (1 - emin)
                if t < 0:
                    continue
                eps = (l0 - (L - 2 * fitting - t)) / l0
                if eps.max() > cmax:
                    continue
                F = festo.force(eps, l0, PRESSURE, d)
                if F.max() > 0.98 * festo.F_MAX_THEORETICAL[d]:
                    continue
                for n in (1, 2, 3):
                    err = [np.sqrt(np.mean((n * F * R[:, c] - T[:, c]) ** 2)) / peak for c in coords]
                    J = sum(e * e for e in err) + err[coords.index(prim)] ** 2
                    if best is None or J < best[0]:
                        best = (J, d, n, float(l0), float(t))
    return best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("design", nargs="?", default=None, help="design file, run folder or 'thesis' (default: the robot's)")
    ap.add_argument("--audit", help="an audit.json of the design: its random-pose NRMSE printed alongside")
    ap.add_argument("--out", help="write the per-actuator results here (JSON)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    skel = robot_skeleton()
    des = load_design(args.design, bodies=skel.bodies, coordinates=skel.coordinates) if args.design else \
        load_design(bodies=skel.bodies, coordinates=skel.coordinates)
    human = pamkin.gait2392()
    rom = load_rom(des.rom, "r")
    names = skel.coordinates
    pelvis = {i for i, c in enumerate(names) if c.startswith("pelvis_")}
    audited = {}
    if args.audit:
        audited = {p["id"]: p for p in json.loads(Path(args.audit).read_text())["pams"]}

    def evaluate(q):
        st = human.evaluate(q)
        return st.paths.lengths, st.paths.dense_moment_arms(len(names)), human.torques(q)

    Lf, Rf, Tf = evaluate(random_poses(skel, rom, 400, seed=11))
    Lt, Rt, Tt = evaluate(random_poses(skel, rom, 500, seed=0))
    fit = des.fitting_length_m
    rows = []
    for pam in des.pams:
        idx = [human.muscles.index(m) for m in pam.human_muscles]
        prim = names.index(pam.primary_coordinate)
        Thf, Tht = Tf[:, idx].sum(1), Tt[:, idx].sum(1)
        coords = sorted((set(np.flatnonzero(np.abs(Tht).max(0) > 1e-9)) | {prim}) - pelvis)
        found = [(best_pam(Lf[:, m], Rf[:, m], Thf, prim, coords, fit), m) for m in idx]
        found = [(b, m) for b, m in found if b is not None]
        row = {"id": pam.id, "name": pam.name, "design_nrmse": audited.get(pam.id, {}).get("random_nrmse")}
        if not found:
            m = max(idx, key=lambda i: np.ptp(Lt[:, i]) / Lt[:, i].max())
            row.update(fits=False, path=human.muscles[m], excursion_m=float(np.ptp(Lt[:, m])),
                       longest_m=float(Lt[:, m].max()))
            print(f"{pam.id:3d} {pam.name[:34]:34s} no PAM fits: {human.muscles[m]} changes length by "
                  f"{1e3 * row['excursion_m']:.0f} of {1e3 * row['longest_m']:.0f} mm "
                  f"({100 * row['excursion_m'] / row['longest_m']:.0f} %)", flush=True)
            rows.append(row)
            continue
        (_, d, n, l0, t), m = min(found, key=lambda x: x[0][0])
        eps = (l0 - (Lt[:, m] - 2 * fit - t)) / l0
        tau = (n * festo.force(eps, l0, PRESSURE, d))[:, None] * Rt[:, m]
        peak = float(np.abs(Tht[:, prim]).max())
        err = {names[c]: float(np.sqrt(np.mean((tau[:, c] - Tht[:, c]) ** 2)) / peak) for c in coords}
        worst = max(err, key=err.get)
        row.update(fits=True, path=human.muscles[m], diameter_mm=d, n_parallel=n, resting_length_m=l0,
                   tendon_length_m=t, nrmse=err[pam.primary_coordinate], worst=err[worst], worst_coordinate=worst)
        than = "" if row["design_nrmse"] is None else f" (design {row['design_nrmse']:.3f})"
        print(f"{pam.id:3d} {pam.name[:34]:34s} on {human.muscles[m]:12s} {d} mm x{n}: NRMSE {row['nrmse']:.3f}"
              f"{than}, worst {row['worst']:.3f} about {worst}", flush=True)
        rows.append(row)
    ok = [r for r in rows if r["fits"]]
    h = np.array([r["nrmse"] for r in ok])
    print(f"a PAM fits the human path of {len(ok)} of {len(rows)} actuators; on those, median NRMSE "
          f"{np.median(h):.3f}, {int((h <= 0.15).sum())} <= 0.15"
          + (f"; the design's on the same: median {np.median([r['design_nrmse'] for r in ok]):.3f}, "
             f"{sum(r['design_nrmse'] <= 0.15 for r in ok)} <= 0.15" if audited else ""))
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
