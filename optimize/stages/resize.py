"""Re-sizing stage: an actuator whose fit the bone rounds left poor (objective above ``resize.above``)
gets its other first-phase diameters (same parallel count: the unit budget holds) through the bone rounds and the
one-segment stage too, and one the one-segment stage put on a pulley block whose fit is poor a block throughout
(``resize.block_refit_above``); the better result kept."""

from __future__ import annotations

import dataclasses

from pamkin.optimize import actuator
from pamkin.optimize.config import RunConfig
from pamkin.optimize.context import RunContext
from pamkin.optimize.results import (
    ActuatorResult,
    design_mass,
    result_score,
    size_text,
    unit_mass,
)
from pamkin.optimize.stages.mass import BLOCK_TRY_HEADROOM_KG


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """Choose the diameter again on the fit the bone meshes leave (after :func:`actuator.finish_actuator`).

    The unit budget chooses every diameter on the first phase's fits, made without the bone meshes; the bone
    rounds then raise some fits many times, and not alike for every diameter (sartorius: 20 mm fitted best
    before them, 10 mm after). An actuator whose saved objective is above ``cfg.resize.above`` gets its other
    first-phase candidates with the same parallel count (so the unit budget still holds) through the bone
    rounds and the one-segment stage (:func:`actuator.finish_choice`, in the workers), where the candidate's score
    before the rounds (objective + mass penalty) was below the actuator's score after them; an actuator the
    one-segment stage put on a pulley block gets the block throughout (:func:`block_tasks`). Kept: the result
    clear of bone, then the one on a straight segment where the present one is, then with the lower score
    (objective + mass penalty), the present one on ties. The actuator's bone log gets one line per try."""
    cfg, stream = ctx.cfg, ctx.stream
    first: dict = ctx.first
    chosen: dict = ctx.choice

    tasks = []
    for k, r in enumerate(results):
        if not (r.success and r.objective is not None and r.objective > cfg.resize.above):
            continue
        now = result_score(r, cfg)
        for key, (pre, _, _) in sorted(first[k].candidates.items()):
            if key[1] == r.n_parallel and key[0] != r.pam.diameter_mm and key != chosen.get(k) and pre < now:
                tasks.append((k, key, None))
    seed = ctx.seed_design
    blocks = block_tasks(ctx, results, cfg, design_mass(seed, results) if seed is not None else None)
    if not tasks and not blocks:
        return results
    print(f"resize after the bone rounds: {len(tasks)} other diameter(s) of "
          f"{len({t[0] for t in tasks})} actuator(s) with fit objective > {cfg.resize.above:g}"
          + (f"; {len(blocks)} pulley block(s) throughout for {len({t[0] for t in blocks})} actuator(s) the "
             f"one-segment stage put on one, fit objective > {cfg.resize.block_refit_above:g}" if blocks else ""),
          file=stream, flush=True)
    tasks += blocks
    tried = sorted(ctx.map(actuator.finish_choice, tasks, "resize"),
                   key=lambda a: (a.id, a.attempts[-1]["diameter_mm"], a.attempts[-1].get("transmission", 1)))
    out = list(results)
    held_out = ctx.validation_error_of() if cfg.resize.on == "validation" else None
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
            lines.append(f"{what} -> {size_text(alt.pam)}: {said(alt)}"
                         f"{', not clear of bone' if key[0] else ''}{', not on one straight segment' if key[1] else ''}"
                         f" (now {size_text(r.pam)}: {said(r)})")
            if key < best_key:
                best, best_key = alt, key
        if best is not r:
            t = best.attempts[-1].get("transmission", 1)
            best.attempts[-1]["start"] = actuator.BONE_RESIZE_START + (f" ({t}:1)" if t > 1 else "")
            lines.append(f"  resize: kept the {best.attempts[-1]['diameter_mm']} mm try"
                         f"{f' with the {t}:1 block throughout' if t > 1 else ''}: {size_text(best.pam)} (was {size_text(r.pam)}"
                         f"{', its block from the one-segment stage' if t > 1 and r.pam.transmission > 1 else ''})")
        else:
            lines.append(f"  resize: kept {size_text(r.pam)}")
        for line in lines:
            print(f"actuator {r.id} {r.name}:{line[1:]}", file=stream, flush=True)
        out[k] = dataclasses.replace(best, bone=dict(best.bone, log=list(best.bone.get("log", [])) + lines))
    return out


def block_tasks(ctx: RunContext, results: list[ActuatorResult], cfg: RunConfig, total_mass: float | None = None) -> list[tuple]:
    """:func:`resize_pass`'s tries of pulley blocks throughout: an actuator the one-segment stage put on a
    k:1 block (on the route fitted without it: out of reach or infeasible at 1:1) whose fit objective is
    above ``cfg.resize.block_refit_above`` (and not above ``cfg.resize.above``: those get their other diameters) is
    solved again with its PAM on a block from the first phase on, at the largest ratio of
    :data:`optimize.mount.BLOCKS` (3:1: the most stroke, the least force; same diameter and parallel count),
    so the route's fit and bone rounds see the block's stroke and force. (Both ratios, measured: twice the
    tries, one more kept — gluteus maximus at 2:1, objective 0.864 -> 0.862 — and over the 10-minute run.)
    Not tried where, with the design's mass ``total_mass`` [kg] given, the pulleys it adds would leave less
    than :data:`BLOCK_TRY_HEADROOM_KG` below ``cfg.mass.max_kg`` (:func:`mass_pass` would take it off again).
    Tasks ``(k, (diameter, n), z, ratio)``, ``z`` the
    result's decision vector before the block (the start where the first phase has no fit of that size)."""
    from pamkin.optimize.mount import BLOCKS  # noqa: PLC0415

    if not (cfg.mount.enabled and cfg.mount.blocks and cfg.resize.block_refit_above > 0):
        return []
    tasks = []
    for k, r in enumerate(results):
        if (r.success and r.objective is not None and cfg.resize.block_refit_above < r.objective
                and not (cfg.resize.above > 0 and r.objective > cfg.resize.above)
                and r.direct is not None and r.pam.transmission > 1):
            t = BLOCKS[-1]
            if total_mass is not None and cfg.mass.max_kg > 0 and t > r.pam.transmission:
                # the pulleys it adds (at the present resting length) would leave no headroom
                heavier = unit_mass(dataclasses.replace(r.pam, transmission=t))
                if total_mass + heavier - unit_mass(r.pam) > cfg.mass.max_kg - BLOCK_TRY_HEADROOM_KG:
                    continue
            tasks.append((k, (r.pam.diameter_mm, r.n_parallel), r.direct.z, t))
    return tasks
