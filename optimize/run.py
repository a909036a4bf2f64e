"""An optimisation run: every actuator's problem, in parallel, with an outer loop over diameter
and parallel count, multi-start, an independent numpy check and the run folder.

Run folder contents: ``design.yaml`` (same format as the built-in design), ``log.txt``,
``summary.json``, ``before_after.png``. Every file is written atomically; the robot data is
changed only by :func:`apply_design` (``pamkin optimize --apply``), and only when every
actuator's solve succeeded.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import multiprocessing as mp
import os
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pamkin import festo
from pamkin.design import ROBOT_DESIGN, Design, Pam, load_design, save_design
from pamkin.errors import DataFileError, PamkinError, RangeWarning
from pamkin.urdf_build import ROBOT_URDF, atomic_write, render_robot_urdf

from .config import RunConfig
from .samples import actuator_data, is_free


class InfeasibleError(PamkinError):
    """An actuator's problem has no feasible point; the message names the violated constraints."""


@dataclass
class ActuatorResult:
    """Best solution of one actuator and every attempt's outcome."""

    id: int
    name: str
    pam: Pam
    status: str
    success: bool
    attempts: list[dict] = field(default_factory=list)
    nrmse_samples: dict[str, float] = field(default_factory=dict)
    torque_samples: dict[str, np.ndarray] = field(default_factory=dict)
    sample_q: dict[str, np.ndarray] = field(default_factory=dict)
    violations: dict[str, float] = field(default_factory=dict)
    seconds: float = 0.0
    relaxed: list[str] = field(default_factory=list)     # constraint groups this actuator could not meet
    bone: dict = field(default_factory=dict)             # bone-mesh stage: exact clearance and rounds
    z: np.ndarray | None = None                          # the solution's decision vector
    n_parallel: int = 1
    # (fit-only first phase of a run with a unit budget) {(diameter, n_parallel): (score, Solution, relaxed)}
    candidates: dict = field(default_factory=dict, repr=False)
    mount: dict = field(default_factory=dict)            # one-segment stage (optimize.mount)
    skipped: list[str] = field(default_factory=list)     # diameter / count tries left out as dominated
    objective: float | None = None                       # the saved solution's fit objective (NRMSE²-like)
    direct: "ActuatorResult | None" = field(default=None, repr=False)   # before the one-segment stage's block
    warm: bool = False                                   # the first phase kept the warm start (its size stays)


# worker state (fork): set before the pool starts
_STATE: dict = {}
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
#: IPOPT statuses of a solve stopped by a cap rather than by what it found.
CAPPED_STATUSES = frozenset({"Maximum_CpuTime_Exceeded", "Maximum_Iterations_Exceeded"})


