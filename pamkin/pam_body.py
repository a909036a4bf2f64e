"""Where a PAM body sits on its route: route point positions, the room a segment leaves for the body,
the segment that holds it best and the body's capsules.

The audit (:mod:`pamkin.audit`) measures with these, and the optimiser's one-segment stage and PAM
clearance pass (:mod:`pamkin.optimize.mount`, :mod:`pamkin.optimize.pam_clearance`) use the same
definitions. Lengths in metres.
"""

from __future__ import annotations

import numpy as np

from .paths import PathSet

__all__ = ["body_room", "mount_segment", "pam_capsules", "route_positions", "segment_names"]


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


def pam_capsules(pts: np.ndarray, j0: int, length: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The PAM body along the route ``pts`` (S, P, 3): ``length`` (S,) [m] of it from the start of segment
    ``j0`` — moved back along the route where it would run past the route's last point (a PAM does not hang
    off its last attachment), never before the first point. One (A, B, valid) per segment of the route
    (A, B (S, 3); valid (S,) where the body covers part of that segment).

    A PAM that fits on segment ``j0`` (:func:`mount_segment`) lies on it from its start; one that does not
    bends over the following points, or, where the route ends first, over the points before ``j0`` too."""
    seg = pts[:, 1:] - pts[:, :-1]
    L = np.linalg.norm(seg, axis=2)                                  # (S, P-1)
    cum = np.concatenate([np.zeros((len(pts), 1)), np.cumsum(L, axis=1)], axis=1)
    length = np.asarray(length, float)
    s0 = np.maximum(np.minimum(cum[:, j0], cum[:, -1] - length), 0.0)
    s1 = s0 + length
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
