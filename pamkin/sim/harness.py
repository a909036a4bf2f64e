"""The harness of the walking simulation: a mocap body welded to the pelvis, moving along the trial's pelvis
placements, its height regulated on the load it carries.

A rigid harness on the trial's pelvis trajectory decides how much of the weight the legs carry through the
floor height alone (the generic skeleton's legs do not fit the scaled subject's pelvis heights: a centimetre of
floor turns the load from 60 % of the weight to a push). A body-weight-support system instead controls its load:
here the harness's vertical offset from the trial follows an admittance law,

    d(offset)/dt = −(F_y − s·W) / c,

F_y the weld's measured vertical force on the pelvis [N], W the body weight [N], s the target share
(:data:`SUPPORT`) and c [N·s/m] the admittance damping (:data:`ADMITTANCE`); the offset is bounded to
[:data:`OFFSET_MIN`, :data:`OFFSET_MAX`]. The horizontal path and the orientation stay the trial's. The load reported
is still the weld's own force; with ``support=None`` the harness is rigid (offset 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

#: Target share of the body weight the regulated harness carries (the goal is ≤ 0.2 on average).
SUPPORT = 0.1
#: Admittance damping of the harness height [N·s/m] (a soft, fast regulation: ~10 ms against a leg of 30 kN/m;
#: docs/mujoco.md gives the results' sensitivity to it).
ADMITTANCE = 300.0
#: Bounds of the harness's vertical offset from the trial's pelvis height [m].
OFFSET_MIN, OFFSET_MAX = -0.15, 0.05


@dataclass
class Harness:
    """The harness path and its regulated height.

    Attributes:
        dt: Time step of ``placements`` [s].
        placements: (N, 4, 4) pelvis placements of the trial every ``dt`` from t = 0 [m].
        weight: Body weight W [N].
        support: Target share s of W (None: rigid harness).
        admittance: c [N·s/m].
        offset: Current vertical offset [m].
    """

    dt: float
    placements: np.ndarray
    weight: float
    support: float | None = SUPPORT
    admittance: float = ADMITTANCE
    offset: float = 0.0

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Mocap position [m] and quaternion (w, x, y, z) at time t [s]."""
        P = self.placements[min(int(round(t / self.dt)), len(self.placements) - 1)]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(P[:3, :3]).ravel())
        return P[:3, 3] + np.array([0.0, self.offset, 0.0]), quat

    def update(self, load_y: float, dt: float) -> None:
        """Integrate the offset over ``dt`` [s] for the measured vertical load ``load_y`` [N] (no-op when rigid)."""
        if self.support is None:
            return
        rate = -(load_y - self.support * self.weight) / self.admittance
        self.offset = float(np.clip(self.offset + rate * dt, OFFSET_MIN, OFFSET_MAX))
