"""Read an OpenSim 4.x ``.osim`` model file into typed Python objects.

Supported:

* ``Body`` (mass properties and attached ``Mesh`` geometry), ``Ground``, and
  ``PhysicalOffsetFrame`` components of bodies and ground (path points and joints may use them).
* Joints: ``CustomJoint`` with ``SpatialTransform`` (``TransformAxis`` with ``Constant``,
  ``LinearFunction``, ``SimmSpline``, ``PolynomialFunction``, ``MultiplierFunction``),
  ``PinJoint``, ``SliderJoint``, ``UniversalJoint``, ``GimbalJoint``, ``BallJoint``,
  ``FreeJoint``, ``PlanarJoint``, ``WeldJoint`` (each read as the equivalent sequence of
  TransformAxes, see :data:`JOINT_AXES`); parent/child ``PhysicalOffsetFrame`` with translation
  and body-fixed XYZ orientation.
* ``Coordinate`` (name, range, default value, locked, clamped).
* ``CoordinateCouplerConstraint`` (one independent coordinate): the dependent coordinate is
  ``scale_factor · f(independent)``.
* Muscles ``Thelen2003Muscle`` and ``Millard2012EquilibriumMuscle`` with
  ``PathPoint``, ``ConditionalPathPoint`` and ``MovingPathPoint`` paths (points on bodies, ground
  or offset frames); every other path-bearing force (``PathActuator``, :data:`PATH_ONLY_CLASSES`:
  ``PathSpring``, other muscle classes) loads as a path of its class: lengths and moment arms
  (static forces of ``PathActuator`` and ``PathSpring`` too, no forces of the other classes).
* ``FunctionBasedPath`` in place of a ``GeometryPath`` (OpenSim 4.5+): coordinates, a
  ``MultivariatePolynomialFunction`` (or a scalar function of one coordinate) for the length, optional
  moment-arm functions (:class:`FunctionPath`).

Forces without a path (coordinate actuators, limit forces, bushings, contact, springs),
contact geometry, controllers, probes and markers cannot change kinematics or muscle paths:
they are skipped with one :class:`SkippedComponentsWarning` listing them.
* Wrap objects ``WrapCylinder``, ``WrapSphere``, ``WrapEllipsoid``, ``WrapTorus`` (on bodies, ground or offset
  frames) and paths' ``PathWrap`` entries (method, range), computed as OpenSim 4.6 does
  (:mod:`pamkin.opensim.wrapping`).

Anything else that changes kinematics or muscle paths (obstacle-set wraps, other constraints,
other joint, function or path-point types) raises
:class:`~pamkin.errors.UnsupportedFeatureError` naming the file, the element and
the component: pamkin never approximates silently.
"""

from __future__ import annotations

import math
import re
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pamkin.errors import OsimError, UnsupportedFeatureError
from pamkin.opensim.functions import (
    Constant,
    CoordinateFunction,
    LinearFunction,
    MultiplierFunction,
    MultivariatePolynomial,
    OneVariable,
    PolynomialFunction,
    ScalarFunction,
    SimmSpline,
)
from pamkin.opensim.wrapping import KIND_CODE, METHOD_CODE, PathWrap, WrapObject

GROUND = "ground"

#: Muscle classes whose parameters pamkin reads.
MUSCLE_CLASSES = ("Thelen2003Muscle", "Millard2012EquilibriumMuscle")
#: Path actuators read like muscles (their path; ``optimal_force`` and the control range as
#: parameters): lengths, moment arms and forces (optimal_force × control, as OpenSim's
#: ``computeActuation``). ``pamkin export-osim`` writes PAMs as PathActuators.
PATH_ACTUATOR_CLASSES = ("PathActuator",)
#: Other forces with a ``GeometryPath`` that load as paths (lengths and moment arms); of these, ``PathSpring``
#: has forces too (stiffness × max(0, L − resting_length) at zero speed, OpenSim's ``getTension``).
PATH_ONLY_CLASSES = ("PathSpring", "Schutte1993Muscle_Deprecated", "Delp1990Muscle_Deprecated",
                     "Thelen2003Muscle_Deprecated", "RigidTendonMuscle", "DeGrooteFregly2016Muscle",
                     "Millard2012AccelerationMuscle", "McKibbenActuator", "Ligament",
                     "Blankevoort1991Ligament")
#: Scalar properties read from path-only forces when present.
PATH_ONLY_PROPERTIES = ("max_isometric_force", "optimal_fiber_length", "tendon_slack_length",
                        "pennation_angle_at_optimal", "optimal_force", "resting_length", "stiffness",
                        "dissipation")

#: The TransformAxes equivalent to OpenSim's fixed joint types: (axis name, unit axis, index of the
#: joint's coordinate). Translations act along axes of the parent frame F, rotations are body-fixed
#: in the listed order (Simbody's Pin, Slider, Universal, Gimbal and Ball/Free with Euler angles,
#: Planar: rotation about Z then translation in F's X-Y plane).
JOINT_AXES: dict[str, tuple[tuple[str, tuple[float, float, float], int], ...]] = {
    "PinJoint": (("rotation1", (0.0, 0.0, 1.0), 0),),
    "SliderJoint": (("translation1", (1.0, 0.0, 0.0), 0),),
    "UniversalJoint": (("rotation1", (1.0, 0.0, 0.0), 0), ("rotation2", (0.0, 1.0, 0.0), 1)),
    "GimbalJoint": (("rotation1", (1.0, 0.0, 0.0), 0), ("rotation2", (0.0, 1.0, 0.0), 1),
                    ("rotation3", (0.0, 0.0, 1.0), 2)),
    "BallJoint": (("rotation1", (1.0, 0.0, 0.0), 0), ("rotation2", (0.0, 1.0, 0.0), 1),
                  ("rotation3", (0.0, 0.0, 1.0), 2)),
    "FreeJoint": (("rotation1", (1.0, 0.0, 0.0), 0), ("rotation2", (0.0, 1.0, 0.0), 1),
                  ("rotation3", (0.0, 0.0, 1.0), 2), ("translation1", (1.0, 0.0, 0.0), 3),
                  ("translation2", (0.0, 1.0, 0.0), 4), ("translation3", (0.0, 0.0, 1.0), 5)),
    "PlanarJoint": (("rotation1", (0.0, 0.0, 1.0), 0), ("translation1", (1.0, 0.0, 0.0), 1),
                    ("translation2", (0.0, 1.0, 0.0), 2)),
    "WeldJoint": (),
}
JOINT_CLASSES = ("CustomJoint",) + tuple(JOINT_AXES)


class SkippedComponentsWarning(UserWarning):
    """Components of an ``.osim`` file that cannot change kinematics or muscle paths were skipped."""

#: PathActuator properties (name in the file -> OpenSim's default when absent).
PATH_ACTUATOR_PROPERTIES: dict[str, float] = {"optimal_force": 1.0, "min_control": -math.inf,
                                               "max_control": math.inf}

#: Thelen2003Muscle properties (name in the file -> default when absent).
THELEN_PROPERTIES: dict[str, float] = {
    "max_isometric_force": math.nan,
    "optimal_fiber_length": math.nan,
    "tendon_slack_length": math.nan,
    "pennation_angle_at_optimal": 0.0,
    "max_contraction_velocity": 10.0,
    "activation_time_constant": 0.015,
    "deactivation_time_constant": 0.05,
    "FmaxTendonStrain": 0.04,
    "FmaxMuscleStrain": 0.6,
    "KshapeActive": 0.45,
    "KshapePassive": 5.0,
    "Af": 0.25,
    "Flen": 1.4,
    "fv_linear_extrap_threshold": 0.95,
    "maximum_pennation_angle": math.acos(0.1),
    "minimum_activation": 0.01,
}

