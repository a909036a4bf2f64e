"""Run description of an attachment-point optimisation (TOML).

Example (every key optional; these are the defaults). The keys marked (v2) are the ingredients of an
optimiser judged by ``pamkin audit`` (multi-joint training poses, the whole torque vector, Festo's rated
force, a mass penalty, the real bone meshes, a unit budget); the default run uses the measured set of
them (``pam_clearance`` stays off, ``one_segment`` is on only for ``one_segment_actuators``, and the
``mount`` stage puts the other PAMs on one segment where their fit allows, README "Optimiser v2"). :data:`FAST_FIT` holds the
earlier 1-D/2-D fit (``examples/optimize_fast.toml``, about 2.5 minutes)::

    design = "v2_seed"           # seed design file, run folder or keyword ("thesis", "split_gluteal", "v2_seed");
                                 # "" = the robot's design robot/data/thesis_design.yaml
    actuators = []               # actuator ids; [] = all
    warm_start = ""              # run folder whose design.yaml seeds the routes and sizes (its diameter and
                                 # parallel count are tried first; the full loop only where they fail; a PAM
                                 # whose warm start holds keeps its pulley-block ratio, and its route where
                                 # the continued bone rounds would end over a strain or force limit it keeps)
    pressure_Pa = 620000.0
    force_model = "v3"
    diameters_mm = [10, 20, 40]  # outer loop
    max_parallel = 3             # outer loop: 1..max_parallel PAMs on the route
    multistart = 1               # extra solves from perturbed seeds (kept if better) ...
    multistart_threshold = 0.001 # ... when the best objective is above this (NRMSE ~ 3 %)
    seed = 0                     # random seed of the perturbations
    workers = 2                  # processes (actuators are independent problems)
    max_iter = 400               # IPOPT iterations per solve
    max_solve_seconds = 12.0     # IPOPT CPU-time limit per solve [s] (0: none); a solve that hits it is
                                 # treated as failed (infeasible diameter / parallel count tries end sooner)

    [samples]
    primary = 25                 # 1-D sweep of the primary coordinate (others 0)
    secondary = 7                # per axis of each 2-D grid primary x secondary
    constraint = 5               # per axis of the full grid over primary + secondaries (strain limits)
    random = 30                  # (v2) multi-joint training poses per actuator (own random stream, never the audit's)
    gait = false                 # (v2) also train on the walking trial (between its frames; both legs, mirrored)

    [weights]
    primary = 1.0
    secondary = 0.5
    regularization = 0.001       # pull towards the seed route, per (region size)^2
    whole_vector = 1.0           # (v2) torque error about every coordinate crossed, on the training poses
    mass = 0.02                  # (v2) outer loop: objective penalty per kg of PAM (diameter, parallel count)

    [limits]
    region_m = 0.05              # half-width of every route point's box around its seed [m]
    min_point_distance_m = 0.01  # between successive route points
    bone_clearance = true        # route segments clear the bone-shaft capsules by the PAM radius (with bone_mesh: until its rounds)
    kmax_scale = 1.0             # contraction limit = kmax_scale * kmax(l0)
    pretension_scale = 1.0       # stretch limit = pretension_scale * Festo's limit
    fix_lengths = false          # keep the seed resting and tendon lengths (move attachment points only)
    move_moving_points = true    # offset points that move with a coordinate (the patella) within the region
    rated_force = true           # (v2) force per PAM <= Festo's rated force and contraction <= Festo's maximum (0.25)
    one_segment = false          # (v2) the PAM (+ fittings) fits on one straight segment of its route, as a
                                 #      constraint of every solve (slow, poor fits: mount below instead)
    one_segment_actuators = [13, 14]  # (v2) actuators solved with the one-segment rows all the same (the
                                 #      gastrocnemii: measured to keep their fit, README)
    mount = true                 # (v2) after the bone rounds, the route fixed: the PAM is put on one straight
    mount_cost = 0.1             #      segment (resting and tendon length re-solved, the tendon over the rest)
                                 #      where the root of the fit objective grows by at most mount_cost; where
                                 #      it narrowly cannot, bone rounds with the PAM on the segment and the points
                                 #      free; elsewhere the run names the PAM and why (optimize.mount)
    mount_failing = true         # (v2, with mount) a PAM whose fit already fails both of the audit's fit limits
                                 #      (primary NRMSE > 0.15 and worst error > 0.25 on the optimiser's own
                                 #      validation poses, optimize.validation) goes on one segment at any fit cost
                                 #      that keeps every limit: buildability first where no fit count is at stake
    mount_passing = true         # (v2, with mount) a PAM that on one segment (or on a pulley block) still passes
                                 #      both audit fit limits on the validation poses, less 0.02, goes on it at any
                                 #      fit cost that keeps every limit: no fit count is lost
    mount_blocks = true          # (v2, with mount) a PAM out of reach of one segment at 1:1, or infeasible there, is tried on a 2:1
                                 #      pulley block on the same route, then 3:1 (same count, same or larger diameter;
                                 #      the same mount_cost rule; optimize.mount.mount_block)
    sensitivity_pct = 9.0        # (v2) a 1 mm error of a fixed attachment point changes the primary torque
                                 # on its 1-D sweep by at most this % of the human peak (audit: 10); 0: off
    bone_mesh = true             # (v2) attachment points on their bone (3..18 mm out), segments clear of the
                                 #      real bone meshes at random, sweep and gait poses (optimize.bone_cuts)
    bone_rounds = 10             # (v2) largest number of re-linearisation rounds of the bone-mesh rows (a route
                                 #      clear of bone still gaining >= 5 % a round gets up to 6 more)
    bone_seed_start = true       # (v2) the bone-mesh rounds also start from the seed route (points moved onto
                                 #      their bone's 3..18 mm band); the better of the two results is kept
    bracket_fit = false          # (v2, with bone_mesh) the fit itself keeps attachment points 3..18 mm out of
                                 #      their bone (smooth bone-distance splines, optimize.bracket)
    pam_clearance = false        # (v2, with bone_mesh) second pass: routes that hit another PAM's body are
                                 #      solved again with the first-pass bodies as obstacles
    rollers = false              # (v2, with bone_mesh) last stage: an actuator failing an audit fit limit on the
                                 #      validation poses gets rollers (cable guides on bone, pamkin.robot.rollers) where
                                 #      its fit without the bone rows goes into bone, long enough that the cable
                                 #      never slips off an end, kept where they lower its validation error and the
                                 #      route is clear (optimize.rollers); a warm re-run does not try again what its
                                 #      warm start's run tried without a gain
    detours = true               # (v2, with bone_mesh) a route segment between two points of one bone (a constant
                                 #      length) too short to hold the PAM body is left out of that bone's rows and
                                 #      afterwards carried round it by via points (pamkin.robot.detour; the added length
                                 #      on the tendon: every torque unchanged), then checked against every bone
    max_units = 60               # (v2) PAM units of the whole robot (both sides; 0: no limit): the diameter
                                 #      and parallel count of every actuator are chosen together, before the
                                 #      bone-mesh rounds, for the least summed score within this budget
    walking_min = 0.9            # (v2, with max_units) after the bone rounds: while the pressure plan of the
                                 #      walking trial, sampled between its frames, is feasible on less than
                                 #      this fraction, actuators at the pressure limit get another diameter /
                                 #      parallel count within the budget, solved again (0: off;
                                 #      optimize.stages.walking)
    resize_above = 1.0           # (v2, with bone_mesh and max_units) after the bone rounds: an actuator whose fit
                                 #      objective is still above this gets its other diameters (same parallel
                                 #      count: the unit budget holds) through the bone rounds and the one-segment
                                 #      stage too, where their fit before the rounds scored less; the lower
                                 #      score after the rounds is kept (0: off)
    block_refit_above = 0.5      # (v2, with mount_blocks and max_units) in the re-sizing: an actuator the one-segment
                                 #      stage put on a pulley block, whose fit objective is above this (and not above
                                 #      resize_above), is solved again with a 3:1 block throughout (same diameter and
                                 #      count: first phase, bone rounds, one-segment stage); the lower score kept,
                                 #      never a PAM off its straight segment (0: off; optimize.stages.resize.block_tasks)
    reallocate = true            # (v2, with bone_mesh and max_units) after the re-sizing: a PAM unit of an actuator
                                 #      with several that fails both audit fit limits on the validation poses
                                 #      (its units buy no pass) moves to the failing actuator nearest to passing
                                 #      (at most 2 tried per unit, one more unit each: bone rounds, one-segment stage),
                                 #      where that one then passes both within 0.02 and the robot's mass stays
                                 #      within max_mass_kg; the unit budget holds (optimize.stages.reallocate)
    resize_on = "objective"      # (v2) what the re-sizing compares: "objective" (score: fit objective + mass
                                 #      penalty) or "validation" (primary NRMSE + worst error on 400 poses like
                                 #      the audit's from the optimiser's own stream, optimize.validation)
    max_mass_kg = 22.0           # (v2, with mount_blocks) the robot's estimated mass (both sides, the audit's:
                                 #      assumed Festo weights and block masses): where the one-segment stage's
                                 #      pulley blocks take it above this, blocks come off again, the least
                                 #      score lost per kg first (0: off)
    pam_ends = true              # (v2, with mount) where every PAM on one segment is anchored: the segment its body
                                 #      sits on (the design's pam_on, where it fits on more than one) and its end
                                 #      (pam_at; the tendon on the other side, where the route has a fixed length on
                                 #      both sides): the place that leaves the fewest intersecting PAM pairs at the
                                 #      run's own poses (optimize.pam_clearance.choose_ends)

    [regions]                    # per actuator or per point: "6" = 0.08, "6.p2" = [0.02, 0.02, 0.0]
    [transmission]               # per actuator: "4" = 2 puts a 2:1 pulley block on its PAM (pamkin.robot.design:
                                 # the route moves twice the PAM's stroke at half its force); default: the
                                 # seed design's (1: direct)
    [eyelets]                    # per actuator: "19" = "talus_r", or {body = "talus_r", at = 0.5, gap = 0.008},
                                 # or a list of those: an eyelet (a via point on a bracket of that body) in
                                 # the seed route (of an optimised actuator) where it passes the body between
                                 # its segment's ends' bodies,
                                 # before the fit (pamkin.robot.eyelets.add_eyelet: where the segment comes nearest
                                 # the bone at the default pose, or a fraction "at" along it; "gap" [m] off
                                 # the bone, default 0.008); the optimiser then moves it like any point.
                                 # Default: soleus (12) nearest, peroneus tertius (19), extensor digitorum
                                 # (22) and hallucis longus (23) half way, all on the talus; a table given
                                 # replaces the default ([eyelets] alone: none); a route already holding a
                                 # point on that body (a warm start's eyelet) is left as it is
"""

