"""The package's architecture, checked on its source: no import cycles (between modules or between
subpackages), subpackages layered one way, and imports of pamkin's own modules at module level."""

from __future__ import annotations

from architecture import cycles, graph, imports, modules

#: Subpackages from the bottom up: each may import only those before it (and the shared top-level
#: modules ``pamkin.errors``, ``pamkin._resources``, ``pamkin.yamlio``, ``pamkin.outputs``).
LAYERS = ["pamkin.opensim", "pamkin.muscles", "pamkin.human", "pamkin.robot", "pamkin.gait", "pamkin.audit",
          "pamkin.viz", "pamkin.build", "pamkin.sim", "pamkin.optimize", "pamkin.cli"]
SHARED = {"pamkin.errors", "pamkin._resources", "pamkin.yamlio", "pamkin.outputs"}
#: Where a function may import one of pamkin's modules: the command line imports a command's modules
#: when the command runs (``pamkin --help`` stays fast) ...
LAZY_ALLOWED = ("pamkin.cli",)
#: ... and the optimiser's CasADi modules load only where a solve needs them (OpenSim and CasADi cannot share
#: a process: a library user who never solves never loads CasADi).
CASADI_MODULES = {"pamkin.optimize.problem", "pamkin.optimize.bracket", "pamkin.optimize.mount",
                  "pamkin.optimize.roller_model", "pamkin.optimize.rollers"}


def _package(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 else module


def test_no_import_cycle_between_modules():
    assert cycles(graph()) == []


def test_no_import_cycle_between_subpackages():
    packages: dict[str, set[str]] = {}
    for module, targets in graph().items():
        packages.setdefault(_package(module), set()).update(
            _package(t) for t in targets if _package(t) != _package(module))
    assert cycles(packages) == []


def test_subpackages_import_only_the_layers_below_them():
    wrong = []
    for module, targets in graph().items():
        pkg = _package(module)
        if pkg not in LAYERS:
            continue
        below = set(LAYERS[: LAYERS.index(pkg)]) | SHARED | {pkg}
        wrong += [f"{module} -> {t}" for t in sorted(targets) if _package(t) not in below and t not in SHARED]
    assert wrong == []


def test_library_modules_import_pamkin_modules_at_module_level():
    known = modules()
    nested = [f"{m}:{line} imports {t}" for m, path in sorted(known.items()) if not m.startswith(LAZY_ALLOWED)
              for t, line, inside in imports(m, path, known) if inside and t not in CASADI_MODULES]
    assert nested == []


def test_the_graph_sees_real_imports():
    """The checker itself: the model imports its kinematics; the CLI reaches the optimiser."""
    g = graph()
    assert "pamkin.human.kinematics" in g["pamkin.human.model"]
    assert any(t.startswith("pamkin.optimize") for t in g["pamkin.cli.optimize"])


def test_importing_the_optimiser_does_not_load_casadi():
    """The run's modules import without CasADi (it loads in the processes that solve)."""
    import subprocess  # noqa: PLC0415
    import sys  # noqa: PLC0415

    code = ("import sys, pamkin.optimize.pipeline, pamkin.cli; "
            "assert 'casadi' not in sys.modules, sorted(m for m in sys.modules if 'casadi' in m)")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).returncode == 0