#: Millard2012EquilibriumMuscle scalar properties read (curves keep OpenSim defaults).
MILLARD_PROPERTIES: dict[str, float] = {
    "max_isometric_force": math.nan,
    "optimal_fiber_length": math.nan,
    "tendon_slack_length": math.nan,
    "pennation_angle_at_optimal": 0.0,
    "max_contraction_velocity": 10.0,
    "minimum_activation": 0.01,
    "maximum_pennation_angle": math.acos(0.1),
}


@dataclass(frozen=True)
class OffsetFrame:
    """A frame fixed in a body: X_body_frame = (R, p).

    Attributes:
        name: Frame name.
        body: Name of the body (or ``"ground"``) the frame is fixed in.
        translation: Origin of the frame in the body frame [m].
        orientation: Body-fixed X-Y-Z Euler angles of the frame relative to the body [rad].
    """

    name: str
    body: str
    translation: tuple[float, float, float]
    orientation: tuple[float, float, float]

    def transform(self) -> np.ndarray:
        """Homogeneous transform (4, 4) from this frame to its body frame."""
        T = np.eye(4)
        T[:3, :3] = rotation_xyz_body_fixed(self.orientation)
        T[:3, 3] = self.translation
        return T


@dataclass(frozen=True)
class TransformAxis:
    """One of a CustomJoint's six ``TransformAxis`` (rotation1-3, translation1-3).

    Attributes:
        name: ``rotation1`` ... ``translation3``.
        coordinates: Names of the coordinates the function takes (0 or 1 supported).
        axis: Unit axis (rotation axes in the successively rotated frame, translation
            axes in the parent offset frame).
        function: The function of the coordinate giving the angle [rad] or displacement [m].
    """

    name: str
    coordinates: tuple[str, ...]
    axis: tuple[float, float, float]
    function: ScalarFunction

    @property
    def is_rotation(self) -> bool:
        return self.name.startswith("rotation")


@dataclass(frozen=True)
class Coordinate:
    """A generalized coordinate.

    Attributes:
        name: Coordinate name.
        joint: Name of the joint owning it.
        range: (min, max) [rad or m].
        default_value: Default value [rad or m].
        locked: OpenSim's ``locked`` flag.
        clamped: OpenSim's ``clamped`` flag.
        rotational: True for rotational (radians), False for translational (metres).
    """

    name: str
    joint: str
    range: tuple[float, float]
    default_value: float
    locked: bool
    clamped: bool
    rotational: bool


@dataclass(frozen=True)
class CoordinateCoupler:
    """A ``CoordinateCouplerConstraint``: ``dependent = scale_factor · function(independent)``.

    Attributes:
        name: Constraint name.
        dependent: The dependent coordinate.
        independent: The independent coordinate.
        function: The coupling function.
        scale_factor: OpenSim's ``scale_factor``.
    """

    name: str
    dependent: str
    independent: str
    function: ScalarFunction
    scale_factor: float = 1.0

    def value(self, x: np.ndarray) -> np.ndarray:
        return self.scale_factor * self.function.value(x)

    def derivative(self, x: np.ndarray) -> np.ndarray:
        return self.scale_factor * self.function.derivative(x)


@dataclass(frozen=True)
class Joint:
    """A joint between a parent and a child body.

    The joint maps the child offset frame M to the parent offset frame F by
    X_FM(q): translations (along translation axes in F) followed by the rotation
    sequence rotation1 · rotation2 · rotation3 (body-fixed). ``PinJoint`` is a
    single rotation about the frames' Z axis and ``WeldJoint`` has no axes.

    Attributes:
        name: Joint name.
        kind: The OpenSim class (``"CustomJoint"``, ``"PinJoint"``, ... see :data:`JOINT_CLASSES`).
        parent_frame: Joint frame F, fixed in the parent body.
        child_frame: Joint frame M, fixed in the child body.
        axes: Transform axes in OpenSim order (translations first when applied).
        coordinates: Coordinates owned by this joint.
    """

    name: str
    kind: str
    parent_frame: OffsetFrame
    child_frame: OffsetFrame
    axes: tuple[TransformAxis, ...]
    coordinates: tuple[str, ...]

    @property
    def parent(self) -> str:
        return self.parent_frame.body

    @property
    def child(self) -> str:
        return self.child_frame.body


@dataclass(frozen=True)
class MeshGeometry:
    """A mesh attached to a body.

    Attributes:
        mesh_file: File name as written in the model (e.g. ``femur_r.vtp``).
        scale_factors: Scale factors along the frame axes.
        frame: Frame the mesh is attached to (fixed in its body).
    """

    mesh_file: str
    scale_factors: tuple[float, float, float]
    frame: OffsetFrame


@dataclass(frozen=True)
class Body:
    """A rigid body.

    Attributes:
        name: Body name.
        mass: Mass [kg].
        mass_center: Centre of mass in the body frame [m].
        inertia: (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) about the centre of mass [kg·m²].
        meshes: Attached meshes.
    """

    name: str
    mass: float
    mass_center: tuple[float, float, float]
    inertia: tuple[float, float, float, float, float, float]
    meshes: tuple[MeshGeometry, ...] = ()


@dataclass(frozen=True)
class PathPoint:
    """A path point fixed in a body.

    Attributes:
        name: Point name.
        body: Body the point is fixed in.
        location: Location in the body frame [m].
    """

    name: str
    body: str
    location: tuple[float, float, float]


@dataclass(frozen=True)
class ConditionalPathPoint(PathPoint):
    """A fixed point that is part of the path only while ``coordinate`` lies in ``range``.

    OpenSim includes it when range[0] − 1e-5 ≤ q ≤ range[1] + 1e-5.
    """

    coordinate: str = ""
    range: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class MovingPathPoint:
    """A point whose location in its body is a function of coordinates.

    Attributes:
        name: Point name.
        body: Body the point moves in.
        functions: (f_x, f_y, f_z) giving the location components [m].
        coordinates: Names of the coordinates of f_x, f_y and f_z.
    """

    name: str
    body: str
    functions: tuple[ScalarFunction, ScalarFunction, ScalarFunction]
    coordinates: tuple[str, str, str]


AnyPathPoint = PathPoint | ConditionalPathPoint | MovingPathPoint


@dataclass(frozen=True)
class FunctionPath:
    """An OpenSim ``FunctionBasedPath``: the path length as a function of some coordinates.

    Attributes:
        coordinates: The coordinates the functions take, in argument order (names).
        length: Length l(q) [m].
        moment_arms: One function per coordinate giving its moment arm [m or m/m], or empty:
            then the moment arms are −∂l/∂q (OpenSim's rule).
    """

    coordinates: tuple[str, ...]
    length: CoordinateFunction
    moment_arms: tuple[CoordinateFunction, ...] = ()


@dataclass(frozen=True)
class Muscle:
    """A musculotendon actuator with a straight-line path.

    Attributes:
        name: Muscle name.
        kind: OpenSim class (``Thelen2003Muscle``, ``Millard2012EquilibriumMuscle`` or ``PathActuator``).
        points: Path points in order (origin first); empty for a function-based path.
        params: Scalar properties by OpenSim property name (SI units).
        wraps: The path's PathWrapSet (wrap objects it may wrap over), in order.
        function_path: The ``FunctionBasedPath`` that replaces the points, or None.
    """

    name: str
    kind: str
    points: tuple[AnyPathPoint, ...]
    params: dict[str, float] = field(hash=False, compare=False)
    wraps: tuple[PathWrap, ...] = ()
    function_path: FunctionPath | None = None


