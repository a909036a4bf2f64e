"""Separate stage (``[separate] enabled``, off by default): the ends of each PAM's mount segment moved on their
brackets until same-side PAM bodies are ``gap_m`` apart and ``bone_gap_m`` from bone at poses of the run's own
random stream (:func:`pamkin.optimize.separation.separate`)."""

from __future__ import annotations

import dataclasses

from pamkin.audit.measure import random_poses
from pamkin.optimize.context import RunContext
from pamkin.optimize.results import ActuatorResult
from pamkin.optimize.separation import separate

#: Random stream of the stage's poses (never the audit's).
SEPARATE_STREAM = 0xA0D7


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """``results`` with the separated routes; the report lines in ``ctx.separation``."""
    cfg = ctx.cfg.separate
    design = ctx.seed_design
    for r in results:
        design = design.replace_pam(r.pam)
    q = random_poses(ctx.human, ctx.rom, cfg.poses, ctx.cfg.seed, stream=SEPARATE_STREAM)
    new, rep = separate(design, ctx.human, q, ctx.bones, gap=cfg.gap_m, bone_gap=cfg.bone_gap_m,
                        max_bracket=cfg.max_bracket_m, max_shift=cfg.max_shift_m, rounds=cfg.rounds)
    lines = [f"separate: {len(rep.moved)} PAMs moved in {rep.rounds} rounds at {cfg.poses} poses; body pairs closer "
             f"than {1000 * cfg.gap_m:g} mm {rep.pairs_before} -> {rep.pairs_after}, bodies closer than "
             f"{1000 * cfg.bone_gap_m:g} mm to bone {rep.bone_before} -> {rep.bone_after}"]
    lines += [f"separate: actuator {i} {design.pam(i).name}: points moved up to {1000 * m['displacement_m']:.1f} mm, "
              f"moment arm about {design.pam(i).primary_coordinate} changed up to {1000 * m['moment_arm_change_m']:.1f} mm"
              for i, m in rep.moved.items()]
    for line in lines:
        print(line, file=ctx.stream, flush=True)
    ctx.separation = lines
    return [dataclasses.replace(r, pam=new.pam(r.id)) for r in results]
