"""PAM robot design files: routes, sizes and operating point of every PAM.

A design file (YAML) describes one side (right) of the robot; the left side is its
mirror image (z → −z in every body frame, ``_r`` → ``_l``). Format::

    name: thesis_2019
    description: ...
    rom: robot_thesis                 # range of motion in robot/data/rom.yaml
    force_model: v3                   # pamkin.robot.festo model (v3, v0)
    pressure_Pa: 620000.0
    fitting_length_m: 0.0125          # per end; each PAM has two fittings
    pams:
      - id: 4
        name: Biceps Femoris Long Head
        human_muscles: [bifemlh_r]    # the Gait2392 muscles it replaces
        primary_coordinate: knee_angle_r
        secondary_coordinates: [hip_flexion_r]
        diameter_mm: 20               # 10, 20 or 40
        n_parallel: 1
        resting_length_m: 0.4
        tendon_length_m: 0.1          # artificial tendon (may be negative only as a flagged defect)
        transmission: 1               # optional: 2 or 3 = a 2:1 or 3:1 pulley block on the PAM's free end
        pam_at: insertion             # optional: the end of its mount segment the PAM sits at (origin, insertion)
        pam_on: p3->p4                # optional: its mount segment (default: the segment that holds it best)
        rollers:                      # optional: cable guides on bone (pamkin.robot.rollers)
          - {segment: p1->p2, body: femur_r, centre: [-0.03, -0.05, 0.0], axis: [0, 0, 1], side: [-1, 0, 0],
             radius_m: 0.008, length_m: 0.04}
        points:                       # route, origin first; PathPoint / MovingPathPoint
          - {name: p5, body: pelvis, location: [-0.126, -0.103, 0.069]}
          - ...

Lengths: path length L = l_pam + 2·fitting + tendon, so the PAM's own length is
l_pam = L − 2·fitting − tendon and its contraction ε = (l_rest − l_pam)/l_rest.

Transmission k (``transmission``, 1, 2 or 3; default 1): with k = 2 the PAM and its fittings sit in a
rigid frame in series with the cable, a pulley on the PAM's free end carrying the cable twice (a 2:1
block); with k = 3 a second pulley at the frame's anchor makes three legs (a 3:1 block). The route's length then changes k times as fast as the PAM's and its tension is the PAM's
force ÷ k: L = k·(l_pam + 2·fitting) + tendon, so l_pam = (L − tendon)/k − 2·fitting, and the force
on the route (the torque's) is n_parallel · F(ε) / k. A PAM whose excursion needs more length than
any straight segment of its route holds (at k = 1) fits on one with k = 2, at twice the force.
"""

from __future__ import annotations

import copy
import difflib
import functools
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from pamkin.errors import DataFileError
from pamkin.human.urdf import GAIT2392_DATA, ROBOT_DIR, load_model_data
from pamkin.outputs import write_file
from pamkin.opensim.functions import Constant, MultiplierFunction
from pamkin.opensim.model_file import (
    AnyPathPoint,
    ConditionalPathPoint,
    MovingPathPoint,
    PathPoint,
    _point_to_dict,
    point_from_dict,
)
from pamkin.robot import festo
from pamkin.robot.pam_body import PAM_AT
from pamkin.robot.rollers import Roller, roller_from_dict
from pamkin.yamlio import strict_load

