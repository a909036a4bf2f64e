"""Muscle paths and PAM routes as MuJoCo spatial tendons, with the closest construct where MuJoCo has none.

* A ``PathPoint`` is a site of its body: exact.
* A ``MovingPathPoint`` is a site of its own body, a child of the point's body with one slide joint per
  moving component (along the body's axes) tied to the coordinate's primary joint by a degree-4 polynomial
  (:class:`pamkin.sim.joints.CoordinateMap`): approximate where the function is a spline.
* A ``ConditionalPathPoint`` with a neighbouring point fixed in the same body (composed couplings): a site on
  a chain of bodies sliding along (point − neighbour), driven by sharp iterated smoothsteps of the coordinate
  (:func:`step_site`): on the point while OpenSim includes it, on the neighbour (a zero-length segment: the
  same length as OpenSim's path without it) while it does not; exact outside a band of
  :data:`pamkin.sim.couplings.STEP_BAND` around each switch, where OpenSim's length jumps. With the neighbour on
  another body placed by the same coordinate alone (a moving patella point), the site's body hangs from the
  neighbour's and slides by activity × offset (:func:`_product_site`; the offset fitted, so not exact).
  Otherwise a site that the tendon passes through always or never, or a small wrap geom through it
  (MuJoCo has no conditional points): the choice with the smaller length error on the fit poses.
* ``WrapCylinder`` and ``WrapSphere`` are wrap geoms (MuJoCo's cylinders are infinite; OpenSim's quadrant
  becomes a side site); ``WrapEllipsoid`` is a sphere or a cylinder (candidates from its radii); a
  ``WrapTorus`` has no MuJoCo counterpart and is left out. MuJoCo wraps a geom placed between two sites, so
  each wrap is placed in one segment of its range (OpenSim picks the segment per pose).

Where a path has choices (conditional points, the wrap segment, the side site, the ellipsoid's stand-in)
every combination is a candidate tendon of one fit model, evaluated on fit poses (their own seed, not the
measurement's) against pamkin's lengths; the candidate with the smallest largest error is kept.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from pamkin.opensim.model_file import ConditionalPathPoint, MovingPathPoint, PathPoint
from pamkin.sim import couplings as cp
from pamkin.opensim.wrapping import PathWrap, WrapObject
from pamkin.sim.geometry import MjGeometry
from pamkin.sim.joints import CoordinateMap, MjJoint
from pamkin.sim.mjcf import MjcfSpec, Site, Tendon, WrapGeom, mjcf_document, safe

#: Largest number of candidate tendons of one path (more: the wraps are chosen one at a time).
MAX_CANDIDATES = 200
#: Fit poses (seed :data:`FIT_SEED`) on which the candidates are compared.
FIT_POSES = 300
FIT_SEED = 12345


@dataclass(frozen=True)
class PathSpec:
    """A path to convert: muscle or PAM route name, its points and its PathWraps."""

    name: str
    points: tuple
    wraps: tuple[PathWrap, ...] = ()


@dataclass
class PathChoice:
    """What the converter chose for one path, and why (its fit-pose error)."""

    name: str
    tendon: Tendon
    conditional: dict[str, bool]
    wraps: list[str]
    omitted: list[str]
    fit_error: float
    #: Conditional points built as steps: {point: {"coordinate": independent coordinate, "switches":
    #: [its values], "band": full width [rad or m],
    #: "iterations": smoothstep iterations per switch}}.
    steps: dict[str, dict] = field(default_factory=dict)

#: Grid points on which a conditional point's activity over its coordinate's range is located.
SWITCH_GRID = 4001


def _activity(pt: ConditionalPathPoint, cmap: CoordinateMap) -> tuple[str, object]:
    """(independent coordinate, vectorised q -> bool: OpenSim includes the point)."""
    coord, fn = cmap.root(pt.coordinate)
    lo, hi = pt.range
    return coord, lambda q: (np.asarray(fn(np.asarray(q, float))) >= lo - 1e-5) & (
        np.asarray(fn(np.asarray(q, float))) <= hi + 1e-5)


def _switches(active, lo: float, hi: float) -> tuple[bool, list[tuple[float, int]]]:
    """Activity at ``lo`` and the switches inside (lo, hi): (coordinate value, +1 on / −1 off as q rises)."""
    q = np.linspace(lo, hi, SWITCH_GRID)
    a = active(q)
    out = []
    for k in np.nonzero(a[1:] != a[:-1])[0]:
        x0, x1 = q[k], q[k + 1]
        for _ in range(60):                     # bisection to round-off
            xm = 0.5 * (x0 + x1)
            x0, x1 = (xm, x1) if active(np.array([xm]))[0] == a[k] else (x0, xm)
        out.append((0.5 * (x0 + x1), 1 if a[k + 1] else -1))
    return bool(a[0]), out


def step_site(name: str, pt: ConditionalPathPoint, neighbour: tuple, cmap: CoordinateMap,
              spec: MjcfSpec) -> dict | None:
    """Build a conditional point as a step site ``name`` (module docstring); None when its coordinate never
    switches inside its range (the always/never candidates then hold it exactly) or the neighbour's frame
    moves relative to the point with other coordinates too.

    Args:
        neighbour: (MuJoCo body, the neighbour site's position in it [m], point − neighbour in that body's
            frame [m], or None: a function of the coordinate, then found by MuJoCo's kinematics and fitted).
    """
    coord, active = _activity(pt, cmap)
    if coord not in cmap.primary:
        return None
    lo, hi = cmap.ranges[coord]
    on, sw = _switches(active, lo, hi)
    body, pos, d = neighbour
    if not sw or (d is not None and np.linalg.norm(d) < 1e-9):
        return None
    offset = _relative_offset(pt, body, pos, coord, cmap, spec) if d is None else None
    if d is None and offset is None:
        return None
    _, a, b = cmap.primary[coord]
    vlo, vhi = sorted((a * lo + b, a * hi + b))
    c0, steps, n_it = float(on), [], []
    for q_s, sign in sw:                        # activity = c0 + Σ sign·H(q − q_s), H in the primary value v
        if a < 0:                               # H(q − q_s) = 1 − H(v − v_s)
            c0, sign = c0 + sign, -sign
        v_s = a * q_s + b
        n_it.append(cp.smoothstep_iterations(max(v_s - vlo, vhi - v_s) / abs(a)))
        names = cmap.add_chain(coord, f"{name}-{len(steps)}", cp.step_chain("", v_s, vlo, vhi, n_it[-1]))
        steps.append((names[f"s{n_it[-1]}"], sign))
    out = {"coordinate": coord, "switches": [q for q, _ in sw], "band": cp.STEP_BAND, "iterations": n_it,
           "active": active}
    if d is None:
        out["parent"], out["offset_fit_error_m"] = _product_site(name, body, pos, offset, coord, c0, steps,
                                                                 cmap, spec)
        return out
    parent, pos = body, pos + c0 * d
    for t, (s_name, sign) in enumerate(steps):  # one slide body per switch, in series along d
        spec.point_bodies.append((f"{name}-step{t}", parent, pos))
        cmap.joints.append(MjJoint(f"{name}-step{t}", f"{name}-step{t}", "slide", np.zeros(3),
                                   d / np.linalg.norm(d), coord, None,
                                   poly=cp.linear_polycoef(sign * np.linalg.norm(d), 0.0), source=s_name))
        parent, pos = f"{name}-step{t}", np.zeros(3)
    spec.sites.append(Site(name, parent, np.zeros(3)))
    out["parent"] = parent
    return out


def _relative_offset(pt, body: str, pos: np.ndarray, coord: str, cmap: CoordinateMap,
                     spec: MjcfSpec) -> tuple[np.ndarray, np.ndarray] | None:
    """(q grid over the coordinate's range, (n, 3) point − neighbour site in ``body``'s frame [m]) by MuJoCo's
    kinematics of the model built so far; None when it also depends on other coordinates."""
    model = mujoco.MjModel.from_xml_string(mjcf_document(cmap.osim, cmap, MjcfSpec(
        spec.name, list(spec.sites), [], [], list(spec.point_bodies))))
    geo = MjGeometry(model, cmap, [])
    ib = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, safe(pt.body))
    inb = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, safe(body))
    c = cmap.coordinates.index(coord)
    qg = np.linspace(*cmap.ranges[coord], 801)
    out = []
    for frac in (0.5, 0.3):                      # two backgrounds of the other coordinates
        q = np.array([lo + frac * (hi - lo) for lo, hi in (cmap.ranges[n] for n in cmap.coordinates)])
        q = np.repeat(q[None], len(qg), axis=0)
        q[:, c] = qg
        g = np.empty((len(qg), 3))
        for n, row in enumerate(cmap.qpos(q)):
            geo.set_pose(row)
            d = geo.data
            P = d.xpos[ib] + d.xmat[ib].reshape(3, 3) @ np.asarray(pt.location, float)
            Rn = d.xmat[inb].reshape(3, 3)
            g[n] = Rn.T @ (P - d.xpos[inb]) - pos
        out.append(g)
    return (qg, out[0]) if np.abs(out[0] - out[1]).max() < 1e-9 else None


def _product_site(name: str, body: str, pos: np.ndarray, offset: tuple[np.ndarray, np.ndarray], coord: str,
                  c0: float, steps: list[tuple[str, int]], cmap: CoordinateMap, spec: MjcfSpec) -> tuple[str, float]:
    """A step body at the neighbour site with a slide per axis whose value is activity(q)·g(q) (g the fitted
    offset to the point): products from sums and squares, ab = ((a + b)² − (a − b)²)/4, each an exact tie.
    Returns the body and the offset fit's largest deviation [m]."""
    qg, g = offset
    _, a, b = cmap.primary[coord]
    v = a * qg + b
    chain, basis = cp.basis_chain(float(v.min()), float(v.max()))
    bnames = cmap.add_chain(coord, "basis", chain)
    act = cmap.add_aux(f"{name}-act", coord, cp.linear_polycoef(0.0, c0), terms=dict(steps))
    step_body = f"{name}-step"
    spec.point_bodies.append((step_body, body, pos))
    worst = 0.0
    for i in range(3):
        coef, err, _ = cp.composed_fit(chain, basis, v, g[:, i], np.gradient(g[:, i], v))
        worst = max(worst, err)
        gi = cmap.add_aux(f"{name}-g{i}", coord, cp.linear_polycoef(0.0, coef[""]),
                          terms={bnames[k]: c for k, c in coef.items() if k})
        sq = [cmap.add_aux(f"{name}-sq{i}{t}", coord, np.array([0, 0, 1.0, 0, 0]),
                           source=cmap.add_aux(f"{name}-sum{i}{t}", coord, np.zeros(5), terms={gi: 1.0, act: sgn}))
              for t, sgn in (("p", 1.0), ("m", -1.0))]
        cmap.joints.append(MjJoint(f"{name}-step-{'xyz'[i]}", step_body, "slide", np.zeros(3), np.eye(3)[i], coord,
                                   None, poly=np.zeros(5), terms={sq[0]: 0.25, sq[1]: -0.25}, error=err))
    spec.sites.append(Site(name, step_body, np.zeros(3)))
    return step_body, worst


def build_sites(paths: Sequence[PathSpec], cmap: CoordinateMap,
                spec: MjcfSpec) -> tuple[list[list[str]], list[dict[int, dict]]]:
    """Sites (and moving-point bodies, step bodies and their tied joints) of every path point; returns the
    site names and, per path, the conditional points built as steps (:func:`step_site`). Conditional points
    come last, so that the neighbours they may collapse onto exist."""
    out, steps = [], []
    for path in paths:
        names = [safe(f"{path.name}-{i}-{pt.name}") for i, pt in enumerate(path.points)]
        anchors: dict[int, tuple[str, np.ndarray]] = {}
        st: dict[int, dict] = {}
        steps.append(st)
        order = sorted(range(len(path.points)), key=lambda i: (isinstance(path.points[i], ConditionalPathPoint), i))
        for i in order:
            pt, name = path.points[i], names[i]
            if isinstance(pt, ConditionalPathPoint) and cmap.couplings == "composed":
                for nb in _neighbours(path, i, st, anchors, cmap):
                    made = step_site(name, pt, nb, cmap, spec)
                    if made is not None:
                        st[i] = made
                        anchors[i] = (made["parent"], np.zeros(3))
                        break
                if i in st:
                    continue
            anchors[i] = _point_site(name, pt, cmap, spec)
        out.append(names)
    return out, steps


def _point_site(name: str, pt, cmap: CoordinateMap, spec: MjcfSpec) -> tuple[str, np.ndarray]:
    """The site of a fixed or moving point (a moving point's body with its tied slides); returns its
    (MuJoCo body, position in it [m])."""
    if not isinstance(pt, MovingPathPoint):
        spec.sites.append(Site(name, pt.body, np.asarray(pt.location, float)))
        return pt.body, np.asarray(pt.location, float)
    body = f"{name}-body"
    spec.point_bodies.append((body, pt.body))
    pos = np.zeros(3)
    for k, (f, c) in enumerate(zip(pt.functions, pt.coordinates)):
        if f.is_constant or not c:
            pos[k] = float(np.asarray(f.value(np.zeros(1)))[0])
            continue
        coord, inner = cmap.root(c)
        mj = MjJoint(f"{name}-{'xyz'[k]}", body, "slide", np.zeros(3), np.eye(3)[k], coord,
                     (lambda ff, gg: (lambda x: ff.value(gg(np.asarray(x, float)))))(f, inner))
        cmap.joints.append(mj)
        cmap.tie(mj)
    spec.sites.append(Site(name, body, pos))
    return body, pos


def _neighbours(path: PathSpec, i: int, steps: dict[int, dict], anchors: dict, cmap: CoordinateMap):
    """Candidate neighbours of conditional point ``i`` to collapse onto, as (MuJoCo body, the neighbour site's
    position in it [m], point − neighbour in that body's frame [m], or None where it varies with the pose):
    fixed points of the same body; earlier step points of the same body whose activity contains the point's
    (so the point is never on while its neighbour is off); then the neighbouring points on other bodies."""
    pt = path.points[i]
    near = [j for j in (i - 1, i + 1) if 0 <= j < len(path.points) and j in anchors]
    for j in near:
        nb = path.points[j]
        if isinstance(nb, PathPoint) and not isinstance(nb, ConditionalPathPoint) and nb.body == pt.body:
            loc = np.asarray(nb.location, float)
            yield nb.body, loc, np.asarray(pt.location, float) - loc
    if i - 1 in steps and path.points[i - 1].body == pt.body:
        coord, active = _activity(pt, cmap)
        c2, active2 = _activity(path.points[i - 1], cmap)
        q = np.linspace(*cmap.ranges[coord], SWITCH_GRID)
        if coord == c2 and not np.any(active(q) & ~active2(q)):
            loc = np.asarray(path.points[i - 1].location, float)
            yield steps[i - 1]["parent"], np.zeros(3), np.asarray(pt.location, float) - loc
    for j in near:
        if j not in steps and not isinstance(path.points[j], ConditionalPathPoint) and \
                getattr(path.points[j], "body", None) != pt.body:
            yield anchors[j][0], anchors[j][1], None


def wrap_geoms(wo: WrapObject, spec: MjcfSpec, made: dict) -> list[tuple[str, list[str]]]:
    """The geoms standing for ``wo`` (added to ``spec`` once) and, per geom, its side-site options."""
    if wo.name in made:
        return made[wo.name]
    R = np.asarray(wo.rotation, float)
    p = np.asarray(wo.translation, float)
    axis, sign = wo.wrap_axis_sign
    options: list[tuple[str, tuple[float, ...], np.ndarray, float]] = []
    if not wo.active:
        pass
    elif wo.kind == "WrapCylinder":
        options.append(("cylinder", (wo.dimensions[0], wo.dimensions[1] / 2), R, wo.dimensions[0]))
    elif wo.kind == "WrapSphere":
        options.append(("sphere", (wo.dimensions[0],), R, wo.dimensions[0]))
    elif wo.kind == "WrapEllipsoid":
        d = np.asarray(wo.dimensions, float)
        for r in sorted({float(d.min()), float(d.mean()), float(d.max())}):
            options.append(("sphere", (r,), R, r))
        for k in range(3):              # a cylinder along each axis, radius the mean of the other two
            other = [d[i] for i in range(3) if i != k]
            Rk = R @ _z_to(k)
            options.append(("cylinder", (float(np.mean(other)), float(d[k])), Rk, float(np.mean(other))))
    out = []
    for n, (kind, size, Rg, radius) in enumerate(options):
        name = safe(f"{wo.name}" if len(options) == 1 else f"{wo.name}-{kind}{n}")
        spec.geoms.append(WrapGeom(name, wo.body, kind, size, Rg, p))
        sides = [""]
        if sign != 0:
            direction = R[:, axis] * sign
            for tag, dist in (("out", 2.0), ("in", 0.5)):
                s = f"{name}-side-{tag}"
                spec.sites.append(Site(s, wo.body, p + direction * radius * dist))
                sides.append(s)
        out.append((name, sides))
    made[wo.name] = out
    return out


def _z_to(k: int) -> np.ndarray:
    """Rotation taking z to axis k (a cylinder geom's axis is its z)."""
    if k == 2:
        return np.eye(3)
    if k == 0:
        return np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    return np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])


