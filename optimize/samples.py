"""Numeric data of one actuator's problem: sample configurations, body placements and
Jacobians (from pamkin's Pinocchio-backed kinematics), human target torques, bone capsules.

Everything here is plain numpy (picklable, sent to worker processes); CasADi is only used in
:mod:`optimize.problem`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from pamkin._resources import data_file
from pamkin.design import Pam
from pamkin.model import Model
from pamkin.osim import MovingPathPoint
from pamkin.paths import PathSet
from pamkin.rom import RangeOfMotion

from .config import RunConfig

CAPSULES_FILE = data_file("bone_capsules.yaml")
#: Interior points of each route segment checked against the bone capsules (segment parameter).
CLEARANCE_T = (0.15, 0.325, 0.5, 0.675, 0.85)
#: Margins the optimiser keeps from its limits, so that the limits also hold between samples.
STRAIN_MARGIN = 0.005           # contraction / stretch [-]
CLEARANCE_MARGIN = 0.006        # bone clearance [m]


@dataclass(frozen=True)
class Capsule:
    """A keep-out capsule fixed in a body: axis a–b [m] in the body frame, radius [m]."""

    name: str
    body: str
    a: np.ndarray
    b: np.ndarray
    radius: float


def load_capsules(side: str = "r", path: Path = CAPSULES_FILE) -> list[Capsule]:
    """Bone-shaft capsules of one side (the left is the mirror image)."""
    data = yaml.safe_load(Path(path).read_text())["capsules"]
    out = []
    for name, c in data.items():
        a, b = np.array(c["a"], float), np.array(c["b"], float)
        body = c["body"]
        if side == "l":
            a, b, body = a * [1, 1, -1], b * [1, 1, -1], body[:-2] + "_l"
        out.append(Capsule(f"{name}_{side}", body, a, b, float(c["radius"])))
    return out


@dataclass
class ActuatorData:
    """Everything numeric the CasADi problem of one actuator needs.

    Shapes: S samples (objective and constraint samples concatenated), B route bodies.
    Attributes:
        pam: The seed PAM.
        q: (S, n_coordinates) sample configurations.
        R: (S, B, 3, 3) and p: (S, B, 3) placements of the route's bodies in ground.
        body_of_point: Route point -> index into the route bodies.
        moving_x: {point index: (S, 3)} world positions of moving (knee-driven) points.
        moving_v: {point index: {coordinate: (S, 3)}} their velocities w.r.t. the coordinate.
        omega, tau: {coordinate: (S, B, 3)} body Jacobian columns (∂x/∂q = ω × x + τ).
        objective: list of (coordinate, sample indices, human torque (len), weight, label).
        constraint_idx: sample indices where the strain and distance limits are imposed.
        clearance_idx: sample indices where the bone clearance is imposed.
        capsules: list of (capsule, (S, 3) world a, (S, 3) world b).
        human_peak: {label: peak |τ_human|}.
    """

    pam: Pam
    q: np.ndarray
    bodies: list[str]
    R: np.ndarray
    p: np.ndarray
    body_of_point: list[int]
    moving_x: dict
    moving_v: dict
    omega: dict
    tau: dict
    objective: list
    constraint_idx: np.ndarray
    clearance_idx: np.ndarray
    capsules: list
    fitting_length: float
    pressure: float
    force_model: str
    primary_coordinate: str


def _grid(model: Model, rom: RangeOfMotion, coords: list[str], n: int) -> np.ndarray:
    q, _ = model.grid(coords, n, rom=rom, base={c: 0.0 for c in model.coordinates})
    return q


def actuator_data(pam: Pam, human: Model, rom: RangeOfMotion, cfg: RunConfig, fitting_length: float,
                  target=None) -> ActuatorData:
    """Sample the problem of one (right-side) PAM.

    Args:
        pam: The seed PAM (its route, coordinates and human muscles).
        human: The model giving kinematics (and, by default, the target torques).
        rom: Range of motion of the samples.
        cfg: Run description.
        fitting_length: One fitting [m].
        target: Optional callable q (N, n_coordinates) -> target torques (N, n_coordinates) [N·m];
            default: the summed torque of the PAM's human muscles at full activation.
    """
    prim = pam.primary_coordinate
    secs = [c for c in pam.secondary_coordinates]
    blocks, objective = [], []
    start = 0
    q1 = _grid(human, rom, [prim], cfg.n_primary)
    blocks.append(q1)
    objective.append((prim, np.arange(start, start + len(q1)), cfg.weight_primary, f"1-D {prim}"))
    start += len(q1)
    for c in secs:
        q2 = _grid(human, rom, [prim, c], cfg.n_secondary)
        blocks.append(q2)
        objective.append((c, np.arange(start, start + len(q2)), cfg.weight_secondary, f"2-D {prim} x {c}"))
        start += len(q2)
    coords = [prim, *secs]
    if any(c.startswith("hip_adduction") for c in coords) and not any(c.startswith("hip_flexion") for c in coords):
        coords.append(prim[:0] + "hip_flexion_" + prim[-1])
    qc = _grid(human, rom, coords, cfg.n_constraint)
    blocks.append(qc)
    # strain limits: the 1-D sweep of the primary coordinate and the full grid over the PAM's coordinates
    constraint_idx = np.concatenate([np.arange(0, len(q1)), np.arange(start, start + len(qc))])
    # bone clearance (smooth in the configuration, and many constraints per sample): every third sample
    # of the 1-D sweep and a coarse (3 per axis) grid over the PAM's coordinates
    q3 = _grid(human, rom, coords, 3)
    clearance_idx = np.concatenate([np.arange(0, len(q1), 3), np.arange(start + len(qc), start + len(qc) + len(q3))])
    blocks.append(q3)
    q = np.vstack(blocks)

    # target torques
    if target is None:
        idx = [human.muscles.index(m) for m in pam.human_muscles]
        T = human.torques(q)[:, idx].sum(axis=1)
    else:
        T = np.asarray(target(q), float)
    obj = []
    for c, rows, w, label in objective:
        obj.append((c, rows, T[rows, human.coordinates.index(c)], w, label))

    # kinematics of the route's bodies
    kin = human.kinematics
    st = kin.forward(q, warn_range=False)
    bodies = []
    for pt in pam.points:
        if pt.body not in bodies:
            bodies.append(pt.body)
    bidx = [human.bodies.index(b) for b in bodies]
    route = PathSet(kin, ["route"], [pam.points])
    W, Tt = route.body_jacobian(st)
    compared = sorted({c for c, *_ in objective})
    omega = {c: W[:, bidx, human.coordinates.index(c)] for c in compared}
    tau = {c: Tt[:, bidx, human.coordinates.index(c)] for c in compared}
    X, dlocal = route.point_positions(st)
    moving_x, moving_v = {}, {}
    for mi, (pid, mp) in enumerate(route._moving):
        moving_x[pid] = X[:, pid]
        b = human.bodies.index(mp.body)
        vel = {}
        for c in compared:
            ci = human.coordinates.index(c)
            w, t_ = W[:, b, ci], Tt[:, b, ci]
            v = np.cross(w, X[:, pid]) + t_
            for ax in range(3):
                if mp.coordinates[ax] == c:
                    v = v + st.body_R[:, b, :, ax] * dlocal[:, mi, ax, None]
            vel[c] = v
        moving_v[pid] = vel
    capsules = []
    if cfg.bone_clearance:
        for cap in load_capsules("r"):
            if cap.body not in human.bodies:
                continue
            b = human.bodies.index(cap.body)
            wa = st.body_p[:, b] + st.body_R[:, b] @ cap.a
            wb = st.body_p[:, b] + st.body_R[:, b] @ cap.b
            capsules.append((cap, wa, wb))
    return ActuatorData(pam, q, bodies, st.body_R[:, bidx], st.body_p[:, bidx],
                        [bodies.index(pt.body) for pt in pam.points], moving_x, moving_v, omega, tau, obj,
                        constraint_idx, clearance_idx, capsules, fitting_length, cfg.pressure_Pa, cfg.force_model, prim)


def is_free(pt) -> bool:
    """Route points whose location is a decision variable (fixed in a body)."""
    return not isinstance(pt, MovingPathPoint)
