"""Can the robot walk like the human? PAM pressure plans over a recorded walking trial.

The trial is an OpenSim pipeline's output (:mod:`pamkin.opensim.storage`): inverse-kinematics angles
(``.mot``, every Gait2392 coordinate) and inverse-dynamics moments (``.sto``, columns
``<coordinate>_moment`` [N·m] / ``<coordinate>_force`` [N]). By default the frames are the IK
frames inside the ID time range; the moments are interpolated linearly onto them. The moments
belong to the subject the pipeline scaled (OpenSim's subject01, about 72 kg) and are used as
given on the generic Gait2392 skeleton of the robot.

At every frame all PAMs of a design (both legs, the left mirrored, and the trunk PAMs; 54 for
the 27-PAM designs) sit on the skeleton in the IK posture; pamkin's path engine gives each PAM's
strain and its moment arms about the 17 non-pelvis coordinates. The Festo v3 force is affine in
pressure at a fixed strain, clipped at zero::

    F_k(P) = max(a_k + b_k·P, 0)          [N; the route's tension: n_parallel and cable efficiency included,
                                           ÷ transmission; b_k > 0]

(a_k, b_k from :func:`pamkin.robot.festo.force` at two pressures, never re-derived). Per frame the
pressures P_k ∈ [0, P_max] solve a lexicographic pair of convex QPs in x_k = P_k/P_max:

1. residual: minimise Σ_c ((τ_c(x) − τ_ID,c)/peak_c)², the moment residual of every coordinate
   normalised by that coordinate's peak |ID moment| over the frames (the same normalisation as
   the 5 % feasibility test);
2. effort: minimise Σ_k x_k² subject to every moment equal to its stage-1 value (the stage-1
   moments are unique: the stage-1 objective is strictly convex in the moments). Should the
   effort QP fail, or move a normalised moment by more than 1e-6, the frame keeps its stage-1
   pressures and is counted (``summary.effort_fallback_frames``).

A PAM that is slack at some pressures (a_k < 0, a contracted PAM) enters with
x_k ∈ [P0_k/P_max, 1], P0_k = −a_k/b_k the pressure where it starts pulling, on which its force
is affine; the effort counts it at P0_k when unused (a convex surrogate), its reported pressure
is then 0, the least pressure giving zero force. A PAM that is slack even at P_max is left out
of the frame's problem. Both QPs are solved by ProxQP (proxsuite) through qpsolvers, warm
started from the previous frame's solution (``solver=`` picks any qpsolvers backend).
Reported moments are recomputed from the final pressures with :func:`pamkin.robot.festo.force`.

A frame is *feasible* when every coordinate's residual is below ``tolerance`` (5 %) of that
coordinate's peak moment.

PAM volume model (air consumption): a Festo DMSP is an ideal McKibben braid of constant thread
length whose resting state is a cylinder of the inner diameter d and the resting length l0,
V0 = π d²/4 · l0. With braid angle θ, l ∝ cos θ and diameter ∝ sin θ, so
V = V0 · sin²θ cos θ / (sin²θ0 cos θ0) with cos θ = (1 − ε) cos θ0. θ0 follows from the free
contraction: the ideal braid stops pulling at θ* = 54.74° (cos θ* = 1/√3), so
cos θ0 = (1/√3)/(1 − kmax) (kmax of :func:`pamkin.robot.festo.kmax`; 54.74° is also where the volume
is largest). Air taken from the supply, in free-air (normal) litres at 101.325 kPa, isothermal:
Σ max(Δ(P_gauge·V), 0)/p_atm over the frames (air is exhausted when P·V falls; a volume change at
zero gauge pressure breathes atmosphere, not supply air), scaled to one stride by
T_stride/T_window (the default window, 1.1 s, is shorter than the 1.235 s stride).
"""

from __future__ import annotations

import math
import time as _time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pamkin._resources import SHARED_DIR
from pamkin.errors import ParameterError, SolverError, StorageFileError
from pamkin.opensim.storage import Storage, read_storage
from pamkin.outputs import strict_json, write_file
from pamkin.robot import festo
from pamkin.robot.biped import PamRobot, design_robot

if TYPE_CHECKING:  # pragma: no cover
    from pamkin.robot.biped import PamRobot

__all__ = [
    "DEFAULT_GRF",
    "DEFAULT_ID",
    "DEFAULT_IK",
    "GAIT_DIR",
    "P_MAX_DEFAULT",
    "CoordinateResult",
    "GaitEvents",
    "GaitPlan",
    "GaitTrial",
    "PamGaitResult",
    "feasible_frame_fraction",
    "force_coefficients",
    "gait_events",
    "gait_plan",
    "load_trial",
    "pam_volume",
    "plan_pressures",
    "plot_pressures",
    "write_outputs",
]

#: The reference walking trial (``gait/`` in the shared reference data: ``../shared`` beside the
#: checkout or ``$PAMKIN_SHARED``).
GAIT_DIR = SHARED_DIR / "gait"
DEFAULT_IK = GAIT_DIR / "subject01_walk1_ik.mot"
DEFAULT_ID = GAIT_DIR / "subject01_walk1_inverse_dynamics.sto"
DEFAULT_GRF = GAIT_DIR / "subject01_walk1_grf.mot"
#: Default supply pressure limit [Pa] (gauge; the Festo DMSP rating and the v3 reference).
P_MAX_DEFAULT = 620e3
#: A frame is feasible when every |residual| < this fraction of its coordinate's peak moment.
FEASIBLE_TOLERANCE = 0.05
#: Atmospheric pressure [Pa] for free-air (normal) litres.
P_ATM = 101325.0
#: Vertical ground reaction force [N] above which a foot is in stance.
STANCE_THRESHOLD_N = 20.0
_STAGE2_SLACK = 1e-6          # effort QP may move a normalised moment by at most this (else: stage-1 pressures)
_COS_THETA_STAR = 1.0 / math.sqrt(3.0)


