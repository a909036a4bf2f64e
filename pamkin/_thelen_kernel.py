"""Compiled (numba) scalar math of OpenSim 4.6's ``Thelen2003Muscle`` at zero fibre velocity.

The single definition of every formula used by :mod:`pamkin.thelen2003`: the curves
(fL, fPE, fT with its toe region), the fixed-width pennation geometry, the replay of
OpenSim's own Newton search, the safeguarded root search, the clamping rules, and
:func:`equilibrium_kernel`, which applies them to every (configuration, muscle) pair in
parallel over chunks of configurations. :mod:`pamkin.thelen2003` documents the model and
holds the public API; read its module docstring first.

Every function here works on Python floats; they are compiled with
``error_model="numpy"`` so that 0/0 gives NaN as in OpenSim (the replayed search relies
on it) instead of raising.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange, vectorize

#: Tendon toe region of OpenSim's Thelen2003Muscle: exponential shape factor and
#: normalized force at the end of the toe (Thelen 2003).
K_TOE = 3.0
F_TOE = 0.33
#: exp(3) once.
E3 = math.exp(K_TOE)
#: fT = TOE_SCALE·(exp(3·e/e_toe) − 1) in the toe region.
TOE_SCALE = F_TOE / (E3 - 1.0)
#: OpenSim treats an optimal pennation angle at or below machine epsilon as unpennated.
EPS = float(np.finfo(float).eps)
#: SimTK::SignificantReal (eps^(7/8)): OpenSim's threshold for "maximum pennation angle is zero"
#: and the smallest Newton step of its equilibrium search.
SIGNIFICANT_REAL = EPS ** 0.875
SQRT_EPS = math.sqrt(EPS)

#: Outcomes of OpenSim's equilibrium search (``Thelen2003Muscle::initMuscleState``).
CONVERGED, AT_LOWER_BOUND, FAILED = 0, 1, 2
#: OpenSim's search: iteration limit.
OPENSIM_MAX_ITERATIONS = 20

_JIT = dict(cache=True, error_model="numpy", nogil=True)

# ----------------------------------------------------------------------------------------------
# Curves (value and slope). Each takes the curve's constants as derived once per muscle by
# its ``*_constants`` function (reciprocals instead of divisions: the kernel is latency bound).
# ----------------------------------------------------------------------------------------------


@njit(**_JIT)
def tendon_constants(e0):
    """(e_toe, k_lin, 3/e_toe) of fT for tendon strain ``e0`` at Fmax: strain at the end of the
    toe region ``99·e0·exp(3)/(166·exp(3) − 67)``, slope of the linear region ``0.67/(e0 −
    e_toe)``, and the toe's exponential rate."""
    e_toe = 99.0 * e0 * E3 / (166.0 * E3 - 67.0)
    return e_toe, 0.67 / (e0 - e_toe), K_TOE / e_toe


@njit(**_JIT)
def tendon_curve(lt_n, e_toe, k_lin, c_toe):
    """fT and dfT/d(lT/lTs) at normalized tendon length ``lt_n`` (see ``tendon_force_length``)."""
    e = lt_n - 1.0
    if e > e_toe:
        return k_lin * (e - e_toe) + F_TOE, k_lin
    if e > 0.0:
        ex = math.exp(c_toe * e)
        return TOE_SCALE * (ex - 1.0), TOE_SCALE * c_toe * ex
    return 0.0, 0.0


@njit(**_JIT)
def active_constants(k):
    """1/k for :func:`active_curve`."""
    return 1.0 / k


@njit(**_JIT)
def active_curve(lm_n, inv_k):
    """fL and dfL/d(lM/l0): the Gaussian ``exp(−(lM/l0 − 1)²/k)``."""
    t = lm_n - 1.0
    f = math.exp(-t * t * inv_k)
    return f, -2.0 * t * inv_k * f


@njit(**_JIT)
def passive_constants(e0, k):
    """(kPE/e0M, 1/(exp(kPE) − 1)) for :func:`passive_curve`."""
    return k / e0, 1.0 / math.expm1(k)


@njit(**_JIT)
def passive_curve(lm_n, rate, inv_denom):
    """fPE and dfPE/d(lM/l0): ``(exp(kPE·(lM/l0 − 1)/e0M) − 1)/(exp(kPE) − 1)`` above l0."""
    s = lm_n - 1.0
    if s > 0.0:
        ex = math.exp(rate * s)
        return (ex - 1.0) * inv_denom, rate * ex * inv_denom
    return 0.0, 0.0


