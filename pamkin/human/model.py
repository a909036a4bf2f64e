"""The :class:`Model`: an imported OpenSim model with kinematics, muscle paths and forces."""

from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path

import numpy as np

from pamkin.errors import (
    ConfigurationError,
    EquilibriumWarning,
    ParameterError,
    UnsupportedFeatureError,
)
from pamkin.human.function_paths import FunctionPaths
from pamkin.human.kinematics import ConfigLike, Kinematics, KinematicsState
from pamkin.human.meshes import find_geometry_dir
from pamkin.human.paths import PathResult, PathSet
from pamkin.human.paths_compiled import FastPaths
from pamkin.human.rom import RangeOfMotion
from pamkin.human.urdf import GAIT2392_DATA, GAIT2392_URDF, cached_urdf, load_model_data
from pamkin.human.wrapping_compiled import FastWrapped
from pamkin.muscles import millard2012
from pamkin.muscles.millard2012 import MillardParams, osim_properties
from pamkin.muscles.thelen2003 import ThelenParams, equilibrium, tendon_force_failed
from pamkin.opensim.model_file import OsimModel, load_osim_file
from pamkin.opensim.wrapping import WrappedPaths


class Model:
    """An OpenSim model in pamkin: import → Xacro → URDF → Pinocchio.

    Build it with :func:`load_osim`. Configurations ``q`` are (N, n_coordinates)
    arrays in :attr:`coordinates` order (or (n_coordinates,), or a mapping from
    coordinate names), in OpenSim units (radians, metres).

    Coordinates coupled by a ``CoordinateCouplerConstraint`` (:attr:`dependent_coordinates`)
    always follow their coupler: their columns of ``q`` are recomputed from the independent
    coordinate (values given there are ignored). Moment arms and Jacobians about an independent
    coordinate are total derivatives (coupling included, as OpenSim's); about a dependent
    coordinate they are 0 by convention (it is not a degree of freedom). OpenSim's
    ``computeMomentArm`` about a dependent coordinate equals pamkin's moment arm about the
    independent one divided by the coupler slope d q_dep / d q_indep (which explodes where the
    slope is near 0).

    Paths with wrap objects (:attr:`wrapping`, :mod:`pamkin.opensim.wrapping`) have OpenSim 4.6's wrapped
    lengths; their moment arms are central differences −(L(q + h) − L(q − h)) / 2h of those lengths
    (h = :attr:`WRAP_STEP`, dependent coordinates following their couplers), which is what OpenSim's
    lengths imply (OpenSim's own ``computeMomentArm`` differs by up to centimetres with wrapping).
    The compiled engine evaluates them in one pass (:mod:`pamkin.human.wrapping_compiled`: straight segments
    exactly, only the wrapped segment, or a multi-wrap path, differenced along the point velocities);
    the numpy engine re-evaluates the kinematics at q ± h.

    Attributes:
        osim: The imported model description.
        urdf_path: The generated URDF.
        kinematics: Batched kinematics (Pinocchio-backed).
        paths: Muscle paths (numpy reference engine; straight lines, wraps ignored).
        wrapping: The wrapped paths (None when no path has a PathWrap).

    Args:
        osim: The imported model.
        urdf_path: Its URDF (generated from the model data by Xacro).
        engine: ``"compiled"`` (default; numba, parallel over configurations) or
            ``"numpy"`` (the reference engine); both give the same numbers to round-off. Wrapped
            paths (:mod:`pamkin.opensim.wrapping`) use numba surface kernels in both; the numpy engine runs
            their path loop in Python.
    """

    def __init__(self, osim: OsimModel, urdf_path: Path, engine: str = "compiled") -> None:
        import pinocchio as pin  # noqa: PLC0415

        self.osim = osim
        self.urdf_path = Path(urdf_path)
        self.pin_model = pin.buildModelFromUrdf(str(urdf_path))
        self.kinematics = Kinematics(osim, self.pin_model)
        fn_cols = [i for i, m in enumerate(osim.muscles) if m.function_path is not None]
        geometric = tuple(m for m in osim.muscles if m.function_path is None)
        # the point paths' machinery sees only the muscles with points
        self._path_osim = dataclasses.replace(osim, muscles=geometric) if fn_cols else osim
        self.paths = PathSet(self.kinematics, [m.name for m in geometric], [m.points for m in geometric])
        # sparse (muscle, coordinate) pairs after the coupling: a dependent coordinate's pairs move
        # to its independent (root) coordinate
        kin = self.kinematics
        part = self.paths.pairs
        out_pairs = sorted({(int(m), int(kin.root_of[c])) for m, c in part})
        self._pairs = np.array(out_pairs, dtype=int).reshape(-1, 2)
        index = {pq: k for k, pq in enumerate(out_pairs)}
        self._pair_out = np.array([index[(int(m), int(kin.root_of[c]))] for m, c in part], dtype=int)
        self._pair_coord = part[:, 1].copy() if len(part) else np.zeros(0, dtype=int)
        self.wrapping: WrappedPaths | None = None
        if any(m.wraps for m in osim.muscles):
            self._init_wrapping(compiled=engine == "compiled")
        self._fast = None
        self._functions = None
        if fn_cols:
            self._init_function_paths(fn_cols)
        if engine == "compiled" and geometric:

            try:
                self._fast = FastPaths(self.paths)
            except TypeError:   # a function type without compiled form: numpy engine
                self._fast = None
        if engine not in ("compiled", "numpy"):
            raise ValueError(f"engine must be 'compiled' or 'numpy', not {engine!r}")
        self._fastwrap = None
        if self._fast is not None and self.wrapping is not None and self.wrapping.compiled:

            # one compiled pass: kinematics, straight and wrapped paths, wrapped moment arms
            self._fastwrap = FastWrapped(self._fast, self.wrapping, self._wpairs, self.kinematics.root_of,
                                         self.WRAP_STEP)
        kinds = [m.kind for m in osim.muscles]
        self._unsupported_force = [m for m in osim.muscles if m.kind not in FORCE_CLASSES]
        self._thelen_cols = [i for i, k in enumerate(kinds) if k == "Thelen2003Muscle"]
        self._millard_cols = [i for i, k in enumerate(kinds) if k == "Millard2012EquilibriumMuscle"]
        self._actuator_cols = [i for i, k in enumerate(kinds) if k == "PathActuator"]
        self._spring_cols = [i for i, k in enumerate(kinds) if k == "PathSpring"]
        self.thelen_params: ThelenParams | None = None
        self.millard_params: MillardParams | None = None
        if not self._unsupported_force:
            thelen = [osim.muscles[i] for i in self._thelen_cols]
            try:
                if thelen:
                    self.thelen_params = ThelenParams.from_osim_properties([m.params for m in thelen],
                                                                           [m.name for m in thelen])
                if self._millard_cols:
                    self.millard_params = _millard_params(osim, [osim.muscles[i] for i in self._millard_cols])
            except ParameterError as e:    # name the file the parameter comes from
                raise ParameterError(f"{osim.path}: {e}") from None

    #: Central-difference step of wrapped paths' moment arms [rad or m].
    WRAP_STEP = 1e-6

    def _init_wrapping(self, compiled: bool) -> None:
        kin = self.kinematics
        self.wrapping = WrappedPaths(self.paths, [m.wraps for m in self._path_osim.muscles], compiled=compiled)
        nc = len(kin.coordinates)
        moves = np.zeros((len(kin.frames), nc), dtype=bool)   # body b moves with coordinate c
        for j in range(kin.n_joints):
            moves[kin.body_support[:, j], kin.coord_of_joint[j]] = True
        straight = self._pairs if kin.couplers else self.paths.pairs
        pairs = {(int(m), int(c)) for m, c in straight}
        wrapped = set()
        for m in self.wrapping.indices:
            mus = self._path_osim.muscles[m]
            bodies = {kin.frames.index(p.body) for p in mus.points}
            bodies |= {kin.frames.index(w.wrap_object.body) for w in mus.wraps}
            for c in range(nc):
                mv = [moves[b, c] for b in bodies]
                if any(mv) and not all(mv):
                    wrapped.add((m, int(kin.root_of[c])))
            wrapped |= {(mm, c) for mm, c in pairs if mm == m}
        pairs |= wrapped
        self._wpairs = np.array(sorted(pairs), dtype=int).reshape(-1, 2)
        self._wrapped_mask = np.isin(self._wpairs[:, 0], self.wrapping.indices)
        index = {(int(m), int(c)): k for k, (m, c) in enumerate(straight)}
        self._wpairs_src = np.array([index.get((int(m), int(c)), -1) for m, c in self._wpairs], dtype=int)
        col = {m: k for k, m in enumerate(self.wrapping.indices)}
        # central differences per coordinate: (coordinate, pair indices, wrapped columns)
        self._wrap_fd = []
        for c in sorted({int(c) for m, c in self._wpairs[self._wrapped_mask]}):
            ks = np.nonzero(self._wrapped_mask & (self._wpairs[:, 1] == c))[0]
            self._wrap_fd.append((c, ks, [col[int(m)] for m in self._wpairs[ks, 0]]))

    def _wrapped_lengths(self, q: np.ndarray, columns=None) -> np.ndarray:
        if self._fast is not None:       # compiled body placements (the numpy kinematics dominate otherwise)
            body_R, body_p = self._fast.body_poses(q)
            return self.wrapping.lengths(_Poses(q, body_R, body_p), columns)
        return self.wrapping.lengths(self.kinematics.forward(q, warn_range=False), columns)

    def _with_wrapping(self, q: np.ndarray, res: PathResult, moment_arms: bool) -> PathResult:
        """Replace the wrapped paths' lengths; their moment arms are central differences of the lengths
        (total derivatives about independent coordinates: dependent coordinates follow their couplers)."""
        W = self.wrapping
        L = res.lengths.copy()
        L[:, W.indices] = self._wrapped_lengths(q)
        if not moment_arms:
            return PathResult(L, self._wpairs, None)
        R = np.zeros((len(q), len(self._wpairs)))
        keep = ~self._wrapped_mask & (self._wpairs_src >= 0)
        R[:, keep] = res.moment_arms[:, self._wpairs_src[keep]]
        h = self.WRAP_STEP
        for c, ks, cols in self._wrap_fd:
            qp, qm = q.copy(), q.copy()
            qp[:, c] += h
            qm[:, c] -= h
            Lp = self._wrapped_lengths(self.kinematics.fill_dependent(qp), cols)
            Lm = self._wrapped_lengths(self.kinematics.fill_dependent(qm), cols)
            R[:, ks] = -(Lp - Lm) / (2 * h)
        return PathResult(L, self._wpairs, R)

    def _with_fast_wrapping(self, q: np.ndarray, res: PathResult, Lw: np.ndarray, Rp: np.ndarray | None,
                            moment_arms: bool) -> PathResult:
        """:meth:`_with_wrapping` for the compiled pass (:class:`pamkin.human.wrapping_compiled.FastWrapped`): wrapped
        lengths ``Lw`` and partial moment arms ``Rp`` given, chained through the couplers."""
        fw = self._fastwrap
        L = res.lengths.copy()
        L[:, self.wrapping.indices] = Lw
        if not moment_arms:
            return PathResult(L, self._wpairs, None)
        R = np.zeros((len(q), len(self._wpairs)))
        keep = ~self._wrapped_mask & (self._wpairs_src >= 0)
        R[:, keep] = res.moment_arms[:, self._wpairs_src[keep]]
        part = Rp * self.kinematics.dependent_derivatives(q)[:, fw.kp_coord] if self.kinematics.couplers else Rp
        np.add.at(R.T, fw.kp_out, part.T)
        return PathResult(L, self._wpairs, R)

    def _init_function_paths(self, fn_cols: list[int]) -> None:
        """Function-based paths beside the point paths; the merged (muscle, coordinate) pair list."""
        kin, osim = self.kinematics, self.osim
        self._functions = FunctionPaths(kin.coordinates, [osim.muscles[i].function_path for i in fn_cols])
        self._fn_cols = np.array(fn_cols, dtype=int)
        self._geo_cols = np.array([i for i, m in enumerate(osim.muscles) if m.function_path is None], dtype=int)
        geo = self._geometry_pairs()
        geo_global = [(int(self._geo_cols[m]), int(c)) for m, c in geo]
        fp = self._functions.pairs
        fn_global = [(int(self._fn_cols[k]), int(kin.root_of[c])) for k, c in fp]
        merged = sorted(set(geo_global) | set(fn_global))
        index = {pq: j for j, pq in enumerate(merged)}
        self._mpairs = np.array(merged, dtype=int).reshape(-1, 2)
        self._geo_pair_pos = np.array([index[pq] for pq in geo_global], dtype=int)
        self._fn_pair_pos = np.array([index[pq] for pq in fn_global], dtype=int)
        self._fn_pair_coord = fp[:, 1].copy()
        # a function of a dependent coordinate: its moment arm moves to the independent one (chain rule)
        self._fn_dependent = bool(len(fp)) and bool(kin.dependent[fp[:, 1]].any())

    def _geometry_pairs(self) -> np.ndarray:
        if self.wrapping is not None:
            return self._wpairs
        return self._pairs if self.kinematics.couplers else self.paths.pairs

    @property
    def pairs(self) -> np.ndarray:
        """(K, 2) (muscle, coordinate) pairs whose moment arms :meth:`path_result` returns: the spanned
        pairs about independent coordinates (a wrapped path also spans the joints that move its wrap
        objects relative to its points; a function-based path spans the coordinates it names)."""
        if self._functions is not None:
            return self._mpairs.copy()
        return self._geometry_pairs().copy()

    @property
    def coordinates(self) -> list[str]:
        """OpenSim coordinate names in model (CoordinateSet) order."""
        return list(self.kinematics.coordinates)

    @property
    def dependent_coordinates(self) -> dict[str, str]:
        """``{dependent coordinate: its independent coordinate}`` of the CoordinateCouplerConstraints."""
        return {k.dependent: k.independent for _, _, k in self.kinematics.couplers}

    @property
    def independent_coordinates(self) -> list[str]:
        """The coordinates that are degrees of freedom (all but the dependent ones), model order."""
        return [c for c, d in zip(self.coordinates, self.kinematics.dependent) if not d]

    @property
    def bodies(self) -> list[str]:
        """Body names (ground excluded) in model order."""
        return list(self.kinematics.bodies)

    @property
    def coordinate_ranges(self) -> np.ndarray:
        """(n_coordinates, 2) coordinate ranges [rad or m]."""
        return self.kinematics.ranges.copy()

    @property
    def default_q(self) -> np.ndarray:
        """(n_coordinates,) default coordinate values."""
        return self.kinematics.defaults.copy()

    def forward(self, q: ConfigLike) -> KinematicsState:
        """Evaluate kinematics of a batch of configurations once (see :class:`KinematicsState`)."""
        return self.kinematics.forward(q)

    def body_transforms(self, q: ConfigLike) -> dict[str, np.ndarray]:
        """Body frame → ground homogeneous transforms, ``{body: (N, 4, 4)}`` [m]."""
        return self.kinematics.body_transforms(q)

    def point_jacobian(self, q: ConfigLike, body: str, point) -> np.ndarray:
        """Jacobian (N, 3, n_coordinates) of a point fixed in ``body`` w.r.t. the coordinates."""
        return self.kinematics.point_jacobian(q, body, point)

    @property
    def muscles(self) -> list[str]:
        """Muscle names in ForceSet order."""
        return [m.name for m in self.osim.muscles]

    def path_result(self, q: ConfigLike, moment_arms: bool = True, chunk: int = 65536) -> PathResult:
        """Lengths and sparse moment arms (only spanned muscle × coordinate pairs, :attr:`pairs`).

        Large batches are processed in chunks of ``chunk`` configurations (bounded memory).
        Function-based paths (OpenSim's ``FunctionBasedPath``) evaluate their functions; their moment
        arms are the file's moment-arm functions when it gives them (as OpenSim uses them), else −∂l/∂q.
        """
        q = self.kinematics.as_q(q)
        if self._functions is None:
            return self._geometry_path_result(q, moment_arms, chunk)
        N = len(q)
        L = np.zeros((N, len(self.osim.muscles)))
        R = np.zeros((N, len(self._mpairs))) if moment_arms else None
        if len(self._geo_cols):
            g = self._geometry_path_result(q, moment_arms, chunk)
            L[:, self._geo_cols] = g.lengths
            if R is not None:
                R[:, self._geo_pair_pos] = g.moment_arms
        Lf, Rf = self._functions.evaluate(q, moment_arms)
        L[:, self._fn_cols] = Lf
        if R is not None and not self._fn_dependent:
            R[:, self._fn_pair_pos] += Rf
        elif R is not None:                 # a dependent coordinate's moment arm moves to its independent one
            Rf = Rf * self.kinematics.dependent_derivatives(q)[:, self._fn_pair_coord]
            np.add.at(R.T, self._fn_pair_pos, Rf.T)
        return PathResult(L, self._mpairs, R)

    def _geometry_path_result(self, q: np.ndarray, moment_arms: bool, chunk: int) -> PathResult:
        """:meth:`path_result` of the paths with points (``q`` already validated)."""
        Lw = Rp = None
        if self._fastwrap is not None:      # in chunks: bounded memory
            parts = [self._fastwrap.evaluate(q[i:i + chunk], moment_arms) for i in range(0, max(len(q), 1), chunk)]
            L, Lw = (np.concatenate([p[j] for p in parts]) for j in (0, 2))
            R, Rp = (np.concatenate([p[j] for p in parts]) if moment_arms else None for j in (1, 3))
        elif self._fast is not None:
            L, R = self._fast.evaluate(q, moment_arms)
        else:
            parts = [self.paths.evaluate(self.kinematics.forward(q[i:i + chunk], warn_range=False), moment_arms)
                     for i in range(0, max(len(q), 1), chunk)]
            L = np.concatenate([p.lengths for p in parts]) if parts else np.zeros((0, len(self.paths.names)))
            R = np.concatenate([p.moment_arms for p in parts]) if moment_arms else None
        if L.shape[0] != len(q):     # no configurations
            L = np.zeros((len(q), len(self.paths.names)))
            R = np.zeros((len(q), len(self.paths.pairs))) if moment_arms else None
        if not self.kinematics.couplers:
            res = PathResult(L, self.paths.pairs, R)
        elif R is None:
            res = PathResult(L, self._pairs, None)
        else:
            G = self.kinematics.dependent_derivatives(q)
            out = np.zeros((len(q), len(self._pairs)))
            np.add.at(out.T, self._pair_out, (R * G[:, self._pair_coord]).T)
            res = PathResult(L, self._pairs, out)
        if self.wrapping is None:
            return res
        if Lw is not None:
            return self._with_fast_wrapping(q, res, Lw, Rp, moment_arms)
        if len(q) <= chunk:
            return self._with_wrapping(q, res, moment_arms)
        parts = [self._with_wrapping(q[i:i + chunk], PathResult(
            res.lengths[i:i + chunk], res.pairs, None if res.moment_arms is None else res.moment_arms[i:i + chunk]),
            moment_arms) for i in range(0, len(q), chunk)]        # bounded memory for the central differences
        return PathResult(np.concatenate([p.lengths for p in parts]), self._wpairs,
                          np.concatenate([p.moment_arms for p in parts]) if moment_arms else None)

    def lengths(self, q: ConfigLike) -> np.ndarray:
        """Musculotendon path lengths (N, n_muscles) [m]."""
        return self.path_result(q, moment_arms=False).lengths

    def moment_arms(self, q: ConfigLike) -> np.ndarray:
        """Moment arms −∂L/∂q (N, n_muscles, n_coordinates) [m; m/m for translations]."""
        return self.path_result(q).dense_moment_arms(len(self.coordinates))

    def _check_forces(self) -> None:
        for i in self._spring_cols:
            m = self.osim.muscles[i]
            missing = [k for k in ("stiffness", "resting_length") if k not in m.params]
            if missing:
                raise ParameterError(f"{self.osim.path}: <PathSpring name=\"{m.name}\">: no <{missing[0]}> "
                                     "(OpenSim's default is NaN)")
        if self._unsupported_force:
            m = self._unsupported_force[0]
            raise UnsupportedFeatureError(
                self.osim.path, f"forces are implemented for {', '.join(FORCE_CLASSES)} only; "
                f"{len(self._unsupported_force)} muscle(s) are {m.kind} (kinematics, lengths and moment "
                "arms work)", element=m.kind, component=m.name)

    def _static_forces(self, L: np.ndarray, activation, rigid_tendon: bool, full: bool):
        """Tendon forces (N, n_muscles) at lengths ``L`` and, if ``full``, the equilibrium (Thelen2003
        muscles: :mod:`pamkin.muscles.thelen2003`; Millard2012: :mod:`pamkin.muscles.millard2012`; ``failed`` entries,
        where OpenSim finds no equilibrium, are NaN and raise an :class:`EquilibriumWarning`). PathActuators pull
        with optimal_force × control (``activation`` is the control, not clamped: OpenSim's
        ``computeActuation``); PathSprings with stiffness × max(0, L − resting_length) (zero lengthening speed:
        the dissipation term vanishes). Their fibre fields in the equilibrium are NaN."""
        self._check_forces()
        special = self._actuator_cols + self._spring_cols
        if not special:
            return self._muscle_forces(L, activation, rigid_tendon, full)
        try:
            act = np.broadcast_to(np.asarray(activation, dtype=float), L.shape)
        except ValueError:
            raise ConfigurationError(f"activation of shape {np.shape(activation)} does not broadcast "
                                     f"to the lengths' shape {L.shape}") from None
        F, eq = self._muscle_forces(L, act, rigid_tendon, full, mixed=True)
        F = np.array(F, dtype=float)
        params = [self.osim.muscles[i].params for i in special]
        for k, i in enumerate(self._actuator_cols):
            F[:, i] = params[k]["optimal_force"] * act[:, i]
        for i in self._spring_cols:
            p = self.osim.muscles[i].params
            F[:, i] = p["stiffness"] * np.maximum(L[:, i] - p["resting_length"], 0.0)
        if eq is not None:
            for f in ("fiber_length", "normalized_fiber_length", "pennation_angle", "tendon_length",
                      "active_fiber_force", "passive_fiber_force"):
                getattr(eq, f)[:, special] = np.nan
            eq.tendon_force[:, special] = F[:, special]
        return F, eq

    def _muscle_forces(self, L: np.ndarray, activation, rigid_tendon: bool, full: bool, mixed: bool = False):
        """:meth:`_static_forces` of the Thelen2003 and Millard2012 muscles (other columns 0 when ``mixed``)."""
        if self.millard_params is None and not mixed:
            if self.thelen_params is None:      # a model without muscles
                return np.zeros(L.shape), None
            if full:
                eq = equilibrium(L, self.thelen_params, activation, rigid_tendon=rigid_tendon)
                self._warn_failed(eq.failed)
                return eq.tendon_force, eq
            F, failed = tendon_force_failed(L, self.thelen_params, activation, rigid_tendon=rigid_tendon)
            self._warn_failed(failed)
            return F, None

        rigid = True if rigid_tendon else None     # False: each muscle's ignore_tendon_compliance
        if not self._thelen_cols and not mixed:
            eq = millard2012.equilibrium(L, self.millard_params, activation, rigid_tendon=rigid)
        else:                                   # Thelen2003, Millard2012 and other forces in one model
            try:
                act = np.broadcast_to(np.asarray(activation, dtype=float), L.shape)
            except ValueError:
                raise ConfigurationError(f"activation of shape {np.shape(activation)} does not broadcast "
                                         f"to the lengths' shape {L.shape}") from None
            th, mi = self._thelen_cols, self._millard_cols
            a = equilibrium(L[:, th], self.thelen_params, act[:, th], rigid_tendon=rigid_tendon) if th else None
            b = millard2012.equilibrium(L[:, mi], self.millard_params, act[:, mi], rigid_tendon=rigid) if mi else None
            parts = {}
            for f in ("fiber_length", "normalized_fiber_length", "pennation_angle", "tendon_length",
                      "tendon_force", "active_fiber_force", "passive_fiber_force", "clamped", "failed"):
                dtype = bool if f in ("clamped", "failed") else float
                x = np.zeros(L.shape, dtype=dtype)
                if a is not None:
                    x[:, th] = getattr(a, f, False)
                if b is not None:
                    x[:, mi] = getattr(b, f)
                parts[f] = x
            eq = millard2012.Equilibrium(**parts)
        self._warn_failed(eq.failed)
        return eq.tendon_force, eq

    def _warn_failed(self, failed: np.ndarray) -> None:
        """EquilibriumWarning naming the (configuration, muscle) pairs without equilibrium."""
        if failed.any():
            i, j = np.argwhere(failed)[0]
            warnings.warn(EquilibriumWarning(
                f"{self.osim.path}: no static equilibrium for {int(failed.sum())} of {failed.size} "
                f"(configuration, muscle) pairs, e.g. {self.muscles[j]} in configuration {i} (OpenSim 4.6 "
                "raises MuscleCannotEquilibrate there); their forces are NaN"), stacklevel=4)

    def evaluate(self, q: ConfigLike, activation: float | np.ndarray = 1.0,
                 rigid_tendon: bool = False) -> MuscleState:
        """Lengths, moment arms, static forces and torques of every muscle, evaluated once.

        Args:
            q: Configurations (N, n_coordinates) [rad, m].
            activation: Activation in [0, 1] (scalar, (n_muscles,) or (N, n_muscles)).
            rigid_tendon: Use a rigid tendon instead of the compliant-tendon equilibrium.
        """
        self._check_forces()
        res = self.path_result(q)
        F, eq = self._static_forces(res.lengths, activation, rigid_tendon, full=True)
        return MuscleState(res, F, eq)

    def evaluate_chunks(self, q: ConfigLike, chunk: int = 50_000, activation: float | np.ndarray = 1.0,
                        rigid_tendon: bool = False):
        """Evaluate a large batch chunk by chunk (bounded memory, e.g. 10^6 configurations).

        Yields:
            (slice of the configurations, :class:`MuscleState` of that chunk).
        """
        q = self.kinematics.as_q(q)
        if chunk < 1:
            raise ValueError("chunk must be >= 1")
        for start in range(0, len(q), chunk):
            sl = slice(start, min(start + chunk, len(q)))
            yield sl, self.evaluate(q[sl], activation, rigid_tendon)

    def tendon_forces(self, q: ConfigLike, activation: float | np.ndarray = 1.0,
                      rigid_tendon: bool = False) -> np.ndarray:
        """Static (zero fibre velocity) tendon forces (N, n_muscles) [N], OpenSim's equilibrium.

        Thelen2003Muscle and Millard2012EquilibriumMuscle (see :mod:`pamkin.muscles.thelen2003`,
        :mod:`pamkin.muscles.millard2012`). ``rigid_tendon=True`` makes every tendon rigid; with False a
        Millard muscle's tendon is rigid where the file sets ``ignore_tendon_compliance``. Where
        OpenSim finds no equilibrium (Thelen2003 or Millard2012) the force is NaN and an
        :class:`~pamkin.errors.EquilibriumWarning` is issued.
        """
        self._check_forces()
        return self._static_forces(self.lengths(q), activation, rigid_tendon, full=False)[0]

    def torques(self, q: ConfigLike, activation: float | np.ndarray = 1.0,
                rigid_tendon: bool = False) -> np.ndarray:
        """Muscle torques force × moment arm (N, n_muscles, n_coordinates) [N·m; N for translations]."""
        st = self.evaluate(q, activation, rigid_tendon)
        return st.dense_torques(len(self.coordinates))

    def group_torques(self, q: ConfigLike, groups, activation: float | np.ndarray = 1.0) -> dict[str, np.ndarray]:
        """Summed torque of each group, ``{group key: (N, n_coordinates)}`` [N·m].

        Args:
            groups: :class:`pamkin.human.groups.MuscleGroup` objects, or a mapping name -> muscle names.
        """
        T = self.torques(q, activation)
        items = groups.items() if isinstance(groups, dict) else [(g.key, g.muscles) for g in groups]
        out = {}
        for key, muscles in items:
            names = self.muscles
            missing = [m for m in muscles if m not in names]
            if missing:
                raise KeyError(f"group {key!r}: unknown muscles {missing}")
            idx = [names.index(m) for m in muscles]
            out[key] = T[:, idx].sum(axis=1)
        return out

    def capacity(self, q: ConfigLike, activation: float | np.ndarray = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Per-coordinate torque capacity envelopes at full activation.

        Returns:
            (positive, negative): (N, n_coordinates) sums of the positive and of the
            negative muscle torques [N·m].
        """
        T = self.torques(q, activation)
        return np.where(T > 0, T, 0.0).sum(axis=1), np.where(T < 0, T, 0.0).sum(axis=1)

    def grid(self, coordinates: list[str], n: int | list[int] = 21, rom=None,
             base: ConfigLike | None = None) -> tuple[np.ndarray, tuple[int, ...]]:
        """Configurations on a 1-D/2-D/N-D grid of coordinates.

        Args:
            coordinates: Grid coordinates (the last varies fastest).
            n: Points per coordinate.
            rom: A :class:`pamkin.human.rom.RangeOfMotion` (coupled limits honoured); default: the
                model's coordinate ranges.
            base: Values of the other coordinates (default: the model defaults).

        Returns:
            (q, shape): q is (prod(shape), n_coordinates); reshape results with ``shape``.
        """

        unknown = [c for c in coordinates if c not in self.coordinates]
        if unknown:

            raise ConfigurationError(f"unknown grid coordinate(s) {unknown}; valid: {self.coordinates}")
        if rom is None:
            rom = RangeOfMotion({c: tuple(r) for c, r in zip(self.coordinates, self.coordinate_ranges.tolist())})
        q0 = self.default_q if base is None else self.kinematics.as_q(base)[0]
        pts = rom.grid(coordinates, n, base=dict(zip(self.coordinates, q0)))
        q = np.tile(q0, (len(pts), 1))
        for i, c in enumerate(coordinates):
            q[:, self.coordinates.index(c)] = pts[:, i]
        shape = tuple([n] * len(coordinates) if isinstance(n, int) else n)
        return q, shape

    def random_q(self, n: int, seed: int | None = 0) -> np.ndarray:
        """``n`` configurations uniform over every coordinate's range (fixed seed by default); locked
        coordinates keep their default value (OpenSim does not change a locked coordinate) and
        dependent coordinates follow their couplers."""
        rng = np.random.default_rng(seed)
        lo, hi = self.kinematics.ranges.T
        q = lo + (hi - lo) * rng.random((n, len(lo)))
        locked = [i for i, c in enumerate(self.osim.coordinates) if c.locked]
        q[:, locked] = self.kinematics.defaults[locked]
        return self.kinematics.fill_dependent(q)


#: Muscle classes with static forces.
FORCE_CLASSES = ("Thelen2003Muscle", "Millard2012EquilibriumMuscle", "PathActuator", "PathSpring")


def _millard_params(osim: OsimModel, muscles) -> MillardParams:
    """Millard2012 parameters: the imported scalar properties, completed by the curve properties,
    ``fiber_damping``, ``ignore_tendon_compliance`` and ``min_control`` read from the model file
    (OpenSim's defaults when the model does not come from a readable file)."""

    extra = osim_properties(osim.path) if Path(osim.path).is_file() else {}
    return MillardParams.from_osim_properties([{**m.params, **extra.get(m.name, {})} for m in muscles],
                                              [m.name for m in muscles])


def load_osim(path: str | os.PathLike, engine: str = "compiled",
              geometry: str | os.PathLike | None = None) -> Model:
    """Load an OpenSim ``.osim`` model: import → Xacro → URDF (cached) → Pinocchio.

    The URDF (in the cache folder, ``$PAMKIN_CACHE``) gets the model's bone meshes as
    ``<visual>`` elements (binary STL files in ``meshes/`` beside it, decimated) when the
    ``.vtp`` files are found: in ``geometry``, or where OpenSim looks (``Geometry/`` beside the
    model file, the model's folder, ``../Geometry``). Without them the URDF has no visuals.

    Args:
        path: The ``.osim`` file (OpenSim 4.x format).
        engine: ``"compiled"`` (default) or ``"numpy"``.
        geometry: Folder of the ``.vtp`` meshes (default: found beside the model).

    Raises:
        pamkin.errors.OsimError: The file is malformed.
        pamkin.errors.UnsupportedFeatureError: It uses features pamkin does not implement.
        pamkin.errors.DataFileError: ``geometry`` is not a folder, or a mesh file is corrupt.
    """

    osim = load_osim_file(path)
    folder = geometry if geometry is not None else find_geometry_dir(path)
    return Model(osim, cached_urdf(osim, folder), engine=engine)


def gait2392(engine: str = "compiled") -> Model:
    """The built-in Gait2392 model (project data ``robot/data/gait2392.yaml``, ``urdf/gait2392.urdf``).

    Needs no OpenSim files: the data file holds the model imported from OpenSim's
    ``gait2392_thelen2003muscle.osim`` (Delp et al., CC BY 3.0).
    """
    return Model(load_model_data(GAIT2392_DATA), GAIT2392_URDF, engine=engine)


class _Poses:
    """What :meth:`pamkin.opensim.wrapping.WrappedPaths.lengths` reads of a :class:`KinematicsState`."""

    def __init__(self, q: np.ndarray, body_R: np.ndarray, body_p: np.ndarray) -> None:
        self.q, self.body_R, self.body_p = q, body_R, body_p


class MuscleState:
    """Muscle quantities of a batch of configurations (see :meth:`Model.evaluate`).

    Attributes:
        paths: Lengths and sparse moment arms.
        tendon_forces: (N, n_muscles) [N].
        equilibrium: The fibre/tendon equilibrium (fibre lengths, pennation, clamping, ``failed``: no
            equilibrium in OpenSim; a :class:`pamkin.muscles.thelen2003.Equilibrium` for Thelen2003-only models,
            else a :class:`pamkin.muscles.millard2012.Equilibrium`).
    """

    def __init__(self, paths: PathResult, tendon_forces: np.ndarray, eq) -> None:
        self.paths = paths
        self.tendon_forces = tendon_forces
        self.equilibrium = eq

    @property
    def lengths(self) -> np.ndarray:
        """(N, n_muscles) musculotendon lengths [m]."""
        return self.paths.lengths

    @property
    def pair_torques(self) -> np.ndarray:
        """(N, K) torques of the spanned (muscle, coordinate) pairs ``paths.pairs`` [N·m]."""
        return self.tendon_forces[:, self.paths.pairs[:, 0]] * self.paths.moment_arms

    def dense_torques(self, n_coordinates: int) -> np.ndarray:
        """(N, n_muscles, n_coordinates) torques [N·m]."""
        N, M = self.lengths.shape
        out = np.zeros((N, M, n_coordinates))
        out[:, self.paths.pairs[:, 0], self.paths.pairs[:, 1]] = self.pair_torques
        return out