def _route_box(pam: Pam, cfg: RunConfig) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Seed location (or offset) and box half-widths [m] of every route point of ``pam``."""
    seed = [np.array(getattr(p, "location", (0.0, 0.0, 0.0)), float) for p in pam.points]
    regions = [np.array(cfg.region(pam.id, p.name), float) if is_free(p) or cfg.move_moving_points
               else np.zeros(3) for p in pam.points]
    return seed, regions


def _bracket(pam: Pam, seed: list[np.ndarray], regions: list[np.ndarray], cfg: RunConfig) -> dict | None:
    """The bone-distance splines of ``pam``'s points for the fit (``[limits] bracket_fit``; built once per
    worker and route box, :func:`optimize.bracket.bracket_splines`), or None."""
    if not (cfg.bone_mesh and cfg.bracket_fit):
        return None
    from .bracket import bracket_splines  # noqa: PLC0415

    key = (pam.id, np.round(np.ravel(seed), 9).tobytes(), np.ravel(regions).tobytes())
    cache = _STATE.setdefault("bracket", {})
    if key not in cache:
        cache[key] = bracket_splines(pam, _STATE["bones"], seed, regions)
    return cache[key]


def _solve_actuator(task: tuple[int, int]) -> ActuatorResult:
    """Outer loop (diameter, n_parallel) and multi-start for one actuator (runs in a worker)."""
    from .problem import ActuatorProblem  # noqa: PLC0415  (casadi only in workers / optimiser)

    k, seed_index = task
    cfg: RunConfig = _STATE["cfg"]
    data = _STATE["data"][k]
    pam: Pam = data.pam
    t0 = time.perf_counter()
    # decision variables: locations of body-fixed points, offsets (seed 0) of moving points
    seed, regions = _route_box(pam, cfg)
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
                                                          _bracket(pam, seed, regions, cfg), mount)
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
        low = mass_penalty(d, n, pam.resting_length_m if cfg.fix_lengths else festo.nominal_length_range(d)[0])
        by = [key for key, (sc, _, _) in candidates.items() if key[1] <= n and sc < low]
        if by:
            skipped.append(f"{d} mm x{n} (its mass alone scores {low:.4g}, more than {by[0][0]} mm x{by[0][1]})")
        return bool(by)

    def peak_force_ratio(sol) -> float:
        """Largest force per PAM of a solution at the training samples over its rated force (0: not bounded)."""
        from .limit_check import RATED, rated_bound  # noqa: PLC0415

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
    if pam.id in _STATE.get("warm_ids", ()) and pam.diameter_mm in cfg.diameters_mm \
            and pam.n_parallel <= cfg.max_parallel:
        warm = (pam.diameter_mm, pam.n_parallel, seed, pam.resting_length_m, pam.tendon_length_m)
        on = None
        if cfg.mount and not cfg.one_segment_for(pam.id):
            from .mount import mounted_segment  # noqa: PLC0415

            p0 = problem(pam.diameter_mm)
            on = mounted_segment(p0, p0.initial_guess(seed, pam.resting_length_m, pam.tendon_length_m))
        if cfg.bone_mesh:
            warm_ok = attempt(*warm, "warm start (as given)", evaluate=True, mount=on).success
        if not warm_ok:
            warm_ok = attempt(*warm, "warm start", mount=on).success
    if not warm_ok:
        same_seed = (pam.diameter_mm, pam.n_parallel)
        results = {}
        for d in cfg.diameters_mm:
            if dominated(d, 1):
                continue
            warm = (pam.resting_length_m, pam.tendon_length_m) if (d, 1) == same_seed else (None, None)
            results[(d, 1)] = attempt(d, 1, seed, *warm, "seed")
        optional = [name for name, on in (("one_segment", cfg.one_segment_for(pam.id)),
                                          ("sensitivity", cfg.sensitivity_pct > 0)) if on]
        for k in range(1, len(optional) + 1):
            if any(s.success for s in results.values()):
                break
            # the PAM cannot sit on one straight segment of this route (then, also not keep the sensitivity
            # limit) within the other limits: say so (``relaxed``), solve without them
            relaxed = frozenset(optional[:k])
            for d in cfg.diameters_mm:
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
            for n in range(2, min(cfg.max_parallel, _STATE.get("n_cap", cfg.max_parallel)) + 1):
                if dominated(d_best, n):
                    break
                s = attempt(d_best, n, prev.points, prev.rest_length, prev.tendon_length, "seed", relaxed)
                if not (s.success and score(s) < 0.95 * score(prev)):
                    break
                prev = s
        if best is not None and best.success and best.objective > cfg.multistart_threshold:
            rng = np.random.default_rng(cfg.seed + 1000 * pam.id + seed_index)
            for m in range(cfg.multistart):
                pts = [p + rng.uniform(-0.5, 0.5, 3) * r for p, r in zip(best.points, regions)]
                attempt(best.diameter_mm, best.n_parallel, pts, None, None, f"perturbed {m + 1}", relaxed)
    assert best is not None
    if _STATE.get("fit_only"):        # unit budget: the bone-mesh rounds follow the global choice
        out = _result(pam, data, best_problem[0], best, attempts, t0, {})
        out.candidates = candidates
        out.skipped = skipped
        out.warm = warm_ok
        return out
    best, bone, cuts = _bone_rounds(best_problem[0], best, pam, cfg)
    best, prob, mount, direct = _mount(best_problem[0], best, pam, cfg, cuts, blocks=not warm_ok)
    return _mounted_result(pam, data, prob, best, mount, direct, attempts, t0, bone, skipped)


#: The bone-mesh rounds start once more from the seed route unless the first result is clear of bone with
#: an objective at most this (NRMSE about 0.1: on the default run no such route gained from it).
SEED_START_SKIP = 0.01

#: Held-out limit checks of an actuator (optimize.limit_check): before the bone-mesh rounds, then after them.
LIMIT_CHECK_ROUNDS = 2


def _bone_rounds(prob, best, pam: Pam, cfg: RunConfig):
    """The bone-mesh stage of a solved actuator (when ``cfg.bone_mesh``): (solution, bone info, its
    :class:`~optimize.bone_cuts.BoneCuts` or None). A warm start taken as given (already through these rounds
    in its run) stays unless a round beats it, and where it keeps every strain and force limit at the held-out
    limit-check poses, also when the rounds' result ends over one of them (no deeper into bone)."""
    if not (cfg.bone_mesh and best.success):
        return best, {}, None
    from .bone_cuts import (N_POINT_CHECK, BoneCuts, bone_check_poses, bone_stage,  # noqa: PLC0415
                            point_contact_poses, push_out)

    q_bone, n_right = bone_check_poses(_STATE["human"], _STATE["rom"], pam, cfg.seed, crossed=prob.data.crossed)
    cuts = BoneCuts(pam, _STATE["human"], _STATE["bones"], q_bone, n_right)
    # same-body segments too short to hold the PAM body are carried round their own bone afterwards
    # (detour_pass): the rounds leave that bone out for them
    below = _detour_below(pam, prob, best, cfg)
    cuts.detour_below = below
    lines: list[str] = []
    before = best
    # the strain and force limits on many more poses than the problem's samples (optimize.limit_check):
    # where the start exceeds one, it is tightened before the rounds; where their result still does, once
    # more and the rounds again. The problem's own limits are restored afterwards (the tightening is a
    # margin of this search, not a different problem: the saved result is checked against the real limits)
    from .limit_check import check_poses, limit_excess, tighten  # noqa: PLC0415

    q_check = check_poses(_STATE["human"], _STATE["rom"], prob.data.crossed or [pam.primary_coordinate],
                          cfg.seed, pam.id)
    limits = (prob.lbg.copy(), prob.ubg.copy())

    def excess_of(sol) -> dict:
        return limit_excess(solution_pam(pam, prob.finalize(sol)), _STATE["human"], q_check, cfg,
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
    best, measure, info = bone_stage(prob, best, cuts, cfg.bone_rounds, lines, keep_start=warm)
    if cfg.bone_seed_start and not warm and not (measure.violation() == 0.0 and best.objective <= SEED_START_SKIP):
        best, measure, info = _seed_start(prob, best, measure, info, cuts, cfg, lines)
    for _ in range(LIMIT_CHECK_ROUNDS - 1):
        excess = excess_of(best)
        if not excess:
            break
        note(excess, "limits tightened, bone rounds again")
        tighten(prob, excess)
        best, measure, more = bone_stage(prob, best, cuts, cfg.bone_rounds, lines)
        info += more
    # attachment points against the other bones at many more poses: where one comes near, those poses
    # join the bone-check poses (right-leg poses, first) and the rounds run again
    extra = point_contact_poses(_STATE["human"], _STATE["bones"], _STATE["rom"],
                                solution_pam(pam, prob.finalize(best)), cfg.seed)
    if len(extra):
        lines.append(f"  attachment point within 3 mm of another bone at {len(extra)} (the closest) of "
                     f"{N_POINT_CHECK} more random poses: added to the bone-check poses, bone rounds again")
        cuts = BoneCuts(pam, _STATE["human"], _STATE["bones"], np.vstack([extra, q_bone]), n_right + len(extra))
        cuts.detour_below = below
        best, measure, more = bone_stage(prob, best, cuts, cfg.bone_rounds, lines)
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
    bone = _bone_info(cuts, before, measure, info, lines, [p.name for p in pam.points])
    bone.update(objective_before=float(before.objective), objective_after=float(best.objective))
    return best, bone, cuts


def _detour_below(pam: Pam, prob, sol, cfg: RunConfig) -> float:
    """Length [m] below which a same-body segment of ``pam`` could never hold its PAM body, whatever resting
    length, diameter or pulley block the one-segment stage and the passes after it choose: the least resting
    length the route's excursion at ``sol`` allows (its stroke over Festo's largest contraction plus the
    stretch limit, on the largest block the run may use) plus both fittings and the segment margin. Such
    segments are left to :func:`detour_pass` (0 without detours)."""
    if not (cfg.detours and sol.success):
        return 0.0
    import casadi as ca  # noqa: PLC0415

    from .mount import BLOCKS  # noqa: PLC0415
    from .problem import SEGMENT_MARGIN  # noqa: PLC0415

    ci = [int(s) for s in prob.data.constraint_idx]
    L = np.array(ca.Function("L", [prob.z], [prob.L[0, ci]])(sol.z)).ravel()
    k = max([prob.k, *(BLOCKS if cfg.mount and cfg.mount_blocks else ())])
    stretch = cfg.pretension_scale * max(festo.max_pretension(d) for d in cfg.diameters_mm)
    # the contraction limit is Festo's rated one at most (reach_bound); without it, no bound below 100 %
    c = max(festo.max_contraction(d) for d in cfg.diameters_mm) if cfg.rated_force else 1.0
    least = float(np.ptp(L)) / (k * (c + stretch))
    return float(least + 2 * prob.data.fitting_length + SEGMENT_MARGIN)


def _seed_start(prob, best, measure, info: list, cuts, cfg: RunConfig, lines: list[str]):
    """The bone-mesh rounds once more, from the seed route with its points moved onto their bone's band
    (:meth:`optimize.bone_cuts.BoneCuts.pull_in`) and lengths sized to it: the fitted route the first
    rounds start from may lie far from bone (the rounds then crawl to a poor local fit). The better
    result (:func:`optimize.bone_cuts.stage_key`) is kept; ``(solution, measure, rounds_info)``."""
    from .bone_cuts import bone_stage, stage_key  # noqa: PLC0415

    npt = cuts.n_points
    pulled = cuts.pull_in(np.array(prob.seed, float).reshape(npt, 3), reach=0.0, zmin=prob.zmin)
    z = prob.initial_guess(list(pulled), None, None)
    z[:3 * npt] = pulled.ravel()
    start = prob.evaluate(z, best.n_parallel)
    lines.append("  bone rounds from the seed route:")
    s, m, more = bone_stage(prob, start, cuts, cfg.bone_rounds, lines)
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


def _finish_actuator(k: int) -> ActuatorResult:
    """Second phase of a run with a unit budget (in a worker): the chosen diameter and parallel count
    of actuator ``k`` (``_STATE["choice"]``) from its first-phase fit, then the bone-mesh rounds."""
    return _finish_choice((k, _STATE["choice"][k], None))


def _finish_choice(task: tuple) -> ActuatorResult:
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
    from .problem import ActuatorProblem  # noqa: PLC0415

    k, key, z_start, *more = task
    t0 = time.perf_counter()
    cfg: RunConfig = _STATE["cfg"]
    data = _STATE["data"][k]
    first: ActuatorResult = _STATE["first"][k]
    pam: Pam = data.pam
    if key is None:                   # nothing feasible: the first phase's (failed) result stands
        return first
    seed, regions = _route_box(pam, cfg)
    t = 1                             # a block throughout: its ratio (the attempt says so)
    if more and more[0] != pam.transmission:
        t = int(more[0])
        k0 = pam.transmission
        pam = dataclasses.replace(pam, transmission=t)
        data = dataclasses.replace(data, pam=pam)
        relax = frozenset(first.candidates[key][2] if key in first.candidates else first.relaxed)
        prob = ActuatorProblem(data, cfg, key[0], seed, regions, relax, _bracket(pam, seed, regions, cfg))
        z = first.candidates[key][1].z if key in first.candidates else z_start
        sol = prob.solve(block_start(prob, z, k0, t, data.fitting_length), key[1])
        start = f"{BONE_RESIZE_START} ({t}:1)"
        if not sol.success:
            return _result(pam, data, prob, sol, first.attempts + [_attempt(key, start, sol, relax, t)],
                           t0 - first.seconds, {})
    elif key in first.candidates and len(more) < 2:
        _, sol, relax = first.candidates[key]
        prob = ActuatorProblem(data, cfg, key[0], seed, regions, relax, _bracket(pam, seed, regions, cfg),
                               sol.mount_segment)
        start = "unit budget choice"
    else:
        relax = frozenset(first.relaxed)
        prob = ActuatorProblem(data, cfg, key[0], seed, regions, relax, _bracket(pam, seed, regions, cfg))
        if len(more) > 1:
            # the solved route as it is, with the new count, where it meets every limit (as a warm start taken
            # as given: the bone rounds go on from a route already clear of bone), else solved from it; with
            # ``keep``, a PAM on one straight segment keeps it (the problem has its one-segment rows, as a warm
            # start's), else the one-segment stage puts it on one again
            start, keep = more[1], len(more) > 2 and bool(more[2])
            if keep and cfg.mount and not cfg.one_segment_for(pam.id):
                from .mount import mounted_segment  # noqa: PLC0415

                on = mounted_segment(prob, np.asarray(z_start, float))
                if on is not None:
                    prob = ActuatorProblem(data, cfg, key[0], seed, regions, relax, _bracket(pam, seed, regions, cfg),
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
            return _result(pam, data, prob, sol, first.attempts, t0 - first.seconds, {})
    best, bone, cuts = _bone_rounds(prob, sol, pam, cfg)
    best, prob, mount, direct = _mount(prob, best, pam, cfg, cuts, blocks=not first.warm)
    attempts = first.attempts + [_attempt(key, start, sol, relax, t)]
    return _mounted_result(pam, data, prob, best, mount, direct, attempts, t0 - first.seconds, bone, first.skipped)


def _attempt(key: tuple, start: str, sol, relax, transmission: int = 1) -> dict:
    """An attempts entry of :func:`_finish_choice` (the diameter / count ``key`` from ``start``)."""
    out = {"diameter_mm": key[0], "n_parallel": key[1], "start": start, "status": sol.status,
           "objective": sol.objective, "feasible": bool(sol.success), "seconds": 0.0, "relaxed": sorted(relax)}
    if transmission != 1:
        out["transmission"] = int(transmission)
    return out


def block_start(prob, z: np.ndarray, k0: int, k: int, fitting_length: float) -> np.ndarray:
    """Decision vector ``z`` of a ``k0``:1 solve as a start for ``prob``, a ``k``:1 one: the same route, the
    resting length and tendon that keep the PAM's strain at every route length
    (:func:`pamkin.design.rescale_for_transmission`); clipped to the bounds."""
    from pamkin.design import rescale_for_transmission  # noqa: PLC0415

    z = np.array(z, float)
    z[-2], z[-1] = rescale_for_transmission(float(z[-2]), float(z[-1]), k0, k, fitting_length)
    return np.clip(z, prob.lbx, prob.ubx)


def _mount(prob, best, pam: Pam, cfg: RunConfig, cuts=None, blocks: bool = True):
    """The one-segment stage of a solved actuator (when ``cfg.mount``; :mod:`optimize.mount`): on its fixed
    route, and where that fails narrowly, with the bone rounds (``cuts``) and the PAM on the segment
    (:func:`optimize.mount.mount_rounds`), then on a pulley block (:func:`optimize.mount.mount_block`) unless
    ``blocks`` is False: an actuator whose warm start was kept keeps its warm size, transmission included
    (its run tried the blocks; the mass budget may have taken one off again, and a warm run would put it on
    again only to take it off). Returns (solution, its problem, mount info, direct), ``direct``
    the (solution, problem, mount info) before a pulley block where the stage put the PAM on one (else None)."""
    if not (cfg.mount and best.success):
        return best, prob, {}, None
    from .mount import BLOCK_REASONS, mount_block, mount_rounds, mount_stage  # noqa: PLC0415

    # made only where a fit cost is weighed (the validation errors of this actuator's crossed coordinates)
    def rule(already_failing: bool, still_passing: bool):
        return lambda a, b: _failing_fit(list(prob.data.crossed or []), already_failing, still_passing)(a, b)

    failing = rule(cfg.mount_failing, cfg.mount_passing) if cfg.mount_failing or cfg.mount_passing else None
    blocked = frozenset(cuts.in_own_bone(np.array(best.points))) if cuts is not None else frozenset()
    best, info = mount_stage(prob, best, pam, cfg, _STATE["human"], _STATE["rom"], solution_pam, failing, blocked)
    if not info.get("mounted") and cuts is not None:
        best, prob, info = mount_rounds(prob, best, info, pam, cfg, cuts, _STATE["human"], _STATE["rom"],
                                        solution_pam, failing)
    direct = None
    if not info.get("mounted") and not blocks:
        if cfg.mount_blocks and info.get("reason") in BLOCK_REASONS and prob.k == 1:
            info = dict(info, line=info["line"] + "; no pulley block tried (warm start: its transmission kept)")
    elif not info.get("mounted"):
        before = (best, prob, info)
        # on a block only mount_passing (the mounted PAM's own errors): mount_failing on blocks too, measured at
        # stop 39, mounted tensor fasciae latae and internal oblique at a large fit cost and the run's later
        # passes (re-sizing, mass budget) moved other PAMs: 9 audit limits failed instead of 6
        passing = rule(False, True) if cfg.mount_passing else None
        best, prob, info = mount_block(prob, best, info, pam, cfg, _STATE["human"], _STATE["rom"], solution_pam,
                                       blocked, passing)
        if info.get("transmission", 1) > 1:
            direct = before
    return best, prob, info, direct


def _mounted_result(pam: Pam, data, prob, best, mount: dict, direct, attempts: list, t0: float, bone: dict,
                    skipped: list) -> ActuatorResult:
    """The saved result after the one-segment stage (:func:`_mount`), with the result from before its pulley
    block as ``direct`` where the stage put the PAM on one (:func:`mass_pass` may go back to it)."""
    out = _result(pam, data, prob, best, attempts, t0, bone, mount)
    out.skipped = list(skipped)
    if direct is not None:
        out.direct = _result(pam, data, direct[1], direct[0], [dict(a) for a in attempts], t0, bone, direct[2])
        out.direct.skipped = list(skipped)
    return out


def choose_units(results: list[ActuatorResult], budget: int) -> tuple[list, float]:
    """Diameter and parallel count of every actuator for the least summed score with at most ``budget``
    PAM units on one side (exact, by dynamic programming over the first phase's feasible candidates).

    Returns:
        ``(choice, total score)``: per result its ``(diameter, n_parallel)`` (None where it has no
        feasible candidate: it keeps its failed solution, counted with its parallel count).

    Raises:
        InfeasibleError: when even the smallest counts exceed the budget.
    """
    fixed = sum(r.n_parallel for r in results if not r.candidates)
    options = [sorted(((sc, key) for key, (sc, _, _) in r.candidates.items()), key=lambda o: o[1][1])
               for r in results if r.candidates]
    cap = budget - fixed
    need = sum(min(key[1] for _, key in opts) for opts in options)
    if need > cap:
        raise InfeasibleError(f"limits.max_units: the actuators' feasible diameter / parallel-count choices need "
                              f"at least {need + fixed} PAM units per side, the budget allows {budget}")
    INF = float("inf")
    table = [0.0] * (cap + 1)           # table[u]: least score of the actuators so far using <= u units
    picks: list[list] = []
    for opts in options:
        new, pick = [INF] * (cap + 1), [None] * (cap + 1)
        for u in range(cap + 1):
            for sc, key in opts:
                if key[1] <= u and table[u - key[1]] + sc < new[u]:
                    new[u], pick[u] = table[u - key[1]] + sc, key
        table = new
        picks.append(pick)
    u, chosen = cap, []
    for opts, pick in zip(reversed(options), reversed(picks)):
        key = pick[u]
        chosen.append(key)
        u -= key[1]
    chosen.reverse()
    it = iter(chosen)
    return [next(it) if r.candidates else None for r in results], float(table[cap])


def solution_pam(pam: Pam, best) -> Pam:
    """The seed PAM with a (finalised) solution's route, sizes, diameter and parallel count (moving
    points shifted by their offsets)."""
    new_points = []
    for pt, loc in zip(pam.points, best.points):
        if is_free(pt):
            new_points.append(type(pt)(pt.name, pt.body, tuple(float(v) for v in loc)))
        else:
            new_points.append(shift_moving_point(pt, loc))
    return Pam(pam.id, pam.name, pam.human_muscles, pam.primary_coordinate, pam.secondary_coordinates,
               best.diameter_mm, best.n_parallel, best.rest_length, best.tendon_length, tuple(new_points),
               pam.notes, pam.transmission)


def _result(pam: Pam, data, prob, best, attempts: list, t0: float, bone: dict, mount: dict | None = None) -> ActuatorResult:
    """The saved form of an actuator's best solution (tendon clipped at 0, moving points shifted)."""
    best = prob.finalize(best)
    if prob.k != pam.transmission:        # the one-segment stage put the PAM on a pulley block
        pam = dataclasses.replace(pam, transmission=prob.k)
    new = solution_pam(pam, best)
    sample_q = {label: data.q[rows] for _, rows, _, _, label in data.objective}
    return ActuatorResult(pam.id, pam.name, new, best.status, best.success, attempts, best.nrmse_samples,
                          best.torque_samples, sample_q, best.violations, time.perf_counter() - t0,
                          sorted(prob.relax), bone, best.z.copy(), best.n_parallel, mount=mount or {},
                          objective=float(best.objective))


def _bone_info(cuts, before, measure, info, lines, names) -> dict:
    return {"rounds": info, "before": cuts.measure(np.array(before.points)).summary(names),
            **measure.summary(names), "clear": bool(measure.violation() == 0.0), "log": lines}


def _clear_actuator(k: int) -> ActuatorResult:
    """PAM–PAM pass of one actuator (in a worker): from its first-pass solution, the bone-mesh rounds
    again with the other PAMs' bodies (first-pass design, fixed) as obstacles."""
    from .bone_cuts import BoneCuts, bone_stage
    from .problem import ActuatorProblem

    t0 = time.perf_counter()
    cfg: RunConfig = _STATE["cfg"]
    data = _STATE["data"][k]
    first: ActuatorResult = _STATE["first"][k]
    pam: Pam = data.pam
    seed, regions = _route_box(pam, cfg)
    prob = ActuatorProblem(data, cfg, first.pam.diameter_mm, seed, regions, frozenset(first.relaxed),
                           _bracket(pam, seed, regions, cfg))
    sol = prob.evaluate(first.z, first.n_parallel)
    q, n_right, bodies, radius, mount = _STATE["obstacles"][k]
    cuts = BoneCuts(pam, _STATE["human"], _STATE["bones"], q, n_right)
    cuts.set_obstacles(bodies, radius, mount)
    cuts.detour_below = _detour_below(pam, prob, sol, cfg)       # as in the first pass's rounds
    lines = ["  PAM-PAM pass:"]
    best, measure, info = bone_stage(prob, sol, cuts, cfg.bone_rounds, lines)
    bone = _bone_info(cuts, sol, measure, info, first.bone.get("log", []) + lines, [p.name for p in pam.points])
    attempts = first.attempts + [{"diameter_mm": best.diameter_mm, "n_parallel": best.n_parallel,
                                  "start": "PAM-PAM pass", "status": best.status, "objective": best.objective,
                                  "feasible": bool(best.success), "seconds": round(time.perf_counter() - t0, 3),
                                  "relaxed": sorted(first.relaxed)}]
    return _result(pam, data, prob, best, attempts, t0 - first.seconds, bone)


def clearance_pass(seed: Design, results: list[ActuatorResult], cfg: RunConfig, stream=sys.stderr
                   ) -> list[ActuatorResult]:
    """Second pass: every actuator whose route comes nearer another PAM's body than their radii (at its
    bone-check poses, first-pass design) is solved again with the other bodies as obstacles."""
    from .bone_cuts import BoneCuts, bone_check_poses
    from .pam_clearance import pam_bodies

    design = seed
    for r in results:
        design = design.replace_pam(r.pam)
    human, rom = _STATE["human"], _STATE["rom"]
    index = {p.id: k for k, p in enumerate(design.pams)}
    todo, obstacles = [], {}
    for k, r in enumerate(results):
        if r.z is None or not r.success:
            continue
        data = _STATE["data"][k]
        q, n_right = bone_check_poses(human, rom, data.pam, cfg.seed, crossed=data.crossed)
        bodies = pam_bodies(design, human, q)
        mine = bodies[index[r.id]]
        others = [b for b in bodies if b.id != r.id]
        cuts = BoneCuts(data.pam, human, _STATE["bones"], q, n_right)
        cuts.set_obstacles(others, mine.radius, mine.mount)
        loc = np.array(first_locations(r, data))
        m = cuts.measure(loc)
        hits = {i: c for i, c in (m.pam_clearance or {}).items() if c < 0}
        if hits:
            todo.append(k)
            obstacles[k] = (q, n_right, others, mine.radius, mine.mount)
            print(f"PAM-PAM: actuator {r.id} {r.name} comes {1e3 * -min(hits.values()):.1f} mm into "
                  f"{len(hits)} other PAM bodies: solving again", file=stream, flush=True)
    if not todo:
        return results
    _STATE.update(first={k: results[k] for k in todo}, obstacles=obstacles)
    out = list(results)
    if cfg.workers > 1 and len(todo) > 1:
        with _pool(min(cfg.workers, len(todo))) as pool:
            for k, r in zip(todo, pool.imap(_clear_actuator, todo)):
                out[k] = r
                _progress(todo.index(k) + 1, len(todo), r, stream)
    else:
        with _one_blas_thread():
            for j, k in enumerate(todo):
                out[k] = _clear_actuator(k)
                _progress(j + 1, len(todo), out[k], stream)
    return out


#: The run names actuators whose fit objective the bone-mesh rounds raise by more than this factor.
FIT_COST_FACTOR = 3.0


def _roller_actuator(k: int) -> ActuatorResult:
    """The roller stage of one actuator (in a worker; :mod:`optimize.rollers`): the bracket-only fit from its
    result, rollers where that fit's segments go into bone, solved with them and checked exactly; the result
    with rollers where it lowers the validation error, else the result as it was (its log says why)."""
    from .bone_cuts import BoneCuts, bone_check_poses, bone_stage  # noqa: PLC0415
    from .problem import FEASIBILITY_TOL, ActuatorProblem  # noqa: PLC0415
    from .rollers import (DEPTH_LIMIT, GAP, LENGTHS, MAX_DEPTH, MIN_GAIN, PLACE_ROUNDS, depths, place,  # noqa: PLC0415
                          roller_data, size_rollers)
    from .validation import validation_error  # noqa: PLC0415
    from pamkin.rollers import open_ended  # noqa: PLC0415

    t0 = time.perf_counter()
    cfg: RunConfig = _STATE["cfg"]
    human, bones, design = _STATE["human"], _STATE["bones"], _STATE["seed_design"]
    r: ActuatorResult = _STATE["first"][k]
    data0 = _STATE["data"][k]
    data = dataclasses.replace(data0, pam=dataclasses.replace(data0.pam, transmission=r.pam.transmission))
    seed, regions = _route_box(data0.pam, cfg)
    relax = frozenset(r.relaxed)
    q_bone, n_right = bone_check_poses(human, _STATE["rom"], data0.pam, cfg.seed, crossed=data.crossed)
    q_val, T_val = _validation_set()
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
    pl = _placement(r.pam, q_bone)
    mount = pl.segment if pl.on_one_segment else None
    bracket = _bracket(data0.pam, seed, regions, cfg)
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
        sol1, _, _ = bone_stage(prob1, sol1, cuts, cfg.bone_rounds)
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
    out = _result(data.pam, data, prob1, sol1, r.attempts + [{
        "diameter_mm": d, "n_parallel": n, "start": "roller stage", "status": sol1.status,
        "objective": sol1.objective, "feasible": bool(sol1.success), "seconds": round(time.perf_counter() - t0, 3),
        "relaxed": sorted(relax)}], t0 - r.seconds,
        {**r.bone, **measure.summary([p.name for p in data.pam.points]), "clear": bool(measure.violation() == 0.0),
         "rollers": [rol.segment for rol in pam1.rollers], "roller_stage": "kept",
         "log": list(r.bone.get("log", [])) + lines + ["    kept with rollers"]}, r.mount)
    out.pam = dataclasses.replace(out.pam, rollers=pam1.rollers)
    out.skipped, out.warm = r.skipped, r.warm
    return out


def _placement(pam: Pam, q: np.ndarray):
    """Where the PAM body of ``pam`` (right side) sits on its route at poses ``q``
    (:func:`pamkin.pam_body.placement`, as the audit puts it)."""
    from pamkin.pam_body import placement, route_positions  # noqa: PLC0415
    from pamkin.robot import PamRobot  # noqa: PLC0415

    human, design = _STATE["human"], _STATE["seed_design"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        robot = PamRobot(Design("mount", (pam,), design.pressure_Pa, design.force_model,
                                design.fitting_length_m, design.rom), human, sides=("r",))
        ks = human.kinematics.forward(q, warn_range=False)
        return placement(route_positions(robot.paths, ks, 0), pam, robot.evaluate(q).pam_lengths[:, 0],
                         design.fitting_length_m)


def detour_pass(results: list[ActuatorResult], cfg: RunConfig, stream=None) -> list[ActuatorResult]:
    """Every same-body segment of a result's route (both ends fixed in one body) that runs into its own bone,
    but the one its PAM body sits on, carried round that bone by via points (:func:`pamkin.detour.detour_pam`:
    a constant length, on the tendon; every torque unchanged), then the route checked exactly against every
    bone at its bone-check poses (the result's bone summary is that check's). Progress on ``stream``
    (default: standard error at the call)."""
    stream = stream or sys.stderr
    from pamkin.detour import detour_pam, same_body_segments  # noqa: PLC0415
    from pamkin.pam_body import segment_names  # noqa: PLC0415

    from .bone_cuts import BoneCuts, bone_check_poses  # noqa: PLC0415

    human, bones = _STATE["human"], _STATE["bones"]
    out = list(results)
    for k, r in enumerate(results):
        if r.z is None or not r.success or not r.bone:
            continue
        data = _STATE["data"][k]
        q, n_right = bone_check_poses(human, _STATE["rom"], data.pam, cfg.seed, crossed=data.crossed)
        pl = _placement(r.pam, q)
        segs = [a for a in same_body_segments(r.pam) if not (pl.on_one_segment and a == pl.segment)]
        if not segs:
            continue
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            state = human.kinematics.forward(q, warn_range=False)
        new, outcome = detour_pam(r.pam, bones, segs, state, list(human.kinematics.frames), n_right)
        if not outcome:
            continue
        names = segment_names(r.pam)
        cuts = BoneCuts(new, human, bones, q, n_right)
        new_names = segment_names(new)         # a rollered segment is measured on its pieces round the roller
        cuts.rollers = {new_names.index(rol.segment): rol for rol in new.rollers}
        loc = np.array([p.location if hasattr(p, "location") else (0.0, 0.0, 0.0) for p in new.points])
        m = cuts.measure(loc)
        what = "; ".join(f"{names[a]}: {v}" for a, v in sorted(outcome.items()))
        line = (f"  detours of actuator {r.id} {r.name}: {what} (tendon +{1e3 * (new.tendon_length_m - r.pam.tendon_length_m):.1f} mm);"
                f" route then {'clear of bone' if m.violation() == 0.0 else f'{1e3 * m.violation():.1f} mm into bone'}"
                f" at its bone-check poses ({time.perf_counter() - t0:.1f} s)")
        print(line.strip(), file=stream, flush=True)
        bone = dict(r.bone, **m.summary([p.name for p in new.points]), clear=bool(m.violation() == 0.0),
                    detours={names[a]: v for a, v in outcome.items()}, log=list(r.bone.get("log", [])) + [line])
        out[k] = dataclasses.replace(r, pam=new, bone=bone)
    return out


def roller_pass(results: list[ActuatorResult], cfg: RunConfig, stream=None) -> list[ActuatorResult]:
    """The roller stage (:mod:`optimize.rollers`) for every actuator whose result fails the audit's fit limits
    (primary NRMSE or worst coordinate error) on the run's validation poses; progress on ``stream`` (default:
    standard error at the call). In a warm re-run, an actuator whose warm start's run tried it and kept it
    without rollers is not tried again (:func:`warm_roller_outcomes`): the stage's cost is then that of the
    actuators it gave rollers."""
    stream = stream or sys.stderr
    lim_n, lim_w = _fit_limits()
    todo = []
    for k, r in enumerate(results):
        if r.z is None or not r.success:
            continue
        nr, w = _validation_errors(r.pam, k)
        if nr > lim_n or w > lim_w:
            todo.append(k)
    warm = warm_roller_outcomes(Path(cfg.warm_start)) if cfg.warm_start else {}
    again = [k for k in todo if results[k].id in _STATE.get("warm_ids", ()) and
             warm.get(results[k].id, "kept") != "kept"]
    if again:
        print("rollers: not tried again (the warm start's run tried them without a gain): " +
              ", ".join(f"{results[k].id} {results[k].name}" for k in again), file=stream, flush=True)
        todo = [k for k in todo if k not in again]
        results = [dataclasses.replace(r, bone=dict(                 # carried on, for a warm re-run from this one
            r.bone or {}, roller_stage=warm[r.id], log=list((r.bone or {}).get("log", [])) + [
                f"  roller stage of actuator {r.id} {r.name}: not tried again: the warm start's run kept it "
                f"{warm[r.id]}"])) if k in again else r for k, r in enumerate(results)]
    if not todo:
        return results
    print(f"rollers: {len(todo)} actuators fail a fit limit on the validation poses: trying rollers", file=stream,
          flush=True)
    _STATE.update(first={k: results[k] for k in todo})
    out = list(results)
    for r in _map(_roller_actuator, todo, cfg, stream):
        out[next(k for k in todo if results[k].id == r.id)] = r
    return out


def warm_roller_outcomes(run_dir: Path) -> dict[int, str]:
    """What the roller stage of the run in ``run_dir`` did with each actuator it tried (its ``summary.json``):
    ``"kept"`` or ``"without rollers: <why>"``, by actuator id; empty where that run had no roller stage or
    wrote no summary. A warm re-run's roller stage does not try again the actuators its warm start's run tried
    without a gain (their warm routes are that run's results)."""
    path = run_dir / "summary.json"
    if not path.is_file():
        return {}
    try:
        bone = json.loads(path.read_text()).get("bone_mesh") or {}
        return {int(k): str(v["roller_stage"]) for k, v in bone.items() if "roller_stage" in v}
    except (ValueError, AttributeError, TypeError) as e:
        raise DataFileError(str(path), f"not a pamkin optimize summary ({e})") from None


def mount_lines(results: list[ActuatorResult], cfg: RunConfig) -> list[str]:
    """The one-segment stage's outcome (:mod:`optimize.mount`): how many PAMs sit on one straight segment,
    then one line per PAM that does not, naming why with its numbers."""
    done = [r for r in results if r.mount]
    if not done:
        return []
    on = [r for r in done if r.mount["mounted"]]
    out = [f"one straight segment: {len(on)} of {len(done)} PAMs (resting and tendon length re-solved on the "
           f"fixed route; mount_cost {cfg.mount_cost:g})"]
    out += [f"one straight segment: actuator {r.id} {r.name} ({r.mount['reason']}): {r.mount['line']}"
            for r in done if not r.mount["mounted"]]
    return out


def fit_cost_lines(results: list[ActuatorResult]) -> list[str]:
    """One line per actuator whose fit the bone-mesh rounds made much worse (objective × > FIT_COST_FACTOR
    and above 0.01, about NRMSE 0.1): the price of keeping the route on and clear of the bones."""
    out = []
    for r in results:
        b = r.bone or {}
        j0, j1 = b.get("objective_before"), b.get("objective_after")
        if j0 is None or j1 is None or j1 <= 0.01 or j1 <= FIT_COST_FACTOR * max(j0, 1e-12):
            continue
        far = _far_points(b.get("before", {}))
        why = ("; its fitted route had points " + ", ".join(far) + " from bone") if far else ""
        out.append(f"actuator {r.id} {r.name}: keeping the route on and clear of bone raised the fit objective "
                   f"{j0:.3g} -> {j1:.3g} (x{j1 / max(j0, 1e-12):.0f}){why}")
    return out


def _far_points(measure: dict) -> list[str]:
    """``["p2 70 mm", ...]``: the points of a bone measure's summary (``point_distance_mm``) over 20 mm
    (the audit's bracket limit) from their bone."""
    return [f"{name} {v:.0f} mm" for name, v in measure.get("point_distance_mm", {}).items() if v > 20]


def bone_limit_lines(results: list[ActuatorResult]) -> list[str]:
    """One line per finished actuator that fails an audit fit limit on the validation poses (primary NRMSE
    or worst error about a crossed coordinate, :mod:`optimize.validation`): its errors on and clear of bone,
    beside those of its first-phase fit of the size the unit budget chose (route points anywhere in their
    boxes, no bone meshes), and where this result's bone rounds started (its points over 20 mm from bone,
    its deepest segment into bone). Where that fit passes both limits the bone limits cost the pass — the PAM is
    out of reach of the audit's fit limits within them, by name with its numbers; where it fails too, the
    route's shape does. Left out: actuators without a bone stage, a failed first phase or a warm start that held
    (its first phase is the warm route, already on its bones)."""
    first = _STATE.get("first") or {}
    if not first or _STATE.get("validation") is None:
        return []
    lim_n, lim_w = _fit_limits()
    out = []
    for k, r in enumerate(results):
        f = first.get(k)
        if not (r.success and r.bone) or f is None or f.id != r.id or f.warm or not f.success:
            continue
        n1, w1 = _validation_errors(r.pam, k)
        if n1 <= lim_n and w1 <= lim_w:
            continue
        ref = _chosen_first_pam(k)
        n0, w0 = _validation_errors(ref, k)
        before = r.bone.get("before", {})
        far = _far_points(before)
        depth = float(before.get("max_segment_penetration_mm", 0.0))
        start = ", ".join(x for x in (("points " + ", ".join(far) + " from bone") if far else "",
                                      f"a segment {depth:.1f} mm into bone" if depth > 2 else "") if x)
        verdict = ("out of reach within the bone limits: without them it passes both"
                   if n0 <= lim_n and w0 <= lim_w else
                   "fails without the bone meshes too: the route's shape and the PAM's force-length curve")
        out.append(f"actuator {r.id} {r.name}: validation NRMSE / worst {n1:.3f} / {w1:.3f} ({_size(r.pam)}, on "
                   f"and clear of bone; audit limits {lim_n:g} / {lim_w:g}); its fit without the bone "
                   f"meshes ({_size(ref)}) {n0:.3f} / {w0:.3f}: {verdict}"
                   + (f" (the bone rounds started from {start})" if start else ""))
    return out


def _chosen_first_pam(k: int) -> Pam:
    """Actuator ``k``'s first-phase fit (no bone meshes) of the diameter and count the unit budget chose
    (``_STATE["choice"]``), as a PAM; its own best fit where that is the choice or was not kept."""
    f: ActuatorResult = _STATE["first"][k]
    key = (_STATE.get("choice") or {}).get(k)
    if not key or key == (f.pam.diameter_mm, f.n_parallel) or key not in f.candidates \
            or f.candidates[key][1] is None:
        return f.pam
    new = solution_pam(dataclasses.replace(_STATE["data"][k].pam, transmission=f.pam.transmission),
                       f.candidates[key][1])
    return dataclasses.replace(new, tendon_length_m=max(new.tendon_length_m, 0.0))


def first_locations(r: ActuatorResult, data) -> list[np.ndarray]:
    """Decision-variable locations (fixed points) / offsets (moving points) of a solved actuator."""
    return [r.z[3 * i:3 * i + 3] for i in range(len(data.pam.points))]


def bone_line(bone: dict) -> str:
    """One line: the exact bone clearance of an actuator after the bone-mesh stage."""
    segs = "; ".join(f"segment {k} {v['depth_mm']:.1f} mm into {v['bone']}"
                     for k, v in bone["segments_into_bone"].items())
    pts = "; ".join(f"point {k} {v:.1f} mm" for k, v in bone["point_distance_mm"].items() if not 0 <= v <= 20)
    pams = "; ".join(f"{v:.1f} mm into PAM {k}" for k, v in bone.get("pam_overlap_mm", {}).items())
    what = "; ".join(x for x in (segs, pts, pams) if x)
    return ("clear" if bone["clear"] else "NOT clear: " + what) + \
        f" (max penetration {bone['max_segment_penetration_mm']:.1f} mm at the bone-check poses)"


def shift_function(fn, delta: float):
    """``fn`` + delta, in the same function class (exactly)."""
    from pamkin.functions import Constant, LinearFunction, MultiplierFunction, PolynomialFunction, SimmSpline

    if delta == 0.0:
        return fn
    if isinstance(fn, Constant):
        return Constant(fn.c + delta)
    if isinstance(fn, LinearFunction):
        return LinearFunction(fn.slope, fn.intercept + delta)
    if isinstance(fn, SimmSpline):
        return SimmSpline(fn.x, tuple(y + delta for y in fn.y))
    if isinstance(fn, PolynomialFunction):
        return PolynomialFunction(fn.coefficients[:-1] + (fn.coefficients[-1] + delta,))
    if isinstance(fn, MultiplierFunction) and fn.scale != 0:
        return MultiplierFunction(shift_function(fn.function, delta / fn.scale), fn.scale)
    raise TypeError(f"cannot shift {fn!r}")


def shift_moving_point(pt, offset):
    """A moving point whose path is translated by ``offset`` (3,) [m] in its body frame."""
    from pamkin.osim import MovingPathPoint

    fns = tuple(shift_function(f, float(d)) for f, d in zip(pt.functions, offset))
    return MovingPathPoint(pt.name, pt.body, fns, pt.coordinates)


def _progress(done: int, total: int, r: ActuatorResult, stream) -> None:
    bar = "#" * int(30 * done / total)
    e = next(iter(r.nrmse_samples.values()), float("nan"))
    print(f"solve [{bar:30s}] {done:2d}/{total}  {r.id:2d} {r.name:26s} {'ok  ' if r.success else 'FAIL'} "
          f"fit NRMSE {e:.3f} ({r.seconds:.1f} s)", file=stream, flush=True)


def _check_progress(stream):
    def report(done: int, total: int, aid: int, name: str) -> None:
        bar = "#" * int(30 * done / total)
        print(f"check [{bar:30s}] {done:2d}/{total}  {aid:2d} {name}", file=stream, flush=True)
    return report


def solve_all(seed_design: Design, cfg: RunConfig, stream=sys.stderr) -> list[ActuatorResult]:
    """Solve every selected actuator of ``seed_design`` (right side)."""
    import pamkin  # noqa: PLC0415
    from pamkin.rom import load_rom  # noqa: PLC0415

    human = pamkin.gait2392()
    rom = load_rom(seed_design.rom, "r")
    ids = cfg.actuators or [p.id for p in seed_design.pams]
    unknown = [i for i in ids if i not in {p.id for p in seed_design.pams}]
    if unknown:
        raise PamkinError(f"unknown actuator id(s) {unknown}")
    pams = [seed_design.pam(i) for i in ids]
    data = [actuator_data(p, human, rom, cfg, seed_design.fitting_length_m) for p in pams]
    _STATE.update(cfg=cfg, data=data, human=human, rom=rom, validation=None, seed_design=seed_design)
    if cfg.mount and (cfg.mount_failing or cfg.mount_passing):
        # the human torques of the validation poses here, before the workers fork: a forked worker that
        # computes them itself hangs in the threads the parent process already started
        _validation_set()
    if cfg.bone_mesh:
        from pamkin.bones import BoneSet  # noqa: PLC0415

        _STATE["bones"] = BoneSet(human)
    _STATE["fit_only"] = bool(cfg.max_units)
    order = {i: k for k, i in enumerate(ids)}
    others = sum(p.n_parallel for p in seed_design.pams if p.id not in order)
    # with a unit budget no actuator can get more PAMs than the budget leaves after one for every other
    # actuator: larger counts are not tried (exact: the choice could never take them)
    _STATE["n_cap"] = cfg.max_units // 2 - others - (len(pams) - 1) if cfg.max_units else cfg.max_parallel
    # the first phase's time grows with the route's points (measured: correlation 0.87 over the 29 defaults)
    results = sorted(_map(_solve_actuator, [(k, 0) for k in range(len(pams))], cfg, stream,
                          cost=[len(p.points) for p in pams]), key=lambda r: order[r.id])
    if not cfg.max_units:
        return mass_pass(seed_design, results, cfg, stream) if cfg.max_mass_kg > 0 else results
    # unit budget: choose every actuator's diameter and count together, then the bone-mesh rounds
    free = sum(r.n_parallel for r in results)
    choice, total = choose_units(results, cfg.max_units // 2 - others)
    units = sum(key[1] if key else r.n_parallel for key, r in zip(choice, results))
    changed = [f"{r.id} {r.name} {r.pam.diameter_mm}x{r.n_parallel} -> {key[0]}x{key[1]}"
               for r, key in zip(results, choice) if key and key != (r.pam.diameter_mm, r.n_parallel)]
    print(f"unit budget {cfg.max_units} (both sides): each actuator's own best needs {2 * (free + others)}; "
          f"chosen {2 * (units + others)} (summed score {total:.4g})" + (": " + "; ".join(changed) if changed else ""),
          file=stream, flush=True)
    _STATE.update(fit_only=False, first=dict(enumerate(results)), choice=dict(enumerate(choice)))
    # the bone rounds' time follows the first phase's (simulated on the default run: 268 -> 263 s, ideal 262)
    results = sorted(_map(_finish_actuator, list(range(len(results))), cfg, stream,
                          cost=[r.seconds for r in results]), key=lambda r: order[r.id])
    if cfg.bone_mesh and cfg.resize_above > 0:
        results = resize_pass(results, cfg, stream)
    if cfg.bone_mesh and cfg.reallocate:
        results = reallocate_pass(results, cfg, stream)
    if cfg.max_mass_kg > 0:
        results = mass_pass(seed_design, results, cfg, stream)
    if cfg.walking_min > 0:
        results = _walking_pass(seed_design, results, cfg.max_units // 2, cfg, stream)   # units of a whole side
    return results


def result_score(r: ActuatorResult, cfg: RunConfig) -> float:
    """A saved result's score: its fit objective plus the mass penalty of its PAMs (both sides, with a
    block's assumed mass) — what the run's choices between results compare."""
    p = r.pam
    return float(r.objective) + cfg.mass_penalty(p.diameter_mm, p.n_parallel, p.resting_length_m, p.transmission)


def _size(p: Pam) -> str:
    """``20 mm x1`` (``on a k:1 pulley block`` where it is on one)."""
    return f"{p.diameter_mm} mm x{p.n_parallel}" + (f" on a {p.transmission}:1 pulley block" if p.transmission > 1 else "")


#: ``start`` of the attempt :func:`resize_pass` adds to an actuator's attempts (a block try: with its ratio).
BONE_RESIZE_START = "resize after the bone rounds"


def resize_pass(results: list[ActuatorResult], cfg: RunConfig, stream=sys.stderr) -> list[ActuatorResult]:
    """Choose the diameter again on the fit the bone meshes leave (after :func:`_finish_actuator`).

    The unit budget chooses every diameter on the first phase's fits, made without the bone meshes; the bone
    rounds then raise some fits many times, and not alike for every diameter (sartorius: 20 mm fitted best
    before them, 10 mm after). An actuator whose saved objective is above ``cfg.resize_above`` gets its other
    first-phase candidates with the same parallel count (so the unit budget still holds) through the bone
    rounds and the one-segment stage (:func:`_finish_choice`, in the workers), where the candidate's score
    before the rounds (objective + mass penalty) was below the actuator's score after them; an actuator the
    one-segment stage put on a pulley block gets the block throughout (:func:`block_tasks`). Kept: the result
    clear of bone, then the one on a straight segment where the present one is, then with the lower score
    (objective + mass penalty), the present one on ties. The actuator's bone log gets one line per try."""
    first: dict = _STATE["first"]
    chosen: dict = _STATE.get("choice", {})

    tasks = []
    for k, r in enumerate(results):
        if not (r.success and r.objective is not None and r.objective > cfg.resize_above):
            continue
        now = result_score(r, cfg)
        for key, (pre, _, _) in sorted(first[k].candidates.items()):
            if key[1] == r.n_parallel and key[0] != r.pam.diameter_mm and key != chosen.get(k) and pre < now:
                tasks.append((k, key, None))
    seed = _STATE.get("seed_design")
    blocks = block_tasks(results, cfg, design_mass(seed, results) if seed is not None else None)
    if not tasks and not blocks:
        return results
    print(f"resize after the bone rounds: {len(tasks)} other diameter(s) of "
          f"{len({t[0] for t in tasks})} actuator(s) with fit objective > {cfg.resize_above:g}"
          + (f"; {len(blocks)} pulley block(s) throughout for {len({t[0] for t in blocks})} actuator(s) the "
             f"one-segment stage put on one, fit objective > {cfg.block_refit_above:g}" if blocks else ""),
          file=stream, flush=True)
    tasks += blocks
    tried = sorted(_map(_finish_choice, tasks, cfg, stream),
                   key=lambda a: (a.id, a.attempts[-1]["diameter_mm"], a.attempts[-1].get("transmission", 1)))
    out = list(results)
    held_out = _validation() if cfg.resize_on == "validation" else None
    for k in sorted({t[0] for t in tasks}):
        r = results[k]
        lines = []

        on_one = bool(r.mount.get("mounted"))

        def key_of(a: ActuatorResult) -> tuple:
            # clear of bone first; a try that leaves one straight segment never replaces a PAM on one
            return (not a.bone.get("clear", True), on_one and not a.mount.get("mounted"),
                    held_out(a, k) if held_out else result_score(a, cfg))

        def said(a: ActuatorResult) -> str:
            return (f"objective {a.objective:.4g}, score {result_score(a, cfg):.4g}"
                    + (f", validation {held_out(a, k):.4g}" if held_out else ""))

        best, best_key = r, key_of(r)
        for alt in tried:
            if alt.id != r.id:
                continue
            t = alt.attempts[-1].get("transmission", 1)
            what = f"  resize: {alt.attempts[-1]['diameter_mm']} mm x{alt.n_parallel}" + \
                (f" on a {t}:1 pulley block throughout" if t > 1 else "")
            if t > 1 and alt.direct is None:      # the mass budget may go back to the result before it
                alt.direct = r if r.pam.transmission < alt.pam.transmission else r.direct
            if not alt.success or alt.objective is None:
                lines.append(f"{what}: {alt.status} (not kept)")
                continue
            key = key_of(alt)
            lines.append(f"{what} -> {_size(alt.pam)}: {said(alt)}"
                         f"{', not clear of bone' if key[0] else ''}{', not on one straight segment' if key[1] else ''}"
                         f" (now {_size(r.pam)}: {said(r)})")
            if key < best_key:
                best, best_key = alt, key
        if best is not r:
            t = best.attempts[-1].get("transmission", 1)
            best.attempts[-1]["start"] = BONE_RESIZE_START + (f" ({t}:1)" if t > 1 else "")
            lines.append(f"  resize: kept the {best.attempts[-1]['diameter_mm']} mm try"
                         f"{f' with the {t}:1 block throughout' if t > 1 else ''}: {_size(best.pam)} (was {_size(r.pam)}"
                         f"{', its block from the one-segment stage' if t > 1 and r.pam.transmission > 1 else ''})")
        else:
            lines.append(f"  resize: kept {_size(r.pam)}")
        for line in lines:
            print(f"actuator {r.id} {r.name}:{line[1:]}", file=stream, flush=True)
        out[k] = dataclasses.replace(best, bone=dict(best.bone, log=list(best.bone.get("log", [])) + lines))
    return out


#: The unit reallocation (:func:`reallocate_pass`) tries at most this many receivers (one solve each, in the
#: workers: about one actuator's bone rounds of wall time on 2 cores) ...
REALLOCATE_TRIES = 2
#: ... among the actuators failing an audit fit limit whose errors are at most this many times the limits
#: (validation NRMSE / 0.15 and worst error / 0.25, the larger): near passing, where one more unit can decide.
REALLOCATE_NEAR = 1.5
#: ``start`` of a reallocated actuator's new attempt.
REALLOCATE_START = "unit reallocation (from the solved route)"


def reallocate_pass(results: list[ActuatorResult], cfg: RunConfig, stream=sys.stderr) -> list[ActuatorResult]:
    """Move PAM units to where they make a PAM pass (after :func:`resize_pass`).

    The unit budget is spent on the first phase's fits, made without the bone meshes; after the bone rounds an
    actuator with several units may fail both of the audit's fit limits (primary NRMSE and worst error about a
    crossed coordinate, on the optimiser's own validation poses, :mod:`optimize.validation`) while one with a
    single unit narrowly fails one. Donors: results with ``n_parallel >= 2`` failing both limits (a warm start
    that held is not one: its run had the same chance). Receivers: the other results failing a limit, within
    :data:`REALLOCATE_NEAR` of the limits, nearest first, at most :data:`REALLOCATE_TRIES` per donor unit, each
    re-solved with one more unit from its solved route (bone rounds and one-segment stage, in the workers),
    the donor with one fewer; the receivers that pass take the units, the most audit limits newly passed
    first, then the smallest error. A move is kept where the receiver then passes both limits within
    :data:`PASS_MARGIN`, the donor's re-solve succeeds, both are clear of bone and on one straight segment
    where they were, and the robot's estimated mass stays within ``cfg.max_mass_kg``: the unit count does
    not change. Only direct (1:1) results take part. Each moved actuator's bone log says so."""
    lim_n, lim_w = _fit_limits()
    seed = _STATE["seed_design"]

    def errors(r: ActuatorResult, k: int) -> tuple[float, float]:
        return _validation_errors(r.pam, k)

    def direct(r: ActuatorResult, k: int) -> bool:
        return (r.success and r.z is not None and r.objective is not None
                and r.pam.transmission == _STATE["data"][k].pam.transmission == 1)

    err = {k: errors(r, k) for k, r in enumerate(results) if direct(r, k)}
    donors = [k for k, (nr, w) in err.items() if results[k].n_parallel >= 2 and nr > lim_n and w > lim_w
              and not _STATE["first"][k].warm]
    near = sorted((max(nr / lim_n, w / lim_w), k) for k, (nr, w) in err.items()
                  if (nr > lim_n or w > lim_w) and k not in donors
                  and results[k].n_parallel < min(cfg.max_parallel, _STATE.get("n_cap", cfg.max_parallel)))
    receivers = [k for ratio, k in near if ratio <= REALLOCATE_NEAR][:REALLOCATE_TRIES * len(donors)]
    if not donors or not receivers:
        return results

    def task(k: int, dn: int) -> tuple:
        # the donor keeps its straight segment (its fit fails either way); a receiver's fit decides where
        # the one-segment stage puts it (measured: peroneus tertius at 10 mm x2 with its segment's rows
        # 0.155, put on one afterwards 0.105)
        r = results[k]
        return (k, (r.pam.diameter_mm, r.n_parallel + dn), r.z, 1, REALLOCATE_START, dn < 0)

    def size(k: int, dn: int = 0) -> str:
        return f"{results[k].pam.diameter_mm} mm x{results[k].n_parallel + dn}"

    print("unit reallocation: " + ", ".join(f"{results[k].id} {results[k].name} ({size(k)}, validation "
                                             f"{err[k][0]:.3f}/{err[k][1]:.3f})" for k in donors)
          + " fail both fit limits; tried with one unit more: " + ", ".join(
              f"{results[k].id} {results[k].name} ({size(k)}, {err[k][0]:.3f}/{err[k][1]:.3f})" for k in receivers),
          file=stream, flush=True)
    tasks = [task(k, -1) for k in donors] + [task(k, +1) for k in receivers]
    done = {(a.id, a.n_parallel): a for a in _map(_finish_choice, tasks, cfg, stream)}
    out = list(results)
    lines: dict[int, list[str]] = {}

    def failed(a: ActuatorResult | None, k: int) -> str:
        """Why the re-solve ``a`` of actuator ``k`` cannot be kept ('' where it can)."""
        if a is None:
            return "not solved"
        if not a.success:
            return a.status
        if not a.bone.get("clear", True):
            return "not clear of bone"
        return "leaves its straight segment" if results[k].mount.get("mounted") and not a.mount.get("mounted") else ""

    free = [k for k in donors if not failed(done.get((results[k].id, results[k].n_parallel - 1)), k)]
    for k in donors:
        if k not in free:
            why = failed(done.get((results[k].id, results[k].n_parallel - 1)), k)
            lines.setdefault(k, []).append(f"  unit reallocation: {size(k, -1)} not kept ({why})")
    passing = []
    for k in receivers:
        a = done.get((results[k].id, results[k].n_parallel + 1))
        if failed(a, k):
            lines.setdefault(k, []).append(f"  unit reallocation: {size(k, +1)}: {failed(a, k)} (not kept)")
            continue
        nr, w = errors(a, k)
        said = f"  unit reallocation: {size(k, +1)}: validation {nr:.3f}/{w:.3f} (was {err[k][0]:.3f}/{err[k][1]:.3f})"
        if nr > lim_n - PASS_MARGIN or w > lim_w - PASS_MARGIN:
            lines.setdefault(k, []).append(f"{said}: not kept (not within both limits less {PASS_MARGIN:g})")
            continue
        gained = (err[k][0] > lim_n) + (err[k][1] > lim_w)         # audit fit limits it newly passes
        passing.append((-gained, max(nr / lim_n, w / lim_w), k, a, said))
    for _, _, k, a, said in sorted(passing, key=lambda t: t[:3]):
        r = results[k]
        if not free:
            lines.setdefault(k, []).append(f"{said}: not kept (no donor unit left)")
            continue
        j = free[0]
        trial = list(out)
        trial[k], trial[j] = a, done[(results[j].id, results[j].n_parallel - 1)]
        mass = design_mass(seed, trial)
        if cfg.max_mass_kg > 0 and mass > cfg.max_mass_kg:
            lines.setdefault(k, []).append(f"{said}: not kept (mass {mass:.2f} kg > {cfg.max_mass_kg:g})")
            continue
        free.pop(0)
        out = trial
        lines.setdefault(k, []).append(f"{said}: kept, its unit from {results[j].id} {results[j].name}")
        nr_j, w_j = errors(out[j], j)
        lines.setdefault(j, []).append(f"  unit reallocation: {size(j, -1)} (a unit to {r.id} {r.name}): validation "
                                       f"{nr_j:.3f}/{w_j:.3f} (was {err[j][0]:.3f}/{err[j][1]:.3f})")
    for k in free:
        lines.setdefault(k, []).append(f"  unit reallocation: kept {size(k)} (no receiver passed with its unit)")
    for k, said in lines.items():
        for line in said:
            print(f"actuator {out[k].id} {out[k].name}:{line[1:]}", file=stream, flush=True)
        out[k] = dataclasses.replace(out[k], bone=dict(out[k].bone, log=list(out[k].bone.get("log", [])) + said))
    return out


def block_tasks(results: list[ActuatorResult], cfg: RunConfig, total_mass: float | None = None) -> list[tuple]:
    """:func:`resize_pass`'s tries of pulley blocks throughout: an actuator the one-segment stage put on a
    k:1 block (on the route fitted without it: out of reach or infeasible at 1:1) whose fit objective is
    above ``cfg.block_refit_above`` (and not above ``cfg.resize_above``: those get their other diameters) is
    solved again with its PAM on a block from the first phase on, at the largest ratio of
    :data:`optimize.mount.BLOCKS` (3:1: the most stroke, the least force; same diameter and parallel count),
    so the route's fit and bone rounds see the block's stroke and force. (Both ratios, measured: twice the
    tries, one more kept — gluteus maximus at 2:1, objective 0.864 -> 0.862 — and over the 10-minute run.)
    Not tried where, with the design's mass ``total_mass`` [kg] given, the pulleys it adds would leave less
    than :data:`BLOCK_TRY_HEADROOM_KG` below ``cfg.max_mass_kg`` (:func:`mass_pass` would take it off again).
    Tasks ``(k, (diameter, n), z, ratio)``, ``z`` the
    result's decision vector before the block (the start where the first phase has no fit of that size)."""
    from .mount import BLOCKS  # noqa: PLC0415

    if not (cfg.mount and cfg.mount_blocks and cfg.block_refit_above > 0):
        return []
    tasks = []
    for k, r in enumerate(results):
        if (r.success and r.objective is not None and cfg.block_refit_above < r.objective
                and not (cfg.resize_above > 0 and r.objective > cfg.resize_above)
                and r.direct is not None and r.pam.transmission > 1):
            t = BLOCKS[-1]
            if total_mass is not None and cfg.max_mass_kg > 0 and t > r.pam.transmission:
                # the pulleys it adds (at the present resting length) would leave no headroom
                heavier = _unit_mass(dataclasses.replace(r.pam, transmission=t))
                if total_mass + heavier - _unit_mass(r.pam) > cfg.max_mass_kg - BLOCK_TRY_HEADROOM_KG:
                    continue
            tasks.append((k, (r.pam.diameter_mm, r.n_parallel), r.direct.z, t))
    return tasks


def _validation_set() -> tuple[np.ndarray, np.ndarray]:
    """The validation poses and the human torques there (:mod:`optimize.validation`), made once per process."""
    from .validation import validation_poses  # noqa: PLC0415

    if _STATE.get("validation") is None:
        human = _STATE["human"]
        q = validation_poses(human, _STATE["rom"], _STATE["cfg"].seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            _STATE["validation"] = (q, human.torques(q))
    return _STATE["validation"]


def _validation_errors(pam: Pam, k: int) -> tuple[float, float]:
    """Primary NRMSE and worst error about a crossed coordinate (:mod:`optimize.validation`) of ``pam`` as
    actuator ``k``'s PAM, on the run's validation poses (the seed design carries the run's pressure, force model
    and fitting length)."""
    from .validation import validation_error  # noqa: PLC0415

    q, T = _validation_set()
    return validation_error(pam, _STATE["human"], q, T, list(_STATE["data"][k].crossed or []),
                            _STATE["seed_design"])


def _fit_limits() -> tuple[float, float]:
    """The audit's fit limits: (primary NRMSE, worst coordinate error) a PAM passes at or below."""
    from pamkin.audit import load_limits  # noqa: PLC0415

    thr = load_limits()["thresholds"]
    return thr["nrmse_good"], thr["worst_coordinate_error_good"]


def _validation():
    """``error(result, k)``: the validation error (:mod:`optimize.validation`: primary NRMSE + worst error about
    a crossed coordinate, on poses like the audit's from the optimiser's own stream) of actuator ``k``'s
    result; the poses and human torques are made once per run."""
    _validation_set()

    def error(r: ActuatorResult, k: int) -> float:
        return float(sum(_validation_errors(r.pam, k)))

    return error


#: ``mount_passing``: a mount at a fit cost is accepted where the mounted PAM's validation NRMSE and worst error
#: stay this far within the audit's limits (the validation poses are 400, the audit's 2000; measured on the
#: default design (stop 37's, unchanged at stop 39) the two differ by at most 0.008 in NRMSE and 0.015 in worst
#: error for every PAM whose errors are below 0.3).
PASS_MARGIN = 0.02


def _failing_fit(crossed: list[str], already_failing: bool = True, still_passing: bool = False):
    """``(spanning, mounted) -> reason | None`` for :func:`optimize.mount.mount_stage`: a reason to mount a PAM
    although its fit cost exceeds ``mount_cost``, where no audit fit count is at stake — with
    ``already_failing`` (``mount_failing``) when the spanning PAM's fit fails both of the audit's fit limits
    (primary NRMSE and worst error about a crossed coordinate, :mod:`optimize.validation`, on the optimiser's own
    validation poses; thresholds from the audit's limits file), so that mounting it changes neither count; with
    ``still_passing`` (``mount_passing``) when the mounted PAM still passes both within :data:`PASS_MARGIN`, so
    that mounting it loses neither; else None."""
    from pamkin.audit import load_limits  # noqa: PLC0415

    from .validation import validation_error  # noqa: PLC0415

    thr = load_limits()["thresholds"]
    lim_n, lim_w = thr["nrmse_good"], thr["worst_coordinate_error_good"]
    q, T = _validation_set()

    def error(pam: Pam) -> tuple[float, float]:
        return validation_error(pam, _STATE["human"], q, T, crossed, _STATE["seed_design"])

    def reason(spanning: Pam, mounted: Pam) -> str | None:
        if already_failing:
            nr0, w0 = error(spanning)
            if nr0 > lim_n and w0 > lim_w:
                nr1, w1 = error(mounted)
                return (f"its fit fails both audit fit limits already (validation NRMSE {nr0:.3f} > {lim_n:g}, "
                        f"worst {w0:.3f} > {lim_w:g}; on one segment {nr1:.3f}, {w1:.3f})")
        if still_passing:
            nr1, w1 = error(mounted)
            if nr1 <= lim_n - PASS_MARGIN and w1 <= lim_w - PASS_MARGIN:
                return (f"on one segment it still passes both audit fit limits (validation NRMSE {nr1:.3f} <= "
                        f"{lim_n:g} - {PASS_MARGIN:g}, worst {w1:.3f} <= {lim_w:g} - {PASS_MARGIN:g})")
        return None

    return reason


def _unit_mass(p: Pam) -> float:
    """Estimated mass [kg] of a PAM's units on both sides (the audit's)."""
    from pamkin.design import pams_mass  # noqa: PLC0415

    return pams_mass([p])


def design_mass(seed: Design, results: list[ActuatorResult]) -> float:
    """The robot's estimated mass [kg] (the audit's, both sides): the results' PAMs, the seed's for actuators
    not optimised."""
    from pamkin.design import pams_mass  # noqa: PLC0415

    ids = {r.id for r in results}
    return pams_mass([p for p in seed.pams if p.id not in ids] + [r.pam for r in results])


#: Headroom [kg] below ``max_mass_kg`` the re-sizing's blocks throughout (:func:`block_tasks`) must leave: a
#: warm re-run from the design re-solves every PAM and its resting lengths drift (measured: +0.33 kg from the
#: stop-27 default, +0.29 kg from the stop-28 one, +0.22 kg from one with semimembranosus' try), and it cannot
#: take a warm block off (it has no result without it).
BLOCK_TRY_HEADROOM_KG = 0.5


def _block_try(r: ActuatorResult) -> bool:
    """Whether ``r`` is a kept try of :func:`block_tasks` (a block throughout from the re-sizing)."""
    return bool(r.attempts) and str(r.attempts[-1].get("start", "")).startswith(BONE_RESIZE_START + " (")


def mass_pass(seed: Design, results: list[ActuatorResult], cfg: RunConfig, stream=sys.stderr
              ) -> list[ActuatorResult]:
    """Keep the robot's estimated mass within ``cfg.max_mass_kg`` where the one-segment stage's pulley blocks
    took it above: while it is over, the block whose removal loses the least score (objective + mass penalty)
    per kilogram saved comes off again — the actuator goes back to its result before the block
    (``ActuatorResult.direct``). The mass is the audit's (:func:`pamkin.design.pam_unit_mass`, both sides,
    the seed's PAMs for actuators not optimised). Where no block is left to take off, the run says so.
    First, the re-sizing's blocks throughout go back to the result before them (the same way) while the mass
    is above the budget less :data:`BLOCK_TRY_HEADROOM_KG`."""
    mass = _unit_mass
    total = design_mass(seed, results)
    out = list(results)
    for budget, only in ((cfg.max_mass_kg - BLOCK_TRY_HEADROOM_KG, _block_try), (cfg.max_mass_kg, None)):
        what = f"mass budget {cfg.max_mass_kg:g} kg" + \
            (f" less {BLOCK_TRY_HEADROOM_KG:g} kg for a warm re-run (blocks throughout)" if only else "")
        while total > budget:
            options = [((result_score(r.direct, cfg) - result_score(r, cfg)) / (mass(r.pam) - mass(r.direct.pam)), k)
                       for k, r in enumerate(out)
                       if r.direct is not None and r.direct.success and mass(r.pam) > mass(r.direct.pam)
                       and (only is None or only(r))]
            if not options:
                if only is None:
                    print(f"{what}: the design's estimate is {total:.2f} kg and no pulley block is left to take off",
                          file=stream, flush=True)
                break
            _, k = min(options)
            r = out[k]
            saved = mass(r.pam) - mass(r.direct.pam)
            line = (f"{what}: {total:.2f} kg; the {r.pam.transmission}:1 block of actuator {r.id} {r.name} comes "
                    f"off again ({_size(r.pam)} -> {_size(r.direct.pam)}, -{saved:.2f} kg, objective {r.objective:.4g} -> "
                    f"{r.direct.objective:.4g})")
            print(line, file=stream, flush=True)
            d = r.direct
            out[k] = dataclasses.replace(d, bone=dict(d.bone, log=list(d.bone.get("log", [])) + ["  " + line]),
                                         mount=dict(d.mount, line=d.mount.get("line", "") + "; " + line))
            total -= saved
    return out


def _walking_pass(seed_design: Design, results: list[ActuatorResult], budget: int, cfg: RunConfig,
                  stream) -> list[ActuatorResult]:
    """The optimised design checked on the walking trial, diameters / counts swapped where it falls short
    (:mod:`optimize.gait_check`)."""
    from pamkin.robot import robot_skeleton  # noqa: PLC0415

    from .gait_check import midpoint_trial, plan, walking_pass  # noqa: PLC0415

    skeleton = robot_skeleton()
    trial = midpoint_trial(skeleton)
    report: dict = {"target": cfg.walking_min}
    if trial is None:
        lines = ["walking check skipped: the walking trial (pamkin.gait.DEFAULT_IK / DEFAULT_ID) is not there"]
    else:
        design = seed_design
        for r in results:
            design = design.replace_pam(r.pam)
        order = {r.id: k for k, r in enumerate(_STATE["first"].values())}

        def resolve(tasks: list) -> list[ActuatorResult]:
            """The actuators of ``tasks`` solved again with another diameter / count (in the workers)."""
            done = {(r.id, r.pam.diameter_mm, r.pam.n_parallel): r
                    for r in _map(_finish_choice, [(order[results[i].id], key, z) for i, key, z in tasks], cfg, stream)}
            return [done[(results[i].id, *key)] for i, key, _ in tasks]

        before = plan(design, skeleton, trial).feasible_frame_fraction
        after_design, results, lines = walking_pass(design, results, _STATE["data"], cfg, budget, skeleton, trial,
                                                    _STATE["human"], _STATE["rom"], resolve)
        report.update(samples=len(trial.times), fraction_before=round(before, 4),
                      fraction_after=round(plan(after_design, skeleton, trial).feasible_frame_fraction, 4))
    for line in lines:
        print(line, file=stream, flush=True)
    _STATE["walking"] = dict(report, log=lines)
    return results


def _map(fn, tasks: list, cfg: RunConfig, stream, cost: list[float] | None = None) -> list[ActuatorResult]:
    """``fn`` over ``tasks`` in ``cfg.workers`` forked processes (progress on ``stream``), in the order they
    finish. With ``cost`` (an estimate of each task's time) the tasks are handed out longest first, so that
    no worker starts a long one while the others run out of work (the results do not depend on the order:
    every task is solved on its own)."""
    if cost is not None:
        tasks = [tasks[i] for i in sorted(range(len(tasks)), key=lambda i: (-cost[i], i))]
    results: list[ActuatorResult] = []
    if cfg.workers > 1 and len(tasks) > 1:
        with _pool(min(cfg.workers, len(tasks))) as pool:
            for r in pool.imap_unordered(fn, tasks):
                results.append(r)
                _progress(len(results), len(tasks), r, stream)
    else:
        with _one_blas_thread():
            for t in tasks:
                results.append(fn(t))
                _progress(len(results), len(tasks), results[-1], stream)
    return results


@contextlib.contextmanager
def _one_blas_thread():
    """Context in which BLAS runs on one thread: every solve does, in the workers (:func:`_pool`) and in the
    run's own process, so that the design does not depend on how many BLAS threads the machine would start
    (they change the summation order) and the workers do not oversubscribe the cores (idle OpenBLAS threads spin;
    measured, 4 actuators on 2 workers of a 2-core machine: 224 -> 180 s wall, system time 101 -> 18 s).
    Two OpenBLAS copies are involved: numpy's, limited with threadpoolctl, and the one CasADi loads with
    IPOPT (MUMPS), which threadpoolctl does not find: it reads ``OPENBLAS_NUM_THREADS`` when it is loaded,
    so the variable is 1 inside the context (restored on exit; a copy loaded inside keeps one thread)."""
    from threadpoolctl import threadpool_limits  # noqa: PLC0415

    before = os.environ.get("OPENBLAS_NUM_THREADS")
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
    finally:
        if before is None:
            os.environ.pop("OPENBLAS_NUM_THREADS", None)
        else:
            os.environ["OPENBLAS_NUM_THREADS"] = before


def _limit_worker() -> None:
    """Pool initializer: one BLAS thread for the worker's life (:func:`_one_blas_thread`)."""
    _STATE["blas_limit"] = _one_blas_thread()
    _STATE["blas_limit"].__enter__()


def _pool(n: int):
    """A pool of ``n`` forked workers (they share the run's state, :data:`_STATE`), one BLAS thread each."""
    return mp.get_context("fork").Pool(n, initializer=_limit_worker)


def check_results(results: list[ActuatorResult]) -> None:
    """Raise :class:`InfeasibleError` naming the violated constraints of infeasible actuators."""
    from .problem import FEASIBILITY_TOL  # noqa: PLC0415  (casadi only in workers / optimiser)

    bad = [r for r in results if not r.success]
    if bad:
        lines = []
        for r in bad:
            worst = sorted(((v, k) for k, v in r.violations.items() if v > FEASIBILITY_TOL), reverse=True)[:3]
            what = "; ".join(f"{k} (violated by {v:.3g})" for v, k in worst) or r.status
            lines.append(f"actuator {r.id} {r.name}: {r.status}: {what}")
        raise InfeasibleError("infeasible: " + " | ".join(lines))


def apply_design(design: Design, design_path: Path | None = None, urdf_path: Path | None = None,
                 run_folder: str | os.PathLike | None = None) -> None:
    """Write a design into the robot data and regenerate its URDF (each file atomically).

    The URDF is rendered from a temporary copy first, so a failure leaves both files unchanged.
    Defaults: ``robot/data/pam_biped.yaml`` and ``urdf/pam_biped.urdf``. ``run_folder`` is named in
    the design file's header.
    """
    import tempfile  # noqa: PLC0415

    design_path = Path(design_path or ROBOT_DESIGN)
    urdf_path = Path(urdf_path or ROBOT_URDF)
    header = _HEADER if run_folder is None else _HEADER.replace(
        "--apply`;", f"--apply` from the run folder {Path(run_folder).name};")
    with tempfile.TemporaryDirectory() as tmp:
        tmp_design = Path(tmp) / Path(design_path).name
        save_design(design, tmp_design, header)
        urdf = render_robot_urdf(design_path=tmp_design).replace(str(Path(tmp)), "")
    save_design(design, design_path, header)
    atomic_write(urdf_path, urdf)


_HEADER = ("# The PAM robot's design (right side; the left side is the mirror image).\n"
           "# Written by `pamkin optimize --apply`; format: pamkin.design.\n")


def _run_header(out_dir: Path, cfg: RunConfig) -> str:
    """Header of a run folder's design.yaml: which command wrote it, from which config."""
    return ("# An optimised PAM design (right side; the left side is the mirror image).\n"
            f"# Written by `pamkin optimize` into the run folder {Path(out_dir).name} "
            f"(config: {Path(cfg.source).name if cfg.source else 'defaults'}); format: pamkin.design.\n"
            "# Not applied to the robot's design (`pamkin optimize --apply` does that); reuse it with\n"
            "# --design or --warm-start and this folder.\n")


def _write_summary(out_dir: Path, summary: dict) -> None:
    """``summary.json`` as strict JSON (atomically): a non-finite number (an undefined or failing-as-infinite
    error, a failed solve's objective) is written as ``null``, which every JSON reader accepts."""
    from pamkin.compare import finite_or_none  # noqa: PLC0415

    atomic_write(out_dir / "summary.json", json.dumps(finite_or_none(summary), indent=2, allow_nan=False))


def warm_seed(seed: Design, warm: Design, names: Design | None = None) -> tuple[Design, set[int]]:
    """``seed`` with every PAM it shares with ``warm`` (a finished run's design) replaced by the warm one, and
    their ids. A warm route's rollers and detour via points are not kept (:func:`pamkin.detour.remove_via`:
    the points the seed route does not have, their length off the tendon again): the roller stage
    (``limits.rollers``) and the detours (``limits.detours``) place them again. ``names`` (default ``seed``):
    the design whose route points a warm route may keep (the seed with every eyelet of the run's table)."""
    from pamkin.detour import remove_via  # noqa: PLC0415

    names = names or seed
    ids = set()
    for p in warm.pams:
        if p.id in {q.id for q in seed.pams}:
            try:
                p = remove_via(p, {pt.name for pt in names.pam(p.id).points})
            except ValueError as e:      # a warm route with points the seed's does not have on other bodies
                raise DataFileError(warm.path or "<warm start>", f"{e}: not a run of this seed design") from None
            seed = seed.replace_pam(dataclasses.replace(p, rollers=()))
            ids.add(p.id)
    return seed, ids


def run(cfg: RunConfig, out_dir: Path, apply: bool = False, stream=sys.stderr, on_design=None) -> dict:
    """Run an optimisation into ``out_dir`` (created); optionally apply the result.

    ``on_design`` (optional) is called with ``out_dir`` as soon as the result's ``design.yaml`` is written,
    before the run's own check and plot (``pamkin optimize`` starts its audit there, beside them).

    Returns:
        The summary (also written to ``out_dir/summary.json``).
    """
    from .check import summarize  # noqa: PLC0415
    from .plots import before_after_plot  # noqa: PLC0415

    from pamkin.robot import robot_skeleton  # noqa: PLC0415

    t0 = time.perf_counter()
    skeleton = robot_skeleton()
    kw = {"bodies": skeleton.bodies, "coordinates": skeleton.coordinates}
    seed = load_design(cfg.design, **kw) if cfg.design else load_design(**kw)
    eyelets: list[str] = []
    names = None
    if cfg.eyelets:         # the optimised actuators' eyelets (pamkin.eyelets), before the warm start
        import pamkin  # noqa: PLC0415
        from pamkin.bones import BoneSet  # noqa: PLC0415

        human = pamkin.gait2392()
        bones = BoneSet(human)
        # every eyelet of the table names the route points a warm start's routes may hold (a warm run's
        # actuators not optimised here keep theirs, lengths and all)
        names = dataclasses.replace(cfg, actuators=[]).apply_eyelets(seed, human, bones)[0]
        seed, eyelets = cfg.apply_eyelets(seed, human, bones)
    warm_ids: set[int] = set()
    if cfg.warm_start:
        seed, warm_ids = warm_seed(seed, load_design(Path(cfg.warm_start) / "design.yaml", **kw), names)
        if cfg.eyelets:     # an optimised actuator's warm route without its eyelet (a run without them) gets it
            seed, eyelets = cfg.apply_eyelets(seed, human, bones)
    for line in eyelets:
        print(line, file=stream, flush=True)
    _STATE["warm_ids"] = warm_ids      # these actuators try their warm diameter and count first
    rolled = [p.id for p in seed.pams if p.rollers]
    if rolled:
        raise DataFileError(seed.path or "<design>", f"PAM(s) {rolled} have rollers, which pamkin optimize does not "
                            "model yet (it would move their points and ignore the rollers); remove the rollers to "
                            "optimise, or audit, view and export the design as it is")
    cfg.check_design(seed)
    seed = cfg.apply_transmission(seed)
    seed = Design(seed.name, seed.pams, cfg.pressure_Pa, cfg.force_model, seed.fitting_length_m, seed.rom,
                  seed.description, seed.path, dict(seed.extra))
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    log = [f"pamkin optimize: seed design {seed.name!r} ({seed.path}), config {cfg.source or 'defaults'}",
           f"workers {cfg.workers}, multistart {cfg.multistart}, diameters {cfg.diameters_mm}, "
           f"max_parallel {cfg.max_parallel}, force model {cfg.force_model}, pressure {cfg.pressure_Pa:.0f} Pa",
           *eyelets]
    _STATE["walking"] = None
    try:
        with _one_blas_thread():       # every solve on one BLAS thread, here as in the workers
            results = solve_all(seed, cfg, stream)
            if cfg.bone_mesh and cfg.pam_clearance:
                results = clearance_pass(seed, results, cfg, stream)
            if cfg.bone_mesh and cfg.rollers:
                results = roller_pass(results, cfg, stream)
            if cfg.bone_mesh and cfg.detours:
                results = detour_pass(results, cfg, stream)
    finally:
        _STATE["warm_ids"] = set()     # a later solve_all in this process (library use) starts cold
    log.extend((_STATE["walking"] or {}).get("log", []))
    solve_seconds = time.perf_counter() - t0
    new = seed
    for r in results:
        new = new.replace_pam(r.pam)
    new = Design(f"optimized from {seed.name}", new.pams, new.pressure_Pa, new.force_model,
                 new.fitting_length_m, new.rom, f"pamkin optimize run {out_dir.name}", "", dict(new.extra))
    ends: list[str] = []
    if cfg.mount and cfg.pam_ends:
        from .pam_clearance import choose_ends  # noqa: PLC0415

        new, ends = choose_ends(new, _STATE["human"], _STATE["rom"], cfg.seed)
        for line in ends:
            print(line, file=stream, flush=True)
    save_design(new, out_dir / "design.yaml", _run_header(out_dir, cfg))
    if on_design is not None:
        on_design(out_dir)
    for r in results:
        log.append(f"actuator {r.id} {r.name}: {r.status} in {r.seconds:.1f} s; attempts: " +
                   "; ".join(f"{a['diameter_mm']} mm x{a['n_parallel']} {a['start']}: {a['status']} "
                             f"J={a['objective']:.4g}{'' if a['feasible'] else ' (infeasible)'} ({a['seconds']:.1f} s)"
                             for a in r.attempts)
                   + ("; not tried, dominated: " + "; ".join(r.skipped) if r.skipped else ""))
        if r.bone:
            log.extend(r.bone["log"])
            log.append(f"  bone-mesh clearance of actuator {r.id} {r.name}: " + bone_line(r.bone))
        if r.mount:
            log.append(f"  actuator {r.id} {r.name}: {r.mount['line']}")
    for r in results:
        if r.bone and not r.bone["clear"]:
            print(f"bone-mesh: actuator {r.id} {r.name}: {bone_line(r.bone)}", file=stream, flush=True)
    costly = fit_cost_lines(results)
    for line in costly:
        print(f"bone-mesh: {line}", file=stream, flush=True)
    reach = bone_limit_lines(results)
    for line in reach:
        print(f"fit limits: {line}", file=stream, flush=True)
    for line in mount_lines(results, cfg):
        print(line, file=stream, flush=True)
    print("solving done; checking every actuator on dense grids (numpy pipeline) ...", file=stream, flush=True)
    summary = summarize(seed, new, results, cfg, progress=_check_progress(stream))
    bone = {str(r.id): {k: v for k, v in r.bone.items() if k != "log"} for r in results if r.bone}
    if bone:
        summary["bone_mesh"] = bone
        summary["bone_mesh_not_clear"] = [f"{r.id} {r.name}: {bone_line(r.bone)}" for r in results
                                          if r.bone and not r.bone["clear"]]
        summary["all_clear_bone"] = not summary["bone_mesh_not_clear"]    # the meshes replace the capsules
        summary["grids"]["min_bone_clearance_m"] += (" (the first phase's bone model; with the bone meshes the "
                                                     "actuators' bone_mesh entries give the clearance)")
        summary["bone_mesh_fit_cost"] = costly
        summary["fit_limits_and_bone"] = reach
    if any(r.mount for r in results):
        summary["one_segment"] = {str(r.id): r.mount for r in results if r.mount}
    if ends:
        summary["pam_ends"] = ends
    if _STATE.get("walking"):
        summary["walking_check"] = _STATE["walking"]      # optimize.gait_check: fractions between the trial's frames
    summary["solve_seconds"] = round(solve_seconds, 1)
    summary["total_seconds"] = round(time.perf_counter() - t0, 1)
    _write_summary(out_dir, summary)
    before_after_plot(seed, new, out_dir / "before_after.png",
                      seed_label=f"warm start ({Path(cfg.warm_start).name})" if warm_ids else None)
    log.extend(ends)
    log.extend(f"fit limits: {line}" for line in reach)
    log.append(f"total {summary['total_seconds']} s (solves {solve_seconds:.1f} s)")
    atomic_write(out_dir / "log.txt", "\n".join(log) + "\n")
    try:
        check_results(results)
    except InfeasibleError:
        summary["applied"] = False
        _write_summary(out_dir, summary)
        raise
    if apply:
        apply_design(new, run_folder=out_dir)
        summary["applied"] = True
        _write_summary(out_dir, summary)
    return summary


def default_workers() -> int:
    return max(1, min(2, os.cpu_count() or 1))