#: The thesis robot's 27 PAMs as designed by hand (sized by the thesis algorithm): the baseline.
THESIS_DESIGN = ROBOT_DIR / "data" / "thesis_design.yaml"
#: The thesis design with its 9-muscle gluteal group split into gluteus maximus (24) and gluteus
#: medius/minimus anterior (28) and posterior (29) (tools/make_split_gluteal.py).
SPLIT_GLUTEAL_DESIGN = ROBOT_DIR / "data" / "split_gluteal_design.yaml"
#: The split-gluteal design with sartorius (6), rectus femoris (8), gracilis (9) and soleus (12) re-seeded on Gait2392's
#: paths (thesis defects beyond the optimiser's boxes): the seed of the default optimiser run
#: (tools/make_split_gluteal.py).
V2_SEED_DESIGN = ROBOT_DIR / "data" / "v2_seed_design.yaml"
#: The v2 seed with synergists merged into 22 PAMs per side (tools/make_merged_seed.py): fewer bodies to place.
MERGED_SEED_DESIGN = ROBOT_DIR / "data" / "merged_seed_design.yaml"
#: The designs a user argument may name by keyword (:func:`resolve_design_path`).
NAMED_DESIGNS = {"thesis": THESIS_DESIGN, "split_gluteal": SPLIT_GLUTEAL_DESIGN, "v2_seed": V2_SEED_DESIGN,
                 "merged_seed": MERGED_SEED_DESIGN}
#: The robot's current design (starts as the thesis design; ``pamkin optimize --apply`` replaces it).
ROBOT_DESIGN = ROBOT_DIR / "data" / "thesis_design.yaml"
DIAMETERS_MM = (10, 20, 40)
#: Transmission ratios a PAM may have: 1 (the cable pulls the PAM directly), 2 or 3 (a 2:1 or 3:1 pulley block).
TRANSMISSIONS = (1, 2, 3)
_REQUIRED = ("id", "name", "human_muscles", "primary_coordinate", "diameter_mm", "resting_length_m",
             "tendon_length_m", "points")


@dataclass(frozen=True)
class Pam:
    """One PAM (right side) of a design.

    Attributes:
        id: Actuator number.
        name: Name.
        human_muscles: Gait2392 muscles it replaces.
        primary_coordinate: Coordinate whose torque it mainly reproduces.
        secondary_coordinates: Further coordinates compared.
        diameter_mm: Festo inner diameter (10, 20, 40).
        n_parallel: PAMs in parallel on the same route.
        resting_length_m: Resting length of one PAM, fittings excluded [m].
        tendon_length_m: Artificial tendon length [m].
        points: Route (origin first).
        notes: Free text.
        transmission: Cable legs at the PAM's free end: 1 (direct), 2 or 3 (a k:1 pulley block: the
            route moves k times the PAM's stroke at 1/k of its force).
        pam_at: The end of its mount segment the PAM (on a block: its frame) is anchored at, "origin" or
            "insertion" (the artificial tendon on the other side); None: the origin end where the route
            before the segment has a fixed length, else the insertion end (:mod:`pamkin.robot.pam_body`).
        pam_on: The mount segment by name (``"p3->p4"``, :func:`pamkin.robot.pam_body.segment_names`) where the
            PAM body fits on more than one; None (or a segment that does not hold it): the segment that
            holds it best (:func:`pamkin.robot.pam_body.placement`). Where the body sits never changes a torque.
        rollers: Cable guides on its route's segments (:mod:`pamkin.robot.rollers`; at most one per segment; the
            PAM body never sits on a segment with a roller).
        cable_efficiency: Share of the PAM's force that reaches the route, in (0, 1]: the capstan factor of the
            cable's turns on a rack (:mod:`pamkin.robot.rack`; 1: none modelled). Multiplies the route's tension
            and so every torque.
    """

    id: int
    name: str
    human_muscles: tuple[str, ...]
    primary_coordinate: str
    secondary_coordinates: tuple[str, ...]
    diameter_mm: int
    n_parallel: int
    resting_length_m: float
    tendon_length_m: float
    points: tuple[AnyPathPoint, ...]
    notes: str = ""
    transmission: int = 1
    pam_at: str | None = None
    pam_on: str | None = None
    rollers: tuple[Roller, ...] = ()
    cable_efficiency: float = 1.0

    @property
    def key(self) -> str:
        """Short key, e.g. ``pam04``."""
        return f"pam{self.id:02d}"


