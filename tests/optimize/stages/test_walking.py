"""The optimiser's walking check (optimize/stages/walking.py): samples between the trial's frames, the
report and swap logic, and a diameter / count change on a fixed route."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pamkin.robot import festo

from pamkin.gait import plan as gait
from pamkin.robot.design import load_design
from pamkin.optimize.stages import walking
from pamkin.optimize.config import RunConfig
from pamkin.robot.biped import robot_skeleton

needs_trial = pytest.mark.skipif(not gait.DEFAULT_IK.is_file(), reason="walking trial (../shared/gait) not available")


@pytest.fixture(scope="module")
def skeleton():
    return robot_skeleton()


@needs_trial
def test_midpoint_trial_lies_between_the_audits_frames(skeleton):
    t = gait.load_trial(skeleton)
    m = walking.midpoint_trial(skeleton)
    assert len(m.times) == len(t.times) - 1
    assert np.all((m.times > t.times[:-1]) & (m.times < t.times[1:]))        # never one of the audit's frames
    i = 17
    assert np.allclose(m.q[i], (t.q[i] + t.q[i + 1]) / 2, atol=0)
    assert np.allclose(m.moments[i], (t.moments[i] + t.moments[i + 1]) / 2, atol=0)
    assert m.coordinates == t.coordinates


@needs_trial
def test_walking_pass_reports_the_fraction_and_swaps_nothing_it_cannot_improve(skeleton):
    import pamkin
    from pamkin.human.rom import load_rom

    design = load_design("thesis", bodies=skeleton.bodies, coordinates=skeleton.coordinates)
    trial = walking.midpoint_trial(skeleton)
    p = walking.plan(design, skeleton, trial)
    frac = p.feasible_frame_fraction
    assert 0.2 < frac < 0.8                                    # the thesis design walks about half the trial
    # every actuator named as limited has a PAM at the pressure limit in an infeasible sample
    ids = walking.limited_actuators(p)
    assert ids
    bad = (np.abs(p.residuals) > p.tolerance * p.peaks).any(axis=1)
    for aid in ids:
        cols = [k for k, r in enumerate(p.pam_results) if r.id == aid]
        assert np.any(p.pressures[np.ix_(bad, cols)] >= p.p_max_Pa * (1 - 1e-6))
    human, rom = pamkin.gait2392(), load_rom(design.rom, "r")
    for target, expect in ((0.0, None), (1.0, "no swap of the actuators at the pressure limit")):
        cfg = RunConfig().replace({"walking.min_fraction": target})
        out, results, lines = walking.walking_pass(design, [], [], cfg, 30, skeleton, trial, human, rom)
        assert out is design and results == []
        assert f"{100 * frac:.1f} % feasible, target {100 * target:.0f} %" in lines[0]
        assert (expect is None and len(lines) == 1) or expect in lines[1]


def test_resize_keeps_the_route_and_meets_the_limits():
    """Actuator 29 of the v2 seed on its route (points fixed) as 20 mm x 2: the points do not move, the
    resting and tendon lengths keep the PAM within Festo's contraction, stretch and rated force on a hip
    grid (checked here with the force model directly)."""
    import pamkin
    from pamkin.optimize.samples import actuator_data
    from pamkin.human.paths import PathSet
    from pamkin.human.rom import load_rom

    seed = load_design("v2_seed")
    human = pamkin.gait2392()
    rom = load_rom(seed.rom, "r")
    cfg = RunConfig()
    pam = seed.pam(29)
    data = actuator_data(pam, human, rom, cfg, seed.fitting_length_m)
    z = np.concatenate([np.ravel([p.location for p in pam.points]), [pam.resting_length_m, 0.0]])
    out = walking.resize(data, cfg, z, 20, 2, human, rom)
    assert out is not None
    new, sol = out
    assert (new.diameter_mm, new.n_parallel) == (20, 2)
    assert [p.location for p in new.points] == [p.location for p in pam.points]
    q, _ = human.grid(["hip_flexion_r", "hip_adduction_r", "hip_rotation_r"], 9, rom=rom)
    L = PathSet(human.kinematics, ["r"], [list(new.points)]).evaluate(human.kinematics.forward(q, warn_range=False)).lengths[:, 0]
    eps = (new.resting_length_m - (L - 2 * seed.fitting_length_m - new.tendon_length_m)) / new.resting_length_m
    assert eps.max() <= festo.max_contraction(20) + 1e-6
    assert eps.min() >= -festo.max_pretension(20) - 1e-6
    F = festo.force(eps, new.resting_length_m, cfg.pressure_Pa, 20, model=cfg.force_model)
    assert F.max() <= festo.F_MAX_THEORETICAL[20] + 1e-6
    assert sol.success and np.isfinite(sol.objective)


@needs_trial
def test_walking_pass_keeps_the_swap_that_walks_most(skeleton):
    """The thesis design walks 48 % of the samples between the trial's frames; its tensor fasciae latae
    (10 mm) is at the pressure limit, and as a 20 mm PAM on the same route the plan is feasible on all
    of them. The pass ranks that swap first, solves it (on the fixed route, else through ``resolve``:
    here a stand-in that returns the same route with the new size) and keeps it; the design it returns
    walks what its line says."""
    import pamkin
    from pamkin.optimize.results import ActuatorResult
    from pamkin.optimize.samples import actuator_data
    from pamkin.human.rom import load_rom

    design = load_design("thesis", bodies=skeleton.bodies, coordinates=skeleton.coordinates)
    human, rom = pamkin.gait2392(), load_rom(design.rom, "r")
    cfg = RunConfig().replace({"walking.min_fraction": 0.95})
    trial = walking.midpoint_trial(skeleton)
    tfl = design.pam(7)
    assert (tfl.diameter_mm, tfl.n_parallel) == (10, 1)

    def result(pam):
        z = np.concatenate([np.ravel([getattr(p, "location", (0.0, 0.0, 0.0)) for p in pam.points]),
                            [pam.resting_length_m, pam.tendon_length_m]])
        return ActuatorResult(pam.id, pam.name, pam, "given", True, z=z, n_parallel=pam.n_parallel,
                              attempts=[{"start": "stand-in", "objective": 0.5}])

    results = [result(p) for p in design.pams]
    data = [actuator_data(p, human, rom, cfg, design.fitting_length_m) if p.id == 7 else None for p in design.pams]
    asked = []

    def resolve(tasks):
        asked.extend((results[i].id, key) for i, key, _ in tasks)
        out = []
        for i, (d, n), _ in tasks:
            pam = dataclasses.replace(results[i].pam, diameter_mm=d, n_parallel=n)
            out.append(dataclasses.replace(result(pam), attempts=[{"start": "re-solved", "objective": 0.4}]))
        return out

    # only the tensor fasciae latae is offered a swap (the other actuators have no problem data here)
    results_tfl = [r if r.id == 7 else dataclasses.replace(r, z=None) for r in results]
    out, new_results, lines = walking.walking_pass(design, results_tfl, data, cfg, 30, skeleton, trial,
                                                      human, rom, resolve)
    assert "48.5 % feasible, target 95 %" in lines[0]
    assert len(lines) == 2 and "actuator 7 Tensor Fasciae Latae: 10x1 -> 20x1" in lines[1], lines
    assert "48.5 % -> 100.0 %" in lines[1]
    new = out.pam(7)
    assert (new.diameter_mm, new.n_parallel) == (20, 1)
    assert [p.location for p in new.points] == [p.location for p in tfl.points]
    assert new_results[[r.id for r in new_results].index(7)].pam == new
    # the fixed route cannot carry a 20 mm PAM within the limits: the best-ranked swap was re-solved, and as
    # it reaches the target the next (40 mm, as good on the plan, heavier) was not tried
    assert asked == [(7, (20, 1))]
    assert walking.plan(out, skeleton, trial).feasible_frame_fraction == 1.0
    # without the stand-in, a swap the fixed route cannot carry is not kept silently
    _, same, lines = walking.walking_pass(design, results_tfl, data, cfg, 30, skeleton, trial, human, rom)
    assert "no swap of the actuators at the pressure limit" in lines[1]
    assert same[[r.id for r in same].index(7)].pam == tfl
