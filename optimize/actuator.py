"""One actuator's solves, run in the workers: the first phase (outer loop over Festo diameter and
parallel count, multistart), the chosen size's bone-mesh rounds and one-segment stage, and the
second-pass solves of the PAM-PAM and roller stages. Every function takes the run's context first."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from pamkin.optimize.bone_cuts import (
    N_POINT_CHECK,
    BoneCuts,
    bone_check_poses,
    bone_stage,
    point_contact_poses,
    push_out,
    stage_key,
)
from pamkin.optimize.config import RunConfig
from pamkin.optimize.context import RunContext
from pamkin.optimize.limit_check import (
    RATED,
    check_poses,
    limit_excess,
    rated_bound,
    tighten,
)
from pamkin.optimize.results import (
    CAPPED_STATUSES,
    ActuatorResult,
    attempt_entry,
    bone_info,
    make_result,
    solution_pam,
)
from pamkin.optimize.validation import validation_error

from pamkin.robot import festo
from pamkin.robot.design import Pam, rescale_for_transmission
from pamkin.robot.rollers import open_ended

#: Leave out diameter / parallel-count tries whose mass penalty alone scores more than a feasible try with at
#: most as many PAMs (they could never be chosen, by the actuator or by the unit budget).
PRUNE_DOMINATED = True


#: A larger diameter whose solve from the seed route stopped at IPOPT's CPU-time or iteration cap is solved once
#: more from the best feasible diameter's fit (its route, resting and tendon length) where that fit's PAM reaches
#: :data:`RETRY_FORCE_RATIO` of its rated force (only there can more force help): IPOPT from the seed may not
#: converge in time where that fit is a good start (peroneus brevis at 20 mm in the default run). Retrying every
#: capped diameter (measured, default run): 664 s instead of 578 s, one more retry of five gaining.
RETRY_CAPPED = True


#: Peak force per PAM over its rated force (at the training samples) from which a larger diameter is retried.
RETRY_FORCE_RATIO = 0.9


def solve_actuator(ctx: RunContext, task: tuple[int, int]) -> ActuatorResult:
    """Outer loop (diameter, n_parallel) and multi-start for one actuator (runs in a worker)."""
    from pamkin.optimize.problem import ActuatorProblem  # noqa: PLC0415  (casadi only in workers / optimiser)

    k, seed_index = task
    cfg: RunConfig = ctx.cfg
    data = ctx.data[k]
    pam: Pam = data.pam
    t0 = time.perf_counter()
    # decision variables: locations of body-fixed points, offsets (seed 0) of moving points
    seed, regions = ctx.route_box(pam)
    attempts, best = [], None
    candidates: dict = {}
    problems: dict = {}
    best_problem: list = [None]
    best_score = [np.inf]

    def mass_penalty(d: int, n: int, rest: float) -> float:
        """The objective's mass penalty of n PAMs of diameter d and resting length ``rest`` (both sides)."""
        return cfg.mass_penalty(d, n, rest, pam.transmission)

    def score(sol) -> float:
        """Objective plus the mass penalty of the PAMs on the route."""
        return sol.objective + mass_penalty(sol.diameter_mm, sol.n_parallel, sol.rest_length)

    def problem(d: int, relax=frozenset(), mount: int | None = None):
        if (d, relax, mount) not in problems:
            problems[(d, relax, mount)] = ActuatorProblem(data, cfg, d, seed, regions, relax,
                                                          ctx.bracket(pam, seed, regions), mount)
        return problems[(d, relax, mount)]

    def attempt(d: int, n: int, points, rest, tendon, label: str, relax=frozenset(), evaluate: bool = False,
                mount: int | None = None):
        nonlocal best
        prob = problem(d, relax, mount)
        z0 = prob.initial_guess(points, rest, tendon)
        sol = prob.evaluate(z0, n) if evaluate else prob.solve(z0, n)
        sol.mount_segment = mount       # the phase after the unit budget solves the same problem
        attempts.append({"diameter_mm": d, "n_parallel": n, "start": label, "status": sol.status,
                         "objective": sol.objective, "feasible": sol.success, "seconds": round(sol.seconds, 3),
                         "relaxed": sorted(relax)})
        sc = score(sol)
        if sol.success and sc < candidates.get((d, n), (np.inf,))[0]:
            candidates[(d, n)] = (sc, sol, relax)
        better = best is None or (sol.success and not best.success) or \
            (sol.success == best.success and sc < best_score[0] - 1e-12)
        if better:
            best = sol
            best_score[0] = sc
            best_problem[0] = prob
        return sol

    skipped: list[str] = []

    def dominated(d: int, n: int) -> bool:
        """(d, n) cannot be chosen, here or by the unit budget: its mass penalty alone (objective >= 0, resting
        length >= Festo's shortest, or the fixed one) scores more than a feasible try with at most n PAMs."""
        if not PRUNE_DOMINATED:
            return False
        low = mass_penalty(d, n, pam.resting_length_m if cfg.limits.fix_lengths else festo.nominal_length_range(d)[0])
        by = [key for key, (sc, _, _) in candidates.items() if key[1] <= n and sc < low]
        if by:
            skipped.append(f"{d} mm x{n} (its mass alone scores {low:.4g}, more than {by[0][0]} mm x{by[0][1]})")
        return bool(by)

    def peak_force_ratio(sol) -> float:
        """Largest force per PAM of a solution at the training samples over its rated force (0: not bounded)."""

        prob = problem(sol.diameter_mm, relaxed)
        rows = np.array([f == RATED for f in prob.family], dtype=bool)
        if not rows.any():
            return 0.0
        g = prob._values(sol.z, sol.n_parallel)[1]          # the rows: force per PAM - rated_bound
        return float(np.max(g[rows]) + rated_bound(sol.diameter_mm)) / festo.F_MAX_THEORETICAL[sol.diameter_mm]

    relaxed: frozenset = frozenset()
    # warm start from a run folder: its diameter and count first; the full loop only if that fails. With
    # the bone meshes, a warm route that meets this run's own constraints is taken as it is (it was cleared
    # of bone in its run): the bone-mesh rounds then improve the fit from there, instead of from a fresh
    # fit that the rounds would have to pull out of bone again.
    # A warm PAM that sits on one straight segment keeps it: its problem has the one-segment rows there.
    warm_ok = False
    if pam.id in ctx.warm_ids and pam.diameter_mm in cfg.first_fit.diameters_mm \
            and pam.n_parallel <= cfg.first_fit.max_parallel:
        warm = (pam.diameter_mm, pam.n_parallel, seed, pam.resting_length_m, pam.tendon_length_m)
        on = None
        if cfg.mount.enabled and not cfg.one_segment_for(pam.id):
            from pamkin.optimize.mount import mounted_segment  # noqa: PLC0415

            p0 = problem(pam.diameter_mm)
            on = mounted_segment(p0, p0.initial_guess(seed, pam.resting_length_m, pam.tendon_length_m))
        if cfg.bone_rounds.enabled:
            warm_ok = attempt(*warm, "warm start (as given)", evaluate=True, mount=on).success
        if not warm_ok:
            warm_ok = attempt(*warm, "warm start", mount=on).success
    if not warm_ok:
        same_seed = (pam.diameter_mm, pam.n_parallel)
        results = {}
        for d in cfg.first_fit.diameters_mm:
            if dominated(d, 1):
                continue
            warm = (pam.resting_length_m, pam.tendon_length_m) if (d, 1) == same_seed else (None, None)
            results[(d, 1)] = attempt(d, 1, seed, *warm, "seed")
        optional = [name for name, on in (("one_segment", cfg.one_segment_for(pam.id)),
                                          ("sensitivity", cfg.limits.sensitivity_pct > 0)) if on]
        for k in range(1, len(optional) + 1):
            if any(s.success for s in results.values()):
                break
            # the PAM cannot sit on one straight segment of this route (then, also not keep the sensitivity
            # limit) within the other limits: say so (``relaxed``), solve without them
            relaxed = frozenset(optional[:k])
            for d in cfg.first_fit.diameters_mm:
                results[(d, 1)] = attempt(d, 1, seed, None, None, "seed", relaxed)
        feasible = {key: s for key, s in results.items() if s.success}
        if feasible and RETRY_CAPPED:
            start = feasible[min(feasible, key=lambda key: score(feasible[key]))]
            strong = peak_force_ratio(start) >= RETRY_FORCE_RATIO
            for key, s in list(results.items()):
                if (strong and key[0] > start.diameter_mm and not s.success and s.status in CAPPED_STATUSES
                        and not dominated(*key)):
                    results[key] = attempt(*key, start.points, start.rest_length, start.tendon_length,
                                           f"{start.diameter_mm} mm fit (the seed start stopped at a cap)", relaxed)
                    if results[key].success:
                        feasible[key] = results[key]
        if feasible:
            d_best = min(feasible, key=lambda key: score(feasible[key]))[0]
            prev = feasible[(d_best, 1)]
            for n in range(2, min(cfg.first_fit.max_parallel, ctx.n_cap) + 1):
                if dominated(d_best, n):
                    break
                s = attempt(d_best, n, prev.points, prev.rest_length, prev.tendon_length, "seed", relaxed)
                if not (s.success and score(s) < 0.95 * score(prev)):
                    break
                prev = s
        if best is not None and best.success and best.objective > cfg.first_fit.multistart_threshold:
            rng = np.random.default_rng(cfg.seed + 1000 * pam.id + seed_index)
            for m in range(cfg.first_fit.multistart):
                pts = [p + rng.uniform(-0.5, 0.5, 3) * r for p, r in zip(best.points, regions)]
                attempt(best.diameter_mm, best.n_parallel, pts, None, None, f"perturbed {m + 1}", relaxed)
    assert best is not None
    if ctx.fit_only:        # unit budget: the bone-mesh rounds follow the global choice
        out = make_result(pam, data, best_problem[0], best, attempts, t0, {})
        out.candidates = candidates
        out.skipped = skipped
        out.warm = warm_ok
        return out
    best, bone, cuts = bone_rounds(ctx, best_problem[0], best, pam, cfg)
    best, prob, mount, direct = mount_actuator(ctx, best_problem[0], best, pam, cfg, cuts, blocks=not warm_ok)
    return mounted_result(pam, data, prob, best, mount, direct, attempts, t0, bone, skipped)