@dataclass(frozen=True)
class Design:
    """A robot design (right side; the left is mirrored).

    Attributes:
        name: Design name.
        pams: PAMs in file order.
        pressure_Pa: Supply pressure (gauge) [Pa].
        force_model: Festo force model name.
        fitting_length_m: Length of one fitting [m].
        rom: Name of the range of motion used for sizing and comparison.
        description: Free text.
        path: File it was read from.
    """

    name: str
    pams: tuple[Pam, ...]
    pressure_Pa: float = 620e3
    force_model: str = "v3"
    fitting_length_m: float = 0.0125
    rom: str = "robot_thesis"
    description: str = ""
    path: str = ""
    extra: dict = field(default_factory=dict, compare=False)

    def pam(self, key: int | str) -> Pam:
        """PAM by id or key."""
        for p in self.pams:
            if key in (p.id, p.key, p.name):
                return p
        raise KeyError(f"design {self.name!r} has no PAM {key!r}")

    def replace_pam(self, pam: Pam) -> Design:
        """A copy with one PAM replaced (matched by id)."""
        return Design(self.name, tuple(pam if p.id == pam.id else p for p in self.pams), self.pressure_Pa,
                      self.force_model, self.fitting_length_m, self.rom, self.description, self.path,
                      dict(self.extra))

    def to_dict(self) -> dict:
        """Plain-data form (what :func:`save_design` writes)."""
        out = {"name": self.name, "description": self.description, "rom": self.rom,
               "force_model": self.force_model, "pressure_Pa": float(self.pressure_Pa),
               "fitting_length_m": float(self.fitting_length_m)}
        out.update(copy.deepcopy(self.extra))
        out["pams"] = [{
            "id": p.id, "name": p.name, "human_muscles": list(p.human_muscles),
            "primary_coordinate": p.primary_coordinate,
            "secondary_coordinates": list(p.secondary_coordinates),
            "diameter_mm": int(p.diameter_mm), "n_parallel": int(p.n_parallel),
            "resting_length_m": float(p.resting_length_m), "tendon_length_m": float(p.tendon_length_m),
            **({"transmission": int(p.transmission)} if p.transmission != 1 else {}),
            **({"pam_at": p.pam_at} if p.pam_at is not None else {}),
            **({"pam_on": p.pam_on} if p.pam_on is not None else {}),
            **({"rollers": [r.to_dict() for r in p.rollers]} if p.rollers else {}),
            **({"cable_efficiency": float(p.cable_efficiency)} if p.cable_efficiency != 1.0 else {}),
            "notes": p.notes,
            "points": [_point_to_dict(pt) for pt in p.points],
        } for p in self.pams]
        return out


def pam_length(route_length, tendon, transmission: int, fitting_length: float):
    """Length [m] of a PAM itself (fittings excluded) on a route of length ``route_length`` [m] (numbers,
    numpy arrays or CasADi expressions alike): (L − tendon)/k − 2·fitting for transmission k; for k = 1
    written L − 2·fitting − tendon, the form every result before transmissions existed was computed with
    (the same value; the same rounding, so those runs stay reproducible to the bit)."""
    if int(transmission) == 1:
        return route_length - 2 * fitting_length - tendon
    return (route_length - tendon) / transmission - 2 * fitting_length


def tendon_for(route_length, resting_length, transmission: int, fitting_length: float):
    """The tendon [m] that leaves the PAM at its resting length on a route of length ``route_length`` [m]
    (the inverse of :func:`pam_length`)."""
    if int(transmission) == 1:
        return route_length - 2 * fitting_length - resting_length
    return route_length - transmission * (2 * fitting_length + resting_length)


def rescale_for_transmission(resting_length: float, tendon: float, k0: int, k: int, fitting_length: float
                             ) -> tuple[float, float]:
    """Resting length and tendon [m] of a PAM moved from a ``k0``:1 to a ``k``:1 transmission so that its
    strain is the same at every route length: l0·k0/k and tendon + 2·fitting·(k0 − k) (from :func:`pam_length`;
    the tendon clipped at 0, where the strain then differs)."""
    return resting_length * k0 / k, max(tendon + 2 * fitting_length * (k0 - k), 0.0)