# --------------------------------------------------------------------------- the trial


@dataclass(frozen=True)
class GaitEvents:
    """Heel strikes and toe-offs [s] per side (``"r"``, ``"l"``), from vertical GRFs.

    Attributes:
        heel_strikes: {side: times [s]} where the vertical force rises above the threshold.
        toe_offs: {side: times [s]} where it falls below.
        threshold_N: Stance threshold [N].
        path: The GRF file.
        stance: {side: (times [s], bool stance)} on the GRF file's time grid.
    """

    heel_strikes: dict[str, np.ndarray]
    toe_offs: dict[str, np.ndarray]
    threshold_N: float
    path: str
    stance: dict[str, tuple[np.ndarray, np.ndarray]] = field(repr=False, default_factory=dict)

    def stride_time(self) -> float | None:
        """Duration of one stride [s] (heel strike to heel strike of the same foot), if seen."""
        for side in ("r", "l"):
            hs = self.heel_strikes.get(side, np.empty(0))
            if len(hs) >= 2:
                return float(hs[1] - hs[0])
        return None

    def to_dict(self) -> dict:
        return {"heel_strikes_s": {s: [round(float(t), 4) for t in v] for s, v in self.heel_strikes.items()},
                "toe_offs_s": {s: [round(float(t), 4) for t in v] for s, v in self.toe_offs.items()},
                "threshold_N": self.threshold_N, "stride_time_s": self.stride_time(), "file": self.path}


def gait_events(grf: str | Path | Storage = DEFAULT_GRF, threshold: float = STANCE_THRESHOLD_N,
                columns: dict[str, str] | None = None) -> GaitEvents:
    """Heel strikes and toe-offs from the vertical ground reaction forces of a ``.mot`` file.

    Args:
        grf: GRF storage file (or a read :class:`~pamkin.opensim.storage.Storage`).
        threshold: Stance when the vertical force exceeds this [N].
        columns: {side: vertical-force column}; default the Gait2392 pipeline's
            ``ground_force_vy`` (right foot) and ``1_ground_force_vy`` (left foot) — the
            assignment of its external-loads file, which the centres of pressure confirm
            (they lie under calcn_r and calcn_l respectively).

    Raises:
        StorageFileError: Malformed file or missing column.
    """
    s = grf if isinstance(grf, Storage) else read_storage(grf)
    columns = columns or {"r": "ground_force_vy", "l": "1_ground_force_vy"}
    hs, to, stance = {}, {}, {}
    for side, col in columns.items():
        on = s.column(col) > threshold
        d = np.diff(on.astype(int))
        hs[side] = s.time[1:][d == 1]
        to[side] = s.time[1:][d == -1]
        stance[side] = (s.time, on)
    return GaitEvents(hs, to, float(threshold), s.path, stance)


@dataclass(frozen=True)
class GaitTrial:
    """Angles and moments of a walking trial on common frames.

    Attributes:
        times: (N,) frame times [s].
        q: (N, n_model_coordinates) configurations in the model's coordinate order [rad, m].
        coordinates: The actuated coordinates (the 17 non-pelvis ones by default).
        moments: (N, len(coordinates)) inverse-dynamics moments [N·m] at the frames.
        ik_path: The angles file.
        id_path: The moments file.
        events: Gait events from the GRF file (``None`` without one).
    """

    times: np.ndarray
    q: np.ndarray
    coordinates: tuple[str, ...]
    moments: np.ndarray
    ik_path: str
    id_path: str
    events: GaitEvents | None = None


def _actuated(model) -> list[str]:
    """Coordinates the PAMs act on: every coordinate except the pelvis's six."""
    return [c for c in model.coordinates if not c.startswith("pelvis_")]


