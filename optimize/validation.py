"""Validation poses: how an actuator's result fits multi-joint poses it was not trained on, so that the run's
choices between finished results (:mod:`optimize.stages.resize`) are made on held-out error rather than
on the training objective.

The poses are drawn like the audit's (every right-leg and lumbar coordinate uniform within the range of
motion, others at their defaults) but from the optimiser's own random stream (:data:`VALIDATION_STREAM`),
never the audit's. The error is the audit's pair of per-PAM numbers: the primary-coordinate NRMSE and the
worst error about any crossed coordinate, both ÷ the human peak about the primary coordinate.
"""

from __future__ import annotations

import warnings

import numpy as np

from pamkin.audit.compare import failing_as_worst
from pamkin.audit.measure import random_poses, torque_metrics
from pamkin.errors import RangeWarning
from pamkin.robot.biped import PamRobot
from pamkin.robot.design import Design, Pam

#: Random stream of the validation poses (``SeedSequence(seed, spawn_key=(VALIDATION_STREAM,))``).
VALIDATION_STREAM = 0xA0D6
#: Number of validation poses.
N_VALIDATION = 400


def validation_poses(model, rom, seed: int = 0, n: int = N_VALIDATION) -> np.ndarray:
    """``n`` poses like the audit's random poses, from :data:`VALIDATION_STREAM`."""

    return random_poses(model, rom, n, seed, stream=VALIDATION_STREAM)


def validation_error(pam: Pam, model, q: np.ndarray, human_torques: np.ndarray, coords: list[str],
                     design: Design | None = None) -> tuple[float, float]:
    """(primary NRMSE, worst error about any of ``coords``) of ``pam`` at poses ``q``: RMS(robot − human
    torque) ÷ the human peak about the primary coordinate; ``human_torques`` (S, n_muscles, n_coordinates)
    from ``model.torques(q)``. The PAM's force uses ``design``'s pressure, force model and fitting length
    (default: a design's defaults, 620 kPa and v3). Where the human muscles give no torque about the primary
    coordinate at these poses both errors are undefined: they count as infinite (the worst, as in the audit),
    so such a result never wins a comparison."""

    base = design or Design("validation", ())
    des = Design(base.name, (pam,), base.pressure_Pa, base.force_model, base.fitting_length_m, base.rom)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        tr = PamRobot(des, model, sides=("r",)).evaluate(q).torques[:, 0, :]

    idx = [model.muscles.index(m) for m in pam.human_muscles]
    th = human_torques[:, idx].sum(axis=1)
    names = model.coordinates
    prim = names.index(pam.primary_coordinate)
    m = torque_metrics(th, tr, prim, sorted({*(names.index(c) for c in coords), prim}), names)
    nrmse, worst = failing_as_worst([m["nrmse"], m["worst_coordinate_error"]])
    return float(nrmse), float(worst)
