"""Robot versus human torques: per PAM, per thesis group and per joint.

For every PAM, the robot torque about a coordinate is compared with the summed torque of the
human muscles it replaces (Gait2392 at full activation, static equilibrium) at the same
configurations, over the robot's range of motion:

* primary coordinate: a 1-D sweep of the primary coordinate, other coordinates 0;
* each secondary coordinate c: a 2-D grid primary × c, torque about c.

Metrics (numbers on the sampled configurations):

* ``nrmse`` = RMS(τ_robot − τ_human) / max|τ_human| (normalised by the human peak, so a
  wrong-signed torque of the right size scores ≈ 1–2 and a perfect match 0);
* ``peak_ratio`` = max|τ_robot| / max|τ_human|;
* ``sign_agreement``: fraction of samples with |τ_human| > 1 % of its peak where the signs agree;
* ``dead_zone_fraction``: fraction of samples where the PAM is outside its strain range
  (stretched beyond Festo's pretension limit or contracted beyond kmax): the thesis's dead zones.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from pamkin.human.groups import load_groups
from pamkin.human.model import Model
from pamkin.human.rom import RangeOfMotion, load_rom
from pamkin.robot.biped import PamRobot


@dataclass(frozen=True)
class TorqueMatch:
    """Robot vs human torque about one coordinate."""

    coordinate: str
    grid: str
    nrmse: float
    peak_ratio: float
    sign_agreement: float
    dead_zone_fraction: float
    human_peak_Nm: float
    robot_peak_Nm: float
    n_samples: int


@dataclass(frozen=True)
class PamComparison:
    """Comparison of one PAM (one side) with the human muscles it replaces."""

    id: int
    name: str
    side: str
    human_muscles: tuple[str, ...]
    diameter_mm: int
    n_parallel: int
    resting_length_m: float
    tendon_length_m: float
    buildable: bool
    primary: TorqueMatch
    secondary: tuple[TorqueMatch, ...] = field(default=())

    def to_dict(self) -> dict:
        d = asdict(self)
        d["human_muscles"] = list(self.human_muscles)
        return d


def torque_match(human: np.ndarray, robot: np.ndarray, in_range: np.ndarray, coordinate: str,
                 grid: str) -> TorqueMatch:
    """Metrics of a robot torque series against a human one (same samples)."""
    human = np.asarray(human, float)
    robot = np.asarray(robot, float)
    peak = float(np.max(np.abs(human))) if human.size else 0.0
    err = robot - human
    nrmse = float(np.sqrt(np.mean(err ** 2)) / peak) if peak > 0 else float("nan")
    rpeak = float(np.max(np.abs(robot))) if robot.size else 0.0
    mask = np.abs(human) > 0.01 * peak
    sign = float(np.mean(np.sign(robot[mask]) == np.sign(human[mask]))) if mask.any() else float("nan")
    return TorqueMatch(coordinate, grid, nrmse, rpeak / peak if peak > 0 else float("nan"), sign,
                       float(np.mean(~in_range)), peak, rpeak, int(human.size))


def _samples(model: Model, rom: RangeOfMotion, coords: list[str], n: int) -> np.ndarray:
    q, _ = model.grid(coords, n, rom=rom, base={c: 0.0 for c in model.coordinates})
    return q


def compare_pam(robot: PamRobot, human: Model, k: int, rom: RangeOfMotion, n: int = 41,
                n2: int = 15) -> PamComparison:
    """Compare PAM column ``k`` of ``robot`` with its human muscles (see module docstring)."""
    pam = robot.pams[k]
    side = robot.sides[k]
    muscles = robot.human_muscles(k)
    idx = [human.muscles.index(m) for m in muscles]
    prim = robot.side_coordinate(k, pam.primary_coordinate)

    def match(coords: list[str], about: str, size: int, label: str) -> TorqueMatch:
        q = _samples(human, rom, coords, size)
        c = human.coordinates.index(about)
        th = human.torques(q)[:, idx, c].sum(axis=1)
        st = robot.evaluate(q)
        tr = st.torques[:, k, c]
        return torque_match(th, tr, st.in_range[:, k], about, label)

    primary = match([prim], prim, n, f"1-D {prim}")
    secondary = [match([prim, robot.side_coordinate(k, sc)], robot.side_coordinate(k, sc), n2,
                       f"2-D {prim} x {robot.side_coordinate(k, sc)}") for sc in pam.secondary_coordinates]
    # a design states rest + 2 fittings + tendon = route length at its longest; buildable needs tendon >= 0
    buildable = bool(pam.tendon_length_m >= 0)
    return PamComparison(pam.id, pam.name, side, muscles, pam.diameter_mm, pam.n_parallel, pam.resting_length_m,
                         pam.tendon_length_m, buildable, primary, tuple(secondary))


def compare_design(robot: PamRobot, human: Model, side: str = "r", n: int = 41, n2: int = 15) -> list[PamComparison]:
    """Compare every PAM of one side."""
    rom = load_rom(robot.design.rom, side)
    return [compare_pam(robot, human, k, rom, n, n2) for k in range(len(robot.pams)) if robot.sides[k] == side]


def compare_groups(robot: PamRobot, human: Model, side: str = "r", n: int = 15) -> dict[str, dict]:
    """Thesis groups: summed robot torque of the PAMs replacing a group's muscles vs the group's human torque.

    Each group is compared about every coordinate its PAMs name as primary or secondary, over a
    2-D grid of the group's two most common coordinates (or 1-D).
    """
    rom = load_rom(robot.design.rom, side)
    out = {}
    for g in load_groups(sides=(side,)):
        if g.kind != "thesis":
            continue
        cols = [k for k in range(len(robot.pams)) if robot.sides[k] == side
                and set(robot.human_muscles(k)) <= set(g.muscles)]
        if not cols:
            continue
        coords: list[str] = []
        for k in cols:
            for c in (robot.pams[k].primary_coordinate, *robot.pams[k].secondary_coordinates):
                c = robot.side_coordinate(k, c)
                if c not in coords:
                    coords.append(c)
        grid = coords[:2]
        q = _samples(human, rom, grid, n)
        T = human.torques(q)
        midx = [human.muscles.index(m) for m in g.muscles]
        st = robot.evaluate(q)
        res = {}
        for c in coords:
            ci = human.coordinates.index(c)
            th = T[:, midx, ci].sum(axis=1)
            tr = st.torques[:, cols, ci].sum(axis=1)
            res[c] = asdict(torque_match(th, tr, st.in_range[:, cols].all(axis=1), c, " x ".join(grid)))
        out[g.key] = {"pams": [robot.pams[k].id for k in cols], "coordinates": res}
    return out


def compare_joints(robot: PamRobot, human: Model, side: str = "r", n: int = 41) -> dict[str, dict]:
    """Per-joint capacity envelopes (sum of positive / negative torques), robot vs human, 1-D sweeps."""
    rom = load_rom(robot.design.rom, side)
    out = {}
    for c in rom.coordinates:
        if c not in human.coordinates:
            continue
        q = _samples(human, rom, [c], n)
        ci = human.coordinates.index(c)
        T = human.torques(q)[:, :, ci]
        R = robot.evaluate(q).torques[:, :, ci]
        out[c] = {"human_max_positive_Nm": float(np.where(T > 0, T, 0).sum(1).max()),
                  "human_min_negative_Nm": float(np.where(T < 0, T, 0).sum(1).min()),
                  "robot_max_positive_Nm": float(np.where(R > 0, R, 0).sum(1).max()),
                  "robot_min_negative_Nm": float(np.where(R < 0, R, 0).sum(1).min())}
    return out


def failing_as_worst(values) -> np.ndarray:
    """``values`` as an array with every undefined (nan) entry replaced by +inf: an error that cannot be
    computed (no human torque to divide by) fails every limit instead of dropping out of a median."""
    a = np.asarray(values, float)
    return np.where(np.isnan(a), np.inf, a)


def finite_or_none(x):
    """``x`` with every non-finite float (in nested dicts, lists and tuples) replaced by ``None``: strict
    JSON (``json.dumps(..., allow_nan=False)``) for results with undefined or failing-as-infinite values."""
    if isinstance(x, dict):
        return {k: finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [finite_or_none(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    return x


def summary_line(rows: list[PamComparison], threshold: float = 0.25) -> dict:
    """Median primary NRMSE, count within ``threshold``, wrong-signed and unbuildable PAMs. A PAM whose
    human muscles give no torque about its primary coordinate has an undefined NRMSE: it counts as
    infinite in the median (as in :mod:`pamkin.audit.measure`) and is named in ``undefined_nrmse``."""
    e = failing_as_worst([r.primary.nrmse for r in rows])
    return {"n": len(rows), "median_nrmse": float(np.median(e)) if len(e) else float("nan"),
            f"within_{threshold}": int(np.sum(e <= threshold)),
            "undefined_nrmse": [r.id for r in rows if np.isnan(r.primary.nrmse)],
            "sign_agreement_below_half": [r.id for r in rows if r.primary.sign_agreement < 0.5],
            "not_buildable": [r.id for r in rows if not r.buildable],
            "with_dead_zones": [r.id for r in rows if r.primary.dead_zone_fraction > 0]}
