"""Run description of an attachment-point optimisation (TOML), nested by stage.

The TOML file and :class:`RunConfig` mirror each other one to one: top-level keys are fields of
:class:`RunConfig`, every ``[section]`` is one of its section dataclasses (``[mount]`` is
:attr:`RunConfig.mount`, a :class:`Mount`), every key a field of that section. Every key is optional; the
defaults are the default run's. Each key is defined once, here: its type, default, range and description
(the field's ``metadata``), from which :func:`config_reference_markdown` generates the reference page and
:meth:`RunConfig.validate` checks a value. An unknown section or key, a wrong type or a value out of range is
an error naming the file and the key (``pamkin optimize`` exits 2), before anything is solved.

Sections: the problem every solve shares (``[samples]``, ``[weights]``, ``[limits]``), then one per stage of
:data:`pamkin.optimize.pipeline.STAGES` that has keys (``[first_fit]``, ``[unit_budget]``, ``[bone_rounds]`` and
its one-segment step ``[mount]``, ``[resize]``, ``[reallocate]``, ``[mass]``, ``[walking]``, ``[clearance]``,
``[rollers]``, ``[detours]``, ``[pam_ends]``), and the per-actuator tables ``[regions]``, ``[transmission]`` and
``[eyelets]`` of the seed stage. Example::

    design = "v2_seed"
    workers = 2

    [first_fit]
    diameters_mm = [20, 40]

    [mount]
    cost = 0.2

    [regions]
    "6" = 0.08
    "6.p2" = [0.02, 0.02, 0.0]

:data:`FAST_FIT` holds the earlier 1-D/2-D fit (``examples/optimize_fast.toml``, about 2.5 minutes).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re
import tomllib
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any

from pamkin.errors import ConfigurationError, DataFileError
from pamkin.human.bones import BoneSet
from pamkin.robot.design import TRANSMISSIONS, rescale_for_transmission, unit_mass
from pamkin.robot.eyelets import EYELET_GAP_M, add_eyelet, has_eyelet

#: Actuators of the v2 seed solved with the one-segment rows by default (``[limits] one_segment_actuators``).
ONE_SEGMENT_ACTUATORS = (13, 14)

#: Default eyelets (``[eyelets]``): the tibia-to-calcaneus segment of soleus, peroneus tertius and the long toe
#: extensors guided on the talus. Entries naming an actuator the seed design lacks, or whose route passes no
#: such segment, are skipped (they fit the v2 seed and the thesis design).
DEFAULT_EYELETS: dict = {"12": ["talus_r"], "19": [{"body": "talus_r", "at": 0.5}],
                         "22": [{"body": "talus_r", "at": 0.5}], "23": [{"body": "talus_r", "at": 0.5}]}


def key(default: Any, doc: str, lo: float | None = None, hi: float | None = None, choices: tuple = (),
        factory=None, unit: str = "") -> Any:
    """A config key: its default, description, allowed range (``lo`` .. ``hi``) or ``choices``, and the unit an
    error message names."""
    meta = {"doc": doc, "lo": lo, "hi": hi, "choices": choices, "unit": unit}
    if factory is not None:
        return field(default_factory=factory, metadata=meta)
    return field(default=default, metadata=meta)


@dataclass
class Samples:
    """``[samples]``: where every actuator's problem samples the human torque (shared by every solve)."""

    primary: int = key(25, "1-D sweep of the primary coordinate (others 0)", 2, 201)
    secondary: int = key(7, "per axis of each 2-D grid primary x secondary", 2, 201)
    constraint: int = key(5, "per axis of the full grid over primary + secondaries (strain limits)", 2, 201)
    random: int = key(30, "multi-joint training poses per actuator (own random stream, never the audit's)", 0, 10000)
    gait: bool = key(False, "also train on the walking trial (between its frames; both legs, mirrored)")


@dataclass
class Weights:
    """``[weights]``: the terms of every actuator's objective."""

    primary: float = key(1.0, "weight of the primary coordinate's 1-D sweep", 0)
    secondary: float = key(0.5, "weight of the 2-D grids", 0)
    regularization: float = key(1e-3, "pull towards the seed route, per (region size)^2", 0)
    whole_vector: float = key(1.0, "torque error about every coordinate crossed, on the training poses", 0)
    mass: float = key(0.02, "objective penalty per kg of PAM (diameter, parallel count; both sides)", 0)


