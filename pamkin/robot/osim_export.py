"""Write a PAM robot design as an OpenSim 4.x model (``.osim``).

:func:`design_to_osim` writes the skeleton (Gait2392 bodies, joints, coordinates) and every
PAM of a design, both sides, as an OpenSim ``PathActuator``. The file loads in OpenSim 4.x
(checked with OpenSim 4.6 by ``tests/test_osim_export.py``: the path lengths OpenSim computes
equal pamkin's to round-off), so a design can be inspected in the OpenSim GUI or simulated.

What is written:

* ``OpenSimDocument Version="40000"`` (the format of the Gait2392 file pamkin imports).
* Bodies with mass, mass centre and inertia, and their ``Mesh`` geometry under the same
  ``mesh_file`` names (OpenSim finds the bones once pointed at a ``Geometry`` folder).
* Every joint as a ``CustomJoint`` with parent/child ``PhysicalOffsetFrame`` s and a
  ``SpatialTransform`` of six ``TransformAxis`` with the functions the importer read
  (``Constant``, ``LinearFunction``, ``SimmSpline``, ``PolynomialFunction``,
  ``MultiplierFunction``); a ``PinJoint`` becomes the equivalent CustomJoint, a ``WeldJoint``
  stays a ``WeldJoint`` (a CustomJoint needs a coordinate).
* Coordinates with the robot's range of motion when ``rom`` is given (box limits; a coupled
  limit such as the thesis's flexion-dependent hip adduction is written as its envelope over
  the range of the coordinate it depends on, since OpenSim ranges are boxes), else the
  skeleton's ranges. Default values are the skeleton's, clamped into the range.
  ``clamped`` and ``locked`` are the skeleton's flags.
* Each PAM as ``PathActuator`` ``pamNN_r`` (the design's route) and ``pamNN_l`` (every point
  mirrored by :func:`pamkin.robot.design.mirror_point`) with a ``GeometryPath`` of ``PathPoint`` /
  ``ConditionalPathPoint`` / ``MovingPathPoint`` s. A ``MovingPathPoint`` component whose
  function is a constant has no coordinate in pamkin; OpenSim needs every socket connected,
  so it is connected to the coordinate of the point's other components (the constant
  ignores it). OpenSim 4.6 requires the three components to depend on one coordinate
  (pamkin does not): other points are refused with :class:`OsimExportError`.
* Each roller (:mod:`pamkin.robot.rollers`) as a ``WrapCylinder`` (quadrant ``+x``) in its body's
  ``WrapObjectSet`` and a ``PathWrap`` over its segment's two points; OpenSim's wrapped lengths equal
  pamkin's (tested).
* ``optimal_force`` = the PAM's maximum force at 620 kPa, F620(l0) (:func:`pamkin.robot.festo.f620`,
  the v3 model's isometric force at zero contraction) × ``n_parallel`` × its cable efficiency ÷ the transmission (a k:1
  block divides the route's tension by k, :mod:`pamkin.robot.design`); ``min_control`` 0,
  ``max_control`` 1. OpenSim's PathActuator tension is control × optimal_force, independent
  of length: a linear stand-in for the PAM, whose real force falls with contraction
  (:func:`pamkin.robot.festo.force`). An XML comment in each actuator states the diameter, resting
  length, parallel count, transmission, tendon and fitting lengths and the human muscles replaced.

Human muscles of the skeleton are not written (the robot has none).
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from pamkin.errors import DataFileError, PamkinError
from pamkin.human.rom import RangeOfMotion
from pamkin.outputs import write_file
from pamkin.opensim.functions import (
    Constant,
    LinearFunction,
    MultiplierFunction,
    PolynomialFunction,
    SimmSpline,
)
from pamkin.opensim.model_file import (
    GROUND,
    AnyPathPoint,
    ConditionalPathPoint,
    Coordinate,
    Joint,
    MovingPathPoint,
    OffsetFrame,
    OsimModel,
    TransformAxis,
)
from pamkin.opensim.wrapping import PathWrap, WrapObject
from pamkin.robot import festo
from pamkin.robot.design import Design, Pam, mirror_point, mirror_roller
from pamkin.robot.rollers import path_wraps

#: OpenSimDocument version written (the OpenSim 4.0 format; read by every 4.x release).
OSIM_VERSION = "40000"
#: Gravity written into the model [m/s²] (OpenSim's default; Gait2392 uses the same).
GRAVITY = (0.0, -9.80665, 0.0)
#: PathActuator colours by diameter (OpenSim's GUI draws the path in this colour).
_COLORS = {10: "0.2 0.6 1", 20: "0.1 0.8 0.2", 40: "0.9 0.5 0.1"}
_AXIS_NAMES = ("rotation1", "rotation2", "rotation3", "translation1", "translation2", "translation3")


class OsimExportError(PamkinError):
    """Writing an ``.osim`` file failed (e.g. the output is not writable)."""


# --------------------------------------------------------------------------- public API
def design_to_osim(design: Design, skeleton: OsimModel, path: str | os.PathLike, *,
                   rom: RangeOfMotion | None = None, name: str = "pam_biped") -> Path:
    """Write ``design`` on ``skeleton`` as an OpenSim 4.x ``.osim`` file (atomically).

    Args:
        design: The robot design (right side; the left side is mirrored).
        skeleton: The skeleton model (e.g. ``load_model_data(GAIT2392_DATA)``); its muscles
            are not written.
        path: Output ``.osim`` file.
        rom: Range of motion for the coordinate ranges (names of one side are used for the
            other side too); coordinates it does not limit keep the skeleton's range.
            ``None``: the skeleton's ranges.
        name: The OpenSim model name.

    Returns:
        The path written.

    Raises:
        DataFileError: The design names a body or coordinate the skeleton lacks, or has a
            non-finite number.
        OsimExportError: The design cannot be written in OpenSim's format (a MovingPathPoint
            whose components depend on different coordinates), or the file cannot be
            written. Nothing is written or left half-written then.
    """
    root = design_document(design, skeleton, rom=rom, name=name)
    text = _serialize(root)
    path = Path(path)
    if path.is_dir():
        raise OsimExportError(f"cannot write {path}: it is a folder")
    blocker = next((a for a in path.parents if a.exists()), None)
    if blocker is not None and not blocker.is_dir():
        raise OsimExportError(f"cannot write {path}: {blocker} is not a folder")
    try:
        write_file(path, text)
    except OSError as e:
        where = f" ({e.filename})" if e.filename and str(e.filename) != str(path) else ""
        raise OsimExportError(f"cannot write {path}: {e.strerror or e}{where}") from None
    return path


def design_document(design: Design, skeleton: OsimModel, *, rom: RangeOfMotion | None = None,
                    name: str = "pam_biped") -> ET.Element:
    """The ``<OpenSimDocument>`` element that :func:`design_to_osim` writes."""
    _check_design(design, skeleton)
    doc = ET.Element("OpenSimDocument", Version=OSIM_VERSION)
    model = ET.SubElement(doc, "Model", name=_safe_name(name))
    model.append(ET.Comment(_comment(
        f"Generated by pamkin from design {design.name!r} ({Path(design.path).name or 'in memory'}) on the "
        f"skeleton {skeleton.name!r}; coordinate ranges: "
        f"{'range of motion ' + repr(rom.name) if rom is not None else 'the skeleton ranges'}. "
        "Each PAM is a PathActuator; see its comment.")))
    ET.SubElement(model, "Ground", name=GROUND)
    _text(model, "gravity", _nums(GRAVITY))
    credits = f"PAM robot design {design.name!r} exported by pamkin."
    if skeleton.credits:
        credits += f" Skeleton {skeleton.name}: {skeleton.credits}"
    _text(model, "credits", credits)
    _text(model, "length_units", "meters")
    _text(model, "force_units", "N")

    bodyset = _set(model, "BodySet", "bodyset")
    for b in skeleton.bodies:
        bel = ET.SubElement(bodyset, "Body", name=b.name)
        if b.meshes:
            geo = ET.SubElement(bel, "attached_geometry")
            for k, m in enumerate(b.meshes, 1):
                mel = ET.SubElement(geo, "Mesh", name=f"{b.name}_geom_{k}")
                _text(mel, "socket_frame", "..")
                _text(mel, "scale_factors", _nums(m.scale_factors))
                _text(mel, "mesh_file", m.mesh_file)
        _text(bel, "mass", _num(b.mass))
        _text(bel, "mass_center", _nums(b.mass_center))
        _text(bel, "inertia", _nums(b.inertia))
        wraps = [pw.wrap_object for pws in _design_wraps(design).values() for pw in pws
                 if pw.wrap_object.body == b.name]
        if wraps:
            wos = ET.SubElement(bel, "WrapObjectSet", name="wrapobjectset")
            objs = ET.SubElement(wos, "objects")
            for wo in wraps:
                objs.append(_wrap_cylinder_element(wo))
            ET.SubElement(wos, "groups")

    jointset = _set(model, "JointSet", "jointset")
    coords = {c.name: c for c in skeleton.coordinates}
    for j in skeleton.joints:
        jointset.append(_joint_element(j, [coords[c] for c in j.coordinates], rom))

    forceset = _set(model, "ForceSet", "forceset")
    for side in ("r", "l"):
        for p in design.pams:
            forceset.append(_actuator_element(design, p, side, skeleton))
    return doc


def coordinate_range(coord: Coordinate, rom: RangeOfMotion | None) -> tuple[float, float]:
    """Range written for ``coord``: the ``rom`` box (or the envelope of a coupled limit), found
    under the coordinate's name or its other side's; else the skeleton's range."""
    if rom is None:
        return coord.range
    coupled = {c.coordinate: c for c in rom.coupled}
    for n in (coord.name, _other_side(coord.name)):
        if n in rom.limits:
            lo, hi = rom.limits[n]
            return (float(lo), float(hi))
        if n in coupled:
            c = coupled[n]
            dep = rom.limits.get(c.depends_on) or rom.limits.get(_other_side(c.depends_on)) or c.at
            lo_a, hi_a = c.limits(np.asarray(dep, float))
            return (float(np.min(lo_a)), float(np.max(hi_a)))
    return coord.range


