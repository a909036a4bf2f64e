"""Run description of an attachment-point optimisation (TOML).

Example (every key optional; these are the defaults)::

    design = ""                  # design file to start from; "" = built-in robot/data/pam_biped.yaml
    actuators = []               # actuator ids; [] = all
    warm_start = ""              # run folder whose design.yaml seeds the routes
    pressure_Pa = 620000.0
    force_model = "v3"
    diameters_mm = [10, 20, 40]  # outer loop
    max_parallel = 3             # outer loop: 1..max_parallel PAMs on the route
    multistart = 2               # extra solves from perturbed seeds (kept if better) ...
    multistart_threshold = 0.001 # ... when the best objective is above this (NRMSE ~ 3 %)
    seed = 0                     # random seed of the perturbations
    workers = 2                  # processes (actuators are independent problems)
    max_iter = 400               # IPOPT iterations per solve

    [samples]
    primary = 25                 # 1-D sweep of the primary coordinate (others 0)
    secondary = 7                # per axis of each 2-D grid primary x secondary
    constraint = 5               # per axis of the full grid over primary + secondaries (strain limits)

    [weights]
    primary = 1.0
    secondary = 0.5
    regularization = 0.001       # pull towards the seed route, per (region size)^2

    [limits]
    region_m = 0.05              # half-width of every route point's box around its seed [m]
    min_point_distance_m = 0.01  # between successive route points
    bone_clearance = true        # route segments clear the bone-shaft capsules by the PAM radius
    kmax_scale = 1.0             # contraction limit = kmax_scale * kmax(l0)
    pretension_scale = 1.0       # stretch limit = pretension_scale * Festo's limit
    fix_lengths = false          # keep the seed resting and tendon lengths (move attachment points only)
    move_moving_points = true    # offset points that move with a coordinate (the patella) within the region

    [regions]                    # per actuator or per point: "6" = 0.08, "6.p2" = [0.02, 0.02, 0.0]
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path

from pamkin.errors import DataFileError

_SECTIONS = {
    "samples": {"primary": "n_primary", "secondary": "n_secondary", "constraint": "n_constraint"},
    "weights": {"primary": "weight_primary", "secondary": "weight_secondary",
                "regularization": "regularization"},
    "limits": {"region_m": "region_m", "min_point_distance_m": "min_point_distance_m",
               "bone_clearance": "bone_clearance", "kmax_scale": "kmax_scale",
               "pretension_scale": "pretension_scale", "fix_lengths": "fix_lengths",
               "move_moving_points": "move_moving_points"},
}


@dataclass
class RunConfig:
    """An optimisation run (see the module docstring for the TOML form and defaults)."""

    design: str = ""
    actuators: list[int] = field(default_factory=list)
    warm_start: str = ""
    pressure_Pa: float = 620e3
    force_model: str = "v3"
    diameters_mm: list[int] = field(default_factory=lambda: [10, 20, 40])
    max_parallel: int = 3
    multistart: int = 2
    multistart_threshold: float = 1e-3
    seed: int = 0
    workers: int = 2
    max_iter: int = 400
    n_primary: int = 25
    n_secondary: int = 7
    n_constraint: int = 5
    weight_primary: float = 1.0
    weight_secondary: float = 0.5
    regularization: float = 1e-3
    region_m: float = 0.05
    min_point_distance_m: float = 0.01
    bone_clearance: bool = True
    kmax_scale: float = 1.0
    pretension_scale: float = 1.0
    fix_lengths: bool = False
    move_moving_points: bool = True
    regions: dict[str, float | list[float]] = field(default_factory=dict)
    source: str = ""

    def validate(self) -> None:
        """Raise :class:`DataFileError` naming the bad key."""
        def bad(msg: str) -> DataFileError:
            return DataFileError(self.source or "<config>", msg)
        if any(d not in (10, 20, 40) for d in self.diameters_mm) or not self.diameters_mm:
            raise bad(f"diameters_mm must be a non-empty subset of [10, 20, 40], got {self.diameters_mm}")
        if not 1 <= self.max_parallel <= 3:
            raise bad("max_parallel must be 1, 2 or 3")
        for name in ("n_primary", "n_secondary", "n_constraint"):
            if getattr(self, name) < 2:
                raise bad(f"samples: {name.removeprefix('n_')} must be >= 2")
        if self.pressure_Pa <= 0:
            raise bad("pressure_Pa must be positive")
        if self.region_m < 0 or self.min_point_distance_m < 0:
            raise bad("limits: region_m and min_point_distance_m must be >= 0")
        if self.kmax_scale <= 0 or self.pretension_scale < 0:
            raise bad("limits: kmax_scale must be > 0 and pretension_scale >= 0")
        if self.workers < 1 or self.multistart < 0 or self.max_iter < 1:
            raise bad("workers >= 1, multistart >= 0, max_iter >= 1")
        for key, v in self.regions.items():
            vals = v if isinstance(v, list) else [v]
            if len(vals) not in (1, 3) or any((not isinstance(x, int | float)) or x < 0 for x in vals):
                raise bad(f"regions.{key}: a non-negative number or 3 numbers [m]")

    def region(self, actuator: int, point: str) -> list[float]:
        """Half-widths (x, y, z) [m] of a route point's box."""
        for key in (f"{actuator}.{point}", str(actuator)):
            if key in self.regions:
                v = self.regions[key]
                return [float(x) for x in v] if isinstance(v, list) else [float(v)] * 3
        return [self.region_m] * 3


def load_config(path: str | Path | None) -> RunConfig:
    """Read a TOML run description (None: all defaults)."""
    if path is None:
        cfg = RunConfig()
        cfg.validate()
        return cfg
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise DataFileError(str(path), "file not found") from None
    except tomllib.TOMLDecodeError as e:
        raise DataFileError(str(path), f"not valid TOML: {e}") from None
    kwargs: dict = {}
    top = {f.name for f in fields(RunConfig)} - {"source"} - {n for s in _SECTIONS.values() for n in s.values()}
    for key, value in data.items():
        if key in _SECTIONS:
            if not isinstance(value, dict):
                raise DataFileError(str(path), f"[{key}] must be a table")
            for k, v in value.items():
                if k not in _SECTIONS[key]:
                    raise DataFileError(str(path), f"unknown key {key}.{k}; known: {sorted(_SECTIONS[key])}")
                kwargs[_SECTIONS[key][k]] = v
        elif key == "regions":
            kwargs["regions"] = dict(value)
        elif key in top:
            kwargs[key] = value
        else:
            raise DataFileError(str(path), f"unknown key {key!r}; known: {sorted(top | set(_SECTIONS))}")
    try:
        cfg = RunConfig(**kwargs, source=str(path))
    except TypeError as e:
        raise DataFileError(str(path), str(e)) from None
    cfg.validate()
    return cfg
