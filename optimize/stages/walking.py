"""Walking check of the optimised design: can its PAMs produce the joint moments of human walking?

The unit budget (:func:`optimize.stages.unit_budget.choose_units`) picks every actuator's Festo diameter and parallel
count for the least summed torque-fit score, and the bone-mesh rounds then move the routes onto bone. The
result can be too weak, or pull in the wrong mix of directions, for walking: measured, gluteus
medius/minimus on 20 mm PAMs along the femur left the 10 mm tensor fasciae latae saturated at 620 kPa in
early left stance (audit: 75 % of the frames feasible). A check on the fit phase's routes (before the
rounds) did not see it (100 %): those routes lie 30-90 mm from bone.

So after the rounds this module plans the pressures (:func:`pamkin.gait.plan.evaluate_plan`) of the design on
the walking trial **between** its frames (each sample the mid-point of two successive frames: angles and
moments averaged; not the audit's frames, but the same trial: README, "Held out?"). While the feasible
fraction is below the target it ranks, for each actuator whose PAMs (either side) are at the pressure
limit in an infeasible sample, the other diameters and parallel counts within the unit budget by the plan
with that size on the same route (cheap: about 0.3 s a plan), and solves the best few: first on the final
route (points fixed: still clear of bone; resting and tendon length re-solved by the actuator's own
problem, with its strain, rated-force and sensitivity limits, then
:func:`optimize.limit_check.limit_excess` on its 2000 check poses), else, in a run, the whole actuator
again with that size (its first-phase fit, the bone-mesh rounds, the limit check). It keeps the solved
swap that raises the fraction most (ties: the smaller objective) and is no worse on bone
(:func:`bone_ok`), and says what it did and what the fit cost.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
from pamkin.optimize import actuator
from pamkin.optimize.context import RunContext
from pamkin.optimize.limit_check import check_poses, limit_excess, tighten
from pamkin.optimize.results import ActuatorResult, solution_pam

from pamkin.gait import plan as gait
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.robot.design import Design

#: Swap steps at most (each solves up to max(2, workers) of the best-ranked untried swaps).
MAX_STEPS = 3


def midpoint_trial(model):
    """The walking trial between its frames (:class:`pamkin.gait.plan.GaitTrial`), or ``None`` when the
    trial files are not there (the check is then skipped)."""

    if not (gait.DEFAULT_IK.is_file() and gait.DEFAULT_ID.is_file()):
        return None
    t = gait.load_trial(model, grf=gait.DEFAULT_GRF if gait.DEFAULT_GRF.is_file() else None)
    mid = lambda a: 0.5 * (a[1:] + a[:-1])  # noqa: E731
    return dataclasses.replace(t, times=mid(t.times), q=mid(t.q), moments=mid(t.moments))


def plan(design: Design, skeleton, trial):
    """The pressure plan of ``design`` on ``trial`` (:class:`pamkin.gait.plan.GaitPlan`)."""

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gait.evaluate_plan(PamRobot(design, skeleton), trial)


def limited_actuators(p) -> list[int]:
    """Ids of the actuators with a PAM (either side) at the pressure limit in an infeasible sample of
    plan ``p``."""
    bad = np.flatnonzero((np.abs(p.residuals) > p.tolerance * p.peaks).any(axis=1))
    hit = (p.pressures[bad] >= p.p_max_Pa * (1 - 1e-6)).any(axis=0)
    return sorted({pr.id for pr, h in zip(p.pam_results, hit) if h})


def resize(data, cfg, z: np.ndarray, diameter: int, n_parallel: int, model, rom):
    """The actuator of ``data`` on the route of decision vector ``z`` (points fixed) with another
    ``diameter`` / ``n_parallel``: resting and tendon length re-solved within every limit of its
    problem (bone capsules aside: the route was cleared against the meshes), then checked on the
    held-out limit-check poses. Returns ``(Pam, Solution)`` or ``None`` when infeasible."""
    from pamkin.optimize.problem import FEASIBILITY_TOL, ActuatorProblem  # noqa: PLC0415

    npt = len(data.pam.points)
    prob = ActuatorProblem(data, cfg, diameter, [z[3 * i:3 * i + 3] for i in range(npt)], [np.zeros(3)] * npt)
    if np.any(prob.lbx > prob.ubx + 1e-12):      # e.g. a larger PAM no longer leaves room for its left copy
        return None
    prob.lbg = np.where(prob._capsule_rows(), -np.inf, prob.lbg)
    z0 = np.clip(z, prob.lbx, prob.ubx)
    q_check = check_poses(model, rom, data.crossed or [data.pam.primary_coordinate], cfg.seed, data.pam.id)
    for _ in range(2):
        sol = prob.evaluate(prob.solve(z0, n_parallel).z, n_parallel)
        if max(sol.violations.values(), default=0.0) > FEASIBILITY_TOL:
            return None
        sol = prob.finalize(sol)
        pam = solution_pam(data.pam, sol)
        excess = limit_excess(pam, model, q_check, cfg, data.fitting_length)
        if not excess:
            return pam, sol
        tighten(prob, excess)
        z0 = sol.z
    return None


def bone_ok(new: dict, old: dict) -> bool:
    """A changed actuator's bone-mesh result (``ActuatorResult.bone``) is no worse than ``old``: no
    segment deeper in bone than the audit's 2 mm or than before, every point within 0..20 mm of its bone."""
    if not old:
        return True
    if not new:
        return False
    depth = new.get("max_segment_penetration_mm", 0.0)
    points = new.get("point_distance_mm", {}).values()
    return depth <= max(2.0, old.get("max_segment_penetration_mm", 0.0)) + 1e-9 and all(0 <= v <= 20 for v in points)