def pam_optimal_force(pam: Pam) -> float:
    """``optimal_force`` written for a PAM: F620(resting length, diameter) × n_parallel × cable efficiency ÷
    transmission [N] (the route's tension)."""
    return (float(festo.f620(pam.resting_length_m, pam.diameter_mm)) * pam.n_parallel * pam.cable_efficiency
            / pam.transmission)


# --------------------------------------------------------------------------- elements
def _joint_element(j: Joint, coords: list[Coordinate], rom: RangeOfMotion | None) -> ET.Element:
    kind = "WeldJoint" if j.kind == "WeldJoint" else "CustomJoint"
    jel = ET.Element(kind, name=j.name)
    pname, cname = _frame_names(j)
    _text(jel, "socket_parent_frame", pname)
    _text(jel, "socket_child_frame", cname)
    if kind == "CustomJoint":
        cel = ET.SubElement(jel, "coordinates")
        for c in coords:
            lo, hi = coordinate_range(c, rom)
            el = ET.SubElement(cel, "Coordinate", name=c.name)
            _text(el, "default_value", _num(min(max(c.default_value, lo), hi)))
            _text(el, "default_speed_value", "0")
            _text(el, "range", _nums((lo, hi)))
            _text(el, "clamped", _flag(c.clamped))
            _text(el, "locked", _flag(c.locked))
    frames = ET.SubElement(jel, "frames")
    for fname, fr in ((pname, j.parent_frame), (cname, j.child_frame)):
        fel = ET.SubElement(frames, "PhysicalOffsetFrame", name=fname)
        _text(fel, "socket_parent", _body_path(fr.body))
        _text(fel, "translation", _nums(fr.translation))
        _text(fel, "orientation", _nums(fr.orientation))
    if kind == "CustomJoint":
        st = ET.SubElement(jel, "SpatialTransform")
        for a in _six_axes(j):
            ta = ET.SubElement(st, "TransformAxis", name=a.name)
            _text(ta, "coordinates", " ".join(a.coordinates))
            _text(ta, "axis", _nums(a.axis))
            ta.append(_function_element(a.function, name="function"))
    return jel