def unit_mass(resting_length: float, diameter_mm: int, transmission: int = 1) -> float:
    """Estimated mass [kg] of one parallel PAM unit of resting length [m] and diameter: the PAM with its
    fittings (:func:`pamkin.robot.festo.pam_mass`) and its transmission (:func:`pamkin.robot.festo.transmission_mass`);
    both assumptions, for bulk comparisons (the audit) and the optimiser's mass penalty."""

    return float(festo.pam_mass(resting_length, diameter_mm)
                 + festo.transmission_mass(resting_length, diameter_mm, transmission))


def pam_unit_mass(pam: Pam) -> float:
    """:func:`unit_mass` of one of a PAM's parallel units [kg]."""
    return unit_mass(pam.resting_length_m, pam.diameter_mm, pam.transmission)


def pams_mass(pams) -> float:
    """Estimated mass [kg] of these PAMs with all their parallel units, on both sides of the robot (the audit's
    mass, the optimiser's mass budget)."""
    return 2 * sum(p.n_parallel * pam_unit_mass(p) for p in pams)


def _fail(path: str, msg: str) -> DataFileError:
    return DataFileError(path, msg)


#: Fields of a PAM entry: required, then optional.
_OPTIONAL = ("secondary_coordinates", "n_parallel", "transmission", "pam_at", "pam_on", "rollers", "notes",
             "cable_efficiency")
#: Top-level fields of a design file.
_TOP = ("name", "description", "rom", "force_model", "pressure_Pa", "fitting_length_m", "pams", "notes")
#: Physical bounds of a design's numbers (SI): a value outside is a typo or a unit mix-up, refused.
BOUNDS = {"resting_length_m": (0.01, 2.0), "tendon_length_m": (-2.0, 2.0), "pressure_Pa": (1e5, 8e5),
          "fitting_length_m": (0.0, 0.1), "cable_efficiency": (0.0, 1.0), "point_distance_m": 1.0}


def _unknown(keys, known, path: str, where: str) -> None:
    """Refuse keys outside ``known``, naming the nearest valid one."""
    for k in keys:
        if k not in known:
            near = difflib.get_close_matches(str(k), known, n=1)
            raise _fail(path, f"{where}unknown field {k!r}" + (f" (did you mean {near[0]!r}?)" if near else
                                                              f"; fields: {sorted(known)}"))


def _int(d: dict, key: str, path: str, where: str, default=None, allowed=None) -> int:
    v = d.get(key, default)
    bad = isinstance(v, bool) or not isinstance(v, int)
    if bad and allowed is None:
        raise _fail(path, f"{where}{key} must be an integer, is {v!r}")
    if allowed is not None and (bad or v not in allowed):
        if key == "diameter_mm":
            raise _fail(path, f"{where}{key} {v!r} is not a Festo DMSP size {tuple(allowed)}")
        raise _fail(path, f"{where}{key} must be one of {tuple(allowed)}, is {v!r}")
    return v


def _number(d: dict, key: str, path: str, where: str, default=None) -> float:
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v):
        raise _fail(path, f"{where}{key} must be a finite number, is {v!r}")
    lo, hi = BOUNDS.get(key, (-np.inf, np.inf))
    if not lo <= v <= hi or (key != "tendon_length_m" and v <= 0 and lo == 0.0):
        if key == "resting_length_m":
            raise _fail(path, f"{where}{key} must be a positive length in [{lo:g}, {hi:g}] m, is {v!r}")
        raise _fail(path, f"{where}{key} must lie in ({lo:g}, {hi:g}], is {v!r}" if lo == 0.0 else
                    f"{where}{key} must lie in [{lo:g}, {hi:g}], is {v!r}")
    return float(v)