#: The bone-mesh rounds start once more from the seed route unless the first result is clear of bone with
#: an objective at most this (NRMSE about 0.1: on the default run no such route gained from it).
SEED_START_SKIP = 0.01


#: Held-out limit checks of an actuator (optimize.limit_check): before the bone-mesh rounds, then after them.
LIMIT_CHECK_ROUNDS = 2


def bone_rounds(ctx: RunContext, prob, best, pam: Pam, cfg: RunConfig):
    """The bone-mesh stage of a solved actuator (when ``cfg.bone_rounds.enabled``): (solution, bone info, its
    :class:`~optimize.bone_cuts.BoneCuts` or None). A warm start taken as given (already through these rounds
    in its run) stays unless a round beats it, and where it keeps every strain and force limit at the held-out
    limit-check poses, also when the rounds' result ends over one of them (no deeper into bone)."""
    if not (cfg.bone_rounds.enabled and best.success):
        return best, {}, None

    q_bone, n_right = bone_check_poses(ctx.human, ctx.rom, pam, cfg.seed, crossed=prob.data.crossed)
    cuts = BoneCuts(pam, ctx.human, ctx.bones, q_bone, n_right)
    # same-body segments too short to hold the PAM body are carried round their own bone afterwards
    # (detour_pass): the rounds leave that bone out for them
    below = detour_below(pam, prob, best, cfg)
    cuts.detour_below = below
    lines: list[str] = []
    before = best
    # the strain and force limits on many more poses than the problem's samples (optimize.limit_check):
    # where the start exceeds one, it is tightened before the rounds; where their result still does, once
    # more and the rounds again. The problem's own limits are restored afterwards (the tightening is a
    # margin of this search, not a different problem: the saved result is checked against the real limits)

    q_check = check_poses(ctx.human, ctx.rom, prob.data.crossed or [pam.primary_coordinate],
                          cfg.seed, pam.id)
    limits = (prob.lbg.copy(), prob.ubg.copy())

    def excess_of(sol) -> dict:
        return limit_excess(solution_pam(pam, prob.finalize(sol)), ctx.human, q_check, cfg,
                            prob.data.fitting_length)

    def note(excess: dict, what: str) -> None:
        lines.append(f"  limit check on {len(q_check)} more poses: " + "; ".join(
            f"{k} exceeded by {v:.4g}" for k, v in excess.items()) + f"; {what}")

    excess = excess_of(best)
    warm_ok = best.status == "given" and not excess      # a warm start within every limit at the check poses
    if excess:
        note(excess, "limits tightened before the bone rounds")
        tighten(prob, excess)
    warm = best.status == "given"
    best, measure, info = bone_stage(prob, best, cuts, cfg.bone_rounds.rounds, lines, keep_start=warm)
    if cfg.bone_rounds.seed_start and not warm and not (measure.violation() == 0.0 and best.objective <= SEED_START_SKIP):
        best, measure, info = seed_start(prob, best, measure, info, cuts, cfg, lines)
    for _ in range(LIMIT_CHECK_ROUNDS - 1):
        excess = excess_of(best)
        if not excess:
            break
        note(excess, "limits tightened, bone rounds again")
        tighten(prob, excess)
        best, measure, more = bone_stage(prob, best, cuts, cfg.bone_rounds.rounds, lines)
        info += more
    # attachment points against the other bones at many more poses: where one comes near, those poses
    # join the bone-check poses (right-leg poses, first) and the rounds run again
    extra = point_contact_poses(ctx.human, ctx.bones, ctx.rom,
                                solution_pam(pam, prob.finalize(best)), cfg.seed)
    if len(extra):
        lines.append(f"  attachment point within 3 mm of another bone at {len(extra)} (the closest) of "
                     f"{N_POINT_CHECK} more random poses: added to the bone-check poses, bone rounds again")
        cuts = BoneCuts(pam, ctx.human, ctx.bones, np.vstack([extra, q_bone]), n_right + len(extra))
        cuts.detour_below = below
        best, measure, more = bone_stage(prob, best, cuts, cfg.bone_rounds.rounds, lines)
        info += more
    prob.lbg, prob.ubg = limits
    best, pushed, moved, outcome = push_out(prob, best, cuts)
    if moved:
        lines.append(f"  points {', '.join(moved)} inside their bone: {outcome}")
        if outcome.startswith("moved"):
            measure = pushed
    excess = excess_of(best)
    if excess:
        lines.append("  limit check: still exceeded: " + "; ".join(f"{k} by {v:.4g}" for k, v in excess.items()))
        if warm_ok and best is not before:
            # a warm start taken as given went through these rounds in its own run and kept every limit here:
            # a continuation that exceeds one is not kept (a warm re-run never makes a route worse in that)
            m0 = cuts.measure(np.array(before.points))
            if m0.violation() <= measure.violation() + 1e-9 and not m0.point_inside_bone():
                lines.append("  kept the warm start as given: it keeps every limit at the check poses and is no "
                             f"deeper into bone ({1e3 * m0.violation():.2f} mm; the rounds' result "
                             f"{1e3 * measure.violation():.2f} mm)")
                best, measure = before, m0
    bone = bone_info(cuts, before, measure, info, lines, [p.name for p in pam.points])
    bone.update(objective_before=float(before.objective), objective_after=float(best.objective))
    return best, bone, cuts


