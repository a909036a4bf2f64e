"""OpenSim joints as MuJoCo joints: one hinge or slide per variable ``TransformAxis``.

An OpenSim ``CustomJoint`` maps its child frame M to its parent frame F by translations along F's axes, then
body-fixed rotations, each axis value a function of a coordinate. MuJoCo joints act in their body's frame in
sequence, so each variable axis becomes one MuJoCo joint of the child body (its anchor and axis carried into
the child body's frame; constant axes fold into the body's placement: exact). The joint's value is the axis
value ``v = f(q)``.

Per independent coordinate one axis is its *primary* joint: the first axis whose value is linear in it,
``v = a·q + b`` (a ≠ 0), so ``q = (v − b)/a`` exactly. Every other axis of that coordinate (knee splines,
coupled coordinates: ``f(s·g(q))``) and every moving path point's coordinate function becomes a *tied* joint:
``v = P(v_primary)``, P the least-squares polynomial of degree ≤ 4 (MuJoCo's ``<equality><joint polycoef>``)
over the coordinate's range. Linear functions are tied exactly; splines approximately (:attr:`MjJoint.error`,
the largest deviation on a 2001-point grid over the range, is reported).

With ``couplings="composed"`` (the default) a spline whose quartic deviates is instead a least-squares
combination of auxiliary joints chained from the primary joint by exact ties (:mod:`pamkin.sim.couplings`:
Chebyshev polynomials and iterated smoothsteps), held by a fixed tendon and a tendon equality; each auxiliary
joint is a slide of its own massless-in-effect body (:data:`pamkin.sim.mjcf.TINY_MASS`) under the world.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pamkin.errors import UnsupportedFeatureError
from pamkin.sim import couplings as cp
from pamkin.opensim.model_file import GROUND, Joint, OsimModel, TransformAxis

#: Degree of the polynomial of a tied joint (MuJoCo's joint equality holds at most degree 4).
POLY_DEGREE = 4
#: Points of the grid a tied joint's polynomial is fitted on and checked against.
FIT_POINTS = 2001
#: Coupling constructs: ``quartic`` (one joint equality per tie) or ``composed`` (auxiliary joint chains).
COUPLINGS = ("composed", "quartic")


@dataclass
class MjJoint:
    """A MuJoCo hinge or slide joint standing for one OpenSim TransformAxis (or moving-point component).

    Attributes:
        name: MuJoCo joint name.
        body: MuJoCo body it belongs to.
        kind: ``"hinge"`` or ``"slide"``.
        pos: Anchor in the body frame [m].
        axis: Unit axis in the body frame.
        coordinate: The independent coordinate its value depends on.
        value: Its value as a function of that coordinate (vectorised) [rad or m].
        primary: True for the coordinate's primary joint.
        poly: Tied joints: coefficients a0..a4 of v = Σ a_k·v_primary^k.
        error: Tied joints: largest |P(v_primary) − v| over the coordinate's range [rad or m].
        source: Name of the joint ``poly`` is in ("" for the coordinate's primary joint).
        terms: Composed ties: v = poly[0] + Σ terms[j]·value(j) over auxiliary joints j (a fixed tendon).
        aux: An auxiliary joint (of a composed chain; carries no model body).
        slope_error: Composed ties: largest |dv/dv_primary| deviation over the range [m/rad, rad/rad or m/m].
    """

    name: str
    body: str
    kind: str
    pos: np.ndarray
    axis: np.ndarray
    coordinate: str
    value: object
    primary: bool = False
    poly: np.ndarray = field(default_factory=lambda: np.zeros(POLY_DEGREE + 1))
    error: float = 0.0
    source: str = ""
    terms: dict[str, float] = field(default_factory=dict)
    aux: bool = False
    slope_error: float = 0.0


@dataclass(frozen=True)
class BodyPlacement:
    """A MuJoCo body: its parent (``"world"`` for ground) and placement X_parent_body (R, p)."""

    name: str
    parent: str
    R: np.ndarray
    p: np.ndarray


def joint_name(joint: Joint, axis: TransformAxis) -> str:
    """MuJoCo name of the joint standing for ``axis`` of ``joint``: ``<joint>_<axis>`` (as pamkin's URDF)."""
    return f"{joint.name}_{axis.name}"


class CoordinateMap:
    """The MuJoCo joints of an OpenSim model and the map between coordinates q and MuJoCo's qpos.

    Args:
        osim: The imported model.
        couplings: ``"composed"`` or ``"quartic"`` (:data:`COUPLINGS`).

    Raises:
        UnsupportedFeatureError: An independent coordinate has no axis linear in it (naming joint and
            coordinate), or a coupler chain is cyclic.
    """

    def __init__(self, osim: OsimModel, couplings: str = "composed") -> None:
        if couplings not in COUPLINGS:
            raise ValueError(f"couplings must be one of {COUPLINGS}, got {couplings!r}")
        self.couplings = couplings
        #: Auxiliary bodies (children of the world, one slide joint each).
        self.aux_bodies: list[str] = []
        self.osim = osim
        self.coordinates = [c.name for c in osim.coordinates]
        self.ranges = {c.name: c.range for c in osim.coordinates}
        self._couplers = {k.dependent: k for k in osim.couplers}
        self.bodies: list[BodyPlacement] = []
        self.joints: list[MjJoint] = []
        #: independent coordinate -> (primary joint index, slope a, intercept b)
        self.primary: dict[str, tuple[int, float, float]] = {}
        for j in osim.joints:
            self._add_joint(j)
        self._choose_primaries()

    # ------------------------------------------------------------------ building
    def root(self, name: str) -> tuple[str, object]:
        """(independent coordinate, function giving ``name``'s value from it) through the couplers."""
        seen = set()
        fn = lambda x: x  # noqa: E731
        while name in self._couplers:
            if name in seen:
                raise UnsupportedFeatureError(self.osim.path, "cyclic coordinate couplers",
                                              element="CoordinateCouplerConstraint", component=name)
            seen.add(name)
            k = self._couplers[name]
            fn = _compose(k, fn)
            name = k.independent
        return name, fn

    def _add_joint(self, j: Joint) -> None:
        X_PF = j.parent_frame.transform()
        X_BM = j.child_frame.transform()
        C = np.eye(4)                  # constants pushed to the right (M-frame)
        steps = []                     # (axis, variable anchor, axis dir, kind)
        order = [a for a in j.axes if not a.is_rotation] + [a for a in j.axes if a.is_rotation]
        for ax in order:
            u = np.asarray(ax.axis, float)
            u = u / np.linalg.norm(u)
            const = not ax.coordinates or ax.function.is_constant
            if const:
                v = float(np.asarray(ax.function.value(np.zeros(1)))[0])
                if v != 0.0:
                    C = C @ _screw(u, v, ax.is_rotation)
                continue
            steps.append((ax, C[:3, :3] @ np.zeros(3) + C[:3, 3], C[:3, :3] @ u))
        T = C @ np.linalg.inv(X_BM)    # body frame -> M frame (p_M = T p_B)
        X = X_PF @ T
        parent = "world" if j.parent == GROUND else j.parent
        self.bodies.append(BodyPlacement(j.child, parent, X[:3, :3].copy(), X[:3, 3].copy()))
        Ti = np.linalg.inv(T)
        for ax, anchor, u in steps:
            coord, fn = self.root(ax.coordinates[0])
            f = ax.function
            self.joints.append(MjJoint(joint_name(j, ax), j.child, "hinge" if ax.is_rotation else "slide",
                                       Ti[:3, :3] @ anchor + Ti[:3, 3], Ti[:3, :3] @ u, coord,
                                       _compose_fn(f, fn)))

    def _choose_primaries(self) -> None:
        for i, mj in enumerate(self.joints):
            if mj.coordinate in self.primary:
                continue
            a, b = _linear(mj.value, self.ranges[mj.coordinate])
            if a is not None:
                mj.primary = True
                self.primary[mj.coordinate] = (i, a, b)
        for mj in list(self.joints):
            if not mj.primary:
                self.tie(mj)

    def tie(self, mj: MjJoint) -> None:
        """Fit ``mj``'s polynomial in its coordinate's primary joint (raises when there is none); with composed
        couplings, refit it as a sum of auxiliary joints where that deviates less (:meth:`_tie_composed`)."""
        if mj.coordinate not in self.primary:
            raise UnsupportedFeatureError(
                self.osim.path, f"coordinate {mj.coordinate!r} moves no TransformAxis linearly, so no MuJoCo "
                "joint can stand for it", element="CustomJoint", component=mj.name)
        _, a, b = self.primary[mj.coordinate]
        lo, hi = self.ranges[mj.coordinate]
        q = np.linspace(lo, hi, FIT_POINTS)
        x = a * q + b
        y = np.asarray(mj.value(q), float) * np.ones_like(q)
        c = np.polynomial.polynomial.polyfit(x, y, POLY_DEGREE)
        c[np.abs(c) < 1e-15] = 0.0
        mj.poly = c
        mj.error = float(np.max(np.abs(np.polynomial.polynomial.polyval(x, c) - y)))
        if self.couplings == "composed" and mj.error > 1e-12:
            self._tie_composed(mj, x, y, np.gradient(y, x))

    def _tie_composed(self, mj: MjJoint, v: np.ndarray, y: np.ndarray, dy: np.ndarray) -> None:
        """Refit ``mj`` (values y, slopes dy at primary values v) in its coordinate's composed basis, kept when
        its largest deviation is below the quartic's."""
        chain, basis = cp.basis_chain(float(v.min()), float(v.max()))
        coef, err, derr = cp.composed_fit(chain, basis, v, y, dy)
        if err >= mj.error:
            return
        names = self.add_chain(mj.coordinate, "basis", chain)
        mj.terms = {names[b]: c for b, c in coef.items() if b}
        mj.poly = cp.linear_polycoef(0.0, coef[""])
        mj.error, mj.slope_error = err, derr

    def add_aux(self, tag: str, coordinate: str, poly: np.ndarray, source: str = "",
                terms: dict[str, float] | None = None) -> str:
        """Add one auxiliary slide joint (on its own body) of ``coordinate``: ``poly`` of joint ``source`` ("" the
        primary joint), or poly[0] + Σ terms[j]·value(j); returns its name."""
        name = safe_aux(f"aux-{coordinate}-{tag}")
        self.aux_bodies.append(name)
        self.joints.append(MjJoint(name, name, "slide", np.zeros(3), np.array([1.0, 0, 0]), coordinate, None,
                                   poly=np.asarray(poly, float), source=source, terms=dict(terms or {}), aux=True))
        return name

    def add_chain(self, coordinate: str, tag: str, chain: list[cp.Aux]) -> dict[str, str]:
        """Add the auxiliary joints of ``chain`` (each on its own body) once per (coordinate, tag); returns
        ``{chain name: joint name}``."""
        names = {a[0]: safe_aux(f"aux-{coordinate}-{tag}-{a[0]}") for a in chain}
        have = {j.name for j in self.joints}
        for name, src, poly in chain:
            if names[name] in have:
                continue
            self.aux_bodies.append(names[name])
            self.joints.append(MjJoint(names[name], names[name], "slide", np.zeros(3), np.array([1.0, 0, 0]),
                                       coordinate, None, poly=np.asarray(poly, float), source=names.get(src, ""),
                                       aux=True))
        return names

    # ------------------------------------------------------------------ maps
    def joint_index(self, name: str) -> int:
        return [j.name for j in self.joints].index(name)

    def qpos(self, q: np.ndarray) -> np.ndarray:
        """(N, n_joints) MuJoCo joint values of configurations q (N, n_coordinates), in :attr:`joints` order,
        tied joints at their polynomial or composition (what MuJoCo's equalities hold)."""
        return self._values(q)[0]

    def dqpos_dq(self, q: np.ndarray) -> np.ndarray:
        """(N, n_joints, n_coordinates) derivatives of :meth:`qpos` (0 about dependent coordinates)."""
        v, d = self._values(q)
        out = np.zeros((len(v), len(self.joints), len(self.coordinates)))
        for k, mj in enumerate(self.joints):
            out[:, k, self.coordinates.index(mj.coordinate)] = d[:, k]
        return out

    def _values(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint values (N, n_joints) and their derivatives about their coordinate (N, n_joints)."""
        q = np.atleast_2d(q)
        index = {j.name: k for k, j in enumerate(self.joints)}
        val = np.full((len(q), len(self.joints)), np.nan)
        der = np.zeros_like(val)
        done = np.zeros(len(self.joints), bool)

        def ev(k: int) -> None:
            if done[k]:
                return
            mj = self.joints[k]
            i, a, b = self.primary[mj.coordinate]
            if mj.primary:
                val[:, k], der[:, k] = a * q[:, self.coordinates.index(mj.coordinate)] + b, a
            elif mj.terms:
                val[:, k], der[:, k] = mj.poly[0], 0.0
                for name, c in mj.terms.items():
                    ev(index[name])
                    val[:, k] += c * val[:, index[name]]
                    der[:, k] += c * der[:, index[name]]
            else:
                s = index[mj.source] if mj.source else i
                ev(s)
                P = np.polynomial.polynomial
                val[:, k] = P.polyval(val[:, s], mj.poly)
                der[:, k] = P.polyval(val[:, s], P.polyder(mj.poly)) * der[:, s]
            done[k] = True

        for k in range(len(self.joints)):
            ev(k)
        return val, der

    def coordinates_of(self, qpos: np.ndarray) -> dict[str, np.ndarray]:
        """Independent coordinates from MuJoCo joint values (N, n_joints): ``{name: (N,)}``."""
        qpos = np.atleast_2d(qpos)
        return {c: (qpos[:, i] - b) / a for c, (i, a, b) in self.primary.items()}


def safe_aux(name: str) -> str:
    """An auxiliary joint/body name MuJoCo accepts (letters, digits, ``_ - .``)."""
    return "".join(ch if ch.isalnum() or ch in "_-." else "_" for ch in name)


def _compose(k, fn):
    return lambda x: k.value(fn(x))


def _compose_fn(f, inner):
    return lambda x: f.value(inner(np.asarray(x, float)))


def _linear(value, rng) -> tuple[float | None, float]:
    """(a, b) when ``value`` is a·q + b over ``rng`` (to 1e-12), else (None, 0)."""
    q = np.linspace(rng[0], rng[1], 11)
    y = np.asarray(value(q), float) * np.ones_like(q)
    a, b = np.polynomial.polynomial.polyfit(q, y, 1)[::-1]
    if abs(a) < 1e-9 or np.max(np.abs(a * q + b - y)) > 1e-12:
        return None, 0.0
    return float(a), float(b)


def _screw(u: np.ndarray, v: float, rotation: bool) -> np.ndarray:
    """Homogeneous transform of a rotation by ``v`` about ``u`` (or a translation v·u)."""
    T = np.eye(4)
    if rotation:
        K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        T[:3, :3] = np.eye(3) + np.sin(v) * K + (1 - np.cos(v)) * K @ K
    else:
        T[:3, 3] = v * u
    return T


__all__ = ["BodyPlacement", "CoordinateMap", "MjJoint", "joint_name"]
