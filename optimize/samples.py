"""Numeric data of one actuator's problem: sample configurations, body placements and
Jacobians (from pamkin's Pinocchio-backed kinematics), human target torques, bone capsules.

Everything here is plain numpy (picklable, sent to worker processes); CasADi is only used in
:mod:`optimize.problem`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pamkin.optimize.config import RunConfig

from pamkin._resources import data_file
from pamkin.audit.measure import GAIT_IK, gait_poses
from pamkin.errors import PamkinError, RangeWarning
from pamkin.human.model import Model
from pamkin.human.paths import PathSet
from pamkin.human.rom import RangeOfMotion
from pamkin.opensim.model_file import MovingPathPoint
from pamkin.robot.design import Pam
from pamkin.yamlio import safe_load

CAPSULES_FILE = data_file("bone_capsules.yaml")
#: Interior points of each route segment checked against the bone capsules (segment parameter).
CLEARANCE_T = (0.15, 0.325, 0.5, 0.675, 0.85)
#: Margins the optimiser keeps from its limits, so that the limits also hold between samples.
STRAIN_MARGIN = 0.005           # contraction / stretch [-]
RATED_MARGIN = 0.02             # force below 98 % of the rated force
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
    data = safe_load(Path(path).read_text())["capsules"]
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
        norm: {label: peak} normalising the whole-vector labels by the human primary peak.
        crossed: The coordinates of the whole-vector term.
        mirrored: The model has a left side (bodies ``*_l``): the robot builds the mirror image of the
            route there, and points on bodies both sides share must leave room for it.
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
    norm: dict = None                   # objective label -> normalising peak (default: the label's own)
    crossed: list = None                # coordinates of the whole-vector term
    mirrored: bool = False              # a two-sided model: the robot's left side mirrors this route


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
    q1 = _grid(human, rom, [prim], cfg.samples.primary)
    blocks.append(q1)
    objective.append((prim, np.arange(start, start + len(q1)), cfg.weights.primary, f"1-D {prim}"))
    start += len(q1)
    for c in secs:
        q2 = _grid(human, rom, [prim, c], cfg.samples.secondary)
        blocks.append(q2)
        objective.append((c, np.arange(start, start + len(q2)), cfg.weights.secondary, f"2-D {prim} x {c}"))
        start += len(q2)
    coords = [prim, *secs]
    if any(c.startswith("hip_adduction") for c in coords) and not any(c.startswith("hip_flexion") for c in coords):
        coords.append(prim[:0] + "hip_flexion_" + prim[-1])
    qc = _grid(human, rom, coords, cfg.samples.constraint)
    blocks.append(qc)
    # strain limits: the 1-D sweep of the primary coordinate and the full grid over the PAM's coordinates
    constraint_idx = np.concatenate([np.arange(0, len(q1)), np.arange(start, start + len(qc))])
    # bone clearance (smooth in the configuration, and many constraints per sample): every third sample
    # of the 1-D sweep and a coarse (3 per axis) grid over the PAM's coordinates
    q3 = _grid(human, rom, coords, 3)
    clearance_idx = np.concatenate([np.arange(0, len(q1), 3), np.arange(start + len(qc), start + len(qc) + len(q3))])
    blocks.append(q3)
    start += len(qc) + len(q3)

    # target torques
    if target is None:
        idx = [human.muscles.index(m) for m in pam.human_muscles]

        def target(qq):
            return human.torques(qq)[:, idx].sum(axis=1)

    # whole torque vector on multi-joint training poses (and the walking trial): every coordinate the
    # route or the human muscles cross, normalised by the human peak about the primary coordinate
    crossed: list[str] = []
    norm: dict[str, float] = {}
    train_rows = np.zeros(0, dtype=int)
    if cfg.weights.whole_vector > 0 and (cfg.samples.random > 0 or cfg.samples.gait):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            crossed = crossed_coordinates(human, rom, pam.points, target, seed=cfg.seed)
        if prim not in crossed:
            crossed.append(prim)
        qt = [training_poses(human, rom, crossed, cfg.samples.random, cfg.seed, pam.id)] if cfg.samples.random > 0 else []
        if cfg.samples.gait:
            qt.append(gait_training_poses(human))
        qt = np.vstack(qt)
        if len(qt):
            train_rows = np.arange(start, start + len(qt))
            blocks.append(qt)
            start += len(qt)
        # the strain and force limits also at the corners of the crossed coordinates' range (held-out
        # poses there stretched soleus and rectus femoris past Festo's rated force)
        qk = corner_poses(human, rom, crossed, cfg.seed, pam.id)
        corner_rows = np.arange(start, start + len(qk))
        blocks.append(qk)
        start += len(qk)
    q = np.vstack(blocks)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)    # training poses may leave the human model's ranges
        T = np.asarray(target(q), float)
    for c in crossed:
        objective.append((c, train_rows, cfg.weights.whole_vector, f"train {c}"))
    if len(train_rows):
        peak = float(np.max(np.abs(T[train_rows, human.coordinates.index(prim)])))
        if peak <= 1e-9:
            peak = float(np.max(np.abs(T[objective[0][1], human.coordinates.index(prim)])))
        norm = {f"train {c}": peak for c in crossed}
        constraint_idx = np.concatenate([constraint_idx, train_rows, corner_rows])
        clearance_idx = np.concatenate([clearance_idx, train_rows[::6]])
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
    if cfg.limits.bone_clearance:
        for cap in load_capsules("r"):
            if cap.body not in human.bodies:
                continue
            b = human.bodies.index(cap.body)
            wa = st.body_p[:, b] + st.body_R[:, b] @ cap.a
            wb = st.body_p[:, b] + st.body_R[:, b] @ cap.b
            capsules.append((cap, wa, wb))
    return ActuatorData(pam, q, bodies, st.body_R[:, bidx], st.body_p[:, bidx],
                        [bodies.index(pt.body) for pt in pam.points], moving_x, moving_v, omega, tau, obj,
                        constraint_idx, clearance_idx, capsules, fitting_length, cfg.pressure_Pa, cfg.force_model, prim,
                        norm, crossed, mirrored=any(b.name.endswith("_l") for b in human.osim.bodies))


#: Random stream of the optimiser's training poses (the audit draws from ``AUDIT_STREAM``).
OPTIMIZE_STREAM = 0xA0D2
#: Every k-th pair of consecutive walking-trial frames gives one training pose (their midpoint).
GAIT_STRIDE = 6
_MIRROR_NEGATE = ("lumbar_bending", "lumbar_rotation")


def crossed_coordinates(model: Model, rom: RangeOfMotion, route, human_torque, n_probe: int = 64,
                        seed: int = 0) -> list[str]:
    """Coordinates (other than the pelvis's) about which the route or the human muscles have a
    torque at some of ``n_probe`` random poses over every coordinate of ``rom``.

    Args:
        route: The PAM's route points.
        human_torque: Callable q (N, n_coordinates) -> (N, n_coordinates) human torques [N·m].
    """
    coords = [c for c in rom.coordinates if c in model.coordinates]
    q = training_poses(model, rom, coords, n_probe, seed, 0)
    kin = model.kinematics
    st = kin.forward(q, warn_range=False)
    R = PathSet(kin, ["route"], [route]).evaluate(st).dense_moment_arms(len(model.coordinates))[:, 0]
    T = np.asarray(human_torque(q), float)
    hit = (np.max(np.abs(R), axis=0) > 1e-9) | (np.max(np.abs(T), axis=0) > 1e-9)
    return [c for c, h in zip(model.coordinates, hit) if h and not c.startswith("pelvis_")]


def with_dependencies(model: Model, rom: RangeOfMotion, coords: list[str]) -> list[str]:
    """``coords`` that ``rom`` limits, plus the coordinates their coupled limits depend on (so that
    :meth:`pamkin.human.rom.RangeOfMotion.from_unit` can place them)."""
    coords = [c for c in coords if c in rom.coordinates]
    for c in list(coords):
        dep = getattr(rom._coupled_by.get(c), "depends_on", None)
        if dep and dep not in coords and dep in model.coordinates:
            coords.append(dep)
    return coords


def poses_from_unit(model: Model, rom: RangeOfMotion, coords: list[str], u: np.ndarray) -> np.ndarray:
    """(N, n_coordinates) poses with ``coords`` placed in their range by the numbers ``u`` (N, len(coords))
    in [0, 1] (:meth:`pamkin.human.rom.RangeOfMotion.from_unit`), every other coordinate 0."""
    q = np.zeros((len(u), len(model.coordinates)))
    for c, v in rom.from_unit(coords, u).items():
        q[:, model.coordinates.index(c)] = v
    return q


def training_poses(model: Model, rom: RangeOfMotion, coords: list[str], n: int, seed: int, actuator: int) -> np.ndarray:
    """``n`` random poses varying ``coords`` (and the coordinates their coupled limits depend on)
    uniformly within ``rom``, others 0; stream :data:`OPTIMIZE_STREAM` (never the audit's)."""
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(OPTIMIZE_STREAM, int(actuator))))
    coords = with_dependencies(model, rom, coords)
    return poses_from_unit(model, rom, coords, rng.random((n, len(coords))))


