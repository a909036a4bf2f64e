"""Static equilibrium of OpenSim 4.6's ``Millard2012EquilibriumMuscle``, compiled with numba.

**Curves.** Every curve of the Millard (2012) model is a ``SmoothSegmentedFunction``: a chain of
quintic Bézier "corner" sections between two points with given slopes, continued by straight
lines outside its domain. The control points follow from the curve's parameters exactly as OpenSim
4.6's ``SmoothSegmentedFunctionFactory`` builds them (re-implemented here from its description and
source, not copied): :func:`active_force_length_curve` (5 sections), :func:`fiber_force_length_curve`
(2), :func:`tendon_force_length_curve` (2), :func:`fiber_compressive_force_length_curve` and
:func:`fiber_compressive_force_cos_pennation_curve` (1 each). Optional parameters that the file
leaves empty take OpenSim's fitted defaults (fibre: stiffness at low force 0.2, stiffness at one
normalized force 2/(e1 − e0), curviness 0.75; tendon: stiffness 1.375/e0, force at toe end 2/3,
curviness 0.5). A curve is evaluated at ``x`` by solving the section's x(u) = x for the Bézier
parameter ``u`` (safeguarded Newton to ``|x(u) − x| ≤ 100·eps``, OpenSim's tolerance) and
returning y(u) and dy/dx = y'(u)/x'(u); the values agree with OpenSim's curve objects to ~1e-15.

**Model adjustments OpenSim makes on load** (``extendFinalizeFromProperties``), reproduced:

* ``fiber_damping`` below 0.001 is set to 0 (the undamped "classic Hill" model).
* With an elastic tendon and no damping the active force-length curve's ``minimum_value`` is
  raised to at least 0.1 (``minimum_activation`` must then be ≥ 0.01, else OpenSim refuses the
  model and so does pamkin); otherwise (damping, or a rigid tendon) it is lowered to 0.
* The minimum fibre length is ``max(SignificantReal, min_norm_active_fiber_length·l0,
  h/sin(maximum_pennation_angle))`` with the parallelogram height ``h = l0·sin(alpha0)`` of the
  fixed-width pennation model (``0.01·l0`` for the pennation part if the maximum angle is 0).

**Static equilibrium (elastic tendon).** At zero path speed OpenSim's
``computeInitialFiberEquilibrium`` (``estimateMuscleFiberState`` with a static solution: fibre
velocity 0, force-velocity multiplier 1, no damping force) searches the fibre length ``lce`` at
which ``Fmax·(a·fL + fPE)·cos(alpha) = Fmax·fT(lT/lTs)``, ``lT = lMT − lce·cos(alpha)``: Newton
steps from the fibre that leaves the tendon at 1.01·lTs, each halved (down to sqrt(eps)) until
the force error drops, iterates raised to the minimum fibre length, at most 200 iterations, to
a force error below ``max(1e-8·Fmax, 10·SignificantReal)``. :func:`equilibrium` replays that
search step by step (the same formulas, curves and stopping rules), so it lands where OpenSim
lands, including its three outcomes:

* converged: the tendon force is ``Fmax·fT(lT/lTs)`` at the fibre length found;
* not converged with the fibre at its minimum length: OpenSim clamps the fibre there and reports
  ``Fmax·fT`` of the tendon length this leaves (0 for a slack tendon) — flagged in
  :attr:`Equilibrium.clamped` (as :mod:`pamkin.muscles.thelen2003` does);
* not converged above the minimum length: OpenSim raises ``MuscleCannotEquilibrate`` (no
  equilibrium). pamkin then returns **NaN** for every quantity of that entry and sets
  :attr:`Equilibrium.failed`; :meth:`pamkin.Model.tendon_forces` also warns
  (:class:`pamkin.errors.EquilibriumWarning`). A huge force is never returned silently.

**Rigid tendon** (``ignore_tendon_compliance=true`` in the file, which OpenSim 4.6 supports for
this muscle, or ``rigid_tendon=True``): the tendon stays at its slack length, the fibre length
follows from the geometry (raised to the minimum fibre length) and the force is
``Fmax·(a·fL + fPE)·cos(alpha)`` (never negative); a fibre at its minimum length is clamped and
pulls nothing, as in OpenSim.

Activation is clamped to ``[minimum_activation, 1]`` as OpenSim's activation model does
(outside [0, 1] is an error). Force-velocity parameters do not change static results (fV(0) = 1).

Reference: M. Millard, T. Uchida, A. Seth, S. L. Delp, "Flexing computational muscle: modeling
and simulation of musculotendon dynamics", J. Biomech. Eng. 135 (2013); OpenSim 4.6
``Millard2012EquilibriumMuscle``, ``SmoothSegmentedFunctionFactory``,
``SegmentedQuinticBezierToolkit``, ``MuscleFixedWidthPennationModel``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numba import njit, prange

from pamkin.errors import ConfigurationError, OsimError, ParameterError

__all__ = [
    "BezierCurve",
    "Equilibrium",
    "MillardParams",
    "active_force_length_curve",
    "equilibrium",
    "fiber_compressive_force_cos_pennation_curve",
    "fiber_compressive_force_length_curve",
    "fiber_force_length_curve",
    "minimum_fiber_length",
    "osim_properties",
    "params_from_osim_xml",
    "tendon_force",
    "tendon_force_length_curve",
]

EPS = float(np.finfo(float).eps)
#: SimTK::SignificantReal (eps^(7/8)).
SIGNIFICANT_REAL = EPS ** 0.875
SQRT_EPS = math.sqrt(EPS)
#: OpenSim's tolerance on x when solving x(u) = x for the Bézier parameter u.
U_TOL = EPS * 1e2
#: Iteration limit of OpenSim's equilibrium search.
OPENSIM_MAX_ITERATIONS = 200
#: Damping coefficients below this are treated as 0 by OpenSim.
MIN_NONZERO_DAMPING = 0.001

# ----------------------------------------------------------------------------------------------
# Curve construction (OpenSim's SmoothSegmentedFunctionFactory)
# ----------------------------------------------------------------------------------------------


def _scale_curviness(c: float) -> float:
    return 0.1 + 0.8 * c


def _corner(x0, y0, dydx0, x1, y1, dydx1, c, name):
    """Control points of a quintic Bézier corner from (x0, y0) with slope dydx0 to (x1, y1) with
    slope dydx1: the two tangent lines meet at C; the inner control points sit a fraction ``c``
    of the way from each end towards C (doubled, which makes the ends flat in curvature)."""
    if abs(dydx0 - dydx1) > math.sqrt(EPS):
        xc = (y1 - y0 - x1 * dydx1 + x0 * dydx0) / (dydx0 - dydx1)
    else:
        xc = (x1 + x0) / 2
    yc = (xc - x1) * dydx1 + y1
    a = (xc - x0) ** 2 + (yc - y0) ** 2
    b = (xc - x1) ** 2 + (yc - y1) ** 2
    d = (x1 - x0) ** 2 + (y1 - y0) ** 2
    if not (d > a and d > b):
        raise ParameterError(f"{name}: the curve parameters do not form a C-shaped corner "
                             f"between x = {x0:g} and x = {x1:g}")
    x0m, y0m = x0 + c * (xc - x0), y0 + c * (yc - y0)
    x1m, y1m = x1 + c * (xc - x1), y1 + c * (yc - y1)
    return (x0, x0m, x0m, x1m, x1m, x1), (y0, y0m, y0m, y1m, y1m, y1)


#: Floats of one packed curve: section count, x0, x1, y0, y1, dy/dx at x0 and x1, then up to
#: five sections of 6 x and 6 y control points.
MAX_SECTIONS = 5
CURVE_SIZE = 7 + 12 * MAX_SECTIONS


@dataclass(frozen=True, eq=False)
class BezierCurve:
    """A smooth segmented curve: quintic Bézier sections on ``[x0, x1]``, lines outside.

    Attributes:
        x_points: (n_sections, 6) x control points.
        y_points: (n_sections, 6) y control points.
        x0, x1: Domain of the Bézier sections.
        y0, y1: Values at x0 and x1.
        dydx0, dydx1: Slopes of the lines continuing the curve left of x0 and right of x1.
        name: Curve name, used in messages.
    """

    x_points: np.ndarray
    y_points: np.ndarray
    x0: float
    x1: float
    y0: float
    y1: float
    dydx0: float
    dydx1: float
    name: str = ""
    packed: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        n = len(self.x_points)
        p = np.zeros(CURVE_SIZE)
        p[:7] = (n, self.x0, self.x1, self.y0, self.y1, self.dydx0, self.dydx1)
        p[7:7 + 6 * n] = np.ravel(self.x_points)
        p[7 + 6 * MAX_SECTIONS:7 + 6 * MAX_SECTIONS + 6 * n] = np.ravel(self.y_points)
        p.setflags(write=False)
        object.__setattr__(self, "packed", p)

    def __call__(self, x) -> np.ndarray:
        """Curve value at ``x`` (any shape)."""
        return self._eval(x)[0]

    def derivative(self, x) -> np.ndarray:
        """First derivative dy/dx at ``x`` (any shape)."""
        return self._eval(x)[1]

    def _eval(self, x):
        x = np.asarray(x, dtype=float)
        flat = np.ascontiguousarray(x.ravel())
        y = np.empty_like(flat)
        dy = np.empty_like(flat)
        _curve_many(self.packed, flat, y, dy)
        return y.reshape(x.shape), dy.reshape(x.shape)


def _curve(sections, x0, x1, y0, y1, dydx0, dydx1, name) -> BezierCurve:
    xs = np.array([s[0] for s in sections])
    ys = np.array([s[1] for s in sections])
    return BezierCurve(xs, ys, float(x0), float(x1), float(y0), float(y1), float(dydx0),
                       float(dydx1), name)


def active_force_length_curve(min_norm_active_fiber_length: float = 0.47 - 0.0259,
                              transition_norm_fiber_length: float = 0.73,
                              max_norm_active_fiber_length: float = 1.8123,
                              shallow_ascending_slope: float = 0.8616,
                              minimum_value: float = 0.1,
                              name: str = "ActiveForceLengthCurve") -> BezierCurve:
    """OpenSim's ``ActiveForceLengthCurve`` (defaults: its property defaults).

    Five corners through the points: (x0, ylow) flat, half-way up the steep ascending limb,
    half-way along the shallow ascending limb (slope ``shallow_ascending_slope``), the plateau
    (1, 1) flat, half-way down the descending limb, (x3, ylow) flat; with x0 =
    ``min_norm_active_fiber_length``, x1 = ``transition_norm_fiber_length``, x3 =
    ``max_norm_active_fiber_length``, ylow = ``minimum_value``; curviness 1.

    Raises:
        ParameterError: parameters outside OpenSim's ranges.
    """
    x0, x1, x2, x3 = (min_norm_active_fiber_length, transition_norm_fiber_length, 1.0,
                      max_norm_active_fiber_length)
    ylow, dydx = minimum_value, shallow_ascending_slope
    root_eps = math.sqrt(EPS)
    if not (x0 >= 0 and x1 > x0 + root_eps and x2 > x1 + root_eps and x3 > x2 + root_eps):
        raise ParameterError(f"{name}: need 0 <= min_norm_active_fiber_length < "
                             "transition_norm_fiber_length < 1 < max_norm_active_fiber_length")
    if not ylow >= 0:
        raise ParameterError(f"{name}: minimum_value must be >= 0")
    if not (dydx >= 0 and dydx < (1 - ylow) / (x2 - x1)):
        raise ParameterError(f"{name}: shallow_ascending_slope must lie in [0, "
                             f"{(1 - ylow) / (x2 - x1):g})")
    c = _scale_curviness(1.0)
    dx = 0.05 * x2
    xs = x2 - dx
    y0, dydx0 = 0.0, 0.0
    y1 = 1 - dydx * (xs - x1)
    dydx01 = 1.25 * (y1 - y0) / (x1 - x0)
    x01, y01 = x0 + 0.5 * (x1 - x0), y0 + 0.5 * (y1 - y0)
    x1s, y1s = x1 + 0.5 * (xs - x1), y1 + 0.5 * (1 - y1)
    y2, dydx2, y3, dydx3 = 1.0, 0.0, 0.0, 0.0
    x23 = (x2 + dx) + 0.5 * (x3 - (x2 + dx))
    y23 = y2 + 0.5 * (y3 - y2)
    dydx23 = (y3 - y2) / ((x3 - dx) - (x2 + dx))
    sections = [_corner(x0, ylow, dydx0, x01, y01, dydx01, c, name),
                _corner(x01, y01, dydx01, x1s, y1s, dydx, c, name),
                _corner(x1s, y1s, dydx, x2, y2, dydx2, c, name),
                _corner(x2, y2, dydx2, x23, y23, dydx23, c, name),
                _corner(x23, y23, dydx23, x3, ylow, dydx3, c, name)]
    return _curve(sections, x0, x3, ylow, ylow, 0.0, 0.0, name)


def fiber_force_length_curve(strain_at_zero_force: float = 0.0,
                             strain_at_one_norm_force: float = 0.7,
                             stiffness_at_low_force: float | None = None,
                             stiffness_at_one_norm_force: float | None = None,
                             curviness: float | None = None,
                             name: str = "FiberForceLengthCurve") -> BezierCurve:
    """OpenSim's passive ``FiberForceLengthCurve`` fPE(lM/l0).

    0 up to ``1 + strain_at_zero_force``, 1 at ``1 + strain_at_one_norm_force``, then a line of
    slope ``stiffness_at_one_norm_force``. The three optional parameters are all given or all
    ``None`` (OpenSim's fitted values 0.2, 2/(e1 − e0), 0.75).

    Raises:
        ParameterError: some but not all optional parameters given, or values out of range.
    """
    e0, e1 = strain_at_zero_force, strain_at_one_norm_force
    opt = (stiffness_at_low_force, stiffness_at_one_norm_force, curviness)
    if all(v is None for v in opt):
        k_low, k_iso, curv = 0.2, 2.0 / (e1 - e0), 0.75
    elif any(v is None for v in opt):
        raise ParameterError(f"{name}: stiffness_at_low_force, stiffness_at_one_norm_force and "
                             "curviness must either all be set or all be empty")
    else:
        k_low, k_iso, curv = (float(v) for v in opt)
    if not e1 > e0:
        raise ParameterError(f"{name}: strain_at_one_norm_force must exceed strain_at_zero_force")
    if not k_iso > 1.0 / (e1 - e0):
        raise ParameterError(f"{name}: stiffness_at_one_norm_force must exceed {1.0 / (e1 - e0):g}")
    if not (k_low > 0.0 and k_low < 1 / (e1 - e0)):
        raise ParameterError(f"{name}: stiffness_at_low_force must lie in (0, {1 / (e1 - e0):g})")
    if not 0 <= curv <= 1:
        raise ParameterError(f"{name}: curviness must lie in [0, 1]")
    c = _scale_curviness(curv)
    x_zero, x_iso = 1 + e0, 1 + e1
    dx = min(0.1 * (1.0 / k_iso), 0.1 * (x_iso - x_zero))
    x_low = x_zero + dx
    x_foot = x_zero + 0.5 * (x_low - x_zero)
    y_low = 0.0 + k_low * (x_low - x_foot)
    sections = [_corner(x_zero, 0.0, 0.0, x_low, y_low, k_low, c, name),
                _corner(x_low, y_low, k_low, x_iso, 1.0, k_iso, c, name)]
    return _curve(sections, x_zero, x_iso, 0.0, 1.0, 0.0, k_iso, name)


def tendon_force_length_curve(strain_at_one_norm_force: float = 0.049,
                              stiffness_at_one_norm_force: float | None = None,
                              norm_force_at_toe_end: float | None = None,
                              curviness: float | None = None,
                              name: str = "TendonForceLengthCurve") -> BezierCurve:
    """OpenSim's ``TendonForceLengthCurve`` fT(lT/lTs).

    0 up to the slack length, a toe region up to ``norm_force_at_toe_end``, then a line of slope
    ``stiffness_at_one_norm_force`` through (1 + ``strain_at_one_norm_force``, 1). The three
    optional parameters are all given or all ``None`` (OpenSim's fitted values 1.375/e0, 2/3, 0.5).

    Raises:
        ParameterError: some but not all optional parameters given, or values out of range.
    """
    e_iso = strain_at_one_norm_force
    opt = (stiffness_at_one_norm_force, norm_force_at_toe_end, curviness)
    if all(v is None for v in opt):
        k_iso, f_toe, curv = 1.375 / e_iso, 2.0 / 3.0, 0.5
    elif any(v is None for v in opt):
        raise ParameterError(f"{name}: stiffness_at_one_norm_force, norm_force_at_toe_end and "
                             "curviness must either all be set or all be empty")
    else:
        k_iso, f_toe, curv = (float(v) for v in opt)
    if not e_iso > 0:
        raise ParameterError(f"{name}: strain_at_one_norm_force must be > 0")
    if not (f_toe > 0 and f_toe < 1):
        raise ParameterError(f"{name}: norm_force_at_toe_end must lie in (0, 1)")
    if not k_iso > 1 / e_iso:
        raise ParameterError(f"{name}: stiffness_at_one_norm_force must exceed {1 / e_iso:g}")
    if not 0 <= curv <= 1:
        raise ParameterError(f"{name}: curviness must lie in [0, 1]")
    c = _scale_curviness(curv)
    x0, y0, dydx0 = 1.0, 0.0, 0.0
    x_iso, y_iso = 1.0 + e_iso, 1.0
    y_toe = f_toe
    x_toe = (y_toe - 1) / k_iso + x_iso
    x_foot, y_foot = 1.0 + (x_toe - 1.0) / 10.0, 0.0
    y_toe_mid = y_toe * 0.5
    x_toe_mid = (y_toe_mid - y_iso) / k_iso + x_iso
    dydx_toe_mid = (y_toe_mid - y_foot) / (x_toe_mid - x_foot)
    x_toe_ctrl = x_foot + 0.5 * (x_toe_mid - x_foot)
    y_toe_ctrl = y_foot + dydx_toe_mid * (x_toe_ctrl - x_foot)
    sections = [_corner(x0, y0, dydx0, x_toe_ctrl, y_toe_ctrl, dydx_toe_mid, c, name),
                _corner(x_toe_ctrl, y_toe_ctrl, dydx_toe_mid, x_toe, y_toe, k_iso, c, name)]
    return _curve(sections, x0, x_toe, y0, y_toe, dydx0, k_iso, name)


def fiber_compressive_force_length_curve(norm_length_at_zero_force: float = 0.5,
                                         stiffness_at_zero_length: float | None = None,
                                         curviness: float | None = None,
                                         name: str = "FiberCompressiveForceLengthCurve"
                                         ) -> BezierCurve:
    """OpenSim's ``FiberCompressiveForceLengthCurve``: 1 at zero fibre length falling to 0 at
    ``norm_length_at_zero_force`` (defaults of the optional pair: slope −2/l, curviness 0.5).
    Not used by the equilibrium muscle; provided for completeness."""
    lmax = norm_length_at_zero_force
    if (stiffness_at_zero_length is None) != (curviness is None):
        raise ParameterError(f"{name}: stiffness_at_zero_length and curviness must both be set "
                             "or both be empty")
    k, curv = ((-2.0 / lmax, 0.5) if curviness is None
               else (float(stiffness_at_zero_length), float(curviness)))
    if not (lmax > 0 and k < -(1.0 / lmax) and 0 <= curv <= 1):
        raise ParameterError(f"{name}: need norm_length_at_zero_force > 0, stiffness < "
                             "-1/norm_length_at_zero_force and curviness in [0, 1]")
    sec = _corner(0.0, 1.0, k, lmax, 0.0, 0.0, _scale_curviness(curv), name)
    return _curve([sec], 0.0, lmax, 1.0, 0.0, k, 0.0, name)


def fiber_compressive_force_cos_pennation_curve(engagement_angle_in_degrees: float = 85.0,
                                                stiffness_at_perpendicular: float | None = None,
                                                curviness: float | None = None,
                                                name: str = "FiberCompressiveForceCosPennationCurve"
                                                ) -> BezierCurve:
    """OpenSim's ``FiberCompressiveForceCosPennationCurve`` of cos(alpha): 1 at cos = 0 falling to
    0 at the engagement angle's cosine (defaults of the optional pair: slope −2/cos, curviness
    0.1). Not used by the equilibrium muscle; provided for completeness."""
    cos_phi0 = math.cos(engagement_angle_in_degrees * math.pi / 180.0)
    if (stiffness_at_perpendicular is None) != (curviness is None):
        raise ParameterError(f"{name}: stiffness_at_perpendicular and curviness must both be set "
                             "or both be empty")
    k, curv = ((-2.0 / cos_phi0, 0.1) if curviness is None
               else (float(stiffness_at_perpendicular), float(curviness)))
    if not (0 < cos_phi0 < 1 and k < 1 / cos_phi0 and 0 <= curv <= 1):
        raise ParameterError(f"{name}: need an engagement angle in (0, 90) degrees, stiffness < "
                             "1/cos(angle) and curviness in [0, 1]")
    sec = _corner(0.0, 1.0, k, cos_phi0, 0.0, 0.0, _scale_curviness(curv), name)
    return _curve([sec], 0.0, cos_phi0, 1.0, 0.0, k, 0.0, name)


# ----------------------------------------------------------------------------------------------
# Curve evaluation (compiled)
# ----------------------------------------------------------------------------------------------

_JIT = dict(cache=True, error_model="numpy", nogil=True)


@njit(inline="always", **_JIT)
def _bezier(u, p, o):
    """Quintic Bézier value and d/du at ``u`` of the 6 control points ``p[o:o + 6]``."""
    v = 1.0 - u
    u2, v2 = u * u, v * v
    u3, v3 = u2 * u, v2 * v
    u4, v4 = u3 * u, v3 * v
    val = (v4 * v * p[o] + 5.0 * v4 * u * p[o + 1] + 10.0 * v3 * u2 * p[o + 2]
           + 10.0 * v2 * u3 * p[o + 3] + 5.0 * v * u4 * p[o + 4] + u4 * u * p[o + 5])
    der = 5.0 * (v4 * (p[o + 1] - p[o]) + 4.0 * v3 * u * (p[o + 2] - p[o + 1])
                 + 6.0 * v2 * u2 * (p[o + 3] - p[o + 2]) + 4.0 * v * u3 * (p[o + 4] - p[o + 3])
                 + u4 * (p[o + 5] - p[o + 4]))
    return val, der


@njit(**_JIT)
def curve_eval(p, off, x):
    """Value and dy/dx of the packed curve ``p[off:off + CURVE_SIZE]`` at ``x``."""
    x0 = p[off + 1]
    x1 = p[off + 2]
    if x < x0:
        return p[off + 3] + p[off + 5] * (x - x0), p[off + 5]
    if x > x1:
        return p[off + 4] + p[off + 6] * (x - x1), p[off + 6]
    if not x <= x1:  # NaN
        return np.nan, np.nan
    n = int(p[off])
    ox = off + 7
    idx = n - 1
    for s in range(n):
        if x >= p[ox + 6 * s] and x < p[ox + 6 * s + 5]:
            idx = s
            break
    ox += 6 * idx
    oy = off + 7 + 6 * MAX_SECTIONS + 6 * idx
    # solve x(u) = x: Newton safeguarded by bisection (x(u) increases on [0, 1])
    xa = p[ox]
    xb = p[ox + 5]
    lo, hi = 0.0, 1.0
    u = (x - xa) / (xb - xa) if xb > xa else 0.0
    u = min(max(u, 0.0), 1.0)
    for _ in range(100):
        xv, dx = _bezier(u, p, ox)
        f = xv - x
        if abs(f) <= U_TOL:
            break
        if f > 0.0:
            hi = u
        else:
            lo = u
        un = u - f / dx if dx > 0.0 else -1.0
        if not (un > lo and un < hi):
            un = 0.5 * (lo + hi)
        if un == u:
            break
        u = un
    # one more Newton step: the root to round-off (OpenSim stops within U_TOL of it)
    xv, dx = _bezier(u, p, ox)
    if dx > 0.0:
        un = u - (xv - x) / dx
        if un >= 0.0 and un <= 1.0:
            u = un
    yv, dy = _bezier(u, p, oy)
    _, dx = _bezier(u, p, ox)
    return yv, dy / dx


@njit(**_JIT)
def _curve_many(p, x, y, dy):
    for i in range(x.shape[0]):
        y[i], dy[i] = curve_eval(p, 0, x[i])


# ----------------------------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------------------------

#: MillardParams scalar field -> (property in the .osim file, OpenSim 4.6 default; None: required).
OSIM_PROPERTIES: dict[str, tuple[str, float | None]] = {
    "max_isometric_force": ("max_isometric_force", None),
    "optimal_fiber_length": ("optimal_fiber_length", None),
    "tendon_slack_length": ("tendon_slack_length", None),
    "pennation_angle_at_optimal": ("pennation_angle_at_optimal", 0.0),
    "maximum_pennation_angle": ("maximum_pennation_angle", math.acos(0.1)),
    "minimum_activation": ("minimum_activation", 0.01),
    "min_control": ("min_control", 0.01),
    "fiber_damping": ("fiber_damping", 0.1),
    "ignore_tendon_compliance": ("ignore_tendon_compliance", 0.0),
    # ActiveForceLengthCurve
    "afl_min_norm_active_fiber_length": ("ActiveForceLengthCurve.min_norm_active_fiber_length",
                                         0.47 - 0.0259),
    "afl_transition_norm_fiber_length": ("ActiveForceLengthCurve.transition_norm_fiber_length", 0.73),
    "afl_max_norm_active_fiber_length": ("ActiveForceLengthCurve.max_norm_active_fiber_length", 1.8123),
    "afl_shallow_ascending_slope": ("ActiveForceLengthCurve.shallow_ascending_slope", 0.8616),
    "afl_minimum_value": ("ActiveForceLengthCurve.minimum_value", 0.1),
    # FiberForceLengthCurve (NaN: empty optional property)
    "fpe_strain_at_zero_force": ("FiberForceLengthCurve.strain_at_zero_force", 0.0),
    "fpe_strain_at_one_norm_force": ("FiberForceLengthCurve.strain_at_one_norm_force", 0.7),
    "fpe_stiffness_at_low_force": ("FiberForceLengthCurve.stiffness_at_low_force", math.nan),
    "fpe_stiffness_at_one_norm_force": ("FiberForceLengthCurve.stiffness_at_one_norm_force", math.nan),
    "fpe_curviness": ("FiberForceLengthCurve.curviness", math.nan),
    # TendonForceLengthCurve (NaN: empty optional property)
    "fse_strain_at_one_norm_force": ("TendonForceLengthCurve.strain_at_one_norm_force", 0.049),
    "fse_stiffness_at_one_norm_force": ("TendonForceLengthCurve.stiffness_at_one_norm_force", math.nan),
    "fse_norm_force_at_toe_end": ("TendonForceLengthCurve.norm_force_at_toe_end", math.nan),
    "fse_curviness": ("TendonForceLengthCurve.curviness", math.nan),
}


def _opt(v: float) -> float | None:
    return None if math.isnan(v) else float(v)


@dataclass(frozen=True, eq=False)
class MillardParams:
    """Per-muscle parameters of OpenSim's ``Millard2012EquilibriumMuscle``; one entry per muscle.

    Every field is an (n_muscles,) read-only float array (scalars broadcast), named after the
    OpenSim property (curve properties prefixed ``afl_``, ``fpe_``, ``fse_`` for the active
    force-length, fibre force-length and tendon force-length curves; see
    :data:`OSIM_PROPERTIES`). Absent properties take OpenSim 4.6's defaults; NaN in an optional
    curve property means "empty" (OpenSim's fitted default). ``ignore_tendon_compliance`` is 1.0
    for a rigid tendon. The curves are built (and checked) on construction.
    """

    max_isometric_force: np.ndarray
    optimal_fiber_length: np.ndarray
    tendon_slack_length: np.ndarray
    pennation_angle_at_optimal: np.ndarray | None = None
    maximum_pennation_angle: np.ndarray | None = None
    minimum_activation: np.ndarray | None = None
    min_control: np.ndarray | None = None
    fiber_damping: np.ndarray | None = None
    ignore_tendon_compliance: np.ndarray | None = None
    afl_min_norm_active_fiber_length: np.ndarray | None = None
    afl_transition_norm_fiber_length: np.ndarray | None = None
    afl_max_norm_active_fiber_length: np.ndarray | None = None
    afl_shallow_ascending_slope: np.ndarray | None = None
    afl_minimum_value: np.ndarray | None = None
    fpe_strain_at_zero_force: np.ndarray | None = None
    fpe_strain_at_one_norm_force: np.ndarray | None = None
    fpe_stiffness_at_low_force: np.ndarray | None = None
    fpe_stiffness_at_one_norm_force: np.ndarray | None = None
    fpe_curviness: np.ndarray | None = None
    fse_strain_at_one_norm_force: np.ndarray | None = None
    fse_stiffness_at_one_norm_force: np.ndarray | None = None
    fse_norm_force_at_toe_end: np.ndarray | None = None
    fse_curviness: np.ndarray | None = None
    names: tuple[str, ...] = ()
    _tables: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        keys = list(OSIM_PROPERTIES)
        sizes = [np.size(getattr(self, k)) for k in keys
                 if getattr(self, k) is not None and np.ndim(getattr(self, k)) > 0]
        n = max(sizes, default=1)
        for key in keys:
            value = getattr(self, key)
            if value is None:
                value = OSIM_PROPERTIES[key][1]
            arr = np.asarray(value, dtype=float)
            if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != n):
                raise ParameterError(f"{key} has shape {arr.shape}, expected ({n},)")
            arr = np.array(np.broadcast_to(arr, (n,)), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)
        names = tuple(str(s) for s in self.names)
        if names and len(names) != n:
            raise ParameterError(f"names has {len(names)} entries for {n} muscles")
        object.__setattr__(self, "names", names)
        self.validate()
        self.table(None)  # builds (and checks) every curve

    @property
    def n_muscles(self) -> int:
        """Number of muscles."""
        return int(self.max_isometric_force.shape[0])

    def muscle_name(self, i: int) -> str:
        """Name of muscle ``i`` (``"muscle #i"`` when no names were given)."""
        return self.names[i] if self.names else f"muscle #{i}"

    def validate(self) -> None:
        """Check the scalar parameters (OpenSim 4.6's checks plus physical ones).

        Raises:
            ParameterError: naming the first offending muscle and parameter.
        """
        half_pi = math.pi / 2
        checks = [
            ("max_isometric_force", self.max_isometric_force > 0, "must be > 0 N"),
            ("optimal_fiber_length", self.optimal_fiber_length > 0, "must be > 0 m"),
            ("tendon_slack_length", self.tendon_slack_length > 0, "must be > 0 m"),
            ("pennation_angle_at_optimal",
             (self.pennation_angle_at_optimal >= 0)
             & (self.pennation_angle_at_optimal <= half_pi - SIGNIFICANT_REAL),
             "must lie in [0, pi/2) rad"),
            ("maximum_pennation_angle",
             (self.maximum_pennation_angle >= 0) & (self.maximum_pennation_angle <= half_pi),
             "must lie in [0, pi/2] rad"),
            ("minimum_activation", self.minimum_activation >= 0, "must be >= 0"),
            ("min_control", self.min_control >= np.minimum(self.minimum_activation, 1.0),
             "must be >= minimum_activation (OpenSim refuses the muscle otherwise)"),
            ("fiber_damping", self.fiber_damping >= 0, "must be >= 0"),
        ]
        for key, ok, rule in checks:
            values = getattr(self, key)
            bad = np.flatnonzero(~(ok & np.isfinite(values)))
            if bad.size:
                i = int(bad[0])
                raise ParameterError(f"{self.muscle_name(i)}: {key} {rule} (got {float(values[i]):g})")

    def curves(self, i: int, rigid: bool | None = None) -> tuple[BezierCurve, BezierCurve, BezierCurve]:
        """(active force-length, fibre force-length, tendon force-length) curves of muscle ``i`` as
        OpenSim uses them (the active curve's minimum value adjusted to the muscle's damping and
        tendon; ``rigid`` overrides ``ignore_tendon_compliance``)."""
        name = self.muscle_name(i)
        rigid_i = bool(self.ignore_tendon_compliance[i]) if rigid is None else rigid
        damped = self.fiber_damping[i] >= MIN_NONZERO_DAMPING
        ymin = float(self.afl_minimum_value[i])
        if not rigid_i and not damped:
            if self.minimum_activation[i] < 0.01:
                raise ParameterError(f"{name}: minimum_activation must be >= 0.01 for an elastic "
                                     "tendon without fiber_damping (OpenSim's classic Hill model)")
            ymin = max(ymin, 0.1)
        else:
            ymin = min(ymin, 0.0)
        try:
            fal = active_force_length_curve(self.afl_min_norm_active_fiber_length[i],
                                            self.afl_transition_norm_fiber_length[i],
                                            self.afl_max_norm_active_fiber_length[i],
                                            self.afl_shallow_ascending_slope[i], ymin,
                                            name="ActiveForceLengthCurve")
            fpe = fiber_force_length_curve(self.fpe_strain_at_zero_force[i],
                                           self.fpe_strain_at_one_norm_force[i],
                                           _opt(self.fpe_stiffness_at_low_force[i]),
                                           _opt(self.fpe_stiffness_at_one_norm_force[i]),
                                           _opt(self.fpe_curviness[i]), name="FiberForceLengthCurve")
            fse = tendon_force_length_curve(self.fse_strain_at_one_norm_force[i],
                                            _opt(self.fse_stiffness_at_one_norm_force[i]),
                                            _opt(self.fse_norm_force_at_toe_end[i]),
                                            _opt(self.fse_curviness[i]), name="TendonForceLengthCurve")
        except ParameterError as e:
            raise ParameterError(f"{name}: {e}") from None
        return fal, fpe, fse

    def table(self, rigid: bool | None) -> np.ndarray:
        """(n_muscles, N_COLUMNS) constants for the kernel; ``rigid`` None: as in the file."""
        if rigid in self._tables:
            return self._tables[rigid]
        m = self.n_muscles
        t = np.zeros((m, N_COLUMNS))
        for i in range(m):
            fal, fpe, fse = self.curves(i, rigid)
            l0 = self.optimal_fiber_length[i]
            alpha0 = self.pennation_angle_at_optimal[i]
            amax = self.maximum_pennation_angle[i]
            h = l0 * math.sin(alpha0)
            sin_max = math.sin(amax)
            pen_lmin = h / sin_max if amax > SIGNIFICANT_REAL else l0 * 0.01
            lmin = max(SIGNIFICANT_REAL, max(self.afl_min_norm_active_fiber_length[i] * l0, pen_lmin))
            beta = self.fiber_damping[i]
            if beta < MIN_NONZERO_DAMPING:
                beta = 0.0
            fmax = self.max_isometric_force[i]
            t[i, C_FMAX] = fmax
            t[i, C_L0] = l0
            t[i, C_LTS] = self.tendon_slack_length[i]
            t[i, C_H] = h
            t[i, C_ALPHA0] = alpha0
            t[i, C_AMAX] = amax
            t[i, C_SINMAX] = sin_max
            t[i, C_PEN_LMIN] = pen_lmin
            t[i, C_PEN_XMIN] = pen_lmin * math.cos(amax)
            t[i, C_LMIN] = lmin
            t[i, C_AMIN] = min(max(self.minimum_activation[i], 0.0), 1.0)
            t[i, C_BETA] = beta
            t[i, C_RIGID] = float(bool(self.ignore_tendon_compliance[i]) if rigid is None else rigid)
            t[i, C_TOL] = max(1e-8 * fmax, SIGNIFICANT_REAL * 10)
            t[i, C_FAL:C_FAL + CURVE_SIZE] = fal.packed
            t[i, C_FPE:C_FPE + CURVE_SIZE] = fpe.packed
            t[i, C_FSE:C_FSE + CURVE_SIZE] = fse.packed
        t.setflags(write=False)
        self._tables[rigid] = t
        return t

    @classmethod
    def from_osim_properties(cls, properties: list[dict[str, float]],
                             names: tuple[str, ...] | list[str] = ()) -> MillardParams:
        """Build from one dict per muscle keyed by OpenSim property names (curve properties as
        ``"Curve.property"``, e.g. ``"TendonForceLengthCurve.strain_at_one_norm_force"``); absent
        properties take OpenSim 4.6's defaults, other keys are ignored.

        Raises:
            ParameterError: a required property is missing or a value is out of range.
        """
        names = tuple(names)
        columns: dict[str, list[float]] = {key: [] for key in OSIM_PROPERTIES}
        for i, props in enumerate(properties):
            for key, (osim_name, default) in OSIM_PROPERTIES.items():
                if osim_name in props:
                    columns[key].append(float(props[osim_name]))
                elif default is None:
                    who = names[i] if names else f"muscle #{i}"
                    raise ParameterError(f"{who}: missing required property {osim_name}")
                else:
                    columns[key].append(default)
        if not properties:
            return cls(**{k: np.zeros(0) for k in ("max_isometric_force", "optimal_fiber_length",
                                                   "tendon_slack_length")})
        return cls(**{k: np.asarray(v, dtype=float) for k, v in columns.items()}, names=names)


#: Curve properties read from a muscle's curve elements.
_CURVE_KEYS = {name.split(".")[0]: [] for name, _ in OSIM_PROPERTIES.values() if "." in name}
for _name, _ in OSIM_PROPERTIES.values():
    if "." in _name:
        _CURVE_KEYS[_name.split(".")[0]].append(_name.split(".")[1])


def osim_properties(path: str | Path) -> dict[str, dict[str, float]]:
    """Every property of every ``<Millard2012EquilibriumMuscle>`` in an ``.osim`` file that
    :class:`MillardParams` uses, ``{muscle name: {OpenSim property name: value}}``; curve
    properties as ``"Curve.property"``; absent or empty properties are left out (defaults);
    ``ignore_tendon_compliance`` as 1.0/0.0.

    Raises:
        OsimError: the file is not valid XML or a property is not a number.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise OsimError(str(path), f"cannot read the Millard2012 muscle properties: {exc}") from None
    out: dict[str, dict[str, float]] = {}
    scalars = [n for n, _ in OSIM_PROPERTIES.values() if "." not in n]
    for objects in root.iterfind(".//ForceSet/objects"):
        for el in objects:
            if el.tag != "Millard2012EquilibriumMuscle":
                continue
            values: dict[str, float] = {}
            for key in scalars:
                _read_number(path, el, el, key, "", values)
            for curve, keys in _CURVE_KEYS.items():
                cel = el.find(curve)
                for key in keys if cel is not None else ():
                    _read_number(path, el, cel, key, f"{curve}.", values)
            out[el.get("name", "")] = values
    return out


def _read_number(path: Path, muscle: ET.Element, parent: ET.Element, key: str, prefix: str,
                 values: dict[str, float]) -> None:
    """Store property ``key`` of ``parent`` (if present and not empty) in ``values``."""
    text = (parent.findtext(key) or "").strip()
    if not text:
        return
    where = {"element": muscle.tag, "component": muscle.get("name", "")}
    if key == "ignore_tendon_compliance":
        if text.lower() not in ("true", "false", "1", "0"):
            raise OsimError(str(path), f"<{key}> must be true or false, is {text!r}", **where)
        values[key] = float(text.lower() in ("true", "1"))
        return
    try:
        values[prefix + key] = float(text)
    except ValueError:
        raise OsimError(str(path), f"<{key}> is not a number: {text!r}", **where) from None


def params_from_osim_xml(path: str | Path) -> MillardParams:
    """Parameters of every ``<Millard2012EquilibriumMuscle>`` in an ``.osim`` file's ForceSet
    (file order, with names); absent properties take OpenSim 4.6's defaults.

    Raises:
        OsimError: the file is not valid XML or a property is not a number.
        ParameterError: a required property is missing or a value is out of range.
    """
    props = osim_properties(path)
    return MillardParams.from_osim_properties(list(props.values()), list(props))


def minimum_fiber_length(params: MillardParams) -> np.ndarray:
    """OpenSim's minimum fibre length of each muscle [m]: ``max(SignificantReal,
    min_norm_active_fiber_length·l0, h/sin(maximum_pennation_angle))``."""
    return params.table(None)[:, C_LMIN].copy()


# ----------------------------------------------------------------------------------------------
# Kernel
# ----------------------------------------------------------------------------------------------

(C_FMAX, C_L0, C_LTS, C_H, C_ALPHA0, C_AMAX, C_SINMAX, C_PEN_LMIN, C_PEN_XMIN, C_LMIN, C_AMIN,
 C_BETA, C_RIGID, C_TOL) = range(14)
C_FAL = 14
C_FPE = C_FAL + CURVE_SIZE
C_FSE = C_FPE + CURVE_SIZE
N_COLUMNS = C_FSE + CURVE_SIZE

#: Rows of the kernel's float output.
(O_FIBER_LENGTH, O_NORMALIZED_FIBER_LENGTH, O_PENNATION_ANGLE, O_TENDON_LENGTH, O_TENDON_FORCE,
 O_ACTIVE_FIBER_FORCE, O_PASSIVE_FIBER_FORCE) = range(7)
N_OUTPUTS = 7
#: Status codes of the kernel.
S_FREE, S_CLAMPED, S_FAILED, S_INVALID = 0, 1, 2, 3


@njit(**_JIT)
def pennation_angle(lce, t):
    """MuscleFixedWidthPennationModel::calcPennationAngle."""
    if t[C_ALPHA0] > EPS:
        if lce > t[C_PEN_LMIN]:
            s = t[C_H] / lce
            return math.asin(s) if s < t[C_SINMAX] else t[C_AMAX]
        return t[C_AMAX]
    return 0.0


@njit(**_JIT)
def force_error(lce, lmt, a, t):
    """OpenSim's static force error ``Fm·cos(alpha) − Ft`` at fibre length ``lce`` and its
    derivative in ``lce`` (fibre velocity 0, fV = 1)."""
    fiso = t[C_FMAX]
    l0 = t[C_L0]
    lts = t[C_LTS]
    phi = pennation_angle(lce, t)
    cos = math.cos(phi)
    sin = math.sin(phi)
    tl = lmt - lce * cos
    lce_n = lce / l0
    fal, dfal = curve_eval(t, C_FAL, lce_n)
    fpe, dfpe = curve_eval(t, C_FPE, lce_n)
    fse, dfse = curve_eval(t, C_FSE, tl / lts)
    fm = fiso * (a * fal * 1.0) + (fiso * fpe + fiso * t[C_BETA] * 0.0)
    ferr = fm * cos - fse * fiso
    inv_l0 = 1.0 / l0
    dfm = fiso * (a * (dfal * inv_l0) * 1.0 + dfpe * inv_l0)
    hl = t[C_H] / lce
    dphi = (-hl / lce) / math.sqrt(1.0 - hl * hl)
    dfm_at = dfm * cos + fm * (-sin * dphi)
    dft = (dfse * fiso / lts) * (lce * sin * dphi - cos)
    return ferr, dfm_at - dft


@njit(**_JIT)
def opensim_search(lmt, a, t):
    """Replay of ``Millard2012EquilibriumMuscle::estimateMuscleFiberState`` (static solution).

    Returns:
        (fibre length, status): S_FREE (converged), S_CLAMPED (stopped at the minimum fibre
        length: clamped there) or S_FAILED (OpenSim raises MuscleCannotEquilibrate).
    """
    lmin = t[C_LMIN]
    tol = t[C_TOL]
    x = lmt - t[C_LTS] * 1.01
    lce = math.sqrt(t[C_H] * t[C_H] + x * x) if x >= t[C_PEN_XMIN] else t[C_PEN_LMIN]
    lce = max(lce, lmin)
    ferr, slope = force_error(lce, lmt, a, t)
    ferr_prev, lce_prev, slope_prev = ferr, lce, slope
    it = 0
    while abs(ferr) > tol and it < OPENSIM_MAX_ITERATIONS:
        h = 1.0
        while abs(ferr) >= abs(ferr_prev):
            delta = -h * ferr_prev / slope_prev
            if abs(delta) > SIGNIFICANT_REAL:
                lce = lce_prev + delta
            else:
                sgn = 0.0
                if delta > 0.0:
                    sgn = 1.0
                elif delta < 0.0:
                    sgn = -1.0
                lce = lce_prev - sgn * SQRT_EPS
                h = 0.0
            lce = max(lce, lmin)
            ferr, slope = force_error(lce, lmt, a, t)
            if h <= SQRT_EPS:
                break
            h = 0.5 * h
        if lce == lce_prev and ferr == ferr_prev:
            break  # stuck: every further iteration repeats this one (same state, same outcome)
        ferr_prev, lce_prev, slope_prev = ferr, lce, slope
        it += 1
    if abs(ferr) < tol:
        return max(lce, lmin), S_FREE
    if lce <= lmin:
        return lmin, S_CLAMPED
    return lce, S_FAILED


@njit(**_JIT)
def solve_entry(lmt, a, t, out, i, j):
    """Equilibrium of one muscle in one configuration, written into ``out[:, i, j]``; returns the
    status."""
    if not math.isfinite(lmt):
        for r in range(out.shape[0]):
            out[r, i, j] = np.nan
        return S_INVALID
    a = min(max(a, t[C_AMIN]), 1.0)
    fiso = t[C_FMAX]
    lmin = t[C_LMIN]
    if t[C_RIGID] > 0.0:
        x = lmt - t[C_LTS]
        lce = math.sqrt(t[C_H] * t[C_H] + x * x) if x >= t[C_PEN_XMIN] else t[C_PEN_LMIN]
        lce = max(lce, lmin)
        status = S_CLAMPED if lce <= lmin else S_FREE
    else:
        lce, status = opensim_search(lmt, a, t)
        if status == S_FAILED:
            for r in range(out.shape[0]):
                out[r, i, j] = np.nan
            return S_FAILED
        if lce <= lmin:  # converged at the minimum length (slack tendon): clamped there too
            status = S_CLAMPED
    phi = pennation_angle(lce, t)
    cos = math.cos(phi)
    tl = lmt - lce * cos
    lce_n = lce / t[C_L0]
    fal = curve_eval(t, C_FAL, lce_n)[0]
    fpe = curve_eval(t, C_FPE, lce_n)[0]
    if status == S_CLAMPED:
        active = 0.0
        passive = 0.0
    else:
        active = fiso * (a * fal * 1.0)
        passive = fiso * fpe
    if t[C_RIGID] > 0.0:
        fm = max(active + passive, 0.0)
        ft = fm * cos
    else:
        ft = curve_eval(t, C_FSE, tl / t[C_LTS])[0] * fiso
    if out.shape[0] == 1:
        out[0, i, j] = ft
        return status
    out[O_FIBER_LENGTH, i, j] = lce
    out[O_NORMALIZED_FIBER_LENGTH, i, j] = lce_n
    out[O_PENNATION_ANGLE, i, j] = phi
    out[O_TENDON_LENGTH, i, j] = tl
    out[O_TENDON_FORCE, i, j] = ft
    out[O_ACTIVE_FIBER_FORCE, i, j] = active
    out[O_PASSIVE_FIBER_FORCE, i, j] = passive
    return status


@njit(parallel=True, **_JIT)
def equilibrium_kernel(lmt, act, table, out, status):
    """Every (configuration, muscle) pair, in parallel over configurations.

    Args:
        lmt: (N, M) musculotendon lengths [m].
        act: (N or 1, M or 1) activation (clamped here to [minimum_activation, 1]).
        table: (M, N_COLUMNS) from :meth:`MillardParams.table`.
        out: (N_OUTPUTS, N, M) or (1, N, M) (tendon force only) float output.
        status: (N, M) int8 output (S_*).
    """
    n, m = lmt.shape
    row_step = 1 if act.shape[0] > 1 else 0
    col_step = 1 if act.shape[1] > 1 else 0
    for i in prange(n):
        for j in range(m):
            a = act[i * row_step, j * col_step]
            status[i, j] = solve_entry(lmt[i, j], a, table[j], out, i, j)


# ----------------------------------------------------------------------------------------------
# Public API
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """Static musculotendon equilibrium; every array has the shape of ``lmt``.

    Attributes:
        fiber_length: Fibre length lM [m] (the minimum fibre length where clamped).
        normalized_fiber_length: lM/l0 [-].
        pennation_angle: alpha [rad].
        tendon_length: lT = lMT − lM·cos(alpha) [m].
        tendon_force: The musculotendon force [N].
        active_fiber_force: Fmax·a·fL along the fibre [N]; 0 where clamped (as OpenSim).
        passive_fiber_force: Fmax·fPE along the fibre [N]; 0 where clamped (as OpenSim).
        clamped: True where the fibre sits at its minimum length.
        failed: True where OpenSim finds no equilibrium (it raises MuscleCannotEquilibrate);
            every float field is NaN there.
    """

    fiber_length: np.ndarray
    normalized_fiber_length: np.ndarray
    pennation_angle: np.ndarray
    tendon_length: np.ndarray
    tendon_force: np.ndarray
    active_fiber_force: np.ndarray
    passive_fiber_force: np.ndarray
    clamped: np.ndarray
    failed: np.ndarray


_OUTPUT_ROWS = {"fiber_length": O_FIBER_LENGTH, "normalized_fiber_length": O_NORMALIZED_FIBER_LENGTH,
                "pennation_angle": O_PENNATION_ANGLE, "tendon_length": O_TENDON_LENGTH,
                "tendon_force": O_TENDON_FORCE, "active_fiber_force": O_ACTIVE_FIBER_FORCE,
                "passive_fiber_force": O_PASSIVE_FIBER_FORCE}


def _prepare(lmt, params: MillardParams, activation):
    lmt = np.asarray(lmt, dtype=float)
    if lmt.ndim == 0 or lmt.shape[-1] != params.n_muscles:
        raise ConfigurationError(
            f"musculotendon lengths have shape {lmt.shape}; the last axis must have "
            f"{params.n_muscles} entries (one per muscle)")
    act = np.asarray(activation, dtype=float)
    try:
        act = np.broadcast_to(act, lmt.shape)
    except ValueError:
        raise ConfigurationError(f"activation of shape {np.shape(activation)} does not broadcast "
                                 f"to the lengths' shape {lmt.shape}") from None
    if not np.all(np.isfinite(np.asarray(activation, dtype=float))):
        raise ConfigurationError("activation must be finite")
    outside = (act < 0.0) | (act > 1.0)
    if np.any(outside):
        raise ConfigurationError(f"activation must lie in [0, 1] (got {float(act[outside].flat[0]):g}); "
                                 "values below minimum_activation are raised to it, as in OpenSim")
    m = params.n_muscles
    act = act.reshape(-1, m)
    if act.strides[0] == 0:
        act = act[:1]
    if m and act.strides[1] == 0:
        act = act[:, :1]
    return np.require(lmt.reshape(-1, m), float, ["C"]), np.array(act, dtype=float)


def _solve(lmt, params: MillardParams, activation, rigid_tendon: bool | None, n_outputs: int):
    lmt2, act2 = _prepare(lmt, params, activation)
    out = np.empty((n_outputs, *lmt2.shape))
    status = np.empty(lmt2.shape, dtype=np.int8)
    if lmt2.size:
        equilibrium_kernel(lmt2, act2, params.table(rigid_tendon), out, status)
    return out, status


def equilibrium(lmt: np.ndarray, params: MillardParams, activation: float | np.ndarray = 1.0,
                rigid_tendon: bool | None = None) -> Equilibrium:
    """Static (zero velocity) equilibrium of OpenSim 4.6 Millard2012EquilibriumMuscles.

    Args:
        lmt: (..., n_muscles) musculotendon lengths [m]; NaN entries give NaN results.
        params: Muscle parameters.
        activation: Activation in [0, 1], scalar or broadcastable to ``lmt``; values below
            ``minimum_activation`` are raised to it like OpenSim; outside [0, 1] is an error.
        rigid_tendon: None (default): each muscle's ``ignore_tendon_compliance``; True: every
            tendon rigid; False: every tendon elastic.

    Returns:
        The equilibrium; where OpenSim finds none, ``failed`` is set and the values are NaN.

    Raises:
        ConfigurationError: ``lmt``'s last axis does not match the number of muscles, or
            ``activation`` is not finite, outside [0, 1] or does not broadcast.
    """
    shape = np.shape(lmt)
    out, status = _solve(lmt, params, activation, rigid_tendon, N_OUTPUTS)
    return Equilibrium(**{k: out[r].reshape(shape) for k, r in _OUTPUT_ROWS.items()},
                       clamped=(status == S_CLAMPED).reshape(shape),
                       failed=(status == S_FAILED).reshape(shape))


def tendon_force(lmt: np.ndarray, params: MillardParams, activation: float | np.ndarray = 1.0,
                 rigid_tendon: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Static equilibrium tendon force of OpenSim 4.6 Millard2012EquilibriumMuscles.

    Matches ``Model.equilibrateMuscles`` + ``Muscle.getTendonForce`` at zero speeds.

    Returns:
        (tendon force [N], failed): both shaped like ``lmt``; the force is NaN where ``failed``
        (OpenSim finds no equilibrium there).
    """
    out, status = _solve(lmt, params, activation, rigid_tendon, 1)
    shape = np.shape(lmt)
    return out[0].reshape(shape), (status == S_FAILED).reshape(shape)
