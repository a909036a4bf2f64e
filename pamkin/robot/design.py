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
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from pamkin.errors import DataFileError
from pamkin.human.urdf import ROBOT_DIR, atomic_write
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
from pamkin.yamlio import safe_load

#: The thesis robot's 27 PAMs as designed by hand (sized by the thesis algorithm): the baseline.
THESIS_DESIGN = ROBOT_DIR / "data" / "thesis_design.yaml"
#: The thesis design with its 9-muscle gluteal group split into gluteus maximus (24) and gluteus
#: medius/minimus anterior (28) and posterior (29) (tools/make_split_gluteal.py).
SPLIT_GLUTEAL_DESIGN = ROBOT_DIR / "data" / "split_gluteal_design.yaml"
#: The split-gluteal design with sartorius (6), rectus femoris (8), gracilis (9) and soleus (12) re-seeded on Gait2392's
#: paths (thesis defects beyond the optimiser's boxes): the seed of the default optimiser run
#: (tools/make_split_gluteal.py).
V2_SEED_DESIGN = ROBOT_DIR / "data" / "v2_seed_design.yaml"
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


def design_from_dict(data: dict, path: str = "<design>", bodies: list[str] | None = None,
                     coordinates: list[str] | None = None) -> Design:
    """Validate and build a :class:`Design` (errors name the file, PAM and field)."""
    if not isinstance(data, dict) or "pams" not in data:
        raise _fail(path, "not a design file: needs a top-level 'pams' list")
    pams = []
    seen = set()
    for k, d in enumerate(data["pams"]):
        where = f"pams[{k}]" + (f" (id {d.get('id')}, {d.get('name')!r})" if isinstance(d, dict) else "")
        if not isinstance(d, dict):
            raise _fail(path, f"{where}: must be a mapping")
        missing = [f for f in _REQUIRED if f not in d]
        if missing:
            raise _fail(path, f"{where}: missing field(s) {missing}")
        if d["id"] in seen:
            raise _fail(path, f"{where}: duplicate id")
        seen.add(d["id"])
        if d["diameter_mm"] not in DIAMETERS_MM:
            raise _fail(path, f"{where}: diameter_mm {d['diameter_mm']!r} is not a Festo DMSP size {DIAMETERS_MM}")
        try:
            rest = float(d["resting_length_m"])
            tendon = float(d["tendon_length_m"])
            npar = int(d.get("n_parallel", 1))
            ratio = d.get("transmission", 1)
        except (TypeError, ValueError) as e:
            raise _fail(path, f"{where}: {e}") from None
        if not np.isfinite(rest) or rest <= 0:
            raise _fail(path, f"{where}: resting_length_m must be a positive length, is {rest}")
        if not np.isfinite(tendon):
            raise _fail(path, f"{where}: tendon_length_m must be finite")
        if npar not in (1, 2, 3):
            raise _fail(path, f"{where}: n_parallel must be 1, 2 or 3")
        if isinstance(ratio, bool) or ratio not in TRANSMISSIONS:
            raise _fail(path, f"{where}: transmission must be one of {TRANSMISSIONS} (cable legs at the PAM's "
                              f"free end), is {ratio!r}")
        pam_at = d.get("pam_at")
        if pam_at is not None and pam_at not in PAM_AT:
            raise _fail(path, f"{where}: pam_at must be one of {PAM_AT} (the end of its mount segment the PAM "
                              f"is anchored at), is {pam_at!r}")
        try:
            points = tuple(point_from_dict(p) for p in d["points"])
        except (KeyError, TypeError, ValueError) as e:
            raise _fail(path, f"{where}: bad route point: {type(e).__name__}: {e}") from None
        if len(points) < 2:
            raise _fail(path, f"{where}: a route needs at least 2 points")
        pam_on = d.get("pam_on")
        segments = [f"{a.name}->{b.name}" for a, b in zip(points[:-1], points[1:])]
        if pam_on is not None and pam_on not in segments:
            raise _fail(path, f"{where}: pam_on must name a segment of its route {segments} (the segment the "
                              f"PAM body sits on), is {pam_on!r}")
        raw_rollers = d.get("rollers") or []
        if not isinstance(raw_rollers, list):
            raise _fail(path, f"{where}: rollers must be a list of mappings")
        try:
            rollers = tuple(roller_from_dict(r, segments, bodies) for r in raw_rollers)
        except ValueError as e:
            raise _fail(path, f"{where}: {e}") from None
        twice = sorted({r.segment for r in rollers if sum(x.segment == r.segment for x in rollers) > 1})
        if twice:
            raise _fail(path, f"{where}: at most one roller per segment; {twice} have more")
        if pam_on is not None and pam_on in {r.segment for r in rollers}:
            raise _fail(path, f"{where}: pam_on {pam_on!r} has a roller: a PAM body sits on a straight segment")
        for pt in points:
            if bodies is not None and pt.body not in bodies:
                raise _fail(path, f"{where}: route point {pt.name!r} is on unknown body {pt.body!r}; "
                                  f"bodies: {bodies}")
            if isinstance(pt, PathPoint) and not np.all(np.isfinite(pt.location)):
                raise _fail(path, f"{where}: route point {pt.name!r} has a non-finite location")
        coords = [d["primary_coordinate"], *d.get("secondary_coordinates", [])]
        if coordinates is not None:
            bad = [c for c in coords if c not in coordinates]
            if bad:
                raise _fail(path, f"{where}: unknown coordinate(s) {bad}")
        pams.append(Pam(int(d["id"]), str(d["name"]), tuple(d["human_muscles"]), d["primary_coordinate"],
                        tuple(d.get("secondary_coordinates", [])), int(d["diameter_mm"]), npar, rest,
                        tendon, points, str(d.get("notes", "")), int(ratio), pam_at, pam_on, rollers))
    known = {"name", "description", "rom", "force_model", "pressure_Pa", "fitting_length_m", "pams"}
    try:
        return Design(str(data.get("name", Path(path).stem)), tuple(pams), float(data.get("pressure_Pa", 620e3)),
                      str(data.get("force_model", "v3")), float(data.get("fitting_length_m", 0.0125)),
                      str(data.get("rom", "robot_thesis")), str(data.get("description", "")), path,
                      {k: v for k, v in data.items() if k not in known})
    except (TypeError, ValueError) as e:
        raise _fail(path, f"bad top-level field: {e}") from None


