"""Compiled (numba) scalar math of OpenSim 4.6's ``Thelen2003Muscle`` at zero fibre velocity.

The single definition of every formula used by :mod:`pamkin.muscles.thelen2003`: the curves
(fL, fPE, fT with its toe region), the fixed-width pennation geometry, the replay of
OpenSim's own Newton search, the safeguarded root search, the clamping rules, and
:func:`equilibrium_kernel`, which applies them to every (configuration, muscle) pair in
parallel over chunks of configurations. :mod:`pamkin.muscles.thelen2003` documents the model and
holds the public API; read its module docstring first.

The math works on scalars (one muscle in one configuration; ``t`` is the muscle's row of
:func:`muscle_table`). Everything is compiled with ``error_model="numpy"`` so that 0/0
gives NaN as in OpenSim (the replayed search relies on it) instead of raising. Both
Newton iterations are written as state machines advanced one function evaluation at a
time, so that the kernel can interleave two independent entries per thread: a single
iteration is a chain of dependent operations (latency bound), and interleaving lets the
processor overlap two chains.
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
def tendon_strain(f, e_toe, k_lin, c_toe):
    """Inverse of :func:`tendon_curve`: the tendon strain ``lT/lTs − 1`` at which fT = ``f``
    (0 for ``f`` <= 0)."""
    if f >= F_TOE:
        return e_toe + (f - F_TOE) / k_lin
    if f > 0.0:
        return math.log1p(f / TOE_SCALE) / c_toe
    return 0.0


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

#: Search modes of :func:`equilibrium_kernel`: no replay of OpenSim's search; the replay where
#: it can end elsewhere than at the root (the default, see :func:`load_entry`); the replay for
#: every entry (the reference the default is tested against).
SEARCH_NONE, SEARCH_FAST, SEARCH_FULL = 0, 1, 2
#: SEARCH_FAST skips the replay for a pennated fibre whose starting length along the tendon
#: (tendon at 1.01·lTs) is at most SEARCH_START_MAX·l0 (ascending limb): there the force error
#: increases with the fibre length and OpenSim's search took at most 9 of its 20 iterations on
#: 1.2·10⁶ random (muscle, length, activation) triples (7 on Gait2392), always ending at the root
#: pamkin finds. Single-thread CPU time on Gait2392 (activation 1), relative to no failure check:
#: SEARCH_FAST 1.09×, SEARCH_FULL 1.2×.
SEARCH_START_MAX = 1.0


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
def fiber_force_along_tendon(a, fl, fpe, cos):
    """Fibre force along the tendon over Fmax, at zero velocity: ``(a·fL + fPE)·cos(alpha)``."""
    return (a * fl + fpe) * cos


@njit(inline="always", **_JIT)
def residual(x, lmt, a, t):
    """Normalized force error g (fibre along tendon − tendon, over Fmax) and dg/dx at fibre
    length along the tendon ``x``, with the parts the outputs need (lM, fL, fPE, fT)."""
    lm, cos, fl, dfl, fpe, dfpe = fiber_side(x, t)
    ft, dft = tendon_side(x, lmt, t)
    fm = a * fl + fpe
    g = fiber_force_along_tendon(a, fl, fpe, cos) - ft
    curv = t[C_H2] / (lm * lm * lm) if t[C_H] > 0.0 else 0.0  # d(cos)/dx
    dg = (a * dfl + dfpe) * t[C_INV_L0] * cos * cos + fm * curv + dft * t[C_INV_LTS]
    return g, dg, lm, fl, fpe, ft


@njit(inline="always", **_JIT)
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
        if lce > t[C_LMIN] and ratio < t[C_SIN_AMAX]:
            along = math.sqrt(lce * lce - t[C_H2])  # lce·cos(alpha)
            cos = along / lce
            root = cos
            sin = ratio
        else:
            cos = t[C_COS_AMAX]
            along = lce * cos
            root = math.sqrt(1.0 - ratio * ratio)
            sin = t[C_SIN_AMAX]
        dcos = ratio * ratio / (lce * root)  # = h²/(lce³·sqrt(1 − h²/lce²))
        dtl = -cos - sin * ratio / root  # d(tendon length)/d(lce)
    else:
        cos = 1.0
        along = lce
        dcos = 0.0 / (lce * lce * lce)  # NaN at lce = 0, as in OpenSim
        dtl = -1.0 + dcos
    lm_n = lce * t[C_INV_L0]
    fl, dfl = active_curve(lm_n, t[C_INV_KACT])
    fpe, dfpe = passive_curve(lm_n, t[C_PE_RATE], t[C_PE_INV_DEN])
    fse, dfse = tendon_curve((lmt - along) * t[C_INV_LTS], t[C_ETOE], t[C_KLIN], t[C_CTOE])
    fm = (a * fl + fpe) * fmax
    ferr = fm * cos - fse * fmax
    dfm_at = (a * dfl + dfpe) * fmax * t[C_INV_L0] * cos + fm * dcos
    dft = dfse * dtl * fmax * t[C_INV_LTS]
    return ferr, dfm_at - dft


# ----------------------------------------------------------------------------------------------
# OpenSim's search, replayed one force evaluation at a time
# ----------------------------------------------------------------------------------------------
#
# OpenSim (``Thelen2003Muscle::initMuscleState``) starts with the tendon at 1.01 × its slack
# length, takes Newton steps on the fibre length, halves a step (down to sqrt(eps)) until
# the force error drops, raises any iterate below the minimum fibre length to it, and
# stops after 20 iterations or when the force error is below
# ``max(1e-8·Fmax, 10·SignificantReal)``. It then reports *converged*, *at lower bound*
# (not converged and the fibre at its minimum length: OpenSim clamps it there) or fails.
#
# The path matters where the fibre is extremely short: for an unpennated muscle the
# minimum fibre length is 0, and once an iterate reaches 0 the Newton slope is 0/0, so
# OpenSim stays at 0 and reports the fibre clamped even though an equilibrium exists just
# above it. Replaying the search is the only way to reproduce that.
#
# The replay is written as a state machine (:func:`search_update` after each evaluation of
# :func:`opensim_force_error`) so that the kernel can interleave independent entries.


@njit(**_JIT)
def search_start(lmt, t):
    """OpenSim's starting fibre length: MuscleFixedWidthPennationModel::calcFiberLength(lMT,
    1.01·lTs), raised to the minimum fibre length."""
    x0 = lmt - 1.01 * t[C_LTS]
    return fiber_length(x0, t[C_H]) if x0 >= t[C_XMIN] else t[C_LMIN]


@njit(**_JIT)
def search_trial(base_lce, base_err, base_slope, step, lmin):
    """OpenSim's trial fibre length for a (fractional) Newton step ``step`` from the base
    iterate; a step too small to matter is replaced by ``sqrt(eps)`` against the Newton
    direction, and then ``step`` becomes 0 (no further halving). Returns (trial, step)."""
    delta = -step * base_err / base_slope
    if abs(delta) > SIGNIFICANT_REAL:
        trial = base_lce + delta
    else:
        sgn = 0.0  # NaN or 0
        if delta > 0.0:
            sgn = 1.0
        elif delta < 0.0:
            sgn = -1.0
        trial = base_lce - sgn * SQRT_EPS
        step = 0.0
    if trial < lmin:
        trial = lmin
    return trial, step


@njit(inline="always", **_JIT)
def search_update(lce, ferr, slope, base_lce, base_err, base_slope, step, n_iter, t):
    """Advance OpenSim's search after evaluating the force error ``ferr`` (and its slope) at
    the fibre length ``lce``.

    ``step`` < 0 marks the evaluation at the starting guess; otherwise ``lce`` was a trial
    of Newton iteration ``n_iter`` from the base iterate with that step fraction.

    Returns:
        (base_lce, base_err, base_slope, step, n_iter, next fibre length to evaluate, done).
        When done, the search's answer is (lce, ferr, slope).
    """
    if step >= 0.0:
        stop = step <= SQRT_EPS or not abs(ferr) >= abs(base_err)
        step *= 0.5
        if not stop:  # the error did not drop: halve the step
            trial, step = search_trial(base_lce, base_err, base_slope, step, t[C_LMIN])
            return base_lce, base_err, base_slope, step, n_iter, trial, False
        if lce == base_lce:  # the same state as before: every further iteration repeats it
            return base_lce, base_err, base_slope, step, n_iter, lce, True
    # NaN compares False: OpenSim stops too
    if not abs(ferr) > t[C_TOL] or n_iter == OPENSIM_MAX_ITERATIONS:
        return base_lce, base_err, base_slope, step, n_iter, lce, True
    trial, step = search_trial(lce, ferr, slope, 1.0, t[C_LMIN])
    return lce, ferr, slope, step, n_iter + 1, trial, False


@njit(**_JIT)
def search_status(lce, ferr, t):
    """Outcome of OpenSim's search that ended at ``lce`` with force error ``ferr``."""
    if abs(ferr) < t[C_TOL]:
        return CONVERGED
    if lce <= t[C_LMIN]:
        return AT_LOWER_BOUND
    return FAILED


