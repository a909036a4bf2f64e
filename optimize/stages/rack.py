"""Rack stage (``[rack] enabled``): every PAM body hung on brackets along a bone of its route's end, the whole
leg's layout chosen at once (:func:`pamkin.optimize.rack_layout.layout`); routes, moment arms and PAM strains
stay as the earlier stages left them (:mod:`pamkin.robot.rack`). In a run of some actuators only
(``--actuators``), the others stay where the seed design has them, as obstacles."""

from __future__ import annotations

import dataclasses

import numpy as np

from pamkin.audit.measure import GAIT_IK, audit_coordinates, gait_poses, random_poses
from pamkin.optimize.context import RunContext
from pamkin.optimize.rack_layout import layout
from pamkin.optimize.results import ActuatorResult
from pamkin.optimize.samples import boundary_poses, with_dependencies
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
    q = stage_poses(ctx, cfg.poses, RACK_STREAM)
    q_check = stage_poses(ctx, cfg.check_poses, RACK_CHECK_STREAM)
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


def stage_poses(ctx: RunContext, n: int, stream: int) -> np.ndarray:
    """``n`` uniform random poses of the right leg and trunk within the range of motion (``stream``) and ``n // 2``
    more at its edges (each coordinate at its lower limit, its upper limit or uniform, a third each:
    :func:`pamkin.optimize.samples.boundary_poses`), where a body comes nearest the next bone and uniform
    samples rarely go (gluteus maximus's rack of the merged seed's run: 4.2 mm from the pelvis at worst over
    2000 uniform poses, 5.9 mm into it over 2000 such edge poses)."""
    if n < 1:
        return random_poses(ctx.human, ctx.rom, 1, ctx.cfg.seed, stream=stream)[:0]
    q = random_poses(ctx.human, ctx.rom, n, ctx.cfg.seed, stream=stream)
    if n // 2 < 1:
        return q
    rng = np.random.default_rng(np.random.SeedSequence(int(ctx.cfg.seed), spawn_key=(int(stream), 1)))
    coords = audit_coordinates(ctx.rom)
    edge = boundary_poses(ctx.human, ctx.rom, coords, rng, n // 2)
    fixed = [k for k, c in enumerate(ctx.human.coordinates) if c not in with_dependencies(ctx.human, ctx.rom, coords)]
    edge[:, fixed] = ctx.human.default_q[fixed]                  # the others where the uniform poses have them
    return np.vstack([q, edge])


def _turns(design, pam_id: int, ctx: RunContext, q) -> tuple[float, np.ndarray]:
    """The cable's turn [rad] at the rack's guide pulley and at the route's end (per pose of ``q``) of a racked
    PAM (:func:`pamkin.robot.rack.rack_turns`)."""
    pam = design.pam(pam_id)
    robot = PamRobot(Design(design.name, (pam,), design.pressure_Pa, design.force_model, design.fitting_length_m,
                            design.rom), ctx.human, sides=("r",))
    return rack_turns(pam, route_positions(robot.paths, ctx.human.kinematics.forward(q, warn_range=False), 0))