def resolve_design_path(design: str | os.PathLike | None = None) -> Path:
    """The design file a user argument names.

    Args:
        design: ``None`` (the robot's current design ``robot/data/thesis_design.yaml``), the keywords
            ``"thesis"`` (``robot/data/thesis_design.yaml``), ``"split_gluteal"``
            (``robot/data/split_gluteal_design.yaml``) and ``"v2_seed"``
            (``robot/data/v2_seed_design.yaml``), a design file, or a run folder of
            ``pamkin optimize`` (its ``design.yaml``).

    Raises:
        DataFileError: A folder without a ``design.yaml``.
    """
    if design is None:
        return ROBOT_DESIGN
    if str(design) == "thesis":
        return THESIS_DESIGN
    if str(design) == "split_gluteal":
        return SPLIT_GLUTEAL_DESIGN
    if str(design) == "v2_seed":
        return V2_SEED_DESIGN
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
        data = safe_load(path.read_text())
    except FileNotFoundError:
        raise _fail(str(path), "file not found") from None
    except yaml.YAMLError as e:
        raise _fail(str(path), f"not valid YAML: {e}") from None
    return design_from_dict(data, str(path), bodies, coordinates)


def save_design(design: Design, path: str | os.PathLike, header: str = "") -> Path:
    """Write a design file atomically (nothing is changed if writing fails)."""
    text = header + yaml.safe_dump(design.to_dict(), sort_keys=False, width=110)
    atomic_write(Path(path), text)
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