# ----------------------------------------------------------------------------------------------
# The equilibrium itself: safeguarded Newton iteration on x, the fibre length along the tendon
# ----------------------------------------------------------------------------------------------


@njit(**_JIT)
def root_guess_from_search(lce, ferr, slope, t, lo, hi):
    """Starting x from the converged OpenSim answer ``lce``, improved by one Newton step on its
    force error where that stays inside the bracket ``(lo, hi)``."""
    xi = math.sqrt(lce * lce - t[C_H2])
    lce = lce - ferr / slope
    x_newton = math.sqrt(lce * lce - t[C_H2])
    if x_newton > lo and x_newton < hi:
        return x_newton
    return xi


@njit(**_JIT)
def root_guess(lmt, a, t):
    """Starting x without OpenSim's search: the tendon stretched by the force the fibre would
    have with the tendon at its slack length (one fixed-point step away from the
    rigid-tendon solution)."""
    _, cos, fl, _, fpe, _ = fiber_side(lmt - t[C_LTS], t)
    e = tendon_strain(fiber_force_along_tendon(a, fl, fpe, cos), t[C_ETOE], t[C_KLIN], t[C_CTOE])
    return lmt - t[C_LTS] * (1.0 + e)


@njit(inline="always", **_JIT)
def root_update(xi, g, dg, lo, hi, dx_old):
    """One step of the bracketed, safeguarded Newton iteration (as "rtsafe") on the residual
    ``g`` (slope ``dg``) at ``xi``: bisect when the Newton step leaves the bracket or is not at
    least half as long as the step before last, so the bracket shrinks at least as fast as
    bisection's. Done (``xi`` unchanged) once |g| <= 1e-13 or the bracket is exhausted.

    Returns:
        (next x, lo, hi, dx_old, done).
    """
    if g < 0.0:
        lo = xi
    else:
        hi = xi
    if abs(g) <= 1e-13 or hi - lo <= 4.0 * EPS * abs(hi):
        return xi, lo, hi, dx_old, True
    dx = g / dg
    newton = xi - dx
    if newton > lo and newton < hi and math.isfinite(newton) and abs(2.0 * dx) <= dx_old:
        return newton, lo, hi, abs(dx), False
    return 0.5 * (lo + hi), lo, hi, 0.5 * (hi - lo), False


