"""Measure pamkin against OpenSim 4.6 on every shared model file (the README's model table).

For each ``.osim`` under ``../shared/opensim-models/Models/*/`` and the two Gait2392 files: does pamkin
load it (or the reason it refuses), what it holds (joint types, couplers, wrap objects, muscle
classes), and at ``--n`` random configurations within the coordinate ranges (dependent coordinates
from their couplers) the largest differences from OpenSim 4.6:

* body transforms (rotation and translation elements) against ``getTransformInGround``;
* musculotendon lengths against ``getLength``;
* moment arms about every independent, unlocked coordinate a path spans, against central differences
  of OpenSim's own lengths (−∂L/∂q, step 1e-6; pairs where steps 1e-6 and 1e-5 disagree by more than
  1e-6 m straddle a wrap or conditional-point switch and are left out, their share is reported), and
  for models without wrapping or BallJoints also against OpenSim's ``computeMomentArm`` (which is
  −∂L/∂q there; with wrapping it is not, see the README);
* static tendon forces at activation 1 (Thelen2003 and Millard2012 muscles), OpenSim's
  ``computeEquilibrium`` one muscle at a time so that each failure (``MuscleCannotEquilibrate``) is
  recorded: the pairs where OpenSim and pamkin find no equilibrium are compared as sets, the other
  forces relative to max(1 N, |F|).

OpenSim runs in child processes (``tests/opensim_ref.py``, ``tests/millard_ref.py``; opensim and
casadi cannot share a process); results are cached in ``$PAMKIN_OPENSIM_CACHE``.

Usage: python tools/measure_models.py [--n 20] [--json OUT.json] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from millard_ref import opensim_forces  # noqa: E402
from opensim_ref import SHARED, opensim_reference  # noqa: E402

import pamkin  # noqa: E402
from pamkin.errors import EquilibriumWarning, PamkinError  # noqa: E402
from pamkin.opensim.model_file import SkippedComponentsWarning  # noqa: E402

MODELS = SHARED / "opensim-models" / "Models"
GAIT = SHARED / "opensim-models" / "Gait2392_Simbody"
H = 1e-6
FORCE_KINDS = ("Thelen2003Muscle", "Millard2012EquilibriumMuscle")


def model_files() -> list[Path]:
    return sorted(MODELS.glob("*/*.osim")) + sorted(GAIT.glob("*.osim"))


def features(model) -> dict:
    osim = model.osim
    joints = collections.Counter(j.kind for j in osim.joints)
    wraps = {w.wrap_object.name: w.wrap_object.kind for m in osim.muscles for w in m.wraps}
    return {"joints": dict(joints), "couplers": len(osim.couplers),
            "wrap_objects": dict(collections.Counter(wraps.values())),
            "wrapped_paths": sum(1 for m in osim.muscles if m.wraps),
            "muscles": dict(collections.Counter(m.kind for m in osim.muscles)),
            "skipped": len(osim.skipped)}


def measure(path: Path, n: int, seed: int) -> dict:
    out: dict = {"file": str(path.relative_to(SHARED / "opensim-models"))}
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SkippedComponentsWarning)
            model = pamkin.load_osim(path)
    except PamkinError as exc:
        out.update(loads=False, error=type(exc).__name__, reason=str(exc).split(str(path))[-1].strip(": "))
        return out
    out.update(loads=True, **features(model))
    q = model.random_q(n, seed=seed)
    ref = opensim_reference(path, q, ("transforms", "lengths"))
    T = model.body_transforms(q)
    out["transform_error"] = max(
        max(np.abs(T[str(b)][:, :3, :3] - ref["R"][:, i]).max(), np.abs(T[str(b)][:, :3, 3] - ref["p"][:, i]).max())
        for i, b in enumerate(ref["bodies"]))
    if not model.muscles:
        out["seconds"] = time.perf_counter() - t0
        return out
    res = model.path_result(q)
    # OpenSim's getMuscles() lists muscles only; pamkin also has path actuators and springs
    names = [str(m) for m in ref["muscles"]]
    col = np.array([model.muscles.index(m) for m in names], dtype=int)
    os_col = {c: k for k, c in enumerate(col)}
    out["length_error"] = float(np.abs(res.lengths[:, col] - ref["lengths"]).max()) if len(col) else None
    # moment arms: central differences of OpenSim's lengths about independent, unlocked coordinates
    locked = [i for i, c in enumerate(model.osim.coordinates) if c.locked]
    dep = np.flatnonzero(model.kinematics.dependent)
    keep = ~np.isin(res.pairs[:, 1], np.concatenate([locked, dep]).astype(int)) & np.isin(res.pairs[:, 0], col)
    pairs, R = res.pairs[keep], res.moment_arms[:, keep]
    if len(pairs):
        coords = sorted({int(c) for c in pairs[:, 1]})
        Q = []
        for c in coords:
            for step in (H, -H, 10 * H, -10 * H):
                qq = q.copy()
                qq[:, c] += step
                Q.append(model.kinematics.fill_dependent(qq))
        Lr = opensim_reference(path, np.concatenate(Q), ("lengths",))["lengths"].reshape(len(coords), 4, n, -1)
        ci = np.array([coords.index(c) for c in pairs[:, 1]])
        mi = np.array([os_col[int(m)] for m in pairs[:, 0]])
        fd = -(Lr[ci, 0, :, mi] - Lr[ci, 1, :, mi]).T / (2 * H)
        fd10 = -(Lr[ci, 2, :, mi] - Lr[ci, 3, :, mi]).T / (20 * H)
        smooth = np.abs(fd - fd10) < 1e-6
        out["moment_arm_error"] = float(np.abs(R - fd)[smooth].max())
        out["moment_arm_pairs"] = int(len(pairs))
        out["moment_arm_kept"] = float(smooth.mean())
        if not out["wrap_objects"] and "BallJoint" not in out["joints"]:
            # without wrapping OpenSim's computeMomentArm is -dL/dq too: compare with it directly
            mr = opensim_reference(path, q, ("moment_arms",), pairs=np.c_[mi, pairs[:, 1]])["moment_arms"]
            out["moment_arm_error_opensim"] = float(np.abs(R - mr).max())
    # forces
    cols = [i for i, m in enumerate(model.osim.muscles) if m.kind in FORCE_KINDS]
    if cols and len(cols) == len(model.muscles):
        fr = opensim_forces(path, q, 1.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", EquilibriumWarning)
            F = model.tendon_forces(q)
        mine = np.isnan(F)
        out["force_failed_opensim"] = int(fr["failed"].sum())
        out["force_failed_pamkin"] = int(mine.sum())
        out["force_failed_same"] = bool(np.array_equal(mine, fr["failed"]))
        ok = ~fr["failed"] & ~mine
        f_ref = fr["tendon_forces"][ok]
        out["force_rel_error"] = float((np.abs(F[ok] - f_ref) / np.maximum(1.0, np.abs(f_ref))).max()) if ok.any() else None
        out["force_abs_error"] = float(np.abs(F[ok] - f_ref).max()) if ok.any() else None
        out["forces"] = int(F.size)
    else:
        out["forces"] = "paths only: " + ", ".join(sorted({m.kind for m in model.osim.muscles if m.kind not in FORCE_KINDS}))
    out["seconds"] = time.perf_counter() - t0
    return out


def _fmt(x, unit=""):
    return "—" if x is None else f"{x:.1e}{unit}"


def row(r: dict) -> str:
    if not r["loads"]:
        return f"| {r['file']} | refused: {r['error']} — {r['reason']} | | | | | |"
    feats = []
    joints = ", ".join(f"{k.replace('Joint', '')} {v}" for k, v in sorted(r["joints"].items()))
    feats.append(joints)
    if r["couplers"]:
        feats.append(f"{r['couplers']} coupler{'s' if r['couplers'] > 1 else ''}")
    if r["wrap_objects"]:
        feats.append(", ".join(f"{v} {k}" for k, v in sorted(r["wrap_objects"].items())) + f" on {r['wrapped_paths']} paths")
    if r["muscles"]:
        feats.append(", ".join(f"{v} {k}" for k, v in sorted(r["muscles"].items())))
    if r["skipped"]:
        feats.append(f"{r['skipped']} components skipped")
    ma = "—"
    if "moment_arm_error" in r:
        ma = f"{r['moment_arm_error']:.1e} m ({r['moment_arm_kept']:.0%} of {r['moment_arm_pairs']} pairs)"
        if "moment_arm_error_opensim" in r:
            ma = f"{r['moment_arm_error_opensim']:.1e} m; " + ma
    f = r.get("forces")
    if isinstance(f, int):
        fail = (f"; no equilibrium: OpenSim {r['force_failed_opensim']}, pamkin {r['force_failed_pamkin']}"
                f"{' (same)' if r['force_failed_same'] else ' (DIFFERENT)'}") if r["force_failed_opensim"] or r["force_failed_pamkin"] else ""
        force = f"{_fmt(r['force_rel_error'])}{fail}"
    else:
        force = f if f else "—"
    return (f"| {r['file']} | loads | {'; '.join(feats)} | {_fmt(r['transform_error'])} | "
            f"{_fmt(r.get('length_error'), ' m')} | {ma} | {force} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=20, help="random configurations per model (default 20)")
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--json", help="write the measurements here")
    ap.add_argument("--only", nargs="*", help="substrings of the files to measure")
    args = ap.parse_args()
    results = []
    print("| file | import | what it holds | body transforms | lengths | moment arms (−∂L/∂q) | tendon forces (rel.) |")
    print("|---|---|---|---|---|---|---|")
    for path in model_files():
        if args.only and not any(s in str(path) for s in args.only):
            continue
        r = measure(path, args.n, args.seed)
        results.append(r)
        print(row(r), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