@dataclass
class Limits:
    """``[limits]``: the constraints of every actuator's problem (shared by every solve)."""

    region_m: float = key(0.05, "half-width of every route point's box around its seed [m]", 0, 1.0)
    min_point_distance_m: float = key(0.01, "least distance between successive route points [m]", 0, 1.0)
    bone_clearance: bool = key(True, "route segments clear the bone-shaft capsules by the PAM radius "
                                     "(with the bone meshes: until their rounds)")
    kmax_scale: float = key(1.0, "contraction limit = kmax_scale x kmax(l0)", 1e-9, 1.0)
    pretension_scale: float = key(1.0, "stretch limit = pretension_scale x Festo's limit", 0, 1.0)
    fix_lengths: bool = key(False, "keep the seed resting and tendon lengths (move attachment points only)")
    move_moving_points: bool = key(True, "offset points that move with a coordinate (the patella) within the region")
    max_resting_length_m: float = key(0.0, "longest resting length a fit may choose [m] (0: Festo's longest for "
                                           "the diameter): a body short enough for a rack", 0, 10.0)
    rated_force: bool = key(True, "force per PAM <= Festo's rated force and contraction <= Festo's maximum (0.25)")
    one_segment: bool = key(False, "the PAM (+ fittings) fits on one straight segment of its route, as a "
                                   "constraint of every solve (slow, poor fits: the [mount] step instead)")
    one_segment_actuators: list[int] = key(None, "actuators solved with the one-segment rows all the same "
                                                 "(the gastrocnemii: measured to keep their fit)",
                                           factory=lambda: list(ONE_SEGMENT_ACTUATORS))
    sensitivity_pct: float = key(9.0, "a 1 mm error of a fixed attachment point changes the primary torque on "
                                      "its 1-D sweep by at most this % of the human peak (audit: 10); 0: off", 0, 100)


@dataclass
class FirstFit:
    """``[first_fit]``: the first-fit stage's outer loop over Festo diameter and parallel count, multistart and
    IPOPT's limits."""

    diameters_mm: list[int] = key(None, "Festo diameters tried (outer loop), a subset of [10, 20, 40]",
                                  factory=lambda: [10, 20, 40])
    max_parallel: int = key(3, "outer loop: 1..max_parallel PAMs on the route", 1, 3)
    multistart: int = key(1, "extra solves from perturbed seeds (kept if better) ...", 0, 100)
    multistart_threshold: float = key(1e-3, "... when the best objective is above this (NRMSE ~ 3 %)", 0)
    max_iter: int = key(400, "IPOPT iterations per solve", 1, 100000)
    max_solve_seconds: float = key(12.0, "IPOPT CPU-time limit per solve [s] (0: none); a solve that hits it is "
                                         "treated as failed", 0, 86400)


@dataclass
class UnitBudget:
    """``[unit_budget]``: the unit-budget stage."""

    max_units: int = key(60, "PAM units of the whole robot (both sides; 0: no limit, the stage is off): every "
                             "actuator's diameter and parallel count chosen together for the least summed score", 0,
                         10000)


@dataclass
class BoneRounds:
    """``[bone_rounds]``: the real bone meshes and the bone-rounds stage."""

    enabled: bool = key(True, "attachment points on their bone (3..18 mm out), segments clear of the real bone "
                              "meshes at random, sweep and gait poses (optimize.bone_cuts); needed by the "
                              "re-sizing, reallocation, PAM-PAM, roller and detour stages")
    rounds: int = key(10, "largest number of re-linearisation rounds (a route clear of bone still gaining "
                          ">= 5 % a round gets up to 6 more)", 1, 20)
    seed_start: bool = key(True, "the rounds also start from the seed route (points moved onto their bone's "
                                 "3..18 mm band); the better of the two results is kept")
    bracket_fit: bool = key(False, "the fit itself keeps attachment points 3..18 mm out of their bone (smooth "
                                   "bone-distance splines, optimize.bracket)")


@dataclass
class Mount:
    """``[mount]``: the one-segment step of the bone-rounds stage (optimize.mount)."""

    enabled: bool = key(True, "after the bone rounds, with the route fixed, the PAM is put on one straight "
                              "segment (resting and tendon length re-solved) where its fit allows")
    cost: float = key(0.1, "largest growth of the root of the fit objective a mount may cost", 0, 100)
    failing: bool = key(True, "a PAM whose fit already fails both audit fit limits on the validation poses goes "
                              "on one segment at any fit cost that keeps every limit")
    passing: bool = key(True, "a PAM that on one segment (or a pulley block) still passes both audit fit limits, "
                              "less 0.02, goes on it at any fit cost that keeps every limit")
    blocks: bool = key(True, "a PAM out of reach of one segment at 1:1 is tried on a 2:1 pulley block, then 3:1")


@dataclass
class Resize:
    """``[resize]``: the re-sizing stage (needs [bone_rounds] and [unit_budget])."""

    above: float = key(1.0, "an actuator whose fit objective is still above this gets its other diameters "
                            "through the bone rounds too; the lower score kept (0: off)", 0)
    block_refit_above: float = key(0.5, "an actuator the one-segment step put on a pulley block, with a fit "
                                        "objective above this, is solved again with a 3:1 block throughout (0: off)",
                                   0)
    on: str = key("objective", "what the re-sizing compares: 'objective' (fit objective + mass penalty) or "
                               "'validation' (primary NRMSE + worst error on the validation poses)",
                  choices=("objective", "validation"))


@dataclass
class Reallocate:
    """``[reallocate]``: the unit-reallocation stage (needs [bone_rounds] and [unit_budget])."""

    enabled: bool = key(True, "a PAM unit of an actuator failing both audit fit limits moves to the failing "
                              "actuator nearest to passing that then passes both")


