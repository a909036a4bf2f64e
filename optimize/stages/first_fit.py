"""First-fit stage: every selected actuator's fit, in the workers (:func:`optimize.actuator.solve_actuator`).

Per actuator, one CasADi/IPOPT problem per Festo diameter (route points in boxes around the seed's, resting
and tendon length), the best diameter's parallel count raised while it gains, then multistart from perturbed
seeds. With a unit budget (``unit_budget.max_units``) the stage only fits and keeps every feasible size as a
candidate (the unit budget chooses among them); without one, each actuator's bone rounds and one-segment stage
follow at once in the same task.
"""

from __future__ import annotations

from pamkin.optimize import actuator
from pamkin.optimize.context import RunContext
from pamkin.optimize.results import ActuatorResult


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """The first phase of every actuator of ``ctx.data`` (``results`` is not read: this stage starts a run)."""
    cfg, seed = ctx.cfg, ctx.seed_design
    pams = [d.pam for d in ctx.data]
    ctx.fit_only = bool(cfg.unit_budget.max_units)
    order = {p.id: k for k, p in enumerate(pams)}
    others = sum(p.n_parallel for p in seed.pams if p.id not in order)
    # with a unit budget no actuator can get more PAMs than the budget leaves after one for every other
    # actuator: larger counts are not tried (exact: the choice could never take them)
    ctx.n_cap = cfg.unit_budget.max_units // 2 - others - (len(pams) - 1) if cfg.unit_budget.max_units else cfg.first_fit.max_parallel
    # the first phase's time grows with the route's points (measured: correlation 0.87 over the 29 defaults)
    done = ctx.map(actuator.solve_actuator, [(k, 0) for k in range(len(pams))], "first_fit",
                   cost=[len(p.points) for p in pams])
    return sorted(done, key=lambda r: order[r.id])