from __future__ import annotations

import copy
import math
import re
import tomllib
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path

from pamkin.errors import ConfigurationError, DataFileError
from pamkin.human.bones import BoneSet
from pamkin.robot.design import TRANSMISSIONS, rescale_for_transmission, unit_mass
from pamkin.robot.eyelets import EYELET_GAP_M, add_eyelet, has_eyelet

_SECTIONS = {
    "samples": {"primary": "n_primary", "secondary": "n_secondary", "constraint": "n_constraint",
                "random": "n_random", "gait": "gait_samples"},
    "weights": {"primary": "weight_primary", "secondary": "weight_secondary",
                "regularization": "regularization", "whole_vector": "weight_whole_vector", "mass": "weight_mass"},
    "limits": {"region_m": "region_m", "min_point_distance_m": "min_point_distance_m",
               "bone_clearance": "bone_clearance", "kmax_scale": "kmax_scale",
               "pretension_scale": "pretension_scale", "fix_lengths": "fix_lengths",
               "move_moving_points": "move_moving_points", "rated_force": "rated_force",
               "one_segment": "one_segment", "one_segment_actuators": "one_segment_actuators", "mount": "mount", "mount_cost": "mount_cost", "mount_failing": "mount_failing", "mount_passing": "mount_passing", "mount_blocks": "mount_blocks", "sensitivity_pct": "sensitivity_pct", "bone_mesh": "bone_mesh", "bone_rounds": "bone_rounds",
               "bone_seed_start": "bone_seed_start", "bracket_fit": "bracket_fit",
               "max_units": "max_units", "walking_min": "walking_min",
               "pam_clearance": "pam_clearance", "rollers": "rollers", "detours": "detours", "resize_above": "resize_above", "block_refit_above": "block_refit_above", "reallocate": "reallocate",
               "max_mass_kg": "max_mass_kg", "pam_ends": "pam_ends", "resize_on": "resize_on"},
}


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


