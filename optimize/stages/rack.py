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
    for i, c in sorted(rep.placed.items()):
        guide, at_end = _turns(new, i, ctx, q_all)
        eta = float(capstan_efficiency(guide + at_end.max(), cfg.friction))
        new = new.replace_pam(dataclasses.replace(new.pam(i), cable_efficiency=eta))
        lines.append(f"rack: actuator {i} {design.pam(i).name} on {c.mount.host} at its {c.mount.end}, bracket "
                     f"{1000 * c.bracket:.1f} mm; cable turns {np.degrees(guide):.0f} deg at the guide and up to "
                     f"{np.degrees(at_end.max()):.0f} deg at the route's end: capstan factor {eta:.3f} at mu = "
                     f"{cfg.friction:g}, in its force (cable_efficiency)")
    for line in lines:
        say(line)
    ctx.rack = lines
    return [dataclasses.replace(r, pam=new.pam(r.id)) if r.id in ids else r for r in results]


def _turns(design, pam_id: int, ctx: RunContext, q) -> tuple[float, np.ndarray]:
    """The cable's turn [rad] at the rack's guide pulley and at the route's end (per pose of ``q``) of a racked
    PAM (:func:`pamkin.robot.rack.rack_turns`)."""
    pam = design.pam(pam_id)
    robot = PamRobot(Design(design.name, (pam,), design.pressure_Pa, design.force_model, design.fitting_length_m,
                            design.rom), ctx.human, sides=("r",))
    return rack_turns(pam, route_positions(robot.paths, ctx.human.kinematics.forward(q, warn_range=False), 0))