def _frame_names(j: Joint) -> tuple[str, str]:
    """Names of the joint's two offset frames: the imported names, made distinct and never a
    body name (a socket path naming a body would be ambiguous)."""
    def pick(fr: OffsetFrame, other: str | None) -> str:
        n = _safe_name(fr.name) if fr.name else ""
        if not n or n == fr.body or n == other:
            n = f"{fr.body}_offset"
        if n == other:
            n = f"{n}_child"
        return n
    p = pick(j.parent_frame, None)
    return p, pick(j.child_frame, p)


def _six_axes(j: Joint) -> list[TransformAxis]:
    """The joint's axes completed to OpenSim's six (missing ones constant 0); rotation axes of
    missing entries are chosen not parallel to the present ones (OpenSim would replace them)."""
    have = {a.name: a for a in j.axes}
    used = [np.asarray(a.axis, float) for a in j.axes if a.is_rotation]
    out = []
    for an in _AXIS_NAMES:
        if an in have:
            out.append(have[an])
            continue
        if an.startswith("rotation"):
            axis = None
            for cand in np.eye(3):
                if all(abs(abs(float(np.dot(cand, u))) - 1.0) > 1e-9 for u in used):
                    axis = cand
                    break
            used.append(axis)
        else:
            axis = np.eye(3)[int(an[-1]) - 1]
        out.append(TransformAxis(an, (), tuple(float(v) for v in axis), Constant(0.0)))
    return out


