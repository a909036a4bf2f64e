"""Muscle paths as CasADi functions of the coordinates (for optimal control and other gradient-based work).

:func:`path_functions` returns one ``casadi.Function`` ``q -> (L, R)``: every muscle's length L [m] and moment
arms R = −∂L/∂q [m or m/m] (total derivatives about the independent coordinates, coupled coordinates following
their couplers; 0 about a dependent coordinate, as :meth:`pamkin.human.model.Model.moment_arms`). It holds

* function-based paths (OpenSim's ``FunctionBasedPath``, e.g. written by ``pamkin fit-paths``): their
  polynomials (or their moment-arm functions when the file gives them), and
* straight-line paths: the model's joint tree (custom axes, spline translations, couplers) and its path
  points (fixed, conditional as ``if_else`` on their coordinate's range, moving as functions of theirs).

Paths over wrap objects have no closed form here: fit them first (``pamkin fit-paths``) and use the fitted
model. Importing this module imports CasADi (never in the same process as OpenSim).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from pamkin.errors import UnsupportedFeatureError
from pamkin.human.model import Model
from pamkin.opensim.functions import (
    Constant,
    LinearFunction,
    MultiplierFunction,
    MultivariatePolynomial,
    OneVariable,
    PolynomialFunction,
    SimmSpline,
)
from pamkin.opensim.model_file import ConditionalPathPoint, FunctionPath, MovingPathPoint

_CONDITIONAL_TOLERANCE = 1e-5      # OpenSim's: a conditional point is active in [min - 1e-5, max + 1e-5]


def scalar_function(fn, x: ca.SX) -> ca.SX:
    """A scalar OpenSim function of ``x`` as a CasADi expression (same values as :mod:`pamkin.opensim.functions`)."""
    if isinstance(fn, Constant):
        return ca.SX(fn.c)
    if isinstance(fn, LinearFunction):
        return fn.slope * x + fn.intercept
    if isinstance(fn, PolynomialFunction):
        out = ca.SX(0.0)
        for c in fn.coefficients:          # highest power first: Horner
            out = out * x + c
        return out
    if isinstance(fn, MultiplierFunction):
        return fn.scale * scalar_function(fn.function, x)
    if isinstance(fn, SimmSpline):
        return _spline(fn, x)
    if isinstance(fn, OneVariable):
        return scalar_function(fn.function, x)
    raise TypeError(f"no CasADi form of the function type {type(fn).__name__}")


def _spline(fn: SimmSpline, x: ca.SX) -> ca.SX:
    """OpenSim's SimmSpline: the cubic of the segment x falls in, linear with the end slopes outside."""
    xs, ys = np.asarray(fn.x, float), np.asarray(fn.y, float)
    b, c, d = fn.coefficients

    def seg(k: int) -> ca.SX:
        dx = x - xs[k]
        return ys[k] + dx * (b[k] + dx * (c[k] + dx * d[k]))

    out = seg(0)
    for k in range(1, len(xs) - 1):
        out = ca.if_else(x > xs[k], seg(k), out)
    out = ca.if_else(x > xs[-1], ys[-1] + (x - xs[-1]) * b[-1], out)
    return ca.if_else(x < xs[0], ys[0] + (x - xs[0]) * b[0], out)


def polynomial(poly: MultivariatePolynomial, x: list) -> ca.SX:
    """A ``MultivariatePolynomialFunction`` of the expressions ``x`` (its term order)."""
    powers = [[ca.SX(1.0)] for _ in x]
    for i, xi in enumerate(x):
        for _ in range(poly.order):
            powers[i].append(powers[i][-1] * xi)
    out = ca.SX(0.0)
    for e, c in zip(poly.exponents, poly.coefficients):
        if c != 0.0:
            term = ca.SX(c)
            for i, k in enumerate(e):
                if k:
                    term = term * powers[i][int(k)]
            out = out + term
    return out


def _coordinate_function(fn, x: list) -> ca.SX:
    return polynomial(fn, x) if isinstance(fn, MultivariatePolynomial) else scalar_function(fn, x[0])


def _full_q(model: Model, q: ca.SX) -> list:
    """Coordinates with the dependent ones replaced by their couplers' functions of the independent ones."""
    full = [q[i] for i in range(q.shape[0])]
    for d, i, k in model.kinematics.couplers:
        full[d] = k.scale_factor * scalar_function(k.function, full[i])
    return full


def _rodrigues(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    K = ca.SX(np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]]))
    return ca.SX.eye(3) + ca.sin(angle) * K + (1.0 - ca.cos(angle)) * ca.mtimes(K, K)


def body_placements(model: Model, q: list) -> tuple[list, list]:
    """(R, p) of every frame in :attr:`Kinematics.frames` (ground last) as CasADi expressions of ``q``."""
    t = model.kinematics.tree
    nj = len(t.parent)
    R, p = [None] * (nj + 1), [None] * (nj + 1)
    R[nj], p[nj] = ca.SX.eye(3), ca.SX.zeros(3, 1)
    for j in range(nj):
        v = scalar_function(t.functions[j], q[t.coordinate[j]])
        Rp, pp = (R[nj], p[nj]) if t.parent[j] < 0 else (R[t.parent[j]], p[t.parent[j]])
        Rb = ca.mtimes(Rp, ca.SX(t.placement_R[j]))
        pb = pp + ca.mtimes(Rp, ca.SX(t.placement_p[j]))
        if t.revolute[j]:
            R[j], p[j] = ca.mtimes(Rb, _rodrigues(t.axis[j], v)), pb
        else:
            R[j], p[j] = Rb, pb + ca.mtimes(Rb, ca.SX(t.axis[j])) * v
    bR = [ca.mtimes(R[t.body_joint[b]], ca.SX(t.body_R[b])) for b in range(len(t.body_joint))]
    bp = [p[t.body_joint[b]] + ca.mtimes(R[t.body_joint[b]], ca.SX(t.body_p[b])) for b in range(len(t.body_joint))]
    return bR, bp


