"""PAM-ends stage: where every PAM on one straight segment is anchored — the segment its body sits on (the
design's ``pam_on``, where it fits on more than one) and its end (``pam_at``) — chosen to leave the fewest
intersecting PAM pairs at the run's own poses (:func:`optimize.pam_clearance.choose_ends`)."""

from __future__ import annotations

import dataclasses

from pamkin.optimize.context import RunContext
from pamkin.optimize.pam_clearance import choose_ends
from pamkin.optimize.results import ActuatorResult


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """``results`` with every PAM's ``pam_on`` / ``pam_at`` chosen; the report lines in ``ctx.pam_ends``."""
    design = ctx.seed_design
    for r in results:
        design = design.replace_pam(r.pam)
    new, lines = choose_ends(design, ctx.human, ctx.rom, ctx.cfg.seed)
    for line in lines:
        print(line, file=ctx.stream, flush=True)
    ctx.pam_ends = list(lines)
    return [dataclasses.replace(r, pam=new.pam(r.id)) for r in results]
