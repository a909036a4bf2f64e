"""Kinematics of an imported model in OpenSim coordinates, from its Pinocchio model.

The URDF (generated from the ``.osim`` through Xacro) has one Pinocchio joint per
variable OpenSim ``TransformAxis``; its value is the axis function of an OpenSim
coordinate (e.g. the knee translations are SimmSplines of knee angle). This module
maps OpenSim coordinates q to Pinocchio's configuration v = f(q) with dv/dq, and
evaluates body placements and point Jacobians with respect to q.

CoordinateCouplerConstraints: a dependent coordinate always follows its coupler,
``q_dep = scale · f(q_indep)``; :meth:`Kinematics.as_q` overwrites the dependent columns of every
configuration from the independent ones (the values given there are ignored), and derivatives
with respect to an independent coordinate are total derivatives (they include the coupling, as
OpenSim's moment arms do). A dependent coordinate is not a degree of freedom: derivatives with
respect to it are reported as 0 (:meth:`Kinematics.chain_dependent`).

Two evaluators share one model description:

* :meth:`Kinematics.pinocchio_placements` — Pinocchio itself, one configuration at a
  time (the reference);
* :meth:`Kinematics.forward` — the same joint tree evaluated for a whole batch of
  configurations at once with numpy (what paths and torques use; tested against
  Pinocchio to round-off).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from pamkin.errors import ConfigurationError, RangeWarning
from pamkin.opensim.model_file import GROUND, OsimModel

#: Configurations accepted by the public API: an (N, n) or (n,) array in model
#: coordinate order, or a mapping coordinate name -> scalar or (N,) array.
ConfigLike = np.ndarray | Mapping[str, object]

#: Values within this distance of a coordinate range are not flagged [rad or m]: .osim files
#: store ranges rounded (Gait2392's knee minimum −2.0943951 is 2.4e-9 above −120°).
RANGE_TOLERANCE = 1e-8


@dataclass(frozen=True)
class KinematicsState:
    """Kinematics of a batch of N configurations (the 'evaluated state').

    Attributes:
        q: (N, n_coordinates) OpenSim coordinates [rad, m], read-only.
        joint_R: (N, n_joints, 3, 3) orientation of each Pinocchio joint frame in ground.
        joint_p: (N, n_joints, 3) origin of each Pinocchio joint frame in ground [m].
        joint_axis: (N, n_joints, 3) unit motion axis of each joint in ground.
        dv_dq: (N, n_joints) derivative of each joint value w.r.t. its OpenSim coordinate.
        body_R: (N, n_bodies + 1, 3, 3) orientation of each body frame in ground (ground itself last).
        body_p: (N, n_bodies + 1, 3) origin of each body frame in ground [m] (ground last).
    """

    q: np.ndarray
    joint_R: np.ndarray
    joint_p: np.ndarray
    joint_axis: np.ndarray
    dv_dq: np.ndarray
    body_R: np.ndarray
    body_p: np.ndarray


@dataclass(frozen=True)
class JointTree:
    """The joint tree :meth:`Kinematics.forward` evaluates, as arrays (for other evaluators, e.g. CasADi's).

    Joint j (one per variable OpenSim TransformAxis) sits at ``placement`` in its parent joint's frame (``parent``
    -1: ground) and moves by v = ``functions[j]``(q[``coordinate[j]``]): a rotation about ``axis`` (``revolute``)
    or a translation along it [rad or m]. Body frame b (:attr:`Kinematics.frames`, ground last) sits at
    (``body_R``, ``body_p``) in joint ``body_joint[b]`` (index n_joints: ground).
    """

    parent: np.ndarray
    placement_R: np.ndarray
    placement_p: np.ndarray
    axis: np.ndarray
    revolute: np.ndarray
    coordinate: np.ndarray
    functions: tuple
    body_joint: np.ndarray
    body_R: np.ndarray
    body_p: np.ndarray


def _rodrigues(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations about a fixed unit ``axis`` (3,) by ``angle`` (N,) [rad]."""
    k = axis
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


