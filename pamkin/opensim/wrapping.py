"""Path wrapping over cylinders, spheres, ellipsoids and tori, computed as OpenSim 4.6 computes it.

OpenSim (``GeometryPath::applyWrapObjects``) takes the active path points, then for every
``PathWrap`` of the path (in order; up to 8 passes when a path has two or more, stopping when the
length changes by less than 0.5 mm) removes that wrap's two points, tries every segment of the
point range the PathWrap names (``range``, 1-based, -1: first/last point) against the wrap object
(in the object's frame) and keeps a *mandatory* wrap (the segment pierces the object) or else the
wrap that lengthens the path least; the two tangent points r1, r2 are inserted into the path,
fixed in the wrap object's body. The length is the sum of the straight segments plus, between the
two points of one wrap, the length over the surface that the wrap object computed. One quirk is
reproduced on purpose: OpenSim caches a point's location in ground the first time it is read for a
state, so after a later pass moves a wrap point, the straight segments still use its first
location (the surface lengths are the new ones).

This module re-implements that algorithm and the surface computations of ``WrapCylinder``
(tangent points slid along the axis, helix length; with several wraps on the path, OpenSim's
tangency iteration on the helix), ``WrapSphere`` (great circle) and ``WrapEllipsoid`` (wrapping
plane by the "hybrid", "midpoint" or "axial" method, tangent points by OpenSim's damped
Gauss-Newton iteration, length as OpenSim's polyline over the surface with 1 mm segments),
and ``WrapTorus`` (the closest point of the centre circle by OpenSim's port of MINPACK's ``lmdif``
with its loose tolerances, reproduced iterate by iterate for one unknown, then a cylinder of the
tube radius tangent to the circle there), with quadrants (``+x`` … ``-z``, ``all``) and ``active``
flags, from the source of opensim-core (read, not copied). The obstacle-set classes
(``WrapCylinderObst``, ``WrapDoubleCylinderObst``, ``WrapSphereObst``) are refused.

The surface computations are scalar numba kernels; the path loop exists twice, in Python
(:func:`wrapped_path_length`, the readable reference) and compiled (chunks of configurations in
parallel for large batches; used by default; both give identical numbers, tested). Lengths match OpenSim
4.6 to round-off; they are piecewise smooth: they jump where a wrap switches on or off, where
OpenSim's discretisations change (number of ellipsoid polyline segments, tangency iterations).
Moment arms of wrapped paths are central differences of these lengths (see
:class:`pamkin.human.model.Model`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import get_num_threads, njit, prange

#: WrapAction codes of OpenSim's WrapObject.
NO_WRAP, INSIDE_RADIUS, WRAPPED, MANDATORY_WRAP = 0, 1, 2, 3
#: Wrap object kinds.
CYLINDER, SPHERE, ELLIPSOID, TORUS = 0, 1, 2, 3
KIND_CODE = {"WrapCylinder": CYLINDER, "WrapSphere": SPHERE, "WrapEllipsoid": ELLIPSOID, "WrapTorus": TORUS}
#: PathWrap methods.
HYBRID, MIDPOINT, AXIAL = 0, 1, 2
METHOD_CODE = {"hybrid": HYBRID, "midpoint": MIDPOINT, "axial": AXIAL}
#: quadrant name -> (axis, sign); sign 0: all quadrants.
QUADRANTS = {"-x": (0, -1), "x": (0, 1), "+x": (0, 1), "-y": (1, -1), "y": (1, 1), "+y": (1, 1),
             "-z": (2, -1), "z": (2, 1), "+z": (2, 1), "all": (0, 0), "unassigned": (0, 0)}

_EPS = 2.220446049250313e-16     # SimTK::Eps
_ROUNDOFF = 2e-13                # OpenSim's ROUNDOFF_ERROR
_OPTS = {"cache": True, "error_model": "numpy"}


@dataclass(frozen=True)
class WrapObject:
    """A wrap surface fixed in a body.

    Attributes:
        name: Wrap object name (unique in the model).
        kind: ``WrapCylinder``, ``WrapSphere``, ``WrapEllipsoid`` or ``WrapTorus``.
        body: Body (or ``ground``) the object is fixed in.
        rotation: Orientation of the object frame in the body (3, 3).
        translation: Origin of the object frame in the body (3,) [m].
        quadrant: OpenSim's quadrant name (``all``, ``x``, ``-y`` …).
        active: OpenSim's ``active`` flag (an inactive object never wraps).
        dimensions: Cylinder (radius, length), sphere (radius,), ellipsoid (three radii), torus (inner
            radius, outer radius) [m].
    """

    name: str
    kind: str
    body: str
    rotation: tuple
    translation: tuple[float, float, float]
    quadrant: str
    active: bool
    dimensions: tuple[float, ...]

    @property
    def wrap_axis_sign(self) -> tuple[int, int]:
        return QUADRANTS[self.quadrant.lower()]


@dataclass(frozen=True)
class PathWrap:
    """One entry of a path's PathWrapSet.

    Attributes:
        name: PathWrap name.
        wrap_object: The wrap object.
        method: ``hybrid``, ``midpoint`` or ``axial`` (ellipsoids only).
        range: (start, end) 1-based indices into the path's PathPointSet; < 1: first/last point.
    """

    name: str
    wrap_object: WrapObject
    method: str = "hybrid"
    range: tuple[int, int] = (-1, -1)


# ----------------------------------------------------------------------------- vector helpers
@njit(**_OPTS)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(**_OPTS)
def _cross(a, b):
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit(**_OPTS)
def _vec(x, y, z):
    out = np.empty(3)
    out[0] = x
    out[1] = y
    out[2] = z
    return out


@njit(**_OPTS)
def _norm(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@njit(**_OPTS)
def _unit(a):
    """WrapMath::NormalizeOrZero (returns the unit vector; zero below SimTK::Eps)."""
    mag = _norm(a)
    if mag >= _EPS:
        return a * (1.0 / mag)
    return np.zeros(3)


@njit(**_OPTS)
def _acos(x):
    if x > 1.0 or x < -1.0 or math.isnan(x):
        return np.nan
    return math.acos(x)


@njit(**_OPTS)
def _dsign(x):
    return 1 if x >= 0.0 else -1


@njit(**_OPTS)
def _closest_on_line(pt, line_pt, line):
    """WrapMath::GetClosestPointOnLineToPoint: (closest point, t)."""
    v1 = pt - line_pt
    mag = _norm(v1)
    v1 = _unit(v1)
    mag2 = _norm(line)
    v2 = _unit(line)
    t = _dot(v1, v2) * mag
    closest = line_pt + t * v2
    return closest, t / mag2


@njit(**_OPTS)
def _det3(r0, r1, r2):
    return (r0[0] * (r1[1] * r2[2] - r1[2] * r2[1]) - r0[1] * (r1[0] * r2[2] - r1[2] * r2[0])
            + r0[2] * (r1[0] * r2[1] - r1[1] * r2[0]))


# ----------------------------------------------------------------------------- cylinder
# The cylinder is the most used wrap object: its code works on (x, y, z) tuples (no heap allocation).
_T0 = (0.0, 0.0, 0.0)
_DN = (0.0, 0.0, 1.0)
_P0 = (0.0, 0.0, -1.0)
_TNAN = (np.nan, np.nan, np.nan)


@njit(**_OPTS)
def _t_add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(**_OPTS)
def _t_sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(**_OPTS)
def _t_mul(s, a):
    return (s * a[0], s * a[1], s * a[2])


@njit(**_OPTS)
def _t_cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(**_OPTS)
def _t_unit(a):
    mag = _norm(a)
    if mag >= _EPS:
        f = 1.0 / mag
        return (a[0] * f, a[1] * f, a[2] * f)
    return _T0


@njit(**_OPTS)
def _t_closest(pt, line_pt, line):
    """WrapMath::GetClosestPointOnLineToPoint on tuples: (closest point, t)."""
    v1 = _t_sub(pt, line_pt)
    mag = _norm(v1)
    v1 = _t_unit(v1)
    mag2 = _norm(line)
    v2 = _t_unit(line)
    t = _dot(v1, v2) * mag
    return _t_add(line_pt, _t_mul(t, v2)), t / mag2


@njit(**_OPTS)
def _t_intersect_lines(p1, p2, p3, p4):
    """WrapMath::IntersectLines: (ok, pInt1, s, pInt2, t); NaN points when the lines are parallel."""
    vec1 = _t_sub(p2, p1)
    mag1 = _norm(vec1)
    vec1 = _t_unit(vec1)
    vec2 = _t_sub(p4, p3)
    mag2 = _norm(vec2)
    vec2 = _t_unit(vec2)
    cp = _t_cross(vec1, vec2)
    denom = _dot(cp, cp)
    if abs(denom) <= _ROUNDOFF:
        return False, _TNAN, np.nan, _TNAN, np.nan
    row0 = _t_sub(p3, p1)
    t = _det3(row0, vec1, cp) / denom
    pint2 = _t_add(p3, _t_mul(t, vec2))
    s = _det3(row0, vec2, cp) / denom
    pint1 = _t_add(p1, _t_mul(s, vec1))
    return True, pint1, s / mag1, pint2, t / mag2


@njit(**_OPTS)
def _t_seg_plane(pt1, pt2, plane, d):
    """WrapMath::IntersectLineSegPlane: (ok, point)."""
    vec = _t_sub(pt2, pt1)
    dotprod = _dot(vec, plane)
    if abs(dotprod) < 1e-5:
        return False, pt1
    t = (-d - plane[0] * pt1[0] - plane[1] * pt1[1] - plane[2] * pt1[2]) / dotprod
    if t < -1e-5 or t > 1.0 + 1e-5:
        return False, pt1
    return True, _t_add(pt1, _t_mul(t, vec))


@njit(**_OPTS)
def _t_dist2_line(point, line_pt, line):
    v = _t_sub(line_pt, point)
    nl = _norm(line)
    n = (line[0] / nl, line[1] / nl, line[2] / nl)
    w = _t_sub(v, _t_mul(_dot(v, n), n))
    return _dot(w, w)


@njit(**_OPTS)
def _t_rot_z(v, angle):
    c, s = math.cos(angle), math.sin(angle)
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


@njit(**_OPTS)
def _adjust_tangent_point(pt1, r1, w1):
    """WrapCylinder::_adjust_tangent_point (axis z): (adjusted?, new r1)."""
    pr = _t_unit(_t_sub(r1, pt1))
    rw = _t_unit(_t_sub(w1, r1))
    alpha = _acos(_dot(pr, _DN))
    omega = _acos(_dot(rw, _DN))
    if abs(alpha - omega) > 0.1 * math.pi / 180.0:
        p1a, _ = _t_closest(pt1, r1, _DN)
        w1a, _ = _t_closest(w1, r1, _DN)
        _ok, _a, _s, p1aw1a, _t = _t_intersect_lines(pt1, w1, p1a, w1a)
        return True, _t_add(r1, _t_mul(1.5, _t_sub(p1aw1a, r1)))
    return False, r1


@njit(**_OPTS)
def _spiral(p1, p2, far_side, r1, r2, radius, single):
    """WrapCylinder::_make_spiral_path: (r1, r2, wrap length)."""
    sense = -1.0 if far_side else 1.0
    iterations = 0
    while True:
        r1a, _ = _t_closest(r1, _P0, _DN)
        r2a, _ = _t_closest(r2, _P0, _DN)
        axial = _dot(_t_sub(r2a, r1a), _DN)
        uu = _t_sub(r1, r1a)
        vv = _t_sub(r2, r2a)
        theta = math.atan2(_dot(_t_cross(uu, vv), _DN), _dot(uu, vv))
        if far_side:
            theta = 2.0 * math.pi - theta
        x = radius * theta
        length = math.sqrt(x * x + axial * axial)
        if single:
            return r1, r2, length
        n = max(int(length / 0.002), 1)
        restart = False
        if n > 1 and iterations < 100:
            t = 1.0 / n
            wp = _t_add(_t_rot_z(r1, sense * t * theta), _t_mul(t * axial, _DN))
            adj1, r1n = _adjust_tangent_point(p1, r1, wp)
            tw = _t_add(_t_rot_z(r1n, sense * (1.0 - t) * theta), _t_mul((1.0 - t) * axial, _DN))
            adj2, r2n = _adjust_tangent_point(p2, r2, tw)
            r1, r2 = r1n, r2n
            if adj1 or adj2:
                iterations += 1
                restart = True
        if not restart:
            return r1, r2, length


@njit(**_OPTS)
def wrap_cylinder(point1, point2, radius, length, wrap_axis, wrap_sign, single):
    """WrapCylinder::wrapLine in the cylinder frame: (code, r1, r2, wrap length)."""
    p1 = (point1[0], point1[1], point1[2])
    p2 = (point2[0], point2[1], point2[2])
    code, r1, r2, wl = _cylinder(p1, p2, radius, length, wrap_axis, wrap_sign, single)
    return code, _vec(r1[0], r1[1], r1[2]), _vec(r2[0], r2[1], r2[2]), wl


@njit(**_OPTS)
def _cylinder(p1, p2, radius, length, wrap_axis, wrap_sign, single):
    dn, p0 = _DN, _P0
    r2sq = radius * radius
    code = WRAPPED
    constrained = wrap_sign != 0
    far_side = False
    long_wrap = False
    if _t_dist2_line(p1, p0, dn) < r2sq or _t_dist2_line(p2, p0, dn) < r2sq:
        return INSIDE_RADIUS, _TNAN, _TNAN, 0.0
    cyl_start = (0.0, 0.0, -0.5 * length)
    cyl_end = (0.0, 0.0, 0.5 * length)
    _ok, near12, t12, near00, _t00 = _t_intersect_lines(p1, p2, cyl_start, cyl_end)
    d12 = _t_sub(near12, near00)
    pierces = _dot(d12, d12) < r2sq and t12 > 0.0 and t12 < 1.0
    if not constrained:
        if pierces:
            code = MANDATORY_WRAP
        else:
            return NO_WRAP, _TNAN, _TNAN, 0.0
    p11, _ = _t_closest(p1, p0, dn)
    p22, _ = _t_closest(p2, p0, dn)
    vv = _t_sub(p1, p11)
    p11_dist = _norm(vv)
    vv = _t_unit(vv)
    sin_t = radius / p11_dist
    dist = radius * sin_t
    pp = _t_add(p11, _t_mul(dist, vv))
    dist = math.sqrt(r2sq - dist * dist)
    uu = _t_cross(dn, vv)
    r1a = _t_add(pp, _t_mul(dist, uu))
    r1b = _t_sub(pp, _t_mul(dist, uu))
    vv = _t_sub(p2, p22)
    p22_dist = _norm(vv)
    vv = _t_unit(vv)
    sin_t = radius / p22_dist
    dist = radius * sin_t
    pp = _t_add(p22, _t_mul(dist, vv))
    dist = math.sqrt(r2sq - dist * dist)
    uu = _t_cross(dn, vv)
    r2a = _t_add(pp, _t_mul(dist, uu))
    r2b = _t_sub(pp, _t_mul(dist, uu))
    ax, sg = wrap_axis, wrap_sign
    if constrained:
        if _dsign(p1[ax]) == sg or _dsign(p2[ax]) == sg:
            if pierces:
                code = MANDATORY_WRAP
            elif _dsign(p1[ax]) != _dsign(p2[ax]) and _dsign(near12[ax]) != sg:
                code = WRAPPED
            else:
                return NO_WRAP, _TNAN, _TNAN, 0.0
        r1am, r1bm, r2am, r2bm = _t_sub(r1a, p11), _t_sub(r1b, p11), _t_sub(r2a, p22), _t_sub(r2b, p22)
        alpha = _acos(_dot(r1am, r2bm) / (_norm(r1am) * _norm(r2bm)))
        beta = _acos(_dot(r1bm, r2am) / (_norm(r1bm) * _norm(r2am)))
        s1a, s1b = _dsign(r1a[ax]) == sg, _dsign(r1b[ax]) == sg
        if s1a and s1b:
            if _dsign(r2a[ax]) == sg:
                r1, r2, far_side = r1b, r2a, not (alpha > beta)
            else:
                r1, r2, far_side = r1a, r2b, alpha > beta
        elif s1a and not s1b:
            r1, r2, far_side = r1a, r2b, alpha > beta
        elif not s1a and s1b:
            r1, r2, far_side = r1b, r2a, not (alpha > beta)
        else:   # none of r1a, r1b on the active side: r2a, r2b decide
            if _dsign(r2a[ax]) == sg:
                r1, r2, far_side = r1b, r2a, not (alpha > beta)
            elif _dsign(r2b[ax]) == sg:
                r1, r2, far_side = r1a, r2b, alpha > beta
            elif alpha > beta:
                r1, r2, far_side = r1a, r2b, True
            else:
                r1, r2, far_side = r1b, r2a, True
        sum_musc = _t_add(_t_sub(r1, p1), _t_sub(r2, p2))
        sum_r = _t_add(_t_sub(r1, p11), _t_sub(r2, p22))
        if _dot(sum_r, sum_musc) < 0.0:
            long_wrap = True
    else:
        r1am, r1bm = _t_unit(_t_sub(r1a, p11)), _t_unit(_t_sub(r1b, p11))
        r2am, r2bm = _t_unit(_t_sub(r2a, p22)), _t_unit(_t_sub(r2b, p22))
        dot1, dot2 = _dot(r1am, r2am), _dot(r1am, r2bm)
        dot3, dot4 = _dot(r1bm, r2am), _dot(r1bm, r2bm)
        if dot1 > dot2 and dot1 > dot3 and dot1 > dot4:
            r1, r2 = r1a, r2a
        elif dot2 > dot3 and dot2 > dot4:
            r1, r2 = r1a, r2b
        elif dot3 > dot4:
            r1, r2 = r1b, r2a
        else:
            r1, r2 = r1b, r2b
    # apex of the cylinder edge between the tangent lines
    t = p11_dist / (p11_dist + p22_dist)
    mpt = _t_add(p1, _t_mul(t, _t_sub(p2, p1)))
    axispt, _ = _t_closest(mpt, p0, dn)
    l1 = _t_unit(_t_sub(p1, axispt))
    l2 = _t_unit(_t_sub(p2, axispt))
    pn = _t_cross(l1, l2)
    npn = _norm(pn)
    pn = (pn[0] / npn, pn[1] / npn, pn[2] / npn)       # UnitVec3
    pn = _t_unit(pn)
    vert1 = _t_unit(_t_cross(dn, pn))
    vert2 = _t_unit(_t_cross(pn, dn))
    apex1 = _t_add(axispt, _t_mul(radius, vert1))
    apex2 = _t_add(axispt, _t_mul(radius, vert2))
    e1, e2 = _t_sub(mpt, apex1), _t_sub(mpt, apex2)
    dist1, dist2 = _dot(e1, e1), _dot(e2, e2)
    if far_side:
        apex = apex2 if dist1 < dist2 else apex1
    else:
        apex = apex1 if dist1 < dist2 else apex2
    uu = _t_unit(_t_sub(p1, apex))
    vv = _t_unit(_t_sub(p2, apex))
    pn = _t_cross(uu, vv)
    npn = _norm(pn)
    pn = (pn[0] / npn, pn[1] / npn, pn[2] / npn)
    d = -p1[0] * pn[0] - p1[1] * pn[1] - p1[2] * pn[2]
    ok1, r1p = _t_seg_plane(_t_sub(r1, _t_mul(10.0, dn)), _t_add(r1, _t_mul(10.0, dn)), pn, d)
    ok2, r2p = _t_seg_plane(_t_sub(r2, _t_mul(10.0, dn)), _t_add(r2, _t_mul(10.0, dn)), pn, d)
    if ok1:
        c, _ = _t_closest(r1p, p11, p22)      # OpenSim passes p22 as the line's direction
        e, f = _t_sub(c, p22), _t_sub(p11, p22)
        if _dot(e, e) < _dot(f, f):
            r1 = r1p
    if ok2:
        c, _ = _t_closest(r2p, p11, p22)
        e, f = _t_sub(c, p11), _t_sub(p22, p11)
        if _dot(e, e) < _dot(f, f):
            r2 = r2p
    half = length / 2.0
    if (r1[2] < -half or r1[2] > half) and (r2[2] < -half or r2[2] > half):
        return NO_WRAP, _TNAN, _TNAN, 0.0
    r1, r2, wl = _spiral(p1, p2, long_wrap, r1, r2, radius, single)
    return code, r1, r2, wl


# ----------------------------------------------------------------------------- sphere
@njit(**_OPTS)
def wrap_sphere(p1, p2, radius, wrap_axis, wrap_sign):
    """WrapSphere::wrapLine in the sphere frame: (code, r1, r2, wrap length)."""
    nan3 = np.full(3, np.nan)
    code = WRAPPED
    far_side = False
    ri = p1 - p2
    mp = -p2
    p1p2 = p1 - p2
    n1, n2 = _norm(p1), _norm(p2)
    if n1 < radius or n2 < radius:
        return INSIDE_RADIUS, nan3, nan3, 0.0
    a = _dot(ri, ri)
    b = -2.0 * _dot(mp, ri)
    c = _dot(mp, mp) - radius * radius
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return NO_WRAP, nan3, nan3, 0.0
    l1 = (-b + math.sqrt(disc)) / (2.0 * a)
    l2 = (-b - math.sqrt(disc)) / (2.0 * a)
    if not 0.0 < l1 < 1.0 or not 0.0 < l2 < 1.0:
        return NO_WRAP, nan3, nan3, 0.0
    if l1 < l2:
        return NO_WRAP, nan3, nan3, 0.0
    p1p2 = _unit(p1p2)
    np2 = _unit(p2)
    hp2 = _cross(p1p2, np2)
    if _norm(hp2) < 0.00001:
        return code, nan3, nan3, np.nan     # OpenSim reuses a stale previous wrap here (undefined)
    n = _unit(hp2)
    cands = np.empty((4, 3))
    for k in range(2):
        pt = p1 if k == 0 else p2
        y = _unit(-pt)
        z = _cross(n, y)
        ang = math.asin(radius / _norm(pt))
        rr = _norm(pt) * math.cos(ang)
        ca, sa = math.cos(ang), math.sin(ang)
        cands[2 * k] = pt + (ca * y - sa * z) * rr
        cands[2 * k + 1] = pt + (ca * y + sa * z) * rr
    r1a, r1b, r2a, r2b = cands[0], cands[1], cands[2], cands[3]
    r1am, r1bm, r2am, r2bm = _unit(r1a), _unit(r1b), _unit(r2a), _unit(r2b)
    j1, j2, j3, j4 = _dot(r1am, r2am), _dot(r1am, r2bm), _dot(r1bm, r2am), _dot(r1bm, r2bm)
    if j1 > j2 and j1 > j3 and j1 > j4:
        r1, r2, r11, r22 = r1a, r2a, r1b, r2b
    elif j2 > j3 and j2 > j4:
        r1, r2, r11, r22 = r1a, r2b, r1b, r2a
    elif j3 > j4:
        r1, r2, r11, r22 = r1b, r2a, r1a, r2b
    else:
        r1, r2, r11, r22 = r1b, r2b, r1a, r2a
    ax, sg = wrap_axis, wrap_sign
    if sg != 0:
        if _dsign(p1[ax]) == sg or _dsign(p2[ax]) == sg:
            mm, tt = _closest_on_line(np.zeros(3), p1, p1p2)
            tt = -tt
            if _dot(mm, mm) < radius * radius and tt > 0.0 and tt < 1.0:
                code = MANDATORY_WRAP
            elif _dsign(p1[ax]) != _dsign(p2[ax]) and _dsign(mm[ax]) != sg:
                code = WRAPPED
            else:
                return NO_WRAP, nan3, nan3, 0.0
        if _dsign(p1[ax]) != sg or _dsign(p2[ax]) != sg:
            wrapaxis = np.zeros(3)
            wrapaxis[ax] = float(sg)
            sum_musc = _unit(-p1 - p2)
            if _dot(r1am, sum_musc) > _dot(r1bm, sum_musc):
                r1, r11 = r1a, r1b
            else:
                r1, r11 = r1b, r1a
            if _dot(r2am, sum_musc) > _dot(r2bm, sum_musc):
                r2, r22 = r2a, r2b
            else:
                r2, r22 = r2b, r2a
            sum_musc = _unit((r1 - p1) + (r2 - p2))
            if _dot(sum_musc, wrapaxis) < 0.0:
                r1, r2 = r11, r22
            sum_musc = (r1 - p1) + (r2 - p2)
            sum_r = r1 + r2
            if _dot(sum_r, sum_musc) < 0.0:
                far_side = True
    r1n, r2n = _unit(r1), _unit(r2)
    angle = _acos(_dot(r1n, r2n))
    if far_side:
        angle = -(2 * math.pi - angle)      # as OpenSim 4.6 (a negative length on far-side wraps)
    return code, r1, r2, radius * angle


# ----------------------------------------------------------------------------- ellipsoid
@njit(**_OPTS)
def _closest_ellipse(a, b, u, v):
    """WrapEllipsoid::closestPointToEllipse: (x, y)."""
    a2, b2 = a * a, b * b
    a2u2, b2v2 = a2 * u * u, b2 * v * v
    near_x = abs(u) <= _ROUNDOFF
    near_y = abs(v) <= _ROUNDOFF
    if near_x and near_y:
        if a < b:
            return (-a if u < 0.0 else a), v
        return u, (-b if v < 0.0 else b)
    if near_x:
        if a >= b or abs(v) >= b - a2 / b:
            return u, (b if v >= 0 else -b)
        y = b2 * v / (b2 - a2)
        ydb = y / b
        return a * math.sqrt(abs(1 - ydb * ydb)), y
    if near_y:
        if b >= a or abs(u) >= a - b2 / a:
            return (a if u >= 0 else -a), v
        x = a2 * u / (a2 - b2)
        xda = x / a
        return x, b * math.sqrt(abs(1 - xda * xda))
    if (u / a) * (u / a) + (v / b) * (v / b) < 1.0:
        t = 0.0
    else:
        t = max(a, b) * math.sqrt(u * u + v * v)
    P = Q = 0.0
    for _ in range(64):
        P = t + a2
        Q = t + b2
        P2, Q2 = P * P, Q * Q
        f = P2 * Q2 - a2u2 * Q2 - b2v2 * P2
        if abs(f) < 1e-09:
            break
        fp = 2.0 * (P * Q * (P + Q) - a2u2 * Q - b2v2 * P)
        t -= f / fp
    return a2 * u / P, b2 * v / Q


@njit(**_OPTS)
def _closest_ellipsoid_s(a, dims, u, v, w, special):
    """WrapEllipsoid::findClosestPoint on scalars: (found, x, y, z); not found when OpenSim's Newton iteration
    fails (OpenSim then leaves its output unchanged); ``dims`` are the unscaled radii (special-case tie-break)."""
    if special < 0:
        best = np.inf
        for i in range(3):
            c = u if i == 0 else (v if i == 1 else w)
            if abs(c) <= _ROUNDOFF:
                s = 0.0
                for j in range(3):
                    if j != i:
                        s += dims[j]
                if best > s:
                    special = i
                    best = s
    if special == 0:
        y, z = _closest_ellipse(a[1], a[2], v, w)
        return True, u, y, z
    if special == 1:
        z, x = _closest_ellipse(a[2], a[0], w, u)
        return True, x, v, z
    if special == 2:
        x, y = _closest_ellipse(a[0], a[1], u, v)
        return True, x, y, w
    aa, bb, cc = a[0], a[1], a[2]
    a2, b2, c2 = aa * aa, bb * bb, cc * cc
    a2u2, b2v2, c2w2 = a2 * u * u, b2 * v * v, c2 * w * w
    if (u / aa) * (u / aa) + (v / bb) * (v / bb) + (w / cc) * (w / cc) < 1.0:
        t = 0.0
    else:
        t = max(aa, max(bb, cc)) * math.sqrt(u * u + v * v + w * w)
    for _ in range(64):
        P, Q, R = t + a2, t + b2, t + c2
        P2, Q2, R2 = P * P, Q * Q, R * R
        f = P2 * Q2 * R2 - a2u2 * Q2 * R2 - b2v2 * P2 * R2 - c2w2 * P2 * Q2
        if abs(f) < 1e-09:
            return True, a2 * u / P, b2 * v / Q, c2 * w / R
        PQ, PR, QR, PQR = P * Q, P * R, Q * R, P * Q * R
        fp = 2.0 * (PQR * (QR + PR + PQ) - a2u2 * QR * (Q + R) - b2v2 * PR * (P + R) - c2w2 * PQ * (P + Q))
        t -= f / fp
    return False, 0.0, 0.0, 0.0


@njit(**_OPTS)
def _closest_ellipsoid(a, dims, p, out, special):
    """:func:`_closest_ellipsoid_s` writing into ``out`` (left unchanged when not found)."""
    ok, x, y, z = _closest_ellipsoid_s(a, dims, p[0], p[1], p[2], special)
    if ok:
        out[0] = x
        out[1] = y
        out[2] = z


@njit(**_OPTS)
def _tangent_residuals(r1, d1, p1, m, a, vs, vs4):
    ee = np.empty(4)
    nr1 = 2.0 * (r1 - m) / (a * a)
    ee[0] = _dot(vs, r1) + vs4
    e1 = -1.0
    for i in range(3):
        e1 += ((r1[i] - m[i]) / a[i]) ** 2
    ee[1] = e1
    ee[2] = _dot(nr1, r1) + d1
    ee[3] = _dot(nr1, p1) + d1
    return ee, ee[0] ** 2 + ee[1] ** 2 + ee[2] ** 2 + ee[3] ** 2


@njit(**_OPTS)
def _inv4(A):
    """Inverse of a 4×4 matrix (Gauss-Jordan elimination with partial pivoting; NaN when singular)."""
    M = A.copy()
    inv = np.eye(4)
    for c in range(4):
        piv = c
        for r in range(c + 1, 4):
            if abs(M[r, c]) > abs(M[piv, c]):
                piv = r
        if M[piv, c] == 0.0:
            return np.full((4, 4), np.nan)
        if piv != c:
            for k in range(4):
                M[c, k], M[piv, k] = M[piv, k], M[c, k]
                inv[c, k], inv[piv, k] = inv[piv, k], inv[c, k]
        d = M[c, c]
        for k in range(4):
            M[c, k] /= d
            inv[c, k] /= d
        for r in range(4):
            if r != c:
                f = M[r, c]
                if f != 0.0:
                    for k in range(4):
                        M[r, k] -= f * M[c, k]
                        inv[r, k] -= f * inv[c, k]
    return inv


@njit(**_OPTS)
def _tangent_point(p1e, r1, p1, m, a, vs, vs4):
    """WrapEllipsoid::calcTangentPoint (normalised coordinates): the adjusted r1."""
    if abs(p1e) < 0.0001:
        return p1.copy()
    r1 = r1.copy()
    alpha = 0.01
    nr1 = 2.0 * (r1 - m) / (a * a)
    d1 = -_dot(nr1, r1)
    ee, ssq = _tangent_residuals(r1, d1, p1, m, a, vs, vs4)
    ssqo = ssq
    nit = 0
    dedth = np.zeros((4, 4))
    vt = np.zeros(4)
    while ssq > 0.00000001 and nit < 50:
        nit += 1
        for i in range(3):
            dedth[i, 0] = vs[i]
            dedth[i, 1] = 2.0 * (r1[i] - m[i]) / (a[i] * a[i])
            dedth[i, 2] = 2.0 * (2.0 * r1[i] - m[i]) / (a[i] * a[i])
            dedth[i, 3] = 2.0 * p1[i] / (a[i] * a[i])
        dedth[3, 0] = 0.0
        dedth[3, 1] = 0.0
        dedth[3, 2] = 1.0
        dedth[3, 3] = 1.0
        p1r1 = _unit(p1 - r1)
        p1m = _unit(p1 - m)
        pcos = _dot(p1r1, p1m)
        dd = 1.0 - pcos ** 100 if pcos > 0.1 else 1.0
        v = np.zeros(4)
        for i in range(4):
            for j in range(4):
                v[i] -= dedth[i, j] * ee[j]
        dedth2 = np.zeros((4, 4))
        for i in range(4):
            for j in range(4):
                for k in range(4):
                    dedth2[i, j] += dedth[i, k] * dedth[j, k]
        diag = np.empty(4)
        for i in range(4):
            diag[i] = dedth2[i, i]
        nit2 = 0
        while ssq >= ssqo and nit2 < 1000:
            for i in range(4):
                dedth2[i, i] = diag[i] * (1.0 + alpha)
            inv = _inv4(dedth2)
            for i in range(4):
                s = 0.0
                for j in range(4):
                    s += dd * inv[i, j] * v[j] / 16.0
                vt[i] = s
            r1 += vt[:3]
            d1 += vt[3]
            ee, s2 = _tangent_residuals(r1, d1, p1, m, a, vs, vs4)
            ssqo = ssq
            ssq = s2
            alpha *= 4.0
            nit2 += 1
        alpha /= 8.0
        fakt = 0.5
        nit2 = 0
        while ssq <= ssqo and nit2 < 1000:
            fakt *= 2.0
            r1 += vt[:3] * fakt
            d1 += vt[3] * fakt
            ee, s2 = _tangent_residuals(r1, d1, p1, m, a, vs, vs4)
            ssqo = ssq
            ssq = s2
            nit2 += 1
        r1 -= vt[:3] * fakt
        d1 -= vt[3] * fakt
        ee, ssq = _tangent_residuals(r1, d1, p1, m, a, vs, vs4)
        ssqo = ssq
    return r1


@njit(**_OPTS)
def _ellipsoid_distance(r1, r2, m, a, vs, vs4, far_side, factor):
    """WrapEllipsoid::CalcDistanceOnEllipsoid (normalised): (length, first interior point, last interior
    point, number of wrap points)."""
    dr = r1 - r2
    ln = _norm(dr) / factor
    if ln < 0.001:
        return ln * factor, r2, r1, 2
    nseg = min(int(ln / 0.001), 499)
    imax = 0
    for i in range(1, 3):
        if abs(vs[i]) > abs(vs[imax]):
            imax = i
    u = np.zeros(3)
    u[imax] = 1.0
    mu = (-_dot(vs, m) - vs4) / _dot(vs, u)
    a0 = m + mu * u
    ar1 = _unit(r1 - a0)
    ar2 = _unit(r2 - a0)
    phi0 = _acos(_dot(ar1, ar2))
    if far_side:
        dphi = -(2 * math.pi - phi0) / nseg
    else:
        dphi = phi0 / nseg
    vsz = _unit(_cross(ar1, ar2))
    vsy = _cross(vsz, ar1)
    f2 = (a0 - m) / a
    cc = _dot(f2, f2) - 1.0
    px, py, pz = r1[0], r1[1], r1[2]
    total = 0.0
    first = r2
    for i in range(nseg - 1):     # scalar code: no temporary arrays in this loop
        phi = (i + 1) * dphi
        c, s = math.cos(phi), math.sin(phi)
        rx = ar1[0] * c + vsy[0] * s + vsz[0] * 0.0
        ry = ar1[1] * c + vsy[1] * s + vsz[1] * 0.0
        rz = ar1[2] * c + vsy[2] * s + vsz[2] * 0.0
        fx, fy, fz = rx / a[0], ry / a[1], rz / a[2]
        aa = fx * fx + fy * fy + fz * fz
        bb = 2.0 * (fx * f2[0] + fy * f2[1] + fz * f2[2])
        mu3 = (-bb + math.sqrt(bb * bb - 4.0 * aa * cc)) / (2.0 * aa)
        qx, qy, qz = a0[0] + mu3 * rx, a0[1] + mu3 * ry, a0[2] + mu3 * rz
        if i == 0:
            first = _vec(qx, qy, qz)
        dx, dy, dz = qx - px, qy - py, qz - pz
        total += math.sqrt(dx * dx + dy * dy + dz * dz)
        px, py, pz = qx, qy, qz
    dx, dy, dz = r2[0] - px, r2[1] - py, r2[2] - pz
    total += math.sqrt(dx * dx + dy * dy + dz * dz)
    last = r1 if nseg < 2 else _vec(px, py, pz)
    return total, first, last, nseg + 1


@njit(**_OPTS)
def wrap_ellipsoid(point1, point2, dims, method, wrap_axis, wrap_sign):
    """WrapEllipsoid::wrapLine in the ellipsoid frame: (code, r1, r2, wrap length)."""
    nan3 = np.full(3, np.nan)
    factor = 3.0 / (dims[0] + dims[1] + dims[2])
    p1 = point1 * factor
    p2 = point2 * factor
    m = np.zeros(3)
    a = dims * factor
    p1e, p2e = -1.0, -1.0
    for i in range(3):
        p1e += ((p1[i] - m[i]) / a[i]) ** 2
        p2e += ((p2[i] - m[i]) / a[i]) ** 2
    if p1e < -0.0001 or p2e < -0.0001:
        return INSIDE_RADIUS, nan3, nan3, 0.0
    p1p2 = p1 - p2
    p1m = _unit(p1 - m)
    p2m = _unit(p2 - m)
    ppm = _dot(p1m, p2m) - 1.0
    if abs(ppm) < 0.0001:
        return NO_WRAP, nan3, nan3, 0.0
    f1 = p1p2 / a
    f2 = (p2 - m) / a
    aa = _dot(f1, f1)
    bb = 2.0 * _dot(f1, f2)
    cc = _dot(f2, f2) - 1.0
    disc = bb * bb - 4.0 * aa * cc
    if disc < 0.0:
        return NO_WRAP, nan3, nan3, 0.0
    l1 = (-bb + math.sqrt(disc)) / (2.0 * aa)
    l2 = (-bb - math.sqrt(disc)) / (2.0 * aa)
    if not 0.0 < l1 < 1.0 or not 0.0 < l2 < 1.0:
        return NO_WRAP, nan3, nan3, 0.0
    r1 = p2 + l1 * p1p2
    r2 = p2 + l2 * p1p2
    r1r2 = r2 - r1
    # wrapping plane: Frans' technique (most parallel axis) and/or the fan technique
    mu = _unit(p1p2)
    t = np.empty(3)
    t_sv = np.empty((3, 3))
    t_c1 = np.full((3, 3), np.nan)
    for i in range(3):
        mu[i] = abs(mu[i])
        t[i] = (m[i] - r1[i]) / r1r2[i]
        for j in range(3):
            t_sv[i, j] = r1[j] + t[i] * r1r2[j]
        _closest_ellipsoid(a, dims, t_sv[i], t_c1[i], i)
    best = 0
    for i in range(1, 3):
        if mu[i] > mu[best]:
            best = i
    c1 = np.full(3, np.nan)
    sv = np.full(3, np.nan)
    fan_weight = -np.inf
    blend_min, blend_max = 0.7073, 0.9
    if method == HYBRID or method == AXIAL:
        if method == HYBRID and mu[best] > blend_min:
            s = 1.0
            if t[best] < 0.0 or t[best] > 1.0:
                s = 0.0
            elif t[best] < 0.3:
                s = t[best] / 0.3
            elif t[best] > 1.0 - 0.3:
                s = (1.0 - t[best]) / 0.3
            if s < 1.0:
                mu[best] = blend_min + s * (mu[best] - blend_min)
        if method == AXIAL or mu[best] > blend_min:
            c1 = t_c1[best].copy()
            sv = t_sv[best].copy()
        if method == HYBRID and mu[best] < blend_max:
            t_sv[2] = r1 + 0.5 * r1r2
            cx, cy, cz = t_c1[0, 0], t_c1[0, 1], t_c1[0, 2]
            sx = sy = sz = 0.0
            for i in range(1, 300 - 1):        # the fan: scalar code, no temporary arrays
                tt = i / 300.0
                ux, uy, uz = r1[0] + tt * r1r2[0], r1[1] + tt * r1r2[1], r1[2] + tt * r1r2[2]
                ok, x, y, z = _closest_ellipsoid_s(a, dims, ux, uy, uz, -1)
                if ok:
                    cx, cy, cz = x, y, z
                vx, vy, vz = cx - ux, cy - uy, cz - uz
                mag = math.sqrt(vx * vx + vy * vy + vz * vz)
                if mag >= _EPS:
                    f = 1.0 / mag
                    vx, vy, vz = vx * f, vy * f, vz * f
                else:
                    vx = vy = vz = 0.0
                sx += vx
                sy += vy
                sz += vz
            v_sum = _unit(_vec(sx, sy, sz))
            t_c1[0] = t_sv[2] + v_sum
            if mu[best] <= blend_min:
                _closest_ellipsoid(a, dims, t_c1[0], c1, -1)
                sv = t_sv[2].copy()
                fan_weight = 1.0
            else:
                tt = (mu[best] - blend_min) / (blend_max - blend_min)
                omt = 1.0 - tt
                _closest_ellipsoid(a, dims, t_c1[0], t_c1[1], -1)
                t_c1[2] = tt * c1 + omt * t_c1[1]
                sv = tt * sv + omt * t_sv[2]
                _closest_ellipsoid(a, dims, t_c1[2], c1, -1)
                fan_weight = omt
    else:
        sv = r1 + 0.5 * (r2 - r1)
        _closest_ellipsoid(a, dims, sv, c1, -1)
    use_c1 = True
    if method == AXIAL:
        use_c1 = t[best] > 0.0 and t[best] < 1.0
    if use_c1:
        r1 = c1.copy()
        r2 = c1.copy()
    ax, sg = wrap_axis, wrap_sign
    if sg != 0:
        dist = c1[ax] - m[ax]
        if _dsign(dist) != sg:
            orig = c1[ax]
            c1 = c1.copy()
            c1[ax] = -c1[ax]
            r1 = c1.copy()
            r2 = c1.copy()
            if abs(fan_weight - (-np.inf)) <= _ROUNDOFF:
                fan_weight = 1.0 - (mu[best] - blend_min) / (blend_max - blend_min)
            fan_weight = min(fan_weight, 1.0)
            if fan_weight > 0.0:
                bis = (orig + c1[ax]) / 2.0
                c1[ax] = c1[ax] + fan_weight * (bis - c1[ax])
                tc1 = c1.copy()
                _closest_ellipsoid(a, dims, tc1, c1, -1)
    p1c1 = p1 - c1
    vs = _unit(_cross(p1p2, p1c1))
    vs4 = -_dot(vs, c1)
    r1 = _tangent_point(p1e, r1, p1, m, a, vs, vs4)
    r2 = _tangent_point(p2e, r2, p2, m, a, vs, vs4)
    far_side = False
    wl, w1, w2, npts = _ellipsoid_distance(r1, r2, m, a, vs, vs4, far_side, factor)
    if sg != 0 and npts > 2:
        r1p1 = _unit(p1 - r1)
        r1w1 = _unit(w1 - r1)
        r2p2 = _unit(p2 - r2)
        r2w2 = _unit(w2 - r2)
        if _dot(r1p1, r1w1) > 0.0 or _dot(r2p2, r2w2) > 0.0:
            wl, w1, w2, npts = _ellipsoid_distance(r1, r2, m, a, vs, vs4, True, factor)
    return MANDATORY_WRAP, r1 / factor, r2 / factor, wl / factor


# ----------------------------------------------------------------------------- torus
# WrapTorus finds the point of the torus' centre circle closest to the segment with MINPACK's lmdif (OpenSim's
# C port, one unknown, one residual, tolerances 1e-4, fixed forward-difference step 1e-5) and wraps over a
# cylinder of the tube radius placed there, tangent to the circle. Below: that lmdif for m = n = 1.
_MACHEP = 1.2e-16
_DWARF = 1.0e-38


@njit(**_OPTS)
def _enorm1(x):
    """MINPACK enorm of a single number."""
    xabs = abs(x)
    if xabs > 3.834e-20 and xabs < 1.304e19:
        return math.sqrt(xabs * xabs)
    if xabs > 3.834e-20:
        return xabs * math.sqrt(1.0)
    return xabs * math.sqrt(1.0 if xabs != 0.0 else 0.0)


@njit(**_OPTS)
def _circle_resid(u, p1, p2, r):
    """WrapTorus::calcCircleResids."""
    d0, d1, d2 = p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]
    mag = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    nx, ny, nz = d0 / mag, d1 / mag, d2 / mag
    c2 = 2.0 * (p1[0] * nx + p1[1] * ny + p1[2] * nz)
    c3 = p1[0] * nx + p1[1] * ny
    c4 = nx * nx + ny * ny
    c5 = p1[0] * p1[0] + p1[1] * p1[1]
    return c2 + 2.0 * u - 2.0 * r * (2.0 * c4 * u + 2.0 * c3) / math.sqrt(u * u * c4 + 2.0 * c3 * u + c5)


@njit(**_OPTS)
def _lmpar1(r, diag, qtb, delta, par):
    """MINPACK lmpar for n = 1: (par, x, sdiag)."""
    nsing = 1
    wa1 = qtb
    if r == 0.0:
        nsing = 0
        wa1 = 0.0
    if nsing >= 1:
        wa1 = wa1 / r
    x = wa1
    it = 0
    sdiag = 0.0
    wa2 = diag * x
    dxnorm = _enorm1(wa2)
    fp = dxnorm - delta
    if fp <= 0.1 * delta:
        return 0.0, x, sdiag
    parl = 0.0
    if nsing >= 1:
        w = diag * (wa2 / dxnorm)
        w = (w - 0.0) / r
        temp = _enorm1(w)
        parl = ((fp / delta) / temp) / temp
    w = (0.0 + r * qtb) / diag
    gnorm = _enorm1(w)
    paru = gnorm / delta
    if paru == 0.0:
        paru = _DWARF / min(delta, 0.1)
    par = max(par, parl)
    par = min(par, paru)
    if par == 0.0:
        par = gnorm / dxnorm
    while True:
        it += 1
        if par == 0.0:
            par = max(_DWARF, 0.001 * paru)
        d = math.sqrt(par) * diag
        # qrsolv for n = 1: a Givens rotation eliminating d
        rr = r
        wa = qtb
        if d != 0.0:
            sd = d
            qtbpj = 0.0
            if abs(rr) < abs(sd):
                cotan = rr / sd
                sin = 0.5 / math.sqrt(0.25 + 0.25 * cotan * cotan)
                cos = sin * cotan
            else:
                tan = sd / rr
                cos = 0.5 / math.sqrt(0.25 + 0.25 * tan * tan)
                sin = cos * tan
            rr = cos * rr + sin * sd
            temp = cos * wa + sin * qtbpj
            wa = temp
        sdiag = rr
        if sdiag == 0.0:
            wa = 0.0
        else:
            wa = (wa - 0.0) / sdiag
        x = wa
        wa2 = diag * x
        dxnorm = _enorm1(wa2)
        temp = fp
        fp = dxnorm - delta
        if abs(fp) <= 0.1 * delta or (parl == 0.0 and fp <= temp < 0.0) or it == 10:
            return par, x, sdiag
        w = diag * (wa2 / dxnorm)
        w = w / sdiag
        temp = _enorm1(w)
        parc = ((fp / delta) / temp) / temp
        if fp > 0.0:
            parl = max(parl, par)
        if fp < 0.0:
            paru = min(paru, par)
        par = max(parl, par + parc)


@njit(**_OPTS)
def _lmdif1(p1, p2, r):
    """OpenSim's lmdif_C on WrapTorus' circle residual from q = 0 (ftol = xtol = 1e-4, gtol = 0, 500
    evaluations, factor 0.2, mode 1): the final q."""
    ftol = xtol = 1e-4
    factor = 0.2
    x = 0.0
    fvec = _circle_resid(x, p1, p2, r)
    nfev = 1
    fnorm = _enorm1(fvec)
    par = 0.0
    it = 1
    diag = 0.0
    delta = 0.0
    xnorm = 0.0
    while True:                                   # outer loop (L30)
        h = 1e-5
        fjac = (_circle_resid(x + h, p1, p2, r) - fvec) / h
        # qrfac, m = n = 1
        acnorm = _enorm1(fjac)
        ajnorm = acnorm
        a = fjac
        if ajnorm != 0.0:
            if a < 0.0:
                ajnorm = -ajnorm
            a = a / ajnorm
            a = a + 1.0
        rdiag = -ajnorm
        wa2 = acnorm
        if it == 1:
            diag = wa2
            if wa2 == 0.0:
                diag = 1.0
            xnorm = _enorm1(diag * x)
            delta = factor * xnorm
            if abs(delta) <= 1e-4:
                delta = factor
        wa4 = fvec
        if a != 0.0:
            s = 0.0 + a * wa4
            temp = -s / a
            wa4 = wa4 + a * temp
        R = rdiag
        qtf = wa4
        gnorm = 0.0
        if fnorm != 0.0 and wa2 != 0.0:
            s = 0.0 + R * (qtf / fnorm)
            gnorm = max(gnorm, abs(s / wa2))
        if gnorm <= 0.0:
            return x
        diag = max(diag, wa2)
        while True:                               # inner loop (L200)
            par, step, _sd = _lmpar1(R, diag, qtf, delta, par)
            step = -step
            xn = x + step
            pnorm = _enorm1(diag * step)
            if it == 1:
                delta = min(delta, pnorm)
            f1 = _circle_resid(xn, p1, p2, r)
            nfev += 1
            fnorm1 = _enorm1(f1)
            actred = -1.0
            if 0.1 * fnorm1 < fnorm:
                temp = fnorm1 / fnorm
                actred = 1.0 - temp * temp
            w3 = 0.0 + R * step
            temp1 = _enorm1(w3) / fnorm
            temp2 = (math.sqrt(par) * pnorm) / fnorm
            prered = temp1 * temp1 + (temp2 * temp2) / 0.5
            dirder = -(temp1 * temp1 + temp2 * temp2)
            ratio = 0.0
            if prered != 0.0:
                ratio = actred / prered
            if ratio <= 0.25:
                if actred >= 0.0:
                    temp = 0.5
                else:
                    temp = 0.5 * dirder / (dirder + 0.5 * actred)
                if 0.1 * fnorm1 >= fnorm or temp < 0.1:
                    temp = 0.1
                delta = temp * min(delta, pnorm / 0.1)
                par = par / temp
            elif par == 0.0 or ratio >= 0.75:
                delta = pnorm / 0.5
                par = 0.5 * par
            if ratio >= 0.0001:
                x = xn
                fvec = f1
                xnorm = _enorm1(diag * x)
                fnorm = fnorm1
                it += 1
            info = 0
            if abs(actred) <= ftol and prered <= ftol and 0.5 * ratio <= 1.0:
                info = 1
            if delta <= xtol * xnorm:
                info = 2
            if info != 0:
                return x
            if nfev >= 500:
                info = 5
            if abs(actred) <= _MACHEP and prered <= _MACHEP and 0.5 * ratio <= 1.0:
                info = 6
            if delta <= _MACHEP * xnorm:
                info = 7
            if gnorm <= _MACHEP:
                info = 8
            if info != 0:
                return x
            if ratio >= 0.0001:
                break


@njit(**_OPTS)
def _torus_closest(radius, p1, p2, wrap_sign, wrap_axis):
    """WrapTorus::findClosestPoint: (found, point of the centre circle)."""
    a = np.empty((2, 3))
    dist = np.empty(2)
    for k in range(2):
        s, e = (p1, p2) if k == 0 else (p2, p1)
        u = _lmdif1(s, e, radius)
        d0, d1, d2 = p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]
        mag = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if k == 0:
            nx, ny, nz = (p2[0] - p1[0]) / mag, (p2[1] - p1[1]) / mag, (p2[2] - p1[2]) / mag
            x, y, z = p1[0] + u * nx, p1[1] + u * ny, p1[2] + u * nz
        else:
            nx, ny, nz = (p1[0] - p2[0]) / mag, (p1[1] - p2[1]) / mag, (p1[2] - p2[2]) / mag
            x, y, z = p2[0] + u * nx, p2[1] + u * ny, p2[2] + u * nz
        a[k, 0], a[k, 1], a[k, 2] = x, y, z
        dist[k] = math.sqrt(x * x + y * y + z * z + radius * radius - 2.0 * radius * math.sqrt(x * x + y * y))
    if wrap_sign != 0:
        s0 = _dsign(a[0, wrap_axis]) == wrap_sign
        s1 = _dsign(a[1, wrap_axis]) == wrap_sign
        if s0 and s1:
            better = 0 if dist[0] < dist[1] else 1
        elif s0:
            better = 0
        elif s1:
            better = 1
        else:
            return False, _T0
    else:
        better = 0 if dist[0] < dist[1] else 1
    mag = math.sqrt(a[better, 0] * a[better, 0] + a[better, 1] * a[better, 1])
    return True, (a[better, 0] * radius / mag, a[better, 1] * radius / mag, 0.0)


@njit(**_OPTS)
def wrap_torus(point1, point2, inner, outer, wrap_axis, wrap_sign, single):
    """WrapTorus::wrapLine in the torus frame: (code, r1, r2, wrap length). OpenSim reports every segment
    as wrapped; where its cylinder does not wrap, r1 and r2 are NaN (the segment is never chosen)."""
    p1 = (point1[0], point1[1], point1[2])
    p2 = (point2[0], point2[1], point2[2])
    found, closest = _torus_closest(outer, p1, p2, wrap_sign, wrap_axis)
    if not found:
        return NO_WRAP, _vec(np.nan, np.nan, np.nan), _vec(np.nan, np.nan, np.nan), 0.0
    c = _t_mul(-1.0, closest)
    cx = _t_unit(c)
    cy = (0.0, 0.0, -1.0)
    cz = _t_cross(cx, cy)
    # cylinder frame: rows cx, cy, cz; origin at R c
    def_R = ((cx[0], cx[1], cx[2]), (cy[0], cy[1], cy[2]), (cz[0], cz[1], cz[2]))
    o = (_dot(def_R[0], c), _dot(def_R[1], c), _dot(def_R[2], c))
    q1 = _t_add((_dot(def_R[0], p1), _dot(def_R[1], p1), _dot(def_R[2], p1)), o)
    q2 = _t_add((_dot(def_R[0], p2), _dot(def_R[1], p2), _dot(def_R[2], p2)), o)
    code, r1, r2, wl = _cylinder(q1, q2, inner, 10000.0, 0, 1, single)
    if code == WRAPPED or code == MANDATORY_WRAP:
        return WRAPPED, _from_cyl(def_R, o, r1), _from_cyl(def_R, o, r2), wl
    return WRAPPED, _vec(np.nan, np.nan, np.nan), _vec(np.nan, np.nan, np.nan), wl


@njit(**_OPTS)
def _from_cyl(R, o, r):
    """R^T (r - o): a point of the torus' cylinder frame in the torus frame."""
    d = _t_sub(r, o)
    return _vec(R[0][0] * d[0] + R[1][0] * d[1] + R[2][0] * d[2], R[0][1] * d[0] + R[1][1] * d[1] + R[2][1] * d[2],
                R[0][2] * d[0] + R[1][2] * d[1] + R[2][2] * d[2])


