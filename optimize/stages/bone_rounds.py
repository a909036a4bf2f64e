"""Bone-rounds stage (with a unit budget): the size the unit budget chose for every actuator, from its first-phase
fit, through the bone-mesh rounds and the one-segment stage, in the workers
(:func:`optimize.actuator.finish_actuator`).

The rounds keep every attachment point 3..18 mm outside its bone and every route segment clear of the real bone
meshes at random, range-boundary, sweep and gait poses (:mod:`optimize.bone_cuts`, re-linearised each round),
re-check the strain and force limits on 2000 more poses (:mod:`optimize.limit_check`), then put the PAM on one
straight segment of its fixed route where its fit allows, or on a pulley block (:mod:`optimize.mount`).
"""

from __future__ import annotations

from pamkin.optimize import actuator
from pamkin.optimize.context import RunContext
from pamkin.optimize.results import ActuatorResult


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """Every actuator's chosen size (``ctx.choice``) finished from its first-phase result (``results``)."""
    order = {r.id: k for k, r in enumerate(results)}
    # the bone rounds' time follows the first phase's (simulated on the default run: 268 -> 263 s, ideal 262)
    done = ctx.map(actuator.finish_actuator, list(range(len(results))), "bone_rounds",
                   cost=[r.seconds for r in results])
    return sorted(done, key=lambda r: order[r.id])