def _actuator_element(design: Design, p: Pam, side: str, skeleton: OsimModel) -> ET.Element:
    pts = p.points if side == "r" else tuple(mirror_point(pt) for pt in p.points)
    key = f"{p.key}_{side}"
    f_max = pam_optimal_force(p)
    act = ET.Element("PathActuator", name=key)
    humans = ", ".join(m if side == "r" else _left(m) for m in p.human_muscles)
    act.append(ET.Comment(_comment(
        f"PAM {p.id} {p.name!r} ({'right' if side == 'r' else 'left, mirrored'} side): Festo DMSP "
        f"{p.diameter_mm} mm, resting length {p.resting_length_m:.6g} m (each PAM, fittings excluded), "
        f"{p.n_parallel} in parallel, artificial tendon {p.tendon_length_m:.6g} m, fittings 2 x "
        f"{design.fitting_length_m:.6g} m"
        f"{f', a {p.transmission}:1 pulley block (the route moves {p.transmission} x the PAM stroke)' if p.transmission != 1 else ''}"
        f"; replaces {humans}. optimal_force = F620(resting length) x "
        f"n_parallel / transmission = {f_max:.6g} N, the maximum force at 620 kPa (pamkin.robot.festo.f620, zero contraction); "
        f"OpenSim's tension = control x optimal_force, control in [0, 1], independent of length (the real "
        f"PAM force falls with contraction).")))
    _text(act, "appliesForce", "true")
    _text(act, "min_control", "0")
    _text(act, "max_control", "1")
    gp = ET.SubElement(act, "GeometryPath", name="geometrypath")
    pps = ET.SubElement(gp, "PathPointSet")
    objs = ET.SubElement(pps, "objects")
    names: set[str] = set()
    for k, pt in enumerate(pts, 1):
        nm = f"{key}-{_safe_name(pt.name) or f'P{k}'}"
        if nm in names:
            nm = f"{nm}_{k}"
        names.add(nm)
        objs.append(_point_element(pt, nm, skeleton))
    ET.SubElement(pps, "groups")
    pws = ET.SubElement(gp, "PathWrapSet")
    pwo = ET.SubElement(pws, "objects")
    for pw in _design_wraps(design).get((p.id, side), []):
        el = ET.SubElement(pwo, "PathWrap", name=pw.name)
        _text(el, "wrap_object", pw.wrap_object.name)
        _text(el, "method", pw.method)
        _text(el, "range", " ".join(str(int(v)) for v in pw.range))
    ET.SubElement(pws, "groups")
    app = ET.SubElement(gp, "Appearance")
    _text(app, "color", _COLORS.get(p.diameter_mm, "0.8 0.1 0.1"))
    _text(act, "optimal_force", _num(f_max))
    return act


def _design_wraps(design: Design) -> dict[tuple[int, str], list[PathWrap]]:
    """Per (PAM id, side) the PathWraps of its rollers (:mod:`pamkin.robot.rollers`), wrap objects named
    ``pamNN_{side}_rollerK``."""
    out = {}
    for p in design.pams:
        if not p.rollers:
            continue
        for side in ("r", "l"):
            pts = p.points if side == "r" else tuple(mirror_point(pt) for pt in p.points)
            rs = p.rollers if side == "r" else tuple(mirror_roller(r) for r in p.rollers)
            out[(p.id, side)] = path_wraps([f"{a.name}->{b.name}" for a, b in zip(pts[:-1], pts[1:])], rs,
                                           f"{p.key}_{side}")
    return out