# ----------------------------------------------------------------------------- frames
@njit(**_OPTS)
def _to_local(x, R, p):
    """R^T (x - p): a point in a frame with orientation R and origin p (array of :func:`_t_to_local`)."""
    a = _t_to_local(x, R, p)
    return _vec(a[0], a[1], a[2])


@njit(**_OPTS)
def _to_world(r, R, p):
    """p + R r (array of :func:`_t_to_world`)."""
    a = _t_to_world(r, R, p)
    return _vec(a[0], a[1], a[2])


@njit(**_OPTS)
def _t_to_local(x, R, p):
    """R^T (x - p) as an (x, y, z) tuple: a point in a frame with orientation R and origin p."""
    d0, d1, d2 = x[0] - p[0], x[1] - p[1], x[2] - p[2]
    return (d0 * R[0, 0] + d1 * R[1, 0] + d2 * R[2, 0], d0 * R[0, 1] + d1 * R[1, 1] + d2 * R[2, 1],
            d0 * R[0, 2] + d1 * R[1, 2] + d2 * R[2, 2])


@njit(**_OPTS)
def _t_to_world(r, R, p):
    """p + R r as an (x, y, z) tuple."""
    return (p[0] + (R[0, 0] * r[0] + R[0, 1] * r[1] + R[0, 2] * r[2]),
            p[1] + (R[1, 0] * r[0] + R[1, 1] * r[1] + R[1, 2] * r[2]),
            p[2] + (R[2, 0] * r[0] + R[2, 1] * r[1] + R[2, 2] * r[2]))


