"""The run's report lines: what the stages did, per actuator, for the log and standard error."""

from __future__ import annotations

import dataclasses

from pamkin.optimize.config import RunConfig
from pamkin.optimize.context import RunContext, fit_limits
from pamkin.optimize.results import ActuatorResult, far_points, size_text, solution_pam

from pamkin.robot.design import Pam


def mount_lines(results: list[ActuatorResult], cfg: RunConfig) -> list[str]:
    """The one-segment stage's outcome (:mod:`optimize.mount`): how many PAMs sit on one straight segment,
    then one line per PAM that does not, naming why with its numbers."""
    done = [r for r in results if r.mount]
    if not done:
        return []
    on = [r for r in done if r.mount["mounted"]]
    out = [f"one straight segment: {len(on)} of {len(done)} PAMs (resting and tendon length re-solved on the "
           f"fixed route; mount_cost {cfg.mount.cost:g})"]
    out += [f"one straight segment: actuator {r.id} {r.name} ({r.mount['reason']}): {r.mount['line']}"
            for r in done if not r.mount["mounted"]]
    return out


#: The run names actuators whose fit objective the bone-mesh rounds raise by more than this factor.
FIT_COST_FACTOR = 3.0


def fit_cost_lines(results: list[ActuatorResult]) -> list[str]:
    """One line per actuator whose fit the bone-mesh rounds made much worse (objective × > FIT_COST_FACTOR
    and above 0.01, about NRMSE 0.1): the price of keeping the route on and clear of the bones."""
    out = []
    for r in results:
        b = r.bone or {}
        j0, j1 = b.get("objective_before"), b.get("objective_after")
        if j0 is None or j1 is None or j1 <= 0.01 or j1 <= FIT_COST_FACTOR * max(j0, 1e-12):
            continue
        far = far_points(b.get("before", {}))
        why = ("; its fitted route had points " + ", ".join(far) + " from bone") if far else ""
        out.append(f"actuator {r.id} {r.name}: keeping the route on and clear of bone raised the fit objective "
                   f"{j0:.3g} -> {j1:.3g} (x{j1 / max(j0, 1e-12):.0f}){why}")
    return out


def bone_limit_lines(ctx: RunContext, results: list[ActuatorResult]) -> list[str]:
    """One line per finished actuator that fails an audit fit limit on the validation poses (primary NRMSE
    or worst error about a crossed coordinate, :mod:`optimize.validation`): its errors on and clear of bone,
    beside those of its first-phase fit of the size the unit budget chose (route points anywhere in their
    boxes, no bone meshes), and where this result's bone rounds started (its points over 20 mm from bone,
    its deepest segment into bone). Where that fit passes both limits the bone limits cost the pass — the PAM is
    out of reach of the audit's fit limits within them, by name with its numbers; where it fails too, the
    route's shape does. Left out: actuators without a bone stage, a failed first phase or a warm start that held
    (its first phase is the warm route, already on its bones)."""
    first = ctx.first
    if not first or ctx.validation is None:
        return []
    lim_n, lim_w = fit_limits()
    out = []
    for k, r in enumerate(results):
        f = first.get(k)
        if not (r.success and r.bone) or f is None or f.id != r.id or f.warm or not f.success:
            continue
        n1, w1 = ctx.validation_errors(r.pam, k)
        if n1 <= lim_n and w1 <= lim_w:
            continue
        ref = chosen_first_pam(ctx, k)
        n0, w0 = ctx.validation_errors(ref, k)
        before = r.bone.get("before", {})
        far = far_points(before)
        depth = float(before.get("max_segment_penetration_mm", 0.0))
        start = ", ".join(x for x in (("points " + ", ".join(far) + " from bone") if far else "",
                                      f"a segment {depth:.1f} mm into bone" if depth > 2 else "") if x)
        verdict = ("out of reach within the bone limits: without them it passes both"
                   if n0 <= lim_n and w0 <= lim_w else
                   "fails without the bone meshes too: the route's shape and the PAM's force-length curve")
        out.append(f"actuator {r.id} {r.name}: validation NRMSE / worst {n1:.3f} / {w1:.3f} ({size_text(r.pam)}, on "
                   f"and clear of bone; audit limits {lim_n:g} / {lim_w:g}); its fit without the bone "
                   f"meshes ({size_text(ref)}) {n0:.3f} / {w0:.3f}: {verdict}"
                   + (f" (the bone rounds started from {start})" if start else ""))
    return out


def chosen_first_pam(ctx: RunContext, k: int) -> Pam:
    """Actuator ``k``'s first-phase fit (no bone meshes) of the diameter and count the unit budget chose
    (``ctx.choice``), as a PAM; its own best fit where that is the choice or was not kept."""
    f: ActuatorResult = ctx.first[k]
    key = ctx.choice.get(k)
    if not key or key == (f.pam.diameter_mm, f.n_parallel) or key not in f.candidates \
            or f.candidates[key][1] is None:
        return f.pam
    new = solution_pam(dataclasses.replace(ctx.data[k].pam, transmission=f.pam.transmission),
                       f.candidates[key][1])
    return dataclasses.replace(new, tendon_length_m=max(new.tendon_length_m, 0.0))


def check_progress(stream):
    def report(done: int, total: int, aid: int, name: str) -> None:
        bar = "#" * int(30 * done / total)
        print(f"check [{bar:30s}] {done:2d}/{total}  {aid:2d} {name}", file=stream, flush=True)
    return report
