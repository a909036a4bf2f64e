"""Compiled (numba) evaluation of kinematics, path lengths and moment arms.

The same model description and formulas as :mod:`pamkin.human.kinematics` and
:mod:`pamkin.human.paths` (which remain the readable reference and are tested against
Pinocchio and OpenSim), evaluated one configuration per loop iteration in
machine code, in parallel over configurations. Results equal the numpy engine to
round-off (tested). Used by :class:`pamkin.human.model.Model` for large batches.

Supported function types: Constant, LinearFunction, SimmSpline and a
MultiplierFunction of these; a model with other functions uses the numpy engine.
"""

from __future__ import annotations

import numpy as np

from pamkin.opensim.functions import (
    Constant,
    LinearFunction,
    MultiplierFunction,
    SimmSpline,
)

try:  # numba is a declared dependency; keep import errors explicit
    import numba
    from numba import njit, prange
except ImportError:  # pragma: no cover
    numba = None

_ROUNDOFF = 2e-13


class FunctionTable:
    """Scalar functions packed into flat arrays for the compiled kernel."""

    def __init__(self) -> None:
        self.kind: list[int] = []      # 0 constant, 1 linear, 2 spline
        self.scale: list[float] = []
        self.p0: list[float] = []
        self.p1: list[float] = []
        self.off: list[int] = []
        self.n: list[int] = []
        self.x: list[float] = []
        self.y: list[float] = []
        self.b: list[float] = []
        self.c: list[float] = []
        self.d: list[float] = []

    def add(self, fn) -> int:
        """Pack ``fn``; return its slot. Raises TypeError for unsupported functions."""
        scale = 1.0
        if isinstance(fn, MultiplierFunction):
            scale, fn = fn.scale, fn.function
        slot = len(self.kind)
        self.scale.append(scale)
        self.off.append(len(self.x))
        if isinstance(fn, Constant):
            self.kind.append(0)
            self.p0.append(fn.c)
            self.p1.append(0.0)
            self.n.append(0)
        elif isinstance(fn, LinearFunction):
            self.kind.append(1)
            self.p0.append(fn.slope)
            self.p1.append(fn.intercept)
            self.n.append(0)
        elif isinstance(fn, SimmSpline):
            self.kind.append(2)
            self.p0.append(0.0)
            self.p1.append(0.0)
            b, c, d = fn.coefficients
            self.n.append(len(fn.x))
            self.x += list(fn.x)
            self.y += list(fn.y)
            self.b += list(b)
            self.c += list(c)
            self.d += list(d)
        else:
            raise TypeError(f"no compiled form for {type(fn).__name__}")
        return slot

    def arrays(self) -> tuple:
        f = lambda v: np.asarray(v, dtype=np.float64)  # noqa: E731
        i = lambda v: np.asarray(v, dtype=np.int64)  # noqa: E731
        return (i(self.kind), f(self.scale), f(self.p0), f(self.p1), i(self.off), i(self.n),
                f(self.x + [0.0]), f(self.y + [0.0]), f(self.b + [0.0]), f(self.c + [0.0]), f(self.d + [0.0]))


