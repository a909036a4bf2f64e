"""PAM-PAM clearance stage (``clearance.enabled``, off by default): every actuator whose route comes nearer
another PAM's body than their radii is solved again with the other bodies as obstacles."""

from __future__ import annotations

import numpy as np
from pamkin.optimize import actuator
from pamkin.optimize.bone_cuts import BoneCuts, bone_check_poses
from pamkin.optimize.context import RunContext
from pamkin.optimize.pam_clearance import pam_bodies
from pamkin.optimize.results import ActuatorResult, first_locations


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """Second pass: every actuator whose route comes nearer another PAM's body than their radii (at its
    bone-check poses, first-pass design) is solved again with the other bodies as obstacles."""
    seed, cfg, stream = ctx.seed_design, ctx.cfg, ctx.stream

    design = seed
    for r in results:
        design = design.replace_pam(r.pam)
    human, rom = ctx.human, ctx.rom
    index = {p.id: k for k, p in enumerate(design.pams)}
    todo, obstacles = [], {}
    for k, r in enumerate(results):
        if r.z is None or not r.success:
            continue
        data = ctx.data[k]
        q, n_right = bone_check_poses(human, rom, data.pam, cfg.seed, crossed=data.crossed)
        bodies = pam_bodies(design, human, q)
        mine = bodies[index[r.id]]
        others = [b for b in bodies if b.id != r.id]
        cuts = BoneCuts(data.pam, human, ctx.bones, q, n_right)
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
    ctx.first, ctx.obstacles = {k: results[k] for k in todo}, obstacles
    out = list(results)
    for r in ctx.map(actuator.clear_actuator, todo, "clearance"):
        out[next(k for k in todo if results[k].id == r.id)] = r
    return out
