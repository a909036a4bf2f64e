"""``pamkin optimize``: relocate PAM attachment points so robot torques match the human's."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}")
    return v


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "optimize", help="optimise PAM routes, sizes and parallel counts (CasADi + IPOPT) against Gait2392",
        description="Solve one CasADi/IPOPT problem per actuator (in parallel): route points within boxes "
                    "around the seed design's, resting and tendon lengths, with an outer loop over Festo "
                    "diameter and number of parallel PAMs, so that the PAM torque matches the torque of the "
                    "human muscles it replaces, about every coordinate the route or the muscles cross, on "
                    "1-D sweeps, 2-D grids and multi-joint training poses, within the PAMs' strain limits and "
                    "Festo's rated force and 25 percent contraction (also at the range-of-motion corners), "
                    "with a 1 mm attachment error moving the primary torque by at most 9 percent of the human "
                    "peak. Defaults (optimize/config.py): the "
                    "v2 seed design (29 actuators: the thesis layout, its gluteal group split in three, "
                    "sartorius, rectus femoris, gracilis and soleus on Gait2392's paths, gluteus "
                    "medius/minimus along the femur over a trochanter pulley, the anterior one from a bracket on "
                    "the iliac wing; the two gastrocnemii solved with their PAM on one straight segment throughout; "
                    "soleus, peroneus tertius and the long toe extensors guided by an eyelet on the talus, "
                    "[eyelets]), "
                    "a 60-unit budget over "
                    "diameters and "
                    "parallel counts, then the real bone meshes (points 3-18 mm outside their bone, pelvis and "
                    "torso points clear of their left copy, segments clear of every bone at random, "
                    "range-boundary, sweep and gait poses; rounds from the fitted and from the seed route; a "
                    "segment between two points of one bone too short ever to hold its PAM is left free of that "
                    "bone and carried round it by via points at the end: a constant length, on the tendon) "
                    "and the strain and force limits and the attachment points' contact with other bones "
                    "re-checked on 2000 more poses per actuator, then every PAM put on one straight segment "
                    "of its fixed route (resting and tendon length re-solved) where its fit allows (at any fit cost that "
                    "keeps every limit where its fit already fails both of the audit's fit limits on the "
                    "optimiser's own validation poses, or where on the segment it still passes both), or, where "
                    "that narrowly fails (fit cost, reach, or the segment a few mm short), with its points "
                    "freed again in a few bone rounds, or, where its "
                    "stroke is out of reach of any segment, on a 2:1 pulley block (3:1 where 2:1 fails), the others "
                    "named with the reason; actuators whose fit is still worst (objective > 1) get their other "
                    "diameters through the bone rounds too and keep the best, and those the stage put on a block "
                    "with a poor fit (objective > 0.5) a 3:1 block throughout (the route fitted with it); a "
                    "unit of an actuator with several that fails both audit fit limits moves to a failing one "
                    "that passes both with it; blocks come off again where "
                    "they take the estimated mass above 22 kg; then a "
                    "walking check (pressure plans of the walking trial between its frames; actuators at the "
                    "pressure limit re-sized within the budget while fewer than 90 percent are feasible); last, "
                    "each PAM on one segment is anchored at the segment (pam_on) and end (pam_at) that leave "
                    "the fewest intersecting PAM pairs where its route allows more than one; then every PAM body "
                    "that fits is hung on a rack (brackets and a guide pulley on a bone at one end of its route, "
                    "routes and torques unchanged; all bodies placed at once, 5 mm from each other and from bone "
                    "at every checked pose; [rack]); about 18 minutes "
                    "on 2 cores. "
                    "Every actuator still failing an audit fit limit on the validation poses is named "
                    "('fit limits:') with its errors beside those of its fit without the bone meshes. "
                    "examples/optimize_fast.toml is the earlier 2.5-minute fit; "
                    "examples/reference_unbuildable.toml and reference_bone_only.toml are references (the fit "
                    "without buildability limits; without the one-segment stage). Writes a run folder "
                    "(design.yaml, summary.json, log.txt, before_after.png) and audits the result next to "
                    "the thesis design (pamkin audit --quick); --apply FILE also writes the design to FILE and its "
                    "URDF beside it (atomically; only when every actuator is feasible; never into the installed "
                    "package). The run is a declared list of stages (pamkin.optimize.pipeline.STAGES); each "
                    "finished per-actuator solve is stored in the run folder as it completes, so --resume RUN "
                    "continues a killed run; --scheduler sends the solves to a Dask cluster.")
    s.add_argument("config", nargs="?", metavar="CONFIG",
                   help="TOML run description nested by stage ([first_fit], [bone_rounds], [mount], ...); every key "
                        "optional, defined with its default and range in pamkin.optimize.config (the documentation's "
                        "configuration reference; examples/optimize_v2.toml spells out every key) (default: all "
                        "defaults)")
    s.add_argument("--out", metavar="DIR", help="run folder (default: runs/<date-time> in the current folder)")
    s.add_argument("--apply", metavar="FILE",
                   help="also write the resulting design to FILE (YAML) and its URDF beside it (FILE with .urdf); "
                        "only when every actuator is feasible; use it with --design FILE (default: not written)")
    s.add_argument("--force", action="store_true",
                   help="replace an existing --out folder whole, removed before the run starts (default: a folder "
                        "holding files is refused)")
    s.add_argument("--resume", metavar="RUN",
                   help="continue the killed run in folder RUN with its own config: finished actuator solves are "
                        "read back from RUN/tasks, the rest solved (CONFIG and the overriding options are not "
                        "allowed with it; default: a new run)")
    s.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the per-actuator solves on a Dask distributed cluster, e.g. tcp://host:8786 "
                        "(needs dask[distributed]; default: --workers local processes)")
    s.add_argument("--actuators", metavar="IDS",
                   help="comma-separated actuator ids, e.g. 4,5,6 (overrides the config; default: all of the seed design)")
    s.add_argument("--workers", type=positive_int, metavar="N",
                   help="worker processes, >= 1 (overrides the config; default: the config's, 2)")
    s.add_argument("--warm-start", metavar="RUN",
                   help="run folder whose design.yaml seeds the routes and sizes; its diameters and parallel counts are "
                        "tried first, the full loop only where they fail; a PAM whose warm start holds keeps its "
                        "pulley-block ratio, and its route where the continued bone rounds would end over a strain "
                        "or force limit it keeps (overrides the config; default: none)")
    s.add_argument("--design", metavar="DESIGN",
                   help="seed design: a design file, a run folder, 'thesis', 'split_gluteal', 'v2_seed' or 'merged_seed' (overrides the config; default: "
                        "the config's, 'v2_seed')")
    s.add_argument("--quiet", action="store_true", help="no progress lines on stderr (default: progress shown)")
    s.add_argument("--no-audit", action="store_true",
                   help="skip the `pamkin audit --quick` of the result and of the thesis design "
                        "(default: both audited, the result's in a second process as soon as its design is "
                        "written; scorecards side by side, written to the run folder)")
    s.set_defaults(func=cmd_optimize)


def cmd_optimize(args: argparse.Namespace) -> int:
    from pamkin.errors import ConfigurationError  # noqa: PLC0415
    from pamkin.optimize.config import (
        config_from_dict,  # noqa: PLC0415
        load_config,  # noqa: PLC0415
    )
    from pamkin.optimize.executor import make_executor  # noqa: PLC0415
    from pamkin.optimize.pipeline import run  # noqa: PLC0415
    from pamkin.optimize.results import InfeasibleError  # noqa: PLC0415

    if args.resume:
        given = [o for o, v in (("CONFIG", args.config), ("--out", args.out), ("--actuators", args.actuators),
                                ("--warm-start", args.warm_start), ("--design", args.design)) if v]
        if given:
            raise ConfigurationError(f"--resume runs with the run's own config: {', '.join(given)} not allowed with it")
        saved = Path(args.resume) / "config.json"
        try:
            cfg = config_from_dict(json.loads(saved.read_text()), str(saved))
        except FileNotFoundError:
            raise ConfigurationError(f"--resume {args.resume}: not a run folder (no config.json)") from None
        except ValueError as e:
            raise ConfigurationError(f"{saved}: not a run's config ({e})") from None
    else:
        cfg = load_config(args.config)
    if args.actuators:
        try:
            cfg.actuators = [int(a) for a in args.actuators.split(",")]
        except ValueError:
            raise ConfigurationError(f"--actuators must be comma-separated integers, got {args.actuators!r}") from None
    if args.workers is not None:
        cfg.workers = args.workers
    if args.warm_start:
        cfg.warm_start = args.warm_start
    if args.design:
        cfg.design = args.design
    cfg.validate()
    out = Path(args.resume or args.out or Path("runs") / time.strftime("%Y%m%d-%H%M%S"))
    stream = open("/dev/null", "w") if args.quiet else sys.stderr  # noqa: SIM115
    audit = None if args.no_audit else BackgroundAudit()
    try:
        executor = make_executor(cfg.workers, args.scheduler)
        try:
            summary = run(cfg, out, apply=args.apply, stream=stream, on_design=audit.start if audit else None,
                          executor=executor, resume=bool(args.resume), force=args.force)
        finally:
            executor.close()
    except InfeasibleError as e:
        if audit is not None:
            audit.close()
        applied = f"; nothing was written to {args.apply}" if args.apply else ""
        print(f"pamkin optimize: {e}\nthe run folder {out} holds the design with these actuators as their solver "
              f"left them (design.yaml, log.txt, summary.json){applied}", file=sys.stderr)
        return 3
    except BaseException:
        if audit is not None:
            audit.close()
        raise
    audit_text = None if audit is None else audit_side_by_side(out, stream, audit)
    print_summary(summary, out, audit_text)
    return 0


class BackgroundAudit:
    """``pamkin audit --quick`` of a run folder's design in a separate process, started as soon as the
    run has written ``design.yaml`` (:func:`pamkin.optimize.pipeline.run`'s ``on_design``), so that it runs on
    the second core beside the run's own check and plot. The process is spawned, not forked (a process
    that has used OpenMP, as libigl's queries do, must not fork), and has one BLAS thread; its result is the
    same as :func:`pamkin.audit.measure.audit_design` here (the audit is deterministic). Should that process die,
    the audit is computed here instead.

    Args:
        options: The audit's options (default: :meth:`pamkin.audit.measure.AuditOptions.quick`).
    """

    def __init__(self, options=None) -> None:
        self.options = options
        self._pool = None
        self._job = None

    def _options(self):
        from pamkin.audit.measure import AuditOptions  # noqa: PLC0415

        return self.options if self.options is not None else AuditOptions.quick()

    def start(self, out_dir: Path) -> None:
        import multiprocessing as mp  # noqa: PLC0415
        from concurrent.futures import ProcessPoolExecutor  # noqa: PLC0415

        from pamkin.audit.measure import audit_design  # noqa: PLC0415
        from pamkin.optimize.executor import _worker_start  # noqa: PLC0415

        self.close()
        try:
            self._pool = ProcessPoolExecutor(1, mp_context=mp.get_context("spawn"),
                                             initializer=_worker_start)
            self._job = self._pool.submit(audit_design, Path(out_dir), options=self._options())
        except (OSError, RuntimeError):       # no second process here: result() audits in this one
            self.close()

    def result(self, out_dir: Path):
        """The audit of ``out_dir``'s design: the background one, or computed here if none was started
        (or its process died). Raises what the audit raises."""
        from concurrent.futures.process import BrokenProcessPool  # noqa: PLC0415

        from pamkin.audit.measure import audit_design  # noqa: PLC0415

        job = self._job
        try:
            if job is not None:
                return job.result()
        except BrokenProcessPool:
            pass
        finally:
            self.close()
        return audit_design(out_dir, options=self._options())

    def close(self) -> None:
        """Stop the background process (if any)."""
        if self._pool is not None:
            if self._job is not None:
                self._job.cancel()
            for proc in list((getattr(self._pool, "_processes", None) or {}).values()):
                proc.terminate()
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._pool = None
        self._job = None


def audit_side_by_side(out: Path, stream, audit: BackgroundAudit | None = None) -> str:
    """``pamkin audit --quick`` of the run's design (``audit``'s, where it was started in the background)
    and of the thesis design: the table, and both scorecards written into the run folder (``audit.json``,
    ``scorecard.txt``, ``audit_thesis.json``)."""
    import json  # noqa: PLC0415

    from pamkin.audit.scorecard import capacity_side_by_side, scorecard_text, side_by_side  # noqa: PLC0415
    from pamkin.errors import PamkinError  # noqa: PLC0415
    from pamkin.outputs import write_file  # noqa: PLC0415

    print("auditing the result and the thesis design (pamkin audit --quick) ...", file=stream, flush=True)
    try:
        thesis = thesis_quick_audit()
        res = (audit or BackgroundAudit()).result(out)
    except PamkinError as e:      # e.g. no bone meshes or walking trial on this machine: the run stands
        if audit is not None:
            audit.close()
        return f"\nAudit skipped ({e}); run pamkin audit {out} with --geometry/--ik where that data is.\n"
    write_file(out / "audit.json", json.dumps(res.to_dict(), indent=1, default=float, allow_nan=False))
    write_file(out / "audit_thesis.json", json.dumps(thesis.to_dict(), indent=1, default=float, allow_nan=False))
    write_file(out / "scorecard.txt", scorecard_text(res))
    lim = res.summary.get("gait_limiting_coordinates") or {}
    gait_line = ("Gait frames limited by (fraction within the tolerance, this run): "
                 + ", ".join(f"{c} {100 * f:.0f} %" for c, f in lim.items()) + "\n") if lim else ""
    return ("\nAudit on held-out samples (pamkin audit --quick; full: pamkin audit " + str(out) +
            " and pamkin audit thesis):\n" + side_by_side([thesis, res], ["thesis design", "this run"]) + gait_line
            + capacity_side_by_side([thesis, res], ["thesis design", "this run"]))


def _audit_inputs_key(options) -> str:
    """A digest of everything the thesis design's audit reads: the options, pamkin's source and robot data
    files (contents), the built-in URDFs, the walking-trial folder (IK angles, inverse-dynamics moments)
    and the bone-mesh files (name, size, modification time)."""
    import hashlib  # noqa: PLC0415

    import pamkin  # noqa: PLC0415
    from pamkin._resources import PACKAGE_DIR, ROBOT_DIR, SHARED_DIR, URDF_DIR  # noqa: PLC0415
    from pamkin.human.bones import find_geometry_dir  # noqa: PLC0415

    h = hashlib.sha256(repr(options).encode())
    for f in sorted(PACKAGE_DIR.rglob("*.py")) + sorted((ROBOT_DIR / "data").glob("*.yaml")):
        h.update(str(f.relative_to(f.parents[1])).encode())
        h.update(f.read_bytes())
    files = sorted(URDF_DIR.glob("*.urdf"))
    files += sorted(Path(options.gait_ik).parent.glob("*")) if options.gait_ik else []
    try:
        files += sorted(find_geometry_dir(pamkin.gait2392(), options.geometry_dir).glob("*"))
    except Exception:  # noqa: BLE001  (no meshes: the audit itself says so)
        files.append(SHARED_DIR)
    for f in files:
        st = f.stat() if f.exists() else None
        h.update(f"{f}:{st.st_size if st else -1}:{st.st_mtime_ns if st else -1}".encode())
    return h.hexdigest()[:24]


def thesis_quick_audit():
    """``pamkin audit --quick`` of the thesis design, kept in the cache folder (``$PAMKIN_CACHE``) under a
    digest of its inputs (:func:`_audit_inputs_key`): the thesis design is fixed, so every run after the
    first reuses it (~7 s); any change of code, data or options computes it again."""
    import pickle  # noqa: PLC0415

    from pamkin._resources import cache_dir  # noqa: PLC0415
    from pamkin.audit.measure import AuditOptions, audit_design  # noqa: PLC0415
    from pamkin.outputs import write_file  # noqa: PLC0415

    options = AuditOptions.quick()
    path = cache_dir() / "audit" / f"thesis_quick_{_audit_inputs_key(options)}.pickle"
    if path.exists():
        try:
            with open(path, "rb") as f:
                return pickle.load(f)
        except Exception:  # noqa: BLE001  (a damaged entry: computed again below)
            pass
    res = audit_design("thesis", options=options)
    try:
        write_file(path, pickle.dumps(res))
    except OSError:       # a read-only cache folder: the result stands
        pass
    return res


LEGEND = """\
Columns: id = actuator; PAM = its name; d x n = Festo diameter [mm] x PAMs in parallel (/k: on a k:1 pulley
block, pamkin.robot.design transmission); rest = resting
length [m]; tendon = artificial tendon [m]; NRMSE = RMS(robot - human torque) / human peak over the
primary coordinate's 1-D sweep (81 samples, independent numpy check; the progress lines' "fit NRMSE"
is the optimiser's own, on its coarser samples), before = seed design, after = optimised; 2-D = NRMSE
on the grid primary x first secondary coordinate (- : none); sign = fraction of samples where robot
and human torque agree in sign; dead = fraction of the constraint grid outside the PAM's strain range;
"""
CAPSULE_LEGEND = "clear = smallest clearance of the bone-shaft capsules beyond the PAM radius [mm]."
MESH_LEGEND = ("into bone = deepest route segment into any bone mesh at the bone-check poses [mm];\n"
               "* = not clear (a segment into bone, or a point not within 0..20 mm of its bone: listed above).")


def print_summary(summary: dict, out: Path, audit_text: str | None = None) -> None:
    """The before/after table with its legend, the totals, the audit (if given) and the next command."""
    rows = summary["actuators"]
    w = max([len(a["name"]) for a in rows] + [3])
    print(f"\nRun folder {out} ({summary['total_seconds']} s)")
    mesh = summary.get("bone_mesh")
    print(f"{'id':>3} {'PAM':{w}s} {'d x n':>8} {'rest m':>7} {'tendon m':>8} {'NRMSE before':>12} "
          f"{'after':>6} {'2-D':>6} {'sign':>5} {'dead':>5} {'into bone mm' if mesh else 'clear mm':>8}")
    for a in rows:
        two = "-" if a["nrmse_2d_after"] is None else f"{a['nrmse_2d_after']:.3f}"
        dn = f"{a['diameter_mm']}x{a['n_parallel']}" + (f"/{a['transmission']}" if a.get("transmission", 1) != 1 else "")
        if mesh:
            b = mesh.get(str(a["id"]))
            last = "-" if b is None else f"{b['max_segment_penetration_mm']:.1f}" + ("" if b["clear"] else " *")
            last = f"{last:>12}"
        else:
            last = f"{1000 * a['min_bone_clearance_m']:8.1f}"
        print(f"{a['id']:3d} {a['name']:{w}s} {dn:>8} "
              f"{a['resting_length_m']:7.3f} {a['tendon_length_m']:8.3f} {a['nrmse_before']:12.3f} "
              f"{a['nrmse_after']:6.3f} {two:>6} {a['sign_agreement']:5.2f} {a['dead_zone_fraction']:5.2f} {last}")
    print(LEGEND + (MESH_LEGEND if mesh else CAPSULE_LEGEND))
    print(f"median NRMSE {summary['median_nrmse_before']:.3f} -> {summary['median_nrmse_after']:.3f}; "
          f"{summary['n_within_0.20_after']} of {len(rows)} within 0.20; "
          f"{summary['n_halved']} halved; all buildable: {summary['all_buildable']}; "
          f"all clear of bone: {summary['all_clear_bone']}"
          + (f"; undefined NRMSE (no human torque about the primary coordinate, counted as infinite): "
             f"{', '.join(map(str, summary['undefined_nrmse']))}" if summary.get("undefined_nrmse") else "")
          + (f"; written to {summary['applied']}" if summary.get("applied") else ""))
    if audit_text:
        print(audit_text, end="")
    if summary.get("applied"):
        print(f"Next: pamkin compare --design {summary['applied']}")
    else:
        print(f"Next: pamkin compare --design {out}    (or pamkin report --design {out}; "
              "add --apply FILE to pamkin optimize to keep it as a design file)")