@dataclass
class Mass:
    """``[mass]``: the mass stage."""

    max_kg: float = key(22.0, "the robot's estimated mass budget (both sides, the audit's) [kg]: pulley blocks "
                              "come off again while it is over (0: off)", 0, 1000)


@dataclass
class Walking:
    """``[walking]``: the walking stage (needs [unit_budget])."""

    min_fraction: float = key(0.9, "while the walking trial's pressure plan is feasible on less than this fraction "
                                   "of its samples, actuators at the pressure limit are re-sized (0: off)", 0, 1)


@dataclass
class Clearance:
    """``[clearance]``: the PAM-PAM clearance stage (needs [bone_rounds])."""

    enabled: bool = key(False, "routes that hit another PAM's body are solved again with the bodies as obstacles")


@dataclass
class Rollers:
    """``[rollers]``: the roller stage (needs [bone_rounds])."""

    enabled: bool = key(False, "actuators failing an audit fit limit get rollers (cable guides on bone) where "
                               "their fit without the bone rows goes into bone, kept where they help")


@dataclass
class Detours:
    """``[detours]``: the detour stage (needs [bone_rounds])."""

    enabled: bool = key(True, "same-body route segments too short to hold the PAM body are left out of that "
                              "bone's rows and carried round it by via points afterwards")


@dataclass
class PamEnds:
    """``[pam_ends]``: the PAM-ends stage (needs [mount])."""

    enabled: bool = key(True, "each PAM on one segment anchored at the segment and end that leave the fewest "
                              "intersecting PAM pairs")


@dataclass
class Separate:
    """``[separate]``: the separate stage (needs [bone_rounds] for the bone meshes)."""

    enabled: bool = key(False, "the ends of each PAM's mount segment moved on their brackets until same-side PAM "
                               "bodies are gap_m apart and bone_gap_m from bone (changes moment arms)")
    gap_m: float = key(0.005, "least gap between two same-side PAM bodies [m]", 0, 0.1)
    bone_gap_m: float = key(0.005, "least gap between a PAM body and bone [m]", 0, 0.1)
    max_bracket_m: float = key(0.05, "farthest a moved point may be from its bone [m]", 0, 0.2)
    max_shift_m: float = key(0.02, "farthest a point may move from where the fit put it [m]", 0, 0.2)
    rounds: int = key(40, "most rounds of moves", 1, 1000)
    poses: int = key(60, "random poses (the stage's own stream) the gaps are enforced at", 1, 5000)


@dataclass
class Rack:
    """``[rack]``: the rack stage (needs [bone_rounds] for the bone meshes)."""

    enabled: bool = key(True, "every PAM body hung on brackets along a bone of its route's end (routes and moment "
                               "arms unchanged), the layout chosen for all PAMs at once")
    gap_m: float = key(0.005, "least gap between two PAM bodies and between a PAM body and bone [m]", 0, 0.1)
    bracket_max_m: float = key(0.05, "farthest a rack bracket (anchor, guide pulley) may be from its bone [m]", 0, 0.2)
    angles: int = key(16, "sides of the bone tried around its axis", 4, 64)
    poses: int = key(200, "random poses (the stage's own stream) the candidates are checked at, and half as many "
                          "more at the range's edges (each coordinate at a limit or uniform)", 1, 5000)
    check_poses: int = key(2000, "more random poses (another stream), and half as many at the range's edges, the "
                                 "chosen racks are checked at again; a rack failing there is dropped and the choice "
                                 "made again", 0, 20000)
    gait: bool = key(True, "check the layout at the poses of the audit's walking trial too (left against right)")
    gait_stride: int = key(6, "every n-th frame of the walking trial", 1, 1000)
    time_limit_s: float = key(120.0, "time limit of the layout's integer program [s]", 1, 3600)
    friction: float = key(0.03, "capstan coefficient of the cable's turns on a rack (guide pulley and route end on "
                                "ball bearings): the PAM's force x exp(-friction x largest turn), its cable_efficiency",
                          0, 1.0)


#: Section name -> its dataclass, in the order of the reference page.
SECTIONS: dict[str, type] = {
    "samples": Samples, "weights": Weights, "limits": Limits, "first_fit": FirstFit, "unit_budget": UnitBudget,
    "bone_rounds": BoneRounds, "mount": Mount, "resize": Resize, "reallocate": Reallocate, "mass": Mass,
    "walking": Walking, "clearance": Clearance, "rollers": Rollers, "detours": Detours, "pam_ends": PamEnds,
    "separate": Separate, "rack": Rack,
}
#: Per-actuator tables (free keys, checked by :meth:`RunConfig.validate`).
TABLES = ("regions", "transmission", "eyelets")
#: Where the keys of the earlier flat layout live now (an old file gets an error naming the new key).
MOVED = {
    "diameters_mm": "first_fit.diameters_mm", "max_parallel": "first_fit.max_parallel",
    "multistart": "first_fit.multistart", "multistart_threshold": "first_fit.multistart_threshold",
    "max_iter": "first_fit.max_iter", "max_solve_seconds": "first_fit.max_solve_seconds",
    "limits.max_units": "unit_budget.max_units", "limits.bone_mesh": "bone_rounds.enabled",
    "limits.bone_rounds": "bone_rounds.rounds", "limits.bone_seed_start": "bone_rounds.seed_start",
    "limits.bracket_fit": "bone_rounds.bracket_fit", "limits.mount": "mount.enabled", "limits.mount_cost": "mount.cost",
    "limits.mount_failing": "mount.failing", "limits.mount_passing": "mount.passing",
    "limits.mount_blocks": "mount.blocks", "limits.resize_above": "resize.above",
    "limits.block_refit_above": "resize.block_refit_above", "limits.resize_on": "resize.on",
    "limits.reallocate": "reallocate.enabled", "limits.max_mass_kg": "mass.max_kg",
    "limits.walking_min": "walking.min_fraction", "limits.pam_clearance": "clearance.enabled",
    "limits.rollers": "rollers.enabled", "limits.detours": "detours.enabled", "limits.pam_ends": "pam_ends.enabled",
}