@njit(**_OPTS)
def _t_dist(a, b):
    """|a − b| (the operations of ``_norm(a - b)``)."""
    d0, d1, d2 = a[0] - b[0], a[1] - b[1], a[2] - b[2]
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@njit(**_OPTS)
def _frame_into(Rout, pout, Rb, pb, R, t):
    """World pose (Rb R, pb + Rb t) of a frame (R, t) fixed in a body at (Rb, pb), written in place."""
    w = _t_to_world(t, Rb, pb)
    for i in range(3):
        pout[i] = w[i]
        for j in range(3):
            Rout[i, j] = Rb[i, 0] * R[0, j] + Rb[i, 1] * R[1, j] + Rb[i, 2] * R[2, j]


@njit(**_OPTS)
def _frame(Rb, pb, R, t):
    """World pose (Rb R, pb + Rb t) of a frame (R, t) fixed in a body at (Rb, pb)."""
    Rout, pout = np.empty((3, 3)), np.empty(3)
    _frame_into(Rout, pout, Rb, pb, R, t)
    return Rout, pout


# ----------------------------------------------------------------------------- the path algorithm
class WrapSpec:
    """A PathWrap prepared for evaluation (object kind, parameters, frame in its body)."""

    def __init__(self, pw: PathWrap, body_index: int) -> None:
        wo = pw.wrap_object
        self.name = pw.name
        self.object = wo.name
        self.kind = KIND_CODE[wo.kind]
        self.body = body_index
        self.R = np.asarray(wo.rotation, dtype=float).reshape(3, 3)
        self.t = np.asarray(wo.translation, dtype=float)
        self.axis, self.sign = wo.wrap_axis_sign
        self.active = wo.active
        self.dims = np.asarray(wo.dimensions, dtype=float)
        self.method = METHOD_CODE[pw.method.lower()]
        self.start, self.end = pw.range

    def wrap(self, a: np.ndarray, b: np.ndarray, single: bool):
        """Wrap the segment a→b (points in the wrap object's frame)."""
        if self.kind == CYLINDER:
            return wrap_cylinder(a, b, self.dims[0], self.dims[1], self.axis, self.sign, single)
        if self.kind == SPHERE:
            return wrap_sphere(a, b, self.dims[0], self.axis, self.sign)
        if self.kind == TORUS:
            return wrap_torus(a, b, self.dims[0], self.dims[1], self.axis, self.sign, single)
        return wrap_ellipsoid(a, b, self.dims, self.method, self.axis, self.sign)


