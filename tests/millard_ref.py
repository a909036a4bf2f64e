"""Millard2012EquilibriumMuscle reference numbers from the real OpenSim 4.6 (child process).

Same pattern as :mod:`opensim_ref` (the test process never imports ``opensim``; results are
cached per request in ``PAMKIN_OPENSIM_CACHE``), with two requests of its own:

* ``curves``: values and first derivatives of OpenSim's curve objects
  (``ActiveForceLengthCurve`` etc.) built from given properties, at given points;
* ``forces``: per configuration and muscle, the static equilibrium of every muscle computed
  one muscle at a time (``computeEquilibrium``), so that a muscle for which OpenSim raises
  (no equilibrium) is recorded as failed instead of aborting ``Model.equilibrateMuscles``.

Script use::

    python tests/millard_ref.py REQUEST.json RESULT.npz
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

CURVE_CLASSES = ("ActiveForceLengthCurve", "FiberForceLengthCurve", "TendonForceLengthCurve",
                 "FiberCompressiveForceLengthCurve", "FiberCompressiveForceCosPennationCurve")


def _run(request: dict, timeout: float) -> dict[str, np.ndarray]:
    text = json.dumps(request, sort_keys=True)
    # the cache key holds the model file's content, not its path (tests write models to tmp folders)
    h = hashlib.sha256(json.dumps({k: v for k, v in request.items() if k != "osim"}, sort_keys=True).encode())
    h.update(Path(__file__).read_bytes())
    if "osim" in request:
        h.update(Path(request["osim"]).read_bytes())
    cache = Path(os.environ.get("PAMKIN_OPENSIM_CACHE", Path(tempfile.gettempdir()) / "pamkin-opensim-cache"))
    cache.mkdir(parents=True, exist_ok=True)
    out = cache / f"millard-{h.hexdigest()[:24]}.npz"
    if not out.exists():
        with tempfile.TemporaryDirectory() as tmp:
            req = Path(tmp) / "request.json"
            req.write_text(text)
            part = Path(tmp) / "result.npz"
            proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), str(req), str(part)],
                                  check=False, capture_output=True, text=True, timeout=timeout)
            if proc.returncode != 0:
                raise RuntimeError(f"OpenSim child process failed:\n{proc.stdout}\n{proc.stderr}")
            os.replace(part, out)
    with np.load(out, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def opensim_curves(specs: list[tuple[str, dict]], x, timeout: float = 600.0) -> dict[str, np.ndarray]:
    """OpenSim's value and derivative of each curve at points ``x``.

    Args:
        specs: ``(class name, {property: value})`` per curve (absent properties: OpenSim defaults).
        x: Points, 1-D.

    Returns:
        ``value`` and ``derivative``, each (n_curves, len(x)).
    """
    return _run({"kind": "curves", "specs": [[c, dict(p)] for c, p in specs],
                 "x": np.asarray(x, float).tolist()}, timeout)


def opensim_forces(osim, q, activation, timeout: float = 1800.0) -> dict[str, np.ndarray]:
    """Lengths and static equilibrium of every muscle of ``osim`` at configurations ``q``.

    Args:
        osim: The ``.osim`` file.
        q: (N, n_coordinates) in CoordinateSet order.
        activation: Scalar, or (N, n_muscles) activations.

    Returns:
        ``muscles`` (names), ``lengths``, ``tendon_forces``, ``fiber_lengths`` (N, n_muscles) and
        ``failed`` (N, n_muscles) bool: OpenSim raised while equilibrating that muscle (its force
        and fibre length are NaN then).
    """
    q = np.atleast_2d(np.asarray(q, float))
    return _run({"kind": "forces", "osim": str(Path(osim).resolve()), "q": q.tolist(),
                 "activation": np.asarray(activation, float).tolist()}, timeout)


def _curves(osim, req) -> dict[str, np.ndarray]:
    x = np.asarray(req["x"], float)
    vals, ders = [], []
    for cls, props in req["specs"]:
        curve = getattr(osim, cls)()
        for key, value in props.items():
            getattr(curve, f"set_{key}")(float(value))
        curve.ensureCurveUpToDate()
        vals.append([curve.calcValue(float(v)) for v in x])
        ders.append([curve.calcDerivative(float(v), 1) for v in x])
    return {"value": np.array(vals), "derivative": np.array(ders)}


def _forces(osim, req) -> dict[str, np.ndarray]:
    model = osim.Model(req["osim"])
    state = model.initSystem()
    q = np.asarray(req["q"], float)
    coords = model.getCoordinateSet()
    muscles = model.getMuscles()
    nq, nm, n = coords.getSize(), muscles.getSize(), q.shape[0]
    act = np.broadcast_to(np.asarray(req["activation"], float), (n, nm))
    mus = [osim.Millard2012EquilibriumMuscle.safeDownCast(muscles.get(i)) or muscles.get(i) for i in range(nm)]
    out = {"muscles": np.array([m.getName() for m in mus]), "lengths": np.zeros((n, nm)),
           "tendon_forces": np.full((n, nm), np.nan), "fiber_lengths": np.full((n, nm), np.nan),
           "failed": np.zeros((n, nm), bool)}
    c_objs = [coords.get(i) for i in range(nq)]
    for k in range(n):
        for i, c in enumerate(c_objs):
            c.setValue(state, float(q[k, i]), False)
            c.setSpeedValue(state, 0.0)
        model.realizePosition(state)
        for j, m in enumerate(mus):
            m.setActivation(state, float(act[k, j]))
        for j, m in enumerate(mus):
            out["lengths"][k, j] = m.getLength(state)
            try:
                m.computeEquilibrium(state)
            except Exception:  # noqa: BLE001  (OpenSim: MuscleCannotEquilibrate)
                out["failed"][k, j] = True
        model.realizeVelocity(state)
        for j, m in enumerate(mus):
            if out["failed"][k, j]:
                continue
            try:
                out["tendon_forces"][k, j] = m.getTendonForce(state)
                out["fiber_lengths"][k, j] = m.getFiberLength(state)
            except Exception:  # noqa: BLE001
                out["failed"][k, j] = True
    return out


def _main(req_path: str, out_path: str) -> None:
    import opensim as osim  # noqa: PLC0415  (only ever imported in this child process)

    osim.Logger.setLevelString("Off")
    req = json.loads(Path(req_path).read_text())
    result = _curves(osim, req) if req["kind"] == "curves" else _forces(osim, req)
    np.savez(out_path, **result)


if __name__ == "__main__":
    _main(sys.argv[1], sys.argv[2])