@vectorize(cache=True)
def tendon_force_length_ufunc(lt_n, e0):
    e_toe, k_lin, c_toe = tendon_constants(e0)
    return tendon_curve(lt_n, e_toe, k_lin, c_toe)[0]


@vectorize(cache=True)
def force_length_active_ufunc(lm_n, k):
    return active_curve(lm_n, active_constants(k))[0]


@vectorize(cache=True)
def force_length_passive_ufunc(lm_n, e0, k):
    rate, inv_denom = passive_constants(e0, k)
    return passive_curve(lm_n, rate, inv_denom)[0]


# ----------------------------------------------------------------------------------------------
# Geometry and per-muscle constants
# ----------------------------------------------------------------------------------------------


@njit(**_JIT)
def parallelogram_height(l0, alpha0):
    """h = l0·sin(alpha0); 0 where OpenSim treats the muscle as unpennated (alpha0 <= eps).

    (OpenSim still uses its ``h`` <= 2.3e-16·l0 there for the minimum fibre length; taking 0
    keeps the geometry consistent and changes nothing measurable.)
    """
    if alpha0 > EPS:
        return l0 * math.sin(alpha0)
    return 0.0


@njit(**_JIT)
def minimum_fiber_length(l0, alpha0, amax):
    """OpenSim's minimum fibre length ``h/sin(alpha_max)`` (0 if unpennated)."""
    if amax > SIGNIFICANT_REAL:
        return parallelogram_height(l0, alpha0) / math.sin(amax)
    return 0.01 * l0


@vectorize(cache=True)
def minimum_fiber_length_ufunc(l0, alpha0, amax):
    return minimum_fiber_length(l0, alpha0, amax)


@njit(**_JIT)
def fiber_length(x, h):
    """Fibre length from its length along the tendon ``x`` (fixed-width pennation: constant
    parallelogram height ``h``)."""
    if h > 0.0:
        return math.sqrt(x * x + h * h)
    return abs(x)


# Columns of the per-muscle table built by :func:`muscle_table`.
(C_FMAX, C_L0, C_INV_L0, C_LTS, C_INV_LTS, C_H, C_H2, C_LMIN, C_XMIN, C_AMAX, C_SIN_AMAX,
 C_COS_AMAX, C_INV_KACT, C_PE_RATE, C_PE_INV_DEN, C_ETOE, C_KLIN, C_CTOE, C_TOL, C_AMIN,
 C_FL_XMIN, C_FPE_XMIN, C_COS_XMIN, N_COLUMNS) = range(24)


@njit(**_JIT)
def muscle_table(fmax, l0, lts, alpha0, e0t, e0m, kact, kpe, amax, amin):
    """(n_muscles, N_COLUMNS) constants of each muscle, derived once per call."""
    m = fmax.shape[0]
    t = np.empty((m, N_COLUMNS))
    for j in range(m):
        r = t[j]
        h = parallelogram_height(l0[j], alpha0[j])
        lmin = minimum_fiber_length(l0[j], alpha0[j], amax[j])
        r[C_FMAX] = fmax[j]
        r[C_L0] = l0[j]
        r[C_INV_L0] = 1.0 / l0[j]
        r[C_LTS] = lts[j]
        r[C_INV_LTS] = 1.0 / lts[j]
        r[C_H] = h
        r[C_H2] = h * h
        r[C_LMIN] = lmin
        r[C_AMAX] = amax[j]
        r[C_SIN_AMAX] = math.sin(amax[j])
        r[C_COS_AMAX] = math.cos(amax[j])
        # minimum fibre length along the tendon
        r[C_XMIN] = lmin * r[C_COS_AMAX] if h > 0.0 else lmin
        r[C_INV_KACT] = active_constants(kact[j])
        r[C_PE_RATE], r[C_PE_INV_DEN] = passive_constants(e0m[j], kpe[j])
        r[C_ETOE], r[C_KLIN], r[C_CTOE] = tendon_constants(e0t[j])
        r[C_TOL] = max(1e-8 * fmax[j], 10.0 * SIGNIFICANT_REAL)  # OpenSim's force tolerance
        r[C_AMIN] = amin[j]
        # the fibre side of the residual at x_min (activation aside): see :func:`residual`
        _, cos, fl, _, fpe, _ = fiber_side(r[C_XMIN], r)
        r[C_FL_XMIN], r[C_FPE_XMIN], r[C_COS_XMIN] = fl, fpe, cos
    return t