def _wrap_cylinder_element(wo: WrapObject) -> ET.Element:
    """A roller's ``<WrapCylinder>`` (orientation as OpenSim's body-fixed X-Y-Z Euler angles)."""
    el = ET.Element("WrapCylinder", name=wo.name)
    _text(el, "active", _flag(wo.active))
    _text(el, "xyz_body_rotation", _nums(xyz_body_fixed_angles(np.asarray(wo.rotation, float))))
    _text(el, "translation", _nums(wo.translation))
    _text(el, "quadrant", wo.quadrant)
    _text(el, "radius", _num(wo.dimensions[0]))
    _text(el, "length", _num(wo.dimensions[1]))
    return el


def xyz_body_fixed_angles(R: np.ndarray) -> tuple[float, float, float]:
    """Body-fixed X-Y-Z Euler angles [rad] of a rotation matrix (the inverse of
    :func:`pamkin.opensim.model_file.rotation_xyz_body_fixed`: R = Rx(a)·Ry(b)·Rz(c))."""
    b = math.asin(max(-1.0, min(1.0, float(R[0, 2]))))
    if abs(R[0, 2]) < 1 - 1e-12:
        a = math.atan2(-R[1, 2], R[2, 2])
        c = math.atan2(-R[0, 1], R[0, 0])
    else:               # gimbal lock: c folded into a
        a = math.atan2(R[2, 1], R[1, 1])
        c = 0.0
    return a, b, c


def _point_element(pt: AnyPathPoint, name: str, skeleton: OsimModel) -> ET.Element:
    if isinstance(pt, MovingPathPoint):
        el = ET.Element("MovingPathPoint", name=name)
        _text(el, "socket_parent_frame", _body_path(pt.body))
        given = [c for c in pt.coordinates if c]
        fallback = given[0] if given else _body_coordinate(pt.body, skeleton)
        for axis, cn in zip("xyz", pt.coordinates):
            _text(el, f"socket_{axis}_coordinate", _coordinate_path(cn or fallback, skeleton))
        for axis, fn in zip("xyz", pt.functions):
            loc = ET.SubElement(el, f"{axis}_location")
            loc.append(_function_element(fn))
        return el
    if isinstance(pt, ConditionalPathPoint):
        el = ET.Element("ConditionalPathPoint", name=name)
        _text(el, "socket_parent_frame", _body_path(pt.body))
        _text(el, "location", _nums(pt.location))
        _text(el, "socket_coordinate", _coordinate_path(pt.coordinate, skeleton))
        _text(el, "range", _nums(pt.range))
        return el
    el = ET.Element("PathPoint", name=name)
    _text(el, "socket_parent_frame", _body_path(pt.body))
    _text(el, "location", _nums(pt.location))
    return el


def _function_element(fn, name: str | None = None) -> ET.Element:
    attrs = {"name": name} if name else {}
    if isinstance(fn, Constant):
        el = ET.Element("Constant", attrs)
        _text(el, "value", _num(fn.c))
    elif isinstance(fn, LinearFunction):
        el = ET.Element("LinearFunction", attrs)
        _text(el, "coefficients", _nums((fn.slope, fn.intercept)))
    elif isinstance(fn, SimmSpline):
        el = ET.Element("SimmSpline", attrs)
        _text(el, "x", _nums(fn.x))
        _text(el, "y", _nums(fn.y))
    elif isinstance(fn, PolynomialFunction):
        el = ET.Element("PolynomialFunction", attrs)
        _text(el, "coefficients", _nums(fn.coefficients))
    elif isinstance(fn, MultiplierFunction):
        el = ET.Element("MultiplierFunction", attrs)
        inner = ET.SubElement(el, "function")
        inner.append(_function_element(fn.function))
        _text(el, "scale", _num(fn.scale))
    else:
        raise TypeError(f"cannot write function {fn!r} to OpenSim")
    return el