@dataclass
class RunConfig:
    """An optimisation run: the top-level keys, one section per stage, the per-actuator tables."""

    design: str = key("v2_seed", "seed design: a design file, a run folder or a keyword ('thesis', "
                                 "'split_gluteal', 'v2_seed', 'merged_seed'); '' = the built-in thesis design")
    actuators: list[int] = key(None, "actuator ids to optimise; [] = all", factory=list)
    warm_start: str = key("", "run folder whose design.yaml seeds the routes and sizes (its diameter and parallel "
                              "count tried first; the full loop only where they fail)")
    pressure_Pa: float = key(620e3, "the PAMs' operating pressure [Pa]", 1e5, 8e5, unit="Pa (e.g. 620000 for 6.2 bar)")
    force_model: str = key("v3", "PAM force model: 'v3' (the lab's measured model) or 'v0' (the thesis table)",
                           choices=("v3", "v0"))
    seed: int = key(0, "random seed of the training poses and perturbations", 0)
    workers: int = key(2, "local worker processes (actuators are independent problems)", 1, 1024)
    samples: Samples = field(default_factory=Samples)
    weights: Weights = field(default_factory=Weights)
    limits: Limits = field(default_factory=Limits)
    first_fit: FirstFit = field(default_factory=FirstFit)
    unit_budget: UnitBudget = field(default_factory=UnitBudget)
    bone_rounds: BoneRounds = field(default_factory=BoneRounds)
    mount: Mount = field(default_factory=Mount)
    resize: Resize = field(default_factory=Resize)
    reallocate: Reallocate = field(default_factory=Reallocate)
    mass: Mass = field(default_factory=Mass)
    walking: Walking = field(default_factory=Walking)
    clearance: Clearance = field(default_factory=Clearance)
    rollers: Rollers = field(default_factory=Rollers)
    detours: Detours = field(default_factory=Detours)
    pam_ends: PamEnds = field(default_factory=PamEnds)
    separate: Separate = field(default_factory=Separate)
    rack: Rack = field(default_factory=Rack)
    regions: dict = key(None, "per actuator or per point: '6' = 0.08, '6.p2' = [0.02, 0.02, 0.0] (box half-widths "
                              "[m])", factory=dict)
    transmission: dict = key(None, "per actuator: '4' = 2 puts a 2:1 pulley block on its PAM (default: the seed "
                                   "design's)", factory=dict)
    eyelets: dict = key(None, "per actuator: '19' = 'talus_r', or {body, at, gap}, or a list of those: an eyelet "
                              "(a via point on a bracket of that body) in the seed route; a table given replaces "
                              "the default (soleus, peroneus tertius, the long toe extensors on the talus)",
                        factory=lambda: copy.deepcopy(DEFAULT_EYELETS))
    source: str = field(default="", metadata={"internal": True})

    def replace(self, changes: dict[str, Any]) -> RunConfig:
        """A validated copy with ``changes`` applied: ``{"workers": 1, "mount.cost": 0.2}`` (dotted keys name a
        section's key, as in the TOML file)."""
        new = copy.deepcopy(self)
        for dotted, value in changes.items():
            section, _, name = dotted.rpartition(".")
            target = getattr(new, section) if section else new
            if section not in ("", *SECTIONS) or name not in {f.name for f in fields(target)}:
                moved = MOVED.get(dotted)
                raise ConfigurationError(f"unknown config key {dotted!r}" + (f" (moved: it is {moved} now)" if moved
                                                                              else ""))
            setattr(target, name, copy.deepcopy(value))
        new.validate()
        return new

    def validate(self) -> None:
        """Check every value's type and range; raise :class:`DataFileError` naming the file and key.

        Also checks values set after loading (command-line overrides)."""
        where = self.source or "<config>"
        for section, obj in [("", self)] + [(s, getattr(self, s)) for s in SECTIONS]:
            if not isinstance(obj, SECTIONS.get(section, RunConfig)):
                raise DataFileError(where, f"[{section}] must be a table")
            for f in fields(obj):
                if (not section and (f.name in SECTIONS or f.name in TABLES)) or f.metadata.get("internal"):
                    continue
                _check_value(where, f"{section}.{f.name}" if section else f.name, f, getattr(obj, f.name))
        _check_cross(self, where)
        _check_tables(self, where)

    def check_design(self, design) -> None:
        """Check actuator ids and region keys against the seed design's actuators and route points.

        Raises:
            DataFileError: naming the file and the key that names no actuator or point.
        """
        where = self.source or "<config>"
        pams = {p.id: p for p in design.pams}
        unknown = [a for a in self.actuators if a not in pams]
        if unknown:
            raise DataFileError(where, f"actuators: unknown actuator id(s) {unknown}; the design {design.name!r} "
                                       f"has {sorted(pams)}")
        if self.unit_budget.max_units:
            ids = set(self.actuators or pams)
            fixed = 2 * sum(p.n_parallel for p in design.pams if p.id not in ids)
            if 2 * len(ids) + fixed > self.unit_budget.max_units:
                raise DataFileError(where, f"unit_budget.max_units: {self.unit_budget.max_units} PAM units cannot "
                                    f"hold one PAM per actuator on both sides: the {len(ids)} optimised actuators "
                                    f"need {2 * len(ids)} and the others keep {fixed}")
        odd = [a for a in self.limits.one_segment_actuators if a not in pams]
        if odd and tuple(self.limits.one_segment_actuators) != ONE_SEGMENT_ACTUATORS:   # the default fits the v2 seed
            raise DataFileError(where, f"limits.one_segment_actuators: unknown actuator id(s) {odd}; the design "
                                       f"{design.name!r} has {sorted(pams)}")
        for k in self.transmission:
            if int(k) not in pams:
                raise DataFileError(where, f"transmission.{k}: names no actuator of the design {design.name!r} "
                                           f"(ids {sorted(pams)})")
        for k in self.regions:
            aid, _, point = str(k).partition(".")
            if int(aid) not in pams:
                raise DataFileError(where, f"regions.{k}: names no actuator of the design {design.name!r} "
                                           f"(ids {sorted(pams)})")
            names = [p.name for p in pams[int(aid)].points]
            if point and point not in names:
                raise DataFileError(where, f"regions.{k}: actuator {aid} has no point {point!r} (points: {names})")

    def eyelet_specs(self) -> dict[int, list[dict]]:
        """The ``[eyelets]`` table as {actuator id: [{"body", "at", "gap"}, ...]} ("at" None: the segment's
        nearest approach to the bone)."""
        out = {}
        for k, v in self.eyelets.items():
            out[int(k)] = [{"body": e, "at": None, "gap": EYELET_GAP_M} if isinstance(e, str) else
                           {"body": e["body"], "at": e.get("at"), "gap": e.get("gap", EYELET_GAP_M)}
                           for e in (v if isinstance(v, list) else [v])]
        return out

    def apply_eyelets(self, design, model, bones=None) -> tuple[object, list[str]]:
        """The design with the ``[eyelets]`` table's eyelets put into the routes of the actuators the run
        optimises (``actuators``; all when empty: an eyelet changes the route's lengths, which only a fit
        makes good), with a log line per eyelet (:func:`pamkin.robot.eyelets.add_eyelet`). A route that already
        holds a point on the body (a warm start's eyelet, or the seed's own point) is left as it is. Entries of
        the default table that do not fit the design (no such actuator, no segment passing the body) are
        skipped; a table given in the config must fit.

        Args:
            design: Seed design.
            model: Human model (kinematic tree, default pose).
            bones: :class:`pamkin.human.bones.BoneSet` (default: the model's meshes, loaded when needed).

        Raises:
            DataFileError: naming the config file and the key, where a given entry does not fit.
        """
        default = self.eyelets == DEFAULT_EYELETS
        ids = {p.id for p in design.pams}
        lines: list[str] = []
        for aid, specs in self.eyelet_specs().items():
            if aid not in ids:
                if default:
                    continue
                raise DataFileError(self.source or "<config>", f"eyelets.{aid}: names no actuator of the design "
                                                               f"{design.name!r} (ids {sorted(ids)})")
            if self.actuators and aid not in self.actuators:
                continue                    # not optimised: its route (and lengths) stay the seed's
            for spec in specs:
                pam, body = design.pam(aid), spec["body"]
                if has_eyelet(pam, body):
                    lines.append(f"eyelets: actuator {aid} {pam.name}: its route already has a point on {body}")
                    continue
                if bones is None:
                    bones = BoneSet(model)
                try:
                    new = add_eyelet(pam, model, bones, body, gap=spec["gap"], at=spec["at"])
                except ConfigurationError as e:
                    if default:
                        continue
                    raise DataFileError(self.source or "<config>", f"eyelets.{aid}: {e}") from None
                e = next(p for p in new.points if p.name not in {q.name for q in pam.points})
                where = "nearest its bone" if spec["at"] is None else f"{spec['at']:g} along"
                lines.append(f"eyelets: actuator {aid} {pam.name}: {e.name} on {body} at "
                             f"({', '.join(f'{1e3 * c:.1f}' for c in e.location)}) mm, {1e3 * spec['gap']:g} mm "
                             f"off its bone (the seed segment's point {where})")
                design = design.replace_pam(new)
        return design, lines

    def apply_transmission(self, design):
        """The design with the ``[transmission]`` table's ratios put on its PAMs (others unchanged). A PAM whose
        ratio changes from k to k' keeps its strain at every route length
        (:func:`pamkin.robot.design.rescale_for_transmission`) — a start for the optimiser, which solves both again."""
        for k, v in self.transmission.items():
            p = design.pam(int(k))
            k0, k2 = p.transmission, int(v)
            if k2 != k0:
                rest, tendon = rescale_for_transmission(p.resting_length_m, p.tendon_length_m, k0, k2,
                                                        design.fitting_length_m)
                p = dataclasses.replace(p, transmission=k2, resting_length_m=rest, tendon_length_m=tendon)
            design = design.replace_pam(p)
        return design

    def mass_penalty(self, diameter_mm: int, n_parallel: int, resting_length: float, transmission: int = 1) -> float:
        """The objective's mass penalty of ``n_parallel`` PAMs of a diameter, resting length [m] and
        transmission, both sides: ``[weights] mass`` × their estimated mass [kg] (:func:`pamkin.robot.design.unit_mass`)."""
        return self.weights.mass * 2 * n_parallel * unit_mass(resting_length, diameter_mm, transmission)

    def one_segment_for(self, actuator: int) -> bool:
        """Whether actuator ``actuator`` is solved with the one-segment rows (``one_segment`` or listed)."""
        return bool(self.limits.one_segment or actuator in self.limits.one_segment_actuators)

    def region(self, actuator: int, point: str) -> list[float]:
        """Half-widths (x, y, z) [m] of a route point's box."""
        for k in (f"{actuator}.{point}", str(actuator)):
            if k in self.regions:
                v = self.regions[k]
                return [float(x) for x in v] if isinstance(v, list) else [float(v)] * 3
        return [self.limits.region_m] * 3


