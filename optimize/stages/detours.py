"""Detour stage: every same-body route segment that runs into its own bone (but the one its PAM body sits on)
carried round that bone by via points (a constant length, on the tendon: every torque unchanged), then checked
exactly against every bone."""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np
from pamkin.optimize.bone_cuts import BoneCuts, bone_check_poses
from pamkin.optimize.context import RunContext
from pamkin.optimize.results import ActuatorResult

from pamkin.errors import RangeWarning
from pamkin.robot.detour import detour_pam, same_body_segments
from pamkin.robot.pam_body import segment_names


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """Every same-body segment of a result's route (both ends fixed in one body) that runs into its own bone,
    but the one its PAM body sits on, carried round that bone by via points (:func:`pamkin.robot.detour.detour_pam`:
    a constant length, on the tendon; every torque unchanged), then the route checked exactly against every
    bone at its bone-check poses (the result's bone summary is that check's). Progress on ``stream``
    (default: standard error at the call)."""
    cfg, stream = ctx.cfg, ctx.stream


    human, bones = ctx.human, ctx.bones
    out = list(results)
    for k, r in enumerate(results):
        if r.z is None or not r.success or not r.bone:
            continue
        data = ctx.data[k]
        q, n_right = bone_check_poses(human, ctx.rom, data.pam, cfg.seed, crossed=data.crossed)
        pl = ctx.placement(r.pam, q)
        segs = [a for a in same_body_segments(r.pam) if not (pl.on_one_segment and a == pl.segment)]
        if not segs:
            continue
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            state = human.kinematics.forward(q, warn_range=False)
        new, outcome = detour_pam(r.pam, bones, segs, state, list(human.kinematics.frames), n_right)
        if not outcome:
            continue
        names = segment_names(r.pam)
        cuts = BoneCuts(new, human, bones, q, n_right)
        new_names = segment_names(new)         # a rollered segment is measured on its pieces round the roller
        cuts.rollers = {new_names.index(rol.segment): rol for rol in new.rollers}
        loc = np.array([p.location if hasattr(p, "location") else (0.0, 0.0, 0.0) for p in new.points])
        m = cuts.measure(loc)
        what = "; ".join(f"{names[a]}: {v}" for a, v in sorted(outcome.items()))
        line = (f"  detours of actuator {r.id} {r.name}: {what} (tendon +{1e3 * (new.tendon_length_m - r.pam.tendon_length_m):.1f} mm);"
                f" route then {'clear of bone' if m.violation() == 0.0 else f'{1e3 * m.violation():.1f} mm into bone'}"
                f" at its bone-check poses ({time.perf_counter() - t0:.1f} s)")
        print(line.strip(), file=stream, flush=True)
        bone = dict(r.bone, **m.summary([p.name for p in new.points]), clear=bool(m.violation() == 0.0),
                    detours={names[a]: v for a, v in outcome.items()}, log=list(r.bone.get("log", [])) + [line])
        out[k] = dataclasses.replace(r, pam=new, bone=bone)
    return out
