"""What an actuator's solve returns and the pure helpers on it: the saved PAM of a solution,
its score, mass and one-line summaries. No run state: everything here is a function of its arguments."""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np
from pamkin.optimize.config import RunConfig
from pamkin.optimize.samples import is_free

from pamkin.errors import PamkinError
from pamkin.opensim.functions import (
    Constant,
    LinearFunction,
    MultiplierFunction,
    PolynomialFunction,
    SimmSpline,
)
from pamkin.opensim.model_file import MovingPathPoint
from pamkin.robot.design import Design, Pam, pams_mass


class InfeasibleError(PamkinError):
    """An actuator's problem has no feasible point; the message names the violated constraints."""


#: IPOPT statuses of a solve stopped by a cap rather than by what it found.
CAPPED_STATUSES = frozenset({"Maximum_CpuTime_Exceeded", "Maximum_Iterations_Exceeded"})


@dataclass
class ActuatorResult:
    """Best solution of one actuator and every attempt's outcome."""

    id: int
    name: str
    pam: Pam
    status: str
    success: bool
    attempts: list[dict] = field(default_factory=list)
    nrmse_samples: dict[str, float] = field(default_factory=dict)
    torque_samples: dict[str, np.ndarray] = field(default_factory=dict)
    sample_q: dict[str, np.ndarray] = field(default_factory=dict)
    violations: dict[str, float] = field(default_factory=dict)
    seconds: float = 0.0
    relaxed: list[str] = field(default_factory=list)     # constraint groups this actuator could not meet
    bone: dict = field(default_factory=dict)             # bone-mesh stage: exact clearance and rounds
    z: np.ndarray | None = None                          # the solution's decision vector
    n_parallel: int = 1
    # (fit-only first phase of a run with a unit budget) {(diameter, n_parallel): (score, Solution, relaxed)}
    candidates: dict = field(default_factory=dict, repr=False)
    mount: dict = field(default_factory=dict)            # one-segment stage (optimize.mount)
    skipped: list[str] = field(default_factory=list)     # diameter / count tries left out as dominated
    objective: float | None = None                       # the saved solution's fit objective (NRMSE²-like)
    direct: "ActuatorResult | None" = field(default=None, repr=False)   # before the one-segment stage's block
    warm: bool = False                                   # the first phase kept the warm start (its size stays)


def solution_pam(pam: Pam, best) -> Pam:
    """The seed PAM with a (finalised) solution's route, sizes, diameter and parallel count (moving
    points shifted by their offsets)."""
    new_points = []
    for pt, loc in zip(pam.points, best.points):
        if is_free(pt):
            new_points.append(type(pt)(pt.name, pt.body, tuple(float(v) for v in loc)))
        else:
            new_points.append(shift_moving_point(pt, loc))
    return Pam(pam.id, pam.name, pam.human_muscles, pam.primary_coordinate, pam.secondary_coordinates,
               best.diameter_mm, best.n_parallel, best.rest_length, best.tendon_length, tuple(new_points),
               pam.notes, pam.transmission)


def shift_function(fn, delta: float):
    """``fn`` + delta, in the same function class (exactly)."""

    if delta == 0.0:
        return fn
    if isinstance(fn, Constant):
        return Constant(fn.c + delta)
    if isinstance(fn, LinearFunction):
        return LinearFunction(fn.slope, fn.intercept + delta)
    if isinstance(fn, SimmSpline):
        return SimmSpline(fn.x, tuple(y + delta for y in fn.y))
    if isinstance(fn, PolynomialFunction):
        return PolynomialFunction(fn.coefficients[:-1] + (fn.coefficients[-1] + delta,))
    if isinstance(fn, MultiplierFunction) and fn.scale != 0:
        return MultiplierFunction(shift_function(fn.function, delta / fn.scale), fn.scale)
    raise TypeError(f"cannot shift {fn!r}")


def shift_moving_point(pt, offset):
    """A moving point whose path is translated by ``offset`` (3,) [m] in its body frame."""

    fns = tuple(shift_function(f, float(d)) for f, d in zip(pt.functions, offset))
    return MovingPathPoint(pt.name, pt.body, fns, pt.coordinates)


def first_locations(r: ActuatorResult, data) -> list[np.ndarray]:
    """Decision-variable locations (fixed points) / offsets (moving points) of a solved actuator."""
    return [r.z[3 * i:3 * i + 3] for i in range(len(data.pam.points))]


def make_result(pam: Pam, data, prob, best, attempts: list, t0: float, bone: dict, mount: dict | None = None) -> ActuatorResult:
    """The saved form of an actuator's best solution (tendon clipped at 0, moving points shifted)."""
    best = prob.finalize(best)
    if prob.k != pam.transmission:        # the one-segment stage put the PAM on a pulley block
        pam = dataclasses.replace(pam, transmission=prob.k)
    new = solution_pam(pam, best)
    sample_q = {label: data.q[rows] for _, rows, _, _, label in data.objective}
    return ActuatorResult(pam.id, pam.name, new, best.status, best.success, attempts, best.nrmse_samples,
                          best.torque_samples, sample_q, best.violations, time.perf_counter() - t0,
                          sorted(prob.relax), bone, best.z.copy(), best.n_parallel, mount=mount or {},
                          objective=float(best.objective))