#: Largest number of range-of-motion corners among an actuator's constraint samples.
MAX_CORNERS = 64


def corner_poses(model: Model, rom: RangeOfMotion, coords: list[str], seed: int, actuator: int,
                 max_n: int = MAX_CORNERS) -> np.ndarray:
    """The corners of the range-of-motion box of ``coords`` (and the coordinates their coupled limits
    depend on), others 0: where a route is longest or shortest when its length is monotone in each
    coordinate, i.e. where the PAM is most stretched (largest force) or most contracted. At most
    ``max_n`` of them (a seeded choice, stream :data:`OPTIMIZE_STREAM`)."""
    import itertools  # noqa: PLC0415

    coords = with_dependencies(model, rom, coords)
    U = np.array(list(itertools.product((0.0, 1.0), repeat=len(coords))), dtype=float).reshape(-1, len(coords))
    if len(U) > max_n:
        rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(OPTIMIZE_STREAM, int(actuator), 1)))
        U = U[np.sort(rng.choice(len(U), max_n, replace=False))]
    return poses_from_unit(model, rom, coords, U)


def boundary_poses(model: Model, rom: RangeOfMotion, coords: list[str], rng: np.random.Generator,
                   n: int) -> np.ndarray:
    """``n`` poses with each of ``coords`` (and the coordinates their coupled limits depend on) at its
    lower limit, its upper limit or uniform within its range, a third each; others 0. Uniform samples
    rarely reach the edges of a many-coordinate range, where routes are longest, shortest or nearest a
    bone."""
    coords = with_dependencies(model, rom, coords)
    u = rng.random((n, len(coords)))
    pick = rng.random((n, len(coords)))
    u[pick < 1 / 3] = 0.0
    u[pick > 2 / 3] = 1.0
    return poses_from_unit(model, rom, coords, u)