#: The earlier default (before the v2 ingredients were switched on): the 1-D/2-D fit of the robot's
#: current design, capsule bone clearance, no unit budget. ``RunConfig(**FAST_FIT)``.
FAST_FIT: dict = {"design": "", "multistart": 2, "max_solve_seconds": 0.0, "n_random": 0, "weight_mass": 0.0,
                  "rated_force": False, "bone_mesh": False, "max_units": 0, "sensitivity_pct": 0.0,
                  "mount": False, "one_segment_actuators": [], "rollers": False, "eyelets": {}}

#: Actuators of the v2 seed solved with the one-segment rows by default (``one_segment_actuators``).
ONE_SEGMENT_ACTUATORS = (13, 14)

#: Default eyelets (``[eyelets]``): the tibia-to-calcaneus segment of soleus, peroneus tertius and the long toe
#: extensors guided on the talus (measured: README "Eyelets"). Entries naming an actuator the seed design
#: lacks, or whose route passes no such segment, are skipped (they fit the v2 seed and the thesis design).
DEFAULT_EYELETS: dict = {"12": ["talus_r"], "19": [{"body": "talus_r", "at": 0.5}],
                         "22": [{"body": "talus_r", "at": 0.5}], "23": [{"body": "talus_r", "at": 0.5}]}