def candidates(path: PathSpec, sites: list[str], spec: MjcfSpec, made: dict,
               standins: dict[int, list[tuple[str, str]]] | None = None,
               steps: dict[int, dict] | None = None) -> list[tuple[Tendon, dict, list, list]]:
    """Every candidate tendon of ``path``: (tendon, conditional choices, wrap geoms used, wraps left out).

    ``standins``: per conditional point index, wrap geoms (geom, side site) that may stand for it;
    ``steps``: conditional points built as steps (always in the tendon)."""
    standins = standins or {}
    steps = steps or {}
    cond = [i for i, pt in enumerate(path.points) if isinstance(pt, ConditionalPathPoint) and i not in steps]
    wrap_opts = []
    omitted = []
    for w in path.wraps:
        geoms = wrap_geoms(w.wrap_object, spec, made)
        if not geoms:
            omitted.append(w.wrap_object.name)
        wrap_opts.append((w, geoms))
    out = []
    for inc in itertools.product(*[[True, False, *standins.get(i, [])] for i in cond]):
        keep = [i for i in range(len(path.points)) if i not in cond or inc[cond.index(i)] is True]
        fixed = []                     # conditional points' stand-in geoms: (segment, geom, side)
        for k, i in enumerate(cond):
            if isinstance(inc[k], tuple):
                j = max(n for n, kk in enumerate(keep) if kk < i)
                fixed.append((j, *inc[k]))
        per_wrap = []
        for w, geoms in wrap_opts:
            lo, hi = w.range
            lo = 1 if lo < 1 else lo
            hi = len(path.points) if hi < 1 else hi
            segs = [j for j in range(len(keep) - 1) if lo <= keep[j] + 1 and keep[j + 1] + 1 <= hi]
            per_wrap.append([None] + [(j, g, s) for j in segs for g, sides in geoms for s in sides])
        combos = list(itertools.product(*per_wrap))
        if len(combos) > MAX_CANDIDATES:            # one wrap at a time, the others left out
            combos = [tuple(o if k == i else None for k in range(len(per_wrap)))
                      for i, opts in enumerate(per_wrap) for o in opts]
        for combo in combos:
            used = fixed + [c for c in combo if c is not None]
            if len({c[0] for c in used}) < len(used):   # two geoms in one segment: MuJoCo needs a site between
                continue
            items: list[tuple] = []
            for j, i in enumerate(keep):
                items.append(("site", sites[i]))
                for c in used:
                    if c[0] == j:
                        items.append(("geom", c[1], c[2]))
            choice = {path.points[i].name: (inc[k] if isinstance(inc[k], bool) else f"wrap {inc[k][0]}")
                      for k, i in enumerate(cond)}
            choice.update({path.points[i].name: "step" for i in sorted(steps)})
            out.append((Tendon(path.name, items), choice, [c[1] for c in used], omitted))
    return out