# ----------------------------------------------------------------------------------------------
# Kernel: each (configuration, muscle) entry is a small state machine; LANES entries are
# advanced in turn, one function evaluation at a time, so that the processor overlaps their
# (otherwise strictly sequential) Newton iterations.
# ----------------------------------------------------------------------------------------------

#: Configurations per parallel work item, and work items a thread takes at a time
#: (``numba.set_parallel_chunksize``).
CHUNK = 64
CHUNKS_PER_GRAB = 4
#: Entries interleaved per thread (2 is fastest: more only add branch mispredictions).
LANES = 2

# Phases of an entry (at or below P_ROOT: still iterating).
P_SEARCH, P_ROOT, P_SOLVED, P_CLAMPED, P_INVALID, P_FAILED, P_IDLE = 0, 1, 2, 3, 4, 5, 6
# Lane scratch: float columns ...
(F_LMT, F_A, F_LCE, F_BASE_LCE, F_BASE_ERR, F_BASE_SLOPE, F_STEP, F_X, F_LO, F_HI, F_DX_OLD,
 F_LM, F_FL, F_FPE, F_FT, N_FLOAT) = range(16)
# ... and integer columns.
I_ROW, I_COL, I_PHASE, I_ITER, N_INT = range(5)
# Rows of the float output array.
(O_FIBER_LENGTH, O_NORMALIZED_FIBER_LENGTH, O_PENNATION_ANGLE, O_TENDON_LENGTH, O_TENDON_FORCE,
 O_ACTIVE_FIBER_FORCE, O_PASSIVE_FIBER_FORCE, N_OUTPUTS) = range(8)


