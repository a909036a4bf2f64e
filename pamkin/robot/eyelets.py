"""Eyelets: a via point on the body a route segment passes between the bodies of its two ends.

A straight route segment from the tibia to the calcaneus crosses two joints (ankle and subtalar) and
passes the talus between them; where it must clear the talus and the malleoli at every pose, its moment
arms about both joints are tied to one straight line. An *eyelet* — a cable guide on a bracket of the
body in between (the extensor retinaculum's job in the human) — splits the segment in two, each crossing
one joint, so the two moment arms can be shaped apart. The optimiser then moves the eyelet like any other
attachment point (within its box, 3..18 mm outside its bone).

:func:`intermediate_bodies` names the bodies a segment passes (the kinematic tree between its ends' bodies);
:func:`add_eyelet` puts an eyelet on one of them: where the segment's straight line at a pose (by default
the model's default pose) comes nearest that body's bone, expressed in the body's frame and moved along the
bone's outward normal to ``gap`` outside its surface (:meth:`pamkin.human.bones.BoneSet.body_closest`).
The route's lengths then change (the route bends at the eyelet at other poses), so the resting and tendon
lengths are for the optimiser to fit again.

The optimiser's ``[eyelets]`` table (:mod:`pamkin.optimize.config`) adds eyelets to the seed design this way.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from pamkin.errors import ConfigurationError
from pamkin.opensim.model_file import PathPoint
from pamkin.robot.biped import PamRobot
from pamkin.robot.design import Design
from pamkin.robot.detour import pam_on_kept, unused_name
from pamkin.robot.pam_body import route_positions, segment_names

__all__ = ["EYELET_GAP_M", "add_eyelet", "eyelet_name", "has_eyelet", "intermediate_bodies"]

#: Default distance of a new eyelet outside its bone [m] (the optimiser keeps points 3..18 mm out).
EYELET_GAP_M = 0.008
#: Spacing of the samples along a segment where its nearest approach to the bone is looked for [m].
STEP_M = 0.001


def _chain(model, body: str) -> list[str]:
    """Bodies from ``body`` up to the root of the model's kinematic tree (``body`` first)."""
    parent = {j.child: j.parent for j in model.osim.joints}
    out = [body]
    while out[-1] in parent and parent[out[-1]] not in out:
        out.append(parent[out[-1]])
    return out


def intermediate_bodies(model, body_a: str, body_b: str) -> list[str]:
    """Bodies strictly between ``body_a`` and ``body_b`` on the kinematic tree's path joining them (in order
    from ``body_a``): ``["talus_r"]`` for ``tibia_r`` and ``calcn_r`` in Gait2392; empty for neighbours."""
    up_a, up_b = _chain(model, body_a), _chain(model, body_b)
    common = next((b for b in up_a if b in up_b), None)
    if common is None:
        raise ConfigurationError(f"bodies {body_a!r} and {body_b!r} are not joined by the model's kinematic tree")
    path = up_a[:up_a.index(common) + 1] + list(reversed(up_b[:up_b.index(common)]))
    return path[1:-1]


def eyelet_name(pam, segment: int) -> str:
    """Name of an eyelet in segment ``segment`` of ``pam``'s route: ``"p2.p3.e"``, not yet used."""

    return unused_name(pam, f"{pam.points[segment].name}.{pam.points[segment + 1].name}.e", sep="")


def has_eyelet(pam, body: str) -> bool:
    """Whether ``pam``'s route already has a fixed point on ``body`` (an eyelet added before, or a seed point)."""
    return any(type(p) is PathPoint and p.body == body for p in pam.points)


def _segment_on(pam, model, body: str) -> int:
    """The route segment of ``pam`` whose two ends' bodies have ``body`` between them (exactly one)."""
    pts = pam.points
    hits = [j for j in range(len(pts) - 1) if body in intermediate_bodies(model, pts[j].body, pts[j + 1].body)]
    if len(hits) != 1:
        where = "no" if not hits else f"{len(hits)}"
        raise ConfigurationError(f"actuator {pam.id} {pam.name}: {where} route segments pass {body!r} between "
                                 "their ends' bodies (an eyelet needs exactly one)")
    return hits[0]