#: Radii of the spheres and cylinders that may stand for a conditional path point [m].
STANDIN_RADII = (0.002, 0.008, 0.02)


def conditional_standins(osim, cmap: CoordinateMap, paths: Sequence[PathSpec], sites: list[list[str]],
                         q_fit: np.ndarray, spec: MjcfSpec,
                         steps: list[dict[int, dict]] | None = None) -> list[dict[int, list[tuple[str, str]]]]:
    """Wrap geoms that may stand for each conditional path point: a sphere and a cylinder through the point,
    on the side of the straight line between its neighbours where the point bends the path (the mean
    direction, in the point's body, over the fit poses where OpenSim includes it), with a side site beyond
    the point. Where the straight line passes beyond the point the path no longer wraps: the point drops
    out geometrically (OpenSim drops it by its coordinate's range)."""
    out: list[dict[int, list[tuple[str, str]]]] = [{} for _ in paths]
    todo = [(m, i) for m, p in enumerate(paths) for i, pt in enumerate(p.points)
            if isinstance(pt, ConditionalPathPoint) and 0 < i < len(p.points) - 1
            and not (steps and i in steps[m])]
    if not todo:
        return out
    model = mujoco.MjModel.from_xml_string(mjcf_document(osim, cmap, MjcfSpec(spec.name, spec.sites, [], [],
                                                                                spec.point_bodies)))
    geo = MjGeometry(model, cmap, [])
    sid = {s.name: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, s.name) for s in spec.sites}
    qpos = cmap.qpos(q_fit)
    pos = np.empty((len(q_fit), model.nsite, 3))
    rot = np.empty((len(q_fit), model.nsite, 3, 3))
    for n in range(len(q_fit)):
        geo.set_pose(qpos[n])
        pos[n] = geo.data.site_xpos
        rot[n] = geo.data.site_xmat.reshape(-1, 3, 3)
    for m, i in todo:
        pt = paths[m].points[i]
        a, p, b = (sid[sites[m][k]] for k in (i - 1, i, i + 1))
        c = cmap.coordinates.index(pt.coordinate)
        on = (q_fit[:, c] >= pt.range[0] - 1e-5) & (q_fit[:, c] <= pt.range[1] + 1e-5)
        if not on.any():
            continue
        A, P, B, R = pos[on, a], pos[on, p], pos[on, b], rot[on, p]
        e = (B - A) / np.linalg.norm(B - A, axis=1, keepdims=True)
        d = P - A - np.einsum("ni,ni->n", P - A, e)[:, None] * e
        nb = np.einsum("nji,nj->ni", R, d).mean(axis=0)       # into the point's body frame
        ab = np.einsum("nji,nj->ni", R, np.cross(d, e)).mean(axis=0)
        if np.linalg.norm(nb) < 1e-9 or np.linalg.norm(ab) < 1e-9:
            continue
        nb /= np.linalg.norm(nb)
        ab -= nb * (ab @ nb)
        ab /= np.linalg.norm(ab)
        Rc = np.column_stack([nb, np.cross(ab, nb), ab])     # cylinder axis (z) = ab
        loc = np.asarray(pt.location, float)
        opts = []
        for r in STANDIN_RADII:
            side = safe(f"{sites[m][i]}-side-{r * 1000:g}mm")
            spec.sites.append(Site(side, pt.body, loc + r * nb))
            for kind, size in (("sphere", (r,)), ("cylinder", (r, 0.05))):
                g = safe(f"{sites[m][i]}-{kind}-{r * 1000:g}mm")
                spec.geoms.append(WrapGeom(g, pt.body, kind, size, Rc, loc - r * nb))
                opts.append((g, side))
        out[m][i] = opts
    return out