def _names(d: dict, key: str, path: str, where: str, known=None, empty: bool = True) -> tuple[str, ...]:
    v = d.get(key, [])
    if not isinstance(v, list) or not all(isinstance(x, str) and x for x in v) or (not empty and not v):
        raise _fail(path, f"{where}{key} must be a {'' if empty else 'non-empty '}list of names, is {v!r}")
    bad = [x for x in v if known is not None and x not in known]
    if bad:
        raise _fail(path, f"{where}{key}: unknown name(s) {bad}")
    return tuple(v)


@functools.lru_cache(maxsize=1)
def _gait2392_muscles() -> frozenset[str]:
    """The Gait2392 muscle names a PAM's ``human_muscles`` may name (read once per process: 0.1 s)."""
    return frozenset(m.name for m in load_model_data(GAIT2392_DATA).muscles)


def _points(d: dict, path: str, where: str, bodies) -> tuple:
    raw = d["points"]
    if not isinstance(raw, list) or not all(isinstance(p, dict) for p in raw):
        raise _fail(path, f"{where}points must be a list of mappings (name, body, location), is {raw!r:.80}")
    try:
        points = tuple(point_from_dict(p) for p in raw)
    except (KeyError, TypeError, ValueError) as e:
        raise _fail(path, f"{where}bad route point: {type(e).__name__}: {e}") from None
    if len(points) < 2:
        raise _fail(path, f"{where}a route needs at least 2 points")
    names = [pt.name for pt in points]
    if len(set(names)) != len(names) or not all(isinstance(n, str) and n for n in names):
        raise _fail(path, f"{where}route point names must be distinct, non-empty names, are {names}")
    for pt in points:
        if bodies is not None and pt.body not in bodies:
            raise _fail(path, f"{where}route point {pt.name!r} is on unknown body {pt.body!r}; bodies: {bodies}")
        if isinstance(pt, PathPoint):
            if not np.all(np.isfinite(pt.location)):
                raise _fail(path, f"{where}route point {pt.name!r} has a non-finite location")
            if np.linalg.norm(pt.location) > BOUNDS["point_distance_m"]:
                raise _fail(path, f"{where}route point {pt.name!r} lies {np.linalg.norm(pt.location):.3g} m from "
                                  f"its body's origin (at most {BOUNDS['point_distance_m']:g} m: a unit mix-up?)")
    return points


def _pam_from_dict(d, k: int, path: str, bodies, coordinates, muscles, seen: set) -> Pam:
    """One PAM entry, validated (errors name the file, the PAM and the field)."""
    where = f"pams[{k}]" + (f" (id {d.get('id')!r}, {d.get('name')!r})" if isinstance(d, dict) else "") + ": "
    if not isinstance(d, dict):
        raise _fail(path, f"{where}must be a mapping")
    missing = [f for f in _REQUIRED if f not in d]
    if missing:
        raise _fail(path, f"{where}missing field(s) {missing}")
    _unknown(d, _REQUIRED + _OPTIONAL, path, where)
    pid = _int(d, "id", path, where)
    if pid < 1 or pid in seen:
        raise _fail(path, f"{where}id must be a distinct integer >= 1")
    seen.add(pid)
    if not isinstance(d["name"], str) or not d["name"]:
        raise _fail(path, f"{where}name must be a non-empty string")
    diameter = _int(d, "diameter_mm", path, where, allowed=DIAMETERS_MM)
    npar = _int(d, "n_parallel", path, where, default=1, allowed=(1, 2, 3))
    ratio = _int(d, "transmission", path, where, default=1, allowed=TRANSMISSIONS)
    rest = _number(d, "resting_length_m", path, where)
    tendon = _number(d, "tendon_length_m", path, where)
    human = _names(d, "human_muscles", path, where, muscles, empty=False)
    if not isinstance(d["primary_coordinate"], str):
        raise _fail(path, f"{where}primary_coordinate must be a coordinate name")
    coords = (d["primary_coordinate"], *_names(d, "secondary_coordinates", path, where))
    bad = [c for c in coords if coordinates is not None and c not in coordinates]
    if bad:
        raise _fail(path, f"{where}unknown coordinate(s) {bad}")
    points = _points(d, path, where, bodies)
    pam_at, pam_on, rollers = _mount_fields(d, points, path, where, bodies)
    if not isinstance(d.get("notes", ""), str):
        raise _fail(path, f"{where}notes must be text")
    efficiency = _number(d, "cable_efficiency", path, where, default=1.0)
    return Pam(pid, d["name"], human, coords[0], coords[1:], diameter, npar, rest, tendon, points,
               d.get("notes", ""), ratio, pam_at, pam_on, rollers, efficiency)


