"""Bone geometry: the model's bone meshes and signed distances to them.

Every mesh the model names (OpenSim ``<Mesh>`` geometry, with its scale factors and frame) is
read from the model's Geometry folder (:func:`pamkin.opensim.vtp.body_meshes`) and kept in its body's
frame. Signed distances are libigl's ``signed_distance`` with the *fast winding number* sign (its AABB
tree and winding-number hierarchy built once per mesh)
(robust for the open meshes Gait2392 ships: half pelvis, foot, spine), **negative inside bone**.
The distance to a body's bone is the minimum over that body's meshes (the union of them).
Queries that only need distances up to a margin can skip the points a coarse grid of exact distances
proves farther than it (``prune=True``, :meth:`BoneSet.far_from`): every distance up to the margin is
unchanged.

Distances between PAM bodies (capsules) use coal (hpp-fcl), Pinocchio's collision library.
"""

from __future__ import annotations

import functools
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pamkin._resources import DEFAULT_GEOMETRY
from pamkin.errors import DataFileError
from pamkin.opensim.vtp import MeshWarning, body_meshes

#: Spacing [m] of the coarse grid of exact distances that proves points far from a bone
#: (:meth:`BoneSet.far_from`; a point is at most ``PRUNE_STEP * sqrt(3) / 2`` from its node).
PRUNE_STEP = 0.004
#: The grid covers each bone's bounding box and this much more on every side [m].
PRUNE_PAD = 0.03
#: Margin [m] within which a numpy segment distance is confirmed with coal before it decides an overlap.
OVERLAP_GUARD = 1e-6


def find_geometry_dir(model, geometry_dir: str | os.PathLike | None = None) -> Path:
    """The folder holding a model's ``.vtp`` bone meshes.

    Search order: ``geometry_dir``; ``$PAMKIN_GEOMETRY``; ``Geometry`` beside the model file and
    one level up (as OpenSim looks for it, and as opensim-models lays it out); the reference
    data folder ``../shared/opensim-models/Geometry`` of a checkout (the built-in Gait2392).

    Raises:
        DataFileError: No folder holds the first mesh the model names.
    """
    names = [g.mesh_file for b in model.osim.bodies for g in b.meshes]
    if geometry_dir is not None:
        cands = [Path(geometry_dir)]
    else:
        cands = []
        if os.environ.get("PAMKIN_GEOMETRY"):
            cands.append(Path(os.environ["PAMKIN_GEOMETRY"]))
        src = Path(str(model.osim.path))
        cands += [src.parent / "Geometry", src.parent, src.parent.parent / "Geometry", DEFAULT_GEOMETRY]
        if getattr(model.osim, "source_osim", None):
            s = Path(model.osim.source_osim)
            cands = [s.parent / "Geometry", s.parent.parent / "Geometry", *cands]
    for c in cands:
        if c.is_dir() and (not names or (c / names[0]).is_file()):
            return c
    raise DataFileError(str(cands[0]) if cands else "<geometry>",
                        f"no folder with the model's bone meshes ({names[:3]}...) among "
                        f"{[str(c) for c in cands]}; give --geometry DIR (OpenSim's Geometry folder) "
                        "or set $PAMKIN_GEOMETRY")


@dataclass(frozen=True)
class BoneMesh:
    """One body's bone surface: vertices (V, 3) [m] in the body frame, triangles (F, 3)."""

    body: str
    vertices: np.ndarray
    faces: np.ndarray
    files: tuple[str, ...]

    @functools.cached_property
    def closed(self) -> bool:
        """Whether the surface is closed and consistently oriented: every directed edge of a triangle
        appears once and its reverse once (then points that no surface separates are on the same
        side of it, inside or outside)."""
        f = self.faces
        e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        directed = np.unique(e, axis=0)
        if len(directed) != len(e):
            return False
        rev = {tuple(x) for x in directed[:, ::-1].tolist()}
        return rev == {tuple(x) for x in directed.tolist()}