def wrapped_path_length(X: np.ndarray, active: np.ndarray, wraps: Sequence[WrapSpec],
                        frames: Sequence[tuple[np.ndarray, np.ndarray]]) -> float:
    """Length of one path at one configuration, wrapped as OpenSim's ``applyWrapObjects``.

    Args:
        X: (n_points, 3) world positions of the path's PathPointSet (inactive points included).
        active: (n_points,) which points are in the path (conditional points).
        wraps: The path's PathWraps.
        frames: Each wrap object's world pose (R, p) at this configuration.
    """
    n_orig = len(X)
    path: list[tuple[int, int]] = [(-1, i) for i in range(n_orig) if active[i]]   # (-1, point) or (wrap, 1|2)
    pos: dict[tuple[int, int], np.ndarray] = {(-1, i): X[i] for i in range(n_orig)}
    surf: dict[tuple[int, int], float] = {}
    obj = [w.object for w in wraps]
    cached: dict[tuple[int, int], np.ndarray] = {}

    def ground(e: tuple[int, int]) -> np.ndarray:
        # OpenSim caches a point's location in ground (Point::getLocationInGround) the first time it is
        # read for a state; a wrap point moved later by PathWrapPoint::setLocation keeps the cached value.
        if e[0] < 0:
            return pos[e]
        if e not in cached:
            cached[e] = pos[e]
        return cached[e]

    def same_object(e1, e2) -> bool:
        return e1[0] >= 0 and e2[0] >= 0 and obj[e1[0]] == obj[e2[0]]

    def length() -> float:
        total = 0.0
        for e1, e2 in itertools.pairwise(path):
            if same_object(e1, e2):
                total += surf[e2]
            else:
                d = ground(e2) - ground(e1)
                total += math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        return total

    def remove(k: int) -> None:
        if (k, 1) in path:
            j = path.index((k, 1))
            del path[j:j + 2]

    nw = len(wraps)
    order = list(range(nw))
    result = [NO_WRAP] * nw
    last = math.inf
    single = nw == 1
    for kk in range(1 if nw < 2 else 8):
        for i in range(nw):
            result[i] = NO_WRAP
            k = order[i]
            w = wraps[k]
            remove(k)
            if not w.active:
                continue
            ws = 0 if w.start < 1 else w.start - 1
            we = n_orig - 1 if w.end < 1 else w.end - 1
            fwd = [j for j in range(ws, we + 1) if active[j]]
            if not fwd:
                return length()
            start, end = path.index((-1, fwd[0])), path.index((-1, fwd[-1]))
            R, p = frames[k]
            best = None
            min_change = math.inf
            for pt1 in range(start, end):
                e1, e2 = path[pt1], path[pt1 + 1]
                if same_object(e1, e2):
                    continue
                a = _to_local(pos[e1], R, p)
                b = _to_local(pos[e2], R, p)
                code, r1, r2, wl = w.wrap(a, b, single)
                result[i] = code
                if code == MANDATORY_WRAP:
                    best = (pt1, r1, r2, wl)
                    break
                if code == WRAPPED:
                    g1, g2 = _to_world(r1, R, p), _to_world(r2, R, p)
                    x1, x2 = ground(e1), ground(e2)
                    change = np.linalg.norm(g1 - x1) + wl + np.linalg.norm(x2 - g2) - np.linalg.norm(x2 - x1)
                    if change < min_change:
                        best = (pt1, r1, r2, wl)
                        min_change = change
            if best is not None:
                pt1, r1, r2, wl = best
                pos[(k, 1)] = _to_world(r1, R, p)
                pos[(k, 2)] = _to_world(r2, R, p)
                surf[(k, 1)] = 0.0
                surf[(k, 2)] = wl
                path.insert(pt1 + 1, (k, 1))
                path.insert(pt1 + 2, (k, 2))
        total = length()
        if abs(total - last) < 0.0005:
            break
        last = total
        if kk == 0 and nw > 1 and result[0] == NO_WRAP and result[1] == INSIDE_RADIUS:
            order[0], order[1] = 1, 0
            remove(0)
    return length()