@dataclass
class RunConfig:
    """An optimisation run (see the module docstring for the TOML form and defaults)."""

    design: str = "v2_seed"
    actuators: list[int] = field(default_factory=list)
    warm_start: str = ""
    pressure_Pa: float = 620e3
    force_model: str = "v3"
    diameters_mm: list[int] = field(default_factory=lambda: [10, 20, 40])
    max_parallel: int = 3
    multistart: int = 1
    multistart_threshold: float = 1e-3
    seed: int = 0
    workers: int = 2
    max_iter: int = 400
    max_solve_seconds: float = 12.0
    n_primary: int = 25
    n_secondary: int = 7
    n_constraint: int = 5
    n_random: int = 30
    gait_samples: bool = False
    weight_primary: float = 1.0
    weight_secondary: float = 0.5
    regularization: float = 1e-3
    weight_whole_vector: float = 1.0
    weight_mass: float = 0.02
    region_m: float = 0.05
    min_point_distance_m: float = 0.01
    bone_clearance: bool = True
    kmax_scale: float = 1.0
    pretension_scale: float = 1.0
    fix_lengths: bool = False
    move_moving_points: bool = True
    rated_force: bool = True
    one_segment: bool = False
    one_segment_actuators: list[int] = field(default_factory=lambda: list(ONE_SEGMENT_ACTUATORS))
    mount: bool = True
    mount_cost: float = 0.1
    mount_failing: bool = True
    mount_passing: bool = True
    mount_blocks: bool = True
    sensitivity_pct: float = 9.0
    bone_mesh: bool = True
    bone_rounds: int = 10
    bone_seed_start: bool = True
    bracket_fit: bool = False
    pam_clearance: bool = False
    rollers: bool = False
    detours: bool = True
    max_units: int = 60
    walking_min: float = 0.9
    resize_above: float = 1.0
    block_refit_above: float = 0.5
    reallocate: bool = True
    max_mass_kg: float = 22.0
    pam_ends: bool = True
    resize_on: str = "objective"
    regions: dict[str, float | list[float]] = field(default_factory=dict)
    transmission: dict[str, int] = field(default_factory=dict)
    eyelets: dict = field(default_factory=lambda: copy.deepcopy(DEFAULT_EYELETS))
    source: str = ""

    def validate(self) -> None:
        """Check every value's type and range; raise :class:`DataFileError` naming the file and key.

        Also checks values set after loading (command-line overrides).
        """
        def bad(key: str, msg: str) -> DataFileError:
            return DataFileError(self.source or "<config>", f"{key}: {msg}")

        for f in fields(self):
            if f.name in ("source", "regions", "transmission", "eyelets"):
                continue
            key, value = _KEYS[f.name], getattr(self, f.name)
            kind = _KINDS[f.name]
            if kind == "int" and not _is_int(value):
                raise bad(key, f"must be an integer, got {value!r}")
            if kind == "float" and not _is_number(value):
                raise bad(key, f"must be a finite number, got {value!r}")
            if kind == "bool" and not isinstance(value, bool):
                raise bad(key, f"must be true or false, got {value!r}")
            if kind == "str" and not isinstance(value, str):
                raise bad(key, f"must be a string, got {value!r}")
            if kind == "list[int]" and not (isinstance(value, list) and all(_is_int(v) for v in value)):
                raise bad(key, f"must be a list of integers, e.g. [1, 2], got {value!r}")
        if not self.diameters_mm or any(d not in (10, 20, 40) for d in self.diameters_mm) \
                or len(set(self.diameters_mm)) != len(self.diameters_mm):
            raise bad("diameters_mm", f"must be a non-empty subset of [10, 20, 40] [mm], got {self.diameters_mm}")
        if any(a < 1 for a in self.actuators) or len(set(self.actuators)) != len(self.actuators):
            raise bad("actuators", f"must be distinct actuator ids >= 1, got {self.actuators}")
        if any(a < 1 for a in self.one_segment_actuators) \
                or len(set(self.one_segment_actuators)) != len(self.one_segment_actuators):
            raise bad("limits.one_segment_actuators", f"must be distinct actuator ids >= 1, got "
                                                      f"{self.one_segment_actuators}")
        if not 1e5 <= self.pressure_Pa <= 8e5:
            raise bad("pressure_Pa", f"must lie in [100000, 800000] Pa (e.g. 620000 for 6.2 bar), got "
                                     f"{self.pressure_Pa:g}")
        if self.force_model not in ("v3", "v0"):
            raise bad("force_model", f"must be 'v3' (the lab's measured model) or 'v0' (the thesis table), got "
                                     f"{self.force_model!r}")
        if self.resize_on not in ("objective", "validation"):
            raise bad("limits.resize_on", f"must be 'objective' or 'validation', got {self.resize_on!r}")
        if self.force_model == "v0" and self.pressure_Pa != 620e3:
            raise bad("force_model", "'v0' is the thesis's 620 kPa table: pressure_Pa must be 620000")
        if not 1 <= self.max_parallel <= 3:
            raise bad("max_parallel", f"must be 1, 2 or 3, got {self.max_parallel}")
        for name in ("n_primary", "n_secondary", "n_constraint"):
            if not 2 <= getattr(self, name) <= 201:
                raise bad(_KEYS[name], f"must be >= 2 and <= 201 samples, got {getattr(self, name)}")
        for name in ("multistart", "seed", "multistart_threshold", "weight_primary", "weight_secondary",
                     "regularization", "region_m", "min_point_distance_m", "pretension_scale",
                     "weight_whole_vector", "weight_mass", "n_random", "max_solve_seconds", "sensitivity_pct",
                     "mount_cost", "resize_above", "block_refit_above", "max_mass_kg"):
            if getattr(self, name) < 0:
                raise bad(_KEYS[name], f"must be >= 0, got {getattr(self, name)}")
        if self.weight_primary + self.weight_secondary <= 0:
            raise bad("weights", "primary and secondary must not both be 0 (nothing to fit)")
        if not 0 < self.kmax_scale <= 1:
            raise bad("limits.kmax_scale", f"must lie in (0, 1], got {self.kmax_scale}")
        if self.pretension_scale > 1:
            raise bad("limits.pretension_scale", f"must lie in [0, 1], got {self.pretension_scale}")
        if self.workers < 1:
            raise bad("workers", f"must be >= 1, got {self.workers}")
        if self.pam_clearance and not self.bone_mesh:
            raise bad("limits.pam_clearance", "needs limits.bone_mesh = true (the PAM-PAM pass reuses its rounds)")
        if self.rollers and not self.bone_mesh:
            raise bad("limits.rollers", "needs limits.bone_mesh = true (rollers are placed and checked on the bone meshes)")
        if self.max_units < 0:
            raise bad("limits.max_units", f"must be >= 0 (0: no limit), got {self.max_units}")
        if not 0 <= self.walking_min <= 1:
            raise bad("limits.walking_min", f"must lie in [0, 1] (a fraction of the samples; 0: off), got "
                                            f"{self.walking_min}")
        if not 1 <= self.bone_rounds <= 20:
            raise bad("limits.bone_rounds", f"must lie in [1, 20], got {self.bone_rounds}")
        if self.max_iter < 1:
            raise bad("max_iter", f"must be >= 1, got {self.max_iter}")
        if not isinstance(self.regions, dict):
            raise bad("regions", "must be a table")
        for key, v in self.regions.items():
            if not re.fullmatch(r"[0-9]+(\.[A-Za-z0-9_]+)?", str(key)):
                raise bad(f"regions.{key}", "keys are an actuator id (\"6\") or actuator.point (\"6.p2\")")
            vals = v if isinstance(v, list) else [v]
            if len(vals) not in (1, 3) or any(not _is_number(x) or x < 0 for x in vals) \
                    or (isinstance(v, list) and len(vals) != 3):
                raise bad(f"regions.{key}", f"a non-negative number or 3 non-negative numbers [m], got {v!r}")
        if not isinstance(self.eyelets, dict):
            raise bad("eyelets", "must be a table")
        for key, v in self.eyelets.items():
            if not re.fullmatch(r"[0-9]+", str(key)):
                raise bad(f"eyelets.{key}", "keys are actuator ids (\"19\")")
            items = v if isinstance(v, list) else [v]
            if not items:
                raise bad(f"eyelets.{key}", "a body name, a table {body, at, gap} or a list of those, got []")
            for e in items:
                if isinstance(e, str) and e:
                    continue
                if not isinstance(e, dict) or not isinstance(e.get("body"), str) or not e["body"] \
                        or set(e) - {"body", "at", "gap"}:
                    raise bad(f"eyelets.{key}", f"a body name (\"talus_r\"), a table {{body, at, gap}} or a list "
                                                f"of those, got {e!r}")
                if "at" in e and not (_is_number(e["at"]) and 0 < e["at"] < 1):
                    raise bad(f"eyelets.{key}", f"'at' is a fraction of the segment within (0, 1), got {e['at']!r}")
                if "gap" in e and not (_is_number(e["gap"]) and 0 < e["gap"] <= 0.018):
                    raise bad(f"eyelets.{key}", f"'gap' is a distance off the bone in (0, 0.018] m, got {e['gap']!r}")
        if not isinstance(self.transmission, dict):
            raise bad("transmission", "must be a table")
        for key, v in self.transmission.items():
            if not re.fullmatch(r"[0-9]+", str(key)):
                raise bad(f"transmission.{key}", "keys are actuator ids (\"4\")")
            if isinstance(v, bool) or v not in TRANSMISSIONS:
                raise bad(f"transmission.{key}", f"must be one of {TRANSMISSIONS} (1: direct, k: a k:1 pulley "
                                                 f"block), got {v!r}")

    def check_design(self, design) -> None:
        """Check actuator ids and region keys against the seed design's actuators and route points.

        Raises:
            DataFileError: naming the file and the key that names no actuator or point.
        """
        pams = {p.id: p for p in design.pams}
        unknown = [a for a in self.actuators if a not in pams]
        if unknown:
            raise DataFileError(self.source or "<config>", f"actuators: unknown actuator id(s) {unknown}; the "
                                                           f"design {design.name!r} has {sorted(pams)}")
        if self.max_units:
            ids = set(self.actuators or pams)
            fixed = 2 * sum(p.n_parallel for p in design.pams if p.id not in ids)
            if 2 * len(ids) + fixed > self.max_units:
                raise DataFileError(self.source or "<config>", f"limits.max_units: {self.max_units} PAM units "
                                    f"cannot hold one PAM per actuator on both sides: the {len(ids)} optimised "
                                    f"actuators need {2 * len(ids)} and the others keep {fixed}")
        odd = [a for a in self.one_segment_actuators if a not in pams]
        if odd and tuple(self.one_segment_actuators) != ONE_SEGMENT_ACTUATORS:   # the default list fits the v2 seed
            raise DataFileError(self.source or "<config>", f"limits.one_segment_actuators: unknown actuator id(s) "
                                                           f"{odd}; the design {design.name!r} has {sorted(pams)}")
        for key in self.transmission:
            if int(key) not in pams:
                raise DataFileError(self.source or "<config>", f"transmission.{key}: names no actuator of the "
                                                               f"design {design.name!r} (ids {sorted(pams)})")
        for key in self.regions:
            aid, _, point = str(key).partition(".")
            if int(aid) not in pams:
                raise DataFileError(self.source or "<config>", f"regions.{key}: names no actuator of the design "
                                                               f"{design.name!r} (ids {sorted(pams)})")
            names = [p.name for p in pams[int(aid)].points]
            if point and point not in names:
                raise DataFileError(self.source or "<config>", f"regions.{key}: actuator {aid} has no point "
                                                               f"{point!r} (points: {names})")

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
        import dataclasses  # noqa: PLC0415


        for key, v in self.transmission.items():
            p = design.pam(int(key))
            k, k2 = p.transmission, int(v)
            if k2 != k:
                rest, tendon = rescale_for_transmission(p.resting_length_m, p.tendon_length_m, k, k2,
                                                        design.fitting_length_m)
                p = dataclasses.replace(p, transmission=k2, resting_length_m=rest, tendon_length_m=tendon)
            design = design.replace_pam(p)
        return design

    def mass_penalty(self, diameter_mm: int, n_parallel: int, resting_length: float, transmission: int = 1) -> float:
        """The objective's mass penalty of ``n_parallel`` PAMs of a diameter, resting length [m] and
        transmission, both sides: ``weight_mass`` × their estimated mass [kg] (:func:`pamkin.robot.design.unit_mass`)."""

        return self.weight_mass * 2 * n_parallel * unit_mass(resting_length, diameter_mm, transmission)

    def one_segment_for(self, actuator: int) -> bool:
        """Whether actuator ``actuator`` is solved with the one-segment rows (``one_segment`` or listed)."""
        return bool(self.one_segment or actuator in self.one_segment_actuators)

    def region(self, actuator: int, point: str) -> list[float]:
        """Half-widths (x, y, z) [m] of a route point's box."""
        for key in (f"{actuator}.{point}", str(actuator)):
            if key in self.regions:
                v = self.regions[key]
                return [float(x) for x in v] if isinstance(v, list) else [float(v)] * 3
        return [self.region_m] * 3


