"""``pamkin audit``: what a design is really worth, measured on samples no optimiser trains on.

For one design (right side; the left mirrored) the audit measures:

1. **Held-out motion** — (a) the 1-D sweeps and 2-D grids of :mod:`pamkin.audit.compare`;
   (b) seeded random poses of every right-leg and lumbar coordinate within the design's range
   of motion (hip adduction within its flexion-dependent limits), drawn from a random stream
   of their own (:data:`AUDIT_STREAM`; the optimiser's samples are grids or other streams);
   (c) every frame of a walking trial (OpenSim IK ``.mot``; default the shared subject01 trial).
2. **Whole torque vector** — each PAM's torque about every coordinate its route or its human
   muscles cross, against the summed torque of the human muscles it replaces (Gait2392, full
   activation, static equilibrium), RMS error ÷ the human peak about the primary coordinate;
   the worst coordinate is named. Dead-zone fraction (strain outside −pretension … kmax) per set.
   The force scale that would fit the primary torque best and the error there
   (:func:`best_force_scale`): whether a miss is the PAM's force level or its torque's shape.
3. **Real bone geometry** — the model's bone meshes (:class:`pamkin.human.bones.BoneSet`): per fixed
   attachment point the signed distance to its own body's bone (the bracket it needs; negative
   inside) and the deepest it gets into any bone at any pose; per route segment the deepest
   penetration of its centre line into any bone over the samples; PAM–PAM clearance between the
   PAM bodies (capsules of the assumed outer diameter) of different actuators, same side over
   all poses, left–right over the walking trial.
4. **Buildability** — tendon ≥ 0; the PAM (max(resting, actual length) + both fittings) fits on
   one straight segment of its route at every sample, else the segment it would bend over.
5. **Force realism** — peak force per PAM unit vs Festo's rated force, resting length vs Festo's
   nominal range and vs the range the force model was measured on, contraction vs 25 %, whether
   kmax is assumed, and the sensitivity: the largest change of the primary torque for a 1 mm
   error of one attachment point (linearised, worst direction) over the primary sweep, in % of
   the human peak.
6. **Bulk** — PAM count (parallel units, both sides), total PAM length, air volume, mass (Festo
   weights are an *assumption*, see :func:`pamkin.robot.festo.pam_mass`).

Limits (``robot/data/audit_limits.yaml``; ``--limits`` overrides) turn the summary into a
pass/fail scorecard.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from pamkin._resources import SHARED_DIR, data_file
from pamkin.audit.assembly import bone_clearance, body_radius, body_radius_source, pair_gap
from pamkin.audit.capacity import joint_capacity
from pamkin.audit.compare import compare_pam, failing_as_worst, finite_or_none
from pamkin.errors import ConfigurationError, DataFileError, RangeWarning
from pamkin.gait.plan import gait_plan
from pamkin.human.bones import BoneSet, body_pair_distance
from pamkin.human.model import Model, gait2392
from pamkin.human.paths import PathSet
from pamkin.human.rom import RangeOfMotion, load_rom
from pamkin.opensim.model_file import ConditionalPathPoint, MovingPathPoint, PathPoint
from pamkin.opensim.storage import read_storage
from pamkin.robot import festo
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.robot.design import (
    Design,
    load_design,
    pam_length,
    pam_unit_mass,
    pams_mass,
)
from pamkin.robot.pam_body import (
    pam_capsules,
    placement,
    route_positions,
    segment_names,
)
from pamkin.robot.rollers import open_ended, roller_axis_points
from pamkin.robot.rack import ANCHOR, GUIDE
from pamkin.yamlio import strict_load

#: Random stream of the audit's poses (``SeedSequence(seed, spawn_key=(AUDIT_STREAM,))``); an
#: optimiser drawing random poses must use another stream (see :func:`random_poses`).
AUDIT_STREAM = 0xA0D1
#: Default limits file.
LIMITS_FILE = data_file("audit_limits.yaml")
#: Default walking trial (IK angles).
GAIT_IK = SHARED_DIR / "gait" / "subject01_walk1_ik.mot"
#: A PAM pair counts as intersecting when its capsules overlap by more than this [m].
CLEARANCE_TOLERANCE = 1e-4
#: Names of the route points that are a rack's brackets (checked against ``rack_bracket_max_m``).
RACK_POINTS = (ANCHOR, GUIDE)
#: Linearisation step of the sensitivity [m] (the result is scaled to a 1 mm error).
SENSITIVITY_STEP = 1e-4


# ----------------------------------------------------------------------------- options and limits
@dataclass(frozen=True)
class AuditOptions:
    """What the audit samples.

    Attributes:
        n_random: Random poses (≥ 2000 for the full audit).
        seed: Seed of the random poses (stream :data:`AUDIT_STREAM`).
        gait_ik: IK ``.mot`` file of a walking trial (``None``: no gait set).
        gait_stride: Use every k-th gait frame.
        segment_step_m: Spacing of the points tested along each route segment [m].
        n_sweep, n_grid: Points of the 1-D sweep and per axis of the 2-D grids.
        n_geometry: How many of the random poses (the first ones) the bone and PAM–PAM checks use
            (every gait frame is used); the torque figures use all of them.
        geometry_dir: Folder of the bone meshes (default: found beside the model).
        gait_plan: Also run the gait pressure plan (``pamkin gait``) for its feasible-frame fraction.
    """

    n_random: int = 2000
    seed: int = 0
    gait_ik: str | None = str(GAIT_IK)
    gait_stride: int = 1
    segment_step_m: float = 0.002
    n_sweep: int = 41
    n_grid: int = 15
    geometry_dir: str | None = None
    gait_plan: bool = True
    n_geometry: int = 1000

    @classmethod
    def quick(cls, **kw) -> AuditOptions:
        """Fewer samples (500 random poses of which 150 for geometry, every 3rd gait frame, 4 mm segment steps)."""
        base = dict(n_random=500, gait_stride=3, segment_step_m=0.004, n_sweep=21, n_grid=9, n_geometry=150)
        base.update(kw)
        return cls(**base)


def load_limits(path: str | os.PathLike | None = None) -> dict:
    """Thresholds and limits: the defaults, updated by the file ``path`` (any subset).

    Raises:
        DataFileError: Unreadable YAML, unknown keys, non-numeric values (naming file and key).
    """
    def read(p: Path) -> dict:
        try:
            data = strict_load(p.read_bytes(), str(p))     # UTF-8, no duplicate keys, no aliases
        except FileNotFoundError:
            raise DataFileError(str(p), "file not found") from None
        except OSError as e:
            raise DataFileError(str(p), f"cannot read: {e}") from None
        if not isinstance(data, dict):
            raise DataFileError(str(p), "a limits file is a mapping with 'thresholds' and/or 'limits'")
        return data

    out = read(LIMITS_FILE)
    out = {"thresholds": dict(out.get("thresholds", {})), "limits": dict(out.get("limits", {}))}
    if path is None:
        return out
    p = Path(path)
    user = read(p)
    unknown = set(user) - {"thresholds", "limits"}
    if unknown:
        raise DataFileError(str(p), f"unknown top-level key(s) {sorted(unknown)}; allowed: thresholds, limits")
    for key, v in (user.get("thresholds") or {}).items():
        if key not in out["thresholds"]:
            raise DataFileError(str(p), f"thresholds.{key}: unknown threshold; known: {sorted(out['thresholds'])}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise DataFileError(str(p), f"thresholds.{key}: must be a number >= 0, is {v!r}")
        out["thresholds"][key] = float(v)
    for key, v in (user.get("limits") or {}).items():
        if key not in out["limits"]:
            raise DataFileError(str(p), f"limits.{key}: unknown summary figure; known: {sorted(out['limits'])}")
        if v is None:
            out["limits"][key] = None          # switched off
            continue
        if not isinstance(v, dict) or set(v) - {"min", "max"} or not v:
            raise DataFileError(str(p), f"limits.{key}: give {{max: x}} and/or {{min: x}} (or null to switch off)")
        for kk, x in v.items():
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                raise DataFileError(str(p), f"limits.{key}.{kk}: must be a number, is {x!r}")
        out["limits"][key] = dict(v)
    return out


# ----------------------------------------------------------------------------- samples
def audit_coordinates(rom: RangeOfMotion) -> list[str]:
    """Coordinates the random poses vary: every right-leg and lumbar coordinate of ``rom``."""
    return [c for c in rom.coordinates if c.endswith("_r") or c.startswith("lumbar")]


def random_poses(model: Model, rom: RangeOfMotion, n: int, seed: int = 0, stream: int = AUDIT_STREAM) -> np.ndarray:
    """``n`` random poses (n, n_coordinates): every right-leg and lumbar coordinate uniform within
    ``rom`` (a coupled coordinate uniform within its limits at the drawn value of the coordinate it
    depends on); every other coordinate at its default.

    Args:
        model: Gives the coordinate order and defaults.
        rom: Range of motion (right side).
        n: Number of poses.
        seed: Seed.
        stream: Random stream (``SeedSequence(seed, spawn_key=(stream,))``); the audit's is
            :data:`AUDIT_STREAM`: optimisers must draw from another one.
    """
    if n < 1:
        raise ConfigurationError(f"the number of random poses must be >= 1, is {n}")
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(stream),)))
    coords = audit_coordinates(rom)
    q = np.tile(model.default_q, (n, 1))
    for c, v in rom.from_unit(coords, rng.random((n, len(coords)))).items():
        q[:, model.coordinates.index(c)] = v
    return q


def gait_poses(model: Model, ik_path: str | os.PathLike, stride: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Every (``stride``-th) frame of an IK ``.mot`` file as configurations (SI units).

    Returns:
        ``(q, time)``: (M, n_coordinates) [rad, m] and (M,) [s].

    Raises:
        pamkin.errors.StorageFileError: Malformed file or missing coordinate columns.
    """

    st = read_storage(ik_path)
    rot = [c.rotational for c in model.osim.coordinates]
    q = st.coordinates_si(model.coordinates, rot)
    return q[::stride], st.time[::stride]


