"""PAM bodies of a design as capsules at given poses (the audit's definition), for the optimiser's
PAM–PAM clearance pass.

A PAM body is the part of its route at the anchored end of its mount segment (the segment that best holds
the PAM with both fittings) for the PAM length plus both fittings, with the body radius of its Festo size and
parallel count (:func:`pamkin.audit.assembly.body_radius`) — exactly what ``pamkin audit`` tests
(:func:`pamkin.robot.pam_body.placement`, :func:`pamkin.robot.pam_body.pam_capsules`).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from pamkin.audit.assembly import body_radius
from pamkin.audit.measure import CLEARANCE_TOLERANCE, GAIT_IK, gait_poses, random_poses
from pamkin.errors import PamkinError, RangeWarning
from pamkin.human.bones import body_pair_distance
from pamkin.robot.biped import PamRobot, placements
from pamkin.robot.design import Design
from pamkin.robot.rack import has_rack
from pamkin.robot.pam_body import (
    pam_capsules,
    route_positions,
    segment_names,
    segment_options,
)


@dataclass
class Body:
    """One actuator's PAM body at S poses: pieces ``(A (S, 3), B (S, 3), valid (S,))`` and radius [m]."""

    id: int
    pieces: list
    radius: float
    mount: int


def pam_bodies(design, model, q: np.ndarray) -> list[Body]:
    """The right-side PAM bodies of every actuator of ``design`` at poses ``q`` (S, n_coordinates)."""

    fit = 2 * design.fitting_length_m
    out = []
    for pam, (place, pts, pam_len) in zip(design.pams, placements(design, model, q)):
        pieces = pam_capsules(pts, place.segment, pam_len + fit, place.side)
        out.append(Body(pam.id, pieces, body_radius(pam.diameter_mm, pam.n_parallel), place.segment))
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

    try:
        g, _ = gait_poses(model, GAIT_IK)
    except (PamkinError, OSError):
        return np.zeros((0, len(model.coordinates)))
    return 0.5 * (g[:-1] + g[1:])


def choose_ends(design, model, rom, seed: int = 0, n_random: int = ENDS_RANDOM):
    """Where every PAM on one straight segment sits: the segment (``pam_on``, where the body fits on more
    than one) and the end of it the PAM is anchored at (``pam_at``, where the route on both sides of the
    segment has a fixed length: :func:`pamkin.robot.pam_body.segment_options`) — the choice with the fewest
    intersecting PAM pairs, left–right (walking trial) first, then same side (random poses and the walking
    trial): a local search from the default places, one PAM moved at a time, at poses of the optimiser's own
    stream (:data:`ENDS_STREAM`). The routes, sizes and so every torque are unchanged.

    Returns:
        ``(design, lines)``: the design with ``pam_on`` and ``pam_at`` set on every PAM on one segment (the
        default place included, so the file says where each PAM sits) and a log line per PAM moved.
    """


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
    # the default places (no pam_on, no pam_at) at every pose of both sets
    # (a PAM on a rack keeps its place: its body hangs on the rack, :mod:`pamkin.robot.rack`)
    default = Design(design.name, tuple(p if has_rack(p) else dataclasses.replace(p, pam_at=None, pam_on=None)
                                        for p in design.pams),
                     design.pressure_Pa, design.force_model, design.fitting_length_m, design.rom)
    options, places, on_one = [], [], []
    for pam, (place, pts, pam_len) in zip(default.pams, placements(default, model, np.vstack([q_r, q_g]))):
        places.append((place.segment, place.side))
        on_one.append(place.on_one_segment)
        opts = (segment_options(pts, pam, pam_len, design.fitting_length_m)
                if place.on_one_segment and not has_rack(pam) else [])
        options.append(opts if places[-1] in opts else [places[-1]])
    radius = [body_radius(p.diameter_mm, p.n_parallel) for p in design.pams]
    caps = {}
    for key, (kin, ps) in sets.items():
        for c in (range(2 * n) if key == "gait" else range(n)):
            pts = route_positions(both.paths, kin, c)
            for j, side in options[c % n]:
                caps[(key, c, j, side)] = pam_capsules(pts, j, ps.pam_lengths[:, c] + fit, side)

    def hit(ca, cb, ra, rb) -> bool:          # the audit's count: an overlap deeper than its tolerance
        return body_pair_distance(ca, cb, ra, rb, CLEARANCE_TOLERANCE)[0] < -CLEARANCE_TOLERANCE

    memo: dict = {}

    def pair(a: int, oa: tuple, b: int, ob: tuple, lr: bool) -> bool:
        key = (a, oa, b, ob, lr)
        if key not in memo:
            if lr:
                memo[key] = "gait" in sets and hit(caps[("gait", a, *oa)], caps[("gait", b + n, *ob)],
                                                   radius[a], radius[b])
            else:
                memo[key] = any(hit(caps[(s, a, *oa)], caps[(s, b, *ob)], radius[a], radius[b]) for s in sets)
        return memo[key]

    def count(choice: list[tuple]) -> tuple[int, int]:
        same = sum(pair(a, choice[a], b, choice[b], False) for a in range(n) for b in range(a + 1, n))
        lr = sum(pair(a, choice[a], b, choice[b], True) for a in range(n) for b in range(n)) if "gait" in sets else 0
        return lr, same

    choice = list(places)
    best = count(choice)
    start = best
    improved = True
    while improved:
        improved = False
        for k in range(n):
            for option in options[k]:
                if option == choice[k]:
                    continue
                trial = choice[:k] + [option] + choice[k + 1:]
                c = count(trial)
                if c < best:
                    choice, best, improved = trial, c, True
    lines = []
    pams = []
    for k, pam in enumerate(design.pams):
        if not on_one[k]:
            pams.append(dataclasses.replace(pam, pam_at=None, pam_on=None))
            continue
        names = segment_names(pam)
        (j, side), (j0, side0) = choice[k], places[k]
        if (j, side) != (j0, side0):
            where = f"the {side} end of its segment" if j == j0 else f"the {side} end of segment {names[j]}"
            lines.append(f"PAM ends: actuator {pam.id} {pam.name} anchored at {where} "
                         f"(default {side0} end of {names[j0]})")
        pams.append(dataclasses.replace(pam, pam_at=side, pam_on=names[j]))
    lines.append(f"PAM ends: intersecting pairs at the run's check poses: same side {start[1]} -> {best[1]}, "
                 f"left-right (walking) {start[0]} -> {best[0]}")
    out = design
    for p in pams:
        out = out.replace_pam(p)
    return out, lines
