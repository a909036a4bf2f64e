"""Each PAM on one straight segment of its solved route: resting and tendon length only.

A PAM cannot bend over a via point or pulley: the PAM body (resting length, or its actual length when
stretched, plus both fittings) must lie on one straight segment of the route at every pose, the
artificial tendon taking the rest of the route over the pulleys (``pamkin audit``, "fits on one
segment"). Solving the routes with that constraint from the start (``[limits] one_segment``) made the
bone-mesh rounds much slower and the fits much worse (default run: 18 min, an actuator infeasible, README
"Optimiser v2"). This stage runs after them instead, on the route they leave (every point fixed, so the
bone clearance is untouched): for the :data:`N_SEGMENTS` longest segments it solves the actuator's own
problem (objective, strain, rated-force and sensitivity rows at its samples) over the resting length l0
and the tendon length t only, with the PAM on that segment at every constraint sample, then checks the
strain and force limits and the segment on the held-out limit-check poses (:mod:`optimize.limit_check`;
a miss tightens the rows once and solves again). The result replaces the spanning PAM when the root of
the objective grows by at most ``cfg.mount.cost``; otherwise the run names the PAM and the reason:

* **out of reach**: the PAM's excursion needs a resting length of at least ΔL / (k (c + s)) (k = the
  transmission, :mod:`pamkin.robot.design`; c = Festo's
  25 % contraction or kmax, s = the stretch limit), more than the longest segment holds at its shortest
  less the fittings — no choice of lengths can put it on one segment; the numbers are reported;
* **infeasible**: within reach by that bound, but the solve finds no lengths meeting every limit;
* **fit cost**: feasible, but the fit would get worse by more than ``mount_cost``.

A shorter PAM works over a larger part of its contraction range, where the Festo force falls, so the
force along the motion changes shape: that, not the geometry, is what mounting costs.

Where the fixed route narrowly fails (fit cost at most :data:`ROUNDS_COST_FACTOR` × ``mount_cost``, or out of
reach by at most :data:`ROUNDS_REACH`), :func:`mount_rounds` frees the points again: the bone-mesh rounds
run from the solved route with the PAM on the segment (the one-segment rows), and the result is kept under
the same rules. Where it stays out of reach or infeasible, :func:`mount_block` tries the same route with the
PAM on a 2:1 pulley block (half the stroke), then a 3:1 block, under the same rule. A warm start keeps a mounted PAM on its
segment (:func:`mounted_segment`; the run then builds its problem with the rows there).
"""

from __future__ import annotations

import time
import warnings

import casadi as ca
import numpy as np
from pamkin.optimize.bone_cuts import bone_stage
from pamkin.optimize.limit_check import EXTRA, check_poses, limit_excess, tighten
from pamkin.optimize.problem import SEGMENT_MARGIN, _norm_rows

from pamkin.errors import RangeWarning
from pamkin.human.paths import PathSet
from pamkin.robot import festo
from pamkin.robot.design import Pam, pam_length, tendon_for
from pamkin.robot.pam_body import segment_margin, segment_names

#: Segments tried per route (the longest at their shortest constraint sample first).
N_SEGMENTS = 2


def held_out_margin(pam: Pam, model, q: np.ndarray, segment: int, fitting: float) -> float:
    """Smallest room [m] left on route segment ``segment`` by the PAM body (max(resting, actual length)
    + both fittings) over the poses ``q`` (negative: it does not fit), at one constant place along the route
    where the route moves on both sides of the segment — the audit's measure
    (:func:`pamkin.robot.pam_body.segment_margin`)."""
    kin = model.kinematics
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        ps = PathSet(kin, ["route"], [pam.points])
        state = kin.forward(q, warn_range=False)
        X, _ = ps.point_positions(state)
        L = ps.evaluate(state, moment_arms=False).lengths[:, 0]
    pam_len = pam_length(L, pam.tendon_length_m, pam.transmission, fitting)
    return segment_margin(X, segment, pam.resting_length_m, pam_len, fitting)


