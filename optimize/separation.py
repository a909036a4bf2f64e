"""Separating PAM bodies: the ends of each PAM's mount segment moved on their brackets until every pair of
same-side bodies is at least a gap apart and every body at least a gap from bone, at given poses.

The bodies are the audit's (:mod:`pamkin.audit.assembly`: capsules of the largest outer radius as placed).
:func:`separate` works like a position-based solver: each round it takes, for every pair of bodies closer than
``gap`` and every body closer than ``bone_gap`` to bone, the pose where that is worst, and moves the fixed
points at both ends of the body's mount segment (the points the body lies between) by the missing distance —
apart along the line joining the two bodies' closest points (half each), or out of the bone along its outward
normal — expressed in each point's own body frame; points moved by several contacts take the sum. A point is
never moved farther than ``max_shift`` from where it was, nor farther than ``max_bracket`` from its bone (nor
into it). Every moved PAM keeps its mount segment and
end (``pam_on``, ``pam_at``) and its PAM length (the tendon takes up the route's change, averaged over the poses).

Moving an attachment point changes the route's moment arms: the report gives, per moved PAM, the largest
displacement and the largest change of its moment arm about its primary coordinate over the poses, so that the
cost of the separation is visible. Lengths in metres.
"""

from __future__ import annotations

import dataclasses
import warnings
from types import SimpleNamespace

import numpy as np

from pamkin.audit.assembly import body_distances, body_points, body_radius, bone_clearance
from pamkin.errors import RangeWarning
from pamkin.opensim.model_file import MovingPathPoint
from pamkin.robot.biped import PamRobot, placements
from pamkin.robot.pam_body import pam_capsules, segment_names

__all__ = ["SeparationReport", "closest_points", "separate"]

#: Extra push beyond the missing distance [m] (so that a contact resolved at one round stays resolved).
MARGIN = 0.0005


@dataclasses.dataclass
class SeparationReport:
    """What :func:`separate` did: rounds used, the pairs closer than the gap and the bodies closer than the
    bone gap before and after (counts), and per moved PAM id its largest point displacement [m] and largest
    change of its moment arm about its primary coordinate [m]."""

    rounds: int
    pairs_before: int
    pairs_after: int
    bone_before: int
    bone_after: int
    moved: dict