def load_trial(model, ik: str | Path = DEFAULT_IK, id: str | Path = DEFAULT_ID,  # noqa: A002
               grf: str | Path | None = DEFAULT_GRF, coordinates: Sequence[str] | None = None,
               time_range: tuple[float, float] | None = None) -> GaitTrial:
    """Read an IK angles file and an ID moments file onto common frames.

    Frames: the IK frames inside the ID file's time range (within 1e-4 s; OpenSim writes
    1.59999886 for 1.6), optionally cut to ``time_range``; moments interpolated linearly.
    Units are taken from the headers: angles are converted from degrees when the IK file says
    ``inDegrees=yes`` (translations stay metres); an IK file without ``inDegrees`` is refused,
    and so is one that says radians but holds angles beyond 4π. The ID file must not say
    ``inDegrees=yes`` (OpenSim's ID output says ``no``); its rotational columns are
    ``<coordinate>_moment`` [N·m].

    Args:
        model: The skeleton (:class:`pamkin.human.model.Model`), for coordinate names and types.
        ik: Angles file (``.mot``).
        id: Moments file (``.sto``).
        grf: Ground reaction forces for the gait events, or ``None``.
        coordinates: Actuated coordinates (default: all but the pelvis's six).
        time_range: (start, end) [s] to cut the frames to.

    Raises:
        StorageFileError: Malformed files, missing columns (named), unit problems, or no
            common frames.
    """
    ik_s, id_s = read_storage(ik), read_storage(id)
    names = list(model.coordinates)
    rotational = [c.rotational for c in model.osim.coordinates]
    q_all = ik_s.coordinates_si(names, rotational)
    if not ik_s.in_degrees:
        rot = np.asarray(rotational)
        big = np.abs(q_all[:, rot]).max(axis=0) > 4 * math.pi
        if big.any():
            col = [n for n, r in zip(names, rotational) if r][int(np.argmax(big))]
            raise StorageFileError(ik_s.path, "the header says inDegrees=no but the angles exceed 4π: "
                                              "are they degrees?", column=col)
    if id_s.in_degrees:
        raise StorageFileError(id_s.path, "the header says inDegrees=yes; inverse-dynamics output (moments "
                                          "in N·m) says inDegrees=no: is this an angles file?")
    coords = list(coordinates) if coordinates is not None else _actuated(model)
    unknown = [c for c in coords if c not in names]
    if unknown:
        raise ParameterError(f"unknown coordinate(s) {unknown}; the model has {names}")
    kind = {c: ("_moment" if r else "_force") for c, r in zip(names, rotational)}
    id_cols = [c + kind[c] for c in coords]
    for c, col in zip(coords, id_cols):
        if col not in id_s:
            other = c + ("_force" if kind[c] == "_moment" else "_moment")
            why = (f" (it has {other!r}: a {'translation' if kind[c] == '_moment' else 'rotation'} in "
                   f"the file, not in the model)") if other in id_s else ""
            raise StorageFileError(id_s.path, f"no inverse-dynamics column for coordinate {c!r}{why}", column=col)
    tol = 1e-4
    lo, hi = float(id_s.time[0]) - tol, float(id_s.time[-1]) + tol
    if time_range is not None:
        lo, hi = max(lo, float(time_range[0]) - 1e-9), min(hi, float(time_range[1]) + 1e-9)
    sel = (ik_s.time >= lo) & (ik_s.time <= hi)
    if not sel.any():
        raise StorageFileError(ik_s.path, f"no IK frame inside the moments' time range [{id_s.time[0]:.4g}, "
                                          f"{id_s.time[-1]:.4g}] s of {id_s.path}"
                                          + (f" cut to {time_range}" if time_range else ""))
    times = ik_s.time[sel]
    moments = id_s.interpolate(times, id_cols, tolerance=tol)
    events = gait_events(grf) if grf is not None else None
    return GaitTrial(times, q_all[sel], tuple(coords), moments, ik_s.path, id_s.path, events)


# --------------------------------------------------------------------------- PAM physics


def _pam_forces(robot: PamRobot, strain: np.ndarray, pressure: float | np.ndarray) -> np.ndarray:
    """Route tensions [N] (n_parallel and cable efficiency included, ÷ transmission) of every PAM column (festo.force) at
    ``pressure`` [Pa], a number or (N, n_pams) per frame and PAM."""
    F = np.zeros_like(strain)
    P = np.asarray(pressure, dtype=float)
    for d in np.unique(robot.diameter):
        cols = robot.diameter == d
        F[:, cols] = festo.force(strain[:, cols], robot.rest[cols], P[:, cols] if P.ndim == 2 else P, int(d),
                                 model=robot.design.force_model)
    return F * robot.n_parallel * robot.efficiency / robot.transmission


