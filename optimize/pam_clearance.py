"""PAM bodies of a design as capsules at given poses (the audit's definition), for the optimiser's
PAM–PAM clearance pass.

A PAM body is the part of its route from the start of its mount segment (the segment that best holds
the PAM with both fittings) for the PAM length plus both fittings, with Festo's assumed outer diameter
(:func:`pamkin.festo.outer_diameter`) — exactly what ``pamkin audit`` tests
(:func:`pamkin.pam_body.pam_capsules`, :func:`pamkin.pam_body.mount_segment`, :func:`pamkin.pam_body.body_room`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from pamkin import festo
from pamkin.errors import RangeWarning


@dataclass
class Body:
    """One actuator's PAM body at S poses: pieces ``(A (S, 3), B (S, 3), valid (S,))`` and radius [m]."""

    id: int
    pieces: list
    radius: float
    mount: int


def pam_bodies(design, model, q: np.ndarray) -> list[Body]:
    """The right-side PAM bodies of every actuator of ``design`` at poses ``q`` (S, n_coordinates)."""
    from pamkin.pam_body import body_room, mount_segment, pam_capsules, route_positions
    from pamkin.robot import PamRobot

    right = PamRobot(design, model, sides=("r",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st = right.evaluate(q)
        ks = model.kinematics.forward(q, warn_range=False)
    fit = 2 * design.fitting_length_m
    out = []
    for k, pam in enumerate(design.pams):
        pts = route_positions(right.paths, ks, k)
        seg_len = np.linalg.norm(pts[:, 1:] - pts[:, :-1], axis=2)
        pam_len = st.pam_lengths[:, k]
        j, _ = mount_segment(body_room(seg_len, pam.resting_length_m, pam_len, design.fitting_length_m))
        pieces = pam_capsules(pts, j, pam_len + fit)
        out.append(Body(pam.id, pieces, festo.outer_diameter(pam.diameter_mm) / 2, j))
    return out


def body_distance(a: Body, b: Body) -> float:
    """Smallest signed distance [m] between two PAM bodies over the poses (negative: they intersect)."""
    from pamkin.bones import capsule_pair_overlap

    best = np.inf
    for A, B, va in a.pieces:
        for C, D, vb in b.pieces:
            ok = va & vb
            if ok.any():
                d, _ = capsule_pair_overlap(A[ok], B[ok], a.radius, C[ok], D[ok], b.radius, 1e-4)
                best = min(best, d)
    return float(best)


def segment_point_distance(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distances (S, K) from points P (S, K, 3) to segments A–B (S, 3) and the closest points (S, K, 3)."""
    AB = (B - A)[:, None, :]
    ab2 = np.maximum(np.sum(AB * AB, axis=2), 1e-300)
    u = np.clip(np.sum((P - A[:, None, :]) * AB, axis=2) / ab2, 0.0, 1.0)
    Q = A[:, None, :] + u[..., None] * AB
    return np.linalg.norm(P - Q, axis=2), Q