#: The earlier default (before the v2 ingredients were switched on): the 1-D/2-D fit of the built-in design,
#: capsule bone clearance, no unit budget. ``RunConfig().replace(FAST_FIT)``.
FAST_FIT: dict = {"design": "", "first_fit.multistart": 2, "first_fit.max_solve_seconds": 0.0, "samples.random": 0,
                  "weights.mass": 0.0, "limits.rated_force": False, "bone_rounds.enabled": False,
                  "unit_budget.max_units": 0, "limits.sensitivity_pct": 0.0, "mount.enabled": False,
                  "limits.one_segment_actuators": [], "rollers.enabled": False, "eyelets": {}}


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _kind(f) -> str:
    return str(f.type)


def _check_value(where: str, name: str, f, value) -> None:
    """One key's type and range (from its field's type and metadata)."""
    kind, meta = _kind(f), f.metadata

    def bad(msg: str) -> DataFileError:
        return DataFileError(where, f"{name}: {msg}")

    if kind == "int" and not _is_int(value):
        raise bad(f"must be an integer, got {value!r}")
    if kind == "float" and not _is_number(value):
        raise bad(f"must be a finite number, got {value!r}")
    if kind == "bool" and not isinstance(value, bool):
        raise bad(f"must be true or false, got {value!r}")
    if kind == "str" and not isinstance(value, str):
        raise bad(f"must be a string, got {value!r}")
    if kind == "list[int]" and not (isinstance(value, list) and all(_is_int(v) for v in value)):
        raise bad(f"must be a list of integers, e.g. [1, 2], got {value!r}")
    lo, hi = meta.get("lo"), meta.get("hi")
    if kind in ("int", "float") and ((lo is not None and value < lo) or (hi is not None and value > hi)):
        unit = f" {meta['unit']}" if meta.get("unit") else ""
        rng = (f"lie in [{lo:g}, {hi:g}]" if lo is not None and hi is not None else
               f"be >= {lo:g}" if lo is not None else f"be <= {hi:g}")
        raise bad(f"must {rng}{unit}, got {value!r}")
    if meta.get("choices") and value not in meta["choices"]:
        raise bad(f"must be one of {list(meta['choices'])}, got {value!r}")