def reach_bound(L: np.ndarray, seg_min: float, diameter: int, cfg, fitting: float,
                transmission: int = 1) -> tuple[float, float]:
    """(least resting length the excursion of the path lengths ``L`` allows, most the segment holds) [m].

    The least: ΔL / (k (c + s)), with k the transmission (the PAM's stroke is the route's ÷ k), c the
    contraction limit (Festo's maximum, or kmax at the longest resting length the segment allows if
    lower) and s the stretch limit; the most: the segment at its shortest less both fittings and
    :data:`~optimize.problem.SEGMENT_MARGIN`."""
    most = seg_min - 2 * fitting - SEGMENT_MARGIN
    km = cfg.limits.kmax_scale * float(festo.kmax(max(most, 1e-3), diameter, model=cfg.force_model))
    c = min(km, festo.max_contraction(diameter)) if cfg.limits.rated_force else km
    s = cfg.limits.pretension_scale * festo.max_pretension(diameter)
    return float((np.max(L) - np.min(L)) / (transmission * (c + s))), float(most)


def mounted_segment(prob, z: np.ndarray, tol: float = 1e-6) -> int | None:
    """The route segment that holds the PAM of decision vector ``z`` at every constraint sample of ``prob``
    (:meth:`optimize.problem.ActuatorProblem.one_segment_rows`; the one with the most room), or None."""
    best, room = None, -tol
    for j in range(len(prob.X) - 1):
        rows = ca.vertcat(*prob.one_segment_rows(j))
        r = float(np.min(np.array(ca.Function("rows", [prob.z], [rows])(z))))
        if r >= room:
            best, room = j, r
    return best


class _MountSolver:
    """The actuator's problem over (l0, t) with the route fixed at ``z_route`` (the points' values put into
    its expressions: a two-variable NLP, cheap to build) and the PAM on one segment."""

    def __init__(self, prob, segment: int, z_route: np.ndarray, n_parallel: int) -> None:
        self.prob = prob
        rows = ca.vertcat(*prob.one_segment_rows(segment))
        self.n_rows = rows.shape[0]
        x = ca.SX.sym("lt", 2)
        z = ca.vertcat(ca.DM(np.asarray(z_route[:-2], float)), x)
        J, g, r = ca.Function("all", [prob.z, prob.npar], [*prob.shared(), rows])(z, n_parallel)
        self.z_route = np.asarray(z_route, float)
        self.solver = ca.nlpsol("mount", "ipopt", {"x": x, "f": J, "g": ca.vertcat(g, r)}, prob._ipopt_options())
        self.g = ca.Function("rows", [x], [r])
        self.n_parallel = n_parallel

    def solve(self, lt0: np.ndarray, extra: float):
        prob = self.prob
        lbg = np.concatenate([np.where(prob._capsule_rows(), -np.inf, prob.lbg), np.full(self.n_rows, extra)])
        ubg = np.concatenate([prob.ubg, np.full(self.n_rows, np.inf)])
        t0 = time.perf_counter()
        res = self.solver(x0=lt0, lbx=prob.lbx[-2:], ubx=prob.ubx[-2:], lbg=lbg, ubg=ubg)
        stats = self.solver.stats()
        lt = np.array(res["x"]).ravel()
        z = self.z_route.copy()
        z[-2:] = lt
        sol = prob._solution(z, float(res["f"]), stats.get("return_status", "?"), bool(stats.get("success")),
                             time.perf_counter() - t0, self.n_parallel, skip_capsules=True)
        rows = np.array(self.g(lt)).ravel()
        if np.min(rows, initial=np.inf) < extra - 1e-6:
            sol.success = False
            sol.violations["PAM on one segment"] = float(extra - np.min(rows))
        return sol


def cost_accepted(cost: float, cfg, failing, spanning, mounted) -> tuple[bool, str | None]:
    """Whether a mount at fit ``cost`` (growth of the objective's root) is kept, and the reason where it is over
    ``cfg.mount.cost``: ``failing(spanning(), mounted())`` (the run's ``mount_failing`` / ``mount_passing`` rules;
    ``spanning`` and ``mounted`` make the two PAMs only when asked), None where there is no such rule."""
    if cost <= cfg.mount.cost:
        return True, None
    reason = failing(spanning(), mounted()) if failing is not None else None
    return reason is not None, reason