def detour_below(pam: Pam, prob, sol, cfg: RunConfig) -> float:
    """Length [m] below which a same-body segment of ``pam`` could never hold its PAM body, whatever resting
    length, diameter or pulley block the one-segment stage and the passes after it choose: the least resting
    length the route's excursion at ``sol`` allows (its stroke over Festo's largest contraction plus the
    stretch limit, on the largest block the run may use) plus both fittings and the segment margin. Such
    segments are left to :func:`detour_pass` (0 without detours)."""
    if not (cfg.detours.enabled and sol.success):
        return 0.0
    import casadi as ca  # noqa: PLC0415
    from pamkin.optimize.mount import BLOCKS  # noqa: PLC0415
    from pamkin.optimize.problem import SEGMENT_MARGIN  # noqa: PLC0415

    ci = [int(s) for s in prob.data.constraint_idx]
    L = np.array(ca.Function("L", [prob.z], [prob.L[0, ci]])(sol.z)).ravel()
    k = max([prob.k, *(BLOCKS if cfg.mount.enabled and cfg.mount.blocks else ())])
    stretch = cfg.limits.pretension_scale * max(festo.max_pretension(d) for d in cfg.first_fit.diameters_mm)
    # the contraction limit is Festo's rated one at most (reach_bound); without it, no bound below 100 %
    c = max(festo.max_contraction(d) for d in cfg.first_fit.diameters_mm) if cfg.limits.rated_force else 1.0
    least = float(np.ptp(L)) / (k * (c + stretch))
    return float(least + 2 * prob.data.fitting_length + SEGMENT_MARGIN)