@dataclass(frozen=True)
class OsimModel:
    """An imported OpenSim model.

    Attributes:
        path: The ``.osim`` file.
        name: Model name.
        bodies: Bodies in file order (ground excluded).
        joints: Joints in file order.
        coordinates: Coordinates in OpenSim's CoordinateSet order (joint order, then
            order within each joint).
        muscles: Muscles (and other path-bearing forces) in ForceSet order.
        credits: The model's credits string.
        couplers: CoordinateCouplerConstraints (dependent coordinates follow them).
        skipped: ``"Class name"`` of every component skipped on import.
    """

    path: str
    name: str
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    coordinates: tuple[Coordinate, ...]
    muscles: tuple[Muscle, ...]
    credits: str = ""
    couplers: tuple[CoordinateCoupler, ...] = ()
    skipped: tuple[str, ...] = ()

    def coordinate(self, name: str) -> Coordinate:
        """The coordinate called ``name`` (KeyError listing valid names otherwise)."""
        for c in self.coordinates:
            if c.name == name:
                return c
        raise KeyError(f"no coordinate {name!r}; valid: {[c.name for c in self.coordinates]}")

    def body(self, name: str) -> Body:
        """The body called ``name``."""
        for b in self.bodies:
            if b.name == name:
                return b
        raise KeyError(f"no body {name!r}; valid: {[b.name for b in self.bodies]}")


def rotation_xyz_body_fixed(angles) -> np.ndarray:
    """Rotation matrix of body-fixed X-Y-Z Euler angles (OpenSim frame orientation) [rad]."""
    a, b, c = (float(v) for v in angles)
    return _rot([1, 0, 0], a) @ _rot([0, 1, 0], b) @ _rot([0, 0, 1], c)


def _rot(axis, angle: float) -> np.ndarray:
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * (K @ K)


# --------------------------------------------------------------------------- parsing


