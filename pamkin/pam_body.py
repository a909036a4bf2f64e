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
    """The PAM body along the route from the start of segment ``j0`` for ``length`` (S,) [m]:
    one (A, B, valid) per segment it covers (A, B (S, 3); valid (S,) where the piece exists)."""
    seg = pts[:, 1:] - pts[:, :-1]
    L = np.linalg.norm(seg, axis=2)
    out = []
    s = np.zeros(len(pts))
    for j in range(j0, seg.shape[1]):
        lo = s
        hi = s + L[:, j]
        ta = np.zeros(len(pts))
        end = np.minimum(length, hi)
        valid = end > lo + 1e-12
        with np.errstate(invalid="ignore", divide="ignore"):
            tb = np.where(L[:, j] > 1e-12, np.clip((end - lo) / L[:, j], 0, 1), 0.0)
        A = pts[:, j] + ta[:, None] * seg[:, j]
        B = pts[:, j] + tb[:, None] * seg[:, j]
        out.append((A, B, valid))
        s = hi
        if np.all(s >= length):
            break
    return out
