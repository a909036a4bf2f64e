"""PAM actuators of a converted robot: pamkin's Festo force law at MuJoCo's tendon lengths, first-order pressure
dynamics.

Each PAM route is a tendon named after its column (``pam01_r`` ...). At every step :meth:`PamDrive.apply` takes
the tendons' current lengths (``ten_length``), computes each route's tension T with
:func:`pamkin.robot.festo.force` (the design's force model; PAM length = (route − tendon)/transmission −
fittings, as :meth:`pamkin.robot.biped.PamRobot.evaluate`; × parallel count × cable efficiency ÷ transmission) at the current
pressure, and applies the generalized forces −Jᵀ·T (J = MuJoCo's tendon Jacobian ``ten_J``) gathered onto each
independent coordinate's joint: τ_c = −Σ_j (Jᵀ·T)_j ∂qpos_j/∂q_c, through the joints tied to it (knee
translations, moving path points). About a coordinate the torque is T × moment arm, pamkin's PAM torque. Applying
it to the coordinate's own joint (``qfrc_applied``) rather than to the tied joints keeps the light bodies of moving
path points free of the PAM forces (a tied joint's force would have to pass through its soft equality).

Pressures follow the commands with a first-order lag (valve and volume): dp/dt = (u − p)/τ, u clipped to
[0, :data:`P_MAX`]; :meth:`PamDrive.advance` integrates it exactly over a step, p += (1 − e^(−dt/τ))(u − p).
τ = :data:`TAU` by default (configurable).
"""

from __future__ import annotations

import mujoco
import numpy as np

from pamkin.robot import festo
from pamkin.robot.biped import PamRobot
from pamkin.robot.design import pam_length
from pamkin.sim.geometry import tendon_jacobian_pattern
from pamkin.sim.joints import CoordinateMap
from pamkin.sim.mjcf import safe

#: Pressure limit of the valves [Pa] (Festo DMSP: 620 kPa).
P_MAX = 620e3
#: Default time constant of the pressure lag [s] (a 10 mm PAM on a proportional valve fills in ~0.1 s).
TAU = 0.05