def _mount_fields(d: dict, points, path: str, where: str, bodies):
    """``pam_at``, ``pam_on`` and ``rollers`` of a PAM entry, validated against its route."""
    pam_at = d.get("pam_at")
    if pam_at is not None and pam_at not in PAM_AT:
        raise _fail(path, f"{where}pam_at must be one of {PAM_AT} (the end of its mount segment the PAM "
                          f"is anchored at), is {pam_at!r}")
    pam_on = d.get("pam_on")
    segments = [f"{a.name}->{b.name}" for a, b in zip(points[:-1], points[1:])]
    if pam_on is not None and pam_on not in segments:
        raise _fail(path, f"{where}pam_on must name a segment of its route {segments} (the segment the "
                          f"PAM body sits on), is {pam_on!r}")
    raw_rollers = d.get("rollers") or []
    if not isinstance(raw_rollers, list) or not all(isinstance(r, dict) for r in raw_rollers):
        raise _fail(path, f"{where}rollers must be a list of mappings")
    try:
        rollers = tuple(roller_from_dict(r, segments, bodies) for r in raw_rollers)
    except (ValueError, TypeError, KeyError) as e:
        raise _fail(path, f"{where}{e}") from None
    twice = sorted({r.segment for r in rollers if sum(x.segment == r.segment for x in rollers) > 1})
    if twice:
        raise _fail(path, f"{where}at most one roller per segment; {twice} have more")
    if pam_on is not None and pam_on in {r.segment for r in rollers}:
        raise _fail(path, f"{where}pam_on {pam_on!r} has a roller: a PAM body sits on a straight segment")
    return pam_at, pam_on, rollers


def design_from_dict(data: dict, path: str = "<design>", bodies: list[str] | None = None,
                     coordinates: list[str] | None = None, muscles: frozenset[str] | None = None) -> Design:
    """Validate and build a :class:`Design` (errors name the file, PAM and field).

    Every field's type and physical range is checked (:data:`BOUNDS`), unknown fields are refused with the
    nearest valid name, ``human_muscles`` must be Gait2392 muscles (``muscles``; default: Gait2392's), route
    points must lie on ``bodies`` and coordinates be ``coordinates`` where those are given.
    """
    if not isinstance(data, dict) or "pams" not in data:
        raise _fail(path, "not a design file: needs a top-level 'pams' list")
    _unknown(data, _TOP, path, "")
    if not isinstance(data["pams"], list) or not data["pams"]:
        raise _fail(path, f"pams must be a non-empty list of PAMs, is {data['pams']!r:.80}")
    muscles = _gait2392_muscles() if muscles is None else muscles
    seen: set[int] = set()
    pams = tuple(_pam_from_dict(d, k, path, bodies, coordinates, muscles, seen) for k, d in enumerate(data["pams"]))
    for key in ("name", "description", "rom", "notes"):
        if not isinstance(data.get(key, ""), str):
            raise _fail(path, f"{key} must be text, is {data[key]!r:.80}")
    force_model = data.get("force_model", "v3")
    if force_model not in festo.MODELS:
        raise _fail(path, f"force_model must be one of {sorted(festo.MODELS)}, is {force_model!r}")
    pressure = _number(data, "pressure_Pa", path, "", 620e3)
    fitting = _number(data, "fitting_length_m", path, "", 0.0125)
    extra = {k: v for k, v in data.items() if k == "notes"}
    return Design(data.get("name", Path(path).stem), pams, pressure, force_model, fitting,
                  data.get("rom", "robot_thesis"), data.get("description", ""), path, extra)


