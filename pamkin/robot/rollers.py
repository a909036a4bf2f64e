"""Rollers: cable guides fixed on a bone that a PAM route's cable runs over on one side.

A roller is a cylinder (radius, length) fixed in a body, on one segment of a route (``"p1->p2"``).
The cable of that segment passes the roller on its ``side``: where the straight segment would pass
between the roller and the bone (on the other side of the roller's axis), or through the roller, the
roller holds it out and the cable wraps over the roller's surface; elsewhere the segment stays
straight. It is OpenSim's ``WrapCylinder`` with the quadrant ``+x`` in a frame whose x axis is the
roller's ``side`` and whose z axis is its ``axis`` (:func:`wrap_object`); pamkin computes it with
OpenSim 4.6's algorithm (:mod:`pamkin.opensim.wrapping`), and the OpenSim export writes it as that wrap
object (checked with OpenSim 4.6 by ``tests/test_osim_export.py``).

A roller changes the route: its length, its moment arms, the pieces that must clear bone (the straight
pieces before and after the roller; the roller itself must clear its bone and sit within a bracket's
distance of it, :mod:`pamkin.audit.measure`). A PAM body never sits on a segment with a roller (it is not
straight there, :mod:`pamkin.robot.pam_body`).

Design-file form (per PAM, body-frame coordinates in metres)::

    rollers:
      - {segment: p1->p2, body: femur_r, centre: [-0.03, -0.05, 0.005], axis: [0, 0, 1],
         side: [-1, 0, 0], radius_m: 0.008, length_m: 0.04}
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from pamkin.opensim.wrapping import NO_WRAP, PathWrap, WrapObject, wrap_cylinder

__all__ = ["Roller", "OPEN_LENGTH_M", "ROLLER_LENGTH_M", "open_ended", "roller_axis_points", "roller_from_dict", "roller_frame", "roller_pieces",
           "roller_world",
           "path_wraps", "wrap_object"]

#: Default roller length along its axis [m].
ROLLER_LENGTH_M = 0.04
#: Length [m] of an open-ended roller: a cable on it never reaches an end. OpenSim's WrapCylinder drops a wrap
#: whose tangent points both lie beyond the cylinder's ends (the cable slips off a short roller, a step in the
#: route's length); a route shorter over its rollers than over open-ended ones is a cable off a roller
#: (:func:`open_ended`).
OPEN_LENGTH_M = 10.0


@dataclass(frozen=True)
class Roller:
    """A roller on one route segment.

    Attributes:
        segment: The route segment it guides, by name (``"p1->p2"``, :func:`pamkin.robot.pam_body.segment_names`).
        body: Body it is fixed in.
        centre: Centre of its axis in the body frame (3,) [m].
        axis: Direction of its axis in the body frame (3,) (unit).
        side: The side of the roller the cable passes on, in the body frame (3,) (unit, perpendicular to
            ``axis``): away from the bone.
        radius_m: Radius [m].
        length_m: Length along the axis [m] (the cable wraps only where it meets the roller within it).
    """

    segment: str
    body: str
    centre: tuple[float, float, float]
    axis: tuple[float, float, float]
    side: tuple[float, float, float]
    radius_m: float
    length_m: float = ROLLER_LENGTH_M

    def to_dict(self) -> dict:
        """Plain-data form (the design file's)."""
        return {"segment": self.segment, "body": self.body, "centre": [float(v) for v in self.centre],
                "axis": [float(v) for v in self.axis], "side": [float(v) for v in self.side],
                "radius_m": float(self.radius_m), "length_m": float(self.length_m)}


def roller_from_dict(d: dict, segments: Sequence[str], bodies: Sequence[str] | None = None) -> Roller:
    """Validate and build a :class:`Roller` from its design-file mapping.

    Args:
        d: ``{segment, body, centre, axis, side, radius_m[, length_m]}``.
        segments: The route's segment names.
        bodies: Known bodies (None: not checked).

    Raises:
        ValueError: A missing or bad field (the message names it); the caller names the file and PAM.
    """
    if not isinstance(d, dict):
        raise ValueError(f"a roller must be a mapping, is {d!r}")
    missing = [f for f in ("segment", "body", "centre", "axis", "side", "radius_m") if f not in d]
    if missing:
        raise ValueError(f"roller: missing field(s) {missing}")
    if d["segment"] not in segments:
        raise ValueError(f"roller segment must name a segment of its route {list(segments)}, is {d['segment']!r}")
    if bodies is not None and d["body"] not in bodies:
        raise ValueError(f"roller on {d['segment']} is on unknown body {d['body']!r}")
    where = f"roller on {d['segment']}"
    vec = {}
    for f in ("centre", "axis", "side"):
        try:
            v = np.asarray(d[f], dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{where}: {f} must be 3 numbers, is {d[f]!r}") from None
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ValueError(f"{where}: {f} must be 3 finite numbers, is {d[f]!r}")
        vec[f] = v
    for f in ("axis", "side"):
        if np.linalg.norm(vec[f]) < 1e-9:
            raise ValueError(f"{where}: {f} must be a non-zero direction")
        vec[f] = vec[f] / np.linalg.norm(vec[f])
    if abs(float(vec["axis"] @ vec["side"])) > 1e-6:
        raise ValueError(f"{where}: side must be perpendicular to axis (their cosine is "
                         f"{float(vec['axis'] @ vec['side']):.3g})")
    try:
        radius = float(d["radius_m"])
        length = float(d.get("length_m", ROLLER_LENGTH_M))
    except (TypeError, ValueError):
        raise ValueError(f"{where}: radius_m and length_m must be numbers") from None
    if not (np.isfinite(radius) and radius > 0) or not (np.isfinite(length) and length > 0):
        raise ValueError(f"{where}: radius_m and length_m must be positive lengths, are {radius}, {length}")
    return Roller(str(d["segment"]), str(d["body"]), tuple(float(x) for x in vec["centre"]),   # type: ignore[arg-type]
                  tuple(float(x) for x in vec["axis"]), tuple(float(x) for x in vec["side"]),  # type: ignore[arg-type]
                  radius, length)


def open_ended(rollers: Sequence[Roller]) -> tuple[Roller, ...]:
    """``rollers`` made :data:`OPEN_LENGTH_M` long (same centre, axis and radius): the cable never leaves them
    over an end."""
    return tuple(replace(r, length_m=OPEN_LENGTH_M) for r in rollers)


def roller_frame(r: Roller) -> np.ndarray:
    """(3, 3) rotation of the roller's wrap-cylinder frame in its body: columns x = ``side``, y = z × x,
    z = ``axis`` (right-handed)."""
    x = np.asarray(r.side, float)
    z = np.asarray(r.axis, float)
    x = x - (x @ z) * z
    x /= np.linalg.norm(x)
    z /= np.linalg.norm(z)
    return np.column_stack([x, np.cross(z, x), z])


def roller_world(r: Roller, R_body: np.ndarray, p_body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The roller frame in ground at S placements of its body (R_body (S, 3, 3), p_body (S, 3)): its
    orientation (S, 3, 3) (columns :func:`roller_frame`'s) and its centre (S, 3) [m]."""
    R = np.einsum("sij,jk->sik", R_body, roller_frame(r))
    return R, p_body + np.einsum("sij,j->si", R_body, np.asarray(r.centre, float))


def roller_axis_points(r: Roller, n: int = 9) -> np.ndarray:
    """(n, 3) points along the roller's axis from end to end, in its body's frame [m] (its surface is
    ``radius_m`` from them: the bone checks of the audit and the optimiser's placement)."""
    return np.asarray(r.centre, float) + np.outer(np.linspace(-0.5, 0.5, n) * r.length_m, r.axis)


def wrap_object(r: Roller, name: str) -> WrapObject:
    """The roller as OpenSim's ``WrapCylinder`` (quadrant ``+x``) named ``name``."""
    return WrapObject(name, "WrapCylinder", r.body, tuple(map(tuple, roller_frame(r).tolist())),
                      tuple(float(v) for v in r.centre), "+x", True, (float(r.radius_m), float(r.length_m)))


def path_wraps(segment_names: Sequence[str], rollers: Sequence[Roller], prefix: str) -> list[PathWrap]:
    """The PathWraps of a route with ``rollers`` (wrap objects named ``{prefix}_roller{k}``): each over its
    segment's two points (1-based range i+1, i+2)."""
    out = []
    for k, r in enumerate(rollers, 1):
        i = list(segment_names).index(r.segment)
        out.append(PathWrap(f"{prefix}_roller{k}_wrap", wrap_object(r, f"{prefix}_roller{k}"), "hybrid", (i + 1, i + 2)))
    return out


def roller_pieces(A: np.ndarray, B: np.ndarray, R_body: np.ndarray, p_body: np.ndarray, r: Roller,
                  single: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where the cable of segment A→B leaves the straight line over a roller.

    Args:
        A, B: (S, 3) world positions of the segment's ends [m].
        R_body, p_body: (S, 3, 3), (S, 3) the roller body's placements.
        r: The roller.
        single: The roller is its route's only one (OpenSim's tangency iteration differs otherwise).

    Returns:
        (T1, T2, wrapped, arc): (S, 3) world tangent points where the cable meets and leaves the roller,
        (S,) whether it wraps and (S,) the cable's length over the roller between them [m]; where it does
        not wrap, T1 = T2 = B (the pieces A→T1, T2→B are then the segment and a point) and arc = 0.
    """
    Rw, pw = roller_world(r, R_body, p_body)                     # roller frame -> world
    a = np.einsum("sji,sj->si", Rw, A - pw)                      # ends in the roller frame
    b = np.einsum("sji,sj->si", Rw, B - pw)
    T1, T2 = B.copy(), B.copy()
    wrapped = np.zeros(len(A), dtype=bool)
    arc = np.zeros(len(A))
    for s in range(len(A)):
        code, r1, r2, wl = wrap_cylinder(a[s], b[s], float(r.radius_m), float(r.length_m), 0, 1, single)
        if code != NO_WRAP and np.all(np.isfinite(r1)) and np.all(np.isfinite(r2)):
            wrapped[s] = True
            T1[s] = pw[s] + Rw[s] @ np.asarray(r1)
            T2[s] = pw[s] + Rw[s] @ np.asarray(r2)
            arc[s] = wl
    return T1, T2, wrapped, arc