class _Reader:
    """Parsing context: the file path for error messages."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def err(self, msg: str, el: ET.Element | None = None, unsupported: bool = False) -> OsimError:
        cls = UnsupportedFeatureError if unsupported else OsimError
        return cls(str(self.path), msg, element=None if el is None else el.tag,
                   component=None if el is None else el.get("name"))

    def text(self, el: ET.Element, tag: str, default: str | None = None) -> str:
        child = el.find(tag)
        if child is None or child.text is None:
            if default is not None:
                return default
            raise self.err(f"missing <{tag}>", el)
        return child.text.strip()

    def floats(self, el: ET.Element, tag: str, n: int | None = None,
               default: str | None = None, allow_inf: bool = False) -> tuple[float, ...]:
        raw = self.text(el, tag, default)
        try:
            vals = tuple(float(v) for v in raw.split())
        except ValueError:
            raise self.err(f"<{tag}> is not a list of numbers: {raw!r}", el) from None
        if n is not None and len(vals) != n:
            raise self.err(f"<{tag}> must have {n} numbers, has {len(vals)}", el)
        if not all(math.isfinite(v) or (allow_inf and not math.isnan(v)) for v in vals):
            raise self.err(f"<{tag}> has a non-finite number: {raw!r}", el)
        return vals

    def flag(self, el: ET.Element, tag: str, default: bool) -> bool:
        raw = self.text(el, tag, "true" if default else "false").lower()
        if raw not in ("true", "false", "1", "0"):
            raise self.err(f"<{tag}> must be true or false, is {raw!r}", el)
        return raw in ("true", "1")

    def function(self, el: ET.Element, owner: ET.Element) -> ScalarFunction:
        tag = el.tag
        if tag == "Constant":
            return Constant(self.floats(el, "value", 1)[0])
        if tag == "LinearFunction":
            coefs = self.floats(el, "coefficients", 2)
            return LinearFunction(coefs[0], coefs[1])
        if tag == "SimmSpline":
            x, y = self.floats(el, "x"), self.floats(el, "y")
            if len(x) != len(y) or len(x) < 2:
                raise self.err(f"SimmSpline needs >= 2 equal-length x and y, has {len(x)}, {len(y)}", owner)
            if any(b <= a for a, b in zip(x, x[1:])):
                raise self.err("SimmSpline x values must increase", owner)
            return SimmSpline(x, y)
        if tag == "PolynomialFunction":
            return PolynomialFunction(self.floats(el, "coefficients"))
        if tag == "MultiplierFunction":
            inner = el.find("function")
            inner_fn = None
            if inner is not None:
                children = list(inner)
                if len(children) == 1:
                    inner_fn = self.function(children[0], owner)
            if inner_fn is None:
                raise self.err("MultiplierFunction without a single inner <function>", owner)
            return MultiplierFunction(inner_fn, self.floats(el, "scale", 1, "1")[0])
        raise self.err(f"function type <{tag}> is not supported", owner, unsupported=True)


def _last(path_text: str) -> str:
    """Last element of an OpenSim socket path (``/bodyset/femur_r`` -> ``femur_r``)."""
    return path_text.strip().rstrip("/").split("/")[-1]


def load_osim_file(path: str | Path) -> OsimModel:
    """Parse an OpenSim 4.x ``.osim`` file.

    Args:
        path: The ``.osim`` file.

    Returns:
        The model's bodies, joints, coordinates and muscles.

    Raises:
        OsimError: The file is missing, not well-formed XML, or inconsistent
            (e.g. a joint names a body that does not exist).
        UnsupportedFeatureError: The model uses a feature pamkin does not implement.
    """
    path = Path(path)
    rd = _Reader(path)
    if not path.is_file():
        raise OsimError(str(path), "file not found")
    try:
        # OpenSim writes tags such as <HuntCrossleyForce::ContactParametersSet>, which XML parsers
        # reject: rename them (pamkin never reads them)
        text = _NESTED_TAG.sub(r"\1\2__\3", path.read_bytes().decode("utf-8", errors="replace"))
        root = ET.fromstring(text)
    except ET.ParseError as e:
        raise OsimError(str(path), f"not a well-formed .osim (XML) file: {e}") from None
    model_el = root.find("Model") if root.tag == "OpenSimDocument" else None
    if model_el is None:
        raise OsimError(str(path), "no <OpenSimDocument><Model> element")
    try:
        version = int(root.get("Version", "0") or 0)
    except ValueError:
        version = 0
    if version < 40000:
        raise UnsupportedFeatureError(
            str(path), f"OpenSimDocument Version {version or '(none)'} predates OpenSim 4.0; pamkin reads "
            "OpenSim 4.x files. Convert it with OpenSim 4: `opensim-cmd update-file OLD.osim NEW.osim`, or "
            "in Python `opensim.Model('OLD.osim').printToXML('NEW.osim')`, or open it in the OpenSim 4 "
            "application and save it again", element="OpenSimDocument")

    skipped: list[str] = []
    frames = _read_frames(rd, model_el)
    wrap_objects = _read_wrap_objects(rd, model_el, frames)
    bodies = _read_bodies(rd, model_el)
    body_names = {b.name for b in bodies} | {GROUND}
    joints = _read_joints(rd, model_el, body_names, frames)
    _check_tree(rd, bodies, joints)
    coordinates = tuple(c for j in joints for c in j[1])
    joints_only = tuple(j[0] for j in joints)
    coord_names = {c.name for c in coordinates}
    couplers = _read_constraints(rd, model_el, coord_names, skipped)
    for tag in ("ContactGeometrySet", "ControllerSet", "ProbeSet", "MarkerSet"):
        objs = model_el.find(f"{tag}/objects")
        skipped += [f"{o.tag} {o.get('name')!r}" for o in (objs if objs is not None else [])]
    comps = model_el.find("components")
    for c in (comps if comps is not None else []):
        if c.tag in ("PhysicalOffsetFrame", "Marker") or c.tag.endswith("Controller") or c.tag.endswith("Probe"):
            skipped.append(f"{c.tag} {c.get('name')!r}")
        else:
            raise rd.err(f"model component <{c.tag}> is not supported", c, unsupported=True)
    muscles = _read_muscles(rd, model_el, body_names, coord_names, frames, skipped, wrap_objects)
    if skipped:
        counts: dict[str, int] = {}
        for s_ in skipped:
            counts[s_.split()[0]] = counts.get(s_.split()[0], 0) + 1
        warnings.warn(SkippedComponentsWarning(
            f"{path}: skipped {len(skipped)} component(s) that cannot change kinematics or muscle paths: "
            + ", ".join(f"{n} {k}" for k, n in counts.items()) + " (" + ", ".join(skipped) + ")"), stacklevel=2)
    credits_el = model_el.find("credits")
    return OsimModel(
        path=str(path),
        name=model_el.get("name", path.stem),
        bodies=bodies,
        joints=joints_only,
        coordinates=coordinates,
        muscles=muscles,
        credits=(credits_el.text or "").strip() if credits_el is not None else "",
        couplers=couplers,
        skipped=tuple(skipped),
    )


_NESTED_TAG = re.compile(r"(</?)([A-Za-z_][\w.]*)::([A-Za-z_]\w*)")

#: Constraint classes pamkin implements.
CONSTRAINT_CLASSES = ("CoordinateCouplerConstraint",)


def _read_constraints(rd: _Reader, model_el: ET.Element, coord_names: set[str],
                      skipped: list[str]) -> tuple[CoordinateCoupler, ...]:
    objs = model_el.find("ConstraintSet/objects")
    out: list[CoordinateCoupler] = []
    for c in (objs if objs is not None else []):
        enforced = rd.flag(c, "isEnforced", True) if c.find("isEnforced") is not None else \
            not rd.flag(c, "isDisabled", False)
        if not enforced:
            skipped.append(f"{c.tag} {c.get('name')!r} (not enforced)")
            continue
        if c.tag not in CONSTRAINT_CLASSES:
            raise rd.err(f"constraint type <{c.tag}> is not supported (constraints pamkin implements: "
                         f"{', '.join(CONSTRAINT_CLASSES)})", c, unsupported=True)
        indep = (rd.text(c, "independent_coordinate_names", "") or "").split()
        dep = rd.text(c, "dependent_coordinate_name", "").strip()
        if len(indep) != 1:
            raise rd.err(f"coupler with {len(indep)} independent coordinates; only one is supported", c,
                         unsupported=True)
        for cn in indep + [dep]:
            if cn not in coord_names:
                raise rd.err(f"coupler names unknown coordinate {cn!r}", c)
        if dep == indep[0]:
            raise rd.err("coupler's dependent and independent coordinates are the same", c)
        fn_el = c.find("coupled_coordinates_function")
        if fn_el is None or len(list(fn_el)) != 1:
            raise rd.err("coupler needs one function in <coupled_coordinates_function>", c)
        fn = rd.function(list(fn_el)[0], c)
        scale = rd.floats(c, "scale_factor", 1, "1")[0]
        if any(k.dependent == dep for k in out):
            raise rd.err(f"coordinate {dep!r} is the dependent coordinate of two couplers", c)
        out.append(CoordinateCoupler(c.get("name") or "", dep, indep[0], fn, scale))
    # no cycles
    dep_of = {k.dependent: k.independent for k in out}
    for k in out:
        seen, cur = set(), k.dependent
        while cur in dep_of:
            if cur in seen:
                raise OsimError(str(rd.path), "couplers form a cycle", element="CoordinateCouplerConstraint",
                                component=k.name)
            seen.add(cur)
            cur = dep_of[cur]
    return tuple(out)


def _read_frames(rd: _Reader, model_el: ET.Element) -> dict[str, OffsetFrame]:
    """PhysicalOffsetFrame components of ground and bodies, by absolute path and by (unique) name."""
    raw: dict[str, tuple[str, ET.Element]] = {}
    owners = [("/ground", model_el.find("Ground"))]
    bodyset = model_el.find("BodySet/objects")
    owners += [(f"/bodyset/{b.get('name')}", b) for b in (bodyset if bodyset is not None else [])]
    for owner_path, owner in owners:
        if owner is None:
            continue
        comps = owner.find("components")
        for fr in (comps if comps is not None else []):
            if fr.tag != "PhysicalOffsetFrame":
                raise rd.err(f"<{fr.tag}> component of {owner.tag} {owner.get('name')!r} is not supported", fr,
                             unsupported=True)
            raw[f"{owner_path}/{fr.get('name')}"] = (owner_path, fr)
    out: dict[str, OffsetFrame] = {}

    def resolve(key: str, depth: int = 0) -> OffsetFrame:
        if key in out:
            return out[key]
        if key == "/ground" or key.startswith("/bodyset/") and key.count("/") == 2:
            b = key.split("/")[-1]
            return OffsetFrame(b, b, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        if key not in raw or depth > 8:
            raise rd.err(f"frame {key!r} not found")
        owner_path, fr = raw[key]
        parent_ref = rd.text(fr, "socket_parent", "..").strip()
        if parent_ref in ("..", ""):
            parent_key = owner_path
        elif parent_ref.startswith("/"):
            parent_key = parent_ref.rstrip("/")
        else:
            parent_key = f"{owner_path}/{parent_ref}".rstrip("/")
        base = resolve(parent_key, depth + 1)
        own = OffsetFrame(fr.get("name") or "", base.body, rd.floats(fr, "translation", 3, "0 0 0"),
                          rd.floats(fr, "orientation", 3, "0 0 0"))
        T = base.transform() @ own.transform()
        out[key] = OffsetFrame(own.name, base.body, tuple(float(v) for v in T[:3, 3]),  # type: ignore[arg-type]
                               _xyz_from_matrix(T[:3, :3]))
        return out[key]

    for key in raw:
        resolve(key)
    names: dict[str, list[str]] = {}
    for key in raw:
        names.setdefault(key.split("/")[-1], []).append(key)
    for n, keys in names.items():
        if len(keys) == 1:
            out.setdefault(n, out[keys[0]])
    return out


def _frame_of(rd: _Reader, ref: str, frames: dict[str, OffsetFrame], body_names: set[str]) -> OffsetFrame | None:
    """The body frame or offset frame an OpenSim socket path names (None: not found)."""
    ref = ref.strip().rstrip("/")
    if ref in frames:
        return frames[ref]
    key = _last(ref)
    if key in body_names and (ref == key or ref in (f"/bodyset/{key}", "/ground", f"/{key}")
                              or ref.endswith(f"/{key}") and key not in frames):
        return OffsetFrame(key, key, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    return frames.get(key)


QUADRANT_NAMES = {f"{s}{a}" for s in ("", "+", "-") for a in "xyzXYZ"} | {"all", "ALL", "All", "Unassigned"}
#: Wrap object properties: class -> ((property, default), ...) as OpenSim 4.6 constructs them.
WRAP_DIMENSIONS = {"WrapCylinder": (("radius", "1"), ("length", "1")), "WrapSphere": (("radius", "0.05"),),
                   "WrapEllipsoid": (("dimensions", "0.05 0.05 0.05"),),
                   "WrapTorus": (("inner_radius", "0.01"), ("outer_radius", "0.05"))}


def _read_wrap_objects(rd: _Reader, model_el: ET.Element, frames: dict[str, OffsetFrame]) -> dict[str, WrapObject]:
    """Wrap objects of ground, bodies and their offset frames, by name."""
    owners = [("/ground", model_el.find("Ground"))]
    bodyset = model_el.find("BodySet/objects")
    owners += [(f"/bodyset/{b.get('name')}", b) for b in (bodyset if bodyset is not None else [])]
    for path, owner in list(owners):
        comps = owner.find("components") if owner is not None else None
        owners += [(f"{path}/{c.get('name')}", c) for c in (comps if comps is not None else [])
                   if c.tag == "PhysicalOffsetFrame"]
    out: dict[str, WrapObject] = {}
    for path, owner in owners:
        objs = owner.find("WrapObjectSet/objects") if owner is not None else None
        for w in (objs if objs is not None else []):
            name = w.get("name") or ""
            if w.tag not in KIND_CODE:
                raise rd.err(f"wrap object <{w.tag}> on {owner.tag} {owner.get('name')!r} is not supported "
                             f"(pamkin computes {', '.join(KIND_CODE)})", w, unsupported=True)
            quadrant = rd.text(w, "quadrant", "all")
            if quadrant not in QUADRANT_NAMES:     # OpenSim's spellings
                raise rd.err(f"quadrant {quadrant!r} is not one of +x, -x, +y, -y, +z, -z, all", w)
            frame = frames.get(path) if path.count("/") > 2 else None
            body = frame.body if frame is not None else path.split("/")[-1]
            T = np.eye(4)
            T[:3, :3] = rotation_xyz_body_fixed(rd.floats(w, "xyz_body_rotation", 3, "0 0 0"))
            T[:3, 3] = rd.floats(w, "translation", 3, "0 0 0")
            if frame is not None:
                T = frame.transform() @ T
            dims = tuple(v for prop, default in WRAP_DIMENSIONS[w.tag] for v in rd.floats(w, prop, None, default))
            n_dims = {"WrapCylinder": 2, "WrapSphere": 1, "WrapEllipsoid": 3, "WrapTorus": 2}[w.tag]
            if len(dims) != n_dims or min(dims) <= 0:
                raise rd.err(f"{w.tag} dimensions must be positive numbers, are {dims}", w)
            if name in out:
                raise rd.err(f"two wrap objects are called {name!r}", w)
            out[name] = WrapObject(name, w.tag, body, tuple(map(tuple, T[:3, :3].tolist())),
                                   tuple(float(v) for v in T[:3, 3]), quadrant, rd.flag(w, "active", True), dims)
    return out


def _read_path_wraps(rd: _Reader, f: ET.Element, gp: ET.Element, n_points: int,
                     wrap_objects: dict[str, WrapObject]) -> tuple[PathWrap, ...]:
    pws = gp.find("PathWrapSet/objects")
    out = []
    for pw in (pws if pws is not None else []):
        if pw.tag != "PathWrap":
            raise rd.err(f"<{pw.tag}> in the PathWrapSet of {f.get('name')!r} is not supported", pw, unsupported=True)
        wo = rd.text(pw, "wrap_object", "")
        if wo not in wrap_objects:
            raise rd.err(f"path wrap of {f.get('name')!r} names unknown wrap object {wo!r}", pw)
        method = rd.text(pw, "method", "hybrid")
        if method.lower() == "unassigned":
            method = "hybrid"
        if method.lower() not in METHOD_CODE or method not in (method.lower(), method.upper(), method.capitalize()):
            raise rd.err(f"wrap method {method!r} is not hybrid, midpoint or axial", pw)
        rng = rd.floats(pw, "range", 2, "-1 -1")
        if any(r != int(r) or r > n_points for r in rng):
            raise rd.err(f"wrap range {rng} must be point numbers 1..{n_points} (or -1)", pw)
        out.append(PathWrap(pw.get("name") or "", wrap_objects[wo], method.lower(), (int(rng[0]), int(rng[1]))))
    return tuple(out)


def _check_empty_set(rd: _Reader, model_el: ET.Element, tag: str, ok_if_missing: bool = True) -> None:
    el = model_el.find(tag)
    if el is None:
        return
    objs = el.find("objects")
    if objs is not None and len(list(objs)):
        first = list(objs)[0]
        raise rd.err(f"{tag} entry is not supported (pamkin models have no constraints)", first,
                     unsupported=True)


def _read_bodies(rd: _Reader, model_el: ET.Element) -> tuple[Body, ...]:
    bodyset = model_el.find("BodySet/objects")
    if bodyset is None:
        raise OsimError(str(rd.path), "no <BodySet><objects>", element="Model")
    out = []
    for b in bodyset:
        if b.tag != "Body":
            raise rd.err(f"<{b.tag}> in BodySet is not supported", b, unsupported=True)
        name = b.get("name")
        if not name:
            raise rd.err("Body without a name", b)
        meshes = []
        for mesh in b.iter("Mesh"):
            scale = rd.floats(mesh, "scale_factors", 3, "1 1 1")
            frame = OffsetFrame(name, name, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
            meshes.append(MeshGeometry(rd.text(mesh, "mesh_file"), scale, frame))
        out.append(Body(
            name=name,
            mass=rd.floats(b, "mass", 1, "0")[0],
            mass_center=rd.floats(b, "mass_center", 3, "0 0 0"),
            inertia=rd.floats(b, "inertia", 6, "0 0 0 0 0 0"),
            meshes=tuple(meshes),
        ))
    return tuple(out)


def _resolve_frame(rd: _Reader, joint_el: ET.Element, ref: str, frames: dict[str, ET.Element],
                   body_names: set[str], depth: int = 0,
                   model_frames: dict[str, OffsetFrame] | None = None) -> OffsetFrame:
    """Resolve a joint's socket to an offset frame fixed in a body."""
    key = _last(ref)
    if key in frames and depth < 8:
        fr = frames[key]
        parent_ref = rd.text(fr, "socket_parent")
        base = _resolve_frame(rd, joint_el, parent_ref, {k: v for k, v in frames.items() if k != key},
                              body_names, depth + 1, model_frames)
        own = OffsetFrame(key, base.body, rd.floats(fr, "translation", 3, "0 0 0"),
                          rd.floats(fr, "orientation", 3, "0 0 0"))
        if base.translation == (0.0, 0.0, 0.0) and base.orientation == (0.0, 0.0, 0.0):
            return own
        T = base.transform() @ own.transform()
        return OffsetFrame(key, base.body, tuple(float(v) for v in T[:3, 3]), _xyz_from_matrix(T[:3, :3]))
    found = _frame_of(rd, ref, model_frames or {}, body_names)
    if found is not None:
        return found
    raise rd.err(f"frame reference {ref!r} names no body, ground or offset frame of this joint", joint_el)