def mount_stage(prob, best, pam: Pam, cfg, model, rom, solution_pam, failing=None, blocked=frozenset()
                ) -> tuple[object, dict]:
    """Put the PAM of a solved actuator on one straight segment of its route (module docstring).

    Args:
        prob: The actuator's :class:`~optimize.problem.ActuatorProblem` (its limits as solved).
        best: Its solution after the bone-mesh rounds.
        pam: The seed PAM (names, the route's point kinds).
        cfg: The run configuration (``mount_cost``, limits).
        model: The human model (kinematics of the held-out checks).
        rom: The range of motion of the held-out checks.
        solution_pam: ``(pam, solution) -> Pam`` (the run's saved form of a solution).
        failing: Optional ``(spanning Pam, mounted Pam) -> str | None``: a reason to mount the PAM although
            the fit cost exceeds ``mount_cost`` (``cfg.mount.failing``: its fit already fails the audit's fit
            limits; ``cfg.mount.passing``: on one segment it still passes them; either way no fit count is at
            stake), or None.

    Returns:
        ``(solution, info)``: the mounted solution, or ``best`` unchanged, and a dict with ``mounted``,
        ``segment``, ``reason`` (why not), ``line`` (one sentence for the log and the report) and the
        numbers behind it.
    """
    names = segment_names(pam)
    f = prob.data.fitting_length
    ci = [int(s) for s in prob.data.constraint_idx]
    seg_fn = ca.Function("segs", [prob.z], [ca.vertcat(*[_norm_rows(prob.X[a + 1] - prob.X[a])[0, ci]
                                                       for a in range(len(prob.X) - 1)])])
    seg_min = np.array(seg_fn(best.z)).reshape(len(prob.X) - 1, len(ci)).min(axis=1)
    L = np.array(ca.Function("L", [prob.z], [prob.L[0, ci]])(best.z)).ravel()
    q_check = check_poses(model, rom, prob.data.crossed or [pam.primary_coordinate], cfg.seed, pam.id)
    j_before = float(best.objective)
    info: dict = {"mounted": False, "objective_before": j_before, "rest_before_m": float(best.rest_length),
                  "tendon_before_m": float(max(best.tendon_length, 0.0))}
    # segments running through their own bone, left to the detours (``blocked``), cannot hold the PAM body
    order = [j for j in np.argsort(-seg_min) if int(j) not in blocked][:N_SEGMENTS]
    if not order:
        info.update(reason="in bone", segment=None, line="cannot sit on one straight segment: every segment runs "
                    "through its own bone (left to the detours)")
        return best, info
    need, most = reach_bound(L, float(seg_min[order[0]]), prob.d, cfg, f, prob.k)
    info.update(least_rest_m=need, segment_holds_m=most, excursion_m=float(np.ptp(L)), segment_index=int(order[0]))
    if need > most:
        info.update(reason="out of reach", segment=names[order[0]],
                    line=f"cannot sit on one straight segment: its excursion {1e3 * np.ptp(L):.0f} mm"
                         f"{f' (a {prob.k}:1 block)' if prob.k != 1 else ''} needs a "
                         f"resting length >= {need:.3f} m, the longest segment ({names[order[0]]}) holds "
                         f"{most:.3f} m at its shortest")
        return best, info
    limits = (prob.lbg.copy(), prob.ubg.copy())
    found = None
    missed: dict[str, float] = {}        # the limits the failed tries exceeded (the held-out ones included)
    try:
        for j in order:
            _, most_j = reach_bound(L, float(seg_min[j]), prob.d, cfg, f, prob.k)
            if need > most_j:
                continue
            lt0 = np.array([float(np.clip(min(best.rest_length, most_j), prob.lbx[-2], prob.ubx[-2])), 0.0])
            lt0[1] = float(np.clip(tendon_for(L.max(), lt0[0], prob.k, f), prob.lbx[-1], prob.ubx[-1]))
            ms = _MountSolver(prob, int(j), best.z, best.n_parallel)
            extra = 0.0
            sol = None
            for _ in range(2):       # solve; where the held-out poses miss a limit, tighten once and again
                sol = ms.solve(lt0, extra)
                if not sol.success:
                    for k, v in sol.violations.items():
                        if v > 1e-6:
                            missed[k] = max(missed.get(k, 0.0), v)
                    break
                cand = solution_pam(pam, prob.finalize(sol))
                excess = limit_excess(cand, model, q_check, cfg, f)
                margin = held_out_margin(cand, model, q_check, int(j), f)
                if not excess and margin >= 0:
                    break
                for k, v in excess.items():
                    missed[f"{k} (held-out poses)"] = max(missed.get(f"{k} (held-out poses)", 0.0), v)
                if margin < 0:
                    missed["PAM on one segment (held-out poses) [m]"] = max(
                        missed.get("PAM on one segment (held-out poses) [m]", 0.0), -margin)
                if excess:
                    tighten(prob, excess)
                if margin < 0:
                    extra += -margin + EXTRA * 0.1
                sol.success = False
            prob.lbg, prob.ubg = limits[0].copy(), limits[1].copy()
            if sol is not None and sol.success and (found is None or sol.objective < found[0].objective):
                found = (sol, int(j))
    finally:
        prob.lbg, prob.ubg = limits
    if found is None:
        worst = sorted(missed.items(), key=lambda kv: -kv[1])[:3]
        info.update(reason="infeasible", segment=names[order[0]], missed=dict(worst),
                    line=f"no resting/tendon length puts it on one straight segment ({', '.join(names[j] for j in order)}) "
                         f"within its limits (its excursion needs >= {need:.3f} m, {names[order[0]]} holds {most:.3f} m; "
                         f"missed: {'; '.join(f'{k} by {v:.3g}' for k, v in worst) or 'solver failure'})")
        return best, info
    sol, j = found
    cost = float(np.sqrt(max(sol.objective, 0.0)) - np.sqrt(max(j_before, 0.0)))
    info.update(segment=names[j], segment_index=j, objective_after=float(sol.objective), rest_after_m=float(sol.rest_length),
                tendon_after_m=float(max(sol.tendon_length, 0.0)), cost=cost)
    ok, accepted = cost_accepted(cost, cfg, failing, lambda: solution_pam(pam, prob.finalize(best)),
                                 lambda: solution_pam(pam, prob.finalize(sol)))
    if not ok:
        info.update(reason="fit cost",
                    line=f"on one straight segment ({names[j]}, resting length {best.rest_length:.3f} -> "
                         f"{sol.rest_length:.3f} m) its fit would get worse: objective {j_before:.4g} -> "
                         f"{sol.objective:.4g} (root +{cost:.3f} > mount_cost {cfg.mount.cost:g}); left spanning the route")
        return best, info
    info.update(mounted=True, reason="",
                line=f"on one straight segment {names[j]}: resting length {best.rest_length:.3f} -> "
                     f"{sol.rest_length:.3f} m, tendon {max(best.tendon_length, 0.0):.3f} -> "
                     f"{max(sol.tendon_length, 0.0):.3f} m, objective {j_before:.4g} -> {sol.objective:.4g}"
                     + (f" (root +{cost:.3f} > mount_cost {cfg.mount.cost:g}, accepted: {accepted})" if accepted else ""))
    if accepted:
        info["failing_fit"] = accepted
    return sol, info