def closest_points(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest points of segments A–B and C–D (3,) (Ericson, *Real-Time Collision Detection*, §5.1.9)."""
    d1, d2, r = B - A, D - C, A - C
    a, e, f = d1 @ d1, d2 @ d2, d2 @ r
    if a <= 1e-24 and e <= 1e-24:
        return A.copy(), C.copy()
    if a <= 1e-24:
        return A.copy(), C + np.clip(f / e, 0, 1) * d2
    c = d1 @ r
    if e <= 1e-24:
        return A + np.clip(-c / a, 0, 1) * d1, C.copy()
    b = d1 @ d2
    den = a * e - b * b
    s = np.clip((b * f - c * e) / den, 0, 1) if den > 1e-24 else 0.0
    t = (b * s + f) / e
    if t < 0:
        t, s = 0.0, np.clip(-c / a, 0, 1)
    elif t > 1:
        t, s = 1.0, np.clip((b - c) / a, 0, 1)
    return A + s * d1, C + t * d2


def _nearest_pieces(pa: list, pb: list, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Closest points of two bodies (pieces) at sample ``s``."""
    best, out = np.inf, None
    for A, B, va in pa:
        for C, D, vb in pb:
            if va[s] and vb[s]:
                p, q = closest_points(A[s], B[s], C[s], D[s])
                if np.linalg.norm(q - p) < best:
                    best, out = float(np.linalg.norm(q - p)), (p, q)
    return out


def _movable(pam, j: int) -> list[int]:
    """Indices of the fixed points at the ends of segment ``j`` of ``pam``'s route."""
    return [i for i in (j, j + 1) if not isinstance(pam.points[i], MovingPathPoint)]


class _State:
    """The bodies of a design at the poses: placements, pieces, radii."""

    def __init__(self, design, model, q: np.ndarray, fixed: list | None = None):
        self.places = placements(design, model, q)
        fit = 2 * design.fitting_length_m
        self.pieces = []
        for k, (place, pts, pam_len) in enumerate(self.places):
            j, side = (place.segment, place.side) if fixed is None else fixed[k]
            self.pieces.append(pam_capsules(pts, j, pam_len + fit, side))
        self.radius = [body_radius(p.diameter_mm, p.n_parallel) for p in design.pams]


def _contacts(st: _State, bones, kin, gap: float, bone_gap: float, step: float):
    """Pairs closer than ``gap`` (a, b, pose, distance) and bodies closer than ``bone_gap`` to bone (k, pose,
    clearance)."""
    n = len(st.pieces)
    pairs = []
    for a in range(n):
        for b in range(a + 1, n):
            d = body_distances(st.pieces[a], st.pieces[b], st.radius[a], st.radius[b])
            s = int(np.argmin(d))
            if d[s] < gap:
                pairs.append((a, b, s, float(d[s])))
    near = []
    if bones is not None:
        for k in range(n):
            c, _ = bone_clearance(bones, kin, st.pieces[k], st.radius[k], step, reach=bone_gap + 0.01)
            s = int(np.argmin(c))
            if c[s] < bone_gap:
                near.append((k, s, float(c[s])))
    return pairs, near


def _bone_normal(bones, kin, pieces: list, radius: float, s: int, step: float) -> np.ndarray:
    """Outward bone normal (world) at the point of a body nearest bone at pose ``s``."""
    P, valid = body_points(pieces, step)
    d, _, _, nrm = bones.nearest(_pose(kin, s), P[s:s + 1], margin=None)
    d = np.where(valid[s:s + 1], d, np.inf)
    i = int(np.argmin(d[0]))
    return nrm[0, i]


def _pose(kin, s: int):
    """Pose ``s`` of a kinematics state (the fields the bone queries read)."""
    return SimpleNamespace(q=kin.q[s:s + 1], body_R=kin.body_R[s:s + 1], body_p=kin.body_p[s:s + 1])


def _move(design, start, model, kin, pushes: dict, bones, max_bracket: float, max_shift: float):
    """The design with each (PAM index, point index) moved by its summed world push (at its pose), in the
    point's body frame, at most ``max_shift`` from where it was in ``start``, kept within ``max_bracket`` of its
    bone and out of it."""
    pams = list(design.pams)
    for (k, i), moves in pushes.items():
        pt = pams[k].points[i]
        b = model.bodies.index(pt.body)
        local = np.asarray(pt.location, float) + sum(kin.body_R[s, b].T @ v for s, v in moves)
        origin = np.asarray(start.pams[k].points[i].location, float)
        shift = local - origin
        if np.linalg.norm(shift) > max_shift:
            local = origin + shift * (max_shift / np.linalg.norm(shift))
        if bones is not None and pt.body in bones.bodies:
            d, c, nrm = bones.body_closest(pt.body, local[None])
            if d[0] > max_bracket:
                local = c[0] + max_bracket * nrm[0]
            elif d[0] < 0:
                local = c[0] + 0.003 * nrm[0]
        pts = list(pams[k].points)
        pts[i] = dataclasses.replace(pt, location=tuple(float(x) for x in local))
        pams[k] = dataclasses.replace(pams[k], points=tuple(pts))
    return dataclasses.replace(design, pams=tuple(pams))


def separate(design, model, q: np.ndarray, bones=None, *, gap: float = 0.005, bone_gap: float = 0.005,
             max_bracket: float = 0.05, max_shift: float = 0.02, rounds: int = 40, step: float = 0.004):
    """Move the ends of the PAMs' mount segments until the bodies are ``gap`` apart and ``bone_gap`` from bone
    at the poses ``q`` (S, n_coordinates) (module docstring).

    Args:
        design: The design (right side).
        model: The robot's skeleton (:func:`pamkin.robot.biped.robot_skeleton`).
        q: Poses.
        bones: :class:`pamkin.human.bones.BoneSet` (None: no bone checks, and no bracket limit).
        gap, bone_gap: Least gaps [m].
        max_bracket: Farthest a moved point may be from its bone [m].
        max_shift: Farthest a point may move from where it was [m] (the route, and so the torque fit, stays
            near the design's).
        rounds: Most rounds.
        step: Spacing of the points along a body's axis for the bone checks [m].

    Returns:
        ``(design, report)``: the separated design and a :class:`SeparationReport`.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        kin = model.kinematics.forward(q, warn_range=False)
        st = _State(design, model, q)
        fixed = [(p.segment, p.side) for p, _, _ in st.places]
        start = design
        pairs, near = _contacts(st, bones, kin, gap, bone_gap, step)
        before = (len(pairs), len(near))
        n_round = 0
        while (pairs or near) and n_round < rounds:
            n_round += 1
            pushes: dict = {}
            for a, b, s, d in pairs:
                p, r = _nearest_pieces(st.pieces[a], st.pieces[b], s)
                u = r - p
                u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else _perpendicular(st.pieces[a], s)
                push = 0.5 * (gap - d + MARGIN)
                for k, sign in ((a, -1.0), (b, 1.0)):
                    for i in _movable(design.pams[k], fixed[k][0]):
                        pushes.setdefault((k, i), []).append((s, sign * push * u))
            for k, s, c in near:
                nrm = _bone_normal(bones, kin, st.pieces[k], st.radius[k], s, step)
                for i in _movable(design.pams[k], fixed[k][0]):
                    pushes.setdefault((k, i), []).append((s, (bone_gap - c + MARGIN) * nrm))
            design = _move(design, start, model, kin, pushes, bones, max_bracket, max_shift)
            st = _State(design, model, q, fixed)
            pairs, near = _contacts(st, bones, kin, gap, bone_gap, step)
        design = _keep_place_and_length(start, design, model, q, fixed)
        return design, SeparationReport(n_round, before[0], len(pairs), before[1], len(near),
                                        _moved(start, design, model, q))


def _perpendicular(pieces: list, s: int) -> np.ndarray:
    """A unit vector perpendicular to a body's first present piece at pose ``s`` (axes that cross)."""
    for A, B, v in pieces:
        if v[s]:
            ax = B[s] - A[s]
            u = np.cross(ax, [0.0, 0.0, 1.0] if abs(ax[2]) < 0.9 * np.linalg.norm(ax) else [1.0, 0.0, 0.0])
            return u / np.linalg.norm(u)
    return np.array([0.0, 0.0, 1.0])


def _keep_place_and_length(start, design, model, q: np.ndarray, fixed: list):
    """Every moved PAM with its mount segment and end named (``pam_on``, ``pam_at``) and its tendon changed by
    the mean change of its route length, so that its PAM length stays."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        L0 = PamRobot(start, model, sides=("r",)).evaluate(q).lengths
        L1 = PamRobot(design, model, sides=("r",)).evaluate(q).lengths
    pams = []
    for k, (p0, p1) in enumerate(zip(start.pams, design.pams)):
        if p0.points == p1.points:
            pams.append(p1)
            continue
        j, side = fixed[k]
        pams.append(dataclasses.replace(p1, tendon_length_m=p1.tendon_length_m + float(np.mean(L1[:, k] - L0[:, k])),
                                        pam_on=segment_names(p1)[j], pam_at=side))
    return dataclasses.replace(design, pams=tuple(pams))


def _moved(start, design, model, q: np.ndarray) -> dict:
    """Per moved PAM id: largest point displacement [m] and moment-arm change about its primary coordinate [m]."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        R0 = PamRobot(start, model, sides=("r",)).evaluate(q).moment_arms
        R1 = PamRobot(design, model, sides=("r",)).evaluate(q).moment_arms
    out = {}
    for k, (p0, p1) in enumerate(zip(start.pams, design.pams)):
        disp = [float(np.linalg.norm(np.subtract(a.location, b.location))) for a, b in zip(p0.points, p1.points)
                if not isinstance(a, MovingPathPoint)]
        if max(disp, default=0.0) > 0:
            c = model.coordinates.index(p0.primary_coordinate)
            out[p0.id] = {"displacement_m": max(disp),
                          "moment_arm_change_m": float(np.max(np.abs(R1[:, k, c] - R0[:, k, c])))}
    return out
