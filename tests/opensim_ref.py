"""Reference numbers from the real OpenSim 4.6, computed in a child process.

``opensim`` and ``casadi`` cannot be imported in one Python process (their
bundled CasADi libraries clash), so the test process never imports
``opensim``. :func:`opensim_reference` runs this file as a script in a child
interpreter, which loads the model, evaluates the requested quantities at the
given configurations and hands back an ``.npz`` file. Results are cached per
(model, configurations, request) in a folder given by ``PAMKIN_OPENSIM_CACHE``
(default: a folder under the system temporary directory).

Script use::

    python tests/opensim_ref.py REQUEST.npz RESULT.npz

REQUEST holds ``osim`` (path), ``q`` (N, n_coordinates) in the model's
CoordinateSet order, ``what`` (list of names) and optionally ``pairs``
(muscle index, coordinate index) for moment arms and ``activation``.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SHARED = HERE.parent.parent / "shared"
GAIT2392 = SHARED / "opensim-models" / "Gait2392_Simbody" / "gait2392_thelen2003muscle.osim"
GAIT2392_MILLARD = SHARED / "opensim-models" / "Gait2392_Simbody" / "gait2392_millard2012muscle.osim"

WHAT_ALL = ("transforms", "lengths", "moment_arms", "tendon_forces")


def opensim_reference(osim: str | os.PathLike, q: np.ndarray, what=WHAT_ALL, pairs=None,
                      activation: float = 1.0, timeout: float = 1800.0) -> dict[str, np.ndarray]:
    """Evaluate ``what`` with OpenSim 4.6 in a child process at configurations ``q``.

    Args:
        osim: Path of the ``.osim`` file.
        q: (N, n_coordinates) coordinate values in the model's CoordinateSet order [rad, m].
        what: Subset of ``("transforms", "lengths", "moment_arms", "tendon_forces")``.
        pairs: (K, 2) int array of (muscle index, coordinate index) for moment arms; by default every
            pair where the muscle's path crosses the coordinate's joint.
        activation: Activation of every muscle for tendon forces.

    Returns:
        ``bodies`` (names), ``coordinates`` (names), ``muscles`` (names), and as requested
        ``R`` (N, n_bodies, 3, 3) and ``p`` (N, n_bodies, 3) body placements in ground,
        ``lengths`` (N, n_muscles) [m], ``pairs`` (K, 2) and ``moment_arms`` (N, K) [m],
        ``tendon_forces``, ``fiber_lengths`` (N, n_muscles) [N, m].
    """
    q = np.ascontiguousarray(np.atleast_2d(np.asarray(q, dtype=float)))
    what = tuple(what)
    h = hashlib.sha256()
    h.update(Path(osim).read_bytes())
    h.update(q.tobytes())
    h.update(repr((what, activation, None if pairs is None else np.asarray(pairs).tolist())).encode())
    h.update(Path(__file__).read_bytes())
    cache = Path(os.environ.get("PAMKIN_OPENSIM_CACHE", Path(tempfile.gettempdir()) / "pamkin-opensim-cache"))
    cache.mkdir(parents=True, exist_ok=True)
    out = cache / f"{h.hexdigest()[:24]}.npz"
    if not out.exists():
        with tempfile.TemporaryDirectory() as tmp:
            req = Path(tmp) / "request.npz"
            kwargs = dict(osim=str(Path(osim).resolve()), q=q, what=np.array(what), activation=activation)
            if pairs is not None:
                kwargs["pairs"] = np.asarray(pairs, dtype=int)
            np.savez(req, **kwargs)
            part = Path(tmp) / "result.npz"
            proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), str(req), str(part)],
                                  capture_output=True, text=True, timeout=timeout)
            if proc.returncode != 0:
                raise RuntimeError(f"OpenSim child process failed:\n{proc.stdout}\n{proc.stderr}")
            os.replace(part, out)
    with np.load(out, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def _spanned_pairs(osim, model, state):
    """(muscle, coordinate) index pairs whose joint lies on the muscle's path."""
    joints = model.getJointSet()
    parent_of = {}
    coord_joint_child = {}
    for j in range(joints.getSize()):
        jt = joints.get(j)
        child = jt.getChildFrame().findBaseFrame().getName()
        parent_of[child] = jt.getParentFrame().findBaseFrame().getName()
        for c in range(jt.numCoordinates()):
            coord_joint_child[jt.get_coordinates(c).getName()] = child

    def ancestors(body):
        out = [body]
        while body in parent_of:
            body = parent_of[body]
            out.append(body)
        return out

    coords = model.getCoordinateSet()
    muscles = model.getMuscles()
    pairs = []
    for m in range(muscles.getSize()):
        pps = muscles.get(m).getGeometryPath().getPathPointSet()
        bodies = {pps.get(i).getParentFrame().findBaseFrame().getName() for i in range(pps.getSize())}
        for c in range(coords.getSize()):
            child = coord_joint_child[coords.get(c).getName()]
            inside = [child in ancestors(b) for b in bodies]
            if any(inside) and not all(inside):
                pairs.append((m, c))
    return np.array(pairs, dtype=int).reshape(-1, 2)