def _xyz_from_matrix(R: np.ndarray) -> tuple[float, float, float]:
    """Body-fixed X-Y-Z Euler angles of a rotation matrix."""
    b = math.asin(max(-1.0, min(1.0, R[0, 2])))
    a = math.atan2(-R[1, 2], R[2, 2])
    c = math.atan2(-R[0, 1], R[0, 0])
    return (a, b, c)


_AXIS_NAMES = ("rotation1", "rotation2", "rotation3", "translation1", "translation2", "translation3")


def _read_joints(rd: _Reader, model_el: ET.Element, body_names: set[str],
                 model_frames: dict[str, OffsetFrame] | None = None) -> list[tuple[Joint, tuple[Coordinate, ...]]]:
    jointset = model_el.find("JointSet/objects")
    if jointset is None:
        raise OsimError(str(rd.path), "no <JointSet><objects>", element="Model")
    out = []
    for j in jointset:
        name = j.get("name") or ""
        if j.tag not in JOINT_CLASSES:
            raise rd.err(f"joint type <{j.tag}> is not supported (supported: {', '.join(JOINT_CLASSES)})",
                         j, unsupported=True)
        frames = {}
        frames_el = j.find("frames")
        if frames_el is not None:
            for fr in frames_el:
                if fr.tag != "PhysicalOffsetFrame":
                    raise rd.err(f"<{fr.tag}> joint frame is not supported", fr, unsupported=True)
                frames[fr.get("name")] = fr
        parent = _resolve_frame(rd, j, rd.text(j, "socket_parent_frame"), frames, body_names,
                                model_frames=model_frames)
        child = _resolve_frame(rd, j, rd.text(j, "socket_child_frame"), frames, body_names,
                               model_frames=model_frames)
        if child.body == GROUND:
            raise rd.err("a joint's child cannot be ground", j)
        coords = []
        coords_el = j.find("coordinates")
        for c in (coords_el if coords_el is not None else []):
            if c.tag != "Coordinate":
                raise rd.err(f"<{c.tag}> in coordinates", c, unsupported=True)
            pf = c.find("prescribed_function")
            if c.find("prescribed") is not None and rd.flag(c, "prescribed", False):
                raise rd.err("prescribed coordinates are not supported", c, unsupported=True)
            rng = rd.floats(c, "range", 2, "-3.141592653589793 3.141592653589793")
            if rng[0] > rng[1]:
                raise rd.err(f"range min {rng[0]} > max {rng[1]}", c)
            coords.append(dict(el=c, name=c.get("name"), range=rng,
                               default=rd.floats(c, "default_value", 1, "0")[0],
                               locked=rd.flag(c, "locked", False),
                               clamped=rd.flag(c, "clamped", True), pf=pf))
        cnames = tuple(c["name"] for c in coords)
        axes: list[TransformAxis] = []
        rotational = {n: True for n in cnames}
        if j.tag == "CustomJoint":
            st = j.find("SpatialTransform")
            if st is None:
                raise rd.err("CustomJoint without <SpatialTransform>", j)
            by_name = {ta.get("name"): ta for ta in st.findall("TransformAxis")}
            for an in _AXIS_NAMES:
                ta = by_name.get(an)
                if ta is None:
                    axes.append(TransformAxis(an, (), _default_axis(an), Constant(0.0)))
                    continue
                axis = np.array(rd.floats(ta, "axis", 3))
                if np.linalg.norm(axis) == 0:
                    raise rd.err("zero axis", ta)
                axis = axis / np.linalg.norm(axis)
                tac = tuple((rd.text(ta, "coordinates", "") or "").split())
                fn_els = [e for e in ta if e.tag not in ("coordinates", "axis")]
                if len(fn_els) != 1:
                    raise rd.err("TransformAxis needs exactly one function", ta)
                fn_el = fn_els[0]
                if fn_el.tag == "function":  # OpenSim 4 may wrap it: <function><LinearFunction/></function>
                    inner = list(fn_el)
                    if len(inner) != 1:
                        raise rd.err("empty <function>", ta)
                    fn_el = inner[0]
                fn = rd.function(fn_el, ta)
                if len(tac) > 1:
                    raise rd.err(f"{an} depends on {len(tac)} coordinates; only one is supported", ta,
                                 unsupported=True)
                for cn in tac:
                    if cn not in cnames:
                        raise rd.err(f"{an} uses coordinate {cn!r} of another joint (coupling across "
                                     "joints is not supported)", ta, unsupported=True)
                if not tac and not fn.is_constant:
                    raise rd.err(f"{an} has a non-constant function but no coordinate", ta)
                if an.startswith("translation") and tac and isinstance(fn, LinearFunction) \
                        and fn.slope != 0 and fn.intercept == 0:
                    rotational[tac[0]] = False
                axes.append(TransformAxis(an, tac, tuple(float(v) for v in axis), fn))
            _check_rotation_axes(rd, j, axes)
            # a coordinate that drives only translations is translational
            for cn in cnames:
                uses = [a for a in axes if cn in a.coordinates]
                if uses and all(not a.is_rotation for a in uses):
                    rotational[cn] = False
        else:
            spec = JOINT_AXES[j.tag]
            if len(cnames) != len(spec):
                raise rd.err(f"{j.tag} must have {len(spec)} coordinate(s), has {len(cnames)}", j)
            axes = [TransformAxis(an, (cnames[k],), ax, LinearFunction(1.0, 0.0)) for an, ax, k in spec]
            for an, _, k in spec:
                if an.startswith("translation"):
                    rotational[cnames[k]] = False
        for c in coords:
            if c["pf"] is not None and len(list(c["pf"])):
                raise rd.err("prescribed_function is not supported", c["el"], unsupported=True)
            if not any(c["name"] in a.coordinates for a in axes):
                raise rd.err(f"coordinate {c['name']!r} drives no TransformAxis", j)
        joint = Joint(name, j.tag, parent, child, tuple(axes), cnames)
        out.append((joint, tuple(Coordinate(c["name"], name, c["range"], c["default"], c["locked"],
                                             c["clamped"], rotational[c["name"]]) for c in coords)))
    return out


