"""Unit-budget stage: every actuator's Festo diameter and parallel count chosen together, for the least summed
score (fit objective + mass penalty) within ``unit_budget.max_units`` PAM units (both sides), by dynamic programming
over the first phase's feasible candidates."""

from __future__ import annotations

from pamkin.optimize.context import RunContext
from pamkin.optimize.results import ActuatorResult, InfeasibleError


def choose_units(results: list[ActuatorResult], budget: int) -> tuple[list, float]:
    """Diameter and parallel count of every actuator for the least summed score with at most ``budget``
    PAM units on one side (exact, by dynamic programming over the first phase's feasible candidates).

    Returns:
        ``(choice, total score)``: per result its ``(diameter, n_parallel)`` (None where it has no
        feasible candidate: it keeps its failed solution, counted with its parallel count).

    Raises:
        InfeasibleError: when even the smallest counts exceed the budget.
    """
    fixed = sum(r.n_parallel for r in results if not r.candidates)
    options = [sorted(((sc, key) for key, (sc, _, _) in r.candidates.items()), key=lambda o: o[1][1])
               for r in results if r.candidates]
    cap = budget - fixed
    need = sum(min(key[1] for _, key in opts) for opts in options)
    if need > cap:
        raise InfeasibleError(f"unit_budget.max_units: the actuators' feasible diameter / parallel-count choices need "
                              f"at least {need + fixed} PAM units per side, the budget allows {budget}")
    INF = float("inf")
    table = [0.0] * (cap + 1)           # table[u]: least score of the actuators so far using <= u units
    picks: list[list] = []
    for opts in options:
        new, pick = [INF] * (cap + 1), [None] * (cap + 1)
        for u in range(cap + 1):
            for sc, key in opts:
                if key[1] <= u and table[u - key[1]] + sc < new[u]:
                    new[u], pick[u] = table[u - key[1]] + sc, key
        table = new
        picks.append(pick)
    u, chosen = cap, []
    for opts, pick in zip(reversed(options), reversed(picks)):
        key = pick[u]
        chosen.append(key)
        u -= key[1]
    chosen.reverse()
    it = iter(chosen)
    return [next(it) if r.candidates else None for r in results], float(table[cap])


def run(ctx: RunContext, results: list[ActuatorResult]) -> list[ActuatorResult]:
    """Choose the sizes (``ctx.choice``) from the first phase's ``results`` (kept as ``ctx.first``); the results
    pass on unchanged (the bone-rounds stage solves the choice)."""
    cfg, seed = ctx.cfg, ctx.seed_design
    ids = {r.id for r in results}
    others = sum(p.n_parallel for p in seed.pams if p.id not in ids)
    free = sum(r.n_parallel for r in results)
    choice, total = choose_units(results, cfg.unit_budget.max_units // 2 - others)
    units = sum(key[1] if key else r.n_parallel for key, r in zip(choice, results))
    changed = [f"{r.id} {r.name} {r.pam.diameter_mm}x{r.n_parallel} -> {key[0]}x{key[1]}"
               for r, key in zip(results, choice) if key and key != (r.pam.diameter_mm, r.n_parallel)]
    print(f"unit budget {cfg.unit_budget.max_units} (both sides): each actuator's own best needs {2 * (free + others)}; "
          f"chosen {2 * (units + others)} (summed score {total:.4g})" + (": " + "; ".join(changed) if changed else ""),
          file=ctx.stream, flush=True)
    ctx.fit_only, ctx.first, ctx.choice = False, dict(enumerate(results)), dict(enumerate(choice))
    return results