def _main(req_path: str, out_path: str) -> None:
    import opensim as osim  # noqa: PLC0415  (only ever imported in this child process)

    osim.Logger.setLevelString("Error")
    req = np.load(req_path, allow_pickle=False)
    model = osim.Model(str(req["osim"]))
    state = model.initSystem()
    what = [str(w) for w in req["what"]]
    q = req["q"]
    coords = model.getCoordinateSet()
    bodies = model.getBodySet()
    muscles = model.getMuscles()
    nq, nb, nm = coords.getSize(), bodies.getSize(), muscles.getSize()
    if q.shape[1] != nq:
        raise SystemExit(f"q has {q.shape[1]} columns, model has {nq} coordinates")
    out: dict[str, np.ndarray] = {
        "coordinates": np.array([coords.get(i).getName() for i in range(nq)]),
        "bodies": np.array([bodies.get(i).getName() for i in range(nb)]),
        "muscles": np.array([muscles.get(i).getName() for i in range(nm)]),
    }
    n = q.shape[0]
    if "pairs" in req.files:
        pairs = req["pairs"]
    else:
        pairs = _spanned_pairs(req["osim"], model, state)
    if "transforms" in what:
        out["R"] = np.zeros((n, nb, 3, 3))
        out["p"] = np.zeros((n, nb, 3))
    if "lengths" in what:
        out["lengths"] = np.zeros((n, nm))
    if "moment_arms" in what:
        out["pairs"] = pairs
        out["moment_arms"] = np.zeros((n, len(pairs)))
    if "tendon_forces" in what:
        out["tendon_forces"] = np.zeros((n, nm))
        out["fiber_lengths"] = np.zeros((n, nm))
    coord_objs = [coords.get(i) for i in range(nq)]
    muscle_objs = [muscles.get(i) for i in range(nm)]
    for k in range(n):
        for i, c in enumerate(coord_objs):
            c.setValue(state, float(q[k, i]), False)
            c.setSpeedValue(state, 0.0)
        model.realizePosition(state)
        if "transforms" in what:
            for b in range(nb):
                X = bodies.get(b).getTransformInGround(state)
                R, p = X.R(), X.p()
                for i in range(3):
                    out["p"][k, b, i] = p.get(i)
                    for j in range(3):
                        out["R"][k, b, i, j] = R.get(i, j)
        if "lengths" in what:
            for m, mo in enumerate(muscle_objs):
                out["lengths"][k, m] = mo.getLength(state)
        if "moment_arms" in what:
            for r, (m, c) in enumerate(pairs):
                out["moment_arms"][k, r] = muscle_objs[m].computeMomentArm(state, coord_objs[c])
        if "tendon_forces" in what:
            for mo in muscle_objs:
                mo.setActivation(state, float(req["activation"]))
            model.equilibrateMuscles(state)
            model.realizeVelocity(state)
            for m, mo in enumerate(muscle_objs):
                out["tendon_forces"][k, m] = mo.getTendonForce(state)
                out["fiber_lengths"][k, m] = mo.getFiberLength(state)
    np.savez(out_path, **out)


if __name__ == "__main__":
    _main(sys.argv[1], sys.argv[2])
