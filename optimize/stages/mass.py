"""Mass stage: pulley blocks taken off again, the least score lost per kilogram first, while the robot's
estimated mass (both sides, the audit's) is above ``mass.max_kg``."""

from __future__ import annotations

import dataclasses

from pamkin.optimize import actuator
from pamkin.optimize.context import RunContext
from pamkin.optimize.results import (
    ActuatorResult,
    design_mass,
    result_score,
    size_text,
    unit_mass,
)

#: Headroom [kg] below ``max_mass_kg`` the re-sizing's blocks throughout (:func:`block_tasks`) must leave: a
#: warm re-run from the design re-solves every PAM and its resting lengths drift (measured: +0.33 kg from the
#: 0.1.0-dev default, +0.29 kg from the 0.1.0-dev one, +0.22 kg from one with semimembranosus' try), and it cannot
#: take a warm block off (it has no result without it).
BLOCK_TRY_HEADROOM_KG = 0.5


def is_block_try(r: ActuatorResult) -> bool:
    """Whether ``r`` is a kept try of :func:`block_tasks` (a block throughout from the re-sizing)."""
    return bool(r.attempts) and str(r.attempts[-1].get("start", "")).startswith(actuator.BONE_RESIZE_START + " (")


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """Keep the robot's estimated mass within ``cfg.mass.max_kg`` where the one-segment stage's pulley blocks
    took it above: while it is over, the block whose removal loses the least score (objective + mass penalty)
    per kilogram saved comes off again — the actuator goes back to its result before the block
    (``ActuatorResult.direct``). The mass is the audit's (:func:`pamkin.robot.design.pam_unit_mass`, both sides,
    the seed's PAMs for actuators not optimised). Where no block is left to take off, the run says so.
    First, the re-sizing's blocks throughout go back to the result before them (the same way) while the mass
    is above the budget less :data:`BLOCK_TRY_HEADROOM_KG`."""
    seed, cfg, stream = ctx.seed_design, ctx.cfg, ctx.stream
    mass = unit_mass
    total = design_mass(seed, results)
    out = list(results)
    for budget, only in ((cfg.mass.max_kg - BLOCK_TRY_HEADROOM_KG, is_block_try), (cfg.mass.max_kg, None)):
        what = f"mass budget {cfg.mass.max_kg:g} kg" + \
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
                    f"off again ({size_text(r.pam)} -> {size_text(r.direct.pam)}, -{saved:.2f} kg, objective {r.objective:.4g} -> "
                    f"{r.direct.objective:.4g})")
            print(line, file=stream, flush=True)
            d = r.direct
            out[k] = dataclasses.replace(d, bone=dict(d.bone, log=list(d.bone.get("log", [])) + ["  " + line]),
                                         mount=dict(d.mount, line=d.mount.get("line", "") + "; " + line))
            total -= saved
    return out
