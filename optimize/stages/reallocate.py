"""Unit-reallocation stage: a PAM unit of an actuator with several that fails both audit fit limits on the
validation poses moves to a failing actuator nearest to passing that then passes both; the unit budget holds."""

from __future__ import annotations

import dataclasses

from pamkin.optimize import actuator
from pamkin.optimize.context import PASS_MARGIN, RunContext, fit_limits
from pamkin.optimize.results import ActuatorResult, design_mass

#: The unit reallocation (:func:`reallocate_pass`) tries at most this many receivers (one solve each, in the
#: workers: about one actuator's bone rounds of wall time on 2 cores) ...
REALLOCATE_TRIES = 2


#: ... among the actuators failing an audit fit limit whose errors are at most this many times the limits
#: (validation NRMSE / 0.15 and worst error / 0.25, the larger): near passing, where one more unit can decide.
REALLOCATE_NEAR = 1.5


#: ``start`` of a reallocated actuator's new attempt.
REALLOCATE_START = "unit reallocation (from the solved route)"


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """Move PAM units to where they make a PAM pass (after :func:`resize_pass`).

    The unit budget is spent on the first phase's fits, made without the bone meshes; after the bone rounds an
    actuator with several units may fail both of the audit's fit limits (primary NRMSE and worst error about a
    crossed coordinate, on the optimiser's own validation poses, :mod:`optimize.validation`) while one with a
    single unit narrowly fails one. Donors: results with ``n_parallel >= 2`` failing both limits (a warm start
    that held is not one: its run had the same chance). Receivers: the other results failing a limit, within
    :data:`REALLOCATE_NEAR` of the limits, nearest first, at most :data:`REALLOCATE_TRIES` per donor unit, each
    re-solved with one more unit from its solved route (bone rounds and one-segment stage, in the workers),
    the donor with one fewer; the receivers that pass take the units, the most audit limits newly passed
    first, then the smallest error. A move is kept where the receiver then passes both limits within
    :data:`PASS_MARGIN`, the donor's re-solve succeeds, both are clear of bone and on one straight segment
    where they were, and the robot's estimated mass stays within ``cfg.mass.max_kg``: the unit count does
    not change. Only direct (1:1) results take part. Each moved actuator's bone log says so."""
    cfg, stream = ctx.cfg, ctx.stream
    lim_n, lim_w = fit_limits()
    seed = ctx.seed_design

    def errors(r: ActuatorResult, k: int) -> tuple[float, float]:
        return ctx.validation_errors(r.pam, k)

    def direct(r: ActuatorResult, k: int) -> bool:
        return (r.success and r.z is not None and r.objective is not None
                and r.pam.transmission == ctx.data[k].pam.transmission == 1)

    err = {k: errors(r, k) for k, r in enumerate(results) if direct(r, k)}
    donors = [k for k, (nr, w) in err.items() if results[k].n_parallel >= 2 and nr > lim_n and w > lim_w
              and not ctx.first[k].warm]
    near = sorted((max(nr / lim_n, w / lim_w), k) for k, (nr, w) in err.items()
                  if (nr > lim_n or w > lim_w) and k not in donors
                  and results[k].n_parallel < min(cfg.first_fit.max_parallel, ctx.n_cap))
    receivers = [k for ratio, k in near if ratio <= REALLOCATE_NEAR][:REALLOCATE_TRIES * len(donors)]
    if not donors or not receivers:
        return results

    def task(k: int, dn: int) -> tuple:
        # the donor keeps its straight segment (its fit fails either way); a receiver's fit decides where
        # the one-segment stage puts it (measured: peroneus tertius at 10 mm x2 with its segment's rows
        # 0.155, put on one afterwards 0.105)
        r = results[k]
        return (k, (r.pam.diameter_mm, r.n_parallel + dn), r.z, 1, REALLOCATE_START, dn < 0)

    def size(k: int, dn: int = 0) -> str:
        return f"{results[k].pam.diameter_mm} mm x{results[k].n_parallel + dn}"

    print("unit reallocation: " + ", ".join(f"{results[k].id} {results[k].name} ({size(k)}, validation "
                                             f"{err[k][0]:.3f}/{err[k][1]:.3f})" for k in donors)
          + " fail both fit limits; tried with one unit more: " + ", ".join(
              f"{results[k].id} {results[k].name} ({size(k)}, {err[k][0]:.3f}/{err[k][1]:.3f})" for k in receivers),
          file=stream, flush=True)
    tasks = [task(k, -1) for k in donors] + [task(k, +1) for k in receivers]
    done = {(a.id, a.n_parallel): a for a in ctx.map(actuator.finish_choice, tasks, "reallocate")}
    out = list(results)
    lines: dict[int, list[str]] = {}

    def failed(a: ActuatorResult | None, k: int) -> str:
        """Why the re-solve ``a`` of actuator ``k`` cannot be kept ('' where it can)."""
        if a is None:
            return "not solved"
        if not a.success:
            return a.status
        if not a.bone.get("clear", True):
            return "not clear of bone"
        return "leaves its straight segment" if results[k].mount.get("mounted") and not a.mount.get("mounted") else ""

    free = [k for k in donors if not failed(done.get((results[k].id, results[k].n_parallel - 1)), k)]
    for k in donors:
        if k not in free:
            why = failed(done.get((results[k].id, results[k].n_parallel - 1)), k)
            lines.setdefault(k, []).append(f"  unit reallocation: {size(k, -1)} not kept ({why})")
    passing = []
    for k in receivers:
        a = done.get((results[k].id, results[k].n_parallel + 1))
        if failed(a, k):
            lines.setdefault(k, []).append(f"  unit reallocation: {size(k, +1)}: {failed(a, k)} (not kept)")
            continue
        nr, w = errors(a, k)
        said = f"  unit reallocation: {size(k, +1)}: validation {nr:.3f}/{w:.3f} (was {err[k][0]:.3f}/{err[k][1]:.3f})"
        if nr > lim_n - PASS_MARGIN or w > lim_w - PASS_MARGIN:
            lines.setdefault(k, []).append(f"{said}: not kept (not within both limits less {PASS_MARGIN:g})")
            continue
        gained = (err[k][0] > lim_n) + (err[k][1] > lim_w)         # audit fit limits it newly passes
        passing.append((-gained, max(nr / lim_n, w / lim_w), k, a, said))
    for _, _, k, a, said in sorted(passing, key=lambda t: t[:3]):
        r = results[k]
        if not free:
            lines.setdefault(k, []).append(f"{said}: not kept (no donor unit left)")
            continue
        j = free[0]
        trial = list(out)
        trial[k], trial[j] = a, done[(results[j].id, results[j].n_parallel - 1)]
        mass = design_mass(seed, trial)
        if cfg.mass.max_kg > 0 and mass > cfg.mass.max_kg:
            lines.setdefault(k, []).append(f"{said}: not kept (mass {mass:.2f} kg > {cfg.mass.max_kg:g})")
            continue
        free.pop(0)
        out = trial
        lines.setdefault(k, []).append(f"{said}: kept, its unit from {results[j].id} {results[j].name}")
        nr_j, w_j = errors(out[j], j)
        lines.setdefault(j, []).append(f"  unit reallocation: {size(j, -1)} (a unit to {r.id} {r.name}): validation "
                                       f"{nr_j:.3f}/{w_j:.3f} (was {err[j][0]:.3f}/{err[j][1]:.3f})")
    for k in free:
        lines.setdefault(k, []).append(f"  unit reallocation: kept {size(k)} (no receiver passed with its unit)")
    for k, said in lines.items():
        for line in said:
            print(f"actuator {out[k].id} {out[k].name}:{line[1:]}", file=stream, flush=True)
        out[k] = dataclasses.replace(out[k], bone=dict(out[k].bone, log=list(out[k].bone.get("log", [])) + said))
    return out
