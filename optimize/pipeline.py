"""An optimisation run: the seed, a declared, ordered list of stages, and the run folder.

A run (:func:`run`) prepares the seed design (:mod:`optimize.stages.seed`), builds the run's context
(:class:`optimize.context.RunContext`: the model, ranges of motion, bones, samples and config), then runs the
stages of :data:`STAGES` in order — each one ``run(ctx, results) -> results``, switched on or off by its
config keys — and writes the run folder: ``design.yaml`` (same format as the built-in designs),
``summary.json`` (with the independent numpy check of :mod:`optimize.verify`), ``log.txt``,
``before_after.png``, ``config.json`` (the run's config, for ``--resume``) and ``tasks/`` (every finished
per-actuator task, :mod:`optimize.store`). Every file is written atomically. The robot's own data is never
written: :func:`apply_design` writes a design where the user names it.
"""

from __future__ import annotations

import json
import os
import sys
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from pamkin.optimize.config import RunConfig, config_to_dict
from pamkin.optimize.context import RunContext
from pamkin.optimize.executor import one_blas_thread
from pamkin.optimize.plots import before_after_plot
from pamkin.optimize.report import (
    bone_limit_lines,
    check_progress,
    fit_cost_lines,
    mount_lines,
)
from pamkin.optimize.results import (
    ActuatorResult,
    InfeasibleError,
    bone_line,
    capped_lines,
    check_results,
)
from pamkin.optimize.samples import actuator_data
from pamkin.optimize.stages import (
    bone_rounds,
    clearance,
    detours,
    first_fit,
    mass,
    pam_ends,
    rack,
    reallocate,
    resize,
    rollers,
    separate,
    unit_budget,
    walking,
)
from pamkin.optimize.stages import seed as seed_stage
from pamkin.optimize.store import RunStore
from pamkin.optimize.verify import summarize

from pamkin.audit.compare import finite_or_none
from pamkin.errors import OutputError, PamkinError
from pamkin.human.bones import BoneSet
from pamkin.human.model import gait2392
from pamkin.human.rom import load_rom
from pamkin.outputs import check_output_file, check_output_folder
from pamkin.human.urdf import render_robot_urdf
from pamkin.outputs import write_file
from pamkin.robot.design import Design, save_design


@dataclass(frozen=True)
class Stage:
    """One stage of the pipeline: ``run(ctx, results) -> results``, on where ``enabled(cfg)``."""

    name: str
    run: Callable[[RunContext, list[ActuatorResult]], list[ActuatorResult]]
    enabled: Callable[[RunConfig], bool]
    summary: str


#: The stages of a run, in order (the seed stage, :mod:`optimize.stages.seed`, comes before them; the
#: independent check, :mod:`optimize.verify`, after). Documentation: one page per stage.
STAGES: tuple[Stage, ...] = (
    Stage("first_fit", first_fit.run, lambda c: True,
          "every actuator's fit: outer loop over Festo diameter and parallel count, multistart "
          "(without a unit budget, each actuator's bone rounds and one-segment stage follow at once)"),
    Stage("unit_budget", unit_budget.run, lambda c: c.unit_budget.max_units > 0,
          "every actuator's diameter and parallel count chosen together within the unit budget"),
    Stage("bone_rounds", bone_rounds.run, lambda c: c.unit_budget.max_units > 0,
          "the chosen size of every actuator through the bone-mesh rounds and the one-segment stage"),
    Stage("resize", resize.run, lambda c: c.unit_budget.max_units > 0 and c.bone_rounds.enabled and c.resize.above > 0,
          "other diameters (and pulley blocks throughout) for actuators the bone rounds left with a poor fit"),
    Stage("reallocate", reallocate.run, lambda c: c.unit_budget.max_units > 0 and c.bone_rounds.enabled and c.reallocate.enabled,
          "PAM units moved from actuators failing both fit limits to ones they make pass"),
    Stage("mass", mass.run, lambda c: c.mass.max_kg > 0,
          "pulley blocks taken off again while the robot's estimated mass is over its budget"),
    Stage("walking", walking.run, lambda c: c.unit_budget.max_units > 0 and c.walking.min_fraction > 0,
          "the walking trial's pressure plans; actuators at the pressure limit re-sized within the budget"),
    Stage("clearance", clearance.run, lambda c: c.bone_rounds.enabled and c.clearance.enabled,
          "routes that hit another PAM's body solved again with the bodies as obstacles"),
    Stage("rollers", rollers.run, lambda c: c.bone_rounds.enabled and c.rollers.enabled,
          "rollers (cable guides on bone) for actuators failing a fit limit"),
    Stage("detours", detours.run, lambda c: c.bone_rounds.enabled and c.detours.enabled,
          "same-body segments into their bone carried round it by via points"),
    Stage("pam_ends", pam_ends.run, lambda c: c.mount.enabled and c.pam_ends.enabled,
          "each PAM's segment and end chosen for the fewest intersecting PAM pairs"),
    Stage("separate", separate.run, lambda c: c.bone_rounds.enabled and c.separate.enabled,
          "mount-segment ends moved on their brackets until PAM bodies are 5 mm apart and 5 mm from bone"),
    Stage("rack", rack.run, lambda c: c.bone_rounds.enabled and c.rack.enabled,
          "every PAM body hung on brackets along a bone of its route's end, the whole layout chosen at once"),
)
#: Files of a run folder a new run writes (an existing folder holding any of them is not overwritten).
RUN_FILES = ("design.yaml", "summary.json", "log.txt", "before_after.png", "config.json")


