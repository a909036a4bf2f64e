"""Bone-mesh clearance of one actuator's route as linear constraints, re-linearised each round.

The bone meshes (:class:`pamkin.human.bones.BoneSet`, exact libigl distances) are not smooth enough for
IPOPT as functions, so the optimiser uses them the way sequential convex collision methods do
(e.g. TrajOpt): at the current route, every segment sample that comes near a bone at some
*bone-check pose* gives one linear constraint — the sample stays on the outer side of the bone's
tangent plane at its closest surface point, by ``SEGMENT_CLEARANCE`` — and every body-fixed
attachment point gets a row along its own bone's outward normal, n·(x − c) ≥ ``POINT_MIN``
(outside the bone), and a ball of radius ``POINT_MAX`` around its bone's closest surface point (within
bracket distance). The segment rows are elastic (a slack with an L1 penalty); the point rows and balls
are hard (a point in bone or on a bracket longer than 20 mm cannot be built; points outside that band
are first moved into it, so every round starts feasible for them and each accepted round ends so); the
points move within a trust region;
after each round the exact distances are measured again and the best round is kept. A second,
optional pass adds rows that keep the route off the other PAMs' bodies (:mod:`optimize.pam_clearance`).

Every world position of a route point is affine in the decision variables (x = base + R_b ℓ), so a
tangent-plane constraint at a pose is one row ``w·z + w0 ≥ 0`` of the decision vector z of
:class:`optimize.problem.ActuatorProblem` (3 coordinates per route point, then l0 and t).

Bone-check poses: random poses over every audited coordinate (their own random stream, never the
audit's), the 1-D sweep of the primary coordinate, the range-of-motion corners and boundary poses of
the coordinates the route crosses, and the walking trial between its frames.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from pamkin.optimize.pam_clearance import segment_point_distance
from pamkin.optimize.samples import (
    boundary_poses,
    corner_poses,
    gait_training_poses,
    poses_from_unit,
    with_dependencies,
)

from pamkin.audit.measure import audit_coordinates
from pamkin.errors import RangeWarning
from pamkin.human.paths import PathSet
from pamkin.robot.detour import piece_clearance, same_body_segments
from pamkin.robot.rollers import roller_pieces

#: Centre line of every segment at least this far outside every bone at the bone-check poses [m]
#: (the audit's limit is 2 mm *into* bone; the difference covers poses between the samples).
SEGMENT_CLEARANCE = 0.003
#: Attachment points: distance from their own bone along its normal [m] (audit: 0 .. 20 mm).
POINT_MIN = 0.003
POINT_MAX = 0.018
#: Segment samples nearer than this to a bone give a constraint [m].
ACTIVATION = 0.010
#: Spacing of the samples along a segment [m] (at its longest). A bone rim thinner than this can pass
#: between two samples (a pelvis-fixed segment over the iliac crest went 3.7 mm into the pelvis with every
#: sample clear); 5 mm sees it, but the default run with it (and the point check) fit worse (median NRMSE
#: 0.119 -> 0.158) and took 36 s longer.
STEP = 0.010
#: At most this many constraints per segment sample (its closest poses) and in all.
PER_SAMPLE = 3
MAX_CUTS = 320
#: PAM–PAM clearance (second pass): the route's centre line keeps the other PAM bodies' radius + its own
#: (on its mount segment; a tendon's elsewhere) + this margin away [m]; at most PAM_ROWS of the rows.
PAM_MARGIN = 0.002
TENDON_RADIUS = 0.003
PAM_ACTIVATION = 0.010
PAM_ROWS = 120
#: Weight of PAM–PAM overlap against bone violations (rows and merit): bone clearance comes first.
PAM_WEIGHT = 0.1
#: Random bone-check poses per actuator.
N_RANDOM = 200
#: Boundary bone-check poses per actuator (crossed coordinates at a limit or uniform).
N_BOUNDARY = 100
#: Attachment-point contact check after the rounds: this many more random poses, and at most
#: POINT_CHECK_ADD of those where a fixed point comes within SEGMENT_CLEARANCE of another bone join the
#: bone-check poses (a pelvis point met the femur at 5 of 2000 audit poses, none of the 200 random ones).
N_POINT_CHECK = 2000
POINT_CHECK_ADD = 20
#: Random stream of the bone-check poses (the audit draws from AUDIT_STREAM, training from OPTIMIZE_STREAM).
BONE_STREAM = 0xA0D3


#: Largest number of alternating moves onto the bracket band and off the midline in :meth:`BoneCuts.pull_in`.
PULL_ITERATIONS = 8
#: A point this close [m] below its ``zmin`` meets it (IPOPT's solutions hold their rows to ~1e-7).
ZMIN_TOLERANCE = 1e-5

#: Trust region of the point coordinates [m]: start, largest, and the size below which the rounds stop.
TRUST_START = 0.02
TRUST_MAX = 0.03
TRUST_MIN = 0.002
#: Once the route is clear of bone, the rounds stop when the merit improves by less than this fraction.
STOP_GAIN = 0.05
#: A route that is clear of bone and still gains at least STOP_GAIN per round when the rounds run out gets
#: up to this many more (the default run's posterior gluteus medius/minimus PAM: objective 0.224 after 10
#: rounds, 0.171 after 13).
EXTRA_CLEAR_ROUNDS = 6
#: Merit of a round: objective + MERIT_PENALTY · (exact violation [m]) (as the rows' penalty).
MERIT_PENALTY = 3000.0


@dataclass
class Measure:
    """Exact clearance of a route at the bone-check poses."""

    segment_depth: np.ndarray          # (segments,) deepest penetration of each segment [m] (<= 0: clear)
    segment_bone: list[str | None]     # the bone of the deepest point
    point_distance: np.ndarray         # (points,) own-bone distance of fixed points [m] (NaN: moving / no mesh)
    pam_clearance: dict | None = None  # other actuator id -> smallest clearance to its PAM body [m] (< 0: hit)

    def violation(self, pam_weight: float = 1.0) -> float:
        """Σ segment penetration + Σ point distance outside [0, 20 mm] + pam_weight · Σ PAM-body
        overlap [m] (0: clear of bone and of the other PAMs)."""
        seg = np.maximum(self.segment_depth, 0.0).sum()
        d = self.point_distance[np.isfinite(self.point_distance)]
        return float(seg + np.maximum(-d, 0).sum() + np.maximum(d - 0.020, 0).sum() + pam_weight * self.pam_overlap())

    def point_inside_bone(self) -> bool:
        """Whether a fixed attachment point lies inside its own bone."""
        return bool(np.nanmin(self.point_distance, initial=np.inf) < 0)

    def pam_overlap(self) -> float:
        """Σ over the other PAM bodies of the deepest overlap [m]."""
        return float(sum(max(-c, 0.0) for c in (self.pam_clearance or {}).values()))

    def summary(self, names: list[str]) -> dict:
        segs = [f"{names[a]}-{names[a + 1]}" for a in range(len(names) - 1)]
        return {
            "max_segment_penetration_mm": round(1e3 * float(max(self.segment_depth.max(), 0.0)), 2),
            "segments_into_bone": {s: {"depth_mm": round(1e3 * float(d), 2), "bone": b}
                                   for s, d, b in zip(segs, self.segment_depth, self.segment_bone) if d > 0},
            "point_distance_mm": {n: round(1e3 * float(d), 2) for n, d in zip(names, self.point_distance)
                                  if np.isfinite(d)},
            "pam_overlap_mm": {str(k): round(-1e3 * c, 2) for k, c in sorted((self.pam_clearance or {}).items())
                               if c < 0},
        }


def right_only_query(query, state, P: np.ndarray, n_right_only: int, **kw) -> tuple:
    """``query(state, P, **kw)`` (a :class:`pamkin.human.bones.BoneSet` method: ``nearest``, ``signed_distance``) with
    the first ``n_right_only`` poses against the right side's bones only (they move the right leg only, as the
    audit's random poses: the left leg's bones, standing at their default, are not tested), the rest against
    every bone; the results concatenated along the poses."""
    from types import SimpleNamespace  # noqa: PLC0415

    k = int(n_right_only)
    if k <= 0:
        return query(state, P, **kw)
    bones = query.__self__
    right = [b for b in bones.bodies if not b.endswith("_l")]
    a = query(SimpleNamespace(body_R=state.body_R[:k], body_p=state.body_p[:k]), P[:k], bodies=right, **kw)
    if k >= len(P):
        return a
    b = query(SimpleNamespace(body_R=state.body_R[k:], body_p=state.body_p[k:]), P[k:], **kw)
    return tuple(np.concatenate([x, y]) for x, y in zip(a, b))


class BoneCuts:
    """Bone-check poses of one actuator and the linear clearance rows of its route.

    Args:
        pam: The seed PAM (route points; moving points are described by offsets, seed 0).
        model: The human model (kinematics of the poses; same skeleton as the robot).
        bones: The skeleton's :class:`pamkin.human.bones.BoneSet`.
        q: (S, n_coordinates) bone-check poses.
    """

    def __init__(self, pam, model, bones, q: np.ndarray, n_right_only: int = 0) -> None:
        self.pam, self.bones = pam, bones
        # the first n_right_only poses move the right leg only (as the audit's random poses): there the
        # left leg's bones, standing at their default, are not tested
        self.n_right_only = int(n_right_only)
        kin = model.kinematics
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            self.state = kin.forward(q, warn_range=False)
            X, _ = PathSet(kin, ["route"], [pam.points]).point_positions(self.state)
        self.S = len(q)
        self.n_points = len(pam.points)
        bidx = [model.bodies.index(pt.body) for pt in pam.points]
        self.R = self.state.body_R[:, bidx]                      # (S, P, 3, 3)
        self.moving = [not hasattr(pt, "location") for pt in pam.points]
        # base of every point: its body origin (fixed points) or its unshifted moving position
        self.base = np.where(np.array(self.moving)[None, :, None], X, self.state.body_p[:, bidx])
        self.has_mesh = [(not m) and bool(bones.meshes.get(pt.body)) for pt, m in zip(pam.points, self.moving)]
        self.obstacles: list = []
        self.n_point_rows = 0          # the first rows of measure(with_rows=True) are the (hard) point rows
        self.radius = 0.0
        self.mount = 0
        #: segments not sampled
        self.skip: set[int] = set()
        #: segment index -> its roller (pamkin.robot.rollers.Roller): the straight pieces around it are sampled
        self.rollers: dict = {}
        #: same-body segments (both ends fixed in one body, :func:`pamkin.robot.detour.same_body_segments`) shorter
        #: than this [m] do not see their own bone: the run carries them round it afterwards
        #: (:func:`pamkin.robot.detour.detour_pam`, a constant length); other bones still count. 0: off
        self.detour_below = 0.0
        #: segments that always see their own bone (the one the PAM body is being put on)
        self.keep: set[int] = set()
        self._same_body = [a for a in same_body_segments(pam) if bones.meshes.get(pam.points[a].body)]
        self._own = {a: bones.bodies.index(pam.points[a].body) for a in self._same_body}
        self._frames = list(kin.frames)

    def set_obstacles(self, bodies: list, radius: float, mount: int) -> None:
        """Other PAMs' bodies (:class:`optimize.pam_clearance.Body` at these poses) to keep clear of;
        ``radius`` [m] of this PAM's body, which sits on segment ``mount``."""
        self.obstacles = list(bodies)
        self.radius, self.mount = float(radius), int(mount)

    def world(self, loc: np.ndarray) -> np.ndarray:
        """(S, P, 3) world positions for the point locations/offsets ``loc`` (P, 3)."""
        return self.base + np.einsum("spij,pj->spi", self.R, loc)

    def _samples(self, X: np.ndarray):
        """Segment samples: (S, K, 3) positions, segment index (K,), parameter t (K,). Each sample is
        ``wa·X[a] + wb·X[a+1] + const`` (kept in ``_wa``, ``_wb`` (K,) and ``_const`` (S, K, 3)): on a straight
        segment (1 − t, t, 0); on a segment with a roller (``rollers``) the samples lie on its straight pieces
        before and after the roller, X[a] → T1 (1 − t, 0, t·T1) and T2 → X[a+1] (0, t, (1 − t)·T2), the
        tangent points (fixed in the roller's bone) from :func:`pamkin.robot.rollers.roller_pieces`."""
        segs, ts, was, wbs, consts, parts = [], [], [], [], [], []
        for a in range(self.n_points - 1):
            if a in self.skip:
                continue
            if a in self.rollers:
                rol = self.rollers[a]
                b = self._frames.index(rol.body)
                T1, T2, _, _ = roller_pieces(X[:, a], X[:, a + 1], self.state.body_R[:, b], self.state.body_p[:, b],
                                             rol, single=len(self.rollers) == 1)
                for first, T in ((True, T1), (False, T2)):
                    far = X[:, a] if first else X[:, a + 1]
                    length = float(np.max(np.linalg.norm(T - far, axis=1)))
                    t = np.linspace(0.0, 1.0, max(3, int(np.ceil(length / STEP)) + 1))
                    segs.append(np.full(len(t), a))
                    ts.append(t)
                    if first:
                        was.append(1 - t), wbs.append(np.zeros(len(t)))
                        consts.append(t[None, :, None] * T[:, None, :])
                        parts.append(X[:, a, None] + t[None, :, None] * (T - X[:, a])[:, None, :])
                    else:
                        was.append(np.zeros(len(t))), wbs.append(t)
                        consts.append((1 - t)[None, :, None] * T[:, None, :])
                        parts.append(T[:, None, :] + t[None, :, None] * (X[:, a + 1] - T)[:, None, :])
                continue
            length = float(np.max(np.linalg.norm(X[:, a + 1] - X[:, a], axis=1)))
            t = np.linspace(0.0, 1.0, max(3, int(np.ceil(length / STEP)) + 1))
            segs.append(np.full(len(t), a))
            ts.append(t)
            was.append(1 - t), wbs.append(t)
            consts.append(np.zeros((self.S, len(t), 3)))
            # (the same floating-point form as before rollers existed: runs without rollers reproduce to the bit)
            parts.append(X[:, a, None] + t[None, :, None] * (X[:, a + 1] - X[:, a])[:, None, :])
        if not segs:                       # every segment skipped
            self._wa, self._wb = np.zeros(0), np.zeros(0)
            self._const = np.zeros((self.S, 0, 3))
            return np.zeros((self.S, 0, 3)), np.zeros(0, dtype=int), np.zeros(0)
        seg, t = np.concatenate(segs), np.concatenate(ts)
        self._wa, self._wb = np.concatenate(was), np.concatenate(wbs)
        self._const = np.concatenate(consts, axis=1)
        return np.concatenate(parts, axis=1), seg, t

    def _nearest(self, P: np.ndarray):
        return right_only_query(self.bones.nearest, self.state, P, self.n_right_only, margin=ACTIVATION, prune=True)

    def measure(self, loc: np.ndarray, with_rows: bool = False):
        """Exact clearance of the route with locations ``loc`` (P, 3); optionally also the rows."""
        X = self.world(loc)
        P, seg, t = self._samples(X)
        if P.shape[1]:
            d, near, c, n = self._nearest(P)
            for a in self.detoured(loc):
                cols = np.flatnonzero(seg == a)
                sub = d[:, cols]
                sub[near[:, cols] == self._own[a]] = np.inf
                d[:, cols] = sub
        else:
            d, near = np.full((self.S, 0), np.inf), np.zeros((self.S, 0), dtype=int)
            c, n = np.zeros((self.S, 0, 3)), np.zeros((self.S, 0, 3))
        depth = np.full(self.n_points - 1, -np.inf)
        bone = [None] * (self.n_points - 1)
        dmin = d.min(axis=0)                                   # (K,)
        for a in range(self.n_points - 1):
            k = np.flatnonzero(seg == a)
            if not len(k):                 # a skipped segment
                depth[a] = -ACTIVATION
                continue
            j = k[np.argmin(dmin[k])]
            depth[a] = -dmin[j] if np.isfinite(dmin[j]) else -ACTIVATION
            if depth[a] > 0:
                s_ = int(np.argmin(d[:, j]))
                bone[a] = self.bones.bodies[near[s_, j]]
        pd = np.full(self.n_points, np.nan)
        cs, ns = {}, {}
        for i, pt in enumerate(self.pam.points):
            if self.has_mesh[i]:
                di, ci, ni = self.bones.body_closest(pt.body, loc[i][None])
                pd[i], cs[i], ns[i] = di[0], ci[0], ni[0]
        pam_c, pam_rows = self._pam_clearance(P, seg, with_rows)
        m = Measure(depth, bone, pd, pam_c)
        if not with_rows:
            return m
        W, w0 = self._rows(loc, d, c, n, seg, t, cs, ns, room=MAX_CUTS - len(pam_rows[0]))
        return m, (np.vstack([W, pam_rows[0]]), np.concatenate([w0, pam_rows[1]]))

    def detoured(self, loc: np.ndarray) -> list[int]:
        """The same-body segments (their own bone has a mesh) shorter than :attr:`detour_below` for the point
        locations ``loc`` (P, 3): those whose own bone is left to the detours."""
        if self.detour_below <= 0:
            return []
        return [a for a in self._same_body if a not in self.keep and self.rollers.get(a) is None
                and np.linalg.norm(loc[a + 1] - loc[a]) < self.detour_below]

    def in_own_bone(self, loc: np.ndarray) -> list[int]:
        """Of :meth:`detoured`, the segments whose straight line enters their own bone (body frame, exact
        at 1 mm samples): they cannot hold the PAM body as they are."""
        out = []
        for a in self.detoured(loc):
            body = self.pam.points[a].body
            if piece_clearance(loc[a], loc[a + 1], lambda P, b=body: self.bones.body_closest(b, P)[0]) < 0:
                out.append(a)
        return out

    def _pam_clearance(self, P, seg, with_rows):
        """Clearance to every obstacle PAM body (and, optionally, rows for the nearest samples)."""
        nz = 3 * self.n_points + 2
        if not self.obstacles:
            return None, (np.zeros((0, nz)), np.zeros(0))

        own = np.where(seg == self.mount, self.radius, TENDON_RADIUS)          # (K,)
        clear: dict = {}
        cand = []                                                             # (clearance, s, k, Q, need)
        for body in self.obstacles:
            for A, B, valid in body.pieces:
                dist, Q = segment_point_distance(P, A, B)
                need = body.radius + own[None, :] + PAM_MARGIN
                c = np.where(valid[:, None], dist - need, np.inf)
                clear[body.id] = min(clear.get(body.id, np.inf), float(c.min()))
                if with_rows:
                    for s_, k in np.argwhere(c < PAM_ACTIVATION):
                        cand.append((float(c[s_, k]), int(s_), int(k), Q[s_, k], float(need[0, k])))
        W, w0 = [], []
        if with_rows and cand:
            cand.sort(key=lambda x: x[0])
            used: dict = {}
            for c_, s_, k, Q, need in cand:
                if len(W) >= PAM_ROWS:
                    break
                if used.get(k, 0) >= PER_SAMPLE:
                    continue
                used[k] = used.get(k, 0) + 1
                a, wa, wb = int(seg[k]), float(self._wa[k]), float(self._wb[k])
                diff = P[s_, k] - Q
                nn = diff / max(np.linalg.norm(diff), 1e-12)
                w = np.zeros(nz)
                w[3 * a:3 * a + 3] += wa * (self.R[s_, a].T @ nn)
                w[3 * a + 3:3 * a + 6] += wb * (self.R[s_, a + 1].T @ nn)
                base = wa * self.base[s_, a] + wb * self.base[s_, a + 1] + self._const[s_, k]
                W.append(PAM_WEIGHT * w)               # a weaker row: bone clearance comes first
                w0.append(PAM_WEIGHT * float(nn @ base - nn @ Q - need))
        if not W:
            return clear, (np.zeros((0, nz)), np.zeros(0))
        return clear, (np.array(W), np.array(w0))

    def _rows(self, loc, d, c, n, seg, t, cs, ns, room: int = MAX_CUTS):
        nz = 3 * self.n_points + 2
        W, w0 = [], []
        # attachment points outside their bone (body frame): n·(x - c) >= POINT_MIN; within bracket
        # distance: the ball |x - c| <= POINT_MAX of :meth:`balls` (both hard: the first n_point_rows rows)
        for i in cs:
            w = np.zeros(nz)
            w[3 * i:3 * i + 3] = ns[i]
            W.append(w)
            w0.append(-(ns[i] @ cs[i]) - POINT_MIN)
        self.n_point_rows = len(W)
        # segment samples near a bone: the closest poses of each, the nearest first
        S, K = d.shape
        cand = np.argwhere(d < ACTIVATION)                     # (M, 2) of (pose, sample)
        if len(cand):
            order = np.argsort(d[cand[:, 0], cand[:, 1]], kind="stable")
            used = np.zeros(K, dtype=int)
            room = room - len(W)
            for s_, k in cand[order]:
                if room <= 0:
                    break
                if used[k] >= PER_SAMPLE:
                    continue
                used[k] += 1
                room -= 1
                a, wa, wb, nn = int(seg[k]), float(self._wa[k]), float(self._wb[k]), n[s_, k]
                w = np.zeros(nz)
                w[3 * a:3 * a + 3] += wa * (self.R[s_, a].T @ nn)
                w[3 * a + 3:3 * a + 6] += wb * (self.R[s_, a + 1].T @ nn)
                base = wa * self.base[s_, a] + wb * self.base[s_, a + 1] + self._const[s_, k]
                W.append(w)
                w0.append(float(nn @ base - nn @ c[s_, k] - SEGMENT_CLEARANCE))
        if not W:
            return np.zeros((0, nz)), np.zeros(0)
        return np.array(W), np.array(w0)

    def pull_in(self, loc: np.ndarray, reach: float = TRUST_START, zmin: np.ndarray | None = None) -> np.ndarray:
        """Fixed points farther from their own bone than ``POINT_MAX + reach`` (out of one round's
        reach) moved along the bone's normal to ``POINT_MAX`` − 2 mm, points nearer than ``POINT_MIN``
        (or inside it) to ``POINT_MIN`` + 2 mm; the others unchanged. ``zmin`` (per point, ``-inf``:
        none; :attr:`optimize.problem.ActuatorProblem.zmin`) also moves points with a smaller body-frame
        z to ``zmin`` + 2 mm (room for the left copy), alternating with the band until both hold."""
        out = np.array(loc, float, copy=True)
        for i, pt in enumerate(self.pam.points):
            if not self.has_mesh[i]:
                continue
            lo = -np.inf if zmin is None else float(zmin[i])
            far = POINT_MAX + reach
            for _ in range(PULL_ITERATIONS):
                d, c, n = self.bones.body_closest(pt.body, out[i][None])
                if d[0] > far:
                    out[i] = c[0] + (POINT_MAX - 0.002) * n[0]
                elif d[0] < POINT_MIN:
                    out[i] = c[0] + (POINT_MIN + 0.002) * n[0]
                elif out[i][2] >= lo - ZMIN_TOLERANCE:
                    break
                if out[i][2] < lo - ZMIN_TOLERANCE:
                    out[i][2] = lo + 0.002
                    far = POINT_MAX          # once moved off the midline, back onto the band proper
        return out

    def balls(self, loc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per route point: centre (closest point of its own bone to ``loc``) and radius
        ``POINT_MAX`` of the ball the point must stay in (a conservative bracket-distance bound:
        the distance to the bone is at most the distance to that surface point); radius ``inf``
        for moving points and bodies without a mesh."""
        c = np.zeros((self.n_points, 3))
        r = np.full(self.n_points, np.inf)
        for i, pt in enumerate(self.pam.points):
            if self.has_mesh[i]:
                _, ci, _ = self.bones.body_closest(pt.body, loc[i][None])
                c[i], r[i] = ci[0], POINT_MAX
        return c, r


def bone_check_poses(model, rom, pam, seed: int, n_random: int = N_RANDOM,
                     gait: bool = True, crossed: list[str] | None = None,
                     n_boundary: int = N_BOUNDARY) -> tuple[np.ndarray, int]:
    """Bone-check poses of one actuator: ``n_random`` random poses over every audited coordinate
    (stream :data:`BONE_STREAM`), the primary coordinate's 1-D sweep (others 0), with ``crossed``
    the range-of-motion corners of those coordinates and ``n_boundary`` boundary poses (each crossed
    coordinate at its lower limit, its upper limit or uniform, a third each) and, when the trial is
    available, the walking trial between its frames.

    The corners and boundary poses are there because uniform samples rarely reach the deep but narrow
    penetrations at the edge of the range (a hamstring's straight pelvis-tibia segment through the
    femur near full hip flexion, abduction and external rotation: 0.2 % of uniform poses, 6.2 mm deep in
    2000 of them, 10.4 mm at the range corners, 13.8 mm in 300 boundary poses).

    Returns:
        ``(q, n_right_only)``: the poses and how many of them (the first) move the right leg only.
    """


    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(BONE_STREAM, int(pam.id))))
    coords = [c for c in audit_coordinates(rom) if c in model.coordinates]
    q = poses_from_unit(model, rom, coords, rng.random((n_random, len(coords))))
    q1, _ = model.grid([pam.primary_coordinate], 15, rom=rom, base={c: 0.0 for c in model.coordinates})
    blocks = [q, q1]
    crossed = with_dependencies(model, rom, [c for c in (crossed or []) if c in model.coordinates])
    if crossed:
        blocks.append(corner_poses(model, rom, crossed, seed, pam.id))
        if n_boundary > 0:
            blocks.append(boundary_poses(model, rom, crossed, rng, n_boundary))
    n_right = sum(len(b) for b in blocks)
    if gait:
        blocks.append(gait_training_poses(model))
    return np.vstack(blocks), n_right


def point_contact_poses(model, bones, rom, pam, seed: int, n: int = N_POINT_CHECK,
                        clearance: float = SEGMENT_CLEARANCE, keep: int = POINT_CHECK_ADD) -> np.ndarray:
    """Poses where a fixed attachment point of ``pam`` (a solved route) comes nearer than ``clearance``
    [m] to a bone other than its own: of ``n`` random poses over every audited coordinate (the right
    leg and lumbar joints; stream :data:`BONE_STREAM`, apart from :func:`bone_check_poses`' draws), the
    ``keep`` closest, (k, n_coordinates) (k = 0: none). A point's own bone is the bracket rows' business.
    """


    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(BONE_STREAM, int(pam.id), 1)))
    coords = [c for c in audit_coordinates(rom) if c in model.coordinates]
    q = poses_from_unit(model, rom, coords, rng.random((n, len(coords))))
    kin = model.kinematics
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        state = kin.forward(q, warn_range=False)
        X, _ = PathSet(kin, ["route"], [pam.points]).point_positions(state)
    right = [b for b in bones.bodies if not b.endswith("_l")]
    worst = np.full(len(q), np.inf)
    for i, pt in enumerate(pam.points):
        if not hasattr(pt, "location"):
            continue
        d, _ = bones.signed_distance(state, X[:, i:i + 1], margin=clearance,
                                     bodies=[b for b in right if b != pt.body], prune=True)
        worst = np.minimum(worst, d[:, 0])
    near = np.flatnonzero(worst < clearance)
    return q[near[np.argsort(worst[near])][:keep]]


#: Bone violations [m] that the choice of the best round does not tell apart (the audit allows a segment
#: 2 mm into bone): a route 0.5 mm in with half the fit error beats a clear one (extensor digitorum longus).
VIOLATION_RESOLUTION = 0.001


def _violation_key(m: Measure) -> int:
    """The bone violation of a round in whole :data:`VIOLATION_RESOLUTION` steps (0: < 1 mm)."""
    return int(m.violation(0.0) // VIOLATION_RESOLUTION)


def stage_key(m: Measure, sol) -> tuple:
    """Order of bone-stage results: fewest bone violations first (whole millimetres), then the least PAM
    overlap, then the lowest objective."""
    return (_violation_key(m), round(m.pam_overlap(), 4), float(sol.objective))


def bone_stage(prob, sol, cuts: BoneCuts, rounds: int = 8, log=None, keep_start: bool = False,
               trust: float = TRUST_START, trust_max: float = TRUST_MAX, extra_rounds: int | None = None,
               give_up=None):
    """Move a solved route clear of bone, and of the obstacle PAM bodies if :meth:`BoneCuts.set_obstacles`
    gave any (sequential linearisation with a trust region).

    Each round linearises the clearance at the current route (:meth:`BoneCuts.measure`), solves the
    problem with these rows (elastic for segments, hard for points) and hard balls within the trust region (starting from the fitted route:
    the first round is always accepted), and measures the exact distances of the result. A round that
    lowers the merit (objective + penalty × exact violation, PAM overlaps weighted by ``PAM_WEIGHT``)
    is accepted and the region grows; otherwise the region halves and the round is repeated from the
    same route. Once clear, the rounds stop when the merit gains less than ``STOP_GAIN``; a clear route
    still gaining more when ``rounds`` are used up gets up to :data:`EXTRA_CLEAR_ROUNDS` more.

    Args:
        prob: The :class:`optimize.problem.ActuatorProblem` that gave ``sol``.
        sol: Its solution (feasible for the problem's own constraints).
        cuts: The actuator's :class:`BoneCuts`.
        rounds: Largest number of solves (but see :data:`EXTRA_CLEAR_ROUNDS`).
        log: Optional list receiving one line per round.
        keep_start: ``sol`` is itself a candidate (a warm start: a route already through these rounds in
            an earlier run): a round must lower the merit of ``sol`` to be accepted, and the result is
            ``sol`` unless a round beats it.
        trust: The first round's trust region (half-width per point coordinate) [m].
        trust_max: The largest trust region [m].
        extra_rounds: Rounds beyond ``rounds`` for a clear route still gaining (default
            :data:`EXTRA_CLEAR_ROUNDS`).
        give_up: Optional ``(previous, accepted) -> bool`` called after every accepted round after the
            first: True ends the rounds (a caller's target out of reach at the current pace).

    Returns:
        ``(solution, measure, rounds_info)``: the best accepted round — fewest bone violations
        first (in whole millimetres, :data:`VIOLATION_RESOLUTION`), then the least PAM overlap, then the
        lowest objective — among rounds feasible for the problem's own constraints
        (the input solution when none is), and its exact :class:`Measure`.
    """
    npt = cuts.n_points
    m0 = cuts.measure(np.array(sol.points))
    best, best_m = sol, m0
    best_key = stage_key(m0, sol)
    info = [{"round": 0, "violation_mm": round(1e3 * m0.violation(), 3), "objective": float(sol.objective)}]
    # the first round starts from the given route, its points outside the bracket band (or short of the
    # room for their left copy) moved onto it
    z = sol.z.copy()
    z[:3 * npt] = cuts.pull_in(np.array(sol.points), reach=0.0, zmin=prob.zmin).ravel()
    merit = np.inf                   # accept the first round
    merit_violation = np.inf
    if keep_start and sol.success:   # ... unless the start is a candidate itself
        merit = sol.objective + MERIT_PENALTY * m0.violation(PAM_WEIGHT)
        merit_violation = m0.violation()
    rho = trust
    gaining = False                  # the last round was accepted, clear of bone, and gained >= STOP_GAIN
    extra = EXTRA_CLEAR_ROUNDS if extra_rounds is None else extra_rounds
    previous = None                  # the last accepted round
    for r in range(rounds + extra):
        if r >= rounds and not gaining:
            break
        _, (W, w0) = cuts.measure(z[:3 * npt].reshape(npt, 3), with_rows=True)
        lbx, ubx = prob.lbx.copy(), prob.ubx.copy()
        zc = z[:3 * npt]
        lbx[:3 * npt] = np.maximum(np.minimum(lbx[:3 * npt], zc), zc - rho)
        ubx[:3 * npt] = np.minimum(np.maximum(ubx[:3 * npt], zc), zc + rho)
        z0 = np.clip(z, lbx, ubx)
        centres, radii = cuts.balls(zc.reshape(npt, 3))
        s, slack = prob.solve_with_rows(z0, sol.n_parallel, W, w0, lbx, ubx, centres, radii, hard_balls=True,
                                        hard_rows=cuts.n_point_rows)
        ms = cuts.measure(np.array(s.points))
        m_new = s.objective + MERIT_PENALTY * ms.violation(PAM_WEIGHT)
        accept = bool(s.success) and m_new < merit
        info.append({"round": r + 1, "rows": int(len(W)), "trust_mm": round(1e3 * rho, 2), "status": s.status,
                     "feasible": bool(s.success), "accepted": accept, "max_slack_mm": round(1e3 * slack, 3),
                     "violation_mm": round(1e3 * ms.violation(), 3), "objective": float(s.objective)})
        if log is not None:
            log.append(f"  bone round {r + 1}: {len(W)} rows, trust {1e3 * rho:.1f} mm, {s.status}, "
                       f"violation {1e3 * ms.violation():.2f} mm, objective {s.objective:.4g}"
                       f"{'' if accept else ' (rejected)'} ({s.seconds:.1f} s)")
        if accept:
            key = stage_key(ms, s)
            if not best.success or (best is sol and not keep_start) or key < best_key:
                best, best_m, best_key = s, ms, key
            step = float(np.max(np.abs(s.z[:3 * npt] - zc)))
            gain = (merit - m_new) / max(abs(merit), 1e-12) if np.isfinite(merit) else np.inf
            z, merit, merit_violation = s.z.copy(), m_new, ms.violation()
            rho = min(trust_max, 1.5 * rho) if step > 0.5 * rho else rho
            if merit_violation == 0.0 and (step < 1e-4 or gain < STOP_GAIN):
                break                # clear of bone, and the fit no longer improves
            if give_up is not None and previous is not None and give_up(previous, s):
                break
            previous = s
            gaining = merit_violation == 0.0
        else:
            gaining = False
            rho *= 0.5
            if rho < TRUST_MIN:
                break
    return best, best_m, info


#: Distances [m] outside the bone that :func:`push_out` tries, in this order, for a point left inside it.
PUSH_TARGETS = (POINT_MIN, 0.002, 0.001, 0.0005)
#: How far [m] :func:`push_out` may move the route's other points when the moved ones alone break a limit.
PUSH_REACH = 0.005


def push_out(prob, sol, cuts: BoneCuts):
    """The fixed points of ``sol`` inside their own bone (exact distance < 0; the rounds' point rows hold
    only in their linearisation, and a curved bone can leave a point just inside) moved out along the
    bone's normal (where that lands inside another of the body's meshes, along the shortest way out,
    :func:`exit_point`) to ``POINT_MIN`` or, where the problem's constraints fail there, to the nearer distances
    of :data:`PUSH_TARGETS` (where the problem's own constraints fail with the moved points, its resting
    and tendon lengths are solved again with the points fixed, and failing that the route's other points
    too, within :data:`PUSH_REACH`, with the bone rows and brackets of a round). A move is kept only when
    the problem's own constraints hold there, no point is inside its bone and the exact bone violation
    (points and segments) does not grow.

    Returns:
        ``(solution, measure, moved, outcome)``: the moved solution and its :class:`Measure`, or ``sol``
        and its own measure when nothing was inside or no move was kept; ``moved`` names the points that
        were inside (empty: none); ``outcome`` is ``"moved out to X mm"`` or ``"not moved out: ..."`` (why
        the nearest move was refused).
    """
    m0 = cuts.measure(np.array(sol.points, float))
    moved, why = [], ""
    for target in PUSH_TARGETS:
        s, m1, moved, why = _push_to(prob, sol, cuts, m0, target)
        if not moved:
            return sol, m0, [], ""
        if not why:
            return s, m1, moved, f"moved out to {1e3 * target:g} mm"
    return sol, m0, moved, f"not moved out (even to {1e3 * PUSH_TARGETS[-1]:g} mm: {why})"


#: Directions and step [m] of the search for the nearest way out of a bone (:func:`exit_point`).
EXIT_DIRECTIONS = 400
EXIT_STEP = 0.00025
EXIT_REACH = 0.025


def _sphere(n: int) -> np.ndarray:
    """``n`` near-uniform unit vectors (Fibonacci sphere)."""
    i = np.arange(n) + 0.5
    polar, azimuth = np.arccos(1.0 - 2.0 * i / n), np.pi * (1.0 + 5.0 ** 0.5) * i
    return np.c_[np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)]


def exit_point(bones, body: str, x: np.ndarray, target: float) -> np.ndarray | None:
    """The nearest point found to ``x`` (body frame [m]) at least ``target`` m outside ``body``'s bone,
    searched along :data:`EXIT_DIRECTIONS` rays in :data:`EXIT_STEP` steps up to :data:`EXIT_REACH`
    (``None`` when no ray gets there). A bone of several overlapping meshes (the pelvis halves and the
    sacrum) can hold a point whose nearest surface point is not the way out: there the move along the
    normal lands inside the other mesh."""
    steps = np.arange(1, int(round(EXIT_REACH / EXIT_STEP)) + 1) * EXIT_STEP
    dirs = _sphere(EXIT_DIRECTIONS)
    pts = x[None, None, :] + steps[None, :, None] * dirs[:, None, :]
    ok = (bones.body_signed_distance(body, pts.reshape(-1, 3)) >= target).reshape(len(dirs), len(steps))
    first = np.where(ok.any(axis=1), ok.argmax(axis=1), len(steps))
    j = int(np.argmin(first))
    return None if first[j] == len(steps) else x + steps[first[j]] * dirs[j]


def _push_to(prob, sol, cuts: BoneCuts, m0: Measure, target: float):
    """One :func:`push_out` attempt at ``target`` m: ``(solution, measure, moved names, why refused)``."""
    loc = np.array(sol.points, float)
    moved = []
    for i, pt in enumerate(cuts.pam.points):
        if not cuts.has_mesh[i]:
            continue
        d, c, n = cuts.bones.body_closest(pt.body, loc[i][None])
        if d[0] < 0:
            out = c[0] + target * n[0]
            if cuts.bones.body_signed_distance(pt.body, out[None])[0] < target - 1e-9:
                out = exit_point(cuts.bones, pt.body, loc[i], target)
                if out is None:
                    return sol, m0, [pt.name], f"no way out within {1e3 * EXIT_REACH:g} mm"
            loc[i] = out
            moved.append(pt.name)
    if not moved:
        return sol, m0, [], ""
    z = sol.z.copy()
    z[:3 * cuts.n_points] = loc.ravel()
    s = prob.evaluate(z, sol.n_parallel)
    if not s.success:        # the moved points fixed, the resting and tendon lengths solved again
        lbx, ubx = prob.lbx.copy(), prob.ubx.copy()
        lbx[:3 * cuts.n_points] = ubx[:3 * cuts.n_points] = loc.ravel()
        nz = len(z)
        s, _ = prob.solve_with_rows(z, sol.n_parallel, np.zeros((0, nz)), np.zeros(0), lbx, ubx)
    if not s.success:        # ... and the other points free within PUSH_REACH, with the bone rows of a round
        _, (W, w0) = cuts.measure(loc, with_rows=True)
        flat = loc.ravel()
        lbx, ubx = prob.lbx.copy(), prob.ubx.copy()
        lbx[:len(flat)], ubx[:len(flat)] = flat - PUSH_REACH, flat + PUSH_REACH
        for i, pt in enumerate(cuts.pam.points):
            if pt.name in moved:
                lbx[3 * i:3 * i + 3] = ubx[3 * i:3 * i + 3] = loc[i]
        centres, radii = cuts.balls(loc)
        s, _ = prob.solve_with_rows(s.z if np.all(np.isfinite(s.z)) else z, sol.n_parallel, W, w0, lbx, ubx,
                                    centres, radii, hard_balls=True)
        loc = np.array(s.points, float)
    m1 = cuts.measure(loc)
    still = [cuts.pam.points[i].name for i in range(cuts.n_points) if cuts.has_mesh[i]
             and cuts.bones.body_signed_distance(cuts.pam.points[i].body, loc[i][None])[0] < 0]
    if still:
        return sol, m0, moved, f"{', '.join(still)} still inside"
    if not (s.success and m1.violation(0.0) <= m0.violation(0.0)):
        worst = max(s.violations.items(), key=lambda kv: kv[1], default=("", 0.0))
        why = (f"{worst[0]} violated by {worst[1]:.3g}" if not s.success else
               f"bone violation {1e3 * m0.violation(0.0):.1f} -> {1e3 * m1.violation(0.0):.1f} mm")
        return sol, m0, moved, why
    s.status = sol.status
    return s, m1, moved, ""