def seed_start(prob, best, measure, info: list, cuts, cfg: RunConfig, lines: list[str]):
    """The bone-mesh rounds once more, from the seed route with its points moved onto their bone's band
    (:meth:`optimize.bone_cuts.BoneCuts.pull_in`) and lengths sized to it: the fitted route the first
    rounds start from may lie far from bone (the rounds then crawl to a poor local fit). The better
    result (:func:`optimize.bone_cuts.stage_key`) is kept; ``(solution, measure, rounds_info)``."""

    npt = cuts.n_points
    pulled = cuts.pull_in(np.array(prob.seed, float).reshape(npt, 3), reach=0.0, zmin=prob.zmin)
    z = prob.initial_guess(list(pulled), None, None)
    z[:3 * npt] = pulled.ravel()
    start = prob.evaluate(z, best.n_parallel)
    lines.append("  bone rounds from the seed route:")
    s, m, more = bone_stage(prob, start, cuts, cfg.bone_rounds.rounds, lines)
    info = info + [{"start": "seed"}] + more
    if s.success and (not best.success or stage_key(m, s) < stage_key(measure, best)):
        lines.append(f"  kept the seed-route result (violation {1e3 * m.violation(0.0):.2f} mm, "
                     f"objective {s.objective:.4g}; fitted-route start {1e3 * measure.violation(0.0):.2f} mm, "
                     f"{best.objective:.4g})")
        return s, m, info
    lines.append(f"  kept the fitted-route result (violation {1e3 * measure.violation(0.0):.2f} mm, objective "
                 f"{best.objective:.4g}; seed-route start {1e3 * m.violation(0.0):.2f} mm, {s.objective:.4g}"
                 f"{'' if s.success else ', infeasible'})")
    return best, measure, info


def finish_actuator(ctx: RunContext, k: int) -> ActuatorResult:
    """Second phase of a run with a unit budget (in a worker): the chosen diameter and parallel count
    of actuator ``k`` (``ctx.choice``) from its first-phase fit, then the bone-mesh rounds."""
    return finish_choice(ctx, (k, ctx.choice[k], None))