def _check_cross(cfg: RunConfig, where: str) -> None:
    """Rules between keys."""
    def bad(k: str, msg: str) -> DataFileError:
        return DataFileError(where, f"{k}: {msg}")

    d = cfg.first_fit.diameters_mm
    if not d or any(x not in (10, 20, 40) for x in d) or len(set(d)) != len(d):
        raise bad("first_fit.diameters_mm", f"must be a non-empty subset of [10, 20, 40] [mm], got {d}")
    for k, ids in (("actuators", cfg.actuators), ("limits.one_segment_actuators", cfg.limits.one_segment_actuators)):
        if any(a < 1 for a in ids) or len(set(ids)) != len(ids):
            raise bad(k, f"must be distinct actuator ids >= 1, got {ids}")
    if cfg.force_model == "v0" and cfg.pressure_Pa != 620e3:
        raise bad("force_model", "'v0' is the thesis's 620 kPa table: pressure_Pa must be 620000")
    if cfg.weights.primary + cfg.weights.secondary <= 0:
        raise bad("weights", "primary and secondary must not both be 0 (nothing to fit)")
    for section in ("clearance", "rollers"):
        if getattr(cfg, section).enabled and not cfg.bone_rounds.enabled:
            raise bad(f"{section}.enabled", "needs bone_rounds.enabled = true (the stage works on the bone meshes)")


