"""Racks: a PAM body carried on brackets along a bone, away from its route, by a constant cable piece.

A PAM whose route starts (or ends) on a body — its *host* — can hang on that body wherever there is room: an
*anchor* bracket holds the PAM (on a pulley block: its frame) and a *guide* pulley on a second bracket turns
its cable back to the route's first (last) point. Both brackets are fixed in the host, so the two new route
pieces — anchor → guide, where the body lies, and guide → route end — have the same length at every pose: the
route's length changes exactly as before, and so do its moment arms (−∂L/∂q), its PAM's strain and force.
Only the artificial tendon grows by the constant pieces (:func:`rack_pam`). The body is then straight by
construction (the anchor → guide piece holds it whole) and its place relative to its own bone never changes,
so clearances to that bone and to the other bodies on the same host are one number each, not a function of
the pose.

The cable turns twice on the host: at the guide pulley and at the route's end point. With pulleys on ball
bearings the loss is small; a plain eyelet would cost the capstan factor ``exp(−μ θ)`` on the turn angle θ
(:func:`capstan_efficiency`). The rack stage measures both turn angles (:func:`rack_turns`: the guide's is
fixed, the route end's changes with the pose) and sets the PAM's ``cable_efficiency`` to the capstan factor of
their largest sum over its poses at the coefficient it assumes (``[rack] friction``): the route's tension, and so
every torque figure, is the PAM's force times that factor — a bound for a PAM pulling (shortening); while it is
stretched, friction adds to the tension instead (not modelled).

Design-file form: the rack is two ordinary route points on the host (named ``rack.anchor`` and ``rack.guide``)
with ``pam_on: rack.anchor->rack.guide`` (``rack.guide->rack.anchor`` at the insertion end) and ``pam_at``
naming the end; nothing else is new. Coordinates in the host body's frame [m].
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from pamkin.opensim.model_file import PathPoint
from pamkin.robot.design import Pam

__all__ = ["ANCHOR", "GUIDE", "RackMount", "capstan_efficiency", "has_rack", "rack_pam", "rack_turns", "route_end",
           "turn_angle"]

#: Names of the two rack points on a route.
ANCHOR = "rack.anchor"
GUIDE = "rack.guide"


@dataclass(frozen=True)
class RackMount:
    """Where a PAM hangs on its host (coordinates in the host body's frame [m]).

    Attributes:
        end: The route end the rack is on, ``"origin"`` or ``"insertion"``.
        host: The body of that route end.
        anchor: (3,) the bracket holding the PAM's far end.
        guide: (3,) the pulley turning the cable to the route's end point.
    """

    end: str
    host: str
    anchor: tuple[float, float, float]
    guide: tuple[float, float, float]

    def __post_init__(self) -> None:
        if self.end not in ("origin", "insertion"):
            raise ValueError(f"a rack's end must be 'origin' or 'insertion', is {self.end!r}")


def route_end(pam: Pam, end: str) -> PathPoint:
    """The route's first (``end="origin"``) or last point."""
    return pam.points[0] if end == "origin" else pam.points[-1]


def has_rack(pam: Pam) -> bool:
    """Whether ``pam``'s route carries a rack (its points named :data:`ANCHOR` and :data:`GUIDE`)."""
    return {p.name for p in pam.points} >= {ANCHOR, GUIDE}


def rack_pam(pam: Pam, mount: RackMount) -> Pam:
    """``pam`` hung on ``mount``: the two rack points put before its origin (after its insertion), the body on
    the anchor–guide piece at the anchor's end, the tendon longer by the two constant pieces so that the PAM
    keeps its length at every pose. Raises ValueError where the route's end is not a fixed point of the host
    or the route already has a rack."""
    if has_rack(pam):
        raise ValueError(f"PAM {pam.id} ({pam.name}) already hangs on a rack")
    g = route_end(pam, mount.end)
    if type(g) is not PathPoint or g.body != mount.host:
        raise ValueError(f"PAM {pam.id} ({pam.name}): its {mount.end} point {g.name!r} is not a fixed point of "
                         f"{mount.host!r}; a rack needs one")
    anchor = PathPoint(ANCHOR, mount.host, tuple(float(v) for v in mount.anchor))
    guide = PathPoint(GUIDE, mount.host, tuple(float(v) for v in mount.guide))
    extra = (float(np.linalg.norm(np.subtract(mount.anchor, mount.guide)))
             + float(np.linalg.norm(np.subtract(mount.guide, g.location))))
    if mount.end == "origin":
        points, on = (anchor, guide) + tuple(pam.points), f"{ANCHOR}->{GUIDE}"
    else:
        points, on = tuple(pam.points) + (guide, anchor), f"{GUIDE}->{ANCHOR}"
    return dataclasses.replace(pam, points=points, pam_on=on, pam_at=mount.end,
                               tendon_length_m=pam.tendon_length_m + extra)


def turn_angle(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Angle [rad] a cable turns at ``b`` going from ``a`` to ``c`` (points (..., 3)): 0 when straight."""
    u = np.asarray(b, float) - np.asarray(a, float)
    v = np.asarray(c, float) - np.asarray(b, float)
    cos = np.sum(u * v, axis=-1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1))
    return np.arccos(np.clip(cos, -1.0, 1.0))


def rack_turns(pam: Pam, pts: np.ndarray) -> tuple[float, np.ndarray]:
    """Angles [rad] the cable of a racked ``pam`` turns: at the guide pulley (fixed in the host: one number) and
    at the route's end point (S,), from its route point positions ``pts`` (S, P, 3), e.g.
    :func:`pamkin.robot.pam_body.route_positions`. Raises ValueError for a PAM without a rack."""
    if not has_rack(pam):
        raise ValueError(f"PAM {pam.id} ({pam.name}) hangs on no rack")
    P = pts if pam.points[0].name == ANCHOR else pts[:, ::-1]
    return float(turn_angle(P[0, 0], P[0, 1], P[0, 2])), turn_angle(P[:, 1], P[:, 2], P[:, 3])


def capstan_efficiency(angle, mu: float) -> np.ndarray:
    """Tension out / tension in of a cable turning ``angle`` [rad] over a fixed guide of friction coefficient
    ``mu`` (capstan equation, ``exp(−μ θ)``)."""
    if not mu >= 0 or math.isinf(mu):
        raise ValueError(f"a friction coefficient must be finite and >= 0, is {mu}")
    return np.exp(-mu * np.asarray(angle, float))