#: Transmissions :func:`mount_block` tries, in this order, for a PAM the one-segment stage cannot mount at 1:1:
#: a 2:1 pulley block, and where no diameter mounts on one, a 3:1 block (a third of the stroke and force;
#: a second pulley, :func:`pamkin.robot.festo.transmission_mass`). The first ratio that mounts is kept; a diameter
#: that fits the 2:1 block only at a fit cost is not tried at 3:1 (a third of the force: measured worse at
#: every such try of the 0.1.0-dev default run, vasti 40 mm root +0.49 -> +0.66, internal oblique, psoas and
#: both gluteus medius/minimus at 20 mm).
BLOCKS = (2, 3)


#: Why the one-segment stage left a PAM spanning its route (``info["reason"]``) where :func:`mount_block` tries a
#: block: out of reach (its stroke needs a longer PAM than any segment holds) and infeasible (no length
#: keeps the strain, force or sensitivity limits on the segment: mostly the contraction, which a shorter stroke
#: eases). Not "fit cost" (the PAM fits at 1:1 but its torques get worse).
BLOCK_REASONS = ("out of reach", "infeasible")


def mount_block(prob, best, info: dict, pam: Pam, cfg, model, rom, solution_pam, blocked=frozenset(),
                failing=None) -> tuple[object, object, dict]:
    """A PAM out of reach of one straight segment of its fixed route, or infeasible there (``info`` from
    :func:`mount_stage`, :data:`BLOCK_REASONS`), on a pulley block instead (``[mount] blocks``): a
    2:1 block, and where no diameter mounts on it a 3:1 block (:data:`BLOCKS`; not for a diameter that fit
    the 2:1 block at a fit cost) — the same route and
    parallel count, the same or a larger diameter, resting length and tendon solved again with the PAM on
    one segment — 1/k of the stroke at 1/k of the force on the route (:mod:`pamkin.robot.design`, transmission) —
    by :func:`mount_stage` under its rule against the direct PAM's objective (root + <= ``mount_cost``, or a
    reason from ``failing`` to accept a larger cost, ``mount_passing``; strain, force and segment re-checked on
    the held-out poses). Of the diameters that pass at the first
    ratio that mounts, the least objective + mass penalty (the block's assumed mass included) is kept. The
    route, so its bone clearance, and the PAM units do not change.

    Returns:
        ``(solution, problem, info)``: the block's, or ``best``, ``prob`` and ``info`` unchanged (``info``
        then says what was tried).
    """
    import dataclasses  # noqa: PLC0415

    from pamkin.optimize.problem import ActuatorProblem  # noqa: PLC0415

    if not (cfg.mount.blocks and info.get("reason") in BLOCK_REASONS and prob.k == 1 and best.success):
        return best, prob, info

    direct = float(best.objective) + cfg.mass_penalty(best.diameter_mm, best.n_parallel, best.rest_length, 1)
    found, tried = None, []
    costly: set[int] = set()        # diameters that fit a smaller block only at a fit cost: not tried again
    for k in BLOCKS:
        these = []
        for d in [d for d in cfg.first_fit.diameters_mm if d >= prob.d and d not in costly]:
            pk = dataclasses.replace(pam, transmission=k, diameter_mm=d)
            p2 = ActuatorProblem(dataclasses.replace(prob.data, pam=pk), cfg, d, prob.seed, prob.regions,
                                 prob.relax, prob.bracket or None)
            start = dataclasses.replace(p2.evaluate(best.z, best.n_parallel), objective=best.objective,
                                        rest_length=best.rest_length / k)
            sol, out = mount_stage(p2, start, pk, cfg, model, rom, solution_pam, failing, blocked)
            these.append(f"{d} mm: {out.get('reason') or 'mounted'}"
                         + (f" (root +{out['cost']:.3f})" if "cost" in out else ""))
            if out.get("reason") == "fit cost":
                costly.add(d)
            if out.get("mounted"):
                score = float(sol.objective) + cfg.mass_penalty(d, best.n_parallel, sol.rest_length, k)
                if found is None or score < found[0]:
                    found = (score, sol, p2, out, k)
        if these:
            tried.append(f"with a {k}:1 pulley block on the same route: {', '.join(these)}")
        if found is not None:
            break
    if found is None:
        info = dict(info, block_tried=tried, line=info["line"] + "; " + "; ".join(tried))
        return best, prob, info
    score, sol, p2, out, k = found
    out = dict(out, transmission=k, direct=info, block_tried=tried, score_before=direct, score_after=score,
               line=f"on one straight segment {out['segment']} with a {k}:1 pulley block ({sol.diameter_mm} mm x"
                    f"{sol.n_parallel}; {info['reason']} at 1:1"
                    + (f", {tried[0].replace('with a ', 'on a ', 1)}" if k != BLOCKS[0] else "")
                    + f"): resting length {best.rest_length:.3f} -> "
                    f"{sol.rest_length:.3f} m, tendon {max(best.tendon_length, 0.0):.3f} -> "
                    f"{max(sol.tendon_length, 0.0):.3f} m, objective {best.objective:.4g} -> {sol.objective:.4g}, "
                    f"with the mass penalty {direct:.4g} -> {score:.4g}")
    return sol, p2, out