def choose(osim, cmap: CoordinateMap, paths: Sequence[PathSpec], reference: Callable[[np.ndarray], np.ndarray],
           q_fit: np.ndarray, spec: MjcfSpec) -> list[PathChoice]:
    """Build every path's candidates, evaluate them at ``q_fit`` in MuJoCo against ``reference(q_fit)``
    (N, n_paths) lengths [m] and keep the best per path (``spec.tendons`` set to the chosen ones)."""
    sites, steps = build_sites(paths, cmap, spec)
    standins = conditional_standins(osim, cmap, paths, sites, q_fit, spec, steps)
    made: dict = {}
    cands = [candidates(p, s, spec, made, st, sp) for p, s, st, sp in zip(paths, sites, standins, steps)]
    fit_spec = MjcfSpec(spec.name, spec.sites, spec.geoms,
                        [Tendon(f"{t.name}~{k}", t.path) for cs in cands for k, (t, _, _, _) in enumerate(cs)],
                        spec.point_bodies)
    model = mujoco.MjModel.from_xml_string(mjcf_document(osim, cmap, fit_spec))
    geo = MjGeometry(model, cmap, [t.name for t in fit_spec.tendons])
    L = geo.lengths(q_fit)
    Lref = reference(q_fit)
    out = []
    col = 0
    for m, (path, cs) in enumerate(zip(paths, cands)):
        err = np.abs(L[:, col:col + len(cs)] - Lref[:, m:m + 1]).max(axis=0)
        best = int(np.argmin(err))
        t, choice, used, omitted = cs[best]
        out.append(PathChoice(path.name, t, choice, used, omitted, float(err[best]),
                              {path.points[i].name: {k: v for k, v in st.items() if k in (
                                  "coordinate", "switches", "band", "iterations", "offset_fit_error_m")}
                               for i, st in steps[m].items()}))
        col += len(cs)
    spec.tendons = [c.tendon for c in out]
    _prune(spec)
    return out


def _prune(spec: MjcfSpec) -> None:
    """Drop the wrap geoms and side sites no chosen tendon uses."""
    used = {x for t in spec.tendons for item in t.path for x in item[1:] if x}
    spec.geoms = [g for g in spec.geoms if g.name in used]
    spec.sites = [s for s in spec.sites if "-side-" not in s.name or s.name in used]
