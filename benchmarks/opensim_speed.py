"""Child-process timing of OpenSim 4.6 on Gait2392 (run by bench_muscles.py; never import with casadi).

Usage: python benchmarks/opensim_speed.py MODEL.osim CONFIGS.npy N_LENGTHS N_MOMENT_ARMS N_FORCES
Prints one JSON line: configurations per second for (a) lengths, (b) lengths + spanned moment arms,
(c) equilibrium tendon forces, each measured on the first N configurations of CONFIGS.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np


def main() -> None:
    import opensim as osim

    osim.Logger.setLevelString("Error")
    path, qfile = sys.argv[1], sys.argv[2]
    n_len, n_ma, n_force = (int(v) for v in sys.argv[3:6])
    q = np.load(qfile)
    model = osim.Model(path)
    state = model.initSystem()
    coords = [model.getCoordinateSet().get(i) for i in range(model.getCoordinateSet().getSize())]
    muscles = [model.getMuscles().get(i) for i in range(model.getMuscles().getSize())]
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1] / "tests"))
    from opensim_ref import _spanned_pairs  # noqa: PLC0415

    pairs = _spanned_pairs(path, model, state)

    def set_q(k):
        for i, c in enumerate(coords):
            c.setValue(state, float(q[k, i]), False)
        model.realizePosition(state)

    out = {}
    t = time.perf_counter()
    for k in range(n_len):
        set_q(k)
        for m in muscles:
            m.getLength(state)
    out["lengths"] = n_len / (time.perf_counter() - t)
    t = time.perf_counter()
    for k in range(n_ma):
        set_q(k)
        for m in muscles:
            m.getLength(state)
        for mi, ci in pairs:
            muscles[mi].computeMomentArm(state, coords[ci])
    out["lengths_moment_arms"] = n_ma / (time.perf_counter() - t)
    for m in muscles:
        m.setActivation(state, 1.0)
    t = time.perf_counter()
    for k in range(n_force):
        set_q(k)
        model.equilibrateMuscles(state)
        model.realizeVelocity(state)
        for m in muscles:
            m.getTendonForce(state)
    out["forces"] = n_force / (time.perf_counter() - t)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