# ----------------------------------------------------------------------------------------------
# Equilibrium of one muscle
# ----------------------------------------------------------------------------------------------


@njit(**_JIT)
def fiber_side(x, t):
    """At fibre length along the tendon ``x``: fibre length, cos(pennation), fL, dfL, fPE, dfPE
    (``t`` is the muscle's row of :func:`muscle_table`)."""
    h = t[C_H]
    lm = fiber_length(x, h)
    cos = x / lm if h > 0.0 else 1.0
    lm_n = lm * t[C_INV_L0]
    fl, dfl = active_curve(lm_n, t[C_INV_KACT])
    fpe, dfpe = passive_curve(lm_n, t[C_PE_RATE], t[C_PE_INV_DEN])
    return lm, cos, fl, dfl, fpe, dfpe


@njit(**_JIT)
def tendon_side(x, lmt, t):
    """fT and dfT/d(lT/lTs) with the fibre at length ``x`` along the tendon."""
    return tendon_curve((lmt - x) * t[C_INV_LTS], t[C_ETOE], t[C_KLIN], t[C_CTOE])


@njit(**_JIT)
def residual(x, lmt, a, t):
    """Normalized force error g (fibre along tendon − tendon, over Fmax) and dg/dx at fibre
    length along the tendon ``x``, with the parts the outputs need (lM, fL, fPE, fT)."""
    lm, cos, fl, dfl, fpe, dfpe = fiber_side(x, t)
    ft, dft = tendon_side(x, lmt, t)
    fm = a * fl + fpe
    g = fm * cos - ft
    curv = t[C_H2] / (lm * lm * lm) if t[C_H] > 0.0 else 0.0  # d(cos)/dx
    dg = (a * dfl + dfpe) * t[C_INV_L0] * cos * cos + fm * curv + dft * t[C_INV_LTS]
    return g, dg, lm, fl, fpe, ft


@njit(**_JIT)
def opensim_force_error(lce, lmt, a, t):
    """OpenSim's positionFunc + multipliersFunc + ferrFunc (fv = 1) and partialsFunc: force
    error [N] and its slope in fibre length (0/0 = NaN at lce = 0 for an unpennated muscle).

    OpenSim's pennation angle is ``asin(h/lce)`` above the minimum fibre length and
    ``alpha_max`` at or below it; its cosine and sine are taken here as ``sqrt(1 − (h/lce)²)``
    and ``h/lce`` (the same numbers to round-off, without trigonometric calls).
    """
    h = t[C_H]
    fmax = t[C_FMAX]
    if h > 0.0:
        ratio = h / lce
        root = math.sqrt(1.0 - ratio * ratio)
        if lce > t[C_LMIN] and ratio < t[C_SIN_AMAX]:
            cos = root
            sin = ratio
        else:
            cos = t[C_COS_AMAX]
            sin = t[C_SIN_AMAX]
        lr = lce * root
        dcos = ratio * ratio / lr  # = h²/(lce³·sqrt(1 − h²/lce²))
        dtl = -cos - sin * ratio / root  # d(tendon length)/d(lce)
    else:
        cos = 1.0
        dcos = 0.0 / (lce * lce * lce)  # NaN at lce = 0, as in OpenSim
        dtl = -1.0 + dcos
    lm_n = lce * t[C_INV_L0]
    fl, dfl = active_curve(lm_n, t[C_INV_KACT])
    fpe, dfpe = passive_curve(lm_n, t[C_PE_RATE], t[C_PE_INV_DEN])
    fse, dfse = tendon_curve((lmt - lce * cos) * t[C_INV_LTS], t[C_ETOE], t[C_KLIN], t[C_CTOE])
    fm = (a * fl + fpe) * fmax
    ferr = fm * cos - fse * fmax
    dfm_at = (a * dfl + dfpe) * fmax * t[C_INV_L0] * cos + fm * dcos
    dft = dfse * dtl * fmax * t[C_INV_LTS]
    return ferr, dfm_at - dft