def finish_choice(ctx: RunContext, task: tuple) -> ActuatorResult:
    """Actuator ``k`` with diameter and parallel count ``key`` (task ``(k, key, z)``), then the bone-mesh
    rounds (in a worker). It starts from the first phase's fit of ``key``; where the first phase has no
    feasible fit of ``key`` (it tries only some counts), from decision vector ``z`` (a solved route), re-fitted
    with ``key`` first. Returns the first phase's result when ``key`` is None, a failed result when the
    re-fit is infeasible.

    A task ``(k, key, z, t)`` puts the PAM on a ``t``:1 pulley block throughout (:func:`block_start`): the
    first phase's fit of ``key`` (else ``z``) re-fitted with the block, then the bone rounds and the
    one-segment stage with it. A task ``(k, key, z, t, start[, keep])`` (``t`` the seed's ratio: no block)
    always starts from ``z``, named ``start`` in the attempts: the route as it is where it meets every limit
    with ``key`` (status "given", as a warm start), else solved from it, else from its points with the
    lengths sized afresh (:meth:`~optimize.problem.ActuatorProblem.initial_guess`); with ``keep`` true a PAM
    on one straight segment at ``z`` is solved with that segment's rows (it stays on it)."""
    from pamkin.optimize.problem import ActuatorProblem  # noqa: PLC0415

    k, key, z_start, *more = task
    t0 = time.perf_counter()
    cfg: RunConfig = ctx.cfg
    data = ctx.data[k]
    first: ActuatorResult = ctx.first[k]
    pam: Pam = data.pam
    if key is None:                   # nothing feasible: the first phase's (failed) result stands
        return first
    seed, regions = ctx.route_box(pam)
    t = 1                             # a block throughout: its ratio (the attempt says so)
    if more and more[0] != pam.transmission:
        t = int(more[0])
        k0 = pam.transmission
        pam = dataclasses.replace(pam, transmission=t)
        data = dataclasses.replace(data, pam=pam)
        relax = frozenset(first.candidates[key][2] if key in first.candidates else first.relaxed)
        prob = ActuatorProblem(data, cfg, key[0], seed, regions, relax, ctx.bracket(pam, seed, regions))
        z = first.candidates[key][1].z if key in first.candidates else z_start
        sol = prob.solve(block_start(prob, z, k0, t, data.fitting_length), key[1])
        start = f"{BONE_RESIZE_START} ({t}:1)"
        if not sol.success:
            return make_result(pam, data, prob, sol, first.attempts + [attempt_entry(key, start, sol, relax, t)],
                           t0 - first.seconds, {})
    elif key in first.candidates and len(more) < 2:
        _, sol, relax = first.candidates[key]
        prob = ActuatorProblem(data, cfg, key[0], seed, regions, relax, ctx.bracket(pam, seed, regions),
                               sol.mount_segment)
        start = "unit budget choice"
    else:
        relax = frozenset(first.relaxed)
        prob = ActuatorProblem(data, cfg, key[0], seed, regions, relax, ctx.bracket(pam, seed, regions))
        if len(more) > 1:
            # the solved route as it is, with the new count, where it meets every limit (as a warm start taken
            # as given: the bone rounds go on from a route already clear of bone), else solved from it; with
            # ``keep``, a PAM on one straight segment keeps it (the problem has its one-segment rows, as a warm
            # start's), else the one-segment stage puts it on one again
            start, keep = more[1], len(more) > 2 and bool(more[2])
            if keep and cfg.mount.enabled and not cfg.one_segment_for(pam.id):
                from pamkin.optimize.mount import mounted_segment  # noqa: PLC0415

                on = mounted_segment(prob, np.asarray(z_start, float))
                if on is not None:
                    prob = ActuatorProblem(data, cfg, key[0], seed, regions, relax, ctx.bracket(pam, seed, regions),
                                           on)
            given = prob.evaluate(np.asarray(z_start, float), key[1])
            sol = given if given.success else prob.solve(np.clip(np.asarray(z_start, float), prob.lbx, prob.ubx),
                                                          key[1])
            if not sol.success:       # a second start: the route's points, its lengths sized afresh for them
                sol = prob.solve(prob.initial_guess(given.points, None, None), key[1])
        else:
            start = "walking check (from the solved route)"
            sol = prob.solve(np.clip(np.asarray(z_start, float), prob.lbx, prob.ubx), key[1])
        if not sol.success:
            return make_result(pam, data, prob, sol, first.attempts, t0 - first.seconds, {})
    best, bone, cuts = bone_rounds(ctx, prob, sol, pam, cfg)
    best, prob, mount, direct = mount_actuator(ctx, prob, best, pam, cfg, cuts, blocks=not first.warm)
    attempts = first.attempts + [attempt_entry(key, start, sol, relax, t)]
    return mounted_result(pam, data, prob, best, mount, direct, attempts, t0 - first.seconds, bone, first.skipped)


def block_start(prob, z: np.ndarray, k0: int, k: int, fitting_length: float) -> np.ndarray:
    """Decision vector ``z`` of a ``k0``:1 solve as a start for ``prob``, a ``k``:1 one: the same route, the
    resting length and tendon that keep the PAM's strain at every route length
    (:func:`pamkin.robot.design.rescale_for_transmission`); clipped to the bounds."""

    z = np.array(z, float)
    z[-2], z[-1] = rescale_for_transmission(float(z[-2]), float(z[-1]), k0, k, fitting_length)
    return np.clip(z, prob.lbx, prob.ubx)


