"""Write the MJCF document of a converted model: bodies, joints, joint equalities, sites, wrap geoms, tendons.

The MuJoCo body frames are the OpenSim body frames (so OpenSim's path points, mass centres and inertias carry
over unchanged); OpenSim's Y-up convention is kept (gravity along −Y). Bone meshes are visuals only (no
contact, no mass: ``inertiafromgeom="false"``; every body's inertia is OpenSim's).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import mujoco
import numpy as np

from pamkin.opensim.model_file import GROUND, OsimModel
from pamkin.sim.joints import CoordinateMap

#: Gravity of OpenSim models (Y up) [m/s²].
GRAVITY = (0.0, -9.80665, 0.0)
#: Mass and principal inertia given to a body with none (MuJoCo needs moving bodies to have mass)
#: [kg, kg·m²]: moving-path-point bodies and massless OpenSim bodies.
TINY_MASS = 1e-5
TINY_INERTIA = 1e-10


@dataclass
class Site:
    """A site: name, MuJoCo body, position in the body [m]."""

    name: str
    body: str
    pos: np.ndarray


@dataclass
class WrapGeom:
    """A wrap geom: ``kind`` ``cylinder`` or ``sphere``, size (radius[, half length]) [m], placement in its body."""

    name: str
    body: str
    kind: str
    size: tuple[float, ...]
    R: np.ndarray
    p: np.ndarray


@dataclass
class Tendon:
    """A spatial tendon: its path ``[("site", name) | ("geom", name, sidesite or "")]``."""

    name: str
    path: list[tuple]


@dataclass
class MjcfSpec:
    """Everything the MJCF holds beyond the joint tree (which comes from :class:`CoordinateMap`)."""

    name: str
    sites: list[Site] = field(default_factory=list)
    geoms: list[WrapGeom] = field(default_factory=list)
    tendons: list[Tendon] = field(default_factory=list)
    #: Extra bodies (moving path points, conditional points' steps): (name, parent body[, position in it [m]]).
    point_bodies: list[tuple] = field(default_factory=list)
    #: ``{body: [(mesh asset name, file, R, p, scale)]}`` visual meshes.
    meshes: dict[str, list[tuple]] = field(default_factory=dict)
    #: Extra XML sections appended under the root (actuators, contact, ...).
    extra: list[ET.Element] = field(default_factory=list)
    timestep: float = 0.001
    #: Contact spheres: (body, position in the body [m], radius [m]).
    contacts: list[tuple[str, tuple[float, float, float], float]] = field(default_factory=list)
    #: Height of a floor plane (normal +Y) [m]; None: no floor.
    floor: float | None = None
    #: The floor as a treadmill belt: a heavy box (top at ``floor``) on a slide joint ``belt`` along x, whose
    #: speed the simulation sets.
    belt: bool = False
    #: Weld this body to a mocap body ``harness`` (which the simulation moves); None: no harness.
    harness: str | None = None
    #: Limit every coordinate's joint to the coordinate's range (default: only clamped coordinates).
    limit_all: bool = False
    #: Viscous damping of the coordinates' joints [N·m·s/rad or N·s/m].
    damping: float = 0.0


def safe(name: str) -> str:
    """A name MuJoCo accepts unchanged in references (letters, digits, ``_ - .``)."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def mjcf_document(osim: OsimModel, cmap: CoordinateMap, spec: MjcfSpec) -> str:
    """The MJCF text of the model."""
    root = ET.Element("mujoco", model=safe(spec.name))
    ET.SubElement(root, "compiler", angle="radian", inertiafromgeom="false", autolimits="true", meshdir=".",
                  balanceinertia="true")
    ET.SubElement(root, "option", timestep=_num(spec.timestep), gravity=_nums(GRAVITY), jacobian="dense",
                  integrator="implicitfast")
    if any(spec.meshes.values()):
        asset = ET.SubElement(root, "asset")
        seen = set()
        for items in spec.meshes.values():
            for name, file, _, _, scale in items:
                if name not in seen:
                    seen.add(name)
                    ET.SubElement(asset, "mesh", name=name, file=file, scale=_nums(scale), inertia="shell")
    world = ET.SubElement(root, "worldbody")
    elements = {"world": world}
    if spec.floor is not None and spec.belt:       # 20 m × 4 m × 0.1 m, 8 t: contacts barely slow it within a step
        belt = ET.SubElement(world, "body", name="belt", pos=_nums((0, spec.floor - 0.05, 0)))
        ET.SubElement(belt, "inertial", pos="0 0 0", mass="8000", diaginertia="10673 277333 266673")
        ET.SubElement(belt, "joint", name="belt", type="slide", axis="1 0 0")
        ET.SubElement(belt, "geom", name="floor", type="box", size="10 0.05 2", friction="1 0.005 0.0001",
                      rgba="0.8 0.8 0.8 1")
    elif spec.floor is not None:                     # a plane's normal is its z: turned onto +Y
        ET.SubElement(world, "geom", name="floor", type="plane", size="5 5 0.1", pos=_nums((0, spec.floor, 0)),
                      quat=_nums((np.sqrt(0.5), -np.sqrt(0.5), 0, 0)), friction="1 0.005 0.0001",
                      rgba="0.8 0.8 0.8 1")
    if spec.harness is not None:
        ET.SubElement(world, "body", name="harness", mocap="true")
    mass = {b.name: b for b in osim.bodies}
    pending = list(cmap.bodies)
    while pending:
        progress = False
        for bp in list(pending):
            if bp.parent not in elements:
                continue
            el = ET.SubElement(elements[bp.parent], "body", name=safe(bp.name), pos=_nums(bp.p), quat=_quat(bp.R))
            _inertial(el, mass.get(bp.name))
            elements[bp.name] = el
            pending.remove(bp)
            progress = True
        if not progress:
            raise ValueError(f"bodies without a path to ground: {[b.name for b in pending]}")
    for b in osim.bodies:       # bodies without a joint (none in OpenSim models: every body has one)
        if b.name not in elements:
            raise ValueError(f"body {b.name!r} has no joint")
    for name, parent, *pos in spec.point_bodies:
        el = ET.SubElement(elements[parent], "body", name=safe(name), **({"pos": _nums(pos[0])} if pos else {}))
        _inertial(el, None)
        elements[name] = el
    for name in cmap.aux_bodies:
        _inertial(ET.SubElement(world, "body", name=safe(name)), None)
        elements[name] = world[-1]
    for mj in cmap.joints:
        ET.SubElement(elements[mj.body], "joint", name=safe(mj.name), type=mj.kind, pos=_nums(mj.pos),
                      axis=_nums(mj.axis), **_limits(cmap, mj, spec))
    for body, items in spec.meshes.items():
        for name, _, R, p, _ in items:
            ET.SubElement(elements[body], "geom", type="mesh", mesh=name, pos=_nums(p), quat=_quat(R),
                          contype="0", conaffinity="0", group="1", rgba="0.89 0.85 0.79 1")
    for g in spec.geoms:
        ET.SubElement(elements["world" if g.body == GROUND else g.body], "geom", name=safe(g.name), type=g.kind,
                      size=_nums(g.size), pos=_nums(g.p), quat=_quat(g.R), contype="0", conaffinity="0",
                      group="3", rgba="0.3 0.5 0.9 0.3")
    for n, (body, pos, radius) in enumerate(spec.contacts):
        ET.SubElement(elements[body], "geom", name=f"contact{n}-{safe(body)}", type="sphere", size=_num(radius),
                      pos=_nums(pos), rgba="0.9 0.3 0.2 1", group="0", friction="1 0.005 0.0001")
    for s in spec.sites:
        ET.SubElement(elements["world" if s.body == GROUND else s.body], "site", name=safe(s.name),
                      pos=_nums(s.pos), size="0.004", group="2")
    ties = [mj for mj in cmap.joints if not mj.primary]
    if ties or spec.harness is not None:
        eq = ET.SubElement(root, "equality")
        if spec.harness is not None:
            ET.SubElement(eq, "weld", name="harness", body1="harness", body2=safe(spec.harness),
                          relpose="0 0 0 1 0 0 0", solref="0.02 1")
        for mj in ties:
            if mj.terms:                # v − Σ c·aux held at poly[0] (tendon_length0 is 0: qpos0 is 0)
                ET.SubElement(eq, "tendon", name=safe(f"tie_{mj.name}"), tendon1=safe(f"tie_{mj.name}"),
                              polycoef=_nums(mj.poly), solref="0.002 1")
                continue
            src = mj.source or cmap.joints[cmap.primary[mj.coordinate][0]].name
            ET.SubElement(eq, "joint", name=safe(f"tie_{mj.name}"), joint1=safe(mj.name), joint2=safe(src),
                          polycoef=_nums(mj.poly), solref="0.002 1")
    composed = [mj for mj in ties if mj.terms]
    if spec.tendons or composed:
        ten = ET.SubElement(root, "tendon")
        for mj in composed:
            el = ET.SubElement(ten, "fixed", name=safe(f"tie_{mj.name}"))
            ET.SubElement(el, "joint", joint=safe(mj.name), coef="1")
            for name, c in mj.terms.items():
                ET.SubElement(el, "joint", joint=safe(name), coef=_num(-c))
        for t in spec.tendons:
            el = ET.SubElement(ten, "spatial", name=safe(t.name), width="0.002")
            for item in t.path:
                if item[0] == "site":
                    ET.SubElement(el, "site", site=safe(item[1]))
                else:
                    attrs = {"geom": safe(item[1])}
                    if item[2]:
                        attrs["sidesite"] = safe(item[2])
                    ET.SubElement(el, "geom", **attrs)
    root.extend(spec.extra)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def _inertial(el: ET.Element, body) -> None:
    if body is None or body.mass <= 0:
        ET.SubElement(el, "inertial", pos="0 0 0", mass=_num(TINY_MASS), diaginertia=_nums([TINY_INERTIA] * 3))
        return
    I = inertia_matrix(body.inertia)
    lam, V = np.linalg.eigh(I)
    if lam.min() <= 0:                     # not a physical inertia: its eigenvalues raised (stated, inertia_issues)
        I = V @ np.diag(np.maximum(lam, TINY_INERTIA)) @ V.T
    vals = (I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2])
    ET.SubElement(el, "inertial", pos=_nums(body.mass_center), mass=_num(body.mass), fullinertia=_nums(vals))