# ----------------------------------------------------------------------------- result
@dataclass
class AuditResult:
    """The audit of one design.

    Attributes:
        design: Design name.
        source: Design file.
        pams: One dict per PAM (right side) with every per-PAM figure.
        summary: Summary figures (keys of the limits).
        criteria: One dict per limit: ``name``, ``value``, ``limit``, ``passed``.
        samples: What was sampled (counts, seed, files).
        seconds: Run time [s].
        details: Arrays for figures and views (not in :meth:`to_dict`).
        assembly: The PAM bodies as measured (radii per Festo size [m] and their source, the gaps) and every
            pair of bodies closer than the gap (:mod:`pamkin.audit.assembly`).
        capacity: The joint-capacity table (:func:`pamkin.audit.capacity.joint_capacity`).
    """

    design: str
    source: str
    pams: list[dict]
    summary: dict
    criteria: list[dict]
    samples: dict
    thresholds: dict
    seconds: float = 0.0
    details: dict = field(default_factory=dict, repr=False)
    assembly: dict = field(default_factory=dict)
    capacity: list = field(default_factory=list)

    @property
    def passed(self) -> bool:
        """Every limit met."""
        return all(c["passed"] is not False for c in self.criteria)

    @property
    def failed(self) -> list[str]:
        """Names of the failed limits."""
        return [c["name"] for c in self.criteria if c["passed"] is False]

    def to_dict(self) -> dict:
        """The result as plain data for strict JSON (``audit.json``): a number that is not finite (an
        undefined error) becomes ``None``."""
        return finite_or_none({"design": self.design, "source": self.source, "passed": self.passed,
                               "failed": self.failed, "summary": self.summary, "criteria": self.criteria,
                               "pams": self.pams, "samples": self.samples, "thresholds": self.thresholds,
                               "assembly": self.assembly, "capacity": self.capacity,
                               "seconds": round(self.seconds, 2)})


# ----------------------------------------------------------------------------- geometry helpers
# ----------------------------------------------------------------------------- the audit
def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float("nan")


def best_force_scale(th: np.ndarray, tr: np.ndarray) -> tuple[float, float]:
    """The factor s the robot torques ``tr`` (S,) [N·m] would need to fit the human's ``th`` (S,) best (least
    squares: s = Σ tr·th / Σ tr²) and the RMS error [N·m] there: how far a PAM's miss is its force level (a
    larger or smaller PAM, more PAMs, another pressure) rather than the shape of its torque over the poses.
    A PAM with no torque: (nan, RMS of ``th``)."""
    tt = float(np.dot(tr, tr))
    if not tt > 0:
        return float("nan"), _rms(th)
    s = float(np.dot(tr, th)) / tt
    return s, _rms(s * tr - th)