# ----------------------------------------------------------------------------- the same loop, compiled
@njit(**_OPTS)
def _wrap_any(kind, a, b, dims, method, axis, sign, single):
    if kind == CYLINDER:
        return wrap_cylinder(a, b, dims[0], dims[1], axis, sign, single)
    if kind == SPHERE:
        return wrap_sphere(a, b, dims[0], axis, sign)
    if kind == TORUS:
        return wrap_torus(a, b, dims[0], dims[1], axis, sign, single)
    return wrap_ellipsoid(a, b, dims, method, axis, sign)


@njit(**_OPTS)
def _ground(e, n, pos, cache, cached):
    if e < n:
        return pos[e]
    if not cached[e]:
        cache[e] = pos[e]
        cached[e] = True
    return cache[e]


@njit(**_OPTS)
def _same_object(e1, e2, n, objs):
    return e1 >= n and e2 >= n and objs[(e1 - n) // 2] == objs[(e2 - n) // 2]


@njit(**_OPTS)
def _length(path, npath, n, objs, pos, cache, cached, surf):
    total = 0.0
    for j in range(npath - 1):
        e1, e2 = path[j], path[j + 1]
        if _same_object(e1, e2, n, objs):
            total += surf[e2]
        else:
            x2 = _ground(e2, n, pos, cache, cached)
            x1 = _ground(e1, n, pos, cache, cached)
            d0, d1, d2 = x2[0] - x1[0], x2[1] - x1[1], x2[2] - x1[2]
            total += math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    return total


@njit(**_OPTS)
def _remove(path, npath, e):
    for j in range(npath):
        if path[j] == e:
            for k in range(j, npath - 2):
                path[k] = path[k + 2]
            return npath - 2
    return npath


@njit(**_OPTS)
def _index(path, npath, e):
    for j in range(npath):
        if path[j] == e:
            return j
    return -1


@njit(**_OPTS)
def _path_length(X, active, kinds, dims, methods, axes, signs, rstart, rend, actives, objs, Rw, pw):
    """:func:`wrapped_path_length` compiled: path entries are point indices (< n) or n + 2 k + (0 | 1) for
    wrap k's first and second tangent point."""
    n = X.shape[0]
    nw = kinds.shape[0]
    cap = n + 2 * nw
    scratch = (np.empty(cap, dtype=np.int64), np.zeros((cap, 3)), np.zeros((cap, 3)),
               np.zeros(cap, dtype=np.bool_), np.zeros(cap), np.empty(nw, dtype=np.int64),
               np.empty(nw, dtype=np.int64))
    return _path_core(X, active, kinds, dims, methods, axes, signs, rstart, rend, actives, objs, Rw, pw,
                      *scratch)[0]


@njit(**_OPTS)
def _path_core(X, active, kinds, dims, methods, axes, signs, rstart, rend, actives, objs, Rw, pw,
               path, pos, cache, cached, surf, order, result):
    """:func:`_path_length` on caller-owned scratch arrays (at least n + 2 nw entries; nw for ``order``,
    ``result``): returns ``(length, npath)`` and leaves the final path in ``path[:npath]``, its entries'
    positions in ``pos`` (tangent points: ``cache`` where ``cached``, the value the length used) and the
    wrap lengths in ``surf``."""
    n = X.shape[0]
    nw = kinds.shape[0]
    npath = 0
    for i in range(n):
        if active[i]:
            path[npath] = i
            npath += 1
    pos[:n] = X
    cached[:n + 2 * nw] = False
    for k in range(nw):
        order[k] = k
        result[k] = NO_WRAP
    last = np.inf
    single = nw == 1
    n_iter = 1 if nw < 2 else 8
    for kk in range(n_iter):
        for i in range(nw):
            result[i] = NO_WRAP
            k = order[i]
            npath = _remove(path, npath, n + 2 * k)
            if not actives[k]:
                continue
            ws = 0 if rstart[k] < 1 else rstart[k] - 1
            we = n - 1 if rend[k] < 1 else rend[k] - 1
            jf = ws
            while jf <= we and not active[jf]:
                jf += 1
            if jf > we:
                return _length(path, npath, n, objs, pos, cache, cached, surf), npath
            jr = we
            while jr >= ws and not active[jr]:
                jr -= 1
            start, end = _index(path, npath, jf), _index(path, npath, jr)
            R, p = Rw[k], pw[k]
            best_pt = -1
            best_r1 = _T0
            best_r2 = _T0
            best_wl = 0.0
            min_change = np.inf
            for pt1 in range(start, end):     # (x, y, z) tuples: no heap allocation in this loop
                e1, e2 = path[pt1], path[pt1 + 1]
                if _same_object(e1, e2, n, objs):
                    continue
                a = _t_to_local(pos[e1], R, p)
                b = _t_to_local(pos[e2], R, p)
                if kinds[k] == CYLINDER:
                    code, r1, r2, wl = _cylinder(a, b, dims[k][0], dims[k][1], axes[k], signs[k], single)
                else:
                    code, r1v, r2v, wl = _wrap_any(kinds[k], _vec(a[0], a[1], a[2]), _vec(b[0], b[1], b[2]),
                                                   dims[k], methods[k], axes[k], signs[k], single)
                    r1, r2 = (r1v[0], r1v[1], r1v[2]), (r2v[0], r2v[1], r2v[2])
                result[i] = code
                if code == MANDATORY_WRAP:
                    best_pt, best_r1, best_r2, best_wl = pt1, r1, r2, wl
                    break
                if code == WRAPPED:
                    g1, g2 = _t_to_world(r1, R, p), _t_to_world(r2, R, p)
                    x1 = _ground(e1, n, pos, cache, cached)
                    x2 = _ground(e2, n, pos, cache, cached)
                    change = _t_dist(g1, x1) + wl + _t_dist(x2, g2) - _t_dist(x2, x1)
                    if change < min_change:
                        best_pt, best_r1, best_r2, best_wl = pt1, r1, r2, wl
                        min_change = change
            if best_pt >= 0:
                e = n + 2 * k
                g1, g2 = _t_to_world(best_r1, R, p), _t_to_world(best_r2, R, p)
                for r in range(3):
                    pos[e, r] = g1[r]
                    pos[e + 1, r] = g2[r]
                surf[e] = 0.0
                surf[e + 1] = best_wl
                for j in range(npath - 1, best_pt, -1):
                    path[j + 2] = path[j]
                path[best_pt + 1] = e
                path[best_pt + 2] = e + 1
                npath += 2
        total = _length(path, npath, n, objs, pos, cache, cached, surf)
        if abs(total - last) < 0.0005:
            break
        last = total
        if kk == 0 and nw > 1 and result[0] == NO_WRAP and result[1] == INSIDE_RADIUS:
            order[0], order[1] = 1, 0
            npath = _remove(path, npath, n)
    return _length(path, npath, n, objs, pos, cache, cached, surf), npath


@njit(**_OPTS)
def _lengths_rows(out, r0, r1, X, keep, body_R, body_p, pstart, pend, wstart, wend, kinds, dims, methods, axes,
                  signs, rstart, rend, actives, objs, wbody, wR, wt):
    for i in range(r0, r1):
        for m in range(pstart.shape[0]):
            a, b = pstart[m], pend[m]
            w0, w1 = wstart[m], wend[m]
            Rw = np.empty((w1 - w0, 3, 3))
            pw = np.empty((w1 - w0, 3))
            for k in range(w0, w1):
                Rw[k - w0], pw[k - w0] = _frame(body_R[i, wbody[k]], body_p[i, wbody[k]], wR[k], wt[k])
            out[i, m] = _path_length(X[i, a:b], keep[i, a:b], kinds[w0:w1], dims[w0:w1], methods[w0:w1],
                                     axes[w0:w1], signs[w0:w1], rstart[w0:w1], rend[w0:w1], actives[w0:w1],
                                     objs[w0:w1], Rw, pw)


@njit(cache=True, error_model="numpy", parallel=True)
def _lengths_chunks(out, n_chunks, X, keep, body_R, body_p, pstart, pend, wstart, wend, kinds, dims, methods,
                    axes, signs, rstart, rend, actives, objs, wbody, wR, wt):
    N = X.shape[0]
    for c in prange(n_chunks):
        _lengths_rows(out, c * N // n_chunks, (c + 1) * N // n_chunks, X, keep, body_R, body_p, pstart, pend,
                      wstart, wend, kinds, dims, methods, axes, signs, rstart, rend, actives, objs, wbody, wR, wt)


def _lengths_batch(X, keep, body_R, body_p, pstart, pend, *rest):
    """(N, M) wrapped lengths; in parallel (a few chunks per thread) only for large batches."""
    N = X.shape[0]
    out = np.zeros((N, len(pstart)))
    threads = get_num_threads()
    if threads > 1 and N * len(pstart) >= 4000:
        _lengths_chunks(out, min(N, 4 * threads), X, keep, body_R, body_p, pstart, pend, *rest)
    else:
        _lengths_rows(out, 0, N, X, keep, body_R, body_p, pstart, pend, *rest)
    return out


class WrappedPaths:
    """Lengths of the wrapped paths of a :class:`pamkin.human.paths.PathSet`.

    Args:
        pathset: The straight-line path set (point positions and conditional points).
        wraps: Per path, its PathWraps (empty for straight paths).
        compiled: Run the path loop compiled (default) or in Python (the reference).

    Attributes:
        indices: The wrapped paths (indices into the path set), the columns of :meth:`lengths`.
    """

    def __init__(self, pathset, wraps: Sequence[Sequence[PathWrap]], compiled: bool = True) -> None:
        self.pathset = pathset
        self.compiled = compiled
        frames = pathset.kin.frames
        self.indices = [m for m, ws in enumerate(wraps) if ws]
        self.specs = {m: [WrapSpec(pw, frames.index(pw.wrap_object.body)) for pw in wraps[m]]
                      for m in self.indices}
        specs = [w for m in self.indices for w in self.specs[m]]
        counts = np.array([len(self.specs[m]) for m in self.indices], dtype=np.int64)
        self._wend = np.cumsum(counts)
        self._wstart = self._wend - counts
        self._pstart = np.array([pathset._path_start[m] for m in self.indices], dtype=np.int64)
        self._pend = np.array([pathset._path_end[m] for m in self.indices], dtype=np.int64)
        names = sorted({w.object for w in specs})
        self._arrays = (
            np.array([w.kind for w in specs], dtype=np.int64),
            np.array([np.pad(w.dims, (0, 3 - len(w.dims))) for w in specs], dtype=float).reshape(-1, 3),
            np.array([w.method for w in specs], dtype=np.int64),
            np.array([w.axis for w in specs], dtype=np.int64),
            np.array([w.sign for w in specs], dtype=np.int64),
            np.array([w.start for w in specs], dtype=np.int64),
            np.array([w.end for w in specs], dtype=np.int64),
            np.array([w.active for w in specs], dtype=np.bool_),
            np.array([names.index(w.object) for w in specs], dtype=np.int64),
            np.array([w.body for w in specs], dtype=np.int64),
            np.array([w.R for w in specs], dtype=float).reshape(-1, 3, 3),
            np.array([w.t for w in specs], dtype=float).reshape(-1, 3),
        )

    def _points(self, state, cols) -> np.ndarray:
        """(N, n_points, 3) world positions of the points of the wrapped paths ``cols`` (others 0)."""
        ps = self.pathset
        idx = np.concatenate([np.arange(self._pstart[c], self._pend[c]) for c in cols]) if len(cols) else \
            np.zeros(0, dtype=int)
        N = state.q.shape[0]
        local = np.broadcast_to(ps.point_local[idx], (N, len(idx), 3)).copy()
        where = {int(p): k for k, p in enumerate(idx)}
        for pid, pt in ps._moving:
            if pid in where:
                for ax in range(3):
                    cn = pt.coordinates[ax]
                    qv = state.q[:, ps.kin.coordinates.index(cn)] if cn else np.zeros(N)
                    local[:, where[pid], ax] = pt.functions[ax].value(qv)
        body = ps.point_body[idx]
        X = np.zeros((N, ps.n_points, 3))
        X[:, idx] = state.body_p[:, body] + np.matmul(state.body_R[:, body], local[..., None])[..., 0]
        return X

    def lengths(self, state, columns: Sequence[int] | None = None) -> np.ndarray:
        """(N, n_wrapped) lengths of the wrapped paths (``indices`` order, or only ``columns`` of it) [m]."""
        ps = self.pathset
        cols = range(len(self.indices)) if columns is None else columns
        X = self._points(state, cols)
        N = X.shape[0]
        keep = np.ones((N, ps.n_points), dtype=bool)
        if len(ps._cond_ids):
            v = state.q[:, ps._cond_coord]
            keep[:, ps._cond_ids] = (v >= ps._cond_lo) & (v <= ps._cond_hi)
        if self.compiled:
            cols = np.asarray(cols, dtype=np.int64)
            (kinds, dims, methods, axes, signs, rstart, rend, actives, objs, wbody, wR, wt) = self._arrays
            return _lengths_batch(np.ascontiguousarray(X), keep, np.ascontiguousarray(state.body_R),
                                  np.ascontiguousarray(state.body_p), self._pstart[cols], self._pend[cols],
                                  self._wstart[cols], self._wend[cols], kinds, dims, methods, axes, signs,
                                  rstart, rend, actives, objs, wbody, wR, wt)
        out = np.zeros((N, len(cols)))
        for col, m in enumerate(self.indices[c] for c in cols):
            a, b = ps._path_start[m], ps._path_end[m]
            specs = self.specs[m]
            for n in range(N):
                frames = []
                for w in specs:
                    Rb, pb = state.body_R[n, w.body], state.body_p[n, w.body]
                    frames.append(_frame(Rb, pb, w.R, w.t))
                out[n, col] = wrapped_path_length(X[n, a:b], keep[n, a:b], specs, frames)
        return out
