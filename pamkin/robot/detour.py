"""Detours: via points that carry a route segment between two points of one bone round that bone.

A route segment whose two ends are fixed in the same body has the same length at every pose, so where it
runs through that body's bone it can be carried round the bone by cable guides (via points on brackets)
without changing any moment arm: the route only gets longer by a constant, which the artificial tendon
takes up (:func:`detour_pam` adds it to ``tendon_length_m``, so the PAM's length, strain, force and every
torque are unchanged at every pose).

:func:`detour` finds the via points in the body's frame: from the deepest point of the straight line it
tries directions all round the line and offsets outwards, and keeps the shortest polyline whose via points
lie ``CLEARANCE``..``BRACKET`` off the bone and whose straight pieces stay ``PIECE_CLEARANCE`` outside it;
where no single via point clears the bone it keeps the one whose pieces come nearest to clearing and
detours those pieces in turn (at most ``MAX_POINTS`` via points). Distances are
:meth:`pamkin.human.bones.BoneSet.body_closest`'s (negative inside bone). Only the segment's own bone is looked
at: other bones move relative to it, and whether the detoured route clears them at a pose is for the
caller to check (``pamkin audit`` does, and so does the optimiser).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from pamkin.opensim.model_file import PathPoint
from pamkin.robot.pam_body import rolled_segments, segment_names

#: A via point lies at least this far outside the bone [m] (the optimiser's attachment points: 3 mm).
CLEARANCE = 0.003
#: ... and at most this far from it [m] (the optimiser's bracket limit, within the audit's 20 mm).
BRACKET = 0.018
#: Every straight piece of the detour stays this far outside the bone [m].
PIECE_CLEARANCE = 0.001
#: At most this many via points per segment.
MAX_POINTS = 3
#: Sample spacing along a piece [m].
STEP = 0.001
#: Directions tried round the line, and the offsets tried along each [m].
N_DIRECTIONS = 48
OFFSETS = np.arange(0.0, 0.0601, 0.001)
#: Of each direction's offsets, the nearest this many admissible ones are tried.
PER_DIRECTION = 10
#: With the other bones (:func:`other_bones`): this many candidates clear of the own bone (the shortest of
#: each direction first, then the second shortest, ...) are checked against them, this many at a time.
CHECKED = 96
BATCH = 8

Distance = Callable[[np.ndarray], np.ndarray]


def _params(length: float, step: float = STEP) -> np.ndarray:
    """Parameters 0..1 of samples at most ``step`` apart along a piece ``length`` [m] long (both ends)."""
    return np.linspace(0.0, 1.0, max(2, int(np.ceil(length / step)) + 1))


def piece_clearance(A: np.ndarray, B: np.ndarray, distance: Distance) -> float:
    """Smallest signed distance [m] from the bone of samples every ``STEP`` along the straight piece A–B."""
    t = _params(float(np.linalg.norm(B - A)))[:, None]
    return float(np.min(distance(A + t * (B - A))))


def _pieces_clearance(A: np.ndarray, B: np.ndarray, V: np.ndarray, distance: Distance) -> np.ndarray:
    """(M,) smallest signed distance of the pieces A–V[m] and V[m]–B, every candidate at once."""
    ta = _params(float(np.linalg.norm(V - A, axis=1).max()))
    tb = _params(float(np.linalg.norm(B - V, axis=1).max()))
    pa = A[None, None, :] + ta[None, :, None] * (V - A)[:, None, :]
    pb = V[:, None, :] + tb[None, :, None] * (B - V)[:, None, :]
    P = np.concatenate([pa, pb], axis=1)
    return distance(P.reshape(-1, 3)).reshape(P.shape[:2]).min(axis=1)


def _basis(e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.eye(3)[int(np.argmin(np.abs(e)))]
    u1 = np.cross(e, a)
    u1 /= np.linalg.norm(u1)
    return u1, np.cross(e, u1)


def _one(A: np.ndarray, B: np.ndarray, distance: Distance, pieces: Distance) -> tuple[np.ndarray, float] | None:
    """The best single via point for A–B: the shortest polyline whose pieces clear (``pieces``' distance),
    else the one nearest to clear; ``(V, its pieces' clearance)``, None where no via point lies
    ``CLEARANCE``..``BRACKET`` off the bone (``distance``)."""
    L = float(np.linalg.norm(B - A))
    S = A + _params(L)[:, None] * (B - A)
    P = S[int(np.argmin(distance(S)))]
    u1, u2 = _basis((B - A) / L)
    th = np.linspace(0.0, 2 * np.pi, N_DIRECTIONS, endpoint=False)
    U = np.cos(th)[:, None] * u1 + np.sin(th)[:, None] * u2                      # (D, 3)
    V = P[None, None, :] + OFFSETS[None, :, None] * U[:, None, :]                # (D, H, 3)
    dv = distance(V.reshape(-1, 3)).reshape(V.shape[:2])
    ok = (dv >= CLEARANCE) & (dv <= BRACKET)
    ok &= np.cumsum(ok, axis=1) <= PER_DIRECTION              # the nearest admissible offsets of each direction
    if not ok.any():
        return None
    cand = V[ok]
    c = _pieces_clearance(A, B, cand, distance)                   # the own bone first: cheap
    length = np.linalg.norm(cand - A, axis=1) + np.linalg.norm(B - cand, axis=1)
    clear = c >= PIECE_CLEARANCE
    if pieces is distance:
        k = int(np.argmin(np.where(clear, length, np.inf))) if clear.any() else int(np.argmax(c))
        return cand[k], float(c[k])
    # with the other bones: the shortest candidates clear of the own bone, a batch at a time — first the
    # shortest of each direction (every side of the line), then the next ones
    direction = np.broadcast_to(np.arange(N_DIRECTIONS)[:, None], ok.shape)[ok]
    idx = np.flatnonzero(clear)
    idx = idx[np.lexsort((length[idx], direction[idx]))]                      # by direction, then length
    rank = np.zeros(len(idx), dtype=int)
    for i in range(1, len(idx)):
        rank[i] = rank[i - 1] + 1 if direction[idx[i]] == direction[idx[i - 1]] else 0
    order = idx[np.lexsort((length[idx], rank))][:CHECKED]
    for i in range(0, len(order), BATCH):
        idx = order[i:i + BATCH]
        co = _pieces_clearance(A, B, cand[idx], pieces)
        if (co >= PIECE_CLEARANCE).any():
            j = int(np.flatnonzero(co >= PIECE_CLEARANCE)[0])
            return cand[idx[j]], float(co[j])
    idx = np.argsort(-c, kind="stable")[:BATCH]                  # none: the nearest to clearing, to recurse on
    co = _pieces_clearance(A, B, cand[idx], pieces)
    j = int(np.argmax(co))
    return cand[idx[j]], float(co[j])


def detour(A: np.ndarray, B: np.ndarray, distance: Distance, max_points: int = MAX_POINTS,
           others: Distance | None = None) -> list[np.ndarray] | None:
    """Via points (in order from A to B) that carry the straight segment A–B round a bone, or None.

    Args:
        A, B: The segment's ends in the bone's body frame [m] (outside the bone).
        distance: Signed distance to the bone [m] of (K, 3) points in that frame (negative inside).
        max_points: At most this many via points.
        others: Optional signed distance [m] of (K, 3) points of that frame to the other bones (the smallest
            over the poses that matter, :func:`other_bones`): the pieces must clear these too.

    Returns:
        ``[]`` where A–B is outside the bone; the via points where every piece clears it by
        ``PIECE_CLEARANCE`` with them; None where no detour of at most ``max_points`` points was found.
    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    if piece_clearance(A, B, distance) >= 0.0:
        return []
    if others is None:
        pieces = distance
    else:
        def pieces(P):
            return np.minimum(distance(P), others(P))
    return _detour(A, B, distance, max_points, pieces)


def _detour(A: np.ndarray, B: np.ndarray, distance: Distance, max_points: int, pieces: Distance
            ) -> list[np.ndarray] | None:
    if piece_clearance(A, B, pieces) >= PIECE_CLEARANCE:
        return []
    if max_points <= 0 or np.linalg.norm(B - A) < 2 * STEP:
        return None
    best = _one(A, B, distance, pieces)
    if best is None:
        return None
    V, _ = best
    left = _detour(A, V, distance, max_points - 1, pieces)
    if left is None:
        return None
    right = _detour(V, B, distance, max_points - 1 - len(left), pieces)
    if right is None:
        return None
    return [*left, V, *right]


def detour_length(A: np.ndarray, B: np.ndarray, via: list[np.ndarray]) -> float:
    """How much longer [m] the polyline A, via…, B is than the straight segment A–B."""
    pts = [np.asarray(A, float), *[np.asarray(v, float) for v in via], np.asarray(B, float)]
    return float(sum(np.linalg.norm(q - p) for p, q in zip(pts[:-1], pts[1:])) - np.linalg.norm(pts[-1] - pts[0]))


def same_body_segments(pam) -> list[int]:
    """Indices of the route segments whose two ends are fixed points (:class:`pamkin.opensim.model_file.PathPoint`) of
    the same body: their length is the same at every pose."""
    pts = pam.points
    return [a for a in range(len(pts) - 1)
            if type(pts[a]) is PathPoint and type(pts[a + 1]) is PathPoint and pts[a].body == pts[a + 1].body]


def unused_name(pam, base: str, sep: str = ".") -> str:
    """``base``, else ``base{sep}1``, ``base{sep}2``, ...: the first that names no point of ``pam``'s route."""
    names = {p.name for p in pam.points}
    name, i = base, 1
    while name in names:
        name, i = f"{base}{sep}{i}", i + 1
    return name


def via_name(pam, a: int, k: int) -> str:
    """Name of the ``k``-th via point (from 1) of the detour of segment ``a``: ``"p3.p4.1"``, not yet used."""
    return unused_name(pam, f"{pam.points[a].name}.{pam.points[a + 1].name}.{k}")


def insert_via(pam, via: dict[int, list[np.ndarray]]):
    """A copy of ``pam`` with via points inserted (``via``: segment index -> its points, body frame [m])
    and the added length on its tendon: the PAM's own length, and every force and torque, unchanged."""
    pts = list(pam.points)
    extra = 0.0
    out = []
    for a, p in enumerate(pts):
        out.append(p)
        if a in via and via[a]:
            body = p.body
            for k, v in enumerate(via[a], 1):
                out.append(PathPoint(via_name(pam, a, k), body, tuple(float(x) for x in v)))
            extra += detour_length(np.array(p.location), np.array(pts[a + 1].location), via[a])
    return pam_on_kept(dataclasses.replace(pam, points=tuple(out), tendon_length_m=pam.tendon_length_m + extra))


def pam_on_kept(pam):
    """``pam`` with its ``pam_on`` dropped where that segment no longer exists (split by a detour, or joined
    again): the PAM body then sits where it fits best (:func:`pamkin.robot.pam_body.placement`)."""

    if getattr(pam, "pam_on", None) is not None and pam.pam_on not in segment_names(pam):
        return dataclasses.replace(pam, pam_on=None)
    return pam


#: Other bones matter at the poses where they come this near a segment's straight line [m] (a detour
#: stays within a few centimetres of it) ...
NEAR = 0.04
#: ... and at most at this many of those poses, the nearest.
MAX_POSES = 64


def other_bones(bones, state, frames: list[str], body: str, A: np.ndarray, B: np.ndarray,
                n_right_only: int = 0) -> Distance | None:
    """Signed distance [m] of points fixed in ``body`` ((K, 3), body frame) to every other bone, the smallest
    over the poses of ``state`` (S configurations; ``frames``: its body order) at which another bone comes
    within :data:`NEAR` of the segment A–B (at most :data:`MAX_POSES` of them, the nearest); None where none
    does. The first ``n_right_only`` poses move the right leg only (as the audit's random poses): there the
    left leg's bones, standing at their default, are not looked at. Distances beyond :data:`NEAR` may be
    reported as ``+inf``."""
    from types import SimpleNamespace  # noqa: PLC0415

    b = frames.index(body)
    R, p = state.body_R[:, b], state.body_p[:, b]
    others = [x for x in bones.bodies if x != body]
    right = [x for x in others if not x.endswith("_l")]

    def query(idx: np.ndarray, P: np.ndarray) -> np.ndarray:
        """(len(idx), K) distances of body-frame points P at poses idx (right-leg-only poses first)."""
        out = np.full((len(idx), len(P)), np.inf)
        for mask, bodies in ((idx < n_right_only, right), (idx >= n_right_only, others)):
            if mask.any():
                sub = SimpleNamespace(body_R=state.body_R[idx[mask]], body_p=state.body_p[idx[mask]])
                W = p[idx[mask]][:, None, :] + np.einsum("sij,kj->ski", R[idx[mask]], P)
                out[mask] = bones.signed_distance(sub, W, margin=NEAR, bodies=bodies, prune=True)[0]
        return out

    line = A + _params(float(np.linalg.norm(B - A)), 4 * STEP)[:, None] * (B - A)
    dmin = query(np.arange(len(R)), line).min(axis=1)
    near = np.flatnonzero(dmin < NEAR)
    if not len(near):
        return None
    near = near[np.argsort(dmin[near])][:MAX_POSES]

    def dist(P: np.ndarray) -> np.ndarray:
        return query(near, P).min(axis=0)

    return dist


def detour_pam(pam, bones, segments: list[int] | None = None, state=None, frames: list[str] | None = None,
               n_right_only: int = 0) -> tuple[object, dict[int, str]]:
    """``pam`` with every same-body segment (``segments``: these of them; default all) that runs into its
    own bone carried round it (:func:`detour`); rollered segments are left alone. With ``state`` (a
    kinematics state of S poses, ``frames`` its body order) the detour's pieces also clear the other bones
    at those poses (:func:`other_bones`; the first ``n_right_only`` move the right leg only).

    Returns:
        ``(pam, outcome)``: the new PAM and, per segment looked at that needed a detour, ``"N via
        points"`` or ``"no detour found"`` (the segment left straight).
    """

    rolled = set(rolled_segments(pam))
    todo = [a for a in same_body_segments(pam) if a not in rolled and (segments is None or a in segments)]
    via: dict[int, list[np.ndarray]] = {}
    outcome: dict[int, str] = {}
    for a in todo:
        body = pam.points[a].body
        if not bones.meshes.get(body):
            continue

        def dist(P, body=body):
            return bones.body_closest(body, P)[0]

        A, B = np.array(pam.points[a].location), np.array(pam.points[a + 1].location)
        others = None if state is None else other_bones(bones, state, frames, body, A, B, n_right_only)
        v = detour(A, B, dist, others=others)
        note = ""
        if v is None and others is not None:           # clear of the own bone at least (the caller checks)
            v = detour(A, B, dist)
            note = " (not clear of the other bones at every pose)" if v else ""
        if v is None:
            outcome[a] = "no detour found"
        elif v:
            via[a] = v
            outcome[a] = f"{len(v)} via point{'s' if len(v) > 1 else ''}{note}"
    return (insert_via(pam, via) if via else pam), outcome


def remove_via(pam, keep: set[str]):
    """``pam`` without the via points :func:`insert_via` added: every fixed point whose name is not in
    ``keep`` between two kept points of its body, their added length taken off the tendon again."""
    pts = list(pam.points)
    kept = [i for i, p in enumerate(pts) if p.name in keep]
    out, extra = [], 0.0
    for i, j in zip(kept[:-1], kept[1:]):
        out.append(pts[i])
        via = pts[i + 1:j]
        if via:
            if not all(type(v) is PathPoint and v.body == pts[i].body for v in via) or pts[j].body != pts[i].body:
                raise ValueError(f"PAM {pam.id} {pam.name}: points {[v.name for v in via]} are not via points of a "
                                 f"detour between {pts[i].name} and {pts[j].name}")
            extra += detour_length(np.array(pts[i].location), np.array(pts[j].location),
                                   [np.array(v.location) for v in via])
    if kept:
        out.append(pts[kept[-1]])
    if len(out) == len(pts):
        return pam
    return pam_on_kept(dataclasses.replace(pam, points=tuple(out), tendon_length_m=pam.tendon_length_m - extra))