def _check_tables(cfg: RunConfig, where: str) -> None:
    """The per-actuator tables ``[regions]``, ``[eyelets]``, ``[transmission]``."""
    def bad(k: str, msg: str) -> DataFileError:
        return DataFileError(where, f"{k}: {msg}")

    for name in TABLES:
        if not isinstance(getattr(cfg, name), dict):
            raise bad(name, "must be a table")
    for k, v in cfg.regions.items():
        if not re.fullmatch(r"[0-9]+(\.[A-Za-z0-9_]+)?", str(k)):
            raise bad(f"regions.{k}", "keys are an actuator id (\"6\") or actuator.point (\"6.p2\")")
        vals = v if isinstance(v, list) else [v]
        if len(vals) not in (1, 3) or any(not _is_number(x) or x < 0 for x in vals) \
                or (isinstance(v, list) and len(vals) != 3):
            raise bad(f"regions.{k}", f"a non-negative number or 3 non-negative numbers [m], got {v!r}")
    for k, v in cfg.eyelets.items():
        if not re.fullmatch(r"[0-9]+", str(k)):
            raise bad(f"eyelets.{k}", "keys are actuator ids (\"19\")")
        items = v if isinstance(v, list) else [v]
        if not items:
            raise bad(f"eyelets.{k}", "a body name, a table {body, at, gap} or a list of those, got []")
        for e in items:
            if isinstance(e, str) and e:
                continue
            if not isinstance(e, dict) or not isinstance(e.get("body"), str) or not e["body"] \
                    or set(e) - {"body", "at", "gap"}:
                raise bad(f"eyelets.{k}", f"a body name (\"talus_r\"), a table {{body, at, gap}} or a list of "
                                          f"those, got {e!r}")
            if "at" in e and not (_is_number(e["at"]) and 0 < e["at"] < 1):
                raise bad(f"eyelets.{k}", f"'at' is a fraction of the segment within (0, 1), got {e['at']!r}")
            if "gap" in e and not (_is_number(e["gap"]) and 0 < e["gap"] <= 0.018):
                raise bad(f"eyelets.{k}", f"'gap' is a distance off the bone in (0, 0.018] m, got {e['gap']!r}")
    for k, v in cfg.transmission.items():
        if not re.fullmatch(r"[0-9]+", str(k)):
            raise bad(f"transmission.{k}", "keys are actuator ids (\"4\")")
        if isinstance(v, bool) or v not in TRANSMISSIONS:
            raise bad(f"transmission.{k}", f"must be one of {TRANSMISSIONS} (1: direct, k: a k:1 pulley block), "
                                           f"got {v!r}")


def load_config(path: str | Path | None) -> RunConfig:
    """Read a TOML run description (None: all defaults); every value is checked (:meth:`RunConfig.validate`).

    Raises:
        pamkin.errors.DataFileError: the file is missing or not TOML, or a key is unknown or out of range (the
            message names the file and the key).
    """
    if path is None:
        cfg = RunConfig()
        cfg.validate()
        return cfg
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataFileError(str(path), "file not found") from None
    except IsADirectoryError:
        raise DataFileError(str(path), "is a folder, not a TOML file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise DataFileError(str(path), f"not valid TOML: {e}") from None
    return config_from_dict(data, str(path))


def config_from_dict(data: dict, source: str) -> RunConfig:
    """A run description from its TOML form as a mapping (``source``: the file named in errors)."""
    cfg = RunConfig(source=source)
    top = {f.name for f in fields(RunConfig) if not f.metadata.get("internal")}
    for name, value in data.items():
        if name in SECTIONS:
            if not isinstance(value, dict):
                raise DataFileError(source, f"[{name}] must be a table")
            known = {f.name for f in fields(SECTIONS[name])}
            for k, v in value.items():
                if k not in known:
                    moved = MOVED.get(f"{name}.{k}")
                    raise DataFileError(source, f"unknown key {name}.{k}" + (f" (moved: it is {moved} now)" if moved
                                                else f"; [{name}] has {sorted(known)}"))
                setattr(getattr(cfg, name), k, copy.deepcopy(v))
        elif name in TABLES:
            if not isinstance(value, dict):
                raise DataFileError(source, f"[{name}] must be a table")
            setattr(cfg, name, copy.deepcopy(value))
        elif name in top:
            setattr(cfg, name, copy.deepcopy(value))
        else:
            moved = MOVED.get(name) or next((MOVED[f"{name}.{k}"] for k in (value if isinstance(value, dict) else {})
                                             if f"{name}.{k}" in MOVED), None)
            hint = f" (moved: it is {moved} now)" if moved else ""
            kind = "section" if isinstance(value, dict) else "key"
            raise DataFileError(source, f"unknown {kind} {name!r}{hint}; known: top-level "
                                        f"{sorted(top - set(SECTIONS) - set(TABLES))}, sections {sorted(SECTIONS)}, "
                                        f"tables {list(TABLES)}")
    cfg.validate()
    return cfg


def config_to_dict(cfg: RunConfig) -> dict:
    """The TOML form of a run description as a mapping (what :func:`config_from_dict` reads back)."""
    out: dict = {}
    for f in fields(RunConfig):
        if f.metadata.get("internal"):
            continue
        value = getattr(cfg, f.name)
        out[f.name] = dataclasses.asdict(value) if f.name in SECTIONS else copy.deepcopy(value)
    return out


def _default(f) -> Any:
    return f.default_factory() if f.default_factory is not MISSING else f.default


def _toml_text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, dict):
        return "{}" if not value else "(see the text)"
    return repr(value)


