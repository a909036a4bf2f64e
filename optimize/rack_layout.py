"""Where every PAM body hangs: rack candidates on each PAM's host bones and one joint choice for all of them.

Every PAM is hung on a rack (:mod:`pamkin.robot.rack`) at one end of its route: the body lies along its host
bone (the host frame's y axis, towards the bone's middle), beside the route's end point, on brackets. The
candidates of a PAM (:func:`candidates`) vary the side of the bone (``angles`` around the axis), the
bracket height and the shift along the bone; a candidate is kept only where, over every pose sampled,

* its body (a capsule of the PAM's largest outer radius, :func:`pamkin.audit.assembly.body_radius`, and the
  PAM's resting length plus both fittings) keeps ``gap`` from every bone — its host's at one pose, since
  it is fixed there, the others at every pose;
* both brackets (anchor and guide) lie within ``bracket_max`` of the host's bone and outside it;
* the cable piece from the guide to the route's end clears the host's bone.

Two candidates of different PAMs conflict where their bodies come closer than ``gap`` at any pose (same
host: once; different hosts: over the poses; right against the mirrored left over the walking poses).
:func:`choose` then picks at most one candidate per PAM, no two in conflict, the most PAMs first and the
lowest brackets next: an integer program (HiGHS through :func:`scipy.optimize.milp`), all PAMs at once.
Lengths in metres.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_matrix
from scipy.sparse import vstack as sparse_vstack

from pamkin.audit.assembly import BODY_GAP_M, body_radius
from pamkin.human.bones import segment_distances
from pamkin.opensim.model_file import PathPoint
from pamkin.robot import festo
from pamkin.robot.biped import placements
from pamkin.robot.design import mirror_name
from pamkin.robot.pam_body import pam_capsules
from pamkin.robot.rack import RackMount, has_rack, rack_pam, route_end

#: Largest distance of a bracket (anchor, guide) from its bone [m] (issue: brackets up to 50 mm).
BRACKET_MAX_M = 0.05
#: Room left between the longest body (stretched to the pretension limit) and the guide pulley [m].
SLACK_M = 0.01
#: Spacing of the points along a body or cable checked against bone [m].
STEP_M = 0.005
#: Spacing of the points along a body checked against its own (host) bone [m]: finer, as it is checked once.
HOST_STEP_M = 0.002
#: Tilts [deg] of a body from its bone's shaft tried besides the shaft direction itself.
TILTS = ((6.0, 0.0), (-6.0, 0.0), (0.0, 6.0), (0.0, -6.0))
#: Relative optimality gap at which the integer program stops (a PAM placed is worth 1 against at most 0.1 for
#: its brackets: 1 % of the ~15-30 PAMs placed is below one PAM).
MIP_GAP = 0.01
#: Extra clearance a candidate keeps from the other bones at the sampled poses, for the poses between them [m].
MARGIN_M = 0.003


@dataclass
class Candidate:
    """One place for one PAM's body.

    Attributes:
        pam: Index of the PAM in the design.
        mount: The rack.
        radius: Body radius [m].
        a, b: (3,) ends of the piece the body may occupy, host frame (a: the anchor, b: the guide pulley) [m].
        bracket: The larger of the anchor's and the guide's distance from bone [m].
        route_end: (3,) the route's end point the guide turns the cable to (host frame) [m].
    """

    pam: int
    mount: RackMount
    radius: float
    a: np.ndarray
    b: np.ndarray
    bracket: float
    route_end: tuple = (0.0, 0.0, 0.0)


def _long_axis(V: np.ndarray) -> np.ndarray:
    """Unit principal axis of the largest spread of the points ``V`` (a bone's vertices): its shaft."""
    _, vec = np.linalg.eigh(np.cov((V - V.mean(axis=0)).T))
    return vec[:, -1] / np.linalg.norm(vec[:, -1])


def _tilted(u: np.ndarray, angle_deg: tuple[float, float]) -> np.ndarray:
    """``u`` turned by the two angles [deg] about the two axes completing it (:func:`_frame`)."""
    e1, e2 = _frame(u)
    a, b = np.radians(angle_deg)
    v = u + np.tan(a) * e1 + np.tan(b) * e2
    return v / np.linalg.norm(v)


def _frame(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``u`` to an orthonormal frame."""
    t = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    e1 = np.cross(u, t)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


def candidates(k: int, pam, end: str, bones, fitting: float, angles: int = 16,
               heights=(0.01, 0.02, 0.03, 0.045, 0.06, 0.08), shifts=(0.0, 0.04, 0.08),
               gap: float = BODY_GAP_M, bracket_max: float = BRACKET_MAX_M, both_ways: bool = True
               ) -> list[Candidate]:
    """Rack candidates of PAM ``k`` at its route's ``end`` passing the host-frame checks of the module
    docstring (the pose-dependent ones: :func:`keep_clear`). ``heights``: offsets of the guide from the route's
    end point across the body's direction [m]; ``shifts``: along it [m]; the body runs from the guide along the
    host bone's shaft (the principal axis of its mesh's vertices) towards the bone's middle, or tilted from it by
    :data:`TILTS`, and, with ``both_ways``, the other way and along the host frame's axes across the shaft too
    (the checks keep the ones that fit)."""
    g = route_end(pam, end)
    if type(g) is not PathPoint or not bones.meshes.get(g.body):
        return []
    host, G = g.body, np.asarray(g.location, float)
    V = np.concatenate([m.vertices for m in bones.meshes[host]])
    shaft = _long_axis(V)
    towards = shaft if np.dot(V.mean(axis=0) - G, shaft) > 0 else -shaft
    r = body_radius(pam.diameter_mm, pam.n_parallel)
    # the longest the body gets (stretched to Festo's pretension limit) plus both fittings
    length = pam.resting_length_m * (1.0 + festo.max_pretension(pam.diameter_mm)) + 2 * fitting
    axes = [towards] + [_tilted(towards, t) for t in TILTS]
    if both_ways:
        axes += [-towards] + [s * e for e in np.eye(3) for s in (1.0, -1.0) if abs(np.dot(e, shaft)) < 0.9]
    out = []
    for u in axes:
        out += _ring(k, end, host, G, u, r, length, bones, angles, heights, shifts, gap, bracket_max)
    return out


def _ring(k, end, host, G, u, r, length, bones, angles, heights, shifts, gap, bracket_max) -> list[Candidate]:
    """The candidates of one direction ``u`` along the host bone (:func:`candidates`); every placement of the
    ring checked at once (:func:`_host_checks`)."""
    e1, e2 = _frame(u)
    phi = np.linspace(0.0, 2 * np.pi, angles, endpoint=False)
    w = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2                     # (angles, 3)
    h, sh = np.meshgrid(np.asarray(heights, float), np.asarray(shifts, float), indexing="ij")
    # guides in the order angle, height, shift; the anchor one body (+ slack) along u from its guide
    guide = (G + w[:, None, None, :] * h[None, :, :, None] + sh[None, :, :, None] * u).reshape(-1, 3)
    anchor = guide + (length + SLACK_M) * u
    bracket = _host_checks(bones, host, G, guide, anchor, r, gap, bracket_max)
    # the body may reach the guide pulley (never past it): the whole anchor-guide piece must clear
    return [Candidate(k, RackMount(end, host, tuple(anchor[i]), tuple(guide[i])), r, anchor[i], guide[i],
                      float(bracket[i]), tuple(G)) for i in np.flatnonzero(np.isfinite(bracket))]


def _host_checks(bones, host, G, guide, anchor, r, gap, bracket_max) -> np.ndarray:
    """(M,) bracket height [m] of each placement (``guide``, ``anchor``: (M, 3)) passing its host-frame checks
    (both brackets outside the bone and within ``bracket_max`` of it, the anchor-guide piece ``r + gap`` clear
    of it, the cable from the guide to the route end ``G`` out of it), +inf where it fails."""
    M = len(guide)
    out = np.full(M, np.inf)
    d_br = bones.body_closest(host, np.vstack([anchor, guide]))[0].reshape(2, M)
    ok = np.all((d_br > 0) & (d_br <= bracket_max), axis=0)
    idx = np.flatnonzero(ok)
    if len(idx):
        body = _segment_points(anchor[idx], guide[idx], HOST_STEP_M)
        d = bones.body_closest(host, body.reshape(-1, 3), far=r + gap + 0.01)[0].reshape(len(idx), -1)
        idx = idx[d.min(axis=1) >= r + gap]
    if len(idx):
        cable = _segment_points(guide[idx], np.repeat(np.asarray(G, float)[None], len(idx), 0), STEP_M)[:, 1:-1]
        if cable.shape[1]:
            d = bones.body_closest(host, cable.reshape(-1, 3), far=0.01)[0].reshape(len(idx), -1)
            idx = idx[d.min(axis=1) >= 0.001]
    out[idx] = np.max(d_br[:, idx], axis=0)
    return out


def _segment_points(A: np.ndarray, B: np.ndarray, step: float) -> np.ndarray:
    """(M, K, 3) points every ``step`` or closer from each ``A`` to its ``B`` ((M, 3) each), the same K for
    all (the longest segment's count)."""
    n = max(2, int(np.ceil(np.max(np.linalg.norm(B - A, axis=1), initial=0.0) / step)) + 1)
    t = np.linspace(0.0, 1.0, n)
    return A[:, None] + t[None, :, None] * (B - A)[:, None]


def world(cands: list[Candidate], state, kin) -> tuple[np.ndarray, np.ndarray]:
    """(S, C, 3) world positions of the candidates' axis ends at the poses of ``state``."""
    idx = np.array([kin.frames.index(c.mount.host) for c in cands])
    A = np.stack([c.a for c in cands])
    B = np.stack([c.b for c in cands])
    R, p = state.body_R[:, idx], state.body_p[:, idx]
    return np.einsum("scij,cj->sci", R, A) + p, np.einsum("scij,cj->sci", R, B) + p


def keep_clear(cands: list[Candidate], bones, state, kin, gap: float = BODY_GAP_M,
               bodies: list[str] | None = None, margin: float = MARGIN_M) -> list[Candidate]:
    """The candidates whose bodies keep ``gap + margin`` from every bone but their host's, and whose cable piece
    (guide → route end) stays out of them, at every pose of ``state``."""
    if not cands:
        return []
    Aw, Bw = world(cands, state, kin)
    Gw, Ew = world([dataclasses.replace(c, a=np.asarray(c.mount.guide), b=_end_point(c)) for c in cands], state, kin)
    keep = []
    for i, c in enumerate(cands):
        others = [b for b in (bodies or bones.bodies) if b != c.mount.host]
        P = _segment_points(Aw[:, i], Bw[:, i], STEP_M)
        d = bones.signed_distance(state, P, margin=c.radius + gap + margin + 0.01, bodies=others, prune=True)[0]
        if np.min(d) < c.radius + gap + margin:
            continue
        C = _segment_points(Gw[:, i], Ew[:, i], STEP_M)[:, 1:-1]
        if C.shape[1] and np.min(bones.signed_distance(state, C, margin=0.01, bodies=others, prune=True)[0]) < 0.001:
            continue
        keep.append(c)
    return keep


def _end_point(c: Candidate) -> np.ndarray:
    """The route end point a candidate's guide turns the cable to (host frame)."""
    return np.asarray(c.route_end, float)


def conflicts(cands: list[Candidate], states: list, kin, gap: float = BODY_GAP_M,
              mirrored: tuple | None = None) -> np.ndarray:
    """(P, 2) index pairs of candidates (of different PAMs) whose bodies come closer than ``gap``: same host
    in the host frame, else over the poses of every state in ``states``; ``mirrored`` = (state, mirror
    function) adds right-against-left pairs (a candidate against every mirrored one, its own included)."""
    C = len(cands)
    if C == 0:
        return np.zeros((0, 2), int)
    pam = np.array([c.pam for c in cands])
    rad = np.array([c.radius for c in cands])
    i, j = np.triu_indices(C, 1)
    keep = pam[i] != pam[j]
    i, j = i[keep], j[keep]
    host = np.array([c.mount.host for c in cands])
    same = host[i] == host[j]                      # fixed to each other: one check in the host frame
    A, B = np.stack([c.a for c in cands]), np.stack([c.b for c in cands])
    d = segment_distances(A[i[same]], B[i[same]], A[j[same]], B[j[same]])
    close = np.zeros(len(i), dtype=bool)
    close[np.flatnonzero(same)[d < rad[i[same]] + rad[j[same]] + gap]] = True
    for st in states:
        Aw, Bw = world(cands, st, kin)
        for s in range(len(Aw)):
            todo = np.flatnonzero(~close & ~same)
            close[todo[_near(Aw[s], Bw[s], i[todo], j[todo], rad[i[todo]] + rad[j[todo]] + gap)]] = True
    out = [np.stack([i[close], j[close]], axis=1)]
    if mirrored is not None:
        st, mirror = mirrored
        left = [mirror(c) for c in cands]
        Ar, Br = world(cands, st, kin)
        Al, Bl = world(left, st, kin)
        ii, jj = np.meshgrid(np.arange(C), np.arange(C), indexing="ij")
        ii, jj = ii.ravel(), jj.ravel()
        hit = np.zeros(len(ii), dtype=bool)
        for s in range(len(Ar)):
            todo = np.flatnonzero(~hit)
            W = (np.concatenate([Ar[s], Al[s]]), np.concatenate([Br[s], Bl[s]]))
            hit[todo[_near(*W, ii[todo], C + jj[todo], rad[ii[todo]] + rad[jj[todo]] + gap)]] = True
        out.append(np.stack([ii[hit], jj[hit]], axis=1))
    return np.concatenate(out) if out else np.zeros((0, 2), int)


def _near(A: np.ndarray, B: np.ndarray, i: np.ndarray, j: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Whether segments ``i`` and ``j`` of (A, B) ((N, 3) ends) come closer than ``limit``: the exact distance
    only where their bounding spheres (centre the midpoint, radius half the length) do."""
    M, h = 0.5 * (A + B), 0.5 * np.linalg.norm(B - A, axis=1)
    out = np.linalg.norm(M[i] - M[j], axis=1) - h[i] - h[j] < limit
    k = np.flatnonzero(out)
    out[k] = segment_distances(A[i[k]], B[i[k]], A[j[k]], B[j[k]]) < limit[k]
    return out


def choose(cands: list[Candidate], pairs: np.ndarray, n_pams: int, time_limit: float = 120.0
           ) -> dict[int, Candidate]:
    """At most one candidate per PAM, no conflicting pair (``pairs`` from :func:`conflicts`; a pair of a
    candidate with itself forbids it), the most PAMs placed and, among those, the lowest brackets:
    ``{pam index: candidate}``."""
    C = len(cands)
    if C == 0:
        return {}
    self_hit = pairs[:, 0] == pairs[:, 1]
    ub = np.ones(C)
    ub[pairs[self_hit, 0]] = 0.0
    pairs = pairs[~self_hit]
    pams = np.array([c.pam for c in cands])
    rows = [coo_matrix((np.ones(C), (pams, np.arange(C))), shape=(n_pams, C))]
    if len(pairs):
        P = len(pairs)
        rows.append(coo_matrix((np.ones(2 * P), (np.repeat(np.arange(P), 2), pairs.ravel())), shape=(P, C)))
    A = sparse_vstack(rows).tocsr()
    bracket = np.array([c.bracket for c in cands])
    cost = -1.0 + 0.1 * bracket / BRACKET_MAX_M
    res = milp(cost, constraints=LinearConstraint(A, -np.inf, 1.0), integrality=np.ones(C),
               bounds=Bounds(0.0, ub), options={"time_limit": time_limit, "mip_rel_gap": MIP_GAP})
    greedy = _greedy(cands, pairs, ub)
    if res.x is None or np.sum(res.x > 0.5) < len(greedy):     # no solution within the time limit
        return greedy
    return {cands[c].pam: cands[c] for c in np.flatnonzero(res.x > 0.5)}


def _greedy(cands: list[Candidate], pairs: np.ndarray, ub: np.ndarray) -> dict[int, Candidate]:
    """A conflict-free choice without the integer program: PAMs with the fewest candidates first, each its
    lowest-bracket candidate that conflicts with none chosen (the fallback where HiGHS finds no solution in
    its time limit)."""
    C = len(cands)
    nbr = [[] for _ in range(C)]
    for a, b in pairs:
        nbr[a].append(b)
        nbr[b].append(a)
    count = np.bincount([c.pam for c in cands])
    order = sorted(range(C), key=lambda c: (count[cands[c].pam], cands[c].bracket))
    taken, blocked, out = set(), np.zeros(C, dtype=bool), {}
    for c in order:
        p = cands[c].pam
        if p in taken or blocked[c] or ub[c] == 0:
            continue
        taken.add(p)
        out[p] = cands[c]
        blocked[nbr[c]] = True
    return out


@dataclass
class RackReport:
    """What :func:`layout` did: the PAMs hung on racks ``{pam id: candidate}``, the ones left on their routes
    (no candidate, or every candidate in conflict), the candidates and conflicts counted, the rounds, and
    per PAM left on its route why (``reasons``: {pam id: text}, :func:`why_left`)."""

    placed: dict
    unplaced: list[int]
    candidates: int
    conflicts: int
    rounds: int
    reasons: dict = dataclasses.field(default_factory=dict)


def why_left(counts: tuple[int, int, int, int]) -> str:
    """Why a PAM found no rack, from its candidate counts: on its bones, of them clear of the other bones at
    the stage's poses, of them clear of the bodies left on their routes, of them passing the check at more
    poses (as far as it went)."""
    on_bone, clear, free, checked = counts
    if on_bone == 0:
        return "no place on the bones of its route's ends (too long or too thick for their room)"
    if clear == 0:
        return f"{on_bone} places on its bones, none clear of the other bones at every pose"
    if free == 0:
        return f"{clear} places clear of bone, none clear of the bodies left on their routes"
    if checked == 0:
        return f"{free} places, none clear of the other bones at the check poses"
    return f"{checked} places, each in conflict with a chosen rack"


def mirror_candidate(c: Candidate) -> Candidate:
    """The left side's copy of a right-side candidate (host mirrored, z negated)."""
    def f(v):
        return np.array([v[0], v[1], -v[2]], float)
    m = RackMount(c.mount.end, mirror_name(c.mount.host), tuple(f(c.mount.anchor)), tuple(f(c.mount.guide)))
    return Candidate(c.pam, m, c.radius, f(c.a), f(c.b), c.bracket, tuple(f(c.route_end)))


def _route_bodies(design, model, q: np.ndarray) -> list[list]:
    """Per PAM the body pieces on its route (as the audit places them) at poses ``q``."""
    out = []
    for (place, pts, length) in placements(design, model, q):
        out.append(pam_capsules(pts, place.segment, length + 2 * design.fitting_length_m, place.side))
    return out


def _checked(pick: dict, pool: list[Candidate], pairs: np.ndarray, bones, kin, q: np.ndarray, gap: float,
             right: list[str], n_pams: int, time_limit: float, tries: int = 5):
    """``pick`` checked at the poses ``q`` (right-leg bones): where a chosen candidate comes too close to another
    bone there, every candidate of its PAM is checked there too, the failing ones leave the pool and the choice
    is made again, until every chosen one passes (at most ``tries`` times; what still fails is dropped from the
    choice). Returns (pick, pool, pairs)."""
    st = kin.forward(q, warn_range=False)
    passed: set[int] = set()                      # ids of the candidates checked at q and passing

    def check(cands: list[Candidate]) -> list[Candidate]:
        todo = [c for c in cands if id(c) not in passed]
        passed.update(id(c) for c in keep_clear(todo, bones, st, kin, gap, right))
        return [c for c in cands if id(c) not in passed]

    for _ in range(tries):
        bad = check(list(pick.values()))
        if not bad:
            return pick, pool, pairs
        failing = {c.pam for c in bad}
        dropped = {id(c) for c in check([c for c in pool if c.pam in failing])}
        pool, pairs = _subset(pool, pairs, [c for c in pool if id(c) not in dropped])
        pick = choose(pool, pairs, n_pams, time_limit)
    bad = {id(c) for c in check(list(pick.values()))}
    return {k: c for k, c in pick.items() if id(c) not in bad}, pool, pairs


def _drop_near(pool: list[Candidate], pairs: np.ndarray, design, model, q: np.ndarray, obstacles: list[int],
               gap: float) -> tuple[list[Candidate], np.ndarray]:
    """``pool`` without the candidates closer than ``gap`` to the bodies of the PAMs ``obstacles`` (indices)
    where they are at poses ``q``, and ``pairs`` renumbered for it."""
    if not obstacles or not pool:
        return pool, pairs
    bodies = _route_bodies(design, model, q)
    radii = [body_radius(p.diameter_mm, p.n_parallel) for p in design.pams]
    st = model.kinematics.forward(q, warn_range=False)
    kept = _clear_of(pool, [bodies[k] for k in obstacles], [radii[k] for k in obstacles], st, model.kinematics, gap)
    return _subset(pool, pairs, kept)


def _subset(pool: list[Candidate], pairs: np.ndarray, kept: list[Candidate]) -> tuple[list[Candidate], np.ndarray]:
    """``kept`` (a sub-list of ``pool``, same order) and the conflict ``pairs`` among them, renumbered."""
    index = {id(c): i for i, c in enumerate(pool)}
    remap = np.full(len(pool), -1)
    remap[[index[id(c)] for c in kept]] = np.arange(len(kept))
    if not len(pairs):
        return kept, pairs
    pairs = remap[pairs]
    return kept, pairs[(pairs >= 0).all(axis=1)]


def _clear_of(cands: list[Candidate], pieces: list, radii: list[float], state, kin, gap: float) -> list[Candidate]:
    """The candidates that keep ``gap`` from every body of ``pieces`` (route bodies at the poses of ``state``)."""
    if not cands or not pieces:
        return cands
    Aw, Bw = world(cands, state, kin)
    ok = np.ones(len(cands), dtype=bool)
    for body, r in zip(pieces, radii):
        for A, B, valid in body:
            for s in np.flatnonzero(valid):
                d = segment_distances(Aw[s], Bw[s], np.repeat(A[s][None], len(cands), 0),
                                      np.repeat(B[s][None], len(cands), 0))
                ok &= d >= np.array([c.radius for c in cands]) + r + gap
    return [c for c, k in zip(cands, ok) if k]


def layout(design, model, bones, q_random: np.ndarray, q_gait: np.ndarray, gap: float = BODY_GAP_M,
           bracket_max: float = BRACKET_MAX_M, angles: int = 16, time_limit: float = 120.0, rounds: int = 1,
           movable: set[int] | None = None, q_check: np.ndarray | None = None, say=None):
    """Every PAM of ``design`` hung on the rack :func:`choose` gives it, the others left on their routes:
    ``(new design, RackReport)``. Candidates (:func:`candidates`) are checked at the random poses (right-leg
    bones) and the walking poses (every bone); conflicts over both, right against left over the walking
    poses. Only the PAMs whose ids are in ``movable`` (default: all) and that hang on no rack yet get
    candidates; the others are obstacles where they are (candidates closer than ``gap`` to their bodies are
    dropped). ``q_check``: more random poses on which the chosen racks are checked again against the other bones
    (:func:`keep_clear`); a chosen candidate that fails there is dropped and the choice made again. With
    ``rounds`` > 1 the PAMs left on their routes become obstacles too and the choice is made
    again (at most ``rounds`` times; it places fewer PAMs)."""
    kin = model.kinematics
    st, sg = kin.forward(q_random, warn_range=False), kin.forward(q_gait, warn_range=False)
    right = [b for b in bones.bodies if not b.endswith("_l")]
    moving = [k for k, p in enumerate(design.pams) if (movable is None or p.id in movable) and not has_rack(p)]
    pool, on_bone = [], {k: 0 for k in moving}
    for k in moving:
        for end in ("origin", "insertion"):
            c = candidates(k, design.pams[k], end, bones, design.fitting_length_m, angles=angles, gap=gap,
                           bracket_max=bracket_max)
            on_bone[k] += len(c)
            c = keep_clear(c, bones, st, kin, gap, right)
            pool += keep_clear(c, bones, sg, kin, gap) if len(q_gait) else c
    clear = {k: sum(c.pam == k for c in pool) for k in moving}
    if say:
        say(f"rack: {len(pool)} candidates for {len({c.pam for c in pool})} of {len(moving)} PAMs")
    states = [st, sg] if len(q_gait) else [st]
    pairs = conflicts(pool, states, kin, gap, mirrored=(sg, mirror_candidate) if len(q_gait) else None)
    n_pairs = len(pairs)
    q_all = np.vstack([q_random, q_gait])
    fixed = [k for k in range(len(design.pams)) if k not in moving]
    pool, pairs = _drop_near(pool, pairs, design, model, q_all, fixed, gap)
    free = {k: sum(c.pam == k for c in pool) for k in moving}
    pick, done = {}, 0
    for done in range(1, rounds + 1):
        pick = choose(pool, pairs, len(design.pams), time_limit)
        if q_check is not None and len(q_check):
            pick, pool, pairs = _checked(pick, pool, pairs, bones, kin, q_check, gap, right, len(design.pams),
                                         time_limit)
        left = [k for k in moving if k not in pick]
        if not left or done == rounds:
            break
        n = len(pool)
        pool, pairs = _drop_near(pool, pairs, design, model, q_all, left, gap)
        if len(pool) == n:
            break
    new = design
    for k, c in pick.items():
        new = new.replace_pam(rack_pam(design.pams[k], c.mount))
    placed = {design.pams[k].id: c for k, c in pick.items()}
    unplaced = [design.pams[k].id for k in moving if k not in pick]
    remaining = {k: sum(c.pam == k for c in pool) for k in moving}
    reasons = {design.pams[k].id: why_left((on_bone[k], clear[k], free[k], remaining[k])) for k in moving if k not in pick}
    return new, RackReport(placed, unplaced, len(pool), n_pairs, done, reasons)