def add_eyelet(pam, model, bones, body: str, *, gap: float = EYELET_GAP_M, at: float | None = None,
               q: np.ndarray | None = None):
    """A copy of ``pam`` with an eyelet (a :class:`pamkin.opensim.model_file.PathPoint`) on ``body``, in the route segment
    whose ends' bodies have ``body`` between them.

    Where: the point of the segment's straight line at pose ``q`` that comes nearest ``body``'s bone (samples
    every :data:`STEP_M`; or the point a fraction ``at`` along it), in ``body``'s frame, moved along the
    bone's outward normal at its closest surface point to ``gap`` outside the bone.

    Args:
        pam: A :class:`pamkin.robot.design.Pam`.
        model: The human model (:class:`pamkin.human.model.Model`): its kinematic tree and poses.
        bones: :class:`pamkin.human.bones.BoneSet` with a mesh of ``body``.
        body: Body the eyelet is fixed in.
        gap: Its distance outside the bone [m] (> 0).
        at: Where along the segment, 0 (its start) .. 1 (its end); default: its nearest approach to the bone.
        q: Pose (n_coordinates,) [rad, m]; default: the model's default pose.

    Raises:
        ConfigurationError: No or more than one segment passes ``body``, or that segment carries a roller;
            ``gap`` or ``at`` out of range; ``q`` not finite; ``body`` unknown or without a bone mesh.
    """

    if not (gap > 0 and np.isfinite(gap)) or not (at is None or 0.0 < at < 1.0):
        raise ConfigurationError(f"actuator {pam.id} {pam.name}: eyelet gap must be > 0 and 'at' within (0, 1), "
                                 f"are {gap!r}, {at!r}")
    if body not in model.kinematics.frames:
        raise ConfigurationError(f"actuator {pam.id} {pam.name}: unknown body {body!r} for an eyelet")
    j = _segment_on(pam, model, body)
    if any(r.segment == segment_names(pam)[j] for r in pam.rollers):
        raise ConfigurationError(f"actuator {pam.id} {pam.name}: segment {segment_names(pam)[j]} carries a roller; "
                                 "an eyelet would split it (remove the roller first)")
    q = model.default_q if q is None else np.asarray(q, float)
    if q.shape != model.default_q.shape or not np.all(np.isfinite(q)):
        raise ConfigurationError(f"actuator {pam.id} {pam.name}: the eyelet's pose must be "
                                 f"{model.default_q.size} finite coordinate values")
    state = model.kinematics.forward(q[None], warn_range=False)
    pts = _route_at(pam, model, state)
    b = list(model.kinematics.frames).index(body)
    R, p = state.body_R[0, b], state.body_p[0, b]
    A, B = R.T @ (pts[j] - p), R.T @ (pts[j + 1] - p)          # the segment in the body's frame
    if at is None:
        t = np.linspace(0.0, 1.0, max(2, int(np.ceil(np.linalg.norm(B - A) / STEP_M)) + 1))[1:-1, None]
    else:
        t = np.array([[at]])
    X = A + t * (B - A)
    d, c, n = bones.body_closest(body, X)
    if not np.all(np.isfinite(d)):
        raise ConfigurationError(f"actuator {pam.id} {pam.name}: body {body!r} has no bone mesh to place an eyelet on")
    k = int(np.argmin(d))
    loc = c[k] + gap * n[k]
    new = PathPoint(eyelet_name(pam, j), body, tuple(float(v) for v in loc))
    points = pam.points[:j + 1] + (new,) + pam.points[j + 1:]
    return pam_on_kept(dataclasses.replace(pam, points=tuple(points)))     # a pam_on it split is dropped


def _route_at(pam, model, state) -> np.ndarray:
    """World positions (n_points, 3) of ``pam``'s route points at the one pose of ``state``."""

    robot = PamRobot(Design("eyelet", (pam,)), model, sides=("r",))
    return route_positions(robot.paths, state, 0)[0]