def _default_axis(name: str) -> tuple[float, float, float]:
    i = int(name[-1]) - 1
    return tuple(1.0 if k == i else 0.0 for k in range(3))  # type: ignore[return-value]


def _check_rotation_axes(rd: _Reader, j: ET.Element, axes: list[TransformAxis]) -> None:
    """Reject CustomJoints where OpenSim would silently re-orthogonalize active rotation axes."""
    active = [a for a in axes if a.is_rotation and not (a.function.is_constant
                                                        and float(a.function.value(0.0)) == 0.0)]
    for i, a in enumerate(active):
        for b in active[i + 1:]:
            if abs(abs(float(np.dot(a.axis, b.axis))) - 1.0) < 1e-9:
                raise rd.err(f"{a.name} and {b.name} are parallel; OpenSim replaces such axes "
                             "and pamkin does not reproduce that", j, unsupported=True)


def _check_tree(rd: _Reader, bodies: tuple[Body, ...], joints) -> None:
    children: dict[str, str] = {}
    for joint, _ in joints:
        if joint.child in children:
            raise OsimError(str(rd.path), f"body {joint.child!r} is the child of two joints "
                            f"({children[joint.child]!r}, {joint.name!r}): closed loops are not supported",
                            element="Joint", component=joint.name)
        children[joint.child] = joint.name
    for b in bodies:
        if b.name not in children:
            raise OsimError(str(rd.path), "body is attached by no joint", element="Body", component=b.name)
    parent_of = {joint.child: joint.parent for joint, _ in joints}
    for b in bodies:
        seen, cur = set(), b.name
        while cur != GROUND:
            if cur in seen:
                raise OsimError(str(rd.path), "joints form a cycle", element="Body", component=b.name)
            seen.add(cur)
            cur = parent_of[cur]


def _read_muscles(rd: _Reader, model_el: ET.Element, body_names: set[str],
                  coord_names: set[str], frames: dict[str, OffsetFrame] | None = None,
                  skipped: list[str] | None = None,
                  wrap_objects: dict[str, WrapObject] | None = None) -> tuple[Muscle, ...]:
    forceset = model_el.find("ForceSet/objects")
    if forceset is None:
        return ()
    out = []
    path_classes = MUSCLE_CLASSES + PATH_ACTUATOR_CLASSES + PATH_ONLY_CLASSES
    for f in forceset:
        name = f.get("name") or ""
        gp = f.find("GeometryPath")
        fbp = f.find("FunctionBasedPath")
        if gp is None and fbp is not None:
            if f.tag not in path_classes:
                raise rd.err(f"force type <{f.tag}> has a path but is not supported (path classes: "
                             f"{', '.join(path_classes)})", f, unsupported=True)
            out.append(Muscle(name, f.tag, (), _read_params(rd, f), (),
                              _read_function_path(rd, fbp, f, coord_names)))
            continue
        if gp is None and f.tag not in path_classes:
            if skipped is not None:   # no path: cannot change kinematics or muscle paths
                skipped.append(f"{f.tag} {name!r}")
                continue
        if f.tag not in path_classes:
            raise rd.err(f"force type <{f.tag}> has a path but is not supported (path classes: "
                         f"{', '.join(path_classes)})", f, unsupported=True)
        if gp is None:
            other = [c.tag for c in f if c.tag.endswith("Path")]
            if other:
                raise rd.err(f"path class <{other[0]}> is not supported (pamkin reads <GeometryPath> and "
                             "<FunctionBasedPath>)", f, unsupported=True)
            raise rd.err("muscle without <GeometryPath> or <FunctionBasedPath>", f)
        if f.tag == "Thelen2003Muscle" and f.find("ignore_tendon_compliance") is not None \
                and rd.flag(f, "ignore_tendon_compliance", False):
            raise rd.err("ignore_tendon_compliance=true: OpenSim 4.6 refuses it for Thelen2003Muscle "
                         "(\"Thelen2003Muscle::ignore_tendon_compliance flag is not currently implemented\"); "
                         "set it to false (pamkin's rigid-tendon forces: rigid_tendon=True)", f, unsupported=True)
        pps = gp.find("PathPointSet/objects")
        if pps is None or len(list(pps)) < 2:
            raise rd.err("path needs at least 2 points", f)
        points = [_read_point(rd, p, f, body_names, coord_names, frames or {}) for p in pps]
        wraps = _read_path_wraps(rd, f, gp, len(points), wrap_objects or {})
        if isinstance(points[0], ConditionalPathPoint) or isinstance(points[-1], ConditionalPathPoint):
            raise rd.err("first and last path points must not be conditional", f, unsupported=True)
        out.append(Muscle(name, f.tag, tuple(points), _read_params(rd, f), wraps))
    return tuple(out)