@njit(**_JIT)
def opensim_search(lmt, a, t):
    """Replay OpenSim 4.6's damped Newton search for the fibre length of one muscle.

    OpenSim (``Thelen2003Muscle::initMuscleState``) starts with the tendon at 1.01 × its
    slack length, takes Newton steps on the fibre length, halves a step (down to
    sqrt(eps)) until the force error drops, raises any iterate below the minimum fibre
    length to it, and stops after 20 iterations or when the force error is below
    ``max(1e-8·Fmax, 10·SignificantReal)``. It then reports *converged*, *at lower bound*
    (not converged and the fibre at its minimum length: OpenSim clamps it there) or fails.

    The path matters where the fibre is extremely short: for an unpennated muscle the
    minimum fibre length is 0, and once an iterate reaches 0 the Newton slope is 0/0, so
    OpenSim stays at 0 and reports the fibre clamped even though an equilibrium exists a
    few micrometres above it. Replaying the search is the only way to reproduce that.

    Returns:
        (status, fibre length, force error, its slope) at the last iterate; status is one of
        CONVERGED, AT_LOWER_BOUND, FAILED.
    """
    lmin = t[C_LMIN]
    tol = t[C_TOL]
    # Starting guess: MuscleFixedWidthPennationModel::calcFiberLength(lMT, 1.01·lTs).
    x0 = lmt - 1.01 * t[C_LTS]
    lce = fiber_length(x0, t[C_H]) if x0 >= t[C_XMIN] else lmin
    ferr, slope = opensim_force_error(lce, lmt, a, t)
    for _ in range(OPENSIM_MAX_ITERATIONS):
        if not abs(ferr) > tol:  # NaN compares False: OpenSim stops too
            break
        prev_err = ferr
        prev_lce = lce
        d = slope
        step = 1.0
        while True:
            delta = -step * prev_err / d
            if abs(delta) > SIGNIFICANT_REAL:
                trial = prev_lce + delta
            else:
                sgn = 0.0  # NaN or 0
                if delta > 0.0:
                    sgn = 1.0
                elif delta < 0.0:
                    sgn = -1.0
                trial = prev_lce - sgn * SQRT_EPS
                step = 0.0
            if trial < lmin:
                trial = lmin
            ferr, slope = opensim_force_error(trial, lmt, a, t)
            lce = trial
            stop = step <= SQRT_EPS or not abs(ferr) >= abs(prev_err)
            step *= 0.5
            if stop:
                break
        if lce == prev_lce:
            break  # same state as before this iteration: every further one repeats it
    if abs(ferr) < tol:
        return CONVERGED, lce, ferr, slope
    if lce <= lmin:
        return AT_LOWER_BOUND, lce, ferr, slope
    return FAILED, lce, ferr, slope


@njit(**_JIT)
def solve_fiber(lmt, a, t, search, max_iterations):
    """Equilibrium of one muscle: (x, lM, fL, fPE, fT) with ``x`` the fibre length along the
    tendon, or ``x`` = NaN where the fibre is clamped at its minimum length (no equilibrium
    above it, or OpenSim's search ends there when ``search``; the other values are then
    undefined).

    The root of :func:`residual` in ``(x_min, lMT − lTs)`` by a bracketed, safeguarded Newton
    iteration (as "rtsafe": bisect when the Newton step leaves the bracket or is not at least
    half as long as the step before last, so the bracket shrinks at least as fast as
    bisection's), started from OpenSim's converged answer when ``search``, else from
    OpenSim's starting guess (tendon at 1.01 × slack length).
    """
    xmin = t[C_XMIN]
    lo = xmin
    hi = lmt - t[C_LTS]  # fibre along tendon that leaves the tendon exactly slack
    if not hi > xmin:
        return np.nan, 0.0, 0.0, 0.0, 0.0  # slack tendon
    # residual(x_min): even the shortest fibre pulls at least as hard as the tendon?
    g_lo = ((a * t[C_FL_XMIN] + t[C_FPE_XMIN]) * t[C_COS_XMIN]
            - tendon_side(xmin, lmt, t)[0])
    if not g_lo < 0.0:
        return np.nan, 0.0, 0.0, 0.0, 0.0
    xi = lmt - 1.01 * t[C_LTS]
    if search:
        status, lce, ferr, slope = opensim_search(lmt, a, t)
        if status == AT_LOWER_BOUND:
            return np.nan, 0.0, 0.0, 0.0, 0.0
        if status == CONVERGED:
            xi = math.sqrt(lce * lce - t[C_H2])
            # one more Newton step on OpenSim's last iterate, if it stays in the bracket
            lce = lce - ferr / slope
            x_newton = math.sqrt(lce * lce - t[C_H2])
            if x_newton > lo and x_newton < hi:
                xi = x_newton
    if not (xi > lo and xi < hi):
        xi = 0.5 * (lo + hi)
    dx_old = hi - lo
    for _ in range(max_iterations):
        g, dg, lm, fl, fpe, ft = residual(xi, lmt, a, t)
        if g < 0.0:
            lo = xi
        else:
            hi = xi
        if abs(g) <= 1e-13:
            return xi, lm, fl, fpe, ft
        if hi - lo <= 4.0 * EPS * abs(hi):
            break
        dx = g / dg
        newton = xi - dx
        if newton > lo and newton < hi and math.isfinite(newton) and abs(2.0 * dx) <= dx_old:
            dx_old = abs(dx)
            xi = newton
        else:
            dx_old = 0.5 * (hi - lo)
            xi = 0.5 * (lo + hi)
    # bracket exhausted, or not converged within max_iterations (not expected)
    _, _, lm, fl, fpe, ft = residual(xi, lmt, a, t)
    return xi, lm, fl, fpe, ft


