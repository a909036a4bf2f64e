"""The pressure controller of the simulations: a feedforward plus a joint-space PD term distributed over the PAMs,
and for standing a balance term on the centre of mass.

Every control period the commanded pressures are ``u = clip(p_ff(t) + Δp, 0, p_max)``:

* ``p_ff(t)``: the feedforward pressures (for the harness walk, ``pamkin gait``'s plan of the trial, interpolated
  linearly in time; for standing, constant);
* ``τ_fb = Kp·(q_ref − q) + Kd·(q̇_ref − q̇)``: a PD torque on the controlled coordinates (the 17 non-pelvis
  ones), gains :data:`KP` [N·m/rad] and :data:`KD` [N·m·s/rad] scaled per coordinate by :data:`GAIN_SCALE`;
* Δp minimises ``|Rᵀ·B·Δp − τ_fb|² + λ·|Δp|²`` subject to ``0 ≤ p_ff + Δp ≤ p_max`` (bounded damped least squares,
  DAQP through qpsolvers): the pressure change whose extra torque is τ_fb, with antagonists relaxed only down
  to zero pressure. R are the PAMs' moment arms about the controlled coordinates and B = diag(∂T/∂p) their force
  gains (the slopes of their affine force laws, :meth:`pamkin.sim.pams.PamDrive.affine`), both at the current
  state (MuJoCo's ``ten_J``; :meth:`pamkin.sim.pams.PamDrive.moment_arms`); λ = :data:`DAMPING_LS` × the mean of
  diag(M·Mᵀ) in units of p_max.

Standing adds two things (:func:`cocontracted_pressures`, :class:`Balance`):

* a co-contracted feedforward: the pressures that hold the pose statically (Rᵀ·(a + B·p) = τ_static) closest to a
  common level (:data:`COCONTRACTION`): antagonists pressurised against each other. A PAM's force falls as it
  shortens, so at a constant pressure it is a spring; the co-contracted joints are stiff without waiting for the
  pressures, which lag their commands by τ;
* a centre-of-mass term on the ankles (ankle strategy): τ_ankles = −K_com·(x_com − x_com,0) − D_com·ẋ_com, split
  evenly between the two ankle_angle coordinates (x forward; a forward centre of mass asks for plantarflexion).

Why the PD gains must stay low against the lag: through the first-order lag 1/(1 + τs) a PD term
Kp·e + Kd·ė acts at a frequency ω as a damping (Kd − Kp·τ)/(1 + ω²τ²) [N·m·s/rad]: with Kp·τ ≥ Kd it feeds energy
into the fast modes (Kp = 800, Kd = 40, τ = 0.05 s is exactly the edge: the 10–17 Hz hip and pelvis oscillation
the standing robot had). The control period adds half a period of delay and, on the light pelvis between the
lumbar and both hips, a sampled damping term Kd·T/I above ~2 is unstable by itself; hence the 2 ms default
control period (:data:`pamkin.sim.simulate.CONTROL_PERIOD`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from qpsolvers import solve_ls

from pamkin.gait.plan import plan_pressures

#: PD gains of the feedback torque of the harness walk [N·m/rad, N·m·s/rad].
KP = 1600.0
KD = 80.0
#: PD gains of the feedback torque when standing (lower: the co-contraction gives the stiffness) [N·m/rad, N·m·s/rad].
KP_STAND = 400.0
KD_STAND = 30.0
#: Common pressure level of the co-contracted standing feedforward [Pa].
COCONTRACTION = 400e3
#: Multiplier of a swinging foot's ankle, subtalar and mtp gains in the harness walk (:class:`SwingGains`).
SWING_SCALE = 0.5
#: A foot is on the floor when its lowest contact sphere is closer to it than this [m].
TOUCH = 0.003
#: Centre-of-mass balance gains of standing, both ankles together [N·m/m, N·m·s/m].
K_COM = 2000.0
D_COM = 300.0
#: Per-coordinate scaling of the gains (by name prefix; others 1).
GAIN_SCALE = {"lumbar": 2.0, "hip": 1.0, "knee": 0.7, "ankle": 0.6, "subtalar": 0.2, "mtp": 0.1}
#: The scaling when standing: the knees stiffer (at 0.7 the thesis design's knees sank onto their hyperextension
#: stops within 2 s).
STAND_GAIN_SCALE = GAIN_SCALE | {"knee": 1.5}
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
    def for_drive(cls, drive, coordinates: list[str], kp: float = KP, kd: float = KD,
                  gain_scale: dict[str, float] | None = None) -> PressureController:
        """A controller of ``coordinates`` with the gains scaled per name prefix (default :data:`GAIN_SCALE`)."""
        table = GAIN_SCALE if gain_scale is None else gain_scale
        scale = np.array([next((v for k, v in table.items() if c.startswith(k)), 1.0) for c in coordinates])
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

    def command(self, drive, data, p_ff: np.ndarray, q_err: np.ndarray, qd_err: np.ndarray,
                tau_extra: np.ndarray | None = None, gain: np.ndarray | None = None) -> np.ndarray:
        """Clipped command [Pa]: feedforward plus :meth:`feedback` of the PD torque (its gains multiplied per
        coordinate by ``gain`` when given, e.g. :meth:`SwingGains.gain`) plus ``tau_extra`` (n,) [N·m] (e.g.
        :meth:`Balance.torque`)."""
        p_ff = np.clip(p_ff, 0.0, self.p_max)
        tau = self.kp * q_err + self.kd * qd_err
        if gain is not None:
            tau = gain * tau
        if tau_extra is not None:
            tau = tau + tau_extra
        return np.clip(p_ff + self.feedback(drive, data, None, None, p_ff, tau=tau), 0.0, self.p_max)


def cocontracted_pressures(drive, data, columns: np.ndarray, tau: np.ndarray, level: float = COCONTRACTION,
                           iterations: int = 3) -> np.ndarray:
    """(n_pams,) pressures [Pa] in [0, p_max] producing the torques ``tau`` [N·m] about the coordinates ``columns``
    (of ``drive.coordinates``) at the current state, as close as possible to the common ``level`` [Pa].

    Minimises |Rᵀ·B·p − (τ − Rᵀ·a)|² + μ·|p − level|² (μ = 1e-4 × the mean of diag(M·Mᵀ), in units of p_max;
    bounded least squares, DAQP), then corrects the target by the exact Festo torques' residual (``iterations``
    times: a PAM slack below some pressure is not affine there)."""
    pm = drive.p_max
    a, b = drive.affine(data)
    R = drive.moment_arms(data)[:, columns]
    M = (R * b[:, None]).T * pm
    mu = np.sqrt(1e-4 * np.trace(M @ M.T) / M.shape[1])
    n = M.shape[1]
    A = np.vstack([M, mu * np.eye(n)])
    target = tau - R.T @ a
    p = np.full(n, float(level))
    for _ in range(iterations):
        x = solve_ls(A, np.concatenate([target, np.full(n, mu * level / pm)]), lb=np.zeros(n), ub=np.ones(n),
                     solver="daqp")
        if x is None:
            break
        p = np.clip(x * pm, 0.0, pm)
        got = drive.generalized_forces(data, drive.tension(data.ten_length[drive.tendons], p))[columns]
        target = target + (tau - got)
    return p


@dataclass
class Balance:
    """Ankle strategy on the centre of mass (module docstring).

    Attributes:
        ankles: Indices of ankle_angle_r and ankle_angle_l among the controller's coordinates.
        x_ref: Reference forward position of the centre of mass [m] (world x).
        k_com, d_com: Gains, both ankles together [N·m/m, N·m·s/m].
    """

    ankles: list[int]
    x_ref: float
    k_com: float = K_COM
    d_com: float = D_COM

    def torque(self, model, data, n: int) -> np.ndarray:
        """(n,) extra torques [N·m] on the controller's n coordinates: −K·(x − x_ref) − D·ẋ split over the
        ankles (MuJoCo's ``subtree_com`` of the last position stage, ``subtree_linvel`` computed here)."""
        mujoco.mj_comVel(model, data)
        mujoco.mj_subtreeVel(model, data)
        tau = np.zeros(n)
        tau[self.ankles] = 0.5 * (-self.k_com * (data.subtree_com[0][0] - self.x_ref)
                                  - self.d_com * data.subtree_linvel[0][0])
        return tau


@dataclass
class SwingGains:
    """Lower foot gains while a foot swings (harness walk).

    A swinging foot is light (≈ 0.015 kg·m² about the ankle): the full ankle gains, Kd·T/I ≈ 6 at the 2 ms
    control period and Kd = Kp·τ, made it ripple at 15–20 Hz; on a treadmill belt the rippling toes caught the
    belt in late swing and it dragged the leg back. While a foot is off the floor (its lowest contact sphere
    more than :data:`TOUCH` above it) its ankle, subtalar and mtp gains are multiplied by ``scale``.

    Attributes:
        n: Number of the controller's coordinates.
        columns: {side: indices of that foot's coordinates among the controller's}.
        scale: The multiplier (:data:`SWING_SCALE`).
    """

    n: int
    columns: dict[str, list[int]]
    scale: float = SWING_SCALE

    @classmethod
    def for_controller(cls, ctrl: PressureController, scale: float = SWING_SCALE) -> SwingGains:
        cols = {side: [ctrl.coordinates.index(f"{j}_{side}") for j in ("ankle_angle", "subtalar_angle", "mtp_angle")
                       if f"{j}_{side}" in ctrl.coordinates] for side in ("r", "l")}
        return cls(len(ctrl.coordinates), cols, scale)

    def gain(self, scene) -> np.ndarray:
        """(n,) gain multipliers for the current state (``scene``: :class:`pamkin.sim.scene.Scene`)."""
        g = np.ones(self.n)
        for side, cols in self.columns.items():
            if scene.foot_gap(side) > TOUCH:
                g[cols] = self.scale
        return g
