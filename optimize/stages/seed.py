"""Seed stage: the design the run starts from — its eyelets, a warm start's routes and sizes, and the pulley
blocks of ``[transmission]`` — checked against the config, with the run's pressure and force model."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from pamkin.optimize.config import RunConfig

from pamkin.errors import DataFileError
from pamkin.human.bones import BoneSet
from pamkin.human.model import gait2392
from pamkin.robot.biped import robot_skeleton
from pamkin.robot.design import Design, load_design
from pamkin.robot.detour import remove_via


def prepare(cfg: RunConfig) -> tuple[Design, set[int], list[str]]:
    """The seed design of a run, the ids of its warm-started actuators and the eyelet lines to report.

    Raises:
        pamkin.errors.DataFileError: a seed PAM with rollers, a warm start that is not a run of this seed, or
            a seed the config does not fit (:meth:`RunConfig.check_design`).
    """
    skeleton = robot_skeleton()
    kw = {"bodies": skeleton.bodies, "coordinates": skeleton.coordinates}
    seed = load_design(cfg.design, **kw) if cfg.design else load_design(**kw)
    eyelets: list[str] = []
    names = None
    if cfg.eyelets:         # the optimised actuators' eyelets (pamkin.robot.eyelets), before the warm start
        human = gait2392()
        bones = BoneSet(human)
        # every eyelet of the table names the route points a warm start's routes may hold (a warm run's
        # actuators not optimised here keep theirs, lengths and all)
        names = dataclasses.replace(cfg, actuators=[]).apply_eyelets(seed, human, bones)[0]
        seed, eyelets = cfg.apply_eyelets(seed, human, bones)
    warm_ids: set[int] = set()
    if cfg.warm_start:
        seed, warm_ids = warm_seed(seed, load_design(Path(cfg.warm_start) / "design.yaml", **kw), names)
        if cfg.eyelets:     # an optimised actuator's warm route without its eyelet (a run without them) gets it
            seed, eyelets = cfg.apply_eyelets(seed, human, bones)
    rolled = [p.id for p in seed.pams if p.rollers]
    if rolled:
        raise DataFileError(seed.path or "<design>", f"PAM(s) {rolled} have rollers, which pamkin optimize does not "
                            "model yet (it would move their points and ignore the rollers); remove the rollers to "
                            "optimise, or audit, view and export the design as it is")
    cfg.check_design(seed)
    seed = cfg.apply_transmission(seed)
    seed = Design(seed.name, seed.pams, cfg.pressure_Pa, cfg.force_model, seed.fitting_length_m, seed.rom,
                  seed.description, seed.path, dict(seed.extra))
    return seed, warm_ids, eyelets


def warm_seed(seed: Design, warm: Design, names: Design | None = None) -> tuple[Design, set[int]]:
    """``seed`` with every PAM it shares with ``warm`` (a finished run's design) replaced by the warm one, and
    their ids. A warm route's rollers and detour via points are not kept (:func:`pamkin.robot.detour.remove_via`:
    the points the seed route does not have, their length off the tendon again): the roller stage
    (``rollers.enabled``) and the detours (``detours.enabled``) place them again. ``names`` (default ``seed``):
    the design whose route points a warm route may keep (the seed with every eyelet of the run's table)."""
    names = names or seed
    ids = set()
    for p in warm.pams:
        if p.id in {q.id for q in seed.pams}:
            try:
                p = remove_via(p, {pt.name for pt in names.pam(p.id).points})
            except ValueError as e:      # a warm route with points the seed's does not have on other bodies
                raise DataFileError(warm.path or "<warm start>", f"{e}: not a run of this seed design") from None
            seed = seed.replace_pam(dataclasses.replace(p, rollers=()))
            ids.add(p.id)
    return seed, ids
