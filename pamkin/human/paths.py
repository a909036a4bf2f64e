"""Straight-line musculotendon paths: lengths and moment arms, batched over configurations.

A path is a sequence of points fixed in bodies (``PathPoint``), fixed points present
only while a coordinate lies in a range (``ConditionalPathPoint``; OpenSim includes
them when ``min − 1e-5 ≤ q ≤ max + 1e-5``) and points whose location in their body is
a function of coordinates (``MovingPathPoint``).

Formulas (N configurations at once, no finite differences):

* length L = Σ_segments |x_b − x_a|;
* moment arm r_c = −∂L/∂q_c = Σ_i f_i · ∂x_i/∂q_c, where f_i = u_out − u_in is the
  net unit-tension force on point i (u: unit segment directions) and
  ∂x_i/∂q_c = ω_bc × x_i + τ_bc + R_b ∂ℓ_i/∂q_c: (ω_bc, τ_bc) is body b's
  velocity Jacobian column for coordinate c (angular part, and velocity of the body
  point at the ground origin) including the coordinate couplings, and ℓ_i is the
  local location of a moving point.

Summing per (path, body) first, r_c = Σ_b ω_bc·(Σ_i x_i × f_i) + τ_bc·(Σ_i f_i).
:func:`path_length` and :func:`path_moment_arm` state the same formula for a single
path on any array type with row indexing (numpy arrays or CasADi matrices of
shape (3, S)): the attachment-point optimiser evaluates them on symbolic points.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pamkin.human.kinematics import Kinematics, KinematicsState
from pamkin.opensim.model_file import (
    AnyPathPoint,
    ConditionalPathPoint,
    MovingPathPoint,
)

#: OpenSim's hard-coded tolerance on ConditionalPathPoint ranges [rad or m].
CONDITIONAL_TOLERANCE = 1e-5


# ----------------------------------------------------------------------------- generic formulas
def _norm_cols(d, xp):
    return xp.sqrt(d[0, :] * d[0, :] + d[1, :] * d[1, :] + d[2, :] * d[2, :])


def _cross_cols(w, x):
    """Column-wise cross product of (3, S) arrays (numpy or CasADi), as a list of rows."""
    return [w[1, :] * x[2, :] - w[2, :] * x[1, :],
            w[2, :] * x[0, :] - w[0, :] * x[2, :],
            w[0, :] * x[1, :] - w[1, :] * x[0, :]]


def path_length(points: Sequence, xp=np):
    """Length of a straight-line path through ``points`` (each (3, S) world positions) [m].

    Works on numpy arrays and CasADi matrices (pass ``xp=casadi``). Returns a (S,) numpy
    array or a (1, S) CasADi row.
    """
    total = 0
    for a, b in zip(points[:-1], points[1:]):
        total = total + _norm_cols(b - a, xp)
    return total


def path_moment_arm(points: Sequence, velocities: Sequence, xp=np):
    """Moment arm −∂L/∂q of a path for one coordinate [m] (or [m/m] for translations).

    Args:
        points: World positions x_i, each (3, S).
        velocities: ∂x_i/∂q for the coordinate, each (3, S) (numeric or symbolic),
            e.g. ``omega × x_i + tau`` from :meth:`PathSet.body_jacobian`.
        xp: ``numpy`` or ``casadi``.
    """
    r = 0
    for a, b, va, vb in zip(points[:-1], points[1:], velocities[:-1], velocities[1:]):
        d = b - a
        n = _norm_cols(d, xp)
        dv = va - vb
        r = r + (d[0, :] * dv[0, :] + d[1, :] * dv[1, :] + d[2, :] * dv[2, :]) / n
    return r


def point_velocity(omega, tau, x, xp=np):
    """∂x/∂q = ω × x + τ for a point x (3, S) fixed in a body with Jacobian column (ω, τ)."""
    c = _cross_cols(omega, x)
    if xp is np:
        return np.stack(c) + tau
    return xp.vertcat(*c) + tau


# ----------------------------------------------------------------------------- batched engine
@dataclass(frozen=True)
class PathResult:
    """Lengths and moment arms of many paths at N configurations.

    Attributes:
        lengths: (N, n_paths) [m].
        pairs: (K, 2) (path index, coordinate index) pairs whose moment arm can be non-zero.
        moment_arms: (N, K) moment arms of ``pairs`` [m or m/m]; None when not requested.
    """

    lengths: np.ndarray
    pairs: np.ndarray
    moment_arms: np.ndarray | None

    def dense_moment_arms(self, n_coordinates: int) -> np.ndarray:
        """(N, n_paths, n_coordinates) moment arms, zero where a path spans no joint of the coordinate."""
        N, M = self.lengths.shape
        out = np.zeros((N, M, n_coordinates))
        if self.moment_arms is not None:
            out[:, self.pairs[:, 0], self.pairs[:, 1]] = self.moment_arms
        return out


def _reduce_sorted(values: np.ndarray, starts: np.ndarray, n_out: int, axis: int = 1) -> np.ndarray:
    """Sum contiguous runs (values sorted by output index; ``starts`` the first index of each)."""
    if values.shape[axis] == 0:
        shape = list(values.shape)
        shape[axis] = n_out
        return np.zeros(shape)
    return np.add.reduceat(values, starts, axis=axis)


class PathSet:
    """Compiled straight-line paths of many muscles (or PAMs) on one model.

    Args:
        kin: The model's kinematics.
        names: Path names.
        paths: Each path's points (origin first). ``ConditionalPathPoint`` may not be
            the first or last point.
    """

    def __init__(self, kin: Kinematics, names: Sequence[str], paths: Sequence[Sequence[AnyPathPoint]]):
        self.kin = kin
        self.names = list(names)
        nb, nc = len(kin.frames), len(kin.coordinates)
        body_index = {b: i for i, b in enumerate(kin.frames)}   # bodies, then ground
        coord_index = {c: i for i, c in enumerate(kin.coordinates)}

        # unique points
        fixed_body, fixed_loc, moving = [], [], []
        point_ids: list[list[int]] = []
        cond: dict[int, tuple[int, float, float]] = {}   # point id -> (coord, lo, hi)
        self._path_start, self._path_end = [], []
        for path in paths:
            self._path_start.append(len(fixed_body))
            ids = []
            for pt in path:
                pid = len(fixed_body)
                if pt.body not in body_index:
                    raise ValueError(f"path point {pt.name!r} is on unknown body {pt.body!r}")
                fixed_body.append(body_index[pt.body])
                if isinstance(pt, MovingPathPoint):
                    fixed_loc.append((0.0, 0.0, 0.0))
                    moving.append((pid, pt))
                else:
                    fixed_loc.append(pt.location)
                if isinstance(pt, ConditionalPathPoint):
                    cond[pid] = (coord_index[pt.coordinate], pt.range[0], pt.range[1])
                ids.append(pid)
            point_ids.append(ids)
            self._path_end.append(len(fixed_body))
        self.n_points = len(fixed_body)
        self.point_body = np.array(fixed_body, dtype=int)
        self.point_local = np.array(fixed_loc, dtype=float).reshape(-1, 3)
        self._moving = moving
        self._moving_ids = np.array([pid for pid, _ in moving], dtype=int)
        self._cond_ids = np.array(sorted(cond), dtype=int)
        self._cond_coord = np.array([cond[i][0] for i in self._cond_ids], dtype=int)
        self._cond_lo = np.array([cond[i][1] for i in self._cond_ids]) - CONDITIONAL_TOLERANCE
        self._cond_hi = np.array([cond[i][2] for i in self._cond_ids]) + CONDITIONAL_TOLERANCE
        cond_pos = {pid: k for k, pid in enumerate(self._cond_ids)}

        # path variants: one per pattern of present/absent conditional points
        var_path, var_cond = [], []     # variant -> path; list of (cond index, present)
        seg_a, seg_b, seg_var = [], [], []
        occ_point, occ_var, occ_prev, occ_next = [], [], [], []
        for m, ids in enumerate(point_ids):
            if ids and (ids[0] in cond or ids[-1] in cond):
                raise ValueError(f"path {self.names[m]!r}: first/last point cannot be conditional")
            conds = [i for i in ids if i in cond]
            for pattern in itertools.product((True, False), repeat=len(conds)):
                v = len(var_path)
                present = dict(zip(conds, pattern))
                var_path.append(m)
                var_cond.append([(cond_pos[i], p) for i, p in present.items()])
                seq = [i for i in ids if present.get(i, True)]
                first_seg = len(seg_a)
                for a, b in zip(seq[:-1], seq[1:]):
                    seg_a.append(a)
                    seg_b.append(b)
                    seg_var.append(v)
                for k, pid in enumerate(seq):
                    occ_point.append(pid)
                    occ_var.append(v)
                    occ_prev.append(first_seg + k - 1 if k > 0 else -1)
                    occ_next.append(first_seg + k if k < len(seq) - 1 else -1)
        self.n_paths = len(point_ids)
        self.n_variants = len(var_path)
        self._var_path = np.array(var_path, dtype=int)
        self._var_cond = var_cond
        self._seg_a = np.array(seg_a, dtype=int)
        self._seg_b = np.array(seg_b, dtype=int)
        seg_var = np.array(seg_var, dtype=int)
        self._seg_starts = np.searchsorted(seg_var, np.arange(self.n_variants))
        n_seg = len(seg_a)
        occ_prev = np.array(occ_prev, dtype=int)
        occ_next = np.array(occ_next, dtype=int)
        self._occ_prev = np.where(occ_prev < 0, n_seg, occ_prev)   # index n_seg: zero direction
        self._occ_next = np.where(occ_next < 0, n_seg, occ_next)
        occ_point = np.array(occ_point, dtype=int)
        occ_var = np.array(occ_var, dtype=int)
        # groups (variant, body): sort occurrences by group
        occ_body = self.point_body[occ_point]
        group_key = occ_var * nb + occ_body
        order = np.argsort(group_key, kind="stable")
        self._occ_order = order
        self._occ_point = occ_point
        keys_sorted = group_key[order]
        uniq, starts = np.unique(keys_sorted, return_index=True)
        self._group_starts = starts
        self._group_var = uniq // nb
        self._group_body = uniq % nb
        group_of_key = {int(k): g for g, k in enumerate(uniq)}
        self._occ_group = np.array([group_of_key[int(k)] for k in group_key], dtype=int)

        # spanned (variant, coordinate) pairs: some but not all of the variant's bodies move with c
        support_c = np.zeros((nb, nc), dtype=bool)  # body b moves with coordinate c
        for j in range(kin.n_joints):
            support_c[kin.body_support[:, j], kin.coord_of_joint[j]] = True
        var_pairs, terms_pair, terms_group = [], [], []
        var_groups: dict[int, list[int]] = {}
        for g, v in enumerate(self._group_var):
            var_groups.setdefault(int(v), []).append(g)
        for v in range(self.n_variants):
            gs = var_groups.get(v, [])
            bodies = [int(self._group_body[g]) for g in gs]
            for c in range(nc):
                moved = [support_c[b, c] for b in bodies]
                moving_here = any(cn == kin.coordinates[c] for pid, pt in moving
                                  if pid in set(occ_point[occ_var == v]) for cn in pt.coordinates)
                if (any(moved) and not all(moved)) or moving_here:
                    k = len(var_pairs)
                    var_pairs.append((v, c))
                    for g, b, mv in zip(gs, bodies, moved):
                        if mv:
                            terms_pair.append(k)
                            terms_group.append(g)
        self._var_pairs = np.array(var_pairs, dtype=int).reshape(-1, 2)
        terms_pair = np.array(terms_pair, dtype=int)
        terms_group = np.array(terms_group, dtype=int)
        order_t = np.argsort(terms_pair, kind="stable")
        self._term_group = terms_group[order_t]
        tp = terms_pair[order_t]
        self._term_bc = self._group_body[self._term_group] * nc + self._var_pairs[tp, 1]
        self._term_starts = np.searchsorted(tp, np.arange(len(var_pairs)))
        self._pairs_with_terms = np.unique(tp)
        # body-coordinate Jacobian columns that are needed
        used_bc, bc_index = np.unique(self._term_bc, return_inverse=True)
        self._used_bc = used_bc
        self._term_bc_index = bc_index
        sel = np.zeros((len(used_bc), kin.n_joints))
        for u, bc in enumerate(used_bc):
            b, c = divmod(int(bc), nc)
            sel[u] = kin.body_support[b] & (kin.coord_of_joint == c)
        self._bc_select = sel
        # moving-point terms: (pair, occurrence, axis function)
        pair_index = {(int(v), int(c)): k for k, (v, c) in enumerate(self._var_pairs)}
        mv_terms = []
        moving_of = {pid: pt for pid, pt in moving}
        for o, (pid, v) in enumerate(zip(occ_point, occ_var)):
            if pid in moving_of:
                pt = moving_of[pid]
                for ax, cn in enumerate(pt.coordinates):
                    if cn:
                        mv_terms.append((pair_index[(int(v), coord_index[cn])], o, pid, ax))
        self._mv_terms = mv_terms
        # path-level pairs (union over variants)
        path_pairs = sorted({(int(self._var_path[v]), int(c)) for v, c in self._var_pairs})
        self.pairs = np.array(path_pairs, dtype=int).reshape(-1, 2)
        pp_index = {p: k for k, p in enumerate(path_pairs)}
        self._varpair_to_pair = np.array([pp_index[(int(self._var_path[v]), int(c))]
                                          for v, c in self._var_pairs], dtype=int)
        self._has_variants = self.n_variants != self.n_paths

    # ------------------------------------------------------------------
    def point_positions(self, state: KinematicsState) -> tuple[np.ndarray, np.ndarray]:
        """World positions (N, P, 3) of every path point and local moving-point derivatives.

        Returns:
            (X, dlocal): ``dlocal`` (N, n_moving, 3, 3) holds ∂ℓ/∂q_axis-coordinate per
            location axis (only the axis' own component is non-zero).
        """
        N = state.q.shape[0]
        local = np.broadcast_to(self.point_local, (N, self.n_points, 3)).copy()
        dlocal = np.zeros((N, len(self._moving), 3))
        for k, (pid, pt) in enumerate(self._moving):
            for ax in range(3):
                cn = pt.coordinates[ax]
                qv = state.q[:, self.kin.coordinates.index(cn)] if cn else np.zeros(N)
                local[:, pid, ax] = pt.functions[ax].value(qv)
                if cn:
                    dlocal[:, k, ax] = pt.functions[ax].derivative(qv)
        R = state.body_R[:, self.point_body]
        X = state.body_p[:, self.point_body] + np.einsum("npij,npj->npi", R, local)
        return X, dlocal

    def polylines(self, state: KinematicsState, k: int = 0) -> list[np.ndarray]:
        """World positions of the points in effect on every path at configuration ``k`` [m].

        Returns:
            One (n_points_in_effect, 3) array per path, origin first; a ConditionalPathPoint
            appears only while its coordinate lies in its range (OpenSim's tolerance).
        """
        X = self.point_positions(state)[0][k]
        keep = np.ones(self.n_points, dtype=bool)
        v = state.q[k, self._cond_coord]
        keep[self._cond_ids] = (v >= self._cond_lo) & (v <= self._cond_hi)
        return [X[a:b][keep[a:b]] for a, b in zip(self._path_start, self._path_end)]

    def variant_masks(self, q: np.ndarray) -> np.ndarray:
        """(N, n_variants) boolean: which path variant is in effect at each configuration."""
        N = q.shape[0]
        present = (q[:, self._cond_coord] >= self._cond_lo) & (q[:, self._cond_coord] <= self._cond_hi)
        masks = np.ones((N, self.n_variants), dtype=bool)
        for v, conds in enumerate(self._var_cond):
            for k, p in conds:
                masks[:, v] &= present[:, k] if p else ~present[:, k]
        return masks

    def body_jacobian(self, state: KinematicsState) -> tuple[np.ndarray, np.ndarray]:
        """Body velocity Jacobian columns (ω, τ), each (N, n_bodies, n_coordinates, 3).

        A point x fixed in body b moves with coordinate c at ∂x/∂q_c = ω × x + τ.
        """
        kin = self.kin
        N = state.q.shape[0]
        wj, tj = self._joint_twists(state)
        nb, nc = len(kin.frames), len(kin.coordinates)
        W = np.zeros((N, nb, nc, 3))
        T = np.zeros((N, nb, nc, 3))
        for b in range(nb):
            for j in np.nonzero(kin.body_support[b])[0]:
                W[:, b, kin.coord_of_joint[j]] += wj[:, j]
                T[:, b, kin.coord_of_joint[j]] += tj[:, j]
        return W, T

    def _joint_twists(self, state: KinematicsState) -> tuple[np.ndarray, np.ndarray]:
        rev = np.array([self.kin._revolute[j] for j in range(self.kin.n_joints)])
        a = state.joint_axis * state.dv_dq[:, :, None]
        wj = np.where(rev[None, :, None], a, 0.0)
        tj = np.where(rev[None, :, None], np.cross(state.joint_p, a), a)
        return wj, tj

    def evaluate(self, state: KinematicsState, moment_arms: bool = True) -> PathResult:
        """Lengths (and moment arms) of every path at the configurations of ``state``."""
        X, dlocal = self.point_positions(state)
        N = X.shape[0]
        d = X[:, self._seg_b] - X[:, self._seg_a]
        n = np.sqrt(np.einsum("nsk,nsk->ns", d, d))
        Lv = _reduce_sorted(n, self._seg_starts, self.n_variants)
        masks = self.variant_masks(state.q) if self._has_variants else None
        L = self._to_paths(Lv, masks)
        if not moment_arms:
            return PathResult(L, self.pairs, None)
        with np.errstate(invalid="ignore", divide="ignore"):
            u = np.where(n[..., None] > 0, d / n[..., None], 0.0)
        u = np.concatenate([u, np.zeros((N, 1, 3))], axis=1)
        f = u[:, self._occ_next] - u[:, self._occ_prev]                      # (N, O, 3)
        xo = X[:, self._occ_point]
        m = np.cross(xo, f)
        fs, ms = f[:, self._occ_order], m[:, self._occ_order]
        F = np.add.reduceat(fs, self._group_starts, axis=1)                 # (N, G, 3)
        Mx = np.add.reduceat(ms, self._group_starts, axis=1)
        wj, tj = self._joint_twists(state)
        Wu = np.matmul(self._bc_select, wj)                                  # (N, U, 3)
        Tu = np.matmul(self._bc_select, tj)
        terms = (np.einsum("ntk,ntk->nt", Wu[:, self._term_bc_index], Mx[:, self._term_group])
                 + np.einsum("ntk,ntk->nt", Tu[:, self._term_bc_index], F[:, self._term_group]))
        rv = np.zeros((N, len(self._var_pairs)))
        if terms.shape[1]:
            sums = np.add.reduceat(terms, self._term_starts[self._pairs_with_terms], axis=1)
            rv[:, self._pairs_with_terms] = sums
        for k, o, pid, ax in self._mv_terms:
            mi = [p for p, _ in self._moving].index(pid)
            b = self.point_body[pid]
            dl = state.body_R[:, b, :, ax] * dlocal[:, mi, ax, None]
            rv[:, k] += np.einsum("nk,nk->n", f[:, o], dl)
        if masks is not None:
            rv = rv * masks[:, self._var_pairs[:, 0]]
        r = np.zeros((N, len(self.pairs)))
        np.add.at(r.T, self._varpair_to_pair, rv.T)
        return PathResult(L, self.pairs, r)

    def _to_paths(self, values_v: np.ndarray, masks: np.ndarray | None) -> np.ndarray:
        if masks is None:
            return values_v
        out = np.zeros((values_v.shape[0], self.n_paths))
        np.add.at(out.T, self._var_path, (values_v * masks).T)
        return out