#: TOML key of every field, as an error names it (``weights.primary``, ``pressure_Pa``).
_KEYS = {attr: f"{sec}.{key}" for sec, keys in _SECTIONS.items() for key, attr in keys.items()}
#: Expected type of every field.
_KINDS: dict[str, str] = {}
for _f in fields(RunConfig):
    _KEYS.setdefault(_f.name, _f.name)
    _KINDS[_f.name] = {"str": "str", "int": "int", "float": "float", "bool": "bool",
                       "list[int]": "list[int]"}.get(str(_f.type), "other")


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
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise DataFileError(str(path), "file not found") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise DataFileError(str(path), f"not valid TOML: {e}") from None
    return config_from_dict(data, str(path))


def config_from_dict(data: dict, source: str) -> RunConfig:
    """A run description from its TOML form as a mapping (``source``: the file named in errors)."""
    kwargs: dict = {}
    top = {f.name for f in fields(RunConfig)} - {"source"} - {n for s in _SECTIONS.values() for n in s.values()}
    for key, value in data.items():
        if key in _SECTIONS:
            if not isinstance(value, dict):
                raise DataFileError(source, f"[{key}] must be a table")
            for k, v in value.items():
                if k not in _SECTIONS[key]:
                    raise DataFileError(source, f"unknown key {key}.{k}; known: {sorted(_SECTIONS[key])}")
                kwargs[_SECTIONS[key][k]] = v
        elif key in ("regions", "transmission", "eyelets"):
            if not isinstance(value, dict):
                raise DataFileError(source, f"[{key}] must be a table")
            kwargs[key] = dict(value)
        elif key in top:
            kwargs[key] = value
        else:
            raise DataFileError(source, f"unknown key {key!r}; known: {sorted(top | set(_SECTIONS))}")
    try:
        cfg = RunConfig(**kwargs, source=source)
    except TypeError as e:
        raise DataFileError(source, str(e)) from None
    cfg.validate()
    return cfg