if numba is not None:

    @njit(cache=True, inline="always")
    def _feval(s, x, kind, scale, p0, p1, off, n, kx, ky, kb, kc, kd):
        """Value and derivative of function slot ``s`` at ``x`` (OpenSim's SimmSpline rules)."""
        k = kind[s]
        if k == 0:
            return scale[s] * p0[s], 0.0
        if k == 1:
            return scale[s] * (p0[s] * x + p1[s]), scale[s] * p0[s]
        o = off[s]
        m = n[s]
        x0 = kx[o]
        xn = kx[o + m - 1]
        if x < x0:
            return scale[s] * (ky[o] + (x - x0) * kb[o]), scale[s] * kb[o]
        if x > xn:
            return scale[s] * (ky[o + m - 1] + (x - xn) * kb[o + m - 1]), scale[s] * kb[o + m - 1]
        if abs(x - x0) <= _ROUNDOFF:
            return scale[s] * ky[o], scale[s] * kb[o]
        if abs(x - xn) <= _ROUNDOFF:
            return scale[s] * ky[o + m - 1], scale[s] * kb[o + m - 1]
        # segment: first knot index i with x <= kx[i], minus one (numpy searchsorted 'left')
        lo = 0
        hi = m
        while lo < hi:
            mid = (lo + hi) // 2
            if kx[o + mid] < x:
                lo = mid + 1
            else:
                hi = mid
        i = lo - 1
        if i < 0:
            i = 0
        if i > m - 2:
            i = m - 2
        j = o + i
        dx = x - kx[j]
        v = ky[j] + dx * (kb[j] + dx * (kc[j] + dx * kd[j]))
        dv = kb[j] + dx * (2.0 * kc[j] + 3.0 * dx * kd[j])
        return scale[s] * v, scale[s] * dv

    @njit(cache=True)
    def _one_config(t, q, want_ma, j_parent, j_R, j_p, j_axis, j_rev, j_coord, j_fn,
                    b_joint, b_R, b_p, body_support,
                    pt_body, pt_local, pt_fn, pt_fcoord, pt_cond, pt_lo, pt_hi,
                    m_start, m_end, pair_start, pair_coord,
                    kind, scale, p0, p1, off, n, kx, ky, kb, kc, kd,
                    L_out, R_out, jR, jp, ja, dvj, Rb, pb, Rj, bR, bp, W, T, X, dL, act, F, lv,
                    pt_slot, ms_start, slot_body, SF, SM):
        """Kinematics, lengths and moment arms of configuration ``t`` (scratch arrays given)."""
        if True:
            nj = j_parent.shape[0]
            nb = b_joint.shape[0]
            npnt = pt_body.shape[0]
            M = m_start.shape[0]
            for j in range(nj):
                v, dv = _feval(j_fn[j], q[t, j_coord[j]], kind, scale, p0, p1, off, n, kx, ky, kb, kc, kd)
                dvj[j] = dv
                par = j_parent[j]
                if par < 0:
                    for r in range(3):
                        pb[r] = j_p[j, r]
                        for c in range(3):
                            Rb[r, c] = j_R[j, r, c]
                else:
                    for r in range(3):
                        acc = jp[par, r]
                        for c in range(3):
                            acc += jR[par, r, c] * j_p[j, c]
                            s_ = 0.0
                            for k in range(3):
                                s_ += jR[par, r, k] * j_R[j, k, c]
                            Rb[r, c] = s_
                        pb[r] = acc
                a0, a1, a2 = j_axis[j, 0], j_axis[j, 1], j_axis[j, 2]
                if j_rev[j]:
                    sn, cs = np.sin(v), np.cos(v)
                    C = 1.0 - cs
                    Rj[0, 0] = cs + a0 * a0 * C
                    Rj[0, 1] = a0 * a1 * C - a2 * sn
                    Rj[0, 2] = a0 * a2 * C + a1 * sn
                    Rj[1, 0] = a1 * a0 * C + a2 * sn
                    Rj[1, 1] = cs + a1 * a1 * C
                    Rj[1, 2] = a1 * a2 * C - a0 * sn
                    Rj[2, 0] = a2 * a0 * C - a1 * sn
                    Rj[2, 1] = a2 * a1 * C + a0 * sn
                    Rj[2, 2] = cs + a2 * a2 * C
                    for r in range(3):
                        jp[j, r] = pb[r]
                        for c in range(3):
                            jR[j, r, c] = Rb[r, 0] * Rj[0, c] + Rb[r, 1] * Rj[1, c] + Rb[r, 2] * Rj[2, c]
                else:
                    for r in range(3):
                        aw = Rb[r, 0] * a0 + Rb[r, 1] * a1 + Rb[r, 2] * a2
                        jp[j, r] = pb[r] + aw * v
                        for c in range(3):
                            jR[j, r, c] = Rb[r, c]
                for r in range(3):
                    ja[j, r] = jR[j, r, 0] * a0 + jR[j, r, 1] * a1 + jR[j, r, 2] * a2
            # body placements
            for b in range(nb):
                j = b_joint[b]
                for r in range(3):
                    acc = jp[j, r]
                    for c in range(3):
                        acc += jR[j, r, c] * b_p[b, c]
                        bR[b, r, c] = jR[j, r, 0] * b_R[b, 0, c] + jR[j, r, 1] * b_R[b, 1, c] \
                            + jR[j, r, 2] * b_R[b, 2, c]
                    bp[b, r] = acc
            # body Jacobian columns (omega, tau) per (body, coordinate)
            if want_ma:
                W[:] = 0.0
                T[:] = 0.0
                for j in range(nj):
                    c = j_coord[j]
                    w0 = ja[j, 0] * dvj[j]
                    w1 = ja[j, 1] * dvj[j]
                    w2 = ja[j, 2] * dvj[j]
                    if j_rev[j]:
                        t0 = jp[j, 1] * w2 - jp[j, 2] * w1
                        t1 = jp[j, 2] * w0 - jp[j, 0] * w2
                        t2 = jp[j, 0] * w1 - jp[j, 1] * w0
                        for b in range(nb):
                            if body_support[b, j]:
                                W[b, c, 0] += w0
                                W[b, c, 1] += w1
                                W[b, c, 2] += w2
                                T[b, c, 0] += t0
                                T[b, c, 1] += t1
                                T[b, c, 2] += t2
                    else:
                        for b in range(nb):
                            if body_support[b, j]:
                                T[b, c, 0] += w0
                                T[b, c, 1] += w1
                                T[b, c, 2] += w2
            # points
            for i in range(npnt):
                b = pt_body[i]
                loc0 = pt_local[i, 0]
                loc1 = pt_local[i, 1]
                loc2 = pt_local[i, 2]
                if pt_fn[i, 0] >= 0:
                    for ax in range(3):
                        cc = pt_fcoord[i, ax]
                        xq = q[t, cc] if cc >= 0 else 0.0
                        vv, dd = _feval(pt_fn[i, ax], xq, kind, scale, p0, p1, off, n, kx, ky, kb, kc, kd)
                        lv[ax] = vv
                        if cc >= 0:
                            for r in range(3):
                                dL[i, ax, r] = bR[b, r, ax] * dd
                    loc0, loc1, loc2 = lv[0], lv[1], lv[2]
                for r in range(3):
                    X[i, r] = bp[b, r] + bR[b, r, 0] * loc0 + bR[b, r, 1] * loc1 + bR[b, r, 2] * loc2
                cc = pt_cond[i]
                if cc >= 0:
                    act[i] = (q[t, cc] >= pt_lo[i]) and (q[t, cc] <= pt_hi[i])
                else:
                    act[i] = True
            # muscles
            F[:] = 0.0
            for m in range(M):
                total = 0.0
                prev = -1
                for i in range(m_start[m], m_end[m]):
                    if not act[i]:
                        continue
                    if prev >= 0:
                        d0 = X[i, 0] - X[prev, 0]
                        d1 = X[i, 1] - X[prev, 1]
                        d2 = X[i, 2] - X[prev, 2]
                        ln = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                        total += ln
                        if want_ma and ln > 0.0:
                            u0, u1, u2 = d0 / ln, d1 / ln, d2 / ln
                            F[prev, 0] += u0
                            F[prev, 1] += u1
                            F[prev, 2] += u2
                            F[i, 0] -= u0
                            F[i, 1] -= u1
                            F[i, 2] -= u2
                    prev = i
                L_out[t, m] = total
                if want_ma:
                    # per body of the path: sum of forces and of their moments about the origin
                    for sl in range(ms_start[m], ms_start[m + 1]):
                        for r in range(3):
                            SF[sl, r] = 0.0
                            SM[sl, r] = 0.0
                    for i in range(m_start[m], m_end[m]):
                        if not act[i]:
                            continue
                        sl = pt_slot[i]
                        f0, f1, f2 = F[i, 0], F[i, 1], F[i, 2]
                        SF[sl, 0] += f0
                        SF[sl, 1] += f1
                        SF[sl, 2] += f2
                        SM[sl, 0] += X[i, 1] * f2 - X[i, 2] * f1
                        SM[sl, 1] += X[i, 2] * f0 - X[i, 0] * f2
                        SM[sl, 2] += X[i, 0] * f1 - X[i, 1] * f0
                    for k in range(pair_start[m], pair_start[m + 1]):
                        c = pair_coord[k]
                        r_ = 0.0
                        for sl in range(ms_start[m], ms_start[m + 1]):
                            b = slot_body[sl]
                            r_ += (W[b, c, 0] * SM[sl, 0] + W[b, c, 1] * SM[sl, 1] + W[b, c, 2] * SM[sl, 2]
                                   + T[b, c, 0] * SF[sl, 0] + T[b, c, 1] * SF[sl, 1] + T[b, c, 2] * SF[sl, 2])
                        for i in range(m_start[m], m_end[m]):
                            if pt_fn[i, 0] >= 0 and act[i]:
                                for ax in range(3):
                                    if pt_fcoord[i, ax] == c:
                                        r_ += F[i, 0] * dL[i, ax, 0] + F[i, 1] * dL[i, ax, 1] \
                                            + F[i, 2] * dL[i, ax, 2]
                        R_out[t, k] = r_


    @njit(cache=True)
    def config_scratch(nj, nb, nc, npnt, nslot):
        """Scratch arrays of :func:`_one_config` for one thread (``jR[nj]``: the universe, identity)."""
        jR = np.empty((nj + 1, 3, 3))   # slot nj: the universe (identity), for bodies welded to ground
        jp = np.zeros((nj + 1, 3))
        for r in range(3):
            for c in range(3):
                jR[nj, r, c] = 1.0 if r == c else 0.0
        return (jR, jp, np.empty((nj, 3)), np.empty(nj), np.empty((3, 3)), np.empty(3), np.empty((3, 3)),
                np.empty((nb, 3, 3)), np.empty((nb, 3)), np.zeros((nb, nc, 3)), np.zeros((nb, nc, 3)),
                np.empty((npnt, 3)), np.zeros((npnt, 3, 3)), np.empty(npnt, dtype=np.bool_), np.zeros((npnt, 3)),
                np.empty(3), np.empty((nslot, 3)), np.empty((nslot, 3)))

    @njit(cache=True)
    def one_config_packed(t, q, want_ma, fa, sc, L_out, R_out):
        """:func:`_one_config` with the model arrays packed as :attr:`FastPaths.packed` and the scratch
        arrays as :func:`config_scratch` returns them."""
        (j_parent, j_R, j_p, j_axis, j_rev, j_coord, j_fn, b_joint, b_R, b_p, body_support,
         pt_body, pt_local, pt_fn, pt_fcoord, pt_cond, pt_lo, pt_hi, m_start, m_end, pair_start, pair_coord,
         kind, scale, p0, p1, off, n, kx, ky, kb, kc, kd, pt_slot, ms_start, slot_body) = fa
        (jR, jp, ja, dvj, Rb, pb, Rj, bR, bp, W, T, X, dL, act, F, lv, SF, SM) = sc
        _one_config(t, q, want_ma, j_parent, j_R, j_p, j_axis, j_rev, j_coord, j_fn,
                    b_joint, b_R, b_p, body_support,
                    pt_body, pt_local, pt_fn, pt_fcoord, pt_cond, pt_lo, pt_hi,
                    m_start, m_end, pair_start, pair_coord,
                    kind, scale, p0, p1, off, n, kx, ky, kb, kc, kd,
                    L_out, R_out, jR, jp, ja, dvj, Rb, pb, Rj, bR, bp, W, T, X, dL, act, F, lv,
                    pt_slot, ms_start, slot_body, SF, SM)

    @njit(cache=True, parallel=True)
    def _paths_kernel(q, want_ma, fa, sizes, L_out, R_out):
        """Lengths and moment arms of every configuration (``sizes``: :attr:`FastPaths.sizes`)."""
        N = q.shape[0]
        nj, nb, npnt, nslot = sizes
        nch = min(N, 64)
        for ch in prange(nch):
            sc = config_scratch(nj, nb, q.shape[1], npnt, nslot)
            for t in range(ch * N // nch, (ch + 1) * N // nch):
                one_config_packed(t, q, want_ma, fa, sc, L_out, R_out)


    @njit(cache=True)
    def _poses_kernel(q, j_parent, j_R, j_p, j_axis, j_rev, j_coord, j_fn, b_joint, b_R, b_p,
                      kind, scale, p0, p1, off, n, kx, ky, kb, kc, kd, bR, bp):
        """Body placements in ground (the kinematics part of ``_one_config``) for every configuration."""
        N = q.shape[0]
        nj = j_parent.shape[0]
        nb = b_joint.shape[0]
        jR = np.empty((nj + 1, 3, 3))
        jp = np.zeros((nj + 1, 3))
        for r in range(3):
            for c in range(3):
                jR[nj, r, c] = 1.0 if r == c else 0.0
        Rb = np.empty((3, 3))
        pb = np.empty(3)
        Rj = np.empty((3, 3))
        for t in range(N):
            for j in range(nj):
                v, _dv = _feval(j_fn[j], q[t, j_coord[j]], kind, scale, p0, p1, off, n, kx, ky, kb, kc, kd)
                par = j_parent[j]
                if par < 0:
                    for r in range(3):
                        pb[r] = j_p[j, r]
                        for c in range(3):
                            Rb[r, c] = j_R[j, r, c]
                else:
                    for r in range(3):
                        acc = jp[par, r]
                        for c in range(3):
                            acc += jR[par, r, c] * j_p[j, c]
                            s_ = 0.0
                            for k in range(3):
                                s_ += jR[par, r, k] * j_R[j, k, c]
                            Rb[r, c] = s_
                        pb[r] = acc
                a0, a1, a2 = j_axis[j, 0], j_axis[j, 1], j_axis[j, 2]
                if j_rev[j]:
                    sn, cs = np.sin(v), np.cos(v)
                    C = 1.0 - cs
                    Rj[0, 0] = cs + a0 * a0 * C
                    Rj[0, 1] = a0 * a1 * C - a2 * sn
                    Rj[0, 2] = a0 * a2 * C + a1 * sn
                    Rj[1, 0] = a1 * a0 * C + a2 * sn
                    Rj[1, 1] = cs + a1 * a1 * C
                    Rj[1, 2] = a1 * a2 * C - a0 * sn
                    Rj[2, 0] = a2 * a0 * C - a1 * sn
                    Rj[2, 1] = a2 * a1 * C + a0 * sn
                    Rj[2, 2] = cs + a2 * a2 * C
                    for r in range(3):
                        jp[j, r] = pb[r]
                        for c in range(3):
                            jR[j, r, c] = Rb[r, 0] * Rj[0, c] + Rb[r, 1] * Rj[1, c] + Rb[r, 2] * Rj[2, c]
                else:
                    for r in range(3):
                        aw = Rb[r, 0] * a0 + Rb[r, 1] * a1 + Rb[r, 2] * a2
                        jp[j, r] = pb[r] + aw * v
                        for c in range(3):
                            jR[j, r, c] = Rb[r, c]
            for b in range(nb):
                j = b_joint[b]
                for r in range(3):
                    acc = jp[j, r]
                    for c in range(3):
                        acc += jR[j, r, c] * b_p[b, c]
                        bR[t, b, r, c] = jR[j, r, 0] * b_R[b, 0, c] + jR[j, r, 1] * b_R[b, 1, c] \
                            + jR[j, r, 2] * b_R[b, 2, c]
                    bp[t, b, r] = acc


class FastPaths:
    """Compiled evaluator for a :class:`~pamkin.human.paths.PathSet` (same results, much faster)."""

    def __init__(self, paths) -> None:
        if numba is None:
            raise ImportError("numba is required for the compiled path evaluator (pip install numba)")
        kin = paths.kin
        ft = FunctionTable()
        self.j_fn = np.array([ft.add(fn) for fn in kin._functions], dtype=np.int64)
        self.j_parent = kin._parent.astype(np.int64)
        self.j_R = np.ascontiguousarray(kin._placement_R)
        self.j_p = np.ascontiguousarray(kin._placement_p)
        self.j_axis = np.ascontiguousarray(kin._axis)
        self.j_rev = kin._revolute.copy()
        self.j_coord = kin._coord_of_joint.astype(np.int64)
        self.b_joint = kin._body_joint.astype(np.int64)
        self.b_R = np.ascontiguousarray(kin._body_R)
        self.b_p = np.ascontiguousarray(kin._body_p)
        self.body_support = kin.body_support.copy()
        # points in path order (PathSet numbers points path by path, in order)
        P = paths.n_points
        self.pt_body = paths.point_body.astype(np.int64)
        self.pt_local = np.ascontiguousarray(paths.point_local)
        self.pt_fn = -np.ones((P, 3), dtype=np.int64)
        self.pt_fcoord = -np.ones((P, 3), dtype=np.int64)
        coord_index = {c: i for i, c in enumerate(kin.coordinates)}
        for pid, pt in paths._moving:
            for ax in range(3):
                self.pt_fn[pid, ax] = ft.add(pt.functions[ax])
                cn = pt.coordinates[ax]
                self.pt_fcoord[pid, ax] = coord_index[cn] if cn else -1
        self.pt_cond = -np.ones(P, dtype=np.int64)
        self.pt_lo = np.zeros(P)
        self.pt_hi = np.zeros(P)
        for k, pid in enumerate(paths._cond_ids):
            self.pt_cond[pid] = paths._cond_coord[k]
            self.pt_lo[pid] = paths._cond_lo[k]
            self.pt_hi[pid] = paths._cond_hi[k]
        self.m_start = np.array(paths._path_start, dtype=np.int64)
        self.m_end = np.array(paths._path_end, dtype=np.int64)
        pairs = paths.pairs
        counts = np.bincount(pairs[:, 0], minlength=paths.n_paths) if len(pairs) else np.zeros(paths.n_paths, int)
        self.pair_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.pair_coord = pairs[:, 1].astype(np.int64) if len(pairs) else np.zeros(0, np.int64)
        self.ftab = ft.arrays()
        # distinct bodies of each path ("slots") and each point's slot
        slot_body, ms_start, pt_slot = [], [0], np.zeros(P, dtype=np.int64)
        for m in range(paths.n_paths):
            seen: dict[int, int] = {}
            for i in range(paths._path_start[m], paths._path_end[m]):
                b = int(self.pt_body[i])
                if b not in seen:
                    seen[b] = len(slot_body)
                    slot_body.append(b)
                pt_slot[i] = seen[b]
            ms_start.append(len(slot_body))
        self.pt_slot = pt_slot
        self.ms_start = np.array(ms_start, dtype=np.int64)
        self.slot_body = np.array(slot_body, dtype=np.int64)
        self.n_paths = paths.n_paths
        self.n_pairs = len(pairs)
        #: The model arrays in :func:`_one_config`'s order (the compiled kernels take them as one tuple).
        self.packed = (self.j_parent, self.j_R, self.j_p, self.j_axis, self.j_rev, self.j_coord, self.j_fn,
                       self.b_joint, self.b_R, self.b_p, self.body_support, self.pt_body, self.pt_local,
                       self.pt_fn, self.pt_fcoord, self.pt_cond, self.pt_lo, self.pt_hi, self.m_start,
                       self.m_end, self.pair_start, self.pair_coord, *self.ftab, self.pt_slot, self.ms_start,
                       self.slot_body)
        #: (joints, frames, path points, path body slots): the sizes of :func:`config_scratch`.
        self.sizes = (len(self.j_parent), len(self.b_joint), len(self.pt_body), len(self.slot_body))

    def body_poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body placements in ground: (N, n_frames, 3, 3) and (N, n_frames, 3), frames as
        :attr:`pamkin.human.kinematics.Kinematics.frames` (bodies, then ground); ``q`` with dependent
        coordinates filled."""
        q = np.ascontiguousarray(q, dtype=np.float64)
        nb = self.b_joint.shape[0]
        bR = np.empty((q.shape[0], nb, 3, 3))
        bp = np.empty((q.shape[0], nb, 3))
        _poses_kernel(q, self.j_parent, self.j_R, self.j_p, self.j_axis, self.j_rev, self.j_coord, self.j_fn,
                      self.b_joint, self.b_R, self.b_p, *self.ftab, bR, bp)
        return bR, bp

    def evaluate(self, q: np.ndarray, moment_arms: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Lengths (N, n_paths) and moment arms (N, n_pairs) (pairs as ``PathSet.pairs``)."""
        q = np.ascontiguousarray(q, dtype=np.float64)
        N = q.shape[0]
        L = np.empty((N, self.n_paths))
        R = np.empty((N, self.n_pairs)) if moment_arms else np.empty((N, 0))
        _paths_kernel(q, moment_arms, self.packed, self.sizes, L, R)
        return L, (R if moment_arms else None)
