"""Where a PAM body sits on its route: route point positions, the room a segment leaves for the body,
the segment that holds it best, the end of that segment it is anchored at and the body's capsules.

A PAM (on a pulley block: its frame) on one straight segment is anchored with a constant artificial
tendon on one side: at the segment's **origin** end (the tendon after it) or its **insertion** end (the
tendon before it). An end is possible only where the route's length on the tendon's other side — from the
route's origin to the segment's start, or from the segment's end to the insertion — is the same at every
pose (:func:`fixed_ends`); otherwise the PAM would have to slide along the segment as the joints move. A
design may name the end (``pam_at``); by default the origin end where possible, else the insertion end.
Where the body fits on more than one segment a design may name the segment too (``pam_on``); by default
the one that leaves the most room. Neither changes a torque: the tendon pieces are constant either way.

The audit (:mod:`pamkin.audit.measure`) measures with these, and the optimiser's one-segment stage and PAM
clearance pass (:mod:`pamkin.optimize.mount`, :mod:`pamkin.optimize.pam_clearance`) use the same
definitions. Lengths in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pamkin.human.paths import PathSet

__all__ = ["PAM_AT", "Placement", "body_interval", "body_room", "body_side", "fixed_ends", "mount_segment", "pam_capsules",
           "placement", "rolled_segments", "route_positions", "segment_margin", "segment_names",
           "segment_options"]

#: The ends of its mount segment a PAM may be anchored at (``pam_at`` of a design's PAM).
PAM_AT = ("origin", "insertion")

#: A route length before/after a segment counts as fixed when it changes by less than this over the poses [m].
FIXED_TOLERANCE = 1e-6


def route_positions(paths: PathSet, state, k: int) -> np.ndarray:
    """(S, P, 3) world positions of route ``k``'s points; an absent conditional point is put on the
    point before it, so that segment i–(i+1) is always the straight piece between present points."""
    X, _ = paths.point_positions(state)
    a, b = paths._path_start[k], paths._path_end[k]
    pts = X[:, a:b].copy()
    if len(paths._cond_ids):
        v = state.q[:, paths._cond_coord]
        present = (v >= paths._cond_lo) & (v <= paths._cond_hi)
        for j, pid in enumerate(paths._cond_ids):
            if a <= pid < b:
                i = pid - a
                pts[~present[:, j], i] = pts[~present[:, j], i - 1]
    return pts


def segment_names(pam) -> list[str]:
    """``"p1->p2"``-style names of a route's segments."""
    return [f"{p.name}->{q.name}" for p, q in zip(pam.points[:-1], pam.points[1:])]


def body_room(seg_len: np.ndarray, resting_length: float, pam_len: np.ndarray, fitting_length: float) -> np.ndarray:
    """Room [m] left on route segments of lengths ``seg_len`` (S, …) by the PAM body — its resting length
    or its actual length ``pam_len`` (S,), whichever is longer, plus both fittings (negative: the PAM does
    not fit there and would bend over the segment's end)."""
    need = np.maximum(resting_length, pam_len) + 2 * fitting_length
    return seg_len - need.reshape(need.shape + (1,) * (np.ndim(seg_len) - 1))


def mount_segment(room: np.ndarray) -> tuple[int, float]:
    """Segment that best holds the PAM: max over segments of min over samples of :func:`body_room`."""
    margin = room.min(axis=0)
    j = int(np.argmax(margin))
    return j, float(margin[j])