@njit(inline="always", **_JIT)
def begin_root(fs, q, t, xi):
    """Enter the root phase from the guess ``xi`` (bracket: x_min .. lMT − lTs)."""
    lo = t[C_XMIN]
    hi = fs[q, F_LMT] - t[C_LTS]  # the tendon exactly slack
    if not (xi > lo and xi < hi):
        xi = 0.5 * (lo + hi)
    fs[q, F_X] = xi
    fs[q, F_LO] = lo
    fs[q, F_HI] = hi
    fs[q, F_DX_OLD] = hi - lo


@njit(inline="always", **_JIT)
def load_entry(fs, ist, q, i, j, lmt, act, table, rigid, search):
    """Put entry (i, j) into lane ``q``: decide what needs no iteration (invalid input, rigid
    tendon, slack tendon, no equilibrium above the minimum fibre length) and otherwise start
    OpenSim's search (``search``) or the root phase."""
    t = table[j]
    length = lmt[i, j]
    a = act[i if act.shape[0] > 1 else 0, j if act.shape[1] > 1 else 0]
    a = min(max(a, t[C_AMIN]), 1.0)
    ist[q, I_ROW] = i
    ist[q, I_COL] = j
    ist[q, I_ITER] = 0
    fs[q, F_LMT] = length
    fs[q, F_A] = a
    if not math.isfinite(length):
        ist[q, I_PHASE] = P_INVALID
        return
    x_slack = length - t[C_LTS]  # fibre along tendon that leaves the tendon exactly slack
    if not x_slack > t[C_XMIN]:
        ist[q, I_PHASE] = P_CLAMPED  # slack tendon
        return
    if rigid:
        lm, cos, fl, _, fpe, _ = fiber_side(x_slack, t)
        fs[q, F_X] = x_slack
        fs[q, F_LM] = lm
        fs[q, F_FL] = fl
        fs[q, F_FPE] = fpe
        fs[q, F_FT] = fiber_force_along_tendon(a, fl, fpe, cos)
        ist[q, I_PHASE] = P_SOLVED
        return
    # residual(x_min) >= 0: even the shortest fibre pulls at least as hard as the tendon
    g_lo = (fiber_force_along_tendon(a, t[C_FL_XMIN], t[C_FPE_XMIN], t[C_COS_XMIN])
            - tendon_side(t[C_XMIN], length, t)[0])
    if not g_lo < 0.0:
        ist[q, I_PHASE] = P_CLAMPED
        return
    # OpenSim's search decides the outcome: it can stop on an unpennated fibre of length 0 (slope
    # 0/0) although a root lies above, and it gives up after 20 Newton iterations (OpenSim then
    # raises MuscleCannotEquilibrate), e.g. from a starting fibre far longer than the equilibrium
    # one (a tendon stretched to several times its slack length), where each Newton step on the
    # exponential passive curve shortens the fibre by only about e0M/kPE·l0. Replaying it is the
    # only exact criterion; from its answer the root phase needs a single evaluation. SEARCH_FAST
    # skips it for pennated fibres starting on the ascending limb (see SEARCH_START_MAX).
    if search == SEARCH_FULL or (search == SEARCH_FAST and (
            not t[C_XMIN] > 0.0 or length - 1.01 * t[C_LTS] > SEARCH_START_MAX * t[C_L0])):
        fs[q, F_LCE] = search_start(length, t)
        fs[q, F_STEP] = -1.0
        ist[q, I_PHASE] = P_SEARCH
    else:
        begin_root(fs, q, t, root_guess(length, a, t))
        ist[q, I_PHASE] = P_ROOT


