"""Wheel smoke test (CI): run every ``pamkin`` command once from a folder outside the checkout.

    <clean venv>/bin/python .ci/smoke_wheel.py --shared ../shared

Run with the Python of a virtual environment into which only the built wheel was installed. The
commands are discovered from the installed parser (``pamkin.cli.build_parser``), so a new command
is smoke-tested as soon as it exists: each gets ``--help`` and a real, quick invocation from
:data:`QUICK` (a command without one fails the test: add it there). Everything runs in a temporary
folder with ``PAMKIN_CACHE``, ``MPLCONFIGDIR`` and ``NUMBA_CACHE_DIR`` inside it.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHECKOUT = Path(__file__).resolve().parents[1]

QUICK_CONFIG = """\
# a small optimisation: one actuator, one diameter, few samples
actuators = [16]
workers = 1
[first_fit]
diameters_mm = [20]
max_parallel = 1
multistart = 0
max_iter = 200
[samples]
primary = 9
secondary = 3
constraint = 3
"""

#: A quick real invocation of each command ({osim}, {geometry}, {shared}, {config} are filled in);
#: and the exit codes that count as success (audit exits 1 when a design limit fails).
QUICK: dict[str, tuple[list[list[str]], tuple[int, ...]]] = {
    "info": ([["info"], ["info", "--osim", "{osim}"], ["info", "--json"]], (0,)),
    "torques": ([["torques", "-n", "3"]], (0,)),
    "size": ([["size"], ["size", "--method", "constrained", "--design", "thesis"]], (0,)),
    "compare": ([["compare", "-n", "5"]], (0,)),
    "optimize": ([["optimize", "{config}", "--out", "run", "--quiet"]], (0,)),
    "view": ([["view", "--html", "view.html", "--geometry", "{geometry}"], ["view", "--html", "v2.html",
                                                                           "--no-meshes"]], (0,)),
    "report": ([["report", "--design", "run", "--pams", "16", "-n", "5", "--n1", "11", "--out", "report"]], (0,)),
    "export-osim": ([["export-osim", "robot", "--out", "robot.osim"], ["info", "--osim", "robot.osim"]], (0,)),
    "urdf": ([["urdf", "--check", "--osim", "{osim}"]], (0,)),
    "gait": ([["gait", "--out", "gait"]], (0,)),
    "audit": ([["audit", "--quick", "--random", "40", "--ik", "none", "--no-gait-plan"]], (0, 1)),
    "build": ([["build", "thesis", "--out", "build"], ["build", "run", "--out", "build-run"]], (0,)),
    "fit-paths": ([["fit-paths", "{shared}/opensim-models/Models/Gait10dof18musc/gait10dof18musc.osim",
                    "--out", "fitted.osim", "--max-order", "4", "--samples", "400", "--test-poses", "50",
                    "--keep-unfitted", "--report", "fit-report"], ["info", "--osim", "fitted.osim"]], (0,)),
    "mjcf": ([["mjcf", "--out", "mjcf"], ["mjcf", "--design", "thesis", "--out", "mjcf-robot", "--measure", "20"]],
             (0,)),
    "simulate": ([["simulate", "--mode", "stand", "--duration", "0.2", "--out", "stand"]], (0,)),
}


def run(cmd: list[str], cwd: Path, env: dict, ok=(0,), stdin=None) -> subprocess.CompletedProcess:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, input=stdin)
    dt = time.perf_counter() - t0
    print(f"  {' '.join(cmd)}  -> exit {p.returncode} ({dt:.1f} s)", flush=True)
    if p.returncode not in ok or "Traceback" in p.stderr:
        print(p.stdout[-3000:], p.stderr[-3000:], sep="\n", file=sys.stderr)
        raise SystemExit(f"smoke test failed: {' '.join(cmd)}")
    return p


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shared", default=str(CHECKOUT.parent / "shared"),
                    help="the reference data folder (default: ../shared beside the checkout)")
    args = ap.parse_args()
    shared = Path(args.shared).resolve()
    osim = shared / "opensim-models" / "Gait2392_Simbody" / "gait2392_thelen2003muscle.osim"
    geometry = shared / "opensim-models" / "Geometry"
    bindir = Path(sys.executable).parent
    pamkin = str(bindir / "pamkin")
    with tempfile.TemporaryDirectory(prefix="pamkin-wheel-smoke-") as tmp:
        work = Path(tmp)
        env = dict(os.environ, PAMKIN_CACHE=str(work / "cache"), MPLCONFIGDIR=str(work / "mpl"),
                   NUMBA_CACHE_DIR=str(work / "numba"), PAMKIN_SHARED=str(shared))
        env.pop("PYTHONPATH", None)
        env.pop("PAMKIN_ROBOT_DIR", None)
        (work / "quick.toml").write_text(QUICK_CONFIG)
        # the installed package, not the checkout; no top-level 'optimize'; the data inside the package
        probe = run([sys.executable, "-c", (
            "import importlib.util, pamkin, pamkin.optimize.pipeline, pamkin.optimize.stages.walking, pamkin._resources as r;"
            "assert importlib.util.find_spec('optimize') is None, 'a top-level optimize package is installed';"
            "m = pamkin.gait2392(); assert len(m.muscles) == 92;"
            "print(pamkin.__file__); print(r.ROBOT_DIR); print(r.URDF_DIR);"
            "assert len(list(r.MESH_DIR.glob('*.stl'))) == 19")], work, env)
        for line in probe.stdout.split():
            if Path(line).resolve().is_relative_to(CHECKOUT):
                raise SystemExit(f"smoke test failed: {line} lies in the checkout, not the installed wheel")
        print(f"installed package: {probe.stdout.split()[0]}")
        run([pamkin, "--version"], work, env)
        run([pamkin, "--help"], work, env)
        from pamkin.cli import build_parser  # noqa: PLC0415  (this interpreter's: the installed wheel)

        sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
        commands = list(sub.choices)
        print(f"commands: {', '.join(commands)}")
        missing = [c for c in commands if c not in QUICK]
        fill = {"osim": str(osim), "geometry": str(geometry), "shared": str(shared),
                "config": str(work / "quick.toml")}
        for c in commands:
            print(f"pamkin {c}")
            run([pamkin, c, "--help"], work, env)
            if c in missing:
                continue
            calls, ok = QUICK[c]
            for call in calls:
                run([pamkin, *(a.format(**fill) for a in call)], work, env, ok=ok)
        # a closed pipe is not an error (pamkin info | head -1)
        p = subprocess.run(f"'{pamkin}' info | head -1", shell=True, cwd=work, env=env, capture_output=True,
                           text=True)
        if p.stderr:
            raise SystemExit(f"smoke test failed: 'pamkin info | head -1' wrote to stderr:\n{p.stderr}")
        if missing:
            raise SystemExit(f"smoke test failed: no quick invocation for {missing}: add one to QUICK in "
                             f"{Path(__file__).name}")
    print("wheel smoke test passed: every command ran from outside the checkout")


if __name__ == "__main__":
    main()
