"""Tendon lengths and moment arms of a MuJoCo model at OpenSim configurations, and their errors against pamkin.

A configuration q (pamkin's coordinates) sets MuJoCo's joints through :meth:`CoordinateMap.qpos` (tied joints
at their polynomial, which MuJoCo's joint equalities hold). Lengths are ``ten_length``; the moment arm about a
coordinate is −dL/dq = −Σ_j ``ten_J``[j] · dqpos_j/dq, the total derivative through the tied joints (what
OpenSim's moment arms are about an independent coordinate).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from pamkin.sim.joints import CoordinateMap
from pamkin.sim.mjcf import safe


class MjGeometry:
    """Evaluate tendons of ``model`` (a compiled MuJoCo model of ``cmap``'s joints).

    Args:
        model: The MuJoCo model.
        cmap: Its coordinate map.
        tendons: Tendon names (columns of the results).
    """

    def __init__(self, model: mujoco.MjModel, cmap: CoordinateMap, tendons: list[str]) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.cmap = cmap
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, safe(j.name)) for j in cmap.joints]
        self.qadr = np.array([model.jnt_qposadr[i] for i in ids])
        self.dadr = np.array([model.jnt_dofadr[i] for i in ids])
        self.tendon_ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, safe(t)) for t in tendons],
                                   dtype=int)
        self._rows, self._cols = tendon_jacobian_pattern(model)

    def set_pose(self, qpos_row: np.ndarray) -> None:
        """Put MuJoCo joint values (in :attr:`CoordinateMap.joints` order) and compute positions and tendons."""
        d = self.data
        d.qpos[self.qadr] = qpos_row
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)
        mujoco.mj_tendon(self.model, d)

    def lengths(self, q: np.ndarray) -> np.ndarray:
        """(N, n_tendons) lengths [m] at configurations q (N, n_coordinates)."""
        return self.evaluate(q, moment_arms=False)[0]

    def evaluate(self, q: np.ndarray, moment_arms: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Lengths (N, n_tendons) [m] and moment arms (N, n_tendons, n_coordinates) [m, or m/m]."""
        q = np.atleast_2d(q)
        qpos = self.cmap.qpos(q)
        G = self.cmap.dqpos_dq(q) if moment_arms else None
        L = np.empty((len(q), len(self.tendon_ids)))
        R = np.empty((len(q), len(self.tendon_ids), q.shape[1])) if moment_arms else None
        for n in range(len(q)):
            self.set_pose(qpos[n])
            L[n] = self.data.ten_length[self.tendon_ids]
            if moment_arms:
                J = self.tendon_jacobian()[self.tendon_ids][:, self.dadr]
                R[n] = -J @ G[n]
        return L, R

    def tendon_jacobian(self) -> np.ndarray:
        """(n_tendons, nv) dense tendon Jacobian dL/dqvel of the current pose (MuJoCo stores it sparse)."""
        J = np.zeros((self.model.ntendon, self.model.nv))
        J[self._rows, self._cols] = self.data.ten_J[: len(self._rows)]
        return J


def tendon_jacobian_pattern(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """(rows, columns) of the entries of MuJoCo's sparse ``ten_J`` (in storage order), fixed per model."""
    rows, cols = [], []
    for t in range(model.ntendon):
        a, n = model.ten_J_rowadr[t], model.ten_J_rownnz[t]
        rows += [t] * n
        cols += list(model.ten_J_colind[a:a + n])
    return np.array(rows, dtype=int), np.array(cols, dtype=int)


@dataclass
class GeometryErrors:
    """Per-path errors of MuJoCo against pamkin on a set of poses.

    Attributes:
        names: Path names.
        length_max, length_p99: |ΔL| largest and 99th percentile per path [m].
        arm_max, arm_p99: largest and 99th percentile |Δr| over the path's coordinates and poses [m].
        length_max_out, arm_max_out: the largest errors over the poses outside the path's conditional steps'
            bands (:func:`compare` ``outside``; equal to the maxima without steps) [m].
        band_poses: poses inside the path's steps' bands.
    """

    names: list[str]
    length_max: np.ndarray
    length_p99: np.ndarray
    arm_max: np.ndarray
    arm_p99: np.ndarray
    length_max_out: np.ndarray | None = None
    arm_max_out: np.ndarray | None = None
    band_poses: np.ndarray | None = None

    def rows(self) -> list[dict]:
        return [{"path": n, "length_max_m": float(a), "length_p99_m": float(b), "arm_max_m": float(c),
                 "arm_p99_m": float(d)} for n, a, b, c, d in zip(self.names, self.length_max, self.length_p99,
                                                                 self.arm_max, self.arm_p99)]


def compare(names: list[str], L: np.ndarray, R: np.ndarray, Lref: np.ndarray, Rref: np.ndarray,
            coordinates: np.ndarray | None = None, outside: np.ndarray | None = None) -> GeometryErrors:
    """Errors of lengths L (N, M) and moment arms R (N, M, C) against the references, moment arms over the
    coordinate columns ``coordinates`` (default all); ``outside`` (N, M): poses counted in the outside-band
    maxima (default all)."""
    if not len(names):
        empty = np.zeros(0)
        return GeometryErrors([], empty, empty, empty, empty, empty, empty, np.zeros(0, int))
    dL = np.abs(L - Lref)
    dR = np.abs(R - Rref)
    if coordinates is not None:
        dR = dR[:, :, coordinates]
    dRp = dR.max(axis=2)                                       # (N, M) worst coordinate per pose
    out = np.ones_like(dL, bool) if outside is None else outside
    dR = np.moveaxis(dR, 1, 0).reshape(len(names), -1)
    return GeometryErrors(list(names), dL.max(axis=0), np.percentile(dL, 99, axis=0), dR.max(axis=1),
                          np.percentile(dR, 99, axis=1), np.where(out, dL, 0).max(axis=0),
                          np.where(out, dRp, 0).max(axis=0), (~out).sum(axis=0))
