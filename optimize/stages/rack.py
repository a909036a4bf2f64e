"""Rack stage (``[rack] enabled``): every PAM body hung on brackets along a bone of its route's end, the whole
leg's layout chosen at once (:func:`pamkin.optimize.rack_layout.layout`); routes, moment arms and PAM strains
stay as the earlier stages left them (:mod:`pamkin.robot.rack`). In a run of some actuators only
(``--actuators``), the others stay where the seed design has them, as obstacles."""

from __future__ import annotations

import dataclasses

import numpy as np

from pamkin.audit.measure import GAIT_IK, gait_poses, random_poses
from pamkin.optimize.context import RunContext
from pamkin.optimize.rack_layout import layout
from pamkin.optimize.results import ActuatorResult
from pamkin.robot.biped import PamRobot
from pamkin.robot.design import Design
from pamkin.robot.pam_body import route_positions
from pamkin.robot.rack import capstan_efficiency, rack_turns

#: Random stream of the stage's poses (never the audit's).
RACK_STREAM = 0xA0D8
#: Random stream of the poses the chosen racks are checked at again (never the audit's).
RACK_CHECK_STREAM = 0xA0D9


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """``results`` with the racked routes; the report lines in ``ctx.rack``."""
    cfg = ctx.cfg.rack
    design = ctx.seed_design
    for r in results:
        design = design.replace_pam(r.pam)
    q = random_poses(ctx.human, ctx.rom, cfg.poses, ctx.cfg.seed, stream=RACK_STREAM)
    q_check = random_poses(ctx.human, ctx.rom, cfg.check_poses, ctx.cfg.seed, stream=RACK_CHECK_STREAM)
    qg = gait_poses(ctx.human, GAIT_IK, stride=cfg.gait_stride)[0] if cfg.gait else q[:0]

    def say(line: str) -> None:
        print(line, file=ctx.stream, flush=True)
    ids = {r.id for r in results}
    new, rep = layout(design, ctx.human, ctx.bones, q, qg, gap=cfg.gap_m, bracket_max=cfg.bracket_max_m,
                      angles=cfg.angles, time_limit=cfg.time_limit_s, movable=ids, q_check=q_check, say=say)
    lines = [f"rack: {len(rep.placed)} of {len(ids)} PAMs hung on racks ({rep.candidates} candidates, "
             f"{rep.conflicts} conflicting pairs, {rep.rounds} rounds); left on their routes: "
             + (", ".join(f"{i} {design.pam(i).name}" for i in rep.unplaced) or "none")]
    lines += [f"rack: actuator {i} {design.pam(i).name} left on its route: {rep.reasons[i]}" for i in rep.unplaced]
    q_all = np.vstack([q, qg]) if len(qg) else q
    lines += [_placed_line(new, i, c, ctx, q_all, cfg.friction) for i, c in sorted(rep.placed.items())]
    for line in lines:
        say(line)
    ctx.rack = lines
    return [dataclasses.replace(r, pam=new.pam(r.id)) if r.id in ids else r for r in results]


def _placed_line(design, pam_id: int, c, ctx: RunContext, q, mu: float) -> str:
    """The report line of a racked PAM: host, end, bracket, the cable's turns over the poses ``q`` and the
    capstan factor at coefficient ``mu`` at the largest of them."""
    pam = design.pam(pam_id)
    robot = PamRobot(Design(design.name, (pam,), design.pressure_Pa, design.force_model, design.fitting_length_m,
                            design.rom), ctx.human, sides=("r",))
    guide, at_end = rack_turns(pam, route_positions(robot.paths, ctx.human.kinematics.forward(q, warn_range=False), 0))
    worst = guide + float(at_end.max())
    return (f"rack: actuator {pam_id} {pam.name} on {c.mount.host} at its {c.mount.end}, bracket "
            f"{1000 * c.bracket:.1f} mm; cable turns {np.degrees(guide):.0f} deg at the guide and up to "
            f"{np.degrees(at_end.max()):.0f} deg at the route's end: capstan factor "
            f"{float(capstan_efficiency(worst, mu)):.3f} at mu = {mu:g} (not in the torque figures)")