def attempt_entry(key: tuple, start: str, sol, relax, transmission: int = 1) -> dict:
    """An attempts entry of :func:`finish_choice` (the diameter / count ``key`` from ``start``)."""
    out = {"diameter_mm": key[0], "n_parallel": key[1], "start": start, "status": sol.status,
           "objective": sol.objective, "feasible": bool(sol.success), "seconds": 0.0, "relaxed": sorted(relax)}
    if transmission != 1:
        out["transmission"] = int(transmission)
    return out


def bone_info(cuts, before, measure, info, lines, names) -> dict:
    return {"rounds": info, "before": cuts.measure(np.array(before.points)).summary(names),
            **measure.summary(names), "clear": bool(measure.violation() == 0.0), "log": lines}


def result_score(r: ActuatorResult, cfg: RunConfig) -> float:
    """A saved result's score: its fit objective plus the mass penalty of its PAMs (both sides, with a
    block's assumed mass) — what the run's choices between results compare."""
    p = r.pam
    return float(r.objective) + cfg.mass_penalty(p.diameter_mm, p.n_parallel, p.resting_length_m, p.transmission)


def size_text(p: Pam) -> str:
    """``20 mm x1`` (``on a k:1 pulley block`` where it is on one)."""
    return f"{p.diameter_mm} mm x{p.n_parallel}" + (f" on a {p.transmission}:1 pulley block" if p.transmission > 1 else "")


def bone_line(bone: dict) -> str:
    """One line: the exact bone clearance of an actuator after the bone-mesh stage."""
    segs = "; ".join(f"segment {k} {v['depth_mm']:.1f} mm into {v['bone']}"
                     for k, v in bone["segments_into_bone"].items())
    pts = "; ".join(f"point {k} {v:.1f} mm" for k, v in bone["point_distance_mm"].items() if not 0 <= v <= 20)
    pams = "; ".join(f"{v:.1f} mm into PAM {k}" for k, v in bone.get("pam_overlap_mm", {}).items())
    what = "; ".join(x for x in (segs, pts, pams) if x)
    return ("clear" if bone["clear"] else "NOT clear: " + what) + \
        f" (max penetration {bone['max_segment_penetration_mm']:.1f} mm at the bone-check poses)"


def far_points(measure: dict) -> list[str]:
    """``["p2 70 mm", ...]``: the points of a bone measure's summary (``point_distance_mm``) over 20 mm
    (the audit's bracket limit) from their bone."""
    return [f"{name} {v:.0f} mm" for name, v in measure.get("point_distance_mm", {}).items() if v > 20]


def unit_mass(p: Pam) -> float:
    """Estimated mass [kg] of a PAM's units on both sides (the audit's)."""

    return pams_mass([p])


def design_mass(seed: Design, results: list[ActuatorResult]) -> float:
    """The robot's estimated mass [kg] (the audit's, both sides): the results' PAMs, the seed's for actuators
    not optimised."""

    ids = {r.id for r in results}
    return pams_mass([p for p in seed.pams if p.id not in ids] + [r.pam for r in results])


def capped_but_feasible(r: ActuatorResult, tol: float) -> bool:
    """Whether ``r``'s solve stopped at IPOPT's CPU-time or iteration cap at a point that keeps every constraint
    within ``tol``: not converged, but a feasible design (how far IPOPT gets within the CPU-time cap depends on
    the machine and its load)."""
    return r.status in CAPPED_STATUSES and max(r.violations.values(), default=0.0) <= tol


def capped_lines(results: list[ActuatorResult]) -> list[str]:
    """A log line per actuator whose solve stopped at a cap within every constraint (:func:`capped_but_feasible`)."""
    from pamkin.optimize.problem import FEASIBILITY_TOL  # noqa: PLC0415  (casadi only in workers / optimiser)

    return [f"actuator {r.id} {r.name}: its solve stopped at the solver's cap ({r.status}) within every "
            f"constraint: kept, not converged" for r in results
            if not r.success and capped_but_feasible(r, FEASIBILITY_TOL)]


def check_results(results: list[ActuatorResult]) -> None:
    """Raise :class:`InfeasibleError` naming the violated constraints of infeasible actuators (a solve stopped at
    a cap within every constraint is not one: :func:`capped_but_feasible`)."""
    from pamkin.optimize.problem import FEASIBILITY_TOL  # noqa: PLC0415  (casadi only in workers / optimiser)

    bad = [r for r in results if not r.success and not capped_but_feasible(r, FEASIBILITY_TOL)]
    if bad:
        lines = []
        for r in bad:
            worst = sorted(((v, k) for k, v in r.violations.items() if v > FEASIBILITY_TOL), reverse=True)[:3]
            what = "; ".join(f"{k} (violated by {v:.3g})" for v, k in worst) or r.status
            lines.append(f"actuator {r.id} {r.name}: {r.status}: {what}")
        raise InfeasibleError("infeasible: " + " | ".join(lines))