#: Mount rounds (:func:`mount_rounds`) are tried where the fixed route's mount failed on fit cost by at most
#: this multiple of ``mount_cost``, or was out of reach by at most :data:`ROUNDS_REACH` (least resting length
#: ÷ what the segment holds). The others are not tried: measured on the default run (0.1.0-dev), none of the
#: six "infeasible" PAMs passed with their points free (root cost +0.10 to +1.75); of those out of reach, the
#: two between 8 and 15 % (flexor digitorum longus 1.11, vasti 1.10) were tried in vain (43 s of worker time)
#: and the others need 31-83 % more segment than they have.
ROUNDS_COST_FACTOR = 2.0
ROUNDS_REACH = 1.08
#: ... or was infeasible only because the PAM overran the segment, by at most this much [m] (the points
#: free can lengthen the segment; measured at 0.1.0-dev on the internal oblique, 3.7 mm short on its fixed route).
ROUNDS_SEGMENT_MISS = 0.01
#: Bone rounds of a mount try, and their first trust region [m] (smaller than the bone stage's: the route is
#: already clear of bone; a 20 mm first step cost the flexor digitorum longus two 10 s solves at the CPU cap).
ROUNDS = 5
ROUNDS_TRUST = 0.005
#: Their largest trust region [m] (rounds at the bone stage's 30 mm failed at the CPU cap: 15 s each).
ROUNDS_TRUST_MAX = 0.015
#: The rounds give up when the fit cost left above ``mount_cost`` (in the objective's root) is more than this
#: many times what the last round gained.
ROUNDS_PACE = 2.0


