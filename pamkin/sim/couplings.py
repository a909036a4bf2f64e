"""Exact compositions of MuJoCo's degree-4 joint couplings: rich fitting bases and sharp steps.

MuJoCo's ``<equality><joint polycoef>`` ties one joint to a polynomial of degree ≤ 4 of another, but ties
compose exactly: auxiliary joints (on bodies that carry nothing) chained by ties hold polynomials of any degree
the chain builds. Two kinds of chain start from a coordinate's primary joint value v (linear maps are one tie):

* Chebyshev: x ∈ [−1, 1] a linear map of v over the range, then T2(x), T3(x), T4(x).
* Smoothsteps: u = ½ + (v − c)/(2w) (w the larger distance from c to an end of the range, so u ∈ [0, 1]),
  then s(u) = 3u² − 2u³ iterated (fixed points 0, ½, 1; slope 1.5 at ½): a sigmoid centred at c that
  sharpens with every iteration (degree 3^k in v).

A spline (knee translation, moving path point) becomes a least-squares combination of T1..T4 and the 3- and
4-fold smoothsteps at :data:`CENTRES` centres (values and, weighted by :data:`SLOPE_WEIGHT`, slopes: moment arms
are slopes), held by a fixed tendon and a tendon equality. A conditional path point's switch is one sharp
smoothstep at the switch value, exact (to round-off) outside a band around the switch.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev as C

#: smoothstep s(u) = 3u² − 2u³ as MuJoCo polycoef (a0..a4).
SMOOTHSTEP = np.array([0.0, 0.0, 3.0, -2.0, 0.0])
#: Centres of the fitting sigmoids (evenly inside the range) and their smoothstep iterations.
CENTRES = 8
SIGMOID_ITERATIONS = (3, 4)
#: Weight of the slope rows of a fit [units of the primary joint: rad or m].
SLOPE_WEIGHT = 0.05
#: Largest width of a step's band [rad or m of the coordinate]: where it differs from the jump by > STEP_TOL.
STEP_BAND = 2e-3
STEP_TOL = 1e-10

#: An auxiliary joint of a chain: (name suffix, source suffix or "" for the primary joint, polycoef a0..a4).
Aux = tuple[str, str, np.ndarray]


def chebyshev_polycoef(m: int) -> np.ndarray:
    """MuJoCo polycoef (power coefficients a0..a4) of the Chebyshev polynomial T_m, m ≤ 4."""
    c = C.cheb2poly(np.eye(m + 1)[m])
    return np.pad(c, (0, 5 - len(c)))


def linear_polycoef(slope: float, intercept: float) -> np.ndarray:
    """polycoef of intercept + slope·v."""
    return np.array([intercept, slope, 0.0, 0.0, 0.0])


def step_chain(tag: str, centre: float, lo: float, hi: float, iterations: int) -> list[Aux]:
    """Chain of a smoothstep of the primary value v rising at ``centre`` over the range [lo, hi]: u, s1..sk
    (the last one, ``{tag}s{k}``, is the step)."""
    w = max(centre - lo, hi - centre)
    out: list[Aux] = [(f"{tag}u", "", linear_polycoef(1 / (2 * w), 0.5 - centre / (2 * w)))]
    for k in range(1, iterations + 1):
        out.append((f"{tag}s{k}", out[-1][0], SMOOTHSTEP))
    return out


def basis_chain(lo: float, hi: float) -> tuple[list[Aux], list[str]]:
    """Auxiliary joints of the fitting basis of a primary value range [lo, hi], and the names of the basis
    functions (a subset of them)."""
    chain: list[Aux] = [("x", "", linear_polycoef(2 / (hi - lo), -(hi + lo) / (hi - lo)))]
    chain += [(f"T{m}", "x", chebyshev_polycoef(m)) for m in (2, 3, 4)]
    basis = ["x", "T2", "T3", "T4"]
    for i, c in enumerate(np.linspace(lo, hi, CENTRES + 2)[1:-1]):
        chain += step_chain(f"c{i}", float(c), lo, hi, max(SIGMOID_ITERATIONS))
        basis += [f"c{i}s{k}" for k in SIGMOID_ITERATIONS]
    return chain, basis


def chain_values(chain: list[Aux], v: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Values and slopes d/dv of every joint of ``chain`` at primary values v."""
    out = {"": (np.asarray(v, float), np.ones_like(v, dtype=float))}
    for name, src, p in chain:
        x, dx = out[src]
        out[name] = (np.polynomial.polynomial.polyval(x, p),
                     np.polynomial.polynomial.polyval(x, np.polynomial.polynomial.polyder(p)) * dx)
    return out


def composed_fit(chain: list[Aux], basis: list[str], v: np.ndarray, y: np.ndarray,
                 dy: np.ndarray) -> tuple[dict[str, float], float, float]:
    """Least-squares fit of y(v) (slopes dy/dv) in the constant and ``basis`` (values and weighted slopes).

    Returns:
        ``{basis name: coefficient}`` ("" the constant), the largest value and slope deviations on the samples.
    """
    vals = chain_values(chain, v)
    A = np.column_stack([np.ones_like(v)] + [vals[b][0] for b in basis])
    D = np.column_stack([np.zeros_like(v)] + [vals[b][1] for b in basis])
    c, *_ = np.linalg.lstsq(np.vstack([A, SLOPE_WEIGHT * D]), np.concatenate([y, SLOPE_WEIGHT * dy]), rcond=None)
    return (dict(zip(["", *basis], c.tolist())), float(np.max(np.abs(A @ c - y))),
            float(np.max(np.abs(D @ c - dy))))


def smoothstep_iterations(half_width: float, band: float = STEP_BAND, tol: float = STEP_TOL) -> int:
    """Iterations of the smoothstep that make a step of u = ½ + (q − q*)/(2·half_width) differ from the jump
    by more than ``tol`` only within ``band`` of the switch q* (``half_width``: the larger distance from q* to
    an end of the coordinate's range)."""
    d = np.geomspace(1e-9, 0.5, 4000)                  # distance from ½ in u
    u = 0.5 - d
    for k in range(1, 200):
        u = 3 * u**2 - 2 * u**3
        wide = d[u > tol]
        if not len(wide) or 2 * wide.max() * 2 * half_width <= band:
            return k
    raise ValueError(f"no smoothstep iteration count reaches a band of {band} over half width {half_width}")


def smoothstep(u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The k-fold smoothstep of u and its derivative d/du."""
    s = np.asarray(u, float)
    d = np.ones_like(s)
    for _ in range(k):
        d = d * (6 * s - 6 * s**2)
        s = 3 * s**2 - 2 * s**3
    return s, d


__all__ = ["SMOOTHSTEP", "STEP_BAND", "basis_chain", "chain_values", "chebyshev_polycoef", "composed_fit",
           "linear_polycoef", "smoothstep", "smoothstep_iterations", "step_chain"]