# --------------------------------------------------------------------------- checks and helpers
def _check_design(design: Design, skeleton: OsimModel) -> None:
    """The design's bodies and coordinates exist in the skeleton and its numbers are finite."""
    where_file = design.path or "<design>"
    bodies = {b.name for b in skeleton.bodies} | {GROUND}
    coords = {c.name for c in skeleton.coordinates}
    for side in ("r", "l"):
        for p in design.pams:
            pts = p.points if side == "r" else tuple(mirror_point(pt) for pt in p.points)
            where = f"PAM {p.id} ({p.name!r}), {'right' if side == 'r' else 'left (mirrored)'} side"
            if not (math.isfinite(p.resting_length_m) and p.resting_length_m > 0):
                raise DataFileError(where_file, f"{where}: resting_length_m must be a positive length")
            if not math.isfinite(p.tendon_length_m):
                raise DataFileError(where_file, f"{where}: tendon_length_m must be finite")
            for pt in pts:
                if pt.body not in bodies:
                    raise DataFileError(where_file, f"{where}: route point {pt.name!r} is on body {pt.body!r}, "
                                                    f"which the skeleton {skeleton.name!r} lacks")
                used = list(pt.coordinates) if isinstance(pt, MovingPathPoint) else (
                    [pt.coordinate] if isinstance(pt, ConditionalPathPoint) else [])
                bad = [c for c in used if c and c not in coords]
                if bad:
                    raise DataFileError(where_file, f"{where}: route point {pt.name!r} uses unknown "
                                                    f"coordinate(s) {bad}")
                if isinstance(pt, MovingPathPoint):
                    for fn, cn in zip(pt.functions, pt.coordinates):
                        if not cn and not fn.is_constant:
                            raise DataFileError(where_file, f"{where}: route point {pt.name!r} has a "
                                                            "non-constant function without a coordinate")
                    if len({c for c in pt.coordinates if c}) > 1:
                        raise OsimExportError(
                            f"{where_file}: {where}: MovingPathPoint {pt.name!r} depends on coordinates "
                            f"{sorted({c for c in pt.coordinates if c})}; OpenSim requires its x, y and z "
                            "locations to depend on one coordinate")
                elif not all(math.isfinite(v) for v in pt.location):
                    raise DataFileError(where_file, f"{where}: route point {pt.name!r} has a non-finite location")


def _body_coordinate(body: str, skeleton: OsimModel) -> str:
    """A coordinate for a MovingPathPoint whose three functions are constants: the first one
    of the joint moving ``body`` (else the model's first)."""
    for j in skeleton.joints:
        if j.child == body and j.coordinates:
            return j.coordinates[0]
    return skeleton.coordinates[0].name


def _coordinate_path(name: str, skeleton: OsimModel) -> str:
    return f"/jointset/{skeleton.coordinate(name).joint}/{name}"


def _body_path(body: str) -> str:
    return "/ground" if body == GROUND else f"/bodyset/{body}"


def _other_side(name: str) -> str:
    if name.endswith("_r"):
        return name[:-2] + "_l"
    if name.endswith("_l"):
        return name[:-2] + "_r"
    return name


def _left(name: str) -> str:
    return name[:-2] + "_l" if name.endswith("_r") else name


def _safe_name(name: str) -> str:
    """A component name OpenSim accepts (no path separators, spaces or other specials)."""
    return re.sub(r"[^A-Za-z0-9_.\-]", "_", str(name))


def _comment(text: str) -> str:
    """Text safe inside an XML comment (no ``--``, no trailing ``-``)."""
    text = str(text)
    while "--" in text:
        text = text.replace("--", "- -")
    return f" {text} "


def _num(v: float) -> str:
    v = float(v)
    if not math.isfinite(v):
        raise ValueError(f"non-finite number {v} cannot be written to OpenSim")
    return repr(v)  # shortest text that reads back to the same double


def _nums(vals: Iterable[float]) -> str:
    return " ".join(_num(v) for v in vals)


def _flag(v: bool) -> str:
    return "true" if v else "false"


def _text(parent: ET.Element, tag: str, text: str) -> ET.Element:
    el = ET.SubElement(parent, tag)
    el.text = text
    return el


def _set(model: ET.Element, tag: str, name: str) -> ET.Element:
    s = ET.SubElement(model, tag, name=name)
    objs = ET.SubElement(s, "objects")
    ET.SubElement(s, "groups")
    return objs


def _serialize(root: ET.Element) -> str:
    ET.indent(root, space="\t")
    return '<?xml version="1.0" encoding="UTF-8" ?>\n' + ET.tostring(root, encoding="unicode") + "\n"
