"""Roller stage (``rollers.enabled``, off by default): actuators failing an audit fit limit on the validation
poses get rollers (cable guides on bone) where their fit without the bone rows goes into bone, kept where they
lower the validation error and the route is clear (:func:`optimize.actuator.roller_actuator`)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from pamkin.optimize import actuator
from pamkin.optimize.context import RunContext, fit_limits
from pamkin.optimize.results import ActuatorResult

from pamkin.errors import DataFileError


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """The roller stage (:mod:`optimize.rollers`) for every actuator whose result fails the audit's fit limits
    (primary NRMSE or worst coordinate error) on the run's validation poses; progress on ``stream`` (default:
    standard error at the call). In a warm re-run, an actuator whose warm start's run tried it and kept it
    without rollers is not tried again (:func:`warm_roller_outcomes`): the stage's cost is then that of the
    actuators it gave rollers."""
    cfg, stream = ctx.cfg, ctx.stream
    lim_n, lim_w = fit_limits()
    todo = []
    for k, r in enumerate(results):
        if r.z is None or not r.success:
            continue
        nr, w = ctx.validation_errors(r.pam, k)
        if nr > lim_n or w > lim_w:
            todo.append(k)
    warm = warm_roller_outcomes(Path(cfg.warm_start)) if cfg.warm_start else {}
    again = [k for k in todo if results[k].id in ctx.warm_ids and
             warm.get(results[k].id, "kept") != "kept"]
    if again:
        print("rollers: not tried again (the warm start's run tried them without a gain): " +
              ", ".join(f"{results[k].id} {results[k].name}" for k in again), file=stream, flush=True)
        todo = [k for k in todo if k not in again]
        results = [dataclasses.replace(r, bone=dict(                 # carried on, for a warm re-run from this one
            r.bone or {}, roller_stage=warm[r.id], log=list((r.bone or {}).get("log", [])) + [
                f"  roller stage of actuator {r.id} {r.name}: not tried again: the warm start's run kept it "
                f"{warm[r.id]}"])) if k in again else r for k, r in enumerate(results)]
    if not todo:
        return results
    print(f"rollers: {len(todo)} actuators fail a fit limit on the validation poses: trying rollers", file=stream,
          flush=True)
    ctx.first = {k: results[k] for k in todo}
    out = list(results)
    for r in ctx.map(actuator.roller_actuator, todo, "rollers"):
        out[next(k for k in todo if results[k].id == r.id)] = r
    return out


def warm_roller_outcomes(run_dir: Path) -> dict[int, str]:
    """What the roller stage of the run in ``run_dir`` did with each actuator it tried (its ``summary.json``):
    ``"kept"`` or ``"without rollers: <why>"``, by actuator id; empty where that run had no roller stage or
    wrote no summary. A warm re-run's roller stage does not try again the actuators its warm start's run tried
    without a gain (their warm routes are that run's results)."""
    path = run_dir / "summary.json"
    if not path.is_file():
        return {}
    try:
        bone = json.loads(path.read_text()).get("bone_mesh") or {}
        return {int(k): str(v["roller_stage"]) for k, v in bone.items() if "roller_stage" in v}
    except (ValueError, AttributeError, TypeError) as e:
        raise DataFileError(str(path), f"not a pamkin optimize summary ({e})") from None
