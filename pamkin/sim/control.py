"""The pressure controller of the simulations: a feedforward plan plus a joint-space PD term distributed over
the PAMs.

Every control period the commanded pressures are ``u = clip(p_ff(t) + Δp, 0, p_max)``:

* ``p_ff(t)``: the feedforward pressures (for the harness walk, ``pamkin gait``'s plan of the trial, interpolated
  linearly in time; for standing, constant);
* ``τ_fb = Kp·(q_ref − q) + Kd·(q̇_ref − q̇)``: a PD torque on the controlled coordinates (the 17 non-pelvis
  ones), gains :data:`KP` [N·m/rad] and :data:`KD` [N·m·s/rad] scaled per coordinate by :data:`GAIN_SCALE`;
* ``Δp = B·R·(Rᵀ·B²·R + λ·I)⁻¹·τ_fb``: the least-norm pressure change whose extra torque is τ_fb (damped least
  squares), R the PAMs' moment arms about those coordinates and B = diag(∂T/∂p) their force gains, both at the
  current state (MuJoCo's ``ten_J``; :meth:`pamkin.sim.pams.PamDrive.moment_arms`, ``pressure_gain``),
  λ = :data:`DAMPING_LS` × mean diagonal of Rᵀ·B²·R.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: PD gains of the feedback torque [N·m/rad, N·m·s/rad].
KP = 400.0
KD = 20.0
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

    def feedback(self, drive, data, q_err: np.ndarray, qd_err: np.ndarray) -> np.ndarray:
        """(n_pams,) pressure change [Pa] for position and speed errors (reference − actual) of the
        controlled coordinates."""
        tau = self.kp * q_err + self.kd * qd_err
        R = drive.moment_arms(data)[:, self.columns]
        B = np.maximum(drive.pressure_gain(data), 0.0)
        BR = B[:, None] * R
        A = BR.T @ BR
        lam = DAMPING_LS * max(np.trace(A) / len(A), 1e-12)
        return BR @ np.linalg.solve(A + lam * np.eye(len(A)), tau)

    def command(self, drive, data, p_ff: np.ndarray, q_err: np.ndarray, qd_err: np.ndarray) -> np.ndarray:
        """Clipped command [Pa]: feedforward plus :meth:`feedback`."""
        return np.clip(p_ff + self.feedback(drive, data, q_err, qd_err), 0.0, self.p_max)