def _proxies(design: Design, p, ids: list[int], cfg, units: int, budget: int, skeleton, trial) -> list:
    """Ranked swaps ``(fraction, id, (diameter, n_parallel))`` of the limited actuators ``ids``: the plan's
    feasible fraction with the other diameter / count on the same route and resting length (a cheap
    ranking; the swap is then solved within the limits). Only swaps that raise the fraction."""
    frac = p.feasible_frame_fraction
    out = []
    for pid in ids:
        cur = design.pam(pid)
        for d in cfg.first_fit.diameters_mm:
            for n in range(1, cfg.first_fit.max_parallel + 1):
                if (d, n) == (cur.diameter_mm, cur.n_parallel) or units - cur.n_parallel + n > budget:
                    continue
                trial_design = design.replace_pam(dataclasses.replace(cur, diameter_mm=d, n_parallel=n))
                f = plan(trial_design, skeleton, trial).feasible_frame_fraction
                if f > frac + 1e-9:
                    out.append((f, pid, (d, n)))
    # most walking first; then fewer units, then the thinner (lighter) PAM
    return sorted(out, key=lambda o: (-o[0], o[2][1], o[2][0]))


def walking_pass(design: Design, results: list, data: list, cfg, budget: int, skeleton, trial,
                 model, rom, resolve=None) -> tuple[Design, list, list[str]]:
    """Swap diameters / parallel counts of the optimised ``design`` until the walking fraction between
    the trial's frames reaches ``cfg.walking.min_fraction`` (or no swap raises it), within ``budget`` PAM units
    on one side of the whole design (every actuator of ``design`` counts, optimised or not).

    Each step ranks the swaps of the actuators at the pressure limit by the plan with the new size on
    the same route (:func:`_proxies`), and solves the best ``max(2, cfg.workers)`` of them in rank
    order, until one reaches the target: on the fixed route (:func:`resize`), else, when ``resolve`` is
    given, the whole actuator again (fit and bone-mesh rounds; ``resolve(tasks)`` takes
    ``[(index, (diameter, n_parallel), z)]`` and returns their results in order). Of the solved swaps
    the step keeps the one that raises the plan's fraction most (ties: the smaller objective) with a
    bone clearance no worse than before (:func:`bone_ok`).

    Args:
        results / data: The run's actuator results and problem data (same order).

    Returns:
        ``(design, results, lines)``: the (possibly changed) design and results, and what was done.
    """
    results = list(results)
    p = plan(design, skeleton, trial)
    frac = p.feasible_frame_fraction
    target = cfg.walking.min_fraction
    lines = [f"walking check ({len(trial.times)} samples between the trial's frames): {100 * frac:.1f} % "
             f"feasible, target {100 * target:.0f} %"]
    units = sum(q.n_parallel for q in design.pams)
    index = {r.id: i for i, r in enumerate(results)}
    tried: set = set()
    for _ in range(MAX_STEPS):
        if frac >= target:
            break
        ids = [pid for pid in limited_actuators(p) if pid in index and results[index[pid]].success
               and results[index[pid]].z is not None]
        ranked = [o for o in _proxies(design, p, ids, cfg, units, budget, skeleton, trial)
                  if (o[1], o[2]) not in tried][:max(2, cfg.workers)]
        tried.update((o[1], o[2]) for o in ranked)
        best = None
        for _, pid, (d, n) in ranked:       # in rank order; the first swap that reaches the target ends the step
            i = index[pid]
            k = results[i].pam.transmission      # a PAM the one-segment stage put on a block keeps it
            di = data[i] if k == data[i].pam.transmission else \
                dataclasses.replace(data[i], pam=dataclasses.replace(data[i].pam, transmission=k))
            out = resize(di, cfg, results[i].z, d, n, model, rom)
            if out is not None:
                r = _resized(results[i], *out)
            elif resolve is not None:
                r = resolve([(i, (d, n), results[i].z)])[0]
            else:
                continue
            if not (r.success and bone_ok(r.bone, results[i].bone)):
                continue
            new_design = design.replace_pam(r.pam)
            q = plan(new_design, skeleton, trial)
            f = q.feasible_frame_fraction
            obj = _objective(r)
            if f > frac + 1e-9 and (best is None or (f, -obj) > (best[0], -best[1])):
                best = (f, obj, i, r, new_design, q)
            if best is not None and best[0] >= target:
                break
        if best is None:
            what = ", ".join(f"{pid} {d}x{n}" for _, pid, (d, n) in ranked)
            lines.append(f"  no swap of the actuators at the pressure limit ({', '.join(map(str, ids)) or 'none'}) "
                         f"raises it within {2 * budget} units" + (f" (solved: {what})" if what else ""))
            if not ranked:
                break
            continue
        f, obj, i, r, design, p = best
        old = results[i].pam
        how = "on its route" if r.attempts and r.attempts[-1]["start"] == RESIZE_START else "re-solved"
        line = (f"  actuator {r.pam.id} {r.pam.name}: {old.diameter_mm}x{old.n_parallel} -> {r.pam.diameter_mm}x"
                f"{r.pam.n_parallel} {how} (objective {_objective(results[i]):.4g} -> {obj:.4g}): {100 * frac:.1f} % -> "
                f"{100 * f:.1f} %")
        lines.append(line)
        units += r.pam.n_parallel - old.n_parallel
        bone = dict(r.bone, log=list(r.bone.get("log", [])) + [line]) if r.bone else r.bone
        results[i] = dataclasses.replace(r, bone=bone)
        frac = f
    if frac < target:
        lines.append(f"  walking check: {100 * frac:.1f} % feasible, below the target {100 * target:.0f} %")
    return design, results, lines