def inertia_matrix(inertia) -> np.ndarray:
    """(3, 3) inertia matrix of OpenSim's (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) [kg·m²]."""
    xx, yy, zz, xy, xz, yz = (float(v) for v in inertia)
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def inertia_issues(osim: OsimModel) -> list[dict]:
    """Bodies whose inertia MuJoCo cannot take as it is, and what the conversion does: principal moments ≤ 0 are
    raised to :data:`TINY_INERTIA`; principal moments violating the triangle inequality A + B ≥ C are balanced
    by MuJoCo (``balanceinertia``)."""
    out = []
    for b in osim.bodies:
        if b.mass <= 0:
            out.append({"body": b.name, "issue": "no mass", "change": f"mass {TINY_MASS} kg"})
            continue
        lam = np.linalg.eigvalsh(inertia_matrix(b.inertia))
        if lam.min() <= 0:
            out.append({"body": b.name, "issue": f"principal moments {lam.tolist()}",
                        "change": f"raised to at least {TINY_INERTIA} kg·m²"})
        elif lam[0] + lam[1] < lam[2] * (1 - 1e-9):
            out.append({"body": b.name, "issue": f"principal moments {lam.tolist()} violate A + B >= C",
                        "change": "balanced by MuJoCo (compiler balanceinertia)"})
    return out


def _limits(cmap: CoordinateMap, mj, spec: MjcfSpec) -> dict[str, str]:
    if not mj.primary:
        return {}
    coord = cmap.osim.coordinate(mj.coordinate)
    extra = {"damping": _num(spec.damping)} if spec.damping else {}
    if not (coord.clamped or spec.limit_all) or mj.coordinate.startswith("pelvis_"):
        return extra
    _, a, b = cmap.primary[mj.coordinate]
    lo, hi = sorted((a * coord.range[0] + b, a * coord.range[1] + b))
    return {"range": _nums((lo, hi)), **extra}


def _quat(R: np.ndarray) -> str:
    """MuJoCo quaternion (w x y z) of a rotation matrix."""
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return _nums(q)


def _num(v: float) -> str:
    return repr(float(v))


def _nums(vals) -> str:
    return " ".join(_num(v) for v in np.asarray(vals, float).ravel())
