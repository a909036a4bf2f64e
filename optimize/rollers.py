"""The roller stage: cable guides where a straight route cannot clear bone and still fit.

The bone-mesh rounds keep every route segment out of bone at every bone-check pose; a straight segment
can do that only by moving away from the bone at every pose, and for some PAMs that costs most of their
fit (the segment goes through the femur or tibia only near the range's edge, or the human's own line runs
inside the bone). For an actuator whose result fails the audit's fit limits on the run's validation poses,
this stage

1. solves its problem again from its result without the bone-mesh rows (its attachment points stay on
   their bones within the bracket band; the segments may enter bone): the *bracket-only fit*;
2. puts a roller (:mod:`pamkin.robot.rollers`) on each segment of that fit that goes deeper than the audit's
   limit into a bone at the bone-check poses (not on the PAM's own segment): fixed in that bone at the
   deepest penetration, on the side the segment passes where it clears the bone, a gap off the surface,
   its axis across the segment (:func:`place`);
   An actuator with such a segment deeper than :data:`MAX_DEPTH` is left as it was;
3. solves with the rollers in the problem (:mod:`optimize.roller_model`), then the bone-mesh rounds
   (:func:`optimize.bone_cuts.bone_stage`; the straight pieces before and after each roller take the
   segment's rows), and checks the result exactly (OpenSim's wrapping, the bone meshes, every bone-check
   pose): every straight piece within the limit, every attachment point and roller outside its bone and
   within the bracket distance; a piece still too deep moves its roller out by half the depth (up to
   :data:`PLACE_ROUNDS` rounds), unless the fit with the rollers is already no better than the result's.
   In the problem a roller is open-ended (:data:`pamkin.robot.rollers.OPEN_LENGTH_M`: OpenSim drops a wrap whose
   tangent points pass beyond the cylinder's ends, a step in the route's length the fit could exploit; measured
   at 0.1.0-dev, internal oblique's 30 mm roller lost its cable at 29 % of random poses and most of its gain with
   it); after the solve it gets the shortest length
   on which the cable stays at every bone-check and validation pose (:func:`size_rollers`): a cable that
   would slip off a roller's end is a guide that fails, and its step in length a fit that is not real;
4. keeps the rollers where the validation error (primary NRMSE + worst coordinate error) falls by more than
   :data:`MIN_GAIN`; otherwise the result stays as it was.

Everything is measured on the optimiser's own poses (bone-check poses, validation stream); the audit
measures on its own held-out ones.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
from pamkin.optimize.bone_cuts import right_only_query
from pamkin.optimize.roller_model import RollerData

from pamkin.errors import RangeWarning
from pamkin.human.paths import PathSet
from pamkin.opensim.model_file import MovingPathPoint
from pamkin.robot.biped import PamRobot
from pamkin.robot.design import Design, Pam
from pamkin.robot.pam_body import route_positions
from pamkin.robot.rollers import Roller, open_ended, roller_axis_points, roller_world

#: Roller radius [m].
RADIUS = 0.005
#: Roller length along its axis [m].
LENGTH = 0.03
#: Gap between the roller's surface and the bone at its first placement [m].
GAP = 0.003
#: Placement rounds: a roller whose pieces still go too deep moves out by half that depth.
PLACE_ROUNDS = 2
#: Segments of the bracket-only fit deeper than this into bone get no roller (the actuator is left as it
#: was): a roller there moves the cable too far from the fit's line (measured on the default run: every
#: actuator with a deeper segment lost its fit with a roller, or found no clear route; those up to it: one
#: gained, one did not).
MAX_DEPTH = 0.006
#: Deepest a straight piece may go into bone at the bone-check poses [m] (the audit's limit is 2 mm).
DEPTH_LIMIT = 0.0015
#: Farthest a roller's surface may sit from its bone [m] (the audit's bracket limit is 20 mm).
ROLLER_BRACKET = 0.018
#: A result with rollers is kept where it lowers the validation error (NRMSE + worst) by more than this.
MIN_GAIN = 0.02
#: Test points along each straight piece (every this many metres) for the exact bone check.
STEP = 0.003
#: Roller lengths [m] tried after the solve, shortest first (:func:`size_rollers`).
LENGTHS = (0.03, 0.04, 0.05, 0.06, 0.08, 0.1)


def roller_data(data, model, roller: Roller, segment: int) -> RollerData:
    """The numbers of ``roller`` (on route segment ``segment``) at the problem's samples ``data.q``."""
    kin = model.kinematics
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st = kin.forward(data.q, warn_range=False)
    b = kin.frames.index(roller.body)
    R, c = roller_world(roller, st.body_R[:, b], st.body_p[:, b])
    W, T = PathSet(kin, ["route"], [data.pam.points]).body_jacobian(st)
    compared = sorted({c_ for c_, *_ in data.objective})
    omega = {c_: W[:, b, model.coordinates.index(c_)] for c_ in compared}
    tau = {c_: T[:, b, model.coordinates.index(c_)] for c_ in compared}
    return RollerData(segment, float(roller.radius_m), float(roller.length_m), R, c, omega, tau)