def mount_actuator(ctx: RunContext, prob, best, pam: Pam, cfg: RunConfig, cuts=None, blocks: bool = True):
    """The one-segment stage of a solved actuator (when ``cfg.mount.enabled``; :mod:`optimize.mount`): on its fixed
    route, and where that fails narrowly, with the bone rounds (``cuts``) and the PAM on the segment
    (:func:`optimize.mount.mount_rounds`), then on a pulley block (:func:`optimize.mount.mount_block`) unless
    ``blocks`` is False: an actuator whose warm start was kept keeps its warm size, transmission included
    (its run tried the blocks; the mass budget may have taken one off again, and a warm run would put it on
    again only to take it off). Returns (solution, its problem, mount info, direct), ``direct``
    the (solution, problem, mount info) before a pulley block where the stage put the PAM on one (else None)."""
    if not (cfg.mount.enabled and best.success):
        return best, prob, {}, None
    from pamkin.optimize.mount import (  # noqa: PLC0415
        BLOCK_REASONS,
        mount_block,
        mount_rounds,
        mount_stage,
    )

    # made only where a fit cost is weighed (the validation errors of this actuator's crossed coordinates)
    def rule(already_failing: bool, still_passing: bool):
        return lambda a, b: ctx.failing_fit(list(prob.data.crossed or []), already_failing, still_passing)(a, b)

    failing = rule(cfg.mount.failing, cfg.mount.passing) if cfg.mount.failing or cfg.mount.passing else None
    blocked = frozenset(cuts.in_own_bone(np.array(best.points))) if cuts is not None else frozenset()
    best, info = mount_stage(prob, best, pam, cfg, ctx.human, ctx.rom, solution_pam, failing, blocked)
    if not info.get("mounted") and cuts is not None:
        best, prob, info = mount_rounds(prob, best, info, pam, cfg, cuts, ctx.human, ctx.rom,
                                        solution_pam, failing)
    direct = None
    if not info.get("mounted") and not blocks:
        if cfg.mount.blocks and info.get("reason") in BLOCK_REASONS and prob.k == 1:
            info = dict(info, line=info["line"] + "; no pulley block tried (warm start: its transmission kept)")
    elif not info.get("mounted"):
        before = (best, prob, info)
        # on a block only mount_passing (the mounted PAM's own errors): mount_failing on blocks too, measured at
        # 0.1.0-dev, mounted tensor fasciae latae and internal oblique at a large fit cost and the run's later
        # passes (re-sizing, mass budget) moved other PAMs: 9 audit limits failed instead of 6
        passing = rule(False, True) if cfg.mount.passing else None
        best, prob, info = mount_block(prob, best, info, pam, cfg, ctx.human, ctx.rom, solution_pam,
                                       blocked, passing)
        if info.get("transmission", 1) > 1:
            direct = before
    return best, prob, info, direct


def mounted_result(pam: Pam, data, prob, best, mount: dict, direct, attempts: list, t0: float, bone: dict,
                    skipped: list) -> ActuatorResult:
    """The saved result after the one-segment stage (:func:`mount_actuator`), with the result from before its pulley
    block as ``direct`` where the stage put the PAM on one (:func:`mass_pass` may go back to it)."""
    out = make_result(pam, data, prob, best, attempts, t0, bone, mount)
    out.skipped = list(skipped)
    if direct is not None:
        out.direct = make_result(pam, data, direct[1], direct[0], [dict(a) for a in attempts], t0, bone, direct[2])
        out.direct.skipped = list(skipped)
    return out


#: ``start`` of the attempt :func:`resize_pass` adds to an actuator's attempts (a block try: with its ratio).
BONE_RESIZE_START = "resize after the bone rounds"


def clear_actuator(ctx: RunContext, k: int) -> ActuatorResult:
    """PAM–PAM pass of one actuator (in a worker): from its first-pass solution, the bone-mesh rounds
    again with the other PAMs' bodies (first-pass design, fixed) as obstacles."""
    from pamkin.optimize.problem import ActuatorProblem

    t0 = time.perf_counter()
    cfg: RunConfig = ctx.cfg
    data = ctx.data[k]
    first: ActuatorResult = ctx.first[k]
    pam: Pam = data.pam
    seed, regions = ctx.route_box(pam)
    prob = ActuatorProblem(data, cfg, first.pam.diameter_mm, seed, regions, frozenset(first.relaxed),
                           ctx.bracket(pam, seed, regions))
    sol = prob.evaluate(first.z, first.n_parallel)
    q, n_right, bodies, radius, mount = ctx.obstacles[k]
    cuts = BoneCuts(pam, ctx.human, ctx.bones, q, n_right)
    cuts.set_obstacles(bodies, radius, mount)
    cuts.detour_below = detour_below(pam, prob, sol, cfg)       # as in the first pass's rounds
    lines = ["  PAM-PAM pass:"]
    best, measure, info = bone_stage(prob, sol, cuts, cfg.bone_rounds.rounds, lines)
    bone = bone_info(cuts, sol, measure, info, first.bone.get("log", []) + lines, [p.name for p in pam.points])
    attempts = first.attempts + [{"diameter_mm": best.diameter_mm, "n_parallel": best.n_parallel,
                                  "start": "PAM-PAM pass", "status": best.status, "objective": best.objective,
                                  "feasible": bool(best.success), "seconds": round(time.perf_counter() - t0, 3),
                                  "relaxed": sorted(first.relaxed)}]
    return make_result(pam, data, prob, best, attempts, t0 - first.seconds, bone)