def _read_params(rd: _Reader, f: ET.Element) -> dict[str, float]:
    """Scalar properties of a path-bearing force (defaults where OpenSim has them)."""
    params = {}
    if f.tag in PATH_ONLY_CLASSES:
        for key in PATH_ONLY_PROPERTIES:
            if f.find(key) is not None:
                params[key] = rd.floats(f, key, 1)[0]
        return params
    defaults = {"Thelen2003Muscle": THELEN_PROPERTIES, "PathActuator": PATH_ACTUATOR_PROPERTIES}.get(
        f.tag, MILLARD_PROPERTIES)
    for key, default in defaults.items():
        el = f.find(key)
        if el is None:
            if math.isnan(default):
                raise rd.err(f"missing <{key}>", f)
            params[key] = default
        else:
            params[key] = rd.floats(f, key, 1, allow_inf=key in ("min_control", "max_control"))[0]
    return params


def _read_coordinate_function(rd: _Reader, holder: ET.Element, owner: ET.Element, n: int,
                              what: str) -> CoordinateFunction:
    """A function of ``n`` coordinates: a MultivariatePolynomialFunction, or a scalar function when n = 1."""
    if holder.tag == "MultivariatePolynomialFunction":
        el = holder
    else:
        children = list(holder)
        if len(children) != 1:
            raise rd.err(f"<{what}> needs exactly one function, has {len(children)}", owner)
        el = children[0]
    if el.tag == "MultivariatePolynomialFunction":
        dim = int(rd.floats(el, "dimension", 1)[0])
        order = int(rd.floats(el, "order", 1)[0])
        if dim != n:
            raise rd.err(f"<{what}>: MultivariatePolynomialFunction of dimension {dim} for {n} coordinate(s)",
                         owner)
        try:
            return MultivariatePolynomial(dim, order, rd.floats(el, "coefficients"))
        except ValueError as e:
            raise rd.err(f"<{what}>: {e}", owner) from None
    if n != 1:
        raise rd.err(f"<{what}>: function type <{el.tag}> of {n} coordinates is not supported "
                     "(MultivariatePolynomialFunction is; scalar functions take one coordinate)", owner,
                     unsupported=True)
    return OneVariable(rd.function(el, owner))


def _read_function_path(rd: _Reader, fbp: ET.Element, owner: ET.Element,
                        coord_names: set[str]) -> FunctionPath:
    """An OpenSim ``FunctionBasedPath`` (coordinates, length function, optional moment-arm functions)."""
    names = tuple(_last(c) for c in rd.text(fbp, "coordinate_paths").split())
    if not names:
        raise rd.err("FunctionBasedPath without <coordinate_paths>", owner)
    for c in names:
        if c not in coord_names:
            raise rd.err(f"FunctionBasedPath names unknown coordinate {c!r}", owner)
    if len(set(names)) != len(names):
        raise rd.err(f"FunctionBasedPath names a coordinate twice: {' '.join(names)}", owner)
    length_el = fbp.find("length_function")
    if length_el is None:
        raise rd.err("FunctionBasedPath without <length_function>", owner)
    length = _read_coordinate_function(rd, length_el, owner, len(names), "length_function")
    arms_el = fbp.find("moment_arm_functions")
    arms = ()
    if arms_el is not None and len(list(arms_el)):
        arms = tuple(_read_coordinate_function(rd, el, owner, len(names), "moment_arm_functions")
                     for el in arms_el)
        if len(arms) != len(names):
            raise rd.err(f"FunctionBasedPath has {len(arms)} moment-arm functions for {len(names)} coordinates",
                         owner)
    return FunctionPath(names, length, arms)


def _read_point(rd: _Reader, p: ET.Element, muscle: ET.Element, body_names: set[str],
                coord_names: set[str], frames: dict[str, OffsetFrame] | None = None) -> AnyPathPoint:
    name = p.get("name") or ""
    if p.tag not in ("PathPoint", "ConditionalPathPoint", "MovingPathPoint"):
        raise rd.err(f"path point type <{p.tag}> in muscle {muscle.get('name')!r} is not supported", p,
                     unsupported=True)
    ref = rd.text(p, "socket_parent_frame")
    frame = _frame_of(rd, ref, frames or {}, body_names)
    if frame is None:
        raise rd.err(f"path point of muscle {muscle.get('name')!r} is on unknown body/frame {_last(ref)!r}", p)
    body = frame.body
    offset = None if frame.name == frame.body and frame.translation == (0.0, 0.0, 0.0) \
        and frame.orientation == (0.0, 0.0, 0.0) else frame.transform()
    if p.tag == "MovingPathPoint":
        fns, cns = [], []
        for axis in "xyz":
            loc = p.find(f"{axis}_location")
            cref = p.find(f"socket_{axis}_coordinate")
            if loc is None or len(list(loc)) != 1:
                raise rd.err(f"MovingPathPoint needs one function in <{axis}_location>", p)
            fn = rd.function(list(loc)[0], p)
            cn = _last(cref.text) if cref is not None and cref.text else ""
            if cn and cn not in coord_names:
                raise rd.err(f"{axis}_location uses unknown coordinate {cn!r}", p)
            if not cn and not fn.is_constant:
                raise rd.err(f"{axis}_location has no coordinate", p)
            fns.append(fn)
            cns.append(cn)
        if offset is not None:
            raise rd.err("MovingPathPoint on an offset frame is not supported", p, unsupported=True)
        return MovingPathPoint(name, body, tuple(fns), tuple(cns))  # type: ignore[arg-type]
    loc = rd.floats(p, "location", 3)
    if offset is not None:
        loc = tuple(float(v) for v in offset[:3, :3] @ np.array(loc) + offset[:3, 3])
    if p.tag == "ConditionalPathPoint":
        cref = rd.text(p, "socket_coordinate")
        cn = _last(cref)
        if cn not in coord_names:
            raise rd.err(f"socket_coordinate names unknown coordinate {cn!r}", p)
        rng = rd.floats(p, "range", 2)
        return ConditionalPathPoint(name, body, loc, coordinate=cn, range=rng)  # type: ignore[arg-type]
    return PathPoint(name, body, loc)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- plain-data form
def function_to_dict(fn: ScalarFunction | CoordinateFunction) -> dict:
    """Plain-data form of a function (for the project's YAML model files)."""
    if isinstance(fn, MultivariatePolynomial):
        return {"type": "MultivariatePolynomialFunction", "dimension": fn.dimension, "order": fn.order,
                "coefficients": list(fn.coefficients)}
    if isinstance(fn, OneVariable):
        return function_to_dict(fn.function)
    if isinstance(fn, Constant):
        return {"type": "Constant", "value": fn.c}
    if isinstance(fn, LinearFunction):
        return {"type": "LinearFunction", "coefficients": [fn.slope, fn.intercept]}
    if isinstance(fn, SimmSpline):
        return {"type": "SimmSpline", "x": list(fn.x), "y": list(fn.y)}
    if isinstance(fn, PolynomialFunction):
        return {"type": "PolynomialFunction", "coefficients": list(fn.coefficients)}
    if isinstance(fn, MultiplierFunction):
        return {"type": "MultiplierFunction", "scale": fn.scale, "function": function_to_dict(fn.function)}
    raise TypeError(f"cannot serialise {fn!r}")