def resolve_design_path(design: str | os.PathLike | None = None) -> Path:
    """The design file a user argument names.

    Args:
        design: ``None`` (the robot's current design ``robot/data/thesis_design.yaml``), the keywords
            ``"thesis"`` (``robot/data/thesis_design.yaml``), ``"split_gluteal"``
            (``robot/data/split_gluteal_design.yaml``), ``"v2_seed"`` (``robot/data/v2_seed_design.yaml``) and
            ``"merged_seed"`` (``robot/data/merged_seed_design.yaml``), a design file, or a run folder of
            ``pamkin optimize`` (its ``design.yaml``).

    Raises:
        DataFileError: A folder without a ``design.yaml``.
    """
    if design is None:
        return ROBOT_DESIGN
    if str(design) in NAMED_DESIGNS:
        return NAMED_DESIGNS[str(design)]
    path = Path(design)
    if path.is_dir():
        if not (path / "design.yaml").is_file():
            raise _fail(str(path), "a folder given as design must be a pamkin optimize run folder holding design.yaml")
        return path / "design.yaml"
    return path


def load_design(path: str | os.PathLike = ROBOT_DESIGN, bodies: list[str] | None = None,
                coordinates: list[str] | None = None) -> Design:
    """Read and validate a design file (``"thesis"`` names the built-in thesis design, a folder
    the ``design.yaml`` of a ``pamkin optimize`` run; see :func:`resolve_design_path`).

    Raises:
        DataFileError: Malformed YAML, missing fields, unknown diameter/body/coordinate,
            non-positive lengths — naming the file and the PAM.
    """
    path = resolve_design_path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise _fail(str(path), "file not found") from None
    except IsADirectoryError:
        raise _fail(str(path), "is a folder without design.yaml") from None
    return design_from_dict(strict_load(raw, str(path)), str(path), bodies, coordinates)


def save_design(design: Design, path: str | os.PathLike, header: str = "") -> Path:
    """Write a design file atomically (nothing is changed if writing fails)."""
    text = header + yaml.safe_dump(design.to_dict(), sort_keys=False, width=110)
    write_file(Path(path), text)
    return Path(path)


def mirror_name(name: str) -> str:
    """``femur_r`` → ``femur_l`` (names without a side are unchanged)."""
    return name[:-2] + "_l" if name.endswith("_r") else name


def mirror_point(pt: AnyPathPoint) -> AnyPathPoint:
    """The left-side point of a right-side route point (z → −z, ``_r`` → ``_l``)."""
    if isinstance(pt, MovingPathPoint):
        fz = pt.functions[2]
        fz = Constant(-fz.c) if isinstance(fz, Constant) else MultiplierFunction(fz, -1.0)
        return MovingPathPoint(mirror_name(pt.name), mirror_name(pt.body), (pt.functions[0], pt.functions[1], fz),
                               tuple(mirror_name(c) for c in pt.coordinates))  # type: ignore[arg-type]
    x, y, z = pt.location
    if isinstance(pt, ConditionalPathPoint):
        return ConditionalPathPoint(mirror_name(pt.name), mirror_name(pt.body), (x, y, -z),
                                    coordinate=mirror_name(pt.coordinate), range=pt.range)
    return PathPoint(mirror_name(pt.name), mirror_name(pt.body), (x, y, -z))