@njit(inline="always", **_JIT)
def advance_entry(fs, ist, q, table, max_iterations):
    """One function evaluation (and the decision that follows) for the entry in lane ``q``."""
    t = table[ist[q, I_COL]]
    length = fs[q, F_LMT]
    a = fs[q, F_A]
    if ist[q, I_PHASE] == P_SEARCH:
        lce = fs[q, F_LCE]
        ferr, slope = opensim_force_error(lce, length, a, t)
        (fs[q, F_BASE_LCE], fs[q, F_BASE_ERR], fs[q, F_BASE_SLOPE], fs[q, F_STEP], ist[q, I_ITER],
         trial, done) = search_update(lce, ferr, slope, fs[q, F_BASE_LCE], fs[q, F_BASE_ERR],
                                      fs[q, F_BASE_SLOPE], fs[q, F_STEP], ist[q, I_ITER], t)
        if not done:
            fs[q, F_LCE] = trial
            return
        status = search_status(lce, ferr, t)
        if status == AT_LOWER_BOUND:
            ist[q, I_PHASE] = P_CLAMPED
            return
        if status == FAILED:  # OpenSim raises MuscleCannotEquilibrate
            ist[q, I_PHASE] = P_FAILED
            return
        xi = root_guess_from_search(lce, ferr, slope, t, t[C_XMIN], length - t[C_LTS])
        begin_root(fs, q, t, xi)
        ist[q, I_ITER] = 0
        ist[q, I_PHASE] = P_ROOT
        return
    xi = fs[q, F_X]
    g, dg, lm, fl, fpe, ft = residual(xi, length, a, t)
    x_next, fs[q, F_LO], fs[q, F_HI], fs[q, F_DX_OLD], done = root_update(
        xi, g, dg, fs[q, F_LO], fs[q, F_HI], fs[q, F_DX_OLD])
    ist[q, I_ITER] += 1
    if not done:
        fs[q, F_X] = x_next
        if ist[q, I_ITER] < max_iterations:
            return
        # not converged within max_iterations (not expected): the last iterate
        xi = x_next
        _, _, lm, fl, fpe, ft = residual(xi, length, a, t)
    fs[q, F_LM] = lm
    fs[q, F_FL] = fl
    fs[q, F_FPE] = fpe
    fs[q, F_FT] = ft
    ist[q, I_PHASE] = P_SOLVED