class PamDrive:
    """Pressures and forces of a robot's PAMs in a MuJoCo model.

    Args:
        robot: The pamkin robot (its PAM parameters and force model).
        model: The MuJoCo model (from :func:`pamkin.sim.convert.convert_robot`).
        cmap: Its coordinate map (``Conversion.cmap``).
        tau: Time constant of the pressure lag [s].
        p_max: Pressure limit [Pa] (≤ 620 kPa).

    Attributes:
        pressure: (n,) current pressures [Pa], in ``robot.names`` order.
        command: (n,) commanded pressures [Pa] (clipped to [0, p_max] when applied).
    """

    def __init__(self, robot: PamRobot, model: mujoco.MjModel, cmap: CoordinateMap, tau: float = TAU,
                 p_max: float = P_MAX) -> None:
        if not tau > 0:
            raise ValueError(f"tau must be > 0 s, got {tau}")
        if not 0 < p_max <= P_MAX:
            raise ValueError(f"p_max must be in (0, {P_MAX:g}] Pa, got {p_max}")
        if any(j.terms or j.source for j in cmap.joints):
            raise ValueError("PAM forces need a conversion with couplings='quartic' (every tie a polynomial of its "
                             "coordinate's joint); composed couplings are for geometry")
        self.robot, self.model, self.tau, self.p_max = robot, model, float(tau), float(p_max)
        self.tendons = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, safe(n)) for n in robot.names])
        if (self.tendons < 0).any():
            raise ValueError("the MuJoCo model lacks PAM tendons (convert it with convert_robot)")
        rows, self._cols = tendon_jacobian_pattern(model)
        slot = np.full(model.ntendon, -1)
        slot[self.tendons] = np.arange(len(self.tendons))
        self._rows = slot[rows]                  # PAM column of each ten_J entry (-1: another tendon)
        self._nnz = len(rows)
        jid = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, safe(j.name)) for j in cmap.joints]
        coords = list(cmap.primary)
        self.coordinates = coords
        self._prim_qadr = np.array([model.jnt_qposadr[jid[cmap.primary[c][0]]] for c in coords])
        self._prim_dof = np.array([model.jnt_dofadr[jid[cmap.primary[c][0]]] for c in coords])
        self._a = np.array([cmap.primary[c][1] for c in coords])
        tied = [(model.jnt_dofadr[jid[k]], coords.index(j.coordinate), np.polynomial.polynomial.polyder(j.poly))
                for k, j in enumerate(cmap.joints) if not j.primary]
        self._tied_dof = np.array([t[0] for t in tied], dtype=int)
        self._tied_coord = np.array([t[1] for t in tied], dtype=int)
        self._tied_der = np.array([t[2] for t in tied]).reshape(len(tied), -1)
        self.pressure = np.zeros(len(robot.names))
        self.command = np.zeros(len(robot.names))
        self._groups = [(np.nonzero(robot.diameter == d)[0], int(d)) for d in np.unique(robot.diameter)]
        model_name = robot.design.force_model
        self._kmax = np.zeros(len(robot.names))           # constant per PAM: computed once
        for cols, d in self._groups:
            self._kmax[cols] = festo.kmax(robot.rest[cols], d, model=model_name)
        #: the v3 law with its constants evaluated once (None: another force model, evaluated by festo.force)
        self._law = (festo.force_law(robot.rest, robot.diameter, kmax=self._kmax)
                     if festo.canonical_model(model_name) == "v3" else None)
        self._trans = [(np.nonzero(robot.transmission == k)[0], int(k)) for k in np.unique(robot.transmission)]
        self._scale = robot.n_parallel * robot.efficiency / robot.transmission

    def tension(self, lengths: np.ndarray, pressure: np.ndarray) -> np.ndarray:
        """Route tensions (..., n) [N] at route lengths (n,) [m] and pressures (..., n) [Pa] (several pressure rows
        at the same lengths in one force-law call per diameter)."""
        r = self.robot
        pam = np.empty_like(lengths)
        for cols, k in self._trans:
            pam[cols] = pam_length(lengths[cols], r.tendon[cols], k, r.design.fitting_length_m)
        strain = (r.rest - pam) / r.rest
        if self._law is not None:
            return self._law(strain, pressure) * self._scale
        F = np.empty(np.shape(pressure))
        for cols, d in self._groups:
            F[..., cols] = festo.force(strain[cols], r.rest[cols], pressure[..., cols], d,
                                       model=r.design.force_model, kmax=self._kmax[cols])
        return F * self._scale

    def generalized_forces(self, data: mujoco.MjData, T: np.ndarray) -> np.ndarray:
        """(n_coordinates,) torques of tensions T about the independent coordinates (:attr:`coordinates`), from
        the current ``ten_J`` [N·m or N]."""
        keep = self._rows >= 0
        f = -np.bincount(self._cols[keep], weights=data.ten_J[:self._nnz][keep] * T[self._rows[keep]],
                         minlength=self.model.nv)
        tau = f[self._prim_dof] * self._a
        g = self._tied_slopes(data)
        np.add.at(tau, self._tied_coord, f[self._tied_dof] * g)
        return tau

    def _tied_slopes(self, data: mujoco.MjData) -> np.ndarray:
        """∂qpos/∂q of every tied joint at the current pose (a · P'(x), Horner)."""
        x = data.qpos[self._prim_qadr][self._tied_coord]
        out = np.zeros(len(x))
        for c in self._tied_der.T[::-1]:
            out = out * x + c
        return out * self._a[self._tied_coord]

    def moment_arms(self, data: mujoco.MjData) -> np.ndarray:
        """(n_pams, n_coordinates) moment arms −dL/dq about the independent coordinates (:attr:`coordinates`) at
        the current pose (``ten_J`` of the last position stage) [m or m/m]."""
        keep = self._rows >= 0
        J = np.zeros((len(self.tendons), self.model.nv))
        J[self._rows[keep], self._cols[keep]] = data.ten_J[:self._nnz][keep]
        R = -J[:, self._prim_dof] * self._a
        g = self._tied_slopes(data)
        for k, (dof, c) in enumerate(zip(self._tied_dof, self._tied_coord)):
            R[:, c] -= J[:, dof] * g[k]
        return R

    def affine(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """(a, b) per PAM at the current lengths: the tension is max(a + b·p, 0) (the v3 force law is affine in
        pressure at a fixed strain; as :func:`pamkin.gait.plan.force_coefficients`, from the tensions at p_max and
        2·p_max; a = b = 0 for a PAM slack up to p_max) [N, N/Pa]."""
        L = data.ten_length[self.tendons]
        n = len(L)
        f1, f2 = self.tension(L, np.outer([P_MAX, 2 * P_MAX], np.ones(n)))
        live = f1 > 0
        b = np.where(live, (f2 - f1) / P_MAX, 0.0)
        return np.where(live, f1 - b * P_MAX, 0.0), b

    def apply(self, data: mujoco.MjData) -> np.ndarray:
        """Apply the PAMs' forces at the current tendon lengths and Jacobian (of the last position stage) and
        pressures as ``qfrc_applied`` on the coordinates' joints; returns the tensions [N]."""
        T = self.tension(data.ten_length[self.tendons], self.pressure)
        tau = self.generalized_forces(data, T)
        data.qfrc_applied[:] = 0.0
        data.qfrc_applied[self._prim_dof] = tau / self._a
        return T

    def advance(self, dt: float) -> None:
        """Integrate the pressure lag over ``dt`` [s] towards the clipped commands (exact for a constant
        command)."""
        u = np.clip(self.command, 0.0, self.p_max)
        self.pressure += (1.0 - np.exp(-dt / self.tau)) * (u - self.pressure)