def torque_metrics(th: np.ndarray, tr: np.ndarray, prim: int, coords: list[int], names: list[str]) -> dict:
    """The audit's torque numbers of one PAM: human ``th`` and robot ``tr`` torques (S, n_coordinates) [N·m];
    ``nrmse`` = RMS error about the primary coordinate ``prim`` ÷ the human peak about it, and per
    coordinate of ``coords`` (indices into ``names``) the same ratio (``coordinate_errors``), the worst of them
    (``worst_coordinate``, ``worst_coordinate_error``), the peaks, and the force scale that would fit the primary
    coordinate best with the NRMSE there (``best_force_scale``, ``nrmse_at_best_scale``, :func:`best_force_scale`)
    and the worst coordinate error at that scale (``worst_at_best_scale``, about ``worst_coordinate_at_best_scale``:
    the same force scales every coordinate's torque). Where the human has no torque about
    ``prim`` on these samples the ratios are undefined (nan; the audit's summary counts them as failing)."""
    peak = float(np.max(np.abs(th[:, prim]))) if len(th) else 0.0

    def errors(s: float) -> tuple[dict, str]:     # per coordinate at force scale s, and the worst of them
        e = {names[c]: _rms(s * tr[:, c] - th[:, c]) / peak if peak > 0 and np.isfinite(s) else float("nan")
             for c in coords}
        return e, (max(e, key=lambda c: (e[c] if np.isfinite(e[c]) else -1)) if e else "")

    err, worst = errors(1.0)
    scale, scaled = best_force_scale(th[:, prim], tr[:, prim])
    at, worst_at = errors(scale)
    return {"nrmse": err.get(names[prim], float("nan")), "human_peak_Nm": peak,
            "best_force_scale": scale, "nrmse_at_best_scale": scaled / peak if peak > 0 else float("nan"),
            "worst_at_best_scale": at.get(worst_at, float("nan")), "worst_coordinate_at_best_scale": worst_at,
            "robot_peak_Nm": float(np.max(np.abs(tr[:, prim]))) if len(tr) else 0.0,
            "coordinate_errors": err, "worst_coordinate": worst, "worst_coordinate_error": err.get(worst, float("nan")),
            "worst_robot_Nm": float(np.max(np.abs(tr[:, names.index(worst)]))) if worst else 0.0,
            "worst_human_Nm": float(np.max(np.abs(th[:, names.index(worst)]))) if worst else 0.0}