def force_coefficients(robot: PamRobot, strain: np.ndarray, p_max: float = P_MAX_DEFAULT
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Affine pressure law F = max(a + b·P, 0) of every PAM at fixed strains.

    Computed from :func:`pamkin.robot.festo.force` at P_max and 2·P_max (where F(P_max) > 0 the
    force is unclipped at both); where F(P_max) = 0 the PAM is slack over [0, P_max] and
    a = b = 0 is returned.

    Args:
        robot: The robot (its design's force model must be affine in pressure: ``v3``).
        strain: (N, n_pams) contractions [-].
        p_max: Largest pressure [Pa].

    Returns:
        a [N] (the unclipped force at zero gauge pressure), b [N/Pa], both (N, n_pams).

    Raises:
        ParameterError: A force model other than v3.
    """
    if festo._check_model(robot.design.force_model) != "v3":
        raise ParameterError(f"design {robot.design.name!r} uses force model {robot.design.force_model!r}: "
                             "pressure plans need the v3 model (affine in pressure)")
    f1 = _pam_forces(robot, strain, p_max)
    f2 = _pam_forces(robot, strain, 2 * p_max)
    live = f1 > 0
    b = np.where(live, (f2 - f1) / p_max, 0.0)
    a = np.where(live, f1 - b * p_max, 0.0)
    return a, b


def pam_volume(strain: np.ndarray, rest_length: np.ndarray, diameter_mm: np.ndarray,
               kmax: np.ndarray) -> np.ndarray:
    """Inner volume [m³] of one PAM (ideal McKibben braid; see the module docstring).

    Args:
        strain: Contraction ε [-] (broadcasts with the others).
        rest_length: Resting length l0 [m].
        diameter_mm: Inner diameter d [mm] (the resting cylinder's).
        kmax: Free contraction [-] (sets the resting braid angle).
    """
    v0 = math.pi / 4 * (np.asarray(diameter_mm, float) * 1e-3) ** 2 * rest_length
    c0 = _COS_THETA_STAR / (1.0 - np.asarray(kmax, float))
    c = np.clip((1.0 - np.asarray(strain, float)) * c0, 0.0, 1.0)
    return v0 * (1.0 - c**2) * c / ((1.0 - c0**2) * c0)


def _pam_kmax(robot: PamRobot) -> np.ndarray:
    out = np.empty(len(robot.names))
    for d in np.unique(robot.diameter):
        cols = robot.diameter == d
        out[cols] = festo.kmax(robot.rest[cols], int(d), model=robot.design.force_model)
    return out


# --------------------------------------------------------------------------- the QPs


@dataclass(frozen=True)
class _Solution:
    pressures: np.ndarray     # (N, n) Pa
    iterations: int
    solve_time_s: float


def plan_pressures(R: np.ndarray, a: np.ndarray, b: np.ndarray, moments: np.ndarray, peak: np.ndarray,
                   p_max: float = P_MAX_DEFAULT, solver: str = "proxqp", eps: float = 1e-10,
                   stage2_fallback: list[int] | None = None) -> np.ndarray:
    """Per-frame PAM pressures reproducing the moments (the lexicographic QPs of the module).

    Args:
        R: (N, n_pams, m) moment arms about the m coordinates [m].
        a: (N, n_pams) force at zero gauge pressure, unclipped [N] (:func:`force_coefficients`).
        b: (N, n_pams) force per pressure [N/Pa] (0: slack up to P_max).
        moments: (N, m) moments to reproduce [N·m].
        peak: (m,) normalisation of each coordinate's residual [N·m] (> 0).
        p_max: Largest pressure [Pa].
        solver: A qpsolvers backend (default ``"proxqp"``; ``"daqp"``, ``"osqp"`` also work).
        eps: Solver tolerance (normalised units).
        stage2_fallback: If given, receives the frames where the effort QP failed or moved the
            moments by more than 1e-6 of a peak; those frames keep the stage-1 pressures.

    Returns:
        (N, n_pams) pressures [Pa] in [0, p_max]; a PAM whose force is zero gets the least
        pressure giving zero force (0).

    Raises:
        SolverError: The solver failed at a frame (named by index).
    """
    import qpsolvers  # noqa: PLC0415

    N, n, m = R.shape
    peak = np.asarray(peak, float)
    if peak.shape != (m,) or np.any(peak <= 0):
        raise ParameterError(f"peak must be {m} positive moments, got {peak!r}")
    opts: dict[str, Any] = {}
    if solver == "proxqp":
        opts = {"eps_abs": eps, "eps_rel": 0.0}
    elif solver == "osqp":
        opts = {"eps_abs": eps, "eps_rel": eps, "polish": True, "max_iter": 200000}
    P = np.zeros((N, n))
    x_prev = np.zeros(n)
    fallback: list[int] = []
    for i in range(N):
        live = b[i] > 0
        if not live.any():
            continue
        idx = np.nonzero(live)[0]
        gain = b[i, idx] * p_max                               # N per unit x
        x_lo = np.clip(-a[i, idx] / gain, 0.0, 1.0)            # slack threshold (contracted PAMs)
        x_hi = np.ones(len(idx))
        G = (R[i, idx, :] * gain[:, None]).T / peak[:, None]   # (m, nl) normalised moment per x
        t0 = (R[i, idx, :] * a[i, idx, None]).sum(axis=0)      # moments at x = 0 (affine part)
        r0 = (t0 - moments[i]) / peak
        x0 = np.clip(x_prev[idx], x_lo, x_hi)
        H1 = G.T @ G
        q1 = G.T @ r0
        x1 = qpsolvers.solve_qp(H1, q1, lb=x_lo, ub=x_hi, solver=solver, initvals=x0, **opts)
        if x1 is None and solver != "daqp":
            # ProxQP occasionally stops without a solution on this positive semi-definite QP (seen on one
            # frame in a few runs of the same data): the active-set DAQP on H1 + 1e-12 I solves it
            x1 = qpsolvers.solve_qp(H1 + 1e-12 * np.eye(len(idx)), q1, lb=x_lo, ub=x_hi, solver="daqp")
        if x1 is None:
            raise SolverError(f"{solver}: residual QP failed at frame {i}")
        x1 = np.clip(x1, x_lo, x_hi)
        rows = np.abs(G).max(axis=1) > 0                       # coordinates some live PAM acts on
        x2 = qpsolvers.solve_qp(np.eye(len(idx)), np.zeros(len(idx)), A=G[rows], b=G[rows] @ x1, lb=x_lo,
                                ub=x_hi, solver=solver, initvals=x1, **opts)
        if x2 is None or np.abs(G @ x2 - G @ x1).max() > _STAGE2_SLACK:
            x2 = x1                                            # keep the stage-1 pressures (counted)
            fallback.append(i)
        x2 = np.clip(x2, x_lo, x_hi)
        x_prev = np.zeros(n)
        x_prev[idx] = x2
        p = x2 * p_max
        p[x2 <= x_lo + 1e-9] = 0.0     # at its lower bound: slack (least pressure 0) or already 0 Pa
        P[i, idx] = p
    if stage2_fallback is not None:
        stage2_fallback.extend(fallback)
    return P


# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class CoordinateResult:
    """Residual of one coordinate over the gait.

    Attributes:
        name: Coordinate.
        peak_moment_Nm: Peak |ID moment| over the frames [N·m].
        rms_residual_Nm: RMS of robot − ID moment [N·m].
        max_residual_Nm: Largest |robot − ID| [N·m].
        within_tolerance_fraction: Frames where this coordinate's residual < tolerance × peak.
    """

    name: str
    peak_moment_Nm: float
    rms_residual_Nm: float
    max_residual_Nm: float
    within_tolerance_fraction: float

    @property
    def rms_residual_pct(self) -> float:
        """RMS residual, % of the peak moment."""
        return 100 * self.rms_residual_Nm / self.peak_moment_Nm

    @property
    def max_residual_pct(self) -> float:
        """Largest residual, % of the peak moment."""
        return 100 * self.max_residual_Nm / self.peak_moment_Nm

    def to_dict(self) -> dict:
        return {"peak_moment_Nm": self.peak_moment_Nm, "rms_residual_Nm": self.rms_residual_Nm,
                "max_residual_Nm": self.max_residual_Nm, "rms_residual_pct_of_peak": self.rms_residual_pct,
                "max_residual_pct_of_peak": self.max_residual_pct,
                "within_tolerance_fraction": self.within_tolerance_fraction}


@dataclass(frozen=True)
class PamGaitResult:
    """One PAM column (one side) over the gait.

    Attributes:
        name: Column name (``pam04_r``).
        id: Actuator id.
        label: PAM name.
        side: ``"r"`` or ``"l"``.
        diameter_mm: Festo diameter [mm].
        n_parallel: PAMs in parallel on the route.
        peak_pressure_kPa: Largest pressure [kPa].
        mean_pressure_kPa: Mean pressure over the frames [kPa].
        saturated_fraction: Frames at P_max.
        dead_zone_fraction: Frames with the strain outside [−max_pretension, kmax].
        slack_fraction: Frames where the PAM pulls nothing.
        peak_force_N: Largest force on the route [N] (the PAMs' force ÷ transmission).
        air_per_stride_NL: Supply air per stride [normal litres] (module docstring).
        volume_range_L: (min, max) inner volume of all its parallel PAMs [L].
        transmission: 1, or k for a PAM on a k:1 pulley block (:mod:`pamkin.robot.design`).
    """

    name: str
    id: int
    label: str
    side: str
    diameter_mm: int
    n_parallel: int
    peak_pressure_kPa: float
    mean_pressure_kPa: float
    saturated_fraction: float
    dead_zone_fraction: float
    slack_fraction: float
    peak_force_N: float
    air_per_stride_NL: float
    volume_range_L: tuple[float, float]
    transmission: int = 1

    def to_dict(self) -> dict:
        return {"id": self.id, "name": self.label, "side": self.side, "diameter_mm": self.diameter_mm,
                "n_parallel": self.n_parallel, "peak_pressure_kPa": self.peak_pressure_kPa,
                "mean_pressure_kPa": self.mean_pressure_kPa, "saturated_fraction": self.saturated_fraction,
                "dead_zone_fraction": self.dead_zone_fraction, "slack_fraction": self.slack_fraction,
                "peak_force_N": self.peak_force_N, "air_per_stride_NL": self.air_per_stride_NL,
                "volume_range_L": list(self.volume_range_L), "transmission": self.transmission}


@dataclass(frozen=True)
class GaitPlan:
    """A design's pressure plan over a walking trial (:func:`gait_plan`).

    Attributes:
        design: Design name.
        design_path: Its file.
        trial: The frames (angles, ID moments, events).
        p_max_Pa: Pressure limit [Pa].
        tolerance: Feasibility tolerance (fraction of each coordinate's peak).
        solver: qpsolvers backend used.
        pam_names: PAM columns.
        pressures: (N, n_pams) [Pa].
        forces: (N, n_pams) [N], from :func:`pamkin.robot.festo.force` at the pressures.
        robot_moments: (N, m) Σ force × moment arm [N·m].
        strain: (N, n_pams) contractions [-].
        in_range: (N, n_pams) strain within the PAM's limits (else a dead zone).
        volumes: (N, n_pams) inner volumes [m³] (parallel PAMs summed).
        coordinate_results: Per coordinate.
        pam_results: Per PAM column.
        outside_rom: {coordinate: frames outside the robot's range of motion}.
        effort_fallback_frames: Frames keeping the stage-1 pressures (effort QP failed).
        timings_s: {"kinematics", "solve", "total"} [s].
    """

    design: str
    design_path: str
    trial: GaitTrial
    p_max_Pa: float
    tolerance: float
    solver: str
    pam_names: tuple[str, ...]
    pressures: np.ndarray
    forces: np.ndarray
    robot_moments: np.ndarray
    strain: np.ndarray
    in_range: np.ndarray
    volumes: np.ndarray
    coordinate_results: tuple[CoordinateResult, ...]
    pam_results: tuple[PamGaitResult, ...]
    outside_rom: dict[str, int]
    effort_fallback_frames: int
    timings_s: dict[str, float]

    @property
    def residuals(self) -> np.ndarray:
        """(N, m) robot − ID moments [N·m]."""
        return self.robot_moments - self.trial.moments

    @property
    def peaks(self) -> np.ndarray:
        """(m,) peak |ID moment| of each coordinate [N·m]."""
        return np.array([c.peak_moment_Nm for c in self.coordinate_results])

    @property
    def feasible(self) -> np.ndarray:
        """(N,) True where every residual is below ``tolerance`` × its coordinate's peak."""
        return np.all(np.abs(self.residuals) < self.tolerance * self.peaks, axis=1)

    @property
    def feasible_frame_fraction(self) -> float:
        """Fraction of frames where all residuals are within tolerance."""
        return float(self.feasible.mean())

    def summary(self) -> dict:
        """Headline numbers (the ``summary`` of :meth:`to_dict`)."""
        P = self.pressures
        sat = [r.name for r in self.pam_results if r.saturated_fraction > 0]
        dead = [r.name for r in self.pam_results if r.dead_zone_fraction > 0]
        t = self.trial.times
        ev = self.trial.events
        return {
            "feasible_frame_fraction": self.feasible_frame_fraction,
            "frames": int(len(t)),
            "time_range_s": [float(t[0]), float(t[-1])],
            "n_pams": len(self.pam_names),
            "coordinates": len(self.trial.coordinates),
            "tolerance_fraction_of_peak": self.tolerance,
            "p_max_kPa": self.p_max_Pa / 1e3,
            "peak_pressure_kPa": float(P.max() / 1e3),
            "mean_pressure_kPa": float(P.mean() / 1e3),
            "saturated_pams": sat,
            "dead_zone_pams": dead,
            "air_per_stride_NL": float(sum(r.air_per_stride_NL for r in self.pam_results)),
            "stride_time_s": ev.stride_time() if ev is not None else None,
            "worst_rms_coordinate": max(self.coordinate_results, key=lambda c: c.rms_residual_pct).name,
            "frames_outside_robot_rom": self.outside_rom,
            "solver": self.solver,
            "effort_fallback_frames": self.effort_fallback_frames,
            "timings_s": self.timings_s,
        }

    def to_dict(self) -> dict:
        """JSON-ready: ``design``, ``summary``, ``coordinates`` {name: ...}, ``pams`` {name: ...},
        ``events``, ``files`` and ``notes`` (no per-frame series: see :func:`write_outputs`)."""
        return {
            "design": self.design,
            "design_path": self.design_path,
            "summary": self.summary(),
            "coordinates": {c.name: c.to_dict() for c in self.coordinate_results},
            "pams": {r.name: r.to_dict() for r in self.pam_results},
            "events": self.trial.events.to_dict() if self.trial.events is not None else None,
            "files": {"ik": self.trial.ik_path, "id": self.trial.id_path},
            "notes": {
                "moments": "inverse-dynamics moments of OpenSim's scaled subject01 (about 72 kg), used as "
                           "given on the generic Gait2392 skeleton",
                "objective": "per frame: min sum((residual_c/peak_c)^2), then min sum((P/P_max)^2) keeping "
                             "the stage-1 moments (QPs, qpsolvers)",
                "feasible": f"every coordinate's |residual| < {self.tolerance:g} x its peak |ID moment|",
                "volume_model": "ideal McKibben braid, resting cylinder pi d^2/4 l0, braid angle from kmax "
                                "(54.74 deg at free contraction); supply air = sum of increases of "
                                "P_gauge*V / p_atm, scaled to one stride",
            },
        }


def _outside_rom(model, q: np.ndarray) -> dict[str, int]:
    lo, hi = model.kinematics.ranges[:, 0], model.kinematics.ranges[:, 1]
    out = (q < lo - 1e-9) | (q > hi + 1e-9)
    return {c: int(out[:, j].sum()) for j, c in enumerate(model.coordinates) if out[:, j].any()}


def _air_supply_NL(pressure: np.ndarray, volume: np.ndarray) -> np.ndarray:
    """Supply air [normal litres] per column over the frames: Σ max(Δ(P·V), 0) / p_atm."""
    pv = pressure * volume
    return np.clip(np.diff(pv, axis=0), 0.0, None).sum(axis=0) / P_ATM * 1e3


def evaluate_plan(robot: PamRobot, trial: GaitTrial, p_max: float = P_MAX_DEFAULT,
                  tolerance: float = FEASIBLE_TOLERANCE, solver: str = "proxqp") -> GaitPlan:
    """Solve and evaluate the pressure plan of ``robot`` on ``trial`` (see :func:`gait_plan`)."""
    if not (np.isfinite(p_max) and p_max > 0):
        raise ParameterError(f"p_max must be a positive pressure [Pa], got {p_max!r}")
    if not (0 < tolerance < 1):
        raise ParameterError(f"tolerance must be a fraction in (0, 1), got {tolerance!r}")
    t_start = _time.perf_counter()
    model = robot.model
    cidx = [model.coordinates.index(c) for c in trial.coordinates]
    with warnings.catch_warnings():        # IK postures outside the robot's range: counted, not warned
        warnings.simplefilter("ignore", category=Warning)
        st = robot.evaluate(trial.q, pressure=0.0)
    R = st.moment_arms[:, :, cidx]
    t_kin = _time.perf_counter() - t_start
    a, b = force_coefficients(robot, st.strain, p_max)
    peak = np.abs(trial.moments).max(axis=0)
    peak = np.where(peak > 0, peak, 1e-3)
    t0 = _time.perf_counter()
    fallback: list[int] = []
    P = plan_pressures(R, a, b, trial.moments, peak, p_max=p_max, solver=solver, stage2_fallback=fallback)
    t_solve = _time.perf_counter() - t0
    F = _pam_forces(robot, st.strain, P)       # the exact model at the planned pressures
    M = np.einsum("nk,nkc->nc", F, R)
    res = M - trial.moments
    coords = []
    for j, c in enumerate(trial.coordinates):
        r = np.abs(res[:, j])
        coords.append(CoordinateResult(c, float(peak[j]), float(np.sqrt(np.mean(r**2))), float(r.max()),
                                       float(np.mean(r < tolerance * peak[j]))))
    vol = pam_volume(st.strain, robot.rest, robot.diameter, _pam_kmax(robot)) * robot.n_parallel
    times = trial.times
    window = float(times[-1] - times[0]) if len(times) > 1 else 0.0
    stride = trial.events.stride_time() if trial.events is not None else None
    scale = (stride / window) if (stride and window > 0) else 1.0
    air = _air_supply_NL(P, vol) * scale
    pams = []
    for k, name in enumerate(robot.names):
        pams.append(PamGaitResult(
            name, robot.pams[k].id, robot.pams[k].name, robot.sides[k], int(robot.diameter[k]),
            int(robot.n_parallel[k]), float(P[:, k].max() / 1e3),
            float(P[:, k].mean() / 1e3), float(np.mean(P[:, k] >= p_max * (1 - 1e-6))),
            float(np.mean(~st.in_range[:, k])), float(np.mean(F[:, k] <= 0)), float(F[:, k].max()),
            float(air[k]), (float(vol[:, k].min() * 1e3), float(vol[:, k].max() * 1e3)), int(robot.transmission[k])))
    total = _time.perf_counter() - t_start
    return GaitPlan(robot.design.name, robot.design.path, trial, float(p_max), float(tolerance), solver,
                    tuple(robot.names), P, F, M, st.strain, st.in_range, vol, tuple(coords), tuple(pams),
                    _outside_rom(model, trial.q), len(fallback),
                    {"kinematics": round(t_kin, 4), "solve": round(t_solve, 4), "total": round(total, 4)})


def _robot(design: PamRobot | str | Path | None) -> PamRobot:

    return design if isinstance(design, PamRobot) else design_robot(design)


def gait_plan(design: PamRobot | str | Path | None = None, ik: str | Path = DEFAULT_IK,
              id: str | Path = DEFAULT_ID, grf: str | Path | None = DEFAULT_GRF,  # noqa: A002
              p_max: float = P_MAX_DEFAULT, tolerance: float = FEASIBLE_TOLERANCE,
              solver: str = "proxqp", time_range: tuple[float, float] | None = None) -> GaitPlan:
    """PAM pressure plan of a design over a walking trial.

    Args:
        design: A :class:`~pamkin.robot.biped.PamRobot`, or as for ``pamkin audit``: ``None`` (the
            robot's design), ``"thesis"``, a design file or a ``pamkin optimize`` run folder.
        ik: IK angles ``.mot`` (default: the shared subject01 trial).
        id: ID moments ``.sto``.
        grf: GRF ``.mot`` for the gait phases (``None``: none; air is then per window).
        p_max: Pressure limit [Pa] (default 620 kPa).
        tolerance: Feasibility tolerance, fraction of each coordinate's peak moment.
        solver: qpsolvers backend.
        time_range: (start, end) [s] to cut the frames to.

    Returns:
        The :class:`GaitPlan` (``.to_dict()`` for JSON).

    Raises:
        pamkin.errors.StorageFileError: A malformed trial file.
        pamkin.errors.DataFileError: A malformed design file.
        pamkin.errors.ParameterError: An out-of-range argument.
        pamkin.errors.SolverError: The QP solver failed.
    """
    robot = _robot(design)
    trial = load_trial(robot.model, ik, id, grf, time_range=time_range)
    return evaluate_plan(robot, trial, p_max=p_max, tolerance=tolerance, solver=solver)


def feasible_frame_fraction(design: PamRobot | str | Path | None = None, ik: str | Path = DEFAULT_IK,
                            id: str | Path = DEFAULT_ID, p_max: float = P_MAX_DEFAULT,  # noqa: A002
                            tolerance: float = FEASIBLE_TOLERANCE) -> float:
    """Fraction of the trial's frames where the design reproduces every ID moment within
    ``tolerance`` (5 %) of that coordinate's peak, at pressures from 0 to ``p_max`` (Pa).

    ``design`` as for :func:`gait_plan` (a robot, ``None``, ``"thesis"``, a file or a run
    folder). About 1 s on the default 67-frame trial (after the path kernels are compiled).
    """
    return gait_plan(design, ik, id, grf=None, p_max=p_max, tolerance=tolerance).feasible_frame_fraction


# --------------------------------------------------------------------------- output


_GROUPS = (("trunk", (1, 2, 3)), ("hip", (24, 25, 26, 27)), ("knee", (4, 5, 6, 7, 8, 9, 10, 11)),
           ("ankle", (12, 13, 14, 15, 16)), ("foot", (17, 18, 19, 20, 21, 22, 23)))


def _groups(plan: GaitPlan) -> list[tuple[str, list[int]]]:
    ids = sorted({r.id for r in plan.pam_results})
    out, seen = [], set()
    for name, members in _GROUPS:
        sel = [i for i in members if i in ids]
        if sel:
            out.append((name, sel))
            seen.update(sel)
    rest = [i for i in ids if i not in seen]
    if rest:
        out.append(("other", rest))
    return out


def plot_pressures(plan: GaitPlan, path: str | Path, title: str | None = None) -> Path:
    """PNG of every PAM's pressure over the trial (rows: trunk, hip, knee, ankle, foot PAMs;
    columns: right and left side), stance phases shaded, heel strikes (solid) and toe-offs
    (dashed) marked; a bottom panel shows the worst residual per frame (% of peak)."""
    import io  # noqa: PLC0415

    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415


    t = plan.trial.times
    groups = _groups(plan)
    fig, axes = plt.subplots(len(groups) + 1, 2, figsize=(12.5, 2.1 * (len(groups) + 1) + 0.8), sharex=True,
                             gridspec_kw={"height_ratios": [1.0] * len(groups) + [0.8]})
    ev = plan.trial.events
    by = {(r.id, r.side): k for k, r in enumerate(plan.pam_results)}
    labels = {r.id: r.label for r in plan.pam_results}
    cmap = plt.get_cmap("tab10")

    def phases(ax, side: str, label: bool) -> None:
        if ev is None:
            return
        ts, on = ev.stance[side]
        sel = (ts >= t[0]) & (ts <= t[-1])
        ax.fill_between(ts[sel], 0, 1, where=on[sel], transform=ax.get_xaxis_transform(), color="0.9", lw=0,
                        label="stance" if label else None)
        for s, c in (("r", "tab:red"), ("l", "tab:blue")):
            for h in ev.heel_strikes[s]:
                if t[0] <= h <= t[-1]:
                    ax.axvline(h, color=c, lw=0.8)
            for h in ev.toe_offs[s]:
                if t[0] <= h <= t[-1]:
                    ax.axvline(h, color=c, lw=0.8, ls="--")

    for row, (gname, ids) in enumerate(groups):
        for col, side in enumerate(("r", "l")):
            ax = axes[row, col]
            phases(ax, side, row == 0 and col == 0)
            for j, i in enumerate(ids):
                k = by.get((i, side))
                if k is None:
                    continue
                ax.plot(t, plan.pressures[:, k] / 1e3, color=cmap(j % 10), lw=1.3,
                        label=f"{i} {labels[i]}" if col == 1 else None)
            ax.set_ylim(-20, plan.p_max_Pa / 1e3 * 1.05)
            ax.axhline(plan.p_max_Pa / 1e3, color="k", lw=0.5, ls=":")
            ax.set_title(f"{gname} PAMs, {'right' if side == 'r' else 'left'} side", fontsize=9, loc="left")
            if col == 0:
                ax.set_ylabel("kPa")
            ax.tick_params(labelsize=8)
        axes[row, 1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    ax = axes[-1, 0]
    rel = 100 * np.abs(plan.residuals) / plan.peaks
    worst = rel.max(axis=1)
    phases(ax, "r", False)
    ax.plot(t, np.maximum(worst, 1e-3), color="k", lw=1.2)
    ax.axhline(100 * plan.tolerance, color="tab:green", lw=1, ls="--")
    ax.set_yscale("log")
    ax.set_ylim(5e-4, max(200.0, 2 * float(worst.max())))
    ax.set_ylabel("% of peak")
    ax.set_title(f"worst residual of the {len(plan.trial.coordinates)} coordinates, % of peak (feasible "
                 f"{100 * plan.feasible_frame_fraction:.0f} % of frames, limit {100 * plan.tolerance:g} %)",
                 fontsize=9, loc="left")
    ax.set_xlabel("time [s]")
    ax.tick_params(labelsize=8)
    ax = axes[-1, 1]
    phases(ax, "l", False)
    ax.plot(t, plan.pressures.sum(axis=1) / 1e3 / len(plan.pam_names), color="k", lw=1.2)
    ax.set_title("mean pressure of all PAMs", fontsize=9, loc="left")
    ax.set_ylabel("kPa")
    ax.set_xlabel("time [s]")
    ax.tick_params(labelsize=8)
    from matplotlib.lines import Line2D  # noqa: PLC0415
    from matplotlib.patches import Patch  # noqa: PLC0415

    handles = [Patch(color="0.9", label="stance of this side's foot"),
               Line2D([], [], color="tab:red", lw=0.8, label="right heel strike (solid) / toe-off (dashed)"),
               Line2D([], [], color="tab:blue", lw=0.8, label="left heel strike / toe-off"),
               Line2D([], [], color="k", lw=0.5, ls=":", label="P_max")]
    fig.legend(handles=handles, loc="upper center", ncol=4, fontsize=8, frameon=False, bbox_to_anchor=(0.45, 0.985))
    fig.suptitle(title or f"PAM pressures of design {plan.design!r} over the walking trial", fontsize=11, y=0.998)
    fig.tight_layout(rect=(0, 0, 1, 0.965))
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80)
    plt.close(fig)
    from PIL import Image  # noqa: PLC0415  (matplotlib's own dependency)

    buf.seek(0)
    small = io.BytesIO()
    Image.open(buf).convert("RGB").quantize(colors=64).save(small, format="png", optimize=True)  # ~4x smaller
    write_file(Path(path), small.getvalue())
    return Path(path)


def write_outputs(plan: GaitPlan, out: str | Path) -> list[Path]:
    """Write ``gait.json`` (:meth:`GaitPlan.to_dict`), ``pressures.csv`` (time, then every PAM's
    pressure [kPa]), ``moments.csv`` (time, then ID and robot moment [N·m] per coordinate) and
    ``pressures.png`` (:func:`plot_pressures`) into folder ``out``, each atomically."""


    out = Path(out)
    t = plan.trial.times
    files = []
    p = out / "gait.json"
    write_file(p, strict_json(plan.to_dict()) + "\n")
    files.append(p)
    head = "time_s," + ",".join(f"{n}_kPa" for n in plan.pam_names)
    rows = [f"{ti:.6f}," + ",".join(f"{v:.3f}" for v in row) for ti, row in zip(t, plan.pressures / 1e3)]
    p = out / "pressures.csv"
    write_file(p, "\n".join([head, *rows]) + "\n")
    files.append(p)
    head = "time_s," + ",".join(f"{c}_id_Nm,{c}_robot_Nm" for c in plan.trial.coordinates)
    both = np.stack([plan.trial.moments, plan.robot_moments], axis=2).reshape(len(t), -1)
    rows = [f"{ti:.6f}," + ",".join(f"{v:.4f}" for v in row) for ti, row in zip(t, both)]
    p = out / "moments.csv"
    write_file(p, "\n".join([head, *rows]) + "\n")
    files.append(p)
    files.append(plot_pressures(plan, out / "pressures.png"))
    return files