def config_to_dict(cfg: RunConfig) -> dict:
    """The TOML form of a run description as a mapping (what :func:`config_from_dict` reads back)."""
    out: dict = {}
    by_field = {f: (sec, key) for sec, keys in _SECTIONS.items() for key, f in keys.items()}
    for f in fields(RunConfig):
        if f.name == "source":
            continue
        value = copy.deepcopy(getattr(cfg, f.name))
        if f.name in by_field:
            sec, key = by_field[f.name]
            out.setdefault(sec, {})[key] = value
        else:
            out[f.name] = value
    return out


def _default_text(f) -> str:
    value = f.default_factory() if f.default_factory is not MISSING else f.default  # type: ignore[misc]
    return repr(value).replace("'", '"').replace("True", "true").replace("False", "false")


def config_reference_markdown() -> str:
    """The reference page of every configuration key (Markdown): section, key, type, default and description,
    read from this module (the TOML example of its docstring and :class:`RunConfig`'s fields)."""
    doc = _key_docs()
    by_field = {f: (sec, key) for sec, keys in _SECTIONS.items() for key, f in keys.items()}
    rows: dict[str, list[str]] = {}
    for f in fields(RunConfig):
        if f.name == "source":
            continue
        sec, key = by_field.get(f.name, ("", f.name))
        if f.name in ("regions", "transmission", "eyelets"):
            sec, key = f.name, "(table)"
        text = doc.get((sec, key), "").replace("|", "\\|")
        kind = _KINDS.get(f.name, "table")
        rows.setdefault(sec, []).append(f"| `{key}` | {kind} | `{_default_text(f)}` | {text} |")
    out = ["Every key of a `pamkin optimize` TOML run description, by section (generated from "
           "`pamkin.optimize.config`). Every key is optional; an unknown key or section, a wrong type or a value "
           "out of range stops the run before any solve with an error naming the file and the key (exit 2).", ""]
    for sec in sorted(rows, key=lambda s: (s != "", s)):
        out += [f"## {'Top level' if not sec else '[' + sec + ']'}", "", "| key | type | default | description |",
                "|---|---|---|---|", *rows[sec], ""]
    return "\n".join(out)


def _key_docs() -> dict[tuple[str, str], str]:
    """(section, key) -> the description of the key in the module docstring's TOML example."""
    out: dict[tuple[str, str], str] = {}
    section, last = "", None
    for line in (__doc__ or "").splitlines():
        text = line.strip()
        m = re.match(r"^\[(\w+)\]\s*(#\s*(.*))?$", text)
        if m:
            section, last = m.group(1), None
            if m.group(3):
                out[(section, "(table)")] = m.group(3)
                last = (section, "(table)")
            continue
        m = re.match(r"^(\w+)\s*=\s*[^#]*(#\s*(.*))?$", text)
        if m and line.startswith("    ") and not line.startswith("     "):
            last = (section, m.group(1))
            out[last] = (m.group(3) or "").strip()
        elif text.startswith("#") and last is not None:
            out[last] = (out[last] + " " + text.lstrip("# ").strip()).strip()
    return out