def roller_actuator(ctx: RunContext, k: int) -> ActuatorResult:
    """The roller stage of one actuator (in a worker; :mod:`optimize.rollers`): the bracket-only fit from its
    result, rollers where that fit's segments go into bone, solved with them and checked exactly; the result
    with rollers where it lowers the validation error, else the result as it was (its log says why)."""
    from pamkin.optimize.problem import FEASIBILITY_TOL, ActuatorProblem  # noqa: PLC0415
    from pamkin.optimize.rollers import (  # noqa: PLC0415
        DEPTH_LIMIT,
        GAP,
        LENGTHS,
        MAX_DEPTH,
        MIN_GAIN,
        PLACE_ROUNDS,
        depths,
        place,
        roller_data,
        size_rollers,
    )

    t0 = time.perf_counter()
    cfg: RunConfig = ctx.cfg
    human, bones, design = ctx.human, ctx.bones, ctx.seed_design
    r: ActuatorResult = ctx.first[k]
    data0 = ctx.data[k]
    data = dataclasses.replace(data0, pam=dataclasses.replace(data0.pam, transmission=r.pam.transmission))
    seed, regions = ctx.route_box(data0.pam)
    relax = frozenset(r.relaxed)
    q_bone, n_right = bone_check_poses(human, ctx.rom, data0.pam, cfg.seed, crossed=data.crossed)
    q_val, T_val = ctx.validation_set()
    crossed = list(data.crossed or [])

    def error(pam: Pam) -> tuple[float, float]:
        return validation_error(pam, human, q_val, T_val, crossed, design)

    lines = [f"  roller stage of actuator {r.id} {r.name}:"]

    def keep(why: str) -> ActuatorResult:
        out = dataclasses.replace(r, bone=dict(r.bone, roller_stage=f"without rollers: {why}", log=list(
            r.bone.get("log", [])) + lines + [f"    kept without rollers: {why}"]),
            seconds=r.seconds + time.perf_counter() - t0)
        return out

    nr0, w0 = error(r.pam)
    pl = ctx.placement(r.pam, q_bone)
    mount = pl.segment if pl.on_one_segment else None
    bracket = ctx.bracket(data0.pam, seed, regions)
    d, n = r.pam.diameter_mm, r.n_parallel
    prob = ActuatorProblem(data, cfg, d, seed, regions, relax, bracket, mount)
    sol0 = prob.solve(r.z, n)
    lines.append(f"    bracket-only fit: {sol0.status}, objective {r.objective if r.objective is not None else float('nan'):.4g}"
                 f" -> {sol0.objective:.4g} ({sol0.seconds:.1f} s)")
    if not sol0.success:
        return keep("the bracket-only fit failed")
    pam_fit = solution_pam(data.pam, prob.finalize(sol0))
    dep = depths(pam_fit, human, bones, q_bone, design, n_right)
    names = [f"{a.name}->{b.name}" for a, b in zip(pam_fit.points[:-1], pam_fit.points[1:])]
    rollers: dict[int, object] = {}
    deep = [j for j, depth in enumerate(dep.segment_depth) if depth > MAX_DEPTH and j != mount]
    lines.append("    segments into bone: " + (", ".join(f"{names[j]} {1e3 * dep.segment_depth[j]:.1f} mm"
                 for j in range(len(names)) if dep.segment_depth[j] > DEPTH_LIMIT) or "none"))
    if deep:
        return keep(f"{', '.join(names[j] for j in deep)} deeper than {1e3 * MAX_DEPTH:g} mm into bone (a roller "
                    "would move the cable too far from the fit's line)")
    for j, depth in enumerate(dep.segment_depth):
        if depth > DEPTH_LIMIT and j != mount and dep.deepest[j] is not None:
            rol = place(bones, human, q_bone, pam_fit, j, dep.deepest[j])
            if rol is not None:
                rollers[j] = rol
    if not rollers:
        return keep("no segment of the bracket-only fit goes into bone where a roller can go")
    cuts = BoneCuts(data0.pam, human, bones, q_bone, n_right)
    z = sol0.z
    L_prev = prob.lengths(z)
    found = None
    for rnd in range(PLACE_ROUNDS):
        keys = sorted(rollers)
        rd = [roller_data(data, human, rol, j) for j, rol in zip(keys, open_ended([rollers[j] for j in keys]))]
        prob1 = ActuatorProblem(data, cfg, d, seed, regions, relax, bracket, mount, rollers=rd)
        z0 = z.copy()
        L_new = prob1.lengths(z0)
        z0[-1] = max(z0[-1] + float(np.mean(L_new - L_prev)), 0.0)   # the PAM as long as before on average
        sol1 = prob1.solve(z0, n)
        where = ", ".join(names[j] for j in sorted(rollers))
        if sol1.status in CAPPED_STATUSES and max(sol1.violations.values(), default=0.0) <= FEASIBILITY_TOL:
            sol1.success = True     # the roller's kinks slow IPOPT's convergence: a feasible capped point serves
        if not sol1.success:
            lines.append(f"    with rollers on {where}, round {rnd + 1}: {sol1.status}")
            break
        # the bone-mesh rounds: points, segments and the straight pieces around the rollers
        cuts.rollers = dict(rollers)
        sol1, _, _ = bone_stage(prob1, sol1, cuts, cfg.bone_rounds.rounds)
        z, L_prev = sol1.z, prob1.lengths(sol1.z)
        pam1 = size_rollers(dataclasses.replace(solution_pam(data.pam, prob1.finalize(sol1)),
                                                rollers=tuple(rol for _, rol in sorted(rollers.items()))),
                            human, np.concatenate([q_bone, q_val]), design)
        if pam1 is None:
            return keep(f"the cable would slip off a roller's end even {1e3 * LENGTHS[-1]:g} mm long")
        rollers = {j: next(r for r in pam1.rollers if r.segment == rollers[j].segment) for j in rollers}
        dep1 = depths(pam1, human, bones, q_bone, design, n_right)
        lines.append(f"    with rollers on {where}, round {rnd + 1}: objective {sol1.objective:.4g}, deepest piece "
                     f"{1e3 * dep1.segment_depth.max():.1f} mm, rollers "
                     f"{', '.join(f'{1e3 * x:.1f}' for x in dep1.roller_bone)} mm off bone, "
                     f"{', '.join(f'{1e3 * r.length_m:g}' for r in pam1.rollers)} mm long")
        if dep1.clear():
            found = (pam1, prob1, sol1, cuts.measure(np.array(sol1.points)))
            break
        if r.objective is not None and sol1.objective >= r.objective:
            # not clear, and fitting worse than the result without rollers: moving the rollers out only moves
            # the cable further from the fit's line (measured: tensor fasciae latae's second round capped, 15 s)
            return keep(f"with rollers the route is not clear and fits no better (objective {r.objective:.4g} -> "
                        f"{sol1.objective:.4g})")
        for j, room in zip(sorted(rollers), dep1.roller_bone):     # a roller (its sized length) into its bone: out
            if room < 0:
                rol = rollers[j]
                rollers[j] = dataclasses.replace(rol, centre=tuple(float(c + (GAP - room) * s_) for c, s_ in
                                                                   zip(rol.centre, rol.side)))
        for j, depth in enumerate(dep1.segment_depth):     # move a roller out, or add one, where too deep
            if depth <= DEPTH_LIMIT or j == mount:
                continue
            if j in rollers:
                rol = rollers[j]
                shift = 0.5 * depth + 0.001
                rollers[j] = dataclasses.replace(rol, centre=tuple(float(c + shift * s_) for c, s_ in
                                                                   zip(rol.centre, rol.side)))
            elif dep1.deepest[j] is not None:
                rol = place(bones, human, q_bone, pam1, j, dep1.deepest[j])
                if rol is not None:
                    rollers[j] = rol
    if found is None:
        return keep("no clear route with rollers")
    pam1, prob1, sol1, measure = found
    nr1, w1 = error(pam1)
    lines.append(f"    validation NRMSE / worst {nr0:.3f} / {w0:.3f} -> {nr1:.3f} / {w1:.3f} with rollers")
    if not nr1 + w1 < nr0 + w0 - MIN_GAIN:
        return keep(f"the rollers gain less than {MIN_GAIN} in validation NRMSE + worst")
    out = make_result(data.pam, data, prob1, sol1, r.attempts + [{
        "diameter_mm": d, "n_parallel": n, "start": "roller stage", "status": sol1.status,
        "objective": sol1.objective, "feasible": bool(sol1.success), "seconds": round(time.perf_counter() - t0, 3),
        "relaxed": sorted(relax)}], t0 - r.seconds,
        {**r.bone, **measure.summary([p.name for p in data.pam.points]), "clear": bool(measure.violation() == 0.0),
         "rollers": [rol.segment for rol in pam1.rollers], "roller_stage": "kept",
         "log": list(r.bone.get("log", [])) + lines + ["    kept with rollers"]}, r.mount)
    out.pam = dataclasses.replace(out.pam, rollers=pam1.rollers)
    out.skipped, out.warm = r.skipped, r.warm
    return out