def audit_design(design: str | os.PathLike | Design | None = None, *, options: AuditOptions | None = None,
                 limits: dict | str | os.PathLike | None = None, human: Model | None = None,
                 progress: Callable[[str], None] | None = None) -> AuditResult:
    """Audit a design (see the module docstring).

    Args:
        design: A design, a design file, a ``pamkin optimize`` run folder, ``"thesis"``, or ``None``
            (the robot's current design).
        options: Sampling options (default :class:`AuditOptions`; ``AuditOptions.quick()``).
        limits: Limits dict (:func:`load_limits`) or a limits file (default: the built-in limits).
        human: The human model (default: built-in Gait2392).
        progress: Called with a short message at each phase.

    Returns:
        The :class:`AuditResult`.
    """
    t0 = time.perf_counter()
    opt = options or AuditOptions()
    lim = limits if isinstance(limits, dict) else load_limits(limits)
    thr = lim["thresholds"]
    say = progress or (lambda msg: None)
    skel = robot_skeleton()
    if isinstance(design, Design):
        des = design
    else:
        des = load_design(design, bodies=skel.bodies, coordinates=skel.coordinates)
    if human is None:

        human = gait2392()
    robot = PamRobot(des, skel)
    n = len(des.pams)
    names = skel.coordinates
    rom = load_rom(des.rom, "r")
    pelvis = {i for i, c in enumerate(names) if c.startswith("pelvis_")}

    # ---- samples
    say(f"samples: {opt.n_random} random poses (seed {opt.seed}), walking trial")
    q_rand = random_poses(skel, rom, opt.n_random, opt.seed)
    if opt.gait_ik:
        q_gait, t_gait = gait_poses(skel, opt.gait_ik, opt.gait_stride)
    else:
        q_gait, t_gait = np.zeros((0, len(names))), np.zeros(0)
    sets = {"random": q_rand, "gait": q_gait}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        say("robot and human torques")
        pam_state = {k: robot.evaluate(q) for k, q in sets.items() if len(q)}
        human_T = {k: human.torques(q) for k, q in sets.items() if len(q)}
        kin_state = {k: skel.kinematics.forward(q, warn_range=False) for k, q in sets.items() if len(q)}

    rows: list[dict] = []
    for k, pam in enumerate(des.pams):
        idx = [human.muscles.index(m) for m in pam.human_muscles]
        prim = names.index(pam.primary_coordinate)
        row: dict = {"id": pam.id, "name": pam.name, "key": pam.key, "human_muscles": list(pam.human_muscles),
                     "primary_coordinate": pam.primary_coordinate, "diameter_mm": pam.diameter_mm,
                     "n_parallel": pam.n_parallel, "resting_length_m": pam.resting_length_m,
                     "tendon_length_m": pam.tendon_length_m}
        crossed: set[int] = set()
        for key, st in pam_state.items():
            R = st.moment_arms[:, k]
            crossed |= set(np.flatnonzero(np.max(np.abs(R), axis=0) > 1e-9).tolist())
            Th = human_T[key][:, idx].sum(axis=1)
            crossed |= set(np.flatnonzero(np.max(np.abs(Th), axis=0) > 1e-9).tolist())
        crossed -= pelvis
        crossed.add(prim)
        coords = sorted(crossed)
        row["coordinates_crossed"] = [names[c] for c in coords]
        for key, st in pam_state.items():
            Th = human_T[key][:, idx].sum(axis=1)
            m = torque_metrics(Th, st.torques[:, k], prim, coords, names)
            row[f"{key}_nrmse"] = m["nrmse"]
            row[f"{key}_worst_coordinate"] = m["worst_coordinate"]
            row[f"{key}_worst_coordinate_error"] = m["worst_coordinate_error"]
            row[f"{key}_coordinate_errors"] = m["coordinate_errors"]
            row[f"{key}_human_peak_Nm"] = m["human_peak_Nm"]
            row[f"{key}_robot_peak_Nm"] = m["robot_peak_Nm"]
            row[f"{key}_worst_robot_peak_Nm"] = m["worst_robot_Nm"]
            row[f"{key}_worst_human_peak_Nm"] = m["worst_human_Nm"]
            row[f"{key}_best_force_scale"] = m["best_force_scale"]
            row[f"{key}_nrmse_at_best_scale"] = m["nrmse_at_best_scale"]
            row[f"{key}_worst_at_best_scale"] = m["worst_at_best_scale"]
            row[f"{key}_worst_coordinate_at_best_scale"] = m["worst_coordinate_at_best_scale"]
            row[f"{key}_dead_zone_fraction"] = float(np.mean(~st.in_range[:, k]))
        if "gait" in pam_state:   # the left PAM on the left leg's gait
            row["gait_dead_zone_fraction_left"] = float(np.mean(~pam_state["gait"].in_range[:, k + n]))
        if pam.rollers and "random" in pam_state:     # a cable off a roller's end: shorter than over open rollers
            opened = Design(des.name, (replace(pam, rollers=open_ended(pam.rollers)),), des.pressure_Pa,
                            des.force_model, des.fitting_length_m, des.rom)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RangeWarning)
                L_open = PamRobot(opened, skel, sides=("r",)).evaluate(sets["random"]).lengths[:, 0]
            row["roller_cable_off_fraction"] = float(np.mean(np.abs(pam_state["random"].lengths[:, k] - L_open) > 1e-9))
        rows.append(row)

    # ---- (a) sweeps and grids
    say("1-D sweeps and 2-D grids")
    right = PamRobot(des, skel, sides=("r",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        for k, row in enumerate(rows):
            c = compare_pam(right, human, k, rom, opt.n_sweep, opt.n_grid)
            row["sweep_nrmse"] = c.primary.nrmse
            row["sweep_dead_zone_fraction"] = c.primary.dead_zone_fraction
            row["grid_nrmse"] = {s.coordinate: s.nrmse for s in c.secondary}

    # ---- buildability, force realism over every sampled pose
    say("buildability and forces")
    q_all = np.vstack([q for q in sets.values() if len(q)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st_all = right.evaluate(q_all)
        ks_all = skel.kinematics.forward(q_all, warn_range=False)
    mounts = []
    for k, (pam, row) in enumerate(zip(des.pams, rows)):
        pts = route_positions(right.paths, ks_all, k)
        place = placement(pts, pam, st_all.pam_lengths[:, k], des.fitting_length_m,
                          right.segment_lengths(ks_all, k) if pam.rollers else None)
        j, margin = place.segment, place.margin
        seg_names = segment_names(pam)
        mounts.append(place)
        row["tendon_ok"] = bool(pam.tendon_length_m >= 0)
        row["on_one_segment"] = bool(margin >= 0)
        row["mount_segment"] = seg_names[j]
        row["mount_margin_m"] = margin
        row["pam_at"] = place.side if margin >= 0 else None
        # the design's pam_at where the route does not allow it (or the PAM is not on one segment)
        row["pam_at_not_possible"] = pam.pam_at if pam.pam_at not in (None, row["pam_at"]) else None
        # the design's pam_on where the PAM body does not fit there with a constant tendon
        row["pam_on_not_possible"] = pam.pam_on if pam.pam_on is not None and (
            pam.pam_on != row["mount_segment"] or margin < 0) else None
        row["bends_over"] = None if margin >= 0 else (
            pam.points[j + 1].name if j + 1 < len(pam.points) - 1 else pam.points[j].name)
        F = st_all.unit_forces[:, k]
        row["peak_force_per_unit_N"] = float(np.max(F))
        rated = festo.F_MAX_THEORETICAL[pam.diameter_mm]
        row["rated_force_N"] = rated
        row["force_ratio"] = float(np.max(F) / rated)
        lo, hi = festo.nominal_length_range(pam.diameter_mm)
        row["nominal_length_ok"] = bool(lo <= pam.resting_length_m <= hi)
        mr = festo.measured_rest_length_range(pam.diameter_mm, des.force_model)
        row["force_model_measured_range_m"] = list(mr) if mr else None
        row["force_model_extrapolated"] = bool(mr is None or not (mr[0] <= pam.resting_length_m <= mr[1]))
        row["kmax_assumed"] = not festo.kmax_is_measured(pam.diameter_mm, des.force_model)
        row["max_contraction"] = float(np.max(st_all.strain[:, k]))
        row["max_contraction_ok"] = bool(row["max_contraction"] <= festo.max_contraction(pam.diameter_mm) + 1e-12)
        row["min_strain"] = float(np.min(st_all.strain[:, k]))

    # ---- sensitivity to a 1 mm attachment error
    say("sensitivity to attachment errors")
    _sensitivity(right, human, rom, rows, opt.n_sweep)

    # ---- bone geometry
    say("bone meshes: attachment points and route segments")

    bones = BoneSet(skel, opt.geometry_dir)
    # random poses vary the right leg only (the left stays at its default): there the left leg's
    # bones are not tested; over the walking trial every bone is
    right_side = [b for b in bones.bodies if not b.endswith("_l")]
    geo = {"random": skel.kinematics.forward(q_rand[:opt.n_geometry], warn_range=False)}
    if "gait" in kin_state:
        geo["gait"] = kin_state["gait"]
    bone_sets = [(geo[k], right_side if k == "random" else None) for k in geo]
    _bone_checks(right, bones, bone_sets, rows, opt.segment_step_m, thr)

    # ---- PAM-PAM clearance
    say("PAM-PAM clearance")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        geo_pam = {k: robot.evaluate(q_rand[:opt.n_geometry]) if k == "random" else pam_state[k] for k in geo}
    pairs, pairs_lr, capsule_cache = _clearance(robot, des, geo, geo_pam, mounts)
    for row in rows:
        row["pam_clearance_min_m"] = None
        row["intersects"] = []
    for (a, b), (dist, s) in pairs.items():
        for x, y in ((a, b), (b, a)):
            r = rows[x]
            if dist < CLEARANCE_TOLERANCE * -1:
                r["intersects"].append(des.pams[y].id)
            if np.isfinite(dist) and (r["pam_clearance_min_m"] is None or dist < r["pam_clearance_min_m"]):
                r["pam_clearance_min_m"] = dist
    lr_hits = sorted({(des.pams[a].id, des.pams[b].id) for (a, b), (dist, _) in pairs_lr.items()
                      if dist < -CLEARANCE_TOLERANCE})

    # ---- assembly: body gaps, body-bone clearance (bodies of their largest outer radius, as placed)
    say("PAM bodies: gaps between them and clearance from bone")
    gap_pairs, gap_pairs_lr = _body_gaps(des, capsule_cache, thr["body_gap_m"])
    close_same = [p for p in gap_pairs if p["distance_m"] < thr["body_gap_m"] - CLEARANCE_TOLERANCE]
    close_lr = [p for p in gap_pairs_lr if p["distance_m"] < thr["body_gap_m"] - CLEARANCE_TOLERANCE]
    _body_bone_checks(des, bones, geo, capsule_cache, rows, right_side, opt.segment_step_m, thr)

    # ---- joint capacity: every PAM at the design's pressure vs every muscle at activation 1
    capacity = joint_capacity(pam_state["random"].torques, _human_columns(human, human_T["random"], names),
                              audit_coordinates(rom), names, thr["capacity_pose_fraction"])

    # ---- bulk
    units = np.array([p.n_parallel for p in des.pams])
    rest = np.array([p.resting_length_m for p in des.pams])
    dia = np.array([p.diameter_mm for p in des.pams])
    mass = pams_mass(des.pams)
    volume = float(np.sum(units * np.pi * (dia / 2000.0) ** 2 * rest)) * 2
    for row, p in zip(rows, des.pams):
        row["mass_kg"] = pam_unit_mass(p) * p.n_parallel
        row["transmission"] = int(p.transmission)
        row["cable_efficiency"] = float(p.cable_efficiency)

    # ---- gait capability
    gait_frac, gait_limiting = None, None
    if opt.gait_plan and opt.gait_ik:
        say("gait pressure plan")
        gait_frac, gait_limiting = _gait_fraction(des, thr, opt.gait_ik)

    # ---- summary
    def count(pred) -> int:
        return int(sum(1 for r in rows if pred(r)))

    # an error that is not defined (no human torque about the PAM's primary coordinate on these poses) counts
    # as the worst, never as a PAM left out of the median and the maximum
    nr = failing_as_worst([r["random_nrmse"] for r in rows])
    we = failing_as_worst([r["random_worst_coordinate_error"] for r in rows])
    summary = {
        "pam_count": int(2 * units.sum()),
        "random_nrmse_median": float(np.median(nr)),
        "random_nrmse_le_0_15": int(np.sum(nr <= thr["nrmse_good"])),
        "worst_coordinate_error_le_0_25": int(np.sum(we <= thr["worst_coordinate_error_good"])),
        "worst_coordinate_error_max": float(np.max(we)),
        "gait_nrmse_median": float(np.median(failing_as_worst([r.get("gait_nrmse", np.nan) for r in rows])))
        if len(q_gait) else None,
        "sweep_nrmse_median": float(np.median(failing_as_worst([r["sweep_nrmse"] for r in rows]))),
        "dead_zone_pams": count(lambda r: r["random_dead_zone_fraction"] > 0 or r.get("gait_dead_zone_fraction", 0) > 0
                                or r.get("gait_dead_zone_fraction_left", 0) > 0),
        "dead_zone_pams_gait": count(lambda r: r.get("gait_dead_zone_fraction", 0) > 0
                                     or r.get("gait_dead_zone_fraction_left", 0) > 0),
        "points_inside_bone": sum(r["points_inside_own_bone"] for r in rows),
        "points_inside_any_bone": sum(r["points_inside_any_bone"] for r in rows),
        "points_over_20mm": sum(r["points_over_bracket"] for r in rows),
        "max_bracket_m": max((r["max_bracket_m"] for r in rows if r["max_bracket_m"] is not None), default=0.0),
        "segments": sum(len(r["segments"]) for r in rows),
        "segments_over_2mm": sum(r["segments_over_limit"] for r in rows),
        "pam_pairs_intersecting": int(sum(1 for (a, b), (d, _) in pairs.items() if d < -CLEARANCE_TOLERANCE)),
        "pam_pairs_intersecting_left_right_gait": len(lr_hits),
        "pam_body_pairs_closer_than_gap": len(close_same),
        "pam_body_pairs_overlapping": sum(1 for p in gap_pairs if p["distance_m"] < -CLEARANCE_TOLERANCE),
        "pam_body_pairs_closer_than_gap_left_right_gait": len(close_lr),
        "pam_bodies_near_bone": count(lambda r: r["body_bone_clearance_m"] < thr["bone_gap_m"]),
        "pam_bodies_into_bone": count(lambda r: r["body_bone_clearance_m"] < 0),
        "body_bone_clearance_median_m": float(np.median([r["body_bone_clearance_m"] for r in rows])),
        "body_bone_clearance_min_m": float(min(r["body_bone_clearance_m"] for r in rows)),
        "capacity_directions_met": sum(1 for c in capacity if c["met"]),
        "capacity_directions": len(capacity),
        "pams_on_one_segment": count(lambda r: r["on_one_segment"]),
        "pams_not_on_one_segment": count(lambda r: not r["on_one_segment"]),
        "pams_negative_tendon": count(lambda r: not r["tendon_ok"]),
        "pams_over_rated_force": count(lambda r: r["force_ratio"] > 1.0),
        "max_force_ratio": float(max(r["force_ratio"] for r in rows)),
        "pams_over_max_contraction": count(lambda r: not r["max_contraction_ok"]),
        "pams_outside_nominal_length": count(lambda r: not r["nominal_length_ok"]),
        "pams_force_model_extrapolated": count(lambda r: r["force_model_extrapolated"]),
        "pams_kmax_assumed": count(lambda r: r["kmax_assumed"]),
        "pams_sensitivity_over_10pct": count(lambda r: r["sensitivity_pct"] > thr["sensitivity_max_pct"]),
        "total_pam_length_m": float(np.sum(units * rest) * 2),
        "air_volume_l": volume * 1000.0,
        "mass_kg": float(mass),
        "gait_feasible_frame_fraction": gait_frac,
        "gait_limiting_coordinates": gait_limiting,
    }
    criteria = []
    for name, lim_ in lim["limits"].items():
        v = summary.get(name)
        if lim_ is None or v is None:
            criteria.append({"name": name, "value": v, "limit": lim_, "passed": None})
            continue
        ok = True
        if "max" in lim_:
            ok &= v <= lim_["max"]
        if "min" in lim_:
            ok &= v >= lim_["min"]
        criteria.append({"name": name, "value": v, "limit": lim_, "passed": bool(ok)})
    samples = {"random_poses": int(len(q_rand)), "random_seed": opt.seed, "random_stream": AUDIT_STREAM,
               "random_coordinates": audit_coordinates(rom), "rom": des.rom,
               "gait_frames": int(len(q_gait)), "gait_ik": opt.gait_ik, "gait_stride": opt.gait_stride,
               "sweep_points": opt.n_sweep, "grid_points_per_axis": opt.n_grid,
               "segment_step_m": opt.segment_step_m, "geometry_random_poses": int(min(opt.n_geometry, len(q_rand))), "geometry_dir": str(bones.geometry_dir),
               "left_right_pairs_intersecting": [list(p) for p in lr_hits]}
    assembly = {"body_radii_m": {str(d): body_radius(d) for d in sorted({p.diameter_mm for p in des.pams})},
                "body_radius_source": body_radius_source(), "fitting_length_m": des.fitting_length_m,
                "gap_m": thr["body_gap_m"], "bone_gap_m": thr["bone_gap_m"],
                "pairs_closer_than_gap": close_same, "pairs_closer_than_gap_left_right_gait": close_lr}
    res = AuditResult(des.name, des.path, rows, summary, criteria, samples, dict(thr), time.perf_counter() - t0,
                      assembly=assembly, capacity=capacity)
    res.details = {"design": des, "q_rand": q_rand, "q_gait": q_gait, "t_gait": t_gait, "mounts": mounts,
                   "capsules": capsule_cache}
    return res


def _sensitivity(right: PamRobot, human: Model, rom: RangeOfMotion, rows: list[dict], n_sweep: int) -> None:
    """Largest primary-torque change [% of the human peak] for a 1 mm error of one attachment point."""
    des = right.design
    kin = right.model.kinematics
    for k, (pam, row) in enumerate(zip(des.pams, rows)):
        prim = pam.primary_coordinate
        q, _ = right.model.grid([prim], n_sweep, rom=rom, base={c: 0.0 for c in right.model.coordinates})
        ci = right.model.coordinates.index(prim)
        idx = [human.muscles.index(m) for m in pam.human_muscles]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            peak = float(np.max(np.abs(human.torques(q)[:, idx, ci].sum(axis=1))))
        routes, labels = [list(pam.points)], [None]
        for i, pt in enumerate(pam.points):
            if isinstance(pt, MovingPathPoint):
                continue
            for ax in range(3):
                for sgn in (1.0, -1.0):
                    loc = np.array(pt.location, float)
                    loc[ax] += sgn * SENSITIVITY_STEP
                    moved = (ConditionalPathPoint(pt.name, pt.body, tuple(loc), pt.coordinate, pt.range)
                             if isinstance(pt, ConditionalPathPoint) else PathPoint(pt.name, pt.body, tuple(loc)))
                    r = list(pam.points)
                    r[i] = moved
                    routes.append(r)
                    labels.append((i, ax, sgn))
        ps = PathSet(kin, [f"v{j}" for j in range(len(routes))], routes)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            res = ps.evaluate(kin.forward(q, warn_range=False))
        L = res.lengths
        Rm = res.dense_moment_arms(len(right.model.coordinates))[:, :, ci]
        k = pam.transmission
        strain = (pam.resting_length_m - pam_length(L, pam.tendon_length_m, k, des.fitting_length_m)) \
            / pam.resting_length_m
        F = festo.force(strain, pam.resting_length_m, des.pressure_Pa, pam.diameter_mm, model=des.force_model)
        tau = F * pam.n_parallel / k * Rm                  # (S, variants)
        worst, where = 0.0, None
        for i in range(len(pam.points)):
            cols = {lab: j for j, lab in enumerate(labels) if lab is not None and lab[0] == i}
            if not cols:
                continue
            grad = np.stack([(tau[:, cols[(i, ax, 1.0)]] - tau[:, cols[(i, ax, -1.0)]]) / (2 * SENSITIVITY_STEP)
                             for ax in range(3)], axis=1)      # (S, 3) [N·m/m]
            change = np.linalg.norm(grad, axis=1) * 1e-3       # worst direction, 1 mm
            m = float(np.max(change))
            if m > worst:
                worst, where = m, pam.points[i].name
        row["sensitivity_Nm_per_mm"] = worst
        row["sensitivity_pct"] = 100.0 * worst / peak if peak > 0 else float("inf")
        row["sensitivity_point"] = where


def _bone_checks(right: PamRobot, bones, sets: list, rows: list[dict], step: float, thr: dict) -> None:
    """Brackets, points inside bone and segment penetrations (right side): per segment the deepest
    penetration over every pose, the bone, and the fraction of the poses at which it goes deeper than
    the limit (``poses_over_limit_fraction``: where a route needs a guide or a different line).

    Args:
        sets: ``(kinematics state, bones to test or None for all)`` per sample set.
    """
    des = right.design
    n_all = right.paths.n_points
    d_pt = np.full(n_all, np.inf)
    b_pt = np.full(n_all, -1)
    # every segment of every route, sampled every `step` metres (at its longest)
    seg_of, seg_t = [], []       # per test point: (pam, segment) index and parameter
    seg_keys = []
    for k, pam in enumerate(des.pams):
        for j in range(len(pam.points) - 1):
            seg_keys.append((k, j))
    seg_depth = np.zeros(len(seg_keys))
    seg_bone = np.full(len(seg_keys), -1)
    seg_hits = np.zeros(len(seg_keys))      # poses at which the segment goes deeper than the limit
    n_poses = 0
    limit = thr["segment_penetration_max_m"]
    # rollers: their axis sampled end to end in the body frame; distances less the radius are the surface's
    kin = right.model.kinematics
    roller_axes = {(k, r.segment): (kin.frames.index(r.body), roller_axis_points(r))
                   for k, pam in enumerate(des.pams) for r in pam.rollers}
    roller_any = dict.fromkeys(roller_axes, np.inf)
    for state, only in sets:
        for key, (b, local) in roller_axes.items():
            Xr = state.body_p[:, b, None, :] + np.einsum("sij,kj->ski", state.body_R[:, b], local)
            dr, _ = bones.signed_distance(state, Xr, margin=0.0, bodies=only)
            roller_any[key] = min(roller_any[key], float(np.min(dr)))
        X, _ = right.paths.point_positions(state)
        d, near = bones.signed_distance(state, X, margin=0.0, bodies=only)
        s = np.argmin(d, axis=0)
        dm = d[s, np.arange(n_all)]
        better = dm < d_pt
        d_pt[better] = dm[better]
        b_pt[better] = near[s, np.arange(n_all)][better]
        starts, ends, ts = [], [], []
        # the straight pieces of every segment (over a roller: before and after it; the roller is checked
        # as an attachment)
        route_pieces = [right.route_pieces(state, k) for k in range(len(des.pams))]
        seg_of, seg_t, n_test = [], [], []
        for si, (k, j) in enumerate(seg_keys):
            n_test.append(0)
            for A, B in route_pieces[k][j]:
                Lmax = float(np.max(np.linalg.norm(B - A, axis=1)))
                t = np.linspace(0.0, 1.0, max(3, int(math.ceil(Lmax / step)) + 1))
                starts.append(A)
                ends.append(B)
                ts.append(t)
                seg_of.append(np.full(len(t), si))
                seg_t.append(t)
                n_test[-1] += len(t)
        seg_of_a = np.concatenate(seg_of)
        t_all = np.concatenate(seg_t)
        A_all = np.concatenate([np.repeat(A[:, None, :], len(t), axis=1) for A, t in zip(starts, ts)], axis=1)
        B_all = np.concatenate([np.repeat(B[:, None, :], len(t), axis=1) for B, t in zip(ends, ts)], axis=1)
        chunk = max(1, 400_000 // len(t_all))
        first = np.concatenate([[0], np.cumsum(n_test)[:-1]])   # each segment's first test point
        n_poses += len(A_all)
        for c0 in range(0, len(A_all), chunk):
            P = A_all[c0:c0 + chunk] + t_all[None, :, None] * (B_all[c0:c0 + chunk] - A_all[c0:c0 + chunk])
            # only penetrations count here: points a coarse grid proves outside every bone are skipped
            # (BoneSet.far_from; every distance <= 0 is the exact one)
            dd, nb = bones.signed_distance(_slice_state(state, c0, c0 + chunk), P, margin=0.0, bodies=only,
                                           prune=True)
            seg_hits += np.sum(np.maximum.reduceat(-dd, first, axis=1) > limit, axis=0)
            col = np.argmin(dd, axis=0)
            depth = -dd[col, np.arange(len(t_all))]
            nbest = nb[col, np.arange(len(t_all))]
            order = np.argsort(depth)              # last write wins: deepest per segment
            upd = depth[order] > seg_depth[seg_of_a[order]]
            seg_depth_new = seg_depth.copy()
            seg_bone_new = seg_bone.copy()
            seg_depth_new[seg_of_a[order][upd]] = depth[order][upd]
            seg_bone_new[seg_of_a[order][upd]] = nbest[order][upd]
            seg_depth, seg_bone = seg_depth_new, seg_bone_new
    si = 0
    for k, (pam, row) in enumerate(zip(des.pams, rows)):
        a = right.paths._path_start[k]
        pts_info = []
        for i, pt in enumerate(pam.points):
            own = None
            if not isinstance(pt, MovingPathPoint):
                own = float(bones.body_signed_distance(pt.body, np.array([pt.location]))[0])
            dmin = float(d_pt[a + i])
            pts_info.append({"name": pt.name, "body": pt.body, "moving": isinstance(pt, MovingPathPoint),
                             "own_bone_distance_m": own,
                             "min_any_bone_distance_m": dmin if np.isfinite(dmin) else None,
                             "deepest_bone": bones.bodies[b_pt[a + i]] if dmin < 0 and b_pt[a + i] >= 0 else None})
        row["points"] = pts_info
        rollers = []
        for r in pam.rollers:
            _, local = roller_axes[(k, r.segment)]
            dany = roller_any[(k, r.segment)] - r.radius_m
            rollers.append({"name": f"roller {r.segment}", "segment": r.segment, "body": r.body,
                            "radius_m": r.radius_m,
                            "own_bone_distance_m": float(np.min(bones.body_signed_distance(r.body, local))) - r.radius_m,
                            "min_any_bone_distance_m": dany if np.isfinite(dany) else None})
        row["rollers"] = rollers
        # rollers count as fixed attachments (their surface: outside bone, within a bracket's distance of it)
        fixed = [p for p in pts_info + rollers if p["own_bone_distance_m"] is not None]
        row["points_inside_own_bone"] = sum(1 for p in fixed if p["own_bone_distance_m"] < 0)
        row["points_inside_any_bone"] = sum(1 for p in pts_info + rollers if p["min_any_bone_distance_m"] is not None
                                            and p["min_any_bone_distance_m"] < 0)
        # a rack's brackets (pamkin.robot.rack) may stand farther out than an attachment point
        row["points_over_bracket"] = sum(1 for p in fixed if p["own_bone_distance_m"] > (
            thr["rack_bracket_max_m"] if p["name"] in RACK_POINTS else thr["bracket_max_m"]))
        row["max_bracket_m"] = max((p["own_bone_distance_m"] for p in fixed), default=None)
        segs = []
        for name in segment_names(pam):
            dp = float(max(seg_depth[si], 0.0))
            segs.append({"segment": name, "penetration_m": dp,
                         "bone": bones.bodies[seg_bone[si]] if dp > 0 and seg_bone[si] >= 0 else None,
                         "poses_over_limit_fraction": float(seg_hits[si] / n_poses) if n_poses else 0.0})
            si += 1
        row["segments"] = segs
        row["max_segment_penetration_m"] = max(x["penetration_m"] for x in segs)
        row["segments_over_limit"] = sum(1 for x in segs if x["penetration_m"] > thr["segment_penetration_max_m"])


def _slice_state(state, a: int, b: int):
    """Configurations a:b of a kinematics state (only the fields the bone queries read)."""
    from types import SimpleNamespace  # noqa: PLC0415

    return SimpleNamespace(q=state.q[a:b], body_R=state.body_R[a:b], body_p=state.body_p[a:b])


def _clearance(robot: PamRobot, des: Design, kin_state: dict, pam_state: dict, mounts: list):
    """Minimum signed distance between the PAM bodies of every pair of actuators.

    Same side (right): over the random poses and the gait; left–right: over the gait.
    Returns ``(pairs, pairs_lr, capsules)`` with ``{(a, b): (distance [m], sample)}``.
    """

    n = len(des.pams)
    radius = [festo.outer_diameter(p.diameter_mm) / 2 for p in des.pams]
    fit = 2 * des.fitting_length_m
    caps: dict[str, list] = {}
    for key, st in kin_state.items():
        ps = pam_state[key]
        cols = range(2 * n) if key == "gait" else range(n)
        caps[key] = {}
        for c in cols:
            k = c % n
            pts = route_positions(robot.paths, st, c)
            length = ps.pam_lengths[:, c] + fit
            # the PAM body at its mount segment's anchored end (moved back where the route ends first)
            caps[key][c] = pam_capsules(pts, mounts[k].segment, length, mounts[k].side)

    def closest(ca: list, cb: list, ra: float, rb: float) -> tuple[float, int]:
        return body_pair_distance(ca, cb, ra, rb, CLEARANCE_TOLERANCE)

    pairs: dict = {}
    pairs_lr: dict = {}
    for a in range(n):
        for b in range(a + 1, n):
            best, arg = np.inf, -1
            for key in caps:
                d, s = closest(caps[key][a], caps[key][b], radius[a], radius[b])
                if d < best:
                    best, arg = d, s
                if best < -CLEARANCE_TOLERANCE:
                    break
            pairs[(a, b)] = (best, arg)
    if "gait" in caps:
        for a in range(n):
            for b in range(n):
                pairs_lr[(a, b)] = closest(caps["gait"][a], caps["gait"][b + n], radius[a], radius[b])
    return pairs, pairs_lr, caps


def _body_gaps(des: Design, caps: dict, gap: float) -> tuple[list[dict], list[dict]]:
    """Every pair of PAM bodies of different actuators (:func:`pamkin.audit.assembly.pair_gap`, bodies of
    their largest outer radius): same side (right) over every sample set of ``caps`` (as :func:`_clearance`
    builds it), left–right over the gait. One dict per pair: ids, names, smallest distance [m], where (set,
    sample) and the fractions of the samples closer than ``gap`` and overlapping."""
    n = len(des.pams)
    radius = [body_radius(p.diameter_mm, p.n_parallel) for p in des.pams]

    def row(a: int, b: int, key_of: list) -> dict:
        best = None
        closer = overlap = samples = 0
        for key, ca, cb in key_of:
            g = pair_gap(ca, cb, radius[a % n], radius[b % n], gap, CLEARANCE_TOLERANCE)
            m = len(ca[0][0]) if ca else 0
            closer += g.closer_fraction * m
            overlap += g.overlap_fraction * m
            samples += m
            if best is None or g.distance_m < best[0]:
                best = (g.distance_m, key, g.sample)
        return {"a": des.pams[a % n].id, "b": des.pams[b % n].id, "a_name": des.pams[a % n].name,
                "b_name": des.pams[b % n].name, "distance_m": best[0], "set": best[1], "sample": best[2],
                "closer_fraction": closer / samples if samples else 0.0,
                "overlap_fraction": overlap / samples if samples else 0.0}

    same = [row(a, b, [(k, caps[k][a], caps[k][b]) for k in caps]) for a in range(n) for b in range(a + 1, n)]
    lr = ([row(a, b + n, [("gait", caps["gait"][a], caps["gait"][b + n])]) for a in range(n) for b in range(n)]
          if "gait" in caps else [])
    return same, lr


def _body_bone_checks(des: Design, bones, geo: dict, caps: dict, rows: list[dict], right_side: list[str],
                      step: float, thr: dict) -> None:
    """Per PAM (right side) the clearance of its body from bone (:func:`pamkin.audit.assembly.bone_clearance`)
    over the random poses (right-side bones) and the gait (every bone): the smallest [m] (negative: into
    bone), the bone, where, and the fraction of the poses closer than the bone gap."""
    gap = thr["bone_gap_m"]
    for k, (pam, row) in enumerate(zip(des.pams, rows)):
        r = body_radius(pam.diameter_mm, pam.n_parallel)
        best, bone, where, under, total = np.inf, None, None, 0, 0
        for key, st in geo.items():
            c, near = bone_clearance(bones, st, caps[key][k], r, step, reach=0.02,
                                     bodies=right_side if key == "random" else None)
            under += int(np.sum(c < gap))
            total += len(c)
            s = int(np.argmin(c)) if len(c) else -1
            if s >= 0 and c[s] < best:
                best, where = float(c[s]), (key, s)
                bone = bones.bodies[near[s]] if near[s] >= 0 else None
        row["body_radius_m"] = r
        row["body_bone_clearance_m"] = best
        row["body_bone_nearest"] = bone
        row["body_bone_where"] = list(where) if where else None
        row["body_bone_under_gap_fraction"] = under / total if total else 0.0


def _human_columns(human: Model, T: np.ndarray, names: list[str]) -> np.ndarray:
    """Human torques ``T`` (S, M, human coordinates) with their columns in the order of ``names``."""
    return T[:, :, [human.coordinates.index(c) for c in names]]


def _gait_fraction(des: Design, thr: dict, ik: str) -> tuple[float, dict[str, float]]:
    """Feasible-frame fraction of the gait pressure plan (as :func:`pamkin.gait.plan.feasible_frame_fraction`)
    and the limiting coordinates: {coordinate: fraction of frames within tolerance} where below 1,
    worst first."""

    plan = gait_plan(PamRobot(des, robot_skeleton()), ik=ik, grf=None, tolerance=thr["gait_residual_pct"] / 100.0)
    limiting = sorted(((c.within_tolerance_fraction, c.name) for c in plan.coordinate_results
                       if c.within_tolerance_fraction < 1.0))
    return float(plan.feasible_frame_fraction), {name: float(f) for f, name in limiting}


__all__ = ["AUDIT_STREAM", "AuditOptions", "AuditResult", "audit_design", "audit_coordinates", "best_force_scale", "gait_poses",
           "load_limits", "random_poses", "torque_metrics"]