def _rows(cls) -> list[str]:
    out = []
    for f in fields(cls):
        if (cls is RunConfig and f.name in SECTIONS) or f.metadata.get("internal"):
            continue
        meta = f.metadata
        rng = ""
        if meta.get("choices"):
            rng = " / ".join(f"`{c}`" for c in meta["choices"])
        elif meta.get("lo") is not None or meta.get("hi") is not None:
            lo = "" if meta.get("lo") is None else f"{meta['lo']:g}"
            hi = "" if meta.get("hi") is None else f"{meta['hi']:g}"
            rng = f"{lo} .. {hi}".strip()
        kind = "table" if f.name in TABLES else _kind(f)
        doc = meta.get("doc", "").replace("|", "\\|")
        out.append(f"| `{f.name}` | {kind} | `{_toml_text(_default(f))}` | {rng} | {doc} |")
    return out


def config_reference_markdown() -> str:
    """The reference page of every configuration key (Markdown), generated from the fields of
    :class:`RunConfig` and its sections: key, type, default, allowed range and description."""
    head = ["| key | type | default | range | description |", "|---|---|---|---|---|"]
    out = ["Every key of a `pamkin optimize` TOML run description (generated from `pamkin.optimize.config`). Every "
           "key is optional; an unknown key or section, a wrong type or a value out of range stops the run before "
           "any solve with an error naming the file and the key (exit 2). Sections mirror "
           "`pamkin.optimize.config.RunConfig` one to one (`[mount] cost` is `cfg.mount.cost`).", "",
           "## Top level and per-actuator tables", "", *head, *_rows(RunConfig), ""]
    for name, cls in SECTIONS.items():
        out += [f"## [{name}]", "", (cls.__doc__ or "").split(":", 1)[-1].strip(), "", *head, *_rows(cls), ""]
    return "\n".join(out)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + "}"
    return repr(value)


def config_toml(cfg: RunConfig | None = None) -> str:
    """A run description as TOML text: every key with its value (default: the defaults) and its description
    as a comment — ``examples/optimize_v2.toml`` is this text of the defaults."""
    cfg = cfg or RunConfig()

    def block(obj) -> list[str]:
        out = []
        for f in fields(obj):
            if (obj is cfg and (f.name in SECTIONS or f.name in TABLES)) or f.metadata.get("internal"):
                continue
            out += [f"# {line}" for line in _wrap(f.metadata.get("doc", ""))]
            out.append(f"{f.name} = {_toml_value(getattr(obj, f.name))}")
        return out

    lines = block(cfg)
    for name in SECTIONS:
        lines += ["", f"[{name}]", *[f"# {line}" for line in _wrap((SECTIONS[name].__doc__ or '').split(':', 1)[-1].strip())],
                  *block(getattr(cfg, name))]
    for name in TABLES:
        table = getattr(cfg, name)
        lines += ["", f"[{name}]"] + [f'"{k}" = {_toml_value(v)}' for k, v in table.items()]
    return "\n".join(lines) + "\n"


def _wrap(text: str, width: int = 108) -> list[str]:
    words, out, line = text.split(), [], ""
    for w in words:
        if line and len(line) + 1 + len(w) > width:
            out.append(line)
            line = w
        else:
            line = f"{line} {w}".strip()
    return out + ([line] if line else [])


def config_changes(cfg: RunConfig, base: RunConfig | None = None) -> dict[str, Any]:
    """The keys where ``cfg`` differs from ``base`` (default: the defaults), dotted as in :meth:`RunConfig.replace`."""
    base = base or RunConfig()
    out: dict[str, Any] = {}
    for f in fields(RunConfig):
        if f.metadata.get("internal"):
            continue
        a, b = getattr(cfg, f.name), getattr(base, f.name)
        if f.name in SECTIONS:
            out.update({f"{f.name}.{g.name}": getattr(a, g.name) for g in fields(a)
                        if getattr(a, g.name) != getattr(b, g.name)})
        elif a != b:
            out[f.name] = a
    return out