#: ``start`` of the attempt a fixed-route swap adds to an actuator's attempts.
RESIZE_START = "walking check (route fixed)"


def _objective(r) -> float:
    """The final objective of a swapped result (the saved solution's where the run recorded it, else after its
    bone-mesh rounds where it had them)."""
    if getattr(r, "objective", None) is not None:
        return float(r.objective)
    if not r.attempts:
        return float("inf")
    if r.attempts[-1]["start"] != RESIZE_START and r.bone:
        return float(r.bone.get("objective_after", r.attempts[-1]["objective"]))
    return float(r.attempts[-1]["objective"])


def _resized(r, pam, sol):
    """Result ``r`` with the fixed-route swap ``(pam, sol)`` of :func:`resize`."""
    return dataclasses.replace(
        r, pam=pam, n_parallel=pam.n_parallel, z=sol.z.copy(), status=sol.status, success=sol.success,
        objective=float(sol.objective),
        nrmse_samples=sol.nrmse_samples, torque_samples=sol.torque_samples, violations=sol.violations,
        attempts=r.attempts + [{"diameter_mm": pam.diameter_mm, "n_parallel": pam.n_parallel,
                                "start": RESIZE_START, "status": sol.status, "objective": sol.objective,
                                "feasible": sol.success, "seconds": sol.seconds, "relaxed": []}])


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """The optimised design checked on the walking trial, diameters / counts swapped where it falls short
    (:mod:`optimize.stages.walking`)."""
    seed_design, cfg, stream = ctx.seed_design, ctx.cfg, ctx.stream
    budget = cfg.unit_budget.max_units // 2      # units of a whole side


    skeleton = robot_skeleton()
    trial = midpoint_trial(skeleton)
    report: dict = {"target": cfg.walking.min_fraction}
    if trial is None:
        lines = ["walking check skipped: the walking trial (pamkin.gait.plan.DEFAULT_IK / DEFAULT_ID) is not there"]
    else:
        design = seed_design
        for r in results:
            design = design.replace_pam(r.pam)
        order = {r.id: k for k, r in enumerate(ctx.first.values())}

        def resolve(tasks: list) -> list[ActuatorResult]:
            """The actuators of ``tasks`` solved again with another diameter / count (in the workers)."""
            done = {(r.id, r.pam.diameter_mm, r.pam.n_parallel): r
                    for r in ctx.map(actuator.finish_choice, [(order[results[i].id], key, z) for i, key, z in tasks], "walking")}
            return [done[(results[i].id, *key)] for i, key, _ in tasks]

        before = plan(design, skeleton, trial).feasible_frame_fraction
        after_design, results, lines = walking_pass(design, results, ctx.data, cfg, budget, skeleton, trial,
                                                    ctx.human, ctx.rom, resolve)
        report.update(samples=len(trial.times), fraction_before=round(before, 4),
                      fraction_after=round(plan(after_design, skeleton, trial).feasible_frame_fraction, 4))
    for line in lines:
        print(line, file=stream, flush=True)
    ctx.walking = dict(report, log=lines)
    return results