def _straight_length(model: Model, muscle, q: list, bR: list, bp: list) -> ca.SX:
    frames = model.kinematics.frames
    coord = {c: i for i, c in enumerate(model.coordinates)}
    pts, active = [], []
    for pt in muscle.points:
        b = frames.index(pt.body)
        if isinstance(pt, MovingPathPoint):
            loc = ca.vertcat(*[scalar_function(f, q[coord[c]] if c else ca.SX(0.0))
                               for f, c in zip(pt.functions, pt.coordinates)])
        else:
            loc = ca.SX(np.asarray(pt.location, float))
        pts.append(bp[b] + ca.mtimes(bR[b], loc))
        if isinstance(pt, ConditionalPathPoint):
            x = q[coord[pt.coordinate]]
            lo, hi = pt.range
            active.append(ca.logic_and(x >= lo - _CONDITIONAL_TOLERANCE, x <= hi + _CONDITIONAL_TOLERANCE))
        else:
            active.append(None)
    # the path runs through the active points: the segment from each active point to the next active one
    length = ca.SX(0.0)
    for k in range(1, len(pts)):
        seg = ca.norm_2(pts[k] - _previous_active(pts, active, k))
        length = length + (seg if active[k] is None else ca.if_else(active[k], seg, 0.0))
    return length


def _previous_active(pts: list, active: list, k: int) -> ca.SX:
    """The nearest point before k that is in the path (the first and last points always are)."""
    out = pts[k - 1]
    if active[k - 1] is None:
        return out
    # pts[k-1] is conditional: if inactive, fall back to the one before it, recursively
    return ca.if_else(active[k - 1], out, _previous_active(pts, active, k - 1))


def _function_length(model: Model, fp: FunctionPath, q: list) -> ca.SX:
    coord = {c: i for i, c in enumerate(model.coordinates)}
    return _coordinate_function(fp.length, [q[coord[c]] for c in fp.coordinates])


def path_functions(model: Model, muscles: list[str] | None = None) -> ca.Function:
    """``casadi.Function('paths', [q], [L, R])`` of the model's paths.

    Args:
        model: A model whose chosen paths are function-based or straight lines (no wrap objects).
        muscles: The paths, in this order (default: every muscle).

    Returns:
        A function of q (n_coordinates,) [rad, m] (dependent entries ignored: they follow their couplers) giving
        L (n_muscles,) [m] and R (n_muscles, n_coordinates) [m or m/m].

    Raises:
        UnsupportedFeatureError: A chosen path wraps over wrap objects (fit it first with ``pamkin fit-paths``).
        KeyError: An unknown muscle.
    """
    names = model.muscles
    chosen = list(range(len(names))) if muscles is None else [names.index(m) for m in muscles]
    q = ca.SX.sym("q", len(model.coordinates))
    full = _full_q(model, q)
    need_kinematics = any(model.osim.muscles[i].function_path is None for i in chosen)
    bR, bp = body_placements(model, full) if need_kinematics else ([], [])
    lengths = []
    for i in chosen:
        m = model.osim.muscles[i]
        if m.function_path is not None:
            lengths.append(_function_length(model, m.function_path, full))
            continue
        if m.wraps:
            raise UnsupportedFeatureError(model.osim.path, "a path over wrap objects has no CasADi form here; fit "
                                          "it first (pamkin fit-paths) and use the fitted model",
                                          element=m.kind, component=m.name)
        lengths.append(_straight_length(model, m, full, bR, bp))
    L = ca.vertcat(*lengths)
    J = ca.jacobian(L, q)
    independent = ca.SX(np.diag((~model.kinematics.dependent).astype(float)))
    R = -ca.mtimes(J, independent)
    arms = _moment_arm_functions(model, chosen, full, q)
    for row, expr in arms.items():
        R[row, :] = expr
    return ca.Function("paths", [q], [L, R], ["q"], ["L", "R"])


def _moment_arm_functions(model: Model, chosen: list[int], full: list, q: ca.SX) -> dict[int, ca.SX]:
    """Rows of R for function-based paths that carry their own moment-arm functions (OpenSim uses them)."""
    out = {}
    coord = {c: i for i, c in enumerate(model.coordinates)}
    kin = model.kinematics
    for row, i in enumerate(chosen):
        fp = model.osim.muscles[i].function_path
        if fp is None or not fp.moment_arms:
            continue
        r = ca.SX.zeros(1, len(model.coordinates))
        args = [full[coord[c]] for c in fp.coordinates]
        for c, f in zip(fp.coordinates, fp.moment_arms):
            j = coord[c]
            value = _coordinate_function(f, args)
            if kin.dependent[j]:        # chain rule onto the independent coordinate
                root = int(kin.root_of[j])
                r[0, root] = r[0, root] + value * ca.jacobian(full[j], q[root])
            else:
                r[0, j] = r[0, j] + value
        out[row] = r
    return out