def _cumulative(pts: np.ndarray, lengths: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    seg = pts[:, 1:] - pts[:, :-1]
    L = np.linalg.norm(seg, axis=2) if lengths is None else lengths  # (S, P-1)
    return seg, L, np.concatenate([np.zeros((len(pts), 1)), np.cumsum(L, axis=1)], axis=1)


def fixed_ends(pts: np.ndarray, j0: int, lengths: np.ndarray | None = None) -> tuple[bool, bool]:
    """Whether segment ``j0`` of the route ``pts`` (S, P, 3) has a fixed-length route before it (from the
    route's origin to its start) and after it (from its end to the insertion) over the S poses: the ends
    a PAM on it can be anchored at with a constant tendon (origin end, insertion end). ``lengths`` (S, P−1):
    the segments' lengths where they are not straight (rollers, :meth:`pamkin.robot.biped.PamRobot.segment_lengths`)."""
    _, _, cum = _cumulative(pts, lengths)
    return (bool(np.ptp(cum[:, j0]) < FIXED_TOLERANCE),
            bool(np.ptp(cum[:, -1] - cum[:, j0 + 1]) < FIXED_TOLERANCE))


def body_side(pam_at: str | None, origin_fixed: bool, insertion_fixed: bool) -> str:
    """The end of its mount segment a PAM body is put at: ``pam_at`` (the design's) where that end is fixed
    (:func:`fixed_ends`), else the origin end where fixed, else the insertion end where fixed, else the origin
    end (a PAM with both sides moving, or one that spans the route)."""
    ok = {"origin": origin_fixed, "insertion": insertion_fixed}
    if pam_at is not None and ok.get(pam_at):
        return pam_at
    return "insertion" if insertion_fixed and not origin_fixed else "origin"


def body_interval(pts: np.ndarray, j0: int, length: np.ndarray, side: str = "origin",
                  lengths: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Arc lengths (s0, s1) (S,) [m] along the route ``pts`` (S, P, 3) of a body of ``length`` (S,) at
    the ``side`` end of segment ``j0`` (:func:`pam_capsules`; ``lengths`` as in :func:`fixed_ends`)."""
    if side not in PAM_AT:
        raise ValueError(f"side must be one of {PAM_AT}, is {side!r}")
    _, _, cum = _cumulative(pts, lengths)
    length = np.asarray(length, float)
    start = cum[:, j0] if side == "origin" else cum[:, j0 + 1] - length
    s0 = np.maximum(np.minimum(start, cum[:, -1] - length), 0.0)
    return s0, s0 + length


def pam_capsules(pts: np.ndarray, j0: int, length: np.ndarray, side: str = "origin",
                 lengths: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The PAM body along the route ``pts`` (S, P, 3): ``length`` (S,) [m] of it from the start of segment
    ``j0`` (``side`` "origin"), or ending at its end ("insertion") — moved along the route where it would run
    past the route's last point (a PAM does not hang off its last attachment) or before its first. One
    (A, B, valid) per segment of the route (A, B (S, 3); valid (S,) where the body covers part of that
    segment).

    A PAM that fits on segment ``j0`` (:func:`mount_segment`) lies on it from that end; one that does not
    bends over the following (preceding) points, or, where the route ends first, over the points on the
    other side of ``j0`` too. ``lengths`` as in :func:`fixed_ends` (a segment with a roller: the body is
    drawn along its chord)."""
    seg, L, cum = _cumulative(pts, lengths)
    s0, s1 = body_interval(pts, j0, length, side, lengths)
    out = []
    for j in range(seg.shape[1]):
        lo, hi = np.maximum(s0, cum[:, j]), np.minimum(s1, cum[:, j + 1])
        valid = hi > lo + 1e-12
        with np.errstate(invalid="ignore", divide="ignore"):
            ok = L[:, j] > 1e-12
            ta = np.where(ok, np.clip((lo - cum[:, j]) / L[:, j], 0, 1), 0.0)
            tb = np.where(ok, np.clip((hi - cum[:, j]) / L[:, j], 0, 1), 0.0)
        out.append((pts[:, j] + ta[:, None] * seg[:, j], pts[:, j] + tb[:, None] * seg[:, j], valid))
    return out


@dataclass(frozen=True)
class Placement:
    """Where a PAM body sits over a set of poses: its mount segment (index), the least room it leaves there
    (:func:`body_room`; negative: the PAM does not fit on one segment and bends over its ends) and the end
    of the segment it is anchored at (:func:`body_side`; "origin" for a PAM that does not fit)."""

    segment: int
    margin: float
    side: str

    @property
    def on_one_segment(self) -> bool:
        return self.margin >= 0


def placement(pts: np.ndarray, pam, pam_len: np.ndarray, fitting_length: float,
              lengths: np.ndarray | None = None) -> Placement:
    """:class:`Placement` of ``pam`` (a :class:`pamkin.robot.design.Pam`) on its route ``pts`` (S, P, 3) at S poses
    with PAM lengths ``pam_len`` (S,) [m] — what ``pamkin audit``, the optimiser's PAM–PAM checks and the
    viewer put where: the design's segment (``pam_on``) where the body fits on it with a constant tendon
    (:func:`segment_options`), else the segment that holds it best. Segments with a roller never hold it;
    ``lengths`` (S, P−1): the segments' lengths over their rollers (:func:`fixed_ends`)."""
    named = _named_segment(pam)
    if named is not None and named < pts.shape[1] - 1:
        m = segment_margin(pts, named, pam.resting_length_m, pam_len, fitting_length, lengths)
        ends = fixed_ends(pts, named, lengths)
        if m >= 0 and any(ends):
            return Placement(named, m, body_side(pam.pam_at, *ends))
    seg_len = np.linalg.norm(pts[:, 1:] - pts[:, :-1], axis=2)
    room = body_room(seg_len, pam.resting_length_m, pam_len, fitting_length)
    rolled = rolled_segments(pam)
    if rolled:
        room = room.copy()
        room[:, rolled] = -np.inf
    j, margin = mount_segment(room)
    if margin < 0:
        return Placement(j, margin, "origin")
    margin = segment_margin(pts, j, pam.resting_length_m, pam_len, fitting_length, lengths)
    return Placement(j, margin, body_side(pam.pam_at, *fixed_ends(pts, j, lengths)) if margin >= 0 else "origin")


def rolled_segments(pam) -> list[int]:
    """Indices of the route segments of ``pam`` that have a roller (:mod:`pamkin.robot.rollers`)."""
    rollers = getattr(pam, "rollers", ())
    if not rollers:
        return []
    names = segment_names(pam)
    return sorted(names.index(r.segment) for r in rollers)


def _named_segment(pam) -> int | None:
    """Index of the design's ``pam_on`` segment (None: not named)."""
    name = getattr(pam, "pam_on", None)
    if name is None:
        return None
    names = segment_names(pam)
    return names.index(name) if name in names else None


def segment_options(pts: np.ndarray, pam, pam_len: np.ndarray, fitting_length: float,
                    lengths: np.ndarray | None = None) -> list[tuple[int, str]]:
    """Every ``(segment, end)`` a PAM body can sit at on its route ``pts`` (S, P, 3) over the S poses: the
    segments without a roller it fits on (:func:`segment_margin` >= 0) with each end whose route on the
    tendon's other side has a fixed length (:func:`fixed_ends`; ``lengths`` as there). Empty where the PAM
    fits on no segment."""
    out = []
    rolled = rolled_segments(pam)
    for j in range(pts.shape[1] - 1):
        if j not in rolled and segment_margin(pts, j, pam.resting_length_m, pam_len, fitting_length, lengths) >= 0:
            out += [(j, side) for side, ok in zip(PAM_AT, fixed_ends(pts, j, lengths)) if ok]
    return out


def segment_margin(pts: np.ndarray, j: int, resting_length: float, pam_len: np.ndarray, fitting_length: float,
                   lengths: np.ndarray | None = None) -> float:
    """Least room [m] the PAM body leaves on segment ``j`` of the route ``pts`` (S, P, 3) over the S poses
    (:func:`body_room`; negative: it does not fit). Where the route changes length on both sides of the
    segment (:func:`fixed_ends`) the PAM floats between two tendons of fixed length, so its start along the
    route is one constant for every pose — after the segment's latest start and before its earliest end
    less the body — and the margin is the smaller of the two. ``lengths`` as in :func:`fixed_ends`."""
    _, L, cum = _cumulative(pts, lengths)
    room = body_room(L[:, j], resting_length, pam_len, fitting_length)
    margin = float(np.min(room))
    if margin >= 0 and not any(fixed_ends(pts, j, lengths)):
        body = L[:, j] - room
        margin = min(margin, float(np.min(cum[:, j + 1] - body) - np.max(cum[:, j])))
    return margin