@dataclasses.dataclass
class Depths:
    """Exact bone check of one route (with its rollers) at a set of poses."""

    segment_depth: np.ndarray          # (n_segments,) deepest any straight piece of the segment goes [m]
    deepest: list                      # per segment: (pose index, world point, bone body) at its deepest, or None
    point_bone: np.ndarray             # (n_points,) own-bone signed distance of each fixed point [m] (nan: moving)
    roller_bone: np.ndarray            # (n_rollers,) own-bone distance of each roller's surface [m]

    def clear(self, limit: float = DEPTH_LIMIT, bracket: float = 0.02) -> bool:
        pts = self.point_bone[np.isfinite(self.point_bone)]
        return bool(np.all(self.segment_depth <= limit) and np.all(pts >= 0) and np.all(pts <= bracket)
                    and np.all(self.roller_bone >= 0) and np.all(self.roller_bone <= ROLLER_BRACKET))


def depths(pam: Pam, model, bones, q: np.ndarray, design: Design, n_right_only: int = 0) -> Depths:
    """Deepest penetration of every segment of ``pam``'s route (straight pieces around its rollers) into
    any bone at poses ``q`` — the first ``n_right_only`` of them move the right leg only and are tested
    against the right side's bones, as the audit's random poses — and the own-bone distances of its
    fixed points and rollers."""

    robot = PamRobot(Design("check", (pam,), design.pressure_Pa, design.force_model, design.fitting_length_m,
                            design.rom), model, sides=("r",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st = model.kinematics.forward(q, warn_range=False)
    pieces = robot.route_pieces(st, 0)
    n_seg = len(pieces)
    seg_depth = np.zeros(n_seg)
    deepest: list = [None] * n_seg
    for j, seg in enumerate(pieces):
        for A, B in seg:
            L = float(np.max(np.linalg.norm(B - A, axis=1)))
            t = np.linspace(0.0, 1.0, max(3, int(np.ceil(L / STEP)) + 1))
            P = A[:, None, :] + t[None, :, None] * (B - A)[:, None, :]
            d, near = right_only_query(bones.signed_distance, st, P, n_right_only, margin=0.0, prune=True)
            k = int(np.argmin(d))
            s, i = np.unravel_index(k, d.shape)
            if -d[s, i] > seg_depth[j]:
                seg_depth[j] = float(-d[s, i])
                deepest[j] = (int(s), P[s, i].copy(), bones.bodies[int(near[s, i])])
    point_bone = np.array([np.nan if isinstance(pt, MovingPathPoint) else
                           float(bones.body_signed_distance(pt.body, np.array([pt.location]))[0]) for pt in pam.points])
    roller_bone = np.array([float(np.min(bones.body_signed_distance(r.body, roller_axis_points(r)))) - r.radius_m
                            for r in pam.rollers])
    return Depths(seg_depth, deepest, point_bone, roller_bone)


def size_rollers(pam: Pam, model, q: np.ndarray, design: Design) -> Pam | None:
    """``pam`` with each roller the shortest of :data:`LENGTHS` (centred where it is) on which the cable never
    leaves it over an end at poses ``q``: the route as long as over an open-ended roller (:func:`pamkin.robot.rollers.open_ended`) at
    every pose (1e-9 m). None where even the longest loses the cable."""

    def lengths(p: Pam) -> np.ndarray:
        des = Design("size", (p,), design.pressure_Pa, design.force_model, design.fitting_length_m, design.rom)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            return PamRobot(des, model, sides=("r",)).evaluate(q).lengths[:, 0]

    rollers = list(open_ended(pam.rollers))
    target = lengths(dataclasses.replace(pam, rollers=tuple(rollers)))
    for i in range(len(rollers)):
        for ln in LENGTHS:
            trial = rollers[:i] + [dataclasses.replace(rollers[i], length_m=ln)] + rollers[i + 1:]
            if np.all(np.abs(lengths(dataclasses.replace(pam, rollers=tuple(trial))) - target) <= 1e-9):
                rollers = trial
                break
        else:
            return None
    return dataclasses.replace(pam, rollers=tuple(rollers))


def place(bones, model, q: np.ndarray, pam: Pam, j: int, hit: tuple, gap: float = GAP) -> Roller | None:
    """A roller for segment ``j`` of ``pam``'s route at its deepest penetration ``hit`` = (pose, world point,
    bone): fixed in that bone on the side the segment passes at the poses where it clears that bone (the
    mean direction, across the segment, from the deepest point to the segment at those poses; the bone's
    surface normal where it never clears it), ``gap`` off the surface there, its axis across the segment
    and that side. None where no such side can be found."""

    s, x, body = hit
    kin = model.kinematics
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st = kin.forward(q, warn_range=False)
    b = kin.frames.index(body)
    Rb, pb = st.body_R[:, b], st.body_p[:, b]
    xl = Rb[s].T @ (x - pb[s])
    robot = PamRobot(Design("place", (dataclasses.replace(pam, rollers=()),)), model, sides=("r",))
    pts = route_positions(robot.paths, st, 0)
    A = np.einsum("sji,sj->si", Rb, pts[:, j] - pb)              # the segment in the bone's frame
    B = np.einsum("sji,sj->si", Rb, pts[:, j + 1] - pb)
    u = B[s] - A[s]
    u /= max(np.linalg.norm(u), 1e-12)
    # where the segment clears this bone: its closest point to the deepest one, seen from there
    t = np.linspace(0.0, 1.0, 41)
    P = A[:, None, :] + t[None, :, None] * (B - A)[:, None, :]
    d = bones.body_signed_distance(body, P.reshape(-1, 3)).reshape(len(q), len(t))
    clear = d.min(axis=1) > gap
    n = None
    if clear.any():
        D = A[clear] - xl
        seg = B[clear] - A[clear]
        tt = np.clip(-np.einsum("si,si->s", D, seg) / np.maximum(np.einsum("si,si->s", seg, seg), 1e-18), 0, 1)
        v = D + tt[:, None] * seg
        v = v - np.outer(v @ u, u)
        n = v.mean(axis=0)
        n = n / np.linalg.norm(n) if np.linalg.norm(n) > 1e-9 else None
    if n is None:
        _, _, N = bones.body_closest(body, xl[None])
        n = N[0] / max(np.linalg.norm(N[0]), 1e-12)
    axis = np.cross(u, n)
    if np.linalg.norm(axis) < 1e-6:
        return None
    axis /= np.linalg.norm(axis)
    side = n - (n @ axis) * axis
    side /= np.linalg.norm(side)
    # out of the bone along that side, then the roller's surface a gap off it along its whole length
    steps = np.arange(0.0, 0.08, 0.0005)
    dd = bones.body_signed_distance(body, xl[None, :] + steps[:, None] * side[None, :])
    outside = np.flatnonzero(dd >= 0)
    if not len(outside):
        return None
    name = f"{pam.points[j].name}->{pam.points[j + 1].name}"
    rol = Roller(name, body, tuple(float(v) for v in xl + steps[outside[0]] * side + (gap + RADIUS) * side),
                 tuple(float(v) for v in axis), tuple(float(v) for v in side), RADIUS, LENGTH)
    for _ in range(4):     # the whole roller a gap off the bone: further out where the bone rises
        room = float(np.min(bones.body_signed_distance(body, roller_axis_points(rol)))) - RADIUS
        if room >= gap - 1e-4:
            break
        rol = dataclasses.replace(rol, centre=tuple(float(c + (gap - room + 1e-4) * s_)
                                                    for c, s_ in zip(rol.centre, side)))
    return rol