def mount_rounds(prob, best, info: dict, pam: Pam, cfg, cuts, model, rom, solution_pam, failing=None):
    """The PAM on one straight segment with its route free: bone rounds with the one-segment rows.

    Where :func:`mount_stage` could not mount the PAM on its fixed route at a small enough cost (``info``;
    see :data:`ROUNDS_COST_FACTOR`, :data:`ROUNDS_REACH`), the bone-mesh rounds
    (:func:`optimize.bone_cuts.bone_stage`, the actuator's bone-check poses ``cuts``) run once more from the
    solved route on the same problem with the PAM on that segment at every constraint sample
    (:meth:`optimize.problem.ActuatorProblem.with_mount`): the points may move (lengthening the segment,
    reshaping the moment arms) within their bone rows and brackets. The result replaces ``best`` when it is
    feasible, no deeper into bone (and no point inside its bone), keeps the strain and force limits and the
    segment on the held-out limit-check poses, and the root of the fit objective grows by at most
    ``cfg.mount.cost`` over ``best``'s.

    Returns:
        ``(solution, problem, info)``: the mounted solution and its problem, or ``best``, ``prob`` and
        ``info`` with a note of the try (``rounds``: what was tried and why it was not kept).
    """
    reason = info.get("reason")
    j = info.get("segment_index")
    if j is None or not best.success:
        return best, prob, info
    if reason == "fit cost":
        if info["cost"] > ROUNDS_COST_FACTOR * cfg.mount.cost:
            return best, prob, info
    elif reason == "out of reach":
        if info["least_rest_m"] > ROUNDS_REACH * info["segment_holds_m"]:
            return best, prob, info
    elif reason == "infeasible":
        missed = info.get("missed") or {}
        if not missed or any(not k.startswith("PAM on one segment") or v > ROUNDS_SEGMENT_MISS
                             for k, v in missed.items()):
            return best, prob, info
    else:
        return best, prob, info

    t0 = time.perf_counter()
    names = segment_names(pam)
    f = prob.data.fitting_length
    p1 = prob.with_mount(int(j))
    start = p1.evaluate(best.z, best.n_parallel)
    keep = set(cuts.keep)
    cuts.keep = keep | {int(j)}          # the PAM's own segment sees its own bone (never left to a detour)
    m0 = cuts.measure(np.array(best.points))
    q_check = check_poses(model, rom, prob.data.crossed or [pam.primary_coordinate], cfg.seed, pam.id)
    seg_rows = np.array([fam.startswith("PAM fits on segment") for fam in p1.family])
    limits = (p1.lbg.copy(), p1.ubg.copy())
    log: list[str] = []
    sol, cost, why, accepted = start, np.inf, "no feasible round", None
    target = np.sqrt(max(best.objective, 0.0)) + cfg.mount.cost       # the root objective to reach

    def slow(previous, latest) -> bool:
        left = np.sqrt(max(latest.objective, 0.0)) - target
        gained = np.sqrt(max(previous.objective, 0.0)) - np.sqrt(max(latest.objective, 0.0))
        if left > ROUNDS_PACE * max(gained, 0.0):
            log.append(f"  given up: root objective {left:.3f} above the mount cost's, the last round gained {gained:.3f}")
            return True
        return False

    try:
        for _ in range(2):      # the rounds; where the held-out poses miss a limit, tightened once and again
            sol, m, _ = bone_stage(p1, sol, cuts, ROUNDS, log, trust=ROUNDS_TRUST, trust_max=ROUNDS_TRUST_MAX,
                                   extra_rounds=0, give_up=slow)
            if not sol.success or sol is start:
                why = "no feasible round"
                break
            if m.violation() > m0.violation() + 1e-9 or m.point_inside_bone():
                why = f"deeper into bone ({1e3 * m.violation():.2f} mm, before {1e3 * m0.violation():.2f} mm)"
                break
            cost = float(np.sqrt(max(sol.objective, 0.0)) - np.sqrt(max(best.objective, 0.0)))
            cand = solution_pam(pam, p1.finalize(sol))
            ok, accepted = cost_accepted(cost, cfg, failing, lambda: solution_pam(pam, prob.finalize(best)),
                                         lambda: cand)
            if not ok:
                why = (f"fit cost: objective {best.objective:.4g} -> {sol.objective:.4g} "
                       f"(root +{cost:.3f} > mount_cost {cfg.mount.cost:g})")
                break
            excess = limit_excess(cand, model, q_check, cfg, f)
            margin = held_out_margin(cand, model, q_check, int(j), f)
            if not excess and margin >= 0:
                why = ""
                break
            why = "held-out poses: " + "; ".join([f"{k} exceeded by {v:.3g}" for k, v in excess.items()]
                                                 + ([f"PAM off its segment by {1e3 * -margin:.1f} mm"] if margin < 0 else []))
            tighten(p1, excess)
            if margin < 0:
                p1.lbg[seg_rows] += -margin + EXTRA * 0.1
    finally:
        p1.lbg, p1.ubg = limits
        cuts.keep = keep
    moved = float(np.max(np.abs(np.asarray(sol.points) - np.asarray(best.points)))) if sol.success else 0.0
    out = dict(info)
    rounds = {"segment": names[j], "seconds": round(time.perf_counter() - t0, 2), "log": log,
              "objective_after": float(sol.objective), "kept": not why, "why_not": why}
    out["rounds"] = rounds
    if why:
        out["line"] = info["line"] + f"; with its points free (bone rounds on {names[j]}): not kept, {why}"
        return best, prob, out
    out.update(mounted=True, reason="", segment=names[j], objective_after=float(sol.objective),
               rest_after_m=float(sol.rest_length), tendon_after_m=float(max(sol.tendon_length, 0.0)), cost=cost,
               line=f"on one straight segment {names[j]} with its points moved (bone rounds with the PAM on it, "
                    f"points up to {1e3 * moved:.1f} mm): resting length {best.rest_length:.3f} -> "
                    f"{sol.rest_length:.3f} m, tendon {max(best.tendon_length, 0.0):.3f} -> "
                    f"{max(sol.tendon_length, 0.0):.3f} m, objective {best.objective:.4g} -> {sol.objective:.4g} "
                    + (f"(root +{cost:.3f} > mount_cost {cfg.mount.cost:g}, accepted: {accepted}) " if accepted else "")
                    + f"(was {reason}: {info['line']})")
    if accepted:
        out["failing_fit"] = accepted
    return sol, p1, out
