"""OpenSim scalar functions of one variable, evaluated exactly as OpenSim 4.6 does.

Used for CustomJoint ``TransformAxis`` functions (e.g. Gait2392's knee translations
as functions of knee angle) and for ``MovingPathPoint`` locations.

Every function evaluates vectorized over numpy arrays and returns value and first
derivative. :class:`SimmSpline` reproduces OpenSim's ``SimmSpline`` (natural cubic
spline with third derivatives at the ends taken from divided differences; linear
extrapolation with the end slopes outside the knots; a 2-point spline is a line).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

_TINY = 1e-7  # OpenSim's TINY_NUMBER: smallest knot spacing used in the fit.
_ROUNDOFF = 2e-13  # OpenSim's ROUNDOFF_ERROR: "equal to an end knot" tolerance.


class ScalarFunction(Protocol):
    """A function y = f(x) of one variable, vectorized."""

    def value(self, x: np.ndarray) -> np.ndarray:
        """f(x), same shape as ``x``."""

    def derivative(self, x: np.ndarray) -> np.ndarray:
        """df/dx, same shape as ``x``."""

    @property
    def is_constant(self) -> bool:
        """True when f does not depend on x."""


@dataclass(frozen=True)
class Constant:
    """``Constant``: f(x) = c."""

    c: float

    def value(self, x: np.ndarray) -> np.ndarray:
        return np.full(np.shape(x), self.c, dtype=float)

    def derivative(self, x: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(x), dtype=float)

    @property
    def is_constant(self) -> bool:
        return True


@dataclass(frozen=True)
class LinearFunction:
    """``LinearFunction``: f(x) = slope·x + intercept (OpenSim ``coefficients`` = slope, intercept)."""

    slope: float
    intercept: float

    def value(self, x: np.ndarray) -> np.ndarray:
        return self.slope * np.asarray(x, dtype=float) + self.intercept

    def derivative(self, x: np.ndarray) -> np.ndarray:
        return np.full(np.shape(x), self.slope, dtype=float)

    @property
    def is_constant(self) -> bool:
        return self.slope == 0.0


@dataclass(frozen=True)
class PolynomialFunction:
    """``PolynomialFunction``: coefficients highest power first (OpenSim's convention)."""

    coefficients: tuple[float, ...]

    def value(self, x: np.ndarray) -> np.ndarray:
        return np.polyval(np.asarray(self.coefficients, dtype=float), np.asarray(x, dtype=float))

    def derivative(self, x: np.ndarray) -> np.ndarray:
        d = np.polyder(np.asarray(self.coefficients, dtype=float))
        return np.polyval(d, np.asarray(x, dtype=float)) * np.ones(np.shape(x))

    @property
    def is_constant(self) -> bool:
        return all(c == 0.0 for c in self.coefficients[:-1])


@dataclass(frozen=True)
class MultiplierFunction:
    """``MultiplierFunction``: f(x) = scale · g(x) (OpenSim's scaled models use it)."""

    function: ScalarFunction
    scale: float

    def value(self, x: np.ndarray) -> np.ndarray:
        return self.scale * self.function.value(x)

    def derivative(self, x: np.ndarray) -> np.ndarray:
        return self.scale * self.function.derivative(x)

    @property
    def is_constant(self) -> bool:
        return self.function.is_constant or self.scale == 0.0


@dataclass(frozen=True)
class SimmSpline:
    """OpenSim's ``SimmSpline`` natural cubic spline through knots (x, y).

    Attributes:
        x: Knot abscissae, increasing, at least 2.
        y: Knot ordinates.
    """

    x: tuple[float, ...]
    y: tuple[float, ...]
    _coef: tuple[np.ndarray, np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.x) != len(self.y):
            raise ValueError(f"SimmSpline: {len(self.x)} x values but {len(self.y)} y values")
        if len(self.x) < 2:
            raise ValueError("SimmSpline: needs at least 2 knots")
        object.__setattr__(self, "_coef", _simm_coefficients(np.asarray(self.x, float),
                                                             np.asarray(self.y, float)))

    def _segment(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xs = np.asarray(self.x, dtype=float)
        k = np.clip(np.searchsorted(xs, x, side="left") - 1, 0, len(xs) - 2)
        return k, x - xs[k]

    def value(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        xs, ys = np.asarray(self.x, float), np.asarray(self.y, float)
        b, c, d = self._coef
        k, dx = self._segment(x)
        out = ys[k] + dx * (b[k] + dx * (c[k] + dx * d[k]))
        # OpenSim's order of checks: outside the knots first, then "equal to an end knot"
        out = np.where(np.abs(x - xs[-1]) <= _ROUNDOFF, ys[-1], out)
        out = np.where(np.abs(x - xs[0]) <= _ROUNDOFF, ys[0], out)
        out = np.where(x > xs[-1], ys[-1] + (x - xs[-1]) * b[-1], out)
        out = np.where(x < xs[0], ys[0] + (x - xs[0]) * b[0], out)
        return out

    def derivative(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        xs = np.asarray(self.x, float)
        b, c, d = self._coef
        k, dx = self._segment(x)
        out = b[k] + dx * (2.0 * c[k] + 3.0 * dx * d[k])
        out = np.where(np.abs(x - xs[-1]) <= _ROUNDOFF, b[-1], out)
        out = np.where(np.abs(x - xs[0]) <= _ROUNDOFF, b[0], out)
        out = np.where(x > xs[-1], b[-1], out)
        out = np.where(x < xs[0], b[0], out)
        return out

    @property
    def is_constant(self) -> bool:
        return len(set(self.y)) == 1

    @property
    def coefficients(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Segment polynomial coefficients (b, c, d): y = y_k + b·dx + c·dx² + d·dx³."""
        return self._coef


def _simm_coefficients(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Polynomial coefficients b, c, d of each segment: y_k + b·dx + c·dx² + d·dx³.

    Same algorithm as OpenSim's ``SimmSpline::calcCoefficients`` (tridiagonal system
    with end conditions from third divided differences; Forsythe, Malcolm & Moler).
    """
    n = len(x)
    b, c, d = np.zeros(n), np.zeros(n), np.zeros(n)
    if n == 2:
        t = max(_TINY, x[1] - x[0])
        b[:] = (y[1] - y[0]) / t
        return b, c, d
    nm1, nm2 = n - 1, n - 2
    d[0] = max(_TINY, x[1] - x[0])
    c[1] = (y[1] - y[0]) / d[0]
    for i in range(1, nm1):
        d[i] = max(_TINY, x[i + 1] - x[i])
        b[i] = 2.0 * (d[i - 1] + d[i])
        c[i + 1] = (y[i + 1] - y[i]) / d[i]
        c[i] = c[i + 1] - c[i]
    b[0] = -d[0]
    b[nm1] = -d[nm2]
    c[0] = 0.0
    c[nm1] = 0.0
    if n > 3:
        d31 = max(_TINY, x[3] - x[1])
        d20 = max(_TINY, x[2] - x[0])
        d1 = max(_TINY, x[nm1] - x[n - 3])
        d2 = max(_TINY, x[nm2] - x[n - 4])
        d30 = max(_TINY, x[3] - x[0])
        d3 = max(_TINY, x[nm1] - x[n - 4])
        c[0] = c[2] / d31 - c[1] / d20
        c[nm1] = c[nm2] / d1 - c[n - 3] / d2
        c[0] = c[0] * d[0] * d[0] / d30
        c[nm1] = -c[nm1] * d[nm2] * d[nm2] / d3
    for i in range(1, n):
        t = d[i - 1] / b[i - 1]
        b[i] -= t * d[i - 1]
        c[i] -= t * c[i - 1]
    c[nm1] /= b[nm1]
    for i in range(nm2, -1, -1):
        c[i] = (c[i] - d[i] * c[i + 1]) / b[i]
    b[nm1] = (y[nm1] - y[nm2]) / d[nm2] + d[nm2] * (c[nm2] + 2.0 * c[nm1])
    for i in range(nm1):
        b[i] = (y[i + 1] - y[i]) / d[i] - d[i] * (c[i + 1] + 2.0 * c[i])
        d[i] = (c[i + 1] - c[i]) / d[i]
        c[i] *= 3.0
    c[nm1] *= 3.0
    d[nm1] = d[nm2]
    return b, c, d


def polynomial_exponents(dimension: int, order: int) -> np.ndarray:
    """Exponents of OpenSim's ``MultivariatePolynomialFunction`` terms, in its coefficient order.

    Ascending powers starting from the last variable: for (X, Y, Z) and order 3 the terms are
    1, Z, Z², Z³, Y, YZ, YZ², Y², Y²Z, Y³, X, XZ, ... X³ (OpenSim's documented table).

    Returns: (n_terms, dimension) integer exponents; n_terms = C(dimension + order, order).
    """
    if dimension < 1 or order < 0:
        raise ValueError(f"polynomial needs dimension >= 1 and order >= 0, not {dimension}, {order}")

    def terms(n: int, p: int):
        if n == 0:
            yield ()
            return
        for e in range(p + 1):
            for rest in terms(n - 1, p - e):
                yield (e,) + rest

    return np.array(list(terms(dimension, order)), dtype=np.int64).reshape(-1, dimension)


def monomial_table(x: np.ndarray, exponents: np.ndarray,
                   derivatives: bool = True) -> tuple[np.ndarray, list[np.ndarray]]:
    """Monomials Π x_i^e_ki at (N, d) points -> (N, n_terms), and their derivatives along each variable.

    The one definition of a polynomial's terms: :class:`MultivariatePolynomial`, the batched evaluation of
    function-based paths (:mod:`pamkin.human.function_paths`) and the path fitter use it.

    Returns:
        (T, D): T (N, n_terms); D a list of d arrays (N, n_terms), ∂T/∂x_i (empty without ``derivatives``).
    """
    x = np.asarray(x, dtype=float).reshape(len(x), -1)
    order = int(exponents.max(initial=0))
    P = np.ones((x.shape[0], x.shape[1], order + 1))
    for p in range(1, order + 1):
        P[:, :, p] = P[:, :, p - 1] * x

    def product(e: np.ndarray) -> np.ndarray:
        out = P[:, 0, e[:, 0]]
        for i in range(1, x.shape[1]):
            out = out * P[:, i, e[:, i]]
        return out

    D = []
    for i in range(x.shape[1] if derivatives else 0):
        e = exponents.copy()
        e[:, i] = np.maximum(e[:, i] - 1, 0)
        D.append(product(e) * exponents[:, i])
    return product(exponents), D


@dataclass(frozen=True)
class MultivariatePolynomial:
    """OpenSim's ``MultivariatePolynomialFunction``: f(x₁ … x_d) = Σ c_k Π x_i^e_ki.

    Attributes:
        dimension: Number of variables d.
        order: Largest sum of exponents in one term.
        coefficients: One per term, in OpenSim's order (:func:`polynomial_exponents`).
    """

    dimension: int
    order: int
    coefficients: tuple[float, ...]
    _exp: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        exp = polynomial_exponents(self.dimension, self.order)
        if len(self.coefficients) != len(exp):
            raise ValueError(f"MultivariatePolynomialFunction of dimension {self.dimension} and order "
                             f"{self.order} needs {len(exp)} coefficients, has {len(self.coefficients)}")
        object.__setattr__(self, "_exp", exp)

    @property
    def exponents(self) -> np.ndarray:
        """(n_terms, dimension) exponents of the terms."""
        return self._exp

    def value(self, x: np.ndarray) -> np.ndarray:
        """f at (N, d) points -> (N,)."""
        T, _ = monomial_table(np.asarray(x, dtype=float).reshape(-1, self.dimension), self._exp)
        return T @ np.asarray(self.coefficients, dtype=float)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """∂f/∂x_i at (N, d) points -> (N, d)."""
        _, D = monomial_table(np.asarray(x, dtype=float).reshape(-1, self.dimension), self._exp)
        c = np.asarray(self.coefficients, dtype=float)
        return np.stack([Di @ c for Di in D], axis=1)


@dataclass(frozen=True)
class OneVariable:
    """A scalar function used where a function of the coordinates is expected (one variable)."""

    function: ScalarFunction
    dimension: int = 1

    def value(self, x: np.ndarray) -> np.ndarray:
        """f at (N, 1) points -> (N,)."""
        return self.function.value(np.asarray(x, dtype=float).reshape(-1))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """df/dx at (N, 1) points -> (N, 1)."""
        return self.function.derivative(np.asarray(x, dtype=float).reshape(-1))[:, None]


#: A function of several coordinates (a ``FunctionBasedPath``'s length or moment-arm function).
CoordinateFunction = MultivariatePolynomial | OneVariable
