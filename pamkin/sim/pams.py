"""PAM actuators of a converted robot: pamkin's Festo force law at MuJoCo's tendon lengths, first-order pressure
dynamics.

Each PAM route (a tendon named after its column, ``pam01_r`` ...) has a MuJoCo ``<general>`` actuator
``pam-<route>`` on its tendon with unit gain and no bias: its control is the force. Before each step
:meth:`PamDrive.apply` sets the controls to −T, T the route's tension from :func:`pamkin.robot.festo.force`
(the design's force model) at the tendon's current length (PAM length = (route − tendon)/transmission −
fittings, as :meth:`pamkin.robot.biped.PamRobot.evaluate`) and the current pressure, × parallel count ÷
transmission. MuJoCo applies it through ``actuator_moment`` (the tendon Jacobian): the generalized forces are
−Jᵀ·T, so about a coordinate the torque is T × moment arm, pamkin's PAM torque.

Pressures follow the commands with a first-order lag (valve and volume): dp/dt = (u − p)/τ, u clipped to
[0, :data:`P_MAX`]; :meth:`PamDrive.advance` integrates it exactly over a step, p += (1 − e^(−dt/τ))(u − p).
τ = :data:`TAU` by default (configurable).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from pamkin.robot import festo
from pamkin.robot.biped import PamRobot
from pamkin.robot.design import pam_length
from pamkin.sim.mjcf import MjcfSpec, safe

#: Pressure limit of the valves [Pa] (Festo DMSP: 620 kPa).
P_MAX = 620e3
#: Default time constant of the pressure lag [s] (a 10 mm PAM on a proportional valve fills in ~0.1 s).
TAU = 0.05


def actuator_name(route: str) -> str:
    """Name of the actuator of PAM route ``route``."""
    return safe(f"pam-{route}")


def add_pam_actuators(spec: MjcfSpec, routes: list[str]) -> None:
    """Add one force actuator (unit gain, no bias, unlimited control) per route tendon to ``spec``."""
    act = ET.Element("actuator")
    for r in routes:
        ET.SubElement(act, "general", name=actuator_name(r), tendon=safe(r), gainprm="1", biasprm="0 0 0",
                      ctrllimited="false")
    spec.extra.append(act)


class PamDrive:
    """Pressures and forces of a robot's PAMs in a MuJoCo model.

    Args:
        robot: The pamkin robot (its PAM parameters and force model).
        model: The MuJoCo model (from :func:`pamkin.sim.convert.convert_robot`).
        tau: Time constant of the pressure lag [s].
        p_max: Pressure limit [Pa] (≤ 620 kPa).

    Attributes:
        pressure: (n,) current pressures [Pa], in ``robot.names`` order.
        command: (n,) commanded pressures [Pa] (clipped to [0, p_max] when applied).
    """

    def __init__(self, robot: PamRobot, model: mujoco.MjModel, tau: float = TAU, p_max: float = P_MAX) -> None:
        if not tau > 0:
            raise ValueError(f"tau must be > 0 s, got {tau}")
        if not 0 < p_max <= P_MAX:
            raise ValueError(f"p_max must be in (0, {P_MAX:g}] Pa, got {p_max}")
        self.robot, self.model, self.tau, self.p_max = robot, model, float(tau), float(p_max)
        self.tendons = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, safe(n)) for n in robot.names])
        self.actuators = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator_name(n))
                                   for n in robot.names])
        if (self.tendons < 0).any() or (self.actuators < 0).any():
            raise ValueError("the MuJoCo model lacks PAM tendons or actuators (convert it with convert_robot)")
        self.pressure = np.zeros(len(robot.names))
        self.command = np.zeros(len(robot.names))
        self._groups = [(np.nonzero(robot.diameter == d)[0], int(d)) for d in np.unique(robot.diameter)]
        self._trans = [(np.nonzero(robot.transmission == k)[0], int(k)) for k in np.unique(robot.transmission)]
        self._scale = robot.n_parallel / robot.transmission

    def tension(self, lengths: np.ndarray, pressure: np.ndarray) -> np.ndarray:
        """Route tensions (n,) [N] at route lengths (n,) [m] and pressures (n,) [Pa]."""
        r = self.robot
        pam = np.empty_like(lengths)
        for cols, k in self._trans:
            pam[cols] = pam_length(lengths[cols], r.tendon[cols], k, r.design.fitting_length_m)
        strain = (r.rest - pam) / r.rest
        F = np.empty_like(lengths)
        for cols, d in self._groups:
            F[cols] = festo.force(strain[cols], r.rest[cols], pressure[cols], d, model=r.design.force_model)
        return F * self._scale

    def apply(self, data: mujoco.MjData) -> np.ndarray:
        """Set the actuators' controls to the PAMs' forces at the current tendon lengths (``ten_length`` of
        the last position stage) and pressures; returns the tensions [N]."""
        T = self.tension(data.ten_length[self.tendons], self.pressure)
        data.ctrl[self.actuators] = -T
        return T

    def advance(self, dt: float) -> None:
        """Integrate the pressure lag over ``dt`` [s] towards the clipped commands (exact for a constant
        command)."""
        u = np.clip(self.command, 0.0, self.p_max)
        self.pressure += (1.0 - np.exp(-dt / self.tau)) * (u - self.pressure)
