"""Compiled wrapped paths and their moment arms in one pass.

Per configuration (numba, parallel over configurations): the kinematics, straight paths and body
Jacobians of :mod:`pamkin.human.paths_compiled`, then every wrapped path by OpenSim 4.6's algorithm
(:func:`pamkin.opensim.wrapping._path_core`), then its moment arms −∂L/∂q about every coordinate it spans:

* one wrap on the path: each straight segment A→B outside the wrap contributes u·(v_B − v_A) exactly
  (u its unit vector, v the point velocities from the body Jacobians and the moving points' functions);
  the wrapped segment (A → tangent points → B) is differenced centrally in the wrap object's frame,
  A and B moved along their velocities relative to the wrap body (step ``h``). OpenSim's tangent
  points are not exactly stationary (a cylinder's axial positions come from a plane construction, not
  the helix), so the envelope theorem would be off (Rajagopal, 300 random configurations: 0.1-0.4 mm
  typically, up to 7.7 mm); the difference is exact to O(h²).
* several wraps (OpenSim iterates them, and each cylinder's spiral adjusts its tangent points 30–50
  times): central differences of the whole path, every point and wrap frame moved along its velocity.

Both are central differences of the same lengths about the same coordinates as before (the linear
motion's second-order terms cancel), without re-running the kinematics: tested against central
differences of pamkin's and OpenSim 4.6's lengths.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from pamkin.human.paths_compiled import config_scratch, one_config_packed
from pamkin.opensim.wrapping import (
    CYLINDER,
    MANDATORY_WRAP,
    WRAPPED,
    _cylinder,
    _frame_into,
    _path_core,
    _wrap_any,
)


@njit(cache=True, error_model="numpy", parallel=True)
def _kernel(q, want_ma, fa, sizes, pts, wa, pstart, pend, wstart, wend, single, kp_start, kp_coord, max_pts, max_w,
            h, L_out, R_out, Lw_out, Rp_out):
    """Straight and wrapped lengths and moment arms of every configuration: ``fa`` and ``sizes`` as
    :attr:`pamkin.human.paths_compiled.FastPaths.packed` and ``.sizes``, ``pts`` its (pt_body, pt_fn, pt_fcoord),
    ``wa`` the wrap arrays of :class:`pamkin.opensim.wrapping.WrappedPaths`."""
    pt_body, pt_fn, pt_fcoord = pts
    (kinds, dims, methods, axes, signs, rstart, rend, actives, objs, wbody, wR, wt) = wa
    N = q.shape[0]
    nj, nb, npnt, nslot = sizes
    ncol = pstart.shape[0]
    cap = max_pts + 2 * max_w
    nch = min(N, 64)
    for ch in prange(nch):
        sc = config_scratch(nj, nb, q.shape[1], npnt, nslot)
        bR, bp, W, T, X, dL, act = sc[7], sc[8], sc[9], sc[10], sc[11], sc[12], sc[13]
        path = np.empty(cap, dtype=np.int64)
        pos = np.zeros((cap, 3))
        cache = np.zeros((cap, 3))
        cached = np.zeros(cap, dtype=np.bool_)
        surf = np.zeros(cap)
        order = np.empty(max_w, dtype=np.int64)
        result = np.empty(max_w, dtype=np.int64)
        Rw = np.empty((max_w, 3, 3))
        pw = np.empty((max_w, 3))
        Fe = np.zeros((cap, 3))
        Xe = np.zeros((cap, 3))
        Rw2 = np.empty((max_w, 3, 3))
        pw2 = np.empty((max_w, 3))
        Xp = np.empty((max_pts, 3))
        S = np.empty((8, 3))
        for t in range(ch * N // nch, (ch + 1) * N // nch):
            one_config_packed(t, q, want_ma, fa, sc, L_out, R_out)
            for col in range(ncol):
                a, b = pstart[col], pend[col]
                w0, w1 = wstart[col], wend[col]
                nw = w1 - w0
                for k in range(w0, w1):
                    _frame_into(Rw[k - w0], pw[k - w0], bR[wbody[k]], bp[wbody[k]], wR[k], wt[k])
                length, npath = _path_core(X[a:b], act[a:b], kinds[w0:w1], dims[w0:w1], methods[w0:w1],
                                           axes[w0:w1], signs[w0:w1], rstart[w0:w1], rend[w0:w1],
                                           actives[w0:w1], objs[w0:w1], Rw[:nw], pw[:nw], path, pos, cache,
                                           cached, surf, order, result)
                Lw_out[t, col] = length
                if not want_ma:
                    continue
                nn = b - a
                for j in range(npath):       # the positions the length used
                    e = path[j]
                    src = cache if (e >= nn and cached[e]) else pos
                    for r in range(3):
                        Xe[e, r] = src[e, r]
                if single[col]:
                    _single_wrap_arms(t, col, a, nn, w0, npath, path, Xe, Fe, W, T, dL, pt_body, pt_fn, pt_fcoord,
                                      kinds, dims, methods, axes, signs, objs, wbody, Rw, pw, kp_start, kp_coord,
                                      h, Rp_out, S)
                else:
                    _path_fd_arms(t, col, a, b, w0, w1, X, act, W, T, dL, pt_body, pt_fn, pt_fcoord, kinds, dims,
                                  methods, axes, signs, rstart, rend, actives, objs, wbody, Rw, pw, Rw2, pw2, Xp,
                                  path, pos, cache, cached, surf, order, result, kp_start, kp_coord, h, Rp_out, S)


@njit(cache=True, inline="always")
def _velocity(out, W, T, body, c, x):
    """Velocity ω × x + τ of the point x moving with ``body`` about coordinate c (body Jacobian columns)."""
    out[0] = W[body, c, 1] * x[2] - W[body, c, 2] * x[1] + T[body, c, 0]
    out[1] = W[body, c, 2] * x[0] - W[body, c, 0] * x[2] + T[body, c, 1]
    out[2] = W[body, c, 0] * x[1] - W[body, c, 1] * x[0] + T[body, c, 2]


@njit(cache=True)
def _point_velocity(out, W, T, dL, pt_body, pt_fn, pt_fcoord, p, c, x):
    """Velocity of path point p (at x) about coordinate c, its own coordinate functions included."""
    _velocity(out, W, T, pt_body[p], c, x)
    if pt_fn[p, 0] >= 0:
        for ax in range(3):
            if pt_fcoord[p, ax] == c:
                for r in range(3):
                    out[r] += dL[p, ax, r]


@njit(cache=True)
def _segment_length(kind, a, b, dims, method, axis, sign):
    """Length |r1 − a| + arc + |b − r2| of the segment a→b wrapped alone over its object (object frame),
    or −1 if it does not wrap."""
    if kind == CYLINDER:          # tuples: no heap allocation
        code, r1, r2, wl = _cylinder((a[0], a[1], a[2]), (b[0], b[1], b[2]), dims[0], dims[1], axis, sign, True)
    else:
        code, r1v, r2v, wl = _wrap_any(kind, a, b, dims, method, axis, sign, True)
        r1, r2 = (r1v[0], r1v[1], r1v[2]), (r2v[0], r2v[1], r2v[2])
    if code != MANDATORY_WRAP and code != WRAPPED:
        return -1.0
    d0, d1, d2 = r1[0] - a[0], r1[1] - a[1], r1[2] - a[2]
    e0, e1, e2 = b[0] - r2[0], b[1] - r2[1], b[2] - r2[2]
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) + wl + math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)


@njit(cache=True)
def _single_wrap_arms(t, col, a, nn, w0, npath, path, Xe, Fe, W, T, dL, pt_body, pt_fn, pt_fcoord, kinds, dims,
                      methods, axes, signs, objs, wbody, Rw, pw, kp_start, kp_coord, h, Rp_out, S):
    """Moment arms of a path with one wrap: straight segments analytically (u · (v_B − v_A)), the
    wrapped segment A→(tangent points)→B by central differences of its wrapped length in the object
    frame, A and B moved along their velocities relative to the wrap body (step ``h``)."""
    jt = -1
    for j in range(npath):
        Fe[path[j], 0] = 0.0
        Fe[path[j], 1] = 0.0
        Fe[path[j], 2] = 0.0
        if path[j] == nn:
            jt = j
    for j in range(npath - 1):       # unit path forces of the straight segments outside the wrap
        e1, e2 = path[j], path[j + 1]
        if e1 >= nn or e2 >= nn:
            continue
        d0 = Xe[e2, 0] - Xe[e1, 0]
        d1 = Xe[e2, 1] - Xe[e1, 1]
        d2 = Xe[e2, 2] - Xe[e1, 2]
        ln = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if ln > 0.0:
            Fe[e1, 0] += d0 / ln
            Fe[e1, 1] += d1 / ln
            Fe[e1, 2] += d2 / ln
            Fe[e2, 0] -= d0 / ln
            Fe[e2, 1] -= d1 / ln
            Fe[e2, 2] -= d2 / ln
    v, vw, la, lb, da, db, ap, bp_ = S[0], S[1], S[2], S[3], S[4], S[5], S[6], S[7]
    ea = eb = -1
    if jt >= 1 and jt + 2 < npath:
        ea, eb = path[jt - 1], path[jt + 2]
        R, o = Rw[0], pw[0]
        for r in range(3):
            la[r] = (Xe[ea, 0] - o[0]) * R[0, r] + (Xe[ea, 1] - o[1]) * R[1, r] + (Xe[ea, 2] - o[2]) * R[2, r]
            lb[r] = (Xe[eb, 0] - o[0]) * R[0, r] + (Xe[eb, 1] - o[1]) * R[1, r] + (Xe[eb, 2] - o[2]) * R[2, r]
    bw = wbody[w0]
    for kp in range(kp_start[col], kp_start[col + 1]):
        c = kp_coord[kp]
        acc = 0.0
        for j in range(npath):
            e = path[j]
            if e >= nn:
                continue
            p = a + e
            _point_velocity(v, W, T, dL, pt_body, pt_fn, pt_fcoord, p, c, Xe[e])
            acc += Fe[e, 0] * v[0] + Fe[e, 1] * v[1] + Fe[e, 2] * v[2]
        if ea >= 0:
            R = Rw[0]
            for side in range(2):
                e = ea if side == 0 else eb
                _point_velocity(v, W, T, dL, pt_body, pt_fn, pt_fcoord, a + e, c, Xe[e])
                _velocity(vw, W, T, bw, c, Xe[e])
                out = da if side == 0 else db
                for r in range(3):
                    out[r] = (v[0] - vw[0]) * R[0, r] + (v[1] - vw[1]) * R[1, r] + (v[2] - vw[2]) * R[2, r]
            for r in range(3):
                ap[r] = la[r] + h * da[r]
                bp_[r] = lb[r] + h * db[r]
            lp = _segment_length(kinds[w0], ap, bp_, dims[w0], methods[w0], axes[w0], signs[w0])
            for r in range(3):
                ap[r] = la[r] - h * da[r]
                bp_[r] = lb[r] - h * db[r]
            lm = _segment_length(kinds[w0], ap, bp_, dims[w0], methods[w0], axes[w0], signs[w0])
            acc -= (lp - lm) / (2.0 * h)
        Rp_out[t, kp] = acc


@njit(cache=True)
def _path_fd_arms(t, col, a, b, w0, w1, X, act, W, T, dL, pt_body, pt_fn, pt_fcoord, kinds, dims, methods, axes,
                  signs, rstart, rend, actives, objs, wbody, Rw, pw, Rw2, pw2, Xp, path, pos, cache, cached, surf,
                  order, result, kp_start, kp_coord, h, Rp_out, S):
    """Moment arms of a path with several wraps (or another object): central differences of the whole
    wrapped length, every point and wrap frame moved along its velocity about the coordinate (step
    ``h``; the second-order terms of the linear motion cancel in the central difference)."""
    nn = b - a
    nw = w1 - w0
    v = S[0]
    for kp in range(kp_start[col], kp_start[col + 1]):
        c = kp_coord[kp]
        moves = False                # a coordinate that moves none of the path's bodies: 0
        for i in range(nn):
            _point_velocity(v, W, T, dL, pt_body, pt_fn, pt_fcoord, a + i, c, X[a + i])
            moves = moves or v[0] != 0.0 or v[1] != 0.0 or v[2] != 0.0
        for k in range(nw):
            bw = wbody[w0 + k]
            for r in range(3):
                moves = moves or W[bw, c, r] != 0.0 or T[bw, c, r] != 0.0
        if not moves:
            Rp_out[t, kp] = 0.0
            continue
        total = 0.0
        for sgn in (1.0, -1.0):
            s = sgn * h
            for i in range(nn):
                _point_velocity(v, W, T, dL, pt_body, pt_fn, pt_fcoord, a + i, c, X[a + i])
                for r in range(3):
                    Xp[i, r] = X[a + i, r] + s * v[r]
            for k in range(nw):
                bw = wbody[w0 + k]
                _velocity(v, W, T, bw, c, pw[k])
                for r in range(3):
                    pw2[k, r] = pw[k, r] + s * v[r]
                    for cc in range(3):    # (I + s [ω]x) R
                        Rw2[k, r, cc] = Rw[k, r, cc] + s * (W[bw, c, (r + 1) % 3] * Rw[k, (r + 2) % 3, cc]
                                                            - W[bw, c, (r + 2) % 3] * Rw[k, (r + 1) % 3, cc])
            ln, _np = _path_core(Xp[:nn], act[a:b], kinds[w0:w1], dims[w0:w1], methods[w0:w1], axes[w0:w1],
                                 signs[w0:w1], rstart[w0:w1], rend[w0:w1], actives[w0:w1], objs[w0:w1], Rw2[:nw],
                                 pw2[:nw], path, pos, cache, cached, surf, order, result)
            total += sgn * ln
        Rp_out[t, kp] = -total / (2.0 * h)


class FastWrapped:
    """Straight and wrapped paths of a model in one compiled pass, with wrapped moment arms.

    Args:
        fast: The model's :class:`pamkin.human.paths_compiled.FastPaths`.
        wrapping: The model's :class:`pamkin.opensim.wrapping.WrappedPaths` (its columns are evaluated).
        wpairs: (K, 2) the (path, independent coordinate) pairs whose moment arms the model reports.
        root_of: (n_coordinates,) each coordinate's independent (root) coordinate.
        step: Central-difference step of the wrapped segments [rad or m].

    Attributes:
        single: (n_wrapped,) which wrapped columns have one wrap (straight segments analytic, only the
            wrapped segment differenced); the others difference the whole path.
        kp_coord, kp_out: per partial pair (grouped by wrapped column, ``kp_start``), its coordinate
            (dependent ones included) and the index into ``wpairs`` of (path, root coordinate).
    """

    def __init__(self, fast, wrapping, wpairs: np.ndarray, root_of: np.ndarray, step: float = 1e-6) -> None:
        self.fast = fast
        W = wrapping
        self.wrapping = W
        self.step = float(step)
        ncol = len(W.indices)
        self.single = np.array([len(W.specs[m]) == 1 for m in W.indices], dtype=np.bool_)
        index = {(int(m), int(c)): k for k, (m, c) in enumerate(wpairs)}
        kp_col, kp_coord, kp_out = [], [], []
        for col, m in enumerate(W.indices):
            for c in range(len(root_of)):
                k = index.get((int(m), int(root_of[c])))
                if k is not None:
                    kp_col.append(col)
                    kp_coord.append(c)
                    kp_out.append(k)
        counts = np.bincount(np.array(kp_col, dtype=np.int64), minlength=ncol)
        self.kp_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.kp_coord = np.array(kp_coord, dtype=np.int64)
        self.kp_out = np.array(kp_out, dtype=np.int64)
        self.max_pts = int(max((W._pend - W._pstart).max(initial=0), 1))
        self.max_w = int(max((W._wend - W._wstart).max(initial=0), 1))
        self._pts = (fast.pt_body, fast.pt_fn, fast.pt_fcoord)

    def evaluate(self, q: np.ndarray, moment_arms: bool = True):
        """``(L, R, Lw, Rp)`` for configurations ``q`` (N, n_coordinates; dependent coordinates filled):
        straight-line lengths (N, n_paths) and partial moment arms (N, n_straight_pairs) as
        :meth:`pamkin.human.paths_compiled.FastPaths.evaluate`, wrapped lengths (N, n_wrapped) [m] and the wrapped
        paths' partial moment arms −∂L/∂q_c (N, n_partial_pairs) [m or m/m] (None without moment arms)."""
        q = np.ascontiguousarray(q, dtype=np.float64)
        N = q.shape[0]
        f, W = self.fast, self.wrapping
        L = np.empty((N, f.n_paths))
        R = np.empty((N, f.n_pairs)) if moment_arms else np.empty((N, 0))
        Lw = np.empty((N, len(W.indices)))
        Rp = np.empty((N, len(self.kp_coord))) if moment_arms else np.empty((N, 0))
        if N:
            _kernel(q, moment_arms, f.packed, f.sizes, self._pts, W._arrays, W._pstart, W._pend, W._wstart,
                    W._wend, self.single, self.kp_start, self.kp_coord, self.max_pts, self.max_w, self.step,
                    L, R, Lw, Rp)
        return L, (R if moment_arms else None), Lw, (Rp if moment_arms else None)
