"""SimmSpline and friends against OpenSim 4.6's own implementation (child process)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pamkin.opensim.functions import LinearFunction, SimmSpline
from pamkin.opensim.model_file import load_osim_file

_SCRIPT = r"""
import json, sys
import opensim as osim
spec = json.load(sys.stdin)
out = []
for s in spec:
    f = osim.SimmSpline()
    for x, y in zip(s["x"], s["y"]):
        f.addPoint(x, y)
    vals, ders = [], []
    for x in s["at"]:
        v = osim.Vector(1, x)
        vals.append(f.calcValue(v))
        d = osim.StdVectorInt(); d.append(0)
        ders.append(f.calcDerivative(d, v))
    out.append({"value": vals, "derivative": ders})
json.dump(out, sys.stdout)
"""


def _opensim_spline(splines):
    proc = subprocess.run([sys.executable, "-c", _SCRIPT], input=json.dumps(splines),
                          capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr)
    return json.loads(proc.stdout)


def _gait2392_splines(path):
    model = load_osim_file(path)
    splines = []
    for j in model.joints:
        splines += [a.function for a in j.axes if isinstance(a.function, SimmSpline)]
    for m in model.muscles:
        for p in m.points:
            splines += [f for f in getattr(p, "functions", ()) if isinstance(f, SimmSpline)]
    return splines


@pytest.mark.opensim
def test_simmspline_matches_opensim(gait2392_path):
    splines = _gait2392_splines(gait2392_path)
    rng = np.random.default_rng(0)
    extra = [SimmSpline((0.0, 1.0, 2.5), (1.0, -2.0, 0.5)), SimmSpline((-1.0, 3.0), (2.0, 4.0)),
             SimmSpline((0.0, 0.1, 0.15, 0.6, 0.7, 2.0), (0.0, 0.3, -0.1, 0.2, 0.25, 1.0))]
    splines = splines + extra
    spec = []
    for s in splines:
        x = np.asarray(s.x)
        mids = (x[:-1] + x[1:]) / 2
        rand = rng.uniform(x[0], x[-1], 40)
        outside = [x[0] - 0.3, x[-1] + 0.3]
        at = np.concatenate([x, mids, rand, outside])
        spec.append({"x": list(s.x), "y": list(s.y), "at": at.tolist()})
    ref = _opensim_spline(spec)
    worst_v = worst_d = 0.0
    for s, sp, r in zip(splines, spec, ref):
        at = np.array(sp["at"])
        worst_v = max(worst_v, np.abs(s.value(at) - np.array(r["value"])).max())
        worst_d = max(worst_d, np.abs(s.derivative(at) - np.array(r["derivative"])).max())
    print(f"{len(splines)} splines: max value error {worst_v:.1e}, max derivative error {worst_d:.1e}")
    assert worst_v <= 1e-12
    assert worst_d <= 1e-12


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=2, max_size=9), st.floats(0.0, 1.0))
def test_simmspline_interpolates_and_derivative_is_consistent(ys, t):
    xs = tuple(float(i) + 0.1 * i * i for i in range(len(ys)))
    s = SimmSpline(xs, tuple(ys))
    assert np.allclose(s.value(np.array(xs)), ys, atol=1e-12)
    x = xs[0] + t * (xs[-1] - xs[0])
    h = 1e-6
    fd = (s.value(np.array(x + h)) - s.value(np.array(x - h))) / (2 * h)
    assert abs(float(s.derivative(np.array(x))) - float(fd)) < 1e-5 * (1 + abs(float(fd)))


def test_linear_function():
    f = LinearFunction(2.0, -1.0)
    assert f.value(np.array([0.0, 1.5])).tolist() == [-1.0, 2.0]
    assert f.derivative(np.array(3.0)) == 2.0
