"""Composed couplings (pamkin.sim.couplings): chains of degree-4 ties against closed forms."""

from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev as C

from pamkin.sim import couplings as cp


def test_chebyshev_chain_composes_exactly():
    chain, basis = cp.basis_chain(-2.0, 0.5)
    v = np.linspace(-2.0, 0.5, 101)
    vals = cp.chain_values(chain, v)
    x = (2 * v + 1.5) / 2.5
    for m in (2, 3, 4):
        assert np.allclose(vals[f"T{m}"][0], C.chebval(x, np.eye(m + 1)[m]), atol=1e-14)
    assert np.allclose(cp.chebyshev_polycoef(3), [0, -3, 0, 4, 0])
    # a sigmoid is the iterated smoothstep of its u; slopes by central differences
    s, ds = cp.smoothstep(0.5 + (v - (-2 + 2.5 / 9)) / (2 * (2.5 - 2.5 / 9)), 4)
    assert np.allclose(vals["c0s4"][0], s, atol=1e-14)
    h = 1e-6
    fd = (cp.chain_values(chain, v + h)["c0s4"][0] - cp.chain_values(chain, v - h)["c0s4"][0]) / (2 * h)
    assert np.allclose(vals["c0s4"][1], fd, atol=1e-7)
    assert len(basis) == 4 + 2 * cp.CENTRES


def test_composed_fit_beats_the_quartic_on_a_kink():
    """|v| smoothed (a kink like the knee spline's near extension): the composed basis fits 10x closer."""
    v = np.linspace(-1, 1, 2001)
    y = np.sqrt(v**2 + 0.01)
    chain, basis = cp.basis_chain(-1, 1)
    _, err, _ = cp.composed_fit(chain, basis, v, y, np.gradient(y, v))
    quartic = np.abs(np.polynomial.polynomial.polyval(v, np.polynomial.polynomial.polyfit(v, y, 4)) - y).max()
    assert err < quartic / 10


def test_smoothstep_step_band():
    """The chosen iteration count makes the step differ from the jump by > 1e-10 only within the band."""
    half = 2.0
    k = cp.smoothstep_iterations(half)
    q = np.linspace(-half, half, 200001)
    s, _ = cp.smoothstep(0.5 + q / (2 * half), k)
    wrong = np.abs(s - (q > 0)) > cp.STEP_TOL
    assert np.ptp(q[wrong]) <= cp.STEP_BAND
    assert s.min() >= 0 and s.max() <= 1
    assert cp.smoothstep_iterations(half) > cp.smoothstep_iterations(half / 10)