def function_from_dict(d: dict) -> ScalarFunction:
    """Inverse of :func:`function_to_dict` (scalar functions)."""
    t = d["type"]
    if t == "Constant":
        return Constant(float(d["value"]))
    if t == "LinearFunction":
        return LinearFunction(float(d["coefficients"][0]), float(d["coefficients"][1]))
    if t == "SimmSpline":
        return SimmSpline(tuple(map(float, d["x"])), tuple(map(float, d["y"])))
    if t == "PolynomialFunction":
        return PolynomialFunction(tuple(map(float, d["coefficients"])))
    if t == "MultiplierFunction":
        return MultiplierFunction(function_from_dict(d["function"]), float(d["scale"]))
    raise ValueError(f"unknown function type {t!r}")


def _coordinate_function_from_dict(d: dict) -> CoordinateFunction:
    if d["type"] == "MultivariatePolynomialFunction":
        return MultivariatePolynomial(int(d["dimension"]), int(d["order"]), tuple(map(float, d["coefficients"])))
    return OneVariable(function_from_dict(d))


def _function_path_to_dict(p: FunctionPath) -> dict:
    return {"coordinates": list(p.coordinates), "length": function_to_dict(p.length),
            "moment_arms": [function_to_dict(f) for f in p.moment_arms]}


def _function_path_from_dict(d: dict | None) -> FunctionPath | None:
    if d is None:
        return None
    return FunctionPath(tuple(d["coordinates"]), _coordinate_function_from_dict(d["length"]),
                        tuple(_coordinate_function_from_dict(f) for f in d.get("moment_arms", [])))


def _frame_to_dict(f: OffsetFrame) -> dict:
    return {"name": f.name, "body": f.body, "translation": list(f.translation),
            "orientation": list(f.orientation)}


def _frame_from_dict(d: dict) -> OffsetFrame:
    return OffsetFrame(d["name"], d["body"], tuple(map(float, d["translation"])),  # type: ignore[arg-type]
                       tuple(map(float, d["orientation"])))  # type: ignore[arg-type]


def _point_to_dict(p: AnyPathPoint) -> dict:
    if isinstance(p, MovingPathPoint):
        return {"type": "MovingPathPoint", "name": p.name, "body": p.body,
                "functions": [function_to_dict(f) for f in p.functions], "coordinates": list(p.coordinates)}
    d = {"type": type(p).__name__, "name": p.name, "body": p.body, "location": list(p.location)}
    if isinstance(p, ConditionalPathPoint):
        d.update(coordinate=p.coordinate, range=list(p.range))
    return d


def point_from_dict(d: dict) -> AnyPathPoint:
    """A path point from its plain-data form (``type``: PathPoint, ConditionalPathPoint, MovingPathPoint)."""
    t = d.get("type", "PathPoint")
    if t == "MovingPathPoint":
        return MovingPathPoint(d["name"], d["body"], tuple(function_from_dict(f) for f in d["functions"]),  # type: ignore[arg-type]
                               tuple(d["coordinates"]))  # type: ignore[arg-type]
    loc = tuple(float(v) for v in d["location"])
    if len(loc) != 3:
        raise ValueError(f"point {d.get('name')!r}: location needs 3 numbers")
    if t == "ConditionalPathPoint":
        return ConditionalPathPoint(d["name"], d["body"], loc, coordinate=d["coordinate"],  # type: ignore[arg-type]
                                    range=tuple(map(float, d["range"])))  # type: ignore[arg-type]
    if t != "PathPoint":
        raise ValueError(f"unknown path point type {t!r}")
    return PathPoint(d["name"], d["body"], loc)  # type: ignore[arg-type]


def _wrap_to_dict(w: PathWrap) -> dict:
    o = w.wrap_object
    return {"name": w.name, "method": w.method, "range": list(w.range),
            "wrap_object": {"name": o.name, "kind": o.kind, "body": o.body, "rotation": [list(r) for r in o.rotation],
                            "translation": list(o.translation), "quadrant": o.quadrant, "active": o.active,
                            "dimensions": list(o.dimensions)}}


def _wrap_from_dict(d: dict) -> PathWrap:
    o = d["wrap_object"]
    wo = WrapObject(o["name"], o["kind"], o["body"], tuple(tuple(map(float, r)) for r in o["rotation"]),
                    tuple(map(float, o["translation"])), o["quadrant"], bool(o["active"]),  # type: ignore[arg-type]
                    tuple(map(float, o["dimensions"])))
    return PathWrap(d["name"], wo, d["method"], tuple(int(v) for v in d["range"]))  # type: ignore[arg-type]


def model_to_dict(model: OsimModel) -> dict:
    """Lossless plain-data form of an imported model (what the project's YAML files hold)."""
    d = {
        "name": model.name,
        "source": Path(model.path).name,
        "credits": model.credits,
        "bodies": [{"name": b.name, "mass": b.mass, "mass_center": list(b.mass_center),
                    "inertia": list(b.inertia),
                    "meshes": [{"mesh_file": m.mesh_file, "scale_factors": list(m.scale_factors),
                                "frame": _frame_to_dict(m.frame)} for m in b.meshes]}
                   for b in model.bodies],
        "joints": [{"name": j.name, "kind": j.kind, "parent_frame": _frame_to_dict(j.parent_frame),
                    "child_frame": _frame_to_dict(j.child_frame), "coordinates": list(j.coordinates),
                    "axes": [{"name": a.name, "coordinates": list(a.coordinates), "axis": list(a.axis),
                              "function": function_to_dict(a.function)} for a in j.axes]}
                   for j in model.joints],
        "coordinates": [{"name": c.name, "joint": c.joint, "range": list(c.range),
                         "default_value": c.default_value, "locked": c.locked, "clamped": c.clamped,
                         "rotational": c.rotational} for c in model.coordinates],
        "muscles": [{"name": m.name, "kind": m.kind, "params": dict(m.params),
                     "points": [_point_to_dict(p) for p in m.points],
                     **({"wraps": [_wrap_to_dict(w) for w in m.wraps]} if m.wraps else {}),
                     **({"function_path": _function_path_to_dict(m.function_path)} if m.function_path else {})}
                    for m in model.muscles],
    }
    if model.couplers:
        d["couplers"] = [{"name": k.name, "dependent": k.dependent, "independent": k.independent,
                          "function": function_to_dict(k.function), "scale_factor": k.scale_factor}
                         for k in model.couplers]
    return d


def model_from_dict(d: dict, path: str = "<data>") -> OsimModel:
    """Inverse of :func:`model_to_dict`."""
    return OsimModel(
        path=path,
        name=d["name"],
        bodies=tuple(Body(b["name"], float(b["mass"]), tuple(b["mass_center"]), tuple(b["inertia"]),
                          tuple(MeshGeometry(m["mesh_file"], tuple(m["scale_factors"]),
                                             _frame_from_dict(m["frame"])) for m in b.get("meshes", [])))
                     for b in d["bodies"]),
        joints=tuple(Joint(j["name"], j["kind"], _frame_from_dict(j["parent_frame"]),
                           _frame_from_dict(j["child_frame"]),
                           tuple(TransformAxis(a["name"], tuple(a["coordinates"]), tuple(a["axis"]),
                                               function_from_dict(a["function"])) for a in j["axes"]),
                           tuple(j["coordinates"])) for j in d["joints"]),
        coordinates=tuple(Coordinate(c["name"], c["joint"], tuple(c["range"]), float(c["default_value"]),
                                     bool(c["locked"]), bool(c["clamped"]), bool(c["rotational"]))
                          for c in d["coordinates"]),
        muscles=tuple(Muscle(m["name"], m["kind"], tuple(point_from_dict(p) for p in m["points"]),
                             {k: float(v) for k, v in m["params"].items()},
                             tuple(_wrap_from_dict(w) for w in m.get("wraps", [])),
                             _function_path_from_dict(m.get("function_path"))) for m in d["muscles"]),
        credits=d.get("credits", ""),
        couplers=tuple(CoordinateCoupler(k["name"], k["dependent"], k["independent"],
                                         function_from_dict(k["function"]), float(k.get("scale_factor", 1.0)))
                       for k in d.get("couplers", [])),
    )