def gait_training_poses(model: Model, ik_path=None, stride: int = GAIT_STRIDE) -> np.ndarray:
    """Right-leg and lumbar poses from a walking trial, *between* its frames (midpoints of every
    ``stride``-th pair, so never an audit sample): the right leg as recorded and the left leg
    mirrored onto the right (lumbar bending and rotation negated); pelvis at 0. Empty when the
    trial or the model's coordinates are missing."""

    path = Path(ik_path or GAIT_IK)
    right = [c for c in model.coordinates if c.endswith("_r")]
    if not path.is_file() or not right:
        return np.zeros((0, len(model.coordinates)))

    try:
        g, _ = gait_poses(model, path)
    except PamkinError:
        return np.zeros((0, len(model.coordinates)))
    mid = 0.5 * (g[:-1:stride] + g[1::stride])
    out = []
    for side in ("r", "l"):
        q = np.zeros((len(mid), len(model.coordinates)))
        for c in model.coordinates:
            i = model.coordinates.index(c)
            if c.endswith("_r"):
                q[:, i] = mid[:, model.coordinates.index(c[:-2] + "_" + side)]
            elif c.startswith("lumbar"):
                q[:, i] = mid[:, i] * (-1.0 if side == "l" and c in _MIRROR_NEGATE else 1.0)
        out.append(q)
    return np.vstack(out)


def is_free(pt) -> bool:
    """Route points whose location is a decision variable (fixed in a body)."""
    return not isinstance(pt, MovingPathPoint)
