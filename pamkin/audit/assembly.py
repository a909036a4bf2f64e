"""Whether a design's PAM bodies can be put together: body–body gaps and body–bone clearance.

A PAM body is a capsule (a cylinder with rounded ends) of the PAM's largest outer radius — the contracted,
inflated DMSP with its fittings, :func:`body_radius`; for PAMs in parallel on one route, the capsule around the
bundle — along the part of its route where the audit places
it (:func:`pamkin.robot.pam_body.pam_capsules`: the PAM length plus both fittings from the anchored end of
its mount segment). Given as *pieces*, one ``(A, B, valid)`` per route segment with (S, 3) ends and an (S,)
mask of the samples where the body covers that segment.

- :func:`body_distances`: per sample, the smallest distance between the surfaces of two bodies
  (negative: they overlap), exact (segment–segment distance less both radii).
- :func:`pair_gap`: a pair's smallest distance over the samples and the fractions of samples closer than
  a gap and overlapping.
- :func:`bone_clearance`: per sample, the smallest distance of a body's surface to any bone mesh (negative:
  the body runs into bone), from points along its axis.

Lengths in metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pamkin.human.bones import segment_distances
from pamkin.robot import festo

__all__ = ["BODY_GAP_M", "BUNDLE_FACTOR", "PairGap", "body_distances", "body_points", "body_radius", "body_radius_source",
           "bone_clearance", "pair_gap"]

#: Least gap [m] between two PAM bodies, and between a PAM body and bone, that a build needs.
BODY_GAP_M = 0.005


#: Radius of the smallest circle around n equal circles of radius 1 side by side (n = 1, 2, 3).
BUNDLE_FACTOR = {1: 1.0, 2: 2.0, 3: 1.0 + 2.0 / 3.0 ** 0.5}


def body_radius(diameter_mm: int, n_parallel: int = 1) -> float:
    """Largest outer radius [m] of a PAM body of a Festo size: half the outer envelope of the contracted
    (inflated, at full pressure) DMSP with its fittings (:func:`pamkin.robot.festo.outer_diameter`). For
    ``n_parallel`` PAMs side by side on one route (1, 2 or 3), the radius of the capsule around the bundle:
    2× one body's for two, (1 + 2/√3)× for three."""
    if n_parallel not in BUNDLE_FACTOR:
        raise ValueError(f"a PAM bundle has 1, 2 or 3 PAMs side by side, not {n_parallel}")
    return BUNDLE_FACTOR[n_parallel] * festo.outer_diameter(diameter_mm) / 2.0


def body_radius_source() -> str:
    """Where :func:`body_radius` comes from (the ``source`` of ``festo_models.json``'s table)."""
    return festo.outer_diameter_source()


def body_distances(pieces_a: list, pieces_b: list, ra: float, rb: float) -> np.ndarray:
    """(S,) smallest distance [m] between the surfaces of two PAM bodies (pieces as in the module
    docstring) at each sample: segment–segment distance less ``ra + rb`` over every pair of pieces present
    at that sample; negative where they overlap, ``+inf`` where one of them is absent."""
    S = len(pieces_a[0][0]) if pieces_a else 0
    best = np.full(S, np.inf)
    for A, B, va in pieces_a:
        for C, D, vb in pieces_b:
            ok = np.flatnonzero(va & vb)
            if len(ok):
                d = segment_distances(A[ok], B[ok], C[ok], D[ok]) - ra - rb
                best[ok] = np.minimum(best[ok], d)
    return best


@dataclass(frozen=True)
class PairGap:
    """Two PAM bodies over the samples: smallest distance [m] (negative: overlap), the sample where it
    occurs, and the fractions of the samples at which they are closer than the gap / overlap (beyond the
    tolerance)."""

    distance_m: float
    sample: int
    closer_fraction: float
    overlap_fraction: float


def pair_gap(pieces_a: list, pieces_b: list, ra: float, rb: float, gap: float = BODY_GAP_M,
             tolerance: float = 1e-4) -> PairGap:
    """:class:`PairGap` of two PAM bodies (:func:`body_distances`): closer than ``gap`` [m] means a
    distance below ``gap − tolerance``, overlapping one below ``−tolerance``."""
    d = body_distances(pieces_a, pieces_b, ra, rb)
    if d.size == 0:
        return PairGap(math.inf, -1, 0.0, 0.0)
    s = int(np.argmin(d))
    return PairGap(float(d[s]), s if np.isfinite(d[s]) else -1, float(np.mean(d < gap - tolerance)),
                   float(np.mean(d < -tolerance)))


def body_points(pieces: list, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along a body's axis, every ``step`` [m] or closer (both ends of every piece included):
    ``(P, valid)``, (S, K, 3) [m] and (S, K) (False where the piece is absent at that sample)."""
    P, V = [], []
    for A, B, v in pieces:
        if not v.any():
            continue
        L = float(np.max(np.linalg.norm(B - A, axis=1)[v]))
        t = np.linspace(0.0, 1.0, max(2, int(math.ceil(L / step)) + 1))
        P.append(A[:, None, :] + t[None, :, None] * (B - A)[:, None, :])
        V.append(np.repeat(v[:, None], len(t), axis=1))
    if not P:
        S = len(pieces[0][0]) if pieces else 0
        return np.zeros((S, 0, 3)), np.zeros((S, 0), dtype=bool)
    return np.concatenate(P, axis=1), np.concatenate(V, axis=1)


def bone_clearance(bones, state, pieces: list, radius: float, step: float, reach: float = 0.02,
                   bodies: list[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(S,) clearance [m] of a PAM body's surface from the nearest bone at each pose and (S,) that bone's
    index into ``bones.bodies`` (-1: none within reach): the signed distance of points along its axis
    (:func:`body_points`, every ``step``) to the bone meshes less ``radius`` — negative where the body runs
    into bone. Clearances larger than ``reach`` [m] may be reported as ``+inf`` (the bone queries are pruned
    there).

    Args:
        bones: :class:`pamkin.human.bones.BoneSet`.
        state: Kinematics state of the S poses the pieces were computed at.
        pieces: The body (module docstring).
        radius: Body radius [m].
        step: Spacing of the points along the axis [m].
        reach: Clearance up to which the figure is exact [m].
        bodies: Bones to test (default: all).
    """
    P, valid = body_points(pieces, step)
    S = len(valid)
    if P.shape[1] == 0:
        return np.full(S, np.inf), np.full(S, -1)
    d, near = bones.signed_distance(state, P, margin=radius + reach, bodies=bodies, prune=True)
    d = np.where(valid, d, np.inf)
    k = np.argmin(d, axis=1)
    dmin = d[np.arange(S), k]
    return dmin - radius, np.where(np.isfinite(dmin), near[np.arange(S), k], -1)