def mirror_roller(r: Roller) -> Roller:
    """The left-side roller of a right-side one (z → −z in the body frame, ``_r`` → ``_l``; the segment named
    by the mirrored points' names)."""
    def m(v):
        return (v[0], v[1], -v[2])

    a, b = r.segment.split("->")
    return Roller(f"{mirror_name(a)}->{mirror_name(b)}", mirror_name(r.body), m(r.centre), m(r.axis), m(r.side),
                  r.radius_m, r.length_m)


#: What each field of a design file holds (the documentation's schema table is generated from this).
FIELD_DOCS = {
    "name": ("text", "the design's name (default: the file's stem)"),
    "description": ("text", "free text"),
    "notes": ("text", "free text"),
    "rom": ("text", "range of motion in robot/data/rom.yaml (default robot_thesis)"),
    "force_model": ("text", "PAM force model: " + ", ".join(sorted(festo.MODELS)) + " (default v3)"),
    "pressure_Pa": ("number [Pa]", "operating pressure (default 620000)"),
    "fitting_length_m": ("number [m]", "length of each of a PAM's two fittings (default 0.0125)"),
    "pams": ("list", "the PAMs of the right side (the left is mirrored), at least one"),
    "pams[].id": ("integer", "distinct, >= 1"),
    "pams[].name": ("text", "non-empty"),
    "pams[].human_muscles": ("list of names", "the Gait2392 muscles the PAM replaces (at least one)"),
    "pams[].primary_coordinate": ("name", "a coordinate of the robot"),
    "pams[].secondary_coordinates": ("list of names", "coordinates of the robot (default none)"),
    "pams[].diameter_mm": ("integer", f"Festo DMSP inner diameter, one of {DIAMETERS_MM}"),
    "pams[].n_parallel": ("integer", "PAMs in parallel on the route, 1-3 (default 1)"),
    "pams[].resting_length_m": ("number [m]", "the PAM's resting length"),
    "pams[].tendon_length_m": ("number [m]", "the artificial tendon in series (negative only as a flagged defect)"),
    "pams[].transmission": ("integer", f"pulley block ratio, one of {TRANSMISSIONS} (default 1: direct)"),
    "pams[].pam_at": ("name", f"the end of its mount segment the PAM sits at, one of {PAM_AT}"),
    "pams[].pam_on": ("name", "its mount segment 'p3->p4' (a segment of its route, without a roller)"),
    "pams[].rollers": ("list", "cable guides on bone, at most one per segment (pamkin.robot.rollers)"),
    "pams[].cable_efficiency": ("number", "share of the PAM's force reaching the route: the capstan factor of "
                                          "its cable's turns on a rack (default 1)"),
    "pams[].notes": ("text", "free text"),
    "pams[].points": ("list", "the route, origin first, at least 2 distinct names: {type, name, body, location} "
                              "with the location [m] in the body's frame"),
}


def design_schema_markdown() -> str:
    """The design file's schema as a Markdown table: field, type, allowed values (from :data:`BOUNDS` and the
    checks of :func:`design_from_dict`) and meaning."""
    rng = {"resting_length_m": BOUNDS["resting_length_m"], "tendon_length_m": BOUNDS["tendon_length_m"],
           "pressure_Pa": BOUNDS["pressure_Pa"], "fitting_length_m": BOUNDS["fitting_length_m"],
           "cable_efficiency": BOUNDS["cable_efficiency"]}
    rows = ["| field | type | range | meaning |", "|---|---|---|---|"]
    for name, (kind, doc) in FIELD_DOCS.items():
        key = name.rpartition(".")[2]
        r = rng.get(key)
        text = "" if r is None else (f"({r[0]:g}, {r[1]:g}]" if r[0] == 0.0 else f"[{r[0]:g}, {r[1]:g}]")
        if key == "points":
            text = f"each within {BOUNDS['point_distance_m']:g} m of its body's origin"
        rows.append(f"| `{name}` | {kind} | {text} | {doc} |")
    return "\n".join(rows)