def make_context(seed: Design, cfg: RunConfig, warm_ids: set[int], stream=None, executor=None,
                 store: RunStore | None = None) -> RunContext:
    """The run's context for ``seed`` (right side): Gait2392, the seed's range of motion, every selected
    actuator's sample data, the bone meshes (``cfg.bone_rounds.enabled``) and the validation poses (made here, before any
    worker starts: a forked worker that computes them itself hangs in the threads this process started)."""
    human = gait2392()
    rom = load_rom(seed.rom, "r")
    ids = cfg.actuators or [p.id for p in seed.pams]
    unknown = [i for i in ids if i not in {p.id for p in seed.pams}]
    if unknown:
        raise PamkinError(f"unknown actuator id(s) {unknown}")
    data = [actuator_data(seed.pam(i), human, rom, cfg, seed.fitting_length_m) for i in ids]
    ctx = RunContext(cfg, seed, human, rom, data, warm_ids=set(warm_ids), stream=stream, executor=executor,
                     store=store, n_cap=cfg.first_fit.max_parallel)
    if cfg.mount.enabled and (cfg.mount.failing or cfg.mount.passing):
        ctx.validation_set()
    if cfg.bone_rounds.enabled:
        ctx.bones = BoneSet(human)
    return ctx


def run_stages(ctx: RunContext) -> list[ActuatorResult]:
    """Every enabled stage of :data:`STAGES`, in order, from no results; the last stage's results."""
    results: list[ActuatorResult] = []
    with one_blas_thread():       # every solve on one BLAS thread, here as in the workers
        for stage in STAGES:
            if stage.enabled(ctx.cfg):
                results = stage.run(ctx, results)
    return results


def solve_all(seed: Design, cfg: RunConfig, stream=sys.stderr, warm_ids: set[int] = frozenset(),
              executor=None, store: RunStore | None = None) -> tuple[list[ActuatorResult], RunContext]:
    """Every stage on ``seed``'s selected actuators: (results, the run's context)."""
    ctx = make_context(seed, cfg, warm_ids, stream, executor, store)
    return run_stages(ctx), ctx


def check_out_dir(out_dir: Path, resume: bool, force: bool = False) -> None:
    """Refuse to start a run into a folder holding files (``resume``: the folder must hold a run's
    ``config.json``; ``force``: an existing folder is replaced whole — removed here, before the run)."""
    if resume:
        if not (out_dir / "config.json").is_file():
            raise OutputError(str(out_dir), "not a run folder to resume (no config.json)")
        return
    check_output_folder(out_dir, force=True)            # a file, or a folder below a file: refused
    if out_dir.is_dir() and any(out_dir.iterdir()):
        if not force:
            held = [name for name in RUN_FILES if (out_dir / name).exists()]
            what = f"a run already ({', '.join(held)})" if held else "files already"
            raise OutputError(str(out_dir), f"holds {what}; choose a new folder, continue it with --resume "
                                            f"{out_dir}, or replace it whole with --force")
        shutil.rmtree(out_dir)