class BoneSet:
    """The bone meshes of a model, per body, with signed-distance queries.

    Args:
        model: A :class:`pamkin.Model` (its ``osim`` names the meshes).
        geometry_dir: Folder of the ``.vtp`` files (default: :func:`find_geometry_dir`).
    """

    def __init__(self, model, geometry_dir: str | os.PathLike | None = None) -> None:

        self.geometry_dir = find_geometry_dir(model, geometry_dir)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MeshWarning)
            meshes = body_meshes(model, self.geometry_dir)
        self.model = model
        self.meshes: dict[str, list[BoneMesh]] = {}
        for body, ms in meshes.items():
            files = [g.mesh_file for b in model.osim.bodies if b.name == body for g in b.meshes]
            self.meshes[body] = [BoneMesh(body, np.ascontiguousarray(m.vertices, dtype=np.float64),
                                          np.ascontiguousarray(m.faces, dtype=np.int64), (f,))
                                 for m, f in zip(ms, files)]
        self.bodies = [b for b, ms in self.meshes.items() if ms]
        self._box = {b: (np.min([m.vertices.min(0) for m in ms], axis=0), np.max([m.vertices.max(0) for m in ms], axis=0))
                     for b, ms in self.meshes.items() if ms}

    @classmethod
    def from_meshes(cls, model, meshes: dict[str, list]) -> BoneSet:
        """A bone set from given meshes (``{body: [(vertices (V, 3), faces (F, 3)), ...]}`` in body
        frames [m]) instead of the model's files; ``model`` gives the body order."""
        self = cls.__new__(cls)
        self.geometry_dir = None
        self.model = model
        self.meshes = {b: [BoneMesh(b, np.ascontiguousarray(v, dtype=np.float64),
                                    np.ascontiguousarray(f, dtype=np.int64), ()) for v, f in ms]
                       for b, ms in meshes.items()}
        self.bodies = [b for b, ms in self.meshes.items() if ms]
        self._box = {b: (np.min([m.vertices.min(0) for m in ms], axis=0),
                         np.max([m.vertices.max(0) for m in ms], axis=0)) for b, ms in self.meshes.items() if ms}
        return self

    def body_signed_distance(self, body: str, points: np.ndarray) -> np.ndarray:
        """Signed distance [m] of points given in ``body``'s frame to that body's bone (negative inside).

        Args:
            body: Body name.
            points: (K, 3) in the body frame [m].

        Returns:
            (K,) distances; ``+inf`` for a body without meshes.
        """
        return self.body_closest(body, points)[0]

    def body_closest(self, body: str, points: np.ndarray,
                     far: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Signed distance, closest bone-surface point and outward unit normal, in ``body``'s frame.

        Args:
            body: Body name.
            points: (K, 3) in the body frame [m].
            far: If given [m], points that :meth:`far_from` proves farther than this outside the bone
                are not looked up: ``+inf`` and NaN for them, as for points not queried. Every
                distance up to ``far`` (and every point inside) is the exact one.

        Returns:
            ``(d, c, n)``: (K,) signed distances [m] (negative inside; ``+inf`` for a body without
            meshes), (K, 3) closest surface points [m] and (K, 3) unit normals pointing out of the
            bone at them (the direction in which the distance grows: ``∇d``); NaN without meshes.
        """
        P = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
        out = np.full(len(P), np.inf)
        C = np.full((len(P), 3), np.nan)
        N = np.full((len(P), 3), np.nan)
        if len(P) == 0:
            return out, C, N
        pruned = self.far_from(body, P, far) if far is not None else None
        for m in self.meshes.get(body, []):
            tree, fwn = self._trees(m)
            # what igl.signed_distance(..., SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER) computes, with its
            # two hierarchies built once per mesh instead of on every call: the closest surface point
            # (AABB tree) and the sign 1 - 2|w| of the fast winding number (order 2, accuracy 2);
            # libigl scales the distance by that continuous sign: keep only the sign and take the
            # exact distance to the closest surface point
            idx = np.arange(len(P))
            closed = pruned is not None and m.closed
            if closed:
                # farther than ``far`` from every surface, in a ball around an outside node that no surface
                # crosses: outside this closed mesh too (skipped without its winding number)
                idx = np.flatnonzero(~pruned)
                if len(idx) == 0:
                    continue
            w = fwn.winding_number(P[idx], 2.0)
            sign = np.where(1.0 - 2.0 * np.abs(w) < 0, -1.0, 1.0)
            if pruned is not None and not closed:
                # farther than ``far`` from every surface: skipped where the sign says outside (an open
                # mesh's winding number can say inside away from its surface: those are looked up)
                keep = ~(pruned[idx] & (sign > 0))
                idx, sign = idx[keep], sign[keep]
            if len(idx) == 0:
                continue
            d, c, n = self._mesh_closest(m, tree, P[idx], sign)
            better = d < out[idx]
            j = idx[better]
            out[j], C[j], N[j] = d[better], c[better], n[better]
        return out, C, N

    @staticmethod
    def _mesh_closest(m: BoneMesh, tree, P: np.ndarray, sign: np.ndarray):
        """Signed distance (sign given), closest point and outward normal of points ``P`` to mesh ``m``."""
        _, face, closest = tree.squared_distance(m.vertices, m.faces, P)
        diff = P - closest
        dist = np.linalg.norm(diff, axis=1)
        s = sign * dist
        # normal: from the closest point towards the query point (outward for points outside,
        # reversed inside); on the surface itself, the closest face's normal
        tri = m.vertices[m.faces[face]]
        fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
        on = dist < 1e-9
        nrm = np.where(on[:, None], fn, sign[:, None] * diff / np.maximum(dist, 1e-300)[:, None])
        return s, closest, nrm

    def far_from(self, body: str, points: np.ndarray, far: float) -> np.ndarray:
        """(K,) mask of the points (body frame [m]) proved farther than ``far`` [m] from every surface of
        ``body``'s bone, from a coarse grid of exact distances (spacing :data:`PRUNE_STEP`, nodes
        computed when first needed and kept in this process): the distance to a surface is 1-Lipschitz,
        so a point at ``r`` from a node whose distance is ``d`` lies at least ``d − r`` from it. Points off
        the grid (more than :data:`PRUNE_PAD` outside the bone's bounding box) and points whose node is
        inside bone are never in the mask."""
        P = np.asarray(points, float).reshape(-1, 3)
        mask = np.zeros(len(P), dtype=bool)
        if body not in self._box or len(P) == 0:
            return mask
        cache = self.__dict__.setdefault("_grid_cache", {})
        if body not in cache:
            lo, hi = self._box[body]
            origin = lo - PRUNE_PAD
            shape = np.ceil((hi - lo + 2 * PRUNE_PAD) / PRUNE_STEP).astype(int) + 1
            cache[body] = (origin, shape, np.full(int(np.prod(shape)), np.nan))
        origin, shape, grid = cache[body]
        ijk = np.rint((P - origin) / PRUNE_STEP).astype(np.int64)
        on = np.all((ijk >= 0) & (ijk < shape), axis=1)
        if not on.any():
            return mask
        flat = np.ravel_multi_index(ijk[on].T, shape)
        todo = np.unique(flat[np.isnan(grid[flat])])
        if len(todo):
            nodes = origin + PRUNE_STEP * np.stack(np.unravel_index(todo, shape), axis=1)
            grid[todo] = self.body_closest(body, nodes)[0]
        node = origin + PRUNE_STEP * ijk[on]
        r = np.linalg.norm(P[on] - node, axis=1)
        mask[on] = grid[flat] - r > far
        return mask

    def _trees(self, mesh: BoneMesh):
        """libigl's AABB tree and fast-winding-number hierarchy of a mesh, built on first use in this
        process (never pickled: the optimiser's workers build their own)."""
        import igl  # noqa: PLC0415

        cache = self.__dict__.setdefault("_tree_cache", {})
        key = id(mesh)
        if key not in cache:
            tree = igl.AABB()
            tree.init(mesh.vertices, mesh.faces)
            fwn = igl.FastWindingNumberBVH()
            fwn.init(mesh.vertices, mesh.faces, 2)
            cache[key] = (mesh, tree, fwn)       # the mesh kept alive: its id stays its own
        return cache[key][1], cache[key][2]

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("_tree_cache", None)
        state.pop("_grid_cache", None)
        return state

    def nearest(self, state, points: np.ndarray, margin: float = 0.0, bodies: list[str] | None = None,
                prune: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Like :meth:`signed_distance`, with the closest surface point and outward normal of the
        nearest bone, in the world frame.

        Returns:
            ``(d, nearest, c, n)``: (S, K) signed distances [m], (S, K) index into :attr:`bodies`
            (-1 where no bone was queried), (S, K, 3) closest points [m] and (S, K, 3) unit normals
            (NaN where no bone was queried).
        """
        return self._query(state, points, margin, bodies, closest=True, prune=prune)

    def signed_distance(self, state, points: np.ndarray, margin: float = 0.0,
                        bodies: list[str] | None = None, prune: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance of world points to every bone, posed by a kinematics state.

        Args:
            state: :class:`pamkin.human.kinematics.KinematicsState` of S configurations.
            points: (S, K, 3) world positions [m] (one set per configuration).
            margin: Points farther than ``margin`` from a bone's bounding box are not queried
                for that bone (their distance is reported as +inf when no bone is near): use it
                when only penetrations or near contacts matter. ``None``: query every bone.
            bodies: Bones to test (default: all).
            prune: Also leave out, per bone, the points that a coarse grid proves farther than
                ``margin`` from it (:meth:`far_from`; needs a ``margin``): every distance up to
                ``margin`` is unchanged, larger ones may be reported as +inf (faster where most
                points are far).

        Returns:
            ``(d, nearest)``: (S, K) signed distances [m] (negative inside bone) and (S, K)
            index into :attr:`bodies` of the nearest bone (-1 where none was queried).
        """
        return self._query(state, points, margin, bodies, closest=False, prune=prune)[:2]

    def _query(self, state, points, margin, bodies, closest: bool, prune: bool = False):
        X = np.asarray(points, float)
        S, K = X.shape[:2]
        d = np.full((S, K), np.inf)
        near = np.full((S, K), -1, dtype=int)
        cw = np.full((S, K, 3), np.nan) if closest else None
        nw = np.full((S, K, 3), np.nan) if closest else None
        names = self.model.bodies
        for bi, body in enumerate(self.bodies):
            if bodies is not None and body not in bodies:
                continue
            b = names.index(body)
            R = state.body_R[:, b]
            p = state.body_p[:, b]
            local = np.einsum("sji,skj->ski", R, X - p[:, None, :])  # R^T (x - p)
            if margin is None:
                mask = np.ones((S, K), dtype=bool)
            else:
                lo, hi = self._box[body]
                mask = np.all((local >= lo - margin) & (local <= hi + margin), axis=2)
            if not mask.any():
                continue
            far = margin if prune and margin is not None else None
            if closest:
                s, c, n = self.body_closest(body, local[mask], far=far)
            else:
                s = self.body_closest(body, local[mask], far=far)[0]
            cur = d[mask]
            better = s < cur
            cur[better] = s[better]
            d[mask] = cur
            nb = near[mask]
            nb[better] = bi
            near[mask] = nb
            if closest:
                Rm = np.broadcast_to(R[:, None], (S, K, 3, 3))[mask]          # (M, 3, 3)
                pm = np.broadcast_to(p[:, None], (S, K, 3))[mask]
                cc, nn = cw[mask], nw[mask]
                cc[better] = (pm + np.einsum("mij,mj->mi", Rm, c))[better]
                nn[better] = np.einsum("mij,mj->mi", Rm, n)[better]
                cw[mask] = cc
                nw[mask] = nn
        return d, near, cw, nw


def capsule_distance(a0: np.ndarray, a1: np.ndarray, ra: float, b0: np.ndarray, b1: np.ndarray, rb: float) -> float:
    """Signed distance [m] between two capsules (segment a0–a1 of radius ra, b0–b1 of radius rb),
    negative when they overlap (coal/hpp-fcl)."""
    import coal  # noqa: PLC0415

    def shape(p, q, r):
        p = np.asarray(p, float)
        q = np.asarray(q, float)
        v = q - p
        L = float(np.linalg.norm(v))
        T = coal.Transform3s()
        T.setTranslation(0.5 * (p + q))
        if L > 1e-12:
            z = v / L
            T.setRotation(_rotation_to_z(z))
        return coal.Capsule(max(r, 1e-9), L), T

    ca, Ta = shape(a0, a1, ra)
    cb, Tb = shape(b0, b1, rb)
    res = coal.DistanceResult()
    return float(coal.distance(ca, Ta, cb, Tb, coal.DistanceRequest(), res))


def _rotation_to_z(z: np.ndarray) -> np.ndarray:
    """A rotation matrix whose third column is the unit vector ``z``."""
    a = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(a, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


def segment_distances(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> np.ndarray:
    """Distance [m] between segments A–B and C–D, per row (vectorised; exact up to rounding).

    The closest points are found as in Ericson, *Real-Time Collision Detection* (2005), §5.1.9: the
    parameter of the first segment on the line through the second, clamped, then the second's
    clamped and the first's recomputed; degenerate (point) segments included.

    Args:
        A, B, C, D: (S, 3) segment ends [m].

    Returns:
        (S,) distances [m].
    """
    A, B, C, D = (np.asarray(x, float) for x in (A, B, C, D))
    d1, d2, r = B - A, D - C, A - C
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    tiny = 1e-24
    pa, pe = a > tiny, e > tiny
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(pa & pe & (denom > tiny * np.maximum(a * e, tiny)),
                     np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        s = np.where(pa & ~pe, np.clip(-c / np.where(pa, a, 1.0), 0.0, 1.0), s)
        t = np.where(pe, (b * s + f) / np.where(pe, e, 1.0), 0.0)
        # t outside [0, 1]: clamp it and recompute s for the clamped t
        lo, hi = t < 0.0, t > 1.0
        s = np.where(pa & pe & lo, np.clip(-c / np.where(pa, a, 1.0), 0.0, 1.0), s)
        s = np.where(pa & pe & hi, np.clip((b - c) / np.where(pa, a, 1.0), 0.0, 1.0), s)
    t = np.clip(t, 0.0, 1.0)
    P = A + s[:, None] * d1
    Q = C + t[:, None] * d2
    return np.linalg.norm(P - Q, axis=1)


def capsule_pair_overlap(A: np.ndarray, B: np.ndarray, ra: float, C: np.ndarray, D: np.ndarray, rb: float,
                         tolerance: float = 1e-4) -> tuple[float, int]:
    """Whether two moving capsules (segments A–B and C–D per sample, radii ra, rb) overlap at some sample.

    Samples whose axis-aligned bounding boxes (grown by the radii) are apart cannot overlap; the
    others' distances are computed at once (:func:`segment_distances`) and checked with coal in that
    order, from the closest, up to the first overlap deeper than ``tolerance`` (or the closest alone
    when none is within :data:`OVERLAP_GUARD` of it).

    Args:
        A, B, C, D: (S, 3) segment ends per sample [m].
        ra, rb: Radii [m].
        tolerance: Overlap that counts [m].

    Returns:
        ``(distance, sample)``: the signed distance [m] (coal's) at the first overlapping sample found
        (≤ −tolerance), else the smallest distance over the samples whose boxes meet (``+inf``, -1 when
        the boxes never meet).
    """
    lo1, hi1 = np.minimum(A, B), np.maximum(A, B)
    lo2, hi2 = np.minimum(C, D), np.maximum(C, D)
    gap = np.maximum(0.0, np.maximum(lo2 - hi1, lo1 - hi2))
    bound = np.linalg.norm(gap, axis=1) - ra - rb
    cand = np.flatnonzero(bound < -tolerance)
    if len(cand) == 0:
        return np.inf, -1
    # every candidate's distance at once (numpy), then coal at the samples that decide: in order of
    # that distance, up to the first overlap coal confirms (the numpy and coal distances agree to
    # rounding; a sample within OVERLAP_GUARD of the tolerance is always asked)
    approx = segment_distances(A[cand], B[cand], C[cand], D[cand]) - ra - rb
    order = np.argsort(approx)
    best, arg = np.inf, -1
    for i in order:
        if approx[i] >= -tolerance + OVERLAP_GUARD and best < np.inf:
            break
        s = int(cand[i])
        dist = capsule_distance(A[s], B[s], ra, C[s], D[s], rb)
        if dist < best:
            best, arg = dist, s
        if dist < -tolerance:
            break
    return best, arg


def body_pair_distance(pieces_a: list, pieces_b: list, ra: float, rb: float, tolerance: float = 1e-4
                       ) -> tuple[float, int]:
    """Smallest signed distance between two moving PAM bodies given as capsule pieces
    (:func:`pamkin.robot.pam_body.pam_capsules`: ``(A, B, valid)`` per route segment, (S, 3), (S, 3), (S,)) of
    radii ``ra``, ``rb`` over the samples where both pieces are present — up to the first overlap deeper
    than ``tolerance`` (:func:`capsule_pair_overlap`).

    Returns:
        ``(distance, sample)``: [m] and the sample's index (``+inf``, -1 when the bodies never come close).
    """
    best, arg = np.inf, -1
    for A, B, va in pieces_a:
        for C, D, vb in pieces_b:
            ok = va & vb
            if not ok.any():
                continue
            d, s = capsule_pair_overlap(A[ok], B[ok], ra, C[ok], D[ok], rb, tolerance)
            if d < best:
                best, arg = d, (int(np.flatnonzero(ok)[s]) if s >= 0 else -1)
            if best < -tolerance:
                return best, arg
    return best, arg
