"""Joint capacity: the robot's strength against the human's, per coordinate and direction.

At each pose, the robot's capacity in the positive direction of a coordinate is the sum of the positive
torques of every PAM about it with every PAM at the design's pressure (620 kPa), both sides (the trunk's
coordinates are crossed by PAMs of both sides); the negative direction likewise. The human's is the same
sum over every muscle of the model at activation 1 (static equilibrium). The ratio robot ÷ human per pose,
its median and the fraction of poses where robot ≥ human are the figures (:func:`joint_capacity`).
Torques in N·m.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CAPACITY_FRACTION", "DIRECTION_NAMES", "direction_capacity", "joint_capacity"]

#: A coordinate-direction is met when the robot reaches the human on at least this fraction of the poses.
CAPACITY_FRACTION = 0.9

#: What the positive / negative direction of a coordinate is called (Gait2392 sign conventions).
DIRECTION_NAMES = {
    "hip_flexion_r": ("flexion", "extension"),
    "hip_adduction_r": ("adduction", "abduction"),
    "hip_rotation_r": ("internal rotation", "external rotation"),
    "knee_angle_r": ("extension", "flexion"),
    "ankle_angle_r": ("dorsiflexion", "plantarflexion"),
    "subtalar_angle_r": ("inversion", "eversion"),
    "mtp_angle_r": ("extension", "flexion"),
    "lumbar_extension": ("extension", "flexion"),
    "lumbar_bending": ("bending right", "bending left"),
}


def direction_capacity(T: np.ndarray, sign: float) -> np.ndarray:
    """(S, C) summed torque [N·m] of every actuator of ``T`` (S, n_actuators, C) acting in direction
    ``sign`` (+1 or −1) about each coordinate, as a magnitude (≥ 0)."""
    return np.sum(np.maximum(sign * np.asarray(T, float), 0.0), axis=1)


def joint_capacity(robot_T: np.ndarray, human_T: np.ndarray, coordinates: list[str],
                   names: list[str], fraction: float = CAPACITY_FRACTION) -> list[dict]:
    """The joint-capacity table: one row per coordinate of ``coordinates`` and direction (+, −).

    Args:
        robot_T: (S, n_pams, n_coordinates) PAM torques [N·m] (every PAM, both sides).
        human_T: (S, n_muscles, n_coordinates) muscle torques [N·m] at the same poses, columns as the robot's.
        coordinates: The coordinates to tabulate.
        names: Every coordinate, in the columns' order.
        fraction: The fraction of poses a met direction needs (:data:`CAPACITY_FRACTION`).

    Returns:
        Rows with ``coordinate``, ``direction`` (``"+"``/``"-"``), ``motion`` (e.g. "extension"),
        ``robot_median_Nm``, ``human_median_Nm``, ``ratio_median``, ``ratio_min`` (robot ÷ human per pose; poses
        where the human has no torque in that direction are left out), ``fraction_robot_ge_human`` (those poses
        count as met) and ``met`` (that fraction ≥ ``fraction``).
    """
    rows = []
    for c in coordinates:
        j = names.index(c)
        for sign, label in ((1.0, "+"), (-1.0, "-")):
            r = direction_capacity(robot_T[:, :, j:j + 1], sign)[:, 0]
            h = direction_capacity(human_T[:, :, j:j + 1], sign)[:, 0]
            has = h > 1e-9
            ratio = r[has] / h[has]
            ge = float(np.mean((r >= h) | ~has)) if len(r) else float("nan")
            motion = DIRECTION_NAMES.get(c, ("positive", "negative"))[0 if sign > 0 else 1]
            rows.append({"coordinate": c, "direction": label, "motion": motion,
                         "robot_median_Nm": float(np.median(r)) if len(r) else float("nan"),
                         "human_median_Nm": float(np.median(h)) if len(h) else float("nan"),
                         "ratio_median": float(np.median(ratio)) if len(ratio) else float("nan"),
                         "ratio_min": float(np.min(ratio)) if len(ratio) else float("nan"),
                         "fraction_robot_ge_human": ge, "met": bool(ge >= fraction)})
    return rows
