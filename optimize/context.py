"""The run's context: the shared inputs every stage and every worker reads, in one explicit object.

A :class:`RunContext` holds the run's configuration, the seed design, the human model (Gait2392), its range
of motion, every actuator's sample data (:func:`optimize.samples.actuator_data`), the bone meshes and the
validation poses, plus what the stages hand on to later ones (the first phase's results, the unit budget's
choice, the PAM-PAM pass's obstacles). Stages read and set it explicitly; the executor
(:mod:`optimize.executor`) sends it to the worker processes with every task (it pickles: a few MB; the
stream, executor and run store it carries for the run's own process are left out). Nothing of a run lives in
a module global.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pamkin.optimize.config import RunConfig
from pamkin.optimize.executor import map_tasks
from pamkin.optimize.samples import is_free
from pamkin.optimize.validation import validation_error, validation_poses

from pamkin.audit.measure import load_limits
from pamkin.errors import RangeWarning
from pamkin.human.model import Model
from pamkin.human.rom import RangeOfMotion
from pamkin.robot.biped import PamRobot
from pamkin.robot.design import Design, Pam
from pamkin.robot.pam_body import Placement, placement, route_positions

#: ``mount_passing``: a mount at a fit cost is accepted where the mounted PAM's validation NRMSE and worst error
#: stay this far within the audit's limits (the validation poses are 400, the audit's 2000; measured on the
#: default design, the two differ by at most 0.008 in NRMSE and 0.015 in worst error for every PAM whose
#: errors are below 0.3).
PASS_MARGIN = 0.02

#: Attributes that stay in the run's own process (not sent to workers).
_LOCAL = ("stream", "executor", "store", "bracket_cache")


@dataclass
class RunContext:
    """Everything a run's stages and workers share.

    Attributes:
        cfg: The run's configuration.
        seed_design: The seed design (right side) with the run's pressure and force model.
        human: Gait2392 (:func:`pamkin.gait2392`).
        rom: Range of motion of the right side [rad, m].
        data: Per optimised actuator (index ``k``): its sample data.
        bones: The bone meshes (:class:`pamkin.human.bones.BoneSet`) where ``cfg.bone_rounds.enabled``, else None.
        validation: ``(q, T)``: the validation poses and the human torques there [N·m], made once per run.
        warm_ids: Actuator ids whose warm start is tried first.
        fit_only: The first phase only fits (a unit budget chooses the sizes before the bone rounds).
        n_cap: Largest parallel count the first phase tries.
        first: Per ``k``: the result a later stage starts from (the first phase's, or the stage's input).
        choice: Per ``k``: the unit budget's ``(diameter_mm, n_parallel)`` (None: no feasible candidate).
        obstacles: Per ``k``: the PAM-PAM pass's obstacles.
        walking: The walking stage's report.
        pam_ends: The pam_ends stage's report lines.
        separation: The separate stage's report lines.
        rack: The rack stage's report lines.
        stream: Where progress goes (run process only).
        executor: Runs the per-actuator tasks (run process only; :mod:`optimize.executor`).
        store: The run folder's store of finished tasks (run process only; :mod:`optimize.store`).
    """

    cfg: RunConfig
    seed_design: Design
    human: Model
    rom: RangeOfMotion
    data: list = field(default_factory=list)
    bones: Any = None
    validation: tuple[np.ndarray, np.ndarray] | None = None
    warm_ids: set[int] = field(default_factory=set)
    fit_only: bool = False
    n_cap: int = 3
    first: dict = field(default_factory=dict)
    choice: dict = field(default_factory=dict)
    obstacles: dict = field(default_factory=dict)
    walking: dict | None = None
    pam_ends: list[str] = field(default_factory=list)
    separation: list[str] = field(default_factory=list)
    rack: list[str] = field(default_factory=list)
    stream: Any = None
    executor: Any = None
    store: Any = None
    bracket_cache: dict = field(default_factory=dict)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        for name in _LOCAL:
            state[name] = {} if name == "bracket_cache" else None
        return state

    def map(self, fn, tasks: list, label: str, cost: list[float] | None = None) -> list:
        """``fn(self, task)`` for every task, on the run's executor, in the order they finish; finished tasks
        are kept in the run's store under ``label`` (a resumed run takes them from there)."""
        return map_tasks(self, fn, tasks, label, cost)

    # -- route boxes -------------------------------------------------------------------------------------------
    def route_box(self, pam: Pam) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Seed location (or offset) and box half-widths [m] of every route point of ``pam``."""
        cfg = self.cfg
        seed = [np.array(getattr(p, "location", (0.0, 0.0, 0.0)), float) for p in pam.points]
        regions = [np.array(cfg.region(pam.id, p.name), float) if is_free(p) or cfg.limits.move_moving_points
                   else np.zeros(3) for p in pam.points]
        return seed, regions

    def bracket(self, pam: Pam, seed: list[np.ndarray], regions: list[np.ndarray]) -> dict | None:
        """The bone-distance splines of ``pam``'s points for the fit (``[bone_rounds] bracket_fit``; built once per
        process and route box, :func:`optimize.bracket.bracket_splines`), or None."""
        if not (self.cfg.bone_rounds.enabled and self.cfg.bone_rounds.bracket_fit):
            return None
        from pamkin.optimize.bracket import bracket_splines  # noqa: PLC0415  (CasADi)

        key = (pam.id, np.round(np.ravel(seed), 9).tobytes(), np.ravel(regions).tobytes())
        if key not in self.bracket_cache:
            self.bracket_cache[key] = bracket_splines(pam, self.bones, seed, regions)
        return self.bracket_cache[key]

    # -- validation poses --------------------------------------------------------------------------------------
    def validation_set(self) -> tuple[np.ndarray, np.ndarray]:
        """The validation poses and the human torques there (:mod:`optimize.validation`), made once per run
        (before the workers start: they receive them with the context)."""
        if self.validation is None:
            q = validation_poses(self.human, self.rom, self.cfg.seed)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RangeWarning)
                self.validation = (q, self.human.torques(q))
        return self.validation

    def validation_errors(self, pam: Pam, k: int) -> tuple[float, float]:
        """Primary NRMSE and worst error about a crossed coordinate (:mod:`optimize.validation`) of ``pam`` as
        actuator ``k``'s PAM, on the run's validation poses (the seed design carries the run's pressure, force
        model and fitting length)."""
        q, T = self.validation_set()
        return validation_error(pam, self.human, q, T, list(self.data[k].crossed or []), self.seed_design)

    def validation_error_of(self):
        """``error(result, k)``: primary NRMSE + worst error of actuator ``k``'s result on the validation poses."""
        self.validation_set()

        def error(r, k: int) -> float:
            return float(sum(self.validation_errors(r.pam, k)))

        return error

    def failing_fit(self, crossed: list[str], already_failing: bool = True, still_passing: bool = False):
        """``(spanning, mounted) -> reason | None`` for :func:`optimize.mount.mount_stage`: a reason to mount a
        PAM although its fit cost exceeds ``mount_cost``, where no audit fit count is at stake — with
        ``already_failing`` (``mount_failing``) when the spanning PAM's fit fails both of the audit's fit limits
        on the validation poses, so that mounting it changes neither count; with ``still_passing``
        (``mount_passing``) when the mounted PAM still passes both within :data:`PASS_MARGIN`; else None."""
        lim_n, lim_w = fit_limits()
        q, T = self.validation_set()

        def error(pam: Pam) -> tuple[float, float]:
            return validation_error(pam, self.human, q, T, crossed, self.seed_design)

        def reason(spanning: Pam, mounted: Pam) -> str | None:
            if already_failing:
                nr0, w0 = error(spanning)
                if nr0 > lim_n and w0 > lim_w:
                    nr1, w1 = error(mounted)
                    return (f"its fit fails both audit fit limits already (validation NRMSE {nr0:.3f} > {lim_n:g}, "
                            f"worst {w0:.3f} > {lim_w:g}; on one segment {nr1:.3f}, {w1:.3f})")
            if still_passing:
                nr1, w1 = error(mounted)
                if nr1 <= lim_n - PASS_MARGIN and w1 <= lim_w - PASS_MARGIN:
                    return (f"on one segment it still passes both audit fit limits (validation NRMSE {nr1:.3f} <= "
                            f"{lim_n:g} - {PASS_MARGIN:g}, worst {w1:.3f} <= {lim_w:g} - {PASS_MARGIN:g})")
            return None

        return reason

    def placement(self, pam: Pam, q: np.ndarray) -> Placement:
        """Where the PAM body of ``pam`` (right side) sits on its route at poses ``q``
        (:func:`pamkin.robot.pam_body.placement`, as the audit puts it)."""
        human, design = self.human, self.seed_design
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            robot = PamRobot(Design("mount", (pam,), design.pressure_Pa, design.force_model,
                                    design.fitting_length_m, design.rom), human, sides=("r",))
            ks = human.kinematics.forward(q, warn_range=False)
            return placement(route_positions(robot.paths, ks, 0), pam, robot.evaluate(q).pam_lengths[:, 0],
                             design.fitting_length_m)


def fit_limits() -> tuple[float, float]:
    """The audit's fit limits: (primary NRMSE, worst coordinate error) a PAM passes at or below."""
    thr = load_limits()["thresholds"]
    return thr["nrmse_good"], thr["worst_coordinate_error_good"]
