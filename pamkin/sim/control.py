"""The pressure controller of the simulations: a feedforward plan plus a joint-space PD term distributed over
the PAMs.

Every control period the commanded pressures are ``u = clip(p_ff(t) + Δp, 0, p_max)``:

* ``p_ff(t)``: the feedforward pressures (for the harness walk, ``pamkin gait``'s plan of the trial, interpolated
  linearly in time; for standing, constant);
* ``τ_fb = Kp·(q_ref − q) + Kd·(q̇_ref − q̇)``: a PD torque on the controlled coordinates (the 17 non-pelvis
  ones), gains :data:`KP` [N·m/rad] and :data:`KD` [N·m·s/rad] scaled per coordinate by :data:`GAIN_SCALE`;
* Δp minimises ``|Rᵀ·B·Δp − τ_fb|² + λ·|Δp|²`` subject to ``0 ≤ p_ff + Δp ≤ p_max`` (bounded damped least squares,
  DAQP through qpsolvers): the pressure change whose extra torque is τ_fb, with antagonists relaxed only down
  to zero pressure. R are the PAMs' moment arms about the controlled coordinates and B = diag(∂T/∂p) their force
  gains (the slopes of their affine force laws, :meth:`pamkin.sim.pams.PamDrive.affine`), both at the current
  state (MuJoCo's ``ten_J``; :meth:`pamkin.sim.pams.PamDrive.moment_arms`); λ = :data:`DAMPING_LS` × the mean of diag(M·Mᵀ) in units of p_max.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from qpsolvers import solve_ls

from pamkin.gait.plan import plan_pressures

#: PD gains of the feedback torque [N·m/rad, N·m·s/rad].
KP = 800.0
KD = 40.0
#: Per-coordinate scaling of the gains (by name prefix; others 1).
GAIN_SCALE = {"lumbar": 2.0, "hip": 1.0, "knee": 0.7, "ankle": 0.6, "subtalar": 0.2, "mtp": 0.1}
#: Relative regularisation of the damped least squares.
DAMPING_LS = 1e-3


@dataclass
class PressureController:
    """Feedforward + distributed PD (module docstring).

    Attributes:
        coordinates: Controlled coordinates (names), in the drive's coordinate order subset.
        columns: Their columns in the drive's :attr:`~pamkin.sim.pams.PamDrive.coordinates`.
        kp, kd: (n,) gains.
        p_max: Pressure limit [Pa].
    """

    coordinates: list[str]
    columns: np.ndarray
    kp: np.ndarray
    kd: np.ndarray
    p_max: float

    @classmethod
    def for_drive(cls, drive, coordinates: list[str], kp: float = KP, kd: float = KD) -> PressureController:
        """A controller of ``coordinates`` with the default gain scaling."""
        scale = np.array([next((v for k, v in GAIN_SCALE.items() if c.startswith(k)), 1.0) for c in coordinates])
        cols = np.array([drive.coordinates.index(c) for c in coordinates])
        return cls(list(coordinates), cols, kp * scale, kd * scale, drive.p_max)

    def feedback(self, drive, data, q_err: np.ndarray, qd_err: np.ndarray, p_ff: np.ndarray,
                 tau: np.ndarray | None = None) -> np.ndarray:
        """(n_pams,) pressure change Δp [Pa] for position and speed errors (reference − actual) of the controlled
        coordinates (or for the torque ``tau`` when given): the bounded damped least squares of the module
        docstring (0 ≤ p_ff + Δp ≤ p_max)."""
        if tau is None:
            tau = self.kp * q_err + self.kd * qd_err
        R = drive.moment_arms(data)[:, self.columns]
        B = drive.affine(data)[1]              # the slope of a pulling PAM (also below its slack pressure)
        M = (B[:, None] * R).T * self.p_max                  # torque per unit of Δp / p_max
        scale = np.trace(M @ M.T) / M.shape[1]
        if not scale > 0:                                     # no PAM can act (all slack)
            return np.zeros(len(B))
        A = np.vstack([M, np.sqrt(DAMPING_LS * scale) * np.eye(M.shape[1])])
        b = np.concatenate([tau, np.zeros(M.shape[1])])
        x = solve_ls(A, b, lb=-p_ff / self.p_max, ub=1.0 - p_ff / self.p_max, solver="daqp")
        return np.zeros(len(B)) if x is None else x * self.p_max

    def pressures_for(self, drive, data, tau: np.ndarray) -> np.ndarray:
        """(n_pams,) pressures [Pa] in [0, p_max] reproducing the torques ``tau`` about the controlled coordinates
        at the current state with the least effort (``pamkin gait``'s two QPs,
        :func:`pamkin.gait.plan.plan_pressures`, on MuJoCo's moment arms and the tensions' affine laws)."""
        a, b = drive.affine(data)
        R = drive.moment_arms(data)[:, self.columns]
        peak = np.maximum(np.abs(tau), 1.0)
        return plan_pressures(R[None], a[None], b[None], tau[None], peak, p_max=self.p_max)[0]

    def command(self, drive, data, p_ff: np.ndarray, q_err: np.ndarray, qd_err: np.ndarray) -> np.ndarray:
        """Clipped command [Pa]: feedforward plus :meth:`feedback`."""
        p_ff = np.clip(p_ff, 0.0, self.p_max)
        return np.clip(p_ff + self.feedback(drive, data, q_err, qd_err, p_ff), 0.0, self.p_max)