class Kinematics:
    """Kinematics of an OpenSim model through its Pinocchio (URDF) model.

    Args:
        osim: The imported OpenSim model.
        pin_model: The Pinocchio model built from the generated URDF.
    """

    def __init__(self, osim: OsimModel, pin_model) -> None:
        import pinocchio as pin  # noqa: PLC0415

        self.osim = osim
        self.pin_model = pin_model
        self.pin_data = pin_model.createData()
        self.coordinates: list[str] = [c.name for c in osim.coordinates]
        self.bodies: list[str] = [b.name for b in osim.bodies]
        self._coord_index = {n: i for i, n in enumerate(self.coordinates)}
        self.ranges = np.array([c.range for c in osim.coordinates], dtype=float)
        self.defaults = np.array([c.default_value for c in osim.coordinates], dtype=float)
        self.rotational = np.array([c.rotational for c in osim.coordinates], dtype=bool)
        # couplers in topological order (independent coordinates computed first)
        self.couplers = []
        by_dep = {k.dependent: k for k in osim.couplers}
        done: set[str] = set()

        def visit(name: str) -> None:
            if name in done or name not in by_dep:
                return
            visit(by_dep[name].independent)
            done.add(name)
            k = by_dep[name]
            self.couplers.append((self._coord_index[k.dependent], self._coord_index[k.independent], k))

        for k in osim.couplers:
            visit(k.dependent)
        self.dependent = np.zeros(len(self.coordinates), dtype=bool)
        self.root_of = np.arange(len(self.coordinates))
        for d, i, _ in self.couplers:
            self.dependent[d] = True
            self.root_of[d] = self.root_of[i]

        axis_of = {f"{j.name}_{a.name}": (j, a) for j in osim.joints for a in j.axes}
        nj = pin_model.njoints - 1
        self.n_joints = nj
        self._parent = np.empty(nj, dtype=int)      # parent joint (-1: ground)
        self._placement_R = np.empty((nj, 3, 3))
        self._placement_p = np.empty((nj, 3))
        self._axis = np.empty((nj, 3))
        self._revolute = np.empty(nj, dtype=bool)
        self._coord_of_joint = np.empty(nj, dtype=int)
        self._functions = []
        for i in range(1, pin_model.njoints):
            name = pin_model.names[i]
            if name not in axis_of:
                raise ConfigurationError(f"Pinocchio joint {name!r} matches no TransformAxis of {osim.path}")
            joint, ax = axis_of[name]
            jm = pin_model.joints[i]
            if jm.nq != 1:
                raise ConfigurationError(f"joint {name!r} has nq={jm.nq}; expected 1")
            self._parent[i - 1] = pin_model.parents[i] - 1
            M = pin_model.jointPlacements[i]
            self._placement_R[i - 1] = M.rotation
            self._placement_p[i - 1] = M.translation
            self._axis[i - 1] = np.asarray(ax.axis, float)
            self._revolute[i - 1] = ax.is_rotation
            self._coord_of_joint[i - 1] = self._coord_index[ax.coordinates[0]]
            self._functions.append(ax.function)
            if jm.idx_q != i - 1:
                raise ConfigurationError("unexpected Pinocchio joint ordering")
        # body frames: Pinocchio BODY frames named after the links; ground comes last (index
        # len(bodies)) so that path points on ground work like points on bodies
        self.frames: list[str] = self.bodies + [GROUND]
        nf = len(self.frames)
        self._body_joint = np.empty(nf, dtype=int)
        self._body_R = np.empty((nf, 3, 3))
        self._body_p = np.empty((nf, 3))
        self._body_frame_id = []
        for b, name in enumerate(self.frames):
            fid = pin_model.getFrameId(name, pin.BODY)
            if fid >= pin_model.nframes:
                raise ConfigurationError(f"body {name!r} has no frame in the URDF")
            fr = pin_model.frames[fid]
            # index n_joints stands for the universe (bodies welded to ground have no moving joint)
            self._body_joint[b] = fr.parentJoint - 1 if fr.parentJoint > 0 else nj
            self._body_R[b] = fr.placement.rotation
            self._body_p[b] = fr.placement.translation
            self._body_frame_id.append(fid)
        # ancestors: support[b, j] true when joint j moves body b
        self.body_support = np.zeros((nf, nj), dtype=bool)
        for b in range(nf):
            j = self._body_joint[b]
            while 0 <= j < nj:
                self.body_support[b, j] = True
                j = self._parent[j]
        # coupling matrix structure: coordinate c drives joints J_c
        self.coord_of_joint = self._coord_of_joint

    @property
    def tree(self) -> JointTree:
        """The joint tree (read-only copies of the arrays :meth:`forward` uses)."""
        return JointTree(self._parent.copy(), self._placement_R.copy(), self._placement_p.copy(), self._axis.copy(),
                         self._revolute.copy(), self._coord_of_joint.copy(), tuple(self._functions),
                         self._body_joint.copy(), self._body_R.copy(), self._body_p.copy())

    # ------------------------------------------------------------------ inputs
    def as_q(self, q: ConfigLike, *, warn_range: bool = True) -> np.ndarray:
        """Validate configurations; return a float (N, n_coordinates) array.

        Args:
            q: (N, n) or (n,) array in model coordinate order, or a mapping from
                coordinate names to scalars or (N,) arrays (missing coordinates take
                their default values).
            warn_range: Emit :class:`RangeWarning` for values outside coordinate ranges.

        Raises:
            ConfigurationError: Wrong shape, unknown coordinate names, NaN or infinite values.
        """
        n = len(self.coordinates)
        if isinstance(q, Mapping):
            unknown = [k for k in q if k not in self._coord_index]
            if unknown:
                raise ConfigurationError(f"unknown coordinate(s) {unknown}; valid: {self.coordinates}")
            cols = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in q.items()}
            sizes = {len(v) for v in cols.values()} or {1}
            N = max(sizes)
            if sizes - {1, N}:
                raise ConfigurationError(f"coordinate arrays have different lengths {sorted(sizes)}")
            arr = np.tile(self.defaults, (N, 1))
            for k, v in cols.items():
                if v.ndim != 1:
                    raise ConfigurationError(f"coordinate {k!r}: expected a scalar or 1-D array")
                arr[:, self._coord_index[k]] = v
        else:
            try:
                arr = np.array(q, dtype=float)
            except (TypeError, ValueError) as e:
                raise ConfigurationError(f"configuration is not numeric: {e}") from None
            if arr.ndim == 1:
                arr = arr[None, :]
            if arr.ndim != 2 or arr.shape[1] != n:
                raise ConfigurationError(
                    f"configuration has shape {np.shape(q)}; expected (N, {n}) or ({n},) "
                    f"in the order {self.coordinates}")
        bad = ~np.isfinite(arr)
        if bad.any():
            rows, cols_ = np.nonzero(bad)
            names = sorted({self.coordinates[c] for c in cols_})
            raise ConfigurationError(f"configuration has NaN/inf values in {names} "
                                     f"(first at row {rows[0]})")
        if warn_range:
            lo, hi = self.ranges[:, 0], self.ranges[:, 1]
            out = ((arr < lo - RANGE_TOLERANCE) | (arr > hi + RANGE_TOLERANCE)) & ~self.dependent
            if out.any():
                names = sorted({self.coordinates[c] for c in np.nonzero(out)[1]})
                warnings.warn(f"{int(out.any(axis=1).sum())} configuration(s) outside the coordinate "
                              f"ranges of {names}; values are used as given (not clamped)",
                              RangeWarning, stacklevel=3)
        return self.fill_dependent(arr)

    def fill_dependent(self, q: np.ndarray) -> np.ndarray:
        """Set the dependent coordinates of ``q`` (N, n) from their couplers, in place; returns ``q``."""
        for d, i, k in self.couplers:
            q[:, d] = k.value(q[:, i])
        return q

    def dependent_derivatives(self, q: np.ndarray) -> np.ndarray:
        """(N, n) d q_c / d q_root(c): 1 for independent coordinates, the chained coupler slopes otherwise."""
        G = np.ones(q.shape)
        for d, i, k in self.couplers:
            G[:, d] = k.derivative(q[:, i]) * G[:, i]
        return G

    def chain_dependent(self, X: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Turn partial derivatives along the last axis (..., n) into total ones (in place).

        Each dependent coordinate's column is added to its independent (root) coordinate's column,
        times d q_dep / d q_root, then set to 0. ``X`` has shape (N, ..., n) for ``q`` (N, n).
        """
        if not self.couplers:
            return X
        G = self.dependent_derivatives(q)
        extra = (slice(None),) + (None,) * (X.ndim - 2)
        for d in np.nonzero(self.dependent)[0]:
            X[..., self.root_of[d]] += X[..., d] * G[extra + (d,)]
            X[..., d] = 0.0
        return X

    def joint_values(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio joint values v = f(q) and dv/dq, both (N, n_joints)."""
        qc = q[:, self._coord_of_joint]
        v = np.empty_like(qc)
        dv = np.empty_like(qc)
        for j, fn in enumerate(self._functions):
            v[:, j] = fn.value(qc[:, j])
            dv[:, j] = fn.derivative(qc[:, j])
        return v, dv

    # ------------------------------------------------------------------ batched
    def forward(self, q: ConfigLike, *, warn_range: bool = True) -> KinematicsState:
        """Body and joint placements for a batch of configurations (numpy, vectorized).

        Args:
            q: Configurations (see :meth:`as_q`).

        Returns:
            The evaluated :class:`KinematicsState`.
        """
        q = self.as_q(q, warn_range=warn_range)
        N = q.shape[0]
        v, dv = self.joint_values(q)
        nj = self.n_joints
        R = np.empty((N, nj + 1, 3, 3))   # the last slot is the universe (identity)
        p = np.empty((N, nj + 1, 3))
        R[:, nj] = np.eye(3)
        p[:, nj] = 0.0
        for j in range(nj):
            par = self._parent[j]
            a = self._axis[j]
            if par < 0:
                Rb = np.broadcast_to(self._placement_R[j], (N, 3, 3))
                pb = np.broadcast_to(self._placement_p[j], (N, 3))
            else:
                Rb = R[:, par] @ self._placement_R[j]
                pb = p[:, par] + R[:, par] @ self._placement_p[j]
            if self._revolute[j]:
                R[:, j] = Rb @ _rodrigues(a, v[:, j])
                p[:, j] = pb
            else:
                R[:, j] = Rb
                p[:, j] = pb + (Rb @ a) * v[:, j, None]
        axis_w = np.einsum("njab,jb->nja", R[:, :nj], self._axis)
        bR = R[:, self._body_joint] @ self._body_R
        bp = p[:, self._body_joint] + np.einsum("nbij,bj->nbi", R[:, self._body_joint], self._body_p)
        q.setflags(write=False)
        return KinematicsState(q, R[:, :nj], p[:, :nj], axis_w, dv, bR, bp)

    def body_transforms(self, q: ConfigLike) -> dict[str, np.ndarray]:
        """Homogeneous transforms (N, 4, 4) of every body frame in ground, by body name."""
        st = self.forward(q)
        N = st.q.shape[0]
        out = {}
        for b, name in enumerate(self.bodies):
            T = np.zeros((N, 4, 4))
            T[:, :3, :3] = st.body_R[:, b]
            T[:, :3, 3] = st.body_p[:, b]
            T[:, 3, 3] = 1.0
            out[name] = T
        return out

    def point_positions(self, state: KinematicsState, body: str | int, points: np.ndarray) -> np.ndarray:
        """Ground positions (N, P, 3) of points (P, 3) or (N, P, 3) fixed in ``body`` [m]."""
        b = body if isinstance(body, int | np.integer) else self.bodies.index(body)
        pts = np.asarray(points, float)
        if pts.ndim == 2:
            return state.body_p[:, b, None, :] + np.einsum("nij,pj->npi", state.body_R[:, b], pts)
        return state.body_p[:, b, None, :] + np.einsum("nij,npj->npi", state.body_R[:, b], pts)

    def point_jacobian(self, q: ConfigLike, body: str, point) -> np.ndarray:
        """Jacobian (N, 3, n_coordinates) of a point fixed in ``body`` w.r.t. the OpenSim coordinates.

        Coupled coordinates are handled by the chain rule (e.g. knee angle moves the
        tibia through the rotation and the two spline translations).

        Args:
            q: Configurations (see :meth:`as_q`).
            body: Body name.
            point: (3,) location in the body frame [m].

        Returns:
            d(point in ground)/dq [m/rad or m/m].
        """
        if body not in self.bodies:
            raise ConfigurationError(f"unknown body {body!r}; valid: {self.bodies}")
        try:
            pt = np.asarray(point, dtype=float)
        except (TypeError, ValueError):
            raise ConfigurationError(f"point must be 3 numbers [m] in the body frame, got {point!r}") from None
        if pt.shape != (3,) or not np.all(np.isfinite(pt)):
            raise ConfigurationError(f"point must be 3 finite numbers [m] in the body frame, got shape {pt.shape}: "
                                     f"{pt.tolist()}")
        st = self.forward(q)
        b = self.bodies.index(body)
        x = self.point_positions(st, b, pt[None, :])[:, 0]
        return self.chain_dependent(self._point_jacobian(st, b, x), st.q)

    def _point_jacobian(self, st: KinematicsState, b: int, x: np.ndarray) -> np.ndarray:
        N = x.shape[0]
        J = np.zeros((N, 3, len(self.coordinates)))
        for j in np.nonzero(self.body_support[b])[0]:
            a = st.joint_axis[:, j]
            col = np.cross(a, x - st.joint_p[:, j]) if self._revolute[j] else a
            J[:, :, self._coord_of_joint[j]] += col * st.dv_dq[:, j, None]
        return J

    # ------------------------------------------------------------------ reference
    def pinocchio_placements(self, q: ConfigLike) -> tuple[np.ndarray, np.ndarray]:
        """Body placements from Pinocchio itself, one configuration at a time (reference).

        Returns:
            (R, p): (N, n_bodies + 1, 3, 3) and (N, n_bodies + 1, 3) (ground last, as in
            :class:`KinematicsState`).
        """
        import pinocchio as pin  # noqa: PLC0415

        q = self.as_q(q, warn_range=False)
        v, _ = self.joint_values(q)
        N = q.shape[0]
        R = np.empty((N, len(self.frames), 3, 3))
        p = np.empty((N, len(self.frames), 3))
        for k in range(N):
            pin.framesForwardKinematics(self.pin_model, self.pin_data, v[k])
            for b, fid in enumerate(self._body_frame_id):
                M = self.pin_data.oMf[fid]
                R[k, b] = M.rotation
                p[k, b] = M.translation
        return R, p

    def pinocchio_point_jacobian(self, q: ConfigLike, body: str, point) -> np.ndarray:
        """Point Jacobian w.r.t. OpenSim coordinates from Pinocchio's frame Jacobian (reference)."""
        import pinocchio as pin  # noqa: PLC0415

        q = self.as_q(q, warn_range=False)
        v, dv = self.joint_values(q)
        b = self.bodies.index(body)
        fid = self._body_frame_id[b]
        out = np.zeros((q.shape[0], 3, len(self.coordinates)))
        for k in range(q.shape[0]):
            pin.computeJointJacobians(self.pin_model, self.pin_data, v[k])
            pin.updateFramePlacements(self.pin_model, self.pin_data)
            J6 = pin.getFrameJacobian(self.pin_model, self.pin_data, fid, pin.LOCAL_WORLD_ALIGNED)
            R = self.pin_data.oMf[fid].rotation
            r = R @ np.asarray(point, float)
            Jp = J6[:3] - np.cross(r, J6[3:].T).T  # velocity of the point = v_o + w x r
            Jq = Jp * dv[k][None, :]
            np.add.at(out[k].T, self._coord_of_joint, Jq.T)
        return self.chain_dependent(out, q)