def run(cfg: RunConfig, out_dir: Path, apply: str | os.PathLike | None = None, stream=sys.stderr,
        on_design=None, executor=None, resume: bool = False, force: bool = False) -> dict:
    """Run an optimisation into ``out_dir``; optionally write the result to the design file ``apply``.

    Args:
        cfg: The run's configuration (:func:`optimize.config.load_config`).
        out_dir: The run folder (created; must not hold another run unless ``resume``).
        apply: Where to write the resulting design (and its URDF beside it, :func:`apply_design`); only when
            every actuator is feasible. None: nowhere.
        stream: Progress and report lines.
        on_design: Called with ``out_dir`` as soon as ``design.yaml`` is written, before the run's own
            check and plot (``pamkin optimize`` starts its audit there, beside them).
        executor: Runs the per-actuator tasks (:mod:`optimize.executor`; default: ``cfg.workers`` local
            processes).
        resume: Continue the killed run in ``out_dir``: its finished tasks are read back, not solved again.
        force: Replace an existing ``out_dir`` whole (default: refuse a folder holding files).

    Returns:
        The summary (also written to ``out_dir/summary.json``).
    """
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    check_out_dir(out_dir, resume, force)
    if apply is not None:
        check_output_file(apply)
    seed, warm_ids, eyelets = seed_stage.prepare(cfg)
    for line in eyelets:
        print(line, file=stream, flush=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    if not resume:
        write_file(out_dir / "config.json", json.dumps(config_to_dict(cfg), indent=2))
    store = RunStore(out_dir)
    if resume:
        print(f"resuming {out_dir}: {store.stored()} finished tasks stored", file=stream, flush=True)
    log = [f"pamkin optimize: seed design {seed.name!r} ({seed.path}), config {cfg.source or 'defaults'}",
           f"workers {cfg.workers}, multistart {cfg.first_fit.multistart}, diameters {cfg.first_fit.diameters_mm}, "
           f"max_parallel {cfg.first_fit.max_parallel}, force model {cfg.force_model}, pressure {cfg.pressure_Pa:.0f} Pa",
           *eyelets]
    results, ctx = solve_all(seed, cfg, stream, warm_ids, executor, store)
    log.extend((ctx.walking or {}).get("log", []))
    solve_seconds = time.perf_counter() - t0
    new = seed
    for r in results:
        new = new.replace_pam(r.pam)
    new = Design(f"optimized from {seed.name}", new.pams, new.pressure_Pa, new.force_model,
                 new.fitting_length_m, new.rom, f"pamkin optimize run {out_dir.name}", "", dict(new.extra))
    save_design(new, out_dir / "design.yaml", _run_header(out_dir, cfg))
    if on_design is not None:
        on_design(out_dir)
    summary = _report(ctx, results, seed, new, log, stream)
    summary["solve_seconds"] = round(solve_seconds, 1)
    summary["total_seconds"] = round(time.perf_counter() - t0, 1)
    _write_summary(out_dir, summary)
    before_after_plot(seed, new, out_dir / "before_after.png",
                      seed_label=f"warm start ({Path(cfg.warm_start).name})" if warm_ids else None)
    log.extend(ctx.pam_ends)
    log.extend(ctx.separation)
    log.extend(ctx.rack)
    log.extend(f"fit limits: {line}" for line in summary.get("fit_limits_and_bone", []))
    for line in capped_lines(results):
        print(line, file=stream, flush=True)
        log.append(line)
    log.append(f"total {summary['total_seconds']} s (solves {solve_seconds:.1f} s)")
    write_file(out_dir / "log.txt", "\n".join(log) + "\n")
    try:
        check_results(results)
    except InfeasibleError:
        summary["applied"] = False
        _write_summary(out_dir, summary)
        raise
    if apply is not None:
        apply_design(new, Path(apply), run_folder=out_dir)
        summary["applied"] = str(apply)
        _write_summary(out_dir, summary)
    return summary


def _report(ctx: RunContext, results: list[ActuatorResult], seed: Design, new: Design, log: list[str],
            stream) -> dict:
    """The run's log lines (appended to ``log``), its report on ``stream`` and its summary (with the
    independent check of :mod:`optimize.verify`)."""
    cfg = ctx.cfg
    for r in results:
        log.append(f"actuator {r.id} {r.name}: {r.status} in {r.seconds:.1f} s; attempts: " +
                   "; ".join(f"{a['diameter_mm']} mm x{a['n_parallel']} {a['start']}: {a['status']} "
                             f"J={a['objective']:.4g}{'' if a['feasible'] else ' (infeasible)'} ({a['seconds']:.1f} s)"
                             for a in r.attempts)
                   + ("; not tried, dominated: " + "; ".join(r.skipped) if r.skipped else ""))
        if r.bone:
            log.extend(r.bone["log"])
            log.append(f"  bone-mesh clearance of actuator {r.id} {r.name}: " + bone_line(r.bone))
        if r.mount:
            log.append(f"  actuator {r.id} {r.name}: {r.mount['line']}")
    for r in results:
        if r.bone and not r.bone["clear"]:
            print(f"bone-mesh: actuator {r.id} {r.name}: {bone_line(r.bone)}", file=stream, flush=True)
    costly = fit_cost_lines(results)
    for line in costly:
        print(f"bone-mesh: {line}", file=stream, flush=True)
    reach = bone_limit_lines(ctx, results)
    for line in reach:
        print(f"fit limits: {line}", file=stream, flush=True)
    for line in mount_lines(results, cfg):
        print(line, file=stream, flush=True)
    print("solving done; checking every actuator on dense grids (numpy pipeline) ...", file=stream, flush=True)
    summary = summarize(seed, new, results, cfg, progress=check_progress(stream))
    bone = {str(r.id): {k: v for k, v in r.bone.items() if k != "log"} for r in results if r.bone}
    if bone:
        summary["bone_mesh"] = bone
        summary["bone_mesh_not_clear"] = [f"{r.id} {r.name}: {bone_line(r.bone)}" for r in results
                                          if r.bone and not r.bone["clear"]]
        summary["all_clear_bone"] = not summary["bone_mesh_not_clear"]    # the meshes replace the capsules
        summary["grids"]["min_bone_clearance_m"] += (" (the first phase's bone model; with the bone meshes the "
                                                     "actuators' bone_mesh entries give the clearance)")
        summary["bone_mesh_fit_cost"] = costly
        summary["fit_limits_and_bone"] = reach
    if any(r.mount for r in results):
        summary["one_segment"] = {str(r.id): r.mount for r in results if r.mount}
    if ctx.pam_ends:
        summary["pam_ends"] = ctx.pam_ends
    if ctx.separation:
        summary["separation"] = ctx.separation
    if ctx.rack:
        summary["rack"] = ctx.rack
    if ctx.walking:
        summary["walking_check"] = ctx.walking      # optimize.stages.walking: fractions between the trial's frames
    return summary


def apply_design(design: Design, design_path: Path, urdf_path: Path | None = None,
                 run_folder: str | os.PathLike | None = None) -> tuple[Path, Path]:
    """Write a design to ``design_path`` and its robot URDF beside it (``urdf_path``, default: the design's
    name with ``.urdf``), each file atomically.

    The URDF is rendered from a temporary copy first, so a failure leaves both files unchanged. The
    installed package's data is never a target: use a path of your own (``pamkin optimize --apply FILE``)
    and load it with ``--design FILE``. ``run_folder`` is named in the design file's header.

    Returns:
        The two paths written.
    """
    design_path = Path(design_path)
    urdf_path = Path(urdf_path) if urdf_path is not None else design_path.with_suffix(".urdf")
    header = _HEADER if run_folder is None else _HEADER.replace(
        "--apply`;", f"--apply` from the run folder {Path(run_folder).name};")
    with tempfile.TemporaryDirectory() as tmp:
        tmp_design = Path(tmp) / design_path.name
        save_design(design, tmp_design, header)
        urdf = render_robot_urdf(design_path=tmp_design).replace(str(Path(tmp)), "")
    save_design(design, design_path, header)
    write_file(urdf_path, urdf)
    return design_path, urdf_path


_HEADER = ("# A PAM robot design (right side; the left side is the mirror image).\n"
           "# Written by `pamkin optimize --apply`; format: pamkin.robot.design.\n")


def _run_header(out_dir: Path, cfg: RunConfig) -> str:
    """Header of a run folder's design.yaml: which command wrote it, from which config."""
    return ("# An optimised PAM design (right side; the left side is the mirror image).\n"
            f"# Written by `pamkin optimize` into the run folder {Path(out_dir).name} "
            f"(config: {Path(cfg.source).name if cfg.source else 'defaults'}); format: pamkin.robot.design.\n"
            "# Not applied to the robot's design (`pamkin optimize --apply` does that); reuse it with\n"
            "# --design or --warm-start and this folder.\n")


def _write_summary(out_dir: Path, summary: dict) -> None:
    """``summary.json`` as strict JSON (atomically): a non-finite number (an undefined or failing-as-infinite
    error, a failed solve's objective) is written as ``null``, which every JSON reader accepts."""
    write_file(out_dir / "summary.json", json.dumps(finite_or_none(summary), indent=2, allow_nan=False))