@njit(inline="always", **_JIT)
def store_entry(fs, ist, q, table, rigid, out_f, out_status):
    """Write the finished entry of lane ``q`` into the outputs (see :func:`equilibrium_kernel`)."""
    i = ist[q, I_ROW]
    j = ist[q, I_COL]
    t = table[j]
    phase = ist[q, I_PHASE]
    if phase == P_INVALID or phase == P_FAILED:
        for r in range(out_f.shape[0]):
            out_f[r, i, j] = np.nan
        out_status[i, j] = FAILED if phase == P_FAILED else CONVERGED
        return
    length = fs[q, F_LMT]
    clamped = phase == P_CLAMPED
    out_status[i, j] = AT_LOWER_BOUND if clamped else CONVERGED
    fmax = t[C_FMAX]
    if clamped:
        ft = 0.0 if rigid else tendon_side(t[C_XMIN], length, t)[0]
    else:
        ft = fs[q, F_FT]
    out_f[O_TENDON_FORCE if out_f.shape[0] > 1 else 0, i, j] = fmax * ft
    if out_f.shape[0] == 1:
        return  # tendon force only
    h = t[C_H]
    if clamped:
        lm = t[C_LMIN]
        alpha = t[C_AMAX] if h > 0.0 else 0.0
        lt = length - t[C_XMIN]
        fl = 0.0  # OpenSim reports no active force
        fpe = passive_curve(lm * t[C_INV_L0], t[C_PE_RATE], t[C_PE_INV_DEN])[0]
    else:
        x = fs[q, F_X]
        lm = fs[q, F_LM]
        fl = fs[q, F_FL]
        fpe = fs[q, F_FPE]
        alpha = math.atan2(h, x) if h > 0.0 else 0.0
        lt = t[C_LTS] if rigid else length - x
    out_f[O_FIBER_LENGTH, i, j] = lm
    out_f[O_NORMALIZED_FIBER_LENGTH, i, j] = lm / t[C_L0]
    out_f[O_PENNATION_ANGLE, i, j] = alpha
    out_f[O_TENDON_LENGTH, i, j] = lt
    out_f[O_ACTIVE_FIBER_FORCE, i, j] = fmax * fs[q, F_A] * fl
    out_f[O_PASSIVE_FIBER_FORCE, i, j] = fmax * fpe


@njit(parallel=True, **_JIT)
def equilibrium_kernel(lmt, act, table, rigid, search, max_iterations, out_f, out_status):
    """Equilibrium of every (configuration, muscle) pair, written into the output arrays.

    Args:
        lmt: (N, M) musculotendon lengths [m]; non-finite entries give NaN results.
        act: (N or 1, M or 1) activation, broadcast over the lengths (clamped here to
            [minimum_activation, 1]).
        table: (M, N_COLUMNS) from :func:`muscle_table`.
        rigid: Inextensible tendon.
        search: SEARCH_NONE, SEARCH_FAST or SEARCH_FULL: replay OpenSim's search
            (compliant tendon only) to find OpenSim's clamped and failed entries; without it,
            no entry fails and the fibre is clamped only where no equilibrium lies above its
            minimum length.
        max_iterations: Iteration limit of the root search.
        out_f: (N_OUTPUTS, N, M) float outputs, rows ``O_*``: fibre length, normalized fibre
            length, pennation angle, tendon length, tendon force, active and passive fibre
            force; or (1, N, M): the tendon force only.
        out_status: (N, M) int8 output: CONVERGED, AT_LOWER_BOUND (fibre clamped at its
            minimum length) or FAILED (OpenSim's search gives up: NaN outputs); NaN lengths
            give NaN outputs with CONVERGED.
    """
    n, m = lmt.shape
    n_chunks = (n + CHUNK - 1) // CHUNK
    for c in prange(n_chunks):
        fs = np.empty((LANES, N_FLOAT))
        ist = np.empty((LANES, N_INT), dtype=np.int64)
        ist[:, I_PHASE] = P_IDLE
        e = c * CHUNK * m  # next entry (flat index i·m + j) of this chunk
        e_end = min(n, (c + 1) * CHUNK) * m
        busy = True
        while busy:
            busy = False
            for q in range(LANES):
                if ist[q, I_PHASE] <= P_ROOT:
                    advance_entry(fs, ist, q, table, max_iterations)
                # store a finished entry, then load entries until one needs iterating
                while ist[q, I_PHASE] > P_ROOT:
                    if ist[q, I_PHASE] != P_IDLE:
                        store_entry(fs, ist, q, table, rigid, out_f, out_status)
                        ist[q, I_PHASE] = P_IDLE
                    if e == e_end:
                        break
                    load_entry(fs, ist, q, e // m, e % m, lmt, act, table, rigid, search)
                    e += 1
                busy = busy or ist[q, I_PHASE] <= P_ROOT