# ----------------------------------------------------------------------------------------------
# Kernel
# ----------------------------------------------------------------------------------------------

#: Configurations per parallel work item.
CHUNK = 64


@njit(parallel=True, **_JIT)
def equilibrium_kernel(lmt, act, table, rigid, search, max_iterations,
                       lm_out, lm_n_out, alpha_out, lt_out, ft_out, fa_out, fp_out, clamped_out):
    """Equilibrium of every (configuration, muscle) pair, written into the output arrays.

    Args:
        lmt: (N, M) musculotendon lengths [m]; non-finite entries give NaN results.
        act: (N, M) activation (clamped here to [minimum_activation, 1]); may be a
            broadcast view.
        table: (M, N_COLUMNS) from :func:`muscle_table`.
        rigid: Inextensible tendon.
        search: Replay OpenSim's search (compliant tendon only).
        max_iterations: Iteration limit of the root search.
        lm_out, lm_n_out, alpha_out, lt_out, ft_out, fa_out, fp_out: (N, M) float outputs:
            fibre length, normalized fibre length, pennation angle, tendon length, tendon
            force, active and passive fibre force.
        clamped_out: (N, M) bool output.
    """
    n, m = lmt.shape
    n_chunks = (n + CHUNK - 1) // CHUNK
    for c in prange(n_chunks):
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            for j in range(m):
                t = table[j]
                length = lmt[i, j]
                if not math.isfinite(length):
                    lm_out[i, j] = np.nan
                    lm_n_out[i, j] = np.nan
                    alpha_out[i, j] = np.nan
                    lt_out[i, j] = np.nan
                    ft_out[i, j] = np.nan
                    fa_out[i, j] = np.nan
                    fp_out[i, j] = np.nan
                    clamped_out[i, j] = False
                    continue
                a = min(max(act[i, j], t[C_AMIN]), 1.0)
                h = t[C_H]
                fmax = t[C_FMAX]
                if rigid:
                    x = length - t[C_LTS]
                    if x > t[C_XMIN]:
                        lm, cos, fl, _, fpe, _ = fiber_side(x, t)
                        ft = (a * fl + fpe) * cos
                    else:
                        x = np.nan
                else:
                    x, lm, fl, fpe, ft = solve_fiber(length, a, t, search, max_iterations)
                clamped = math.isnan(x)
                if clamped:
                    lm = t[C_LMIN]
                    alpha = t[C_AMAX] if h > 0.0 else 0.0
                    lt = length - t[C_XMIN]
                    fl = 0.0
                    fpe = passive_curve(lm * t[C_INV_L0], t[C_PE_RATE], t[C_PE_INV_DEN])[0]
                    if rigid:
                        ft = 0.0
                    else:
                        ft = tendon_side(t[C_XMIN], length, t)[0]
                else:
                    alpha = math.atan2(h, x) if h > 0.0 else 0.0
                    lt = t[C_LTS] if rigid else length - x
                lm_out[i, j] = lm
                lm_n_out[i, j] = lm / t[C_L0]
                alpha_out[i, j] = alpha
                lt_out[i, j] = lt
                ft_out[i, j] = fmax * ft
                fa_out[i, j] = fmax * a * fl
                fp_out[i, j] = fmax * fpe
                clamped_out[i, j] = clamped
