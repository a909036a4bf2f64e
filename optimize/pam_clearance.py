"""PAM bodies of a design as capsules at given poses (the audit's definition), for the optimiser's
PAM–PAM clearance pass.

A PAM body is the part of its route at the anchored end of its mount segment (the segment that best holds
the PAM with both fittings) for the PAM length plus both fittings, with Festo's assumed outer diameter
(:func:`pamkin.festo.outer_diameter`) — exactly what ``pamkin audit`` tests
(:func:`pamkin.pam_body.placement`, :func:`pamkin.pam_body.pam_capsules`).
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
    from pamkin.pam_body import pam_capsules, placements

    fit = 2 * design.fitting_length_m
    out = []
    for pam, (place, pts, pam_len) in zip(design.pams, placements(design, model, q)):
        pieces = pam_capsules(pts, place.segment, pam_len + fit, place.side)
        out.append(Body(pam.id, pieces, festo.outer_diameter(pam.diameter_mm) / 2, place.segment))
    return out


def segment_point_distance(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distances (S, K) from points P (S, K, 3) to segments A–B (S, 3) and the closest points (S, K, 3)."""
    AB = (B - A)[:, None, :]
    ab2 = np.maximum(np.sum(AB * AB, axis=2), 1e-300)
    u = np.clip(np.sum((P - A[:, None, :]) * AB, axis=2) / ab2, 0.0, 1.0)
    Q = A[:, None, :] + u[..., None] * AB
    return np.linalg.norm(P - Q, axis=2), Q


#: Random stream of :func:`choose_ends`' poses (never the audit's).
ENDS_STREAM = 0xA0D5
#: Random poses (right leg and lumbar within the range of motion) :func:`choose_ends` checks the PAM pairs at;
#: with the walking trial between its frames (both legs as recorded: the left–right pairs).
ENDS_RANDOM = 500


def _walking_midframes(model) -> np.ndarray:
    """Both legs of the walking trial *between* its frames (never an audit sample); empty without it."""
    from pamkin.audit import GAIT_IK, gait_poses
    from pamkin.errors import PamkinError

    try:
        g, _ = gait_poses(model, GAIT_IK)
    except (PamkinError, OSError):
        return np.zeros((0, len(model.coordinates)))
    return 0.5 * (g[:-1] + g[1:])


def choose_ends(design, model, rom, seed: int = 0, n_random: int = ENDS_RANDOM):
    """The end of its mount segment every PAM on one straight segment is anchored at (``pam_at``), where
    the route on both sides of the segment has a fixed length (:func:`pamkin.pam_body.fixed_ends`; elsewhere
    only one end is possible): the choice with the fewest intersecting PAM pairs, left–right (walking
    trial) first, then same side (random poses and the walking trial) — a local search from the default
    ends, one PAM flipped at a time, at poses of the optimiser's own stream (:data:`ENDS_STREAM`).
    The routes, sizes and so every torque are unchanged.

    Returns:
        ``(design, lines)``: the design with ``pam_at`` set on every PAM on one segment (the default end
        included, so the file says where each PAM sits) and a log line per PAM moved to its other end.
    """
    import dataclasses

    from pamkin.audit import CLEARANCE_TOLERANCE, random_poses
    from pamkin.bones import body_pair_distance
    from pamkin.design import Design
    from pamkin.pam_body import fixed_ends, pam_capsules, placements, route_positions
    from pamkin.robot import PamRobot

    n = len(design.pams)
    both = PamRobot(design, model)
    q_r = random_poses(model, rom, n_random, seed, stream=ENDS_STREAM)
    q_g = _walking_midframes(model)
    fit = 2 * design.fitting_length_m
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        sets = {"random": (model.kinematics.forward(q_r, warn_range=False), both.evaluate(q_r))}
        if len(q_g):
            sets["gait"] = (model.kinematics.forward(q_g, warn_range=False), both.evaluate(q_g))
    # the default ends (no pam_at) at every pose of both sets
    default = Design(design.name, tuple(dataclasses.replace(p, pam_at=None) for p in design.pams),
                     design.pressure_Pa, design.force_model, design.fitting_length_m, design.rom)
    options, places = [], []
    for place, pts, _ in placements(default, model, np.vstack([q_r, q_g])):
        places.append(place)
        if not place.on_one_segment:
            options.append([place.side])
            continue
        ends = fixed_ends(pts, place.segment)
        options.append([s for s, ok in zip(("origin", "insertion"), ends) if ok] or [place.side])
    radius = [festo.outer_diameter(p.diameter_mm) / 2 for p in design.pams]
    caps = {}
    for key, (kin, ps) in sets.items():
        for c in (range(2 * n) if key == "gait" else range(n)):
            pts = route_positions(both.paths, kin, c)
            for side in options[c % n]:
                caps[(key, c, side)] = pam_capsules(pts, places[c % n].segment, ps.pam_lengths[:, c] + fit, side)

    def hit(ca, cb, ra, rb) -> bool:          # the audit's count: an overlap deeper than its tolerance
        return body_pair_distance(ca, cb, ra, rb, CLEARANCE_TOLERANCE)[0] < -CLEARANCE_TOLERANCE

    memo: dict = {}

    def pair(a: int, sa: str, b: int, sb: str, lr: bool) -> bool:
        key = (a, sa, b, sb, lr)
        if key not in memo:
            if lr:
                memo[key] = "gait" in sets and hit(caps[("gait", a, sa)], caps[("gait", b + n, sb)], radius[a], radius[b])
            else:
                memo[key] = any(hit(caps[(s, a, sa)], caps[(s, b, sb)], radius[a], radius[b]) for s in sets)
        return memo[key]

    def count(choice: list[str]) -> tuple[int, int]:
        same = sum(pair(a, choice[a], b, choice[b], False) for a in range(n) for b in range(a + 1, n))
        lr = sum(pair(a, choice[a], b, choice[b], True) for a in range(n) for b in range(n)) if "gait" in sets else 0
        return lr, same

    choice = [p.side for p in places]
    best = count(choice)
    start = best
    improved = True
    while improved:
        improved = False
        for k in range(n):
            for side in options[k]:
                if side == choice[k]:
                    continue
                trial = choice[:k] + [side] + choice[k + 1:]
                c = count(trial)
                if c < best:
                    choice, best, improved = trial, c, True
    lines = []
    pams = []
    for k, pam in enumerate(design.pams):
        side = choice[k] if places[k].on_one_segment else None
        if side is not None and side != places[k].side:
            lines.append(f"PAM ends: actuator {pam.id} {pam.name} anchored at the {side} end of its segment "
                         f"(default {places[k].side})")
        pams.append(dataclasses.replace(pam, pam_at=side))
    lines.append(f"PAM ends: intersecting pairs at the run's check poses: same side {start[1]} -> {best[1]}, "
                 f"left-right (walking) {start[0]} -> {best[0]}")
    out = design
    for p in pams:
        out = out.replace_pam(p)
    return out, lines
