"""The command line and library never surprise: bad input is a clear pamkin error (exit 2, naming the
file and key), never a traceback; help, defaults and --version; export-osim round trip."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import pamkin
from pamkin.cli import build_parser, main
from pamkin.errors import ConfigurationError, DataFileError, ParameterError
from locations import ROOT



# ------------------------------------------------------------------ pamkin optimize: the TOML config
def _optimize_config_error(tmp_path, capsys, text: str) -> str:
    """Run ``pamkin optimize`` on a config; it must fail before any work with exit 2; return stderr."""
    cfg = tmp_path / "run.toml"
    cfg.write_text(text)
    code = main(["optimize", str(cfg), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert str(cfg) in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
    return err


def test_config_negative_weight(tmp_path, capsys):
    err = _optimize_config_error(tmp_path, capsys, "[weights]\nsecondary = -0.5\n")
    assert "weights.secondary: must be >= 0, got -0.5" in err


def test_config_pressure_in_bar_not_pascal(tmp_path, capsys):
    err = _optimize_config_error(tmp_path, capsys, "pressure_Pa = 6.2\n")
    assert "pressure_Pa: must lie in [100000, 800000] Pa" in err and "got 6.2" in err


def test_config_bone_clearance_not_boolean(tmp_path, capsys):
    err = _optimize_config_error(tmp_path, capsys, '[limits]\nbone_clearance = "no"\n')
    assert "limits.bone_clearance: must be true or false, got 'no'" in err


def test_config_region_key_names_no_actuator(tmp_path, capsys):
    err = _optimize_config_error(tmp_path, capsys, '[regions]\n"99" = 0.02\n')
    assert "regions.99: names no actuator" in err


def test_config_region_key_names_no_point(tmp_path, capsys):
    err = _optimize_config_error(tmp_path, capsys, '[regions]\n"6.p9" = 0.02\n')
    assert "regions.6.p9: actuator 6 has no point 'p9'" in err


def test_config_region_key_malformed(tmp_path, capsys):
    err = _optimize_config_error(tmp_path, capsys, '[regions]\n"knee" = 0.02\n')
    assert "regions.knee" in err


def test_config_multistart_not_integer(tmp_path, capsys):
    err = _optimize_config_error(tmp_path, capsys, '[first_fit]\nmultistart = "three"\n')
    assert "multistart: must be an integer, got 'three'" in err


def test_config_diameters_not_a_list(tmp_path, capsys):
    err = _optimize_config_error(tmp_path, capsys, "[first_fit]\ndiameters_mm = 20\n")
    assert "diameters_mm: must be a list of integers" in err


def test_config_max_iter_not_integer(tmp_path, capsys):
    err = _optimize_config_error(tmp_path, capsys, "[first_fit]\nmax_iter = 2.5\n")
    assert "max_iter: must be an integer, got 2.5" in err


def test_config_type_checks_also_apply_to_programmatic_configs():
    from pamkin.optimize.config import RunConfig

    with pytest.raises(DataFileError, match="workers: must be an integer"):
        RunConfig().replace({"workers": True}).validate()
    with pytest.raises(DataFileError, match="limits.kmax_scale"):
        RunConfig().replace({"limits.kmax_scale": 1.5}).validate()


def test_workers_zero_is_an_error(capsys):
    with pytest.raises(SystemExit) as e:
        main(["optimize", "--workers", "0"])
    assert e.value.code == 2
    assert "--workers: must be an integer >= 1, got '0'" in capsys.readouterr().err


# ------------------------------------------------------------------ no traceback reaches a user
def test_broken_pipe_exits_quietly(tmp_path):
    env = dict(os.environ, PYTHONUNBUFFERED="0")
    p = subprocess.run(f"{sys.executable} -m pamkin.cli info | head -1", shell=True, capture_output=True,
                       text=True, env=env, cwd=tmp_path, timeout=300)
    assert p.stdout.startswith("3DGaitModel2392")
    assert p.stderr == "", p.stderr


def test_broken_pipe_in_main_returns_zero(monkeypatch):
    class Closed:
        def write(self, s):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            raise BrokenPipeError(32, "Broken pipe")

        def fileno(self):
            raise ValueError("no file")

    monkeypatch.setattr(sys, "stdout", Closed())
    assert main(["info"]) == 0


def test_negative_max_isometric_force_names_file_and_plain_number(tmp_path, gait2392_path, capsys):
    src = gait2392_path.read_text()
    start = src.index("<max_isometric_force>") + len("<max_isometric_force>")
    end = src.index("</max_isometric_force>")
    bad = tmp_path / "bad_force.osim"
    bad.write_text(src[:start] + "-100" + src[end:])
    with pytest.raises(ParameterError) as e:
        pamkin.load_osim(bad)
    msg = str(e.value)
    assert str(bad) in msg and "max_isometric_force must be > 0 N (got -100)" in msg
    assert "np.float64" not in msg
    # and through the command line: exit 2, one line naming the file
    capsys.readouterr()
    assert main(["info", "--osim", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err and "(got -100)" in err


@pytest.fixture(scope="module")
def human():
    return pamkin.gait2392()


def test_point_jacobian_unknown_body(human):
    with pytest.raises(ConfigurationError, match="unknown body 'femur'"):
        human.point_jacobian(np.zeros(23), "femur", [0.0, 0.0, 0.0])


def test_point_jacobian_point_of_two_numbers(human):
    with pytest.raises(ConfigurationError, match="point must be 3 finite numbers"):
        human.point_jacobian(np.zeros(23), "femur_r", [0.0, 0.1])


def test_activation_outside_unit_interval_is_an_error(human):
    q = np.zeros((2, 23))
    for bad in (1.5, -0.2):
        with pytest.raises(ConfigurationError, match=r"activation must lie in \[0, 1\]"):
            human.tendon_forces(q, activation=bad)
    assert np.all(human.tendon_forces(q, activation=0.0) >= 0)    # 0 is allowed (raised to 0.01 as OpenSim)


def test_activation_outside_unit_interval_cli(capsys):
    assert main(["torques", "--activation", "1.2", "-n", "2"]) == 2
    assert "activation" in capsys.readouterr().err


# ------------------------------------------------------------------ help, defaults, version, info
def _subcommands():
    p = build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return p, sub


#: Options allowed to state no default (none today).
PENDING: set[str] = set()


def test_every_subcommand_and_option_has_help_and_default():
    _, sub = _subcommands()
    helps = {a.dest: a.help for a in sub._choices_actions}
    problems = []
    for name, sp in sub.choices.items():
        if not helps.get(name):
            problems.append(f"{name}: no help in the command list")
        if not sp.description:
            problems.append(f"{name}: no description")
        for a in sp._actions:
            if isinstance(a, argparse._HelpAction):
                continue
            opt = a.option_strings[0] if a.option_strings else a.dest
            h = a.help or ""
            if not h:
                problems.append(f"{name} {opt}: no help")
                continue
            positional_required = not a.option_strings and a.nargs is None
            if not positional_required and not a.required and "default" not in h \
                    and f"{name} {opt}" not in PENDING:
                problems.append(f"{name} {opt}: help states no default")
    assert problems == []


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"pamkin {pamkin.__version__}"


def test_info_lists_muscles_with_units(capsys):
    assert main(["info"]) == 0
    out = capsys.readouterr().out
    assert "rotations in degrees, translations in metres" in out
    assert "max isometric force [N]" in out
    assert "knee_angle_r" in out and " deg" in out and " m\n" in out
    assert "semimem_r" in out and "1288" in out


# ------------------------------------------------------------------ export-osim round trip
def test_export_osim_loads_back_into_pamkin(tmp_path, capsys):
    from pamkin.robot.biped import design_robot

    out = tmp_path / "robot.osim"
    assert main(["export-osim", "robot", "--out", str(out)]) == 0
    model = pamkin.load_osim(out)
    robot = design_robot(None)
    assert sorted(model.muscles) == sorted(robot.names)                  # 54 PathActuator routes
    assert {m.kind for m in model.osim.muscles} == {"PathActuator"}
    assert all(m.params["optimal_force"] > 0 and m.params["max_control"] == 1.0 for m in model.osim.muscles)
    q = model.random_q(25, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        qd = {c: q[:, i] for i, c in enumerate(model.coordinates)}
        idx = [model.muscles.index(n) for n in robot.names]
        np.testing.assert_allclose(model.lengths(qd)[:, idx], robot.evaluate(qd).lengths, atol=1e-12)
        R = model.moment_arms(qd)[:, idx]
        Rr = robot.evaluate(qd).moment_arms
        ci = [model.coordinates.index(c) for c in robot.coordinates]
        np.testing.assert_allclose(R[:, :, ci], Rr, atol=1e-10)
    # PathActuator forces: optimal force x control (the activation argument), as OpenSim's computeActuation
    F = model.tendon_forces(q[:2], activation=0.5)
    assert np.allclose(F, 0.5 * np.array([m.params["optimal_force"] for m in model.osim.muscles]), rtol=1e-15)


def test_tests_write_no_cache_outside_checkout_and_temp():
    import tempfile

    cache = Path(os.environ["PAMKIN_CACHE"]).resolve()
    from pamkin._resources import cache_dir

    assert cache_dir().resolve() == cache
    inside = [Path(tempfile.gettempdir()).resolve(), ROOT.resolve()]
    assert any(cache.is_relative_to(p) for p in inside), cache


def test_thesis_quick_audit_is_cached_by_its_inputs(tmp_path, monkeypatch):
    """`pamkin optimize` audits the thesis design once per set of inputs: the second call reads the cache
    (no audit), other options give another key, and a damaged entry is computed again."""
    import pamkin.audit.measure
    from pamkin.audit.measure import AuditOptions
    from pamkin.cli import optimize as cli_opt

    monkeypatch.setenv("PAMKIN_CACHE", str(tmp_path))
    calls = []

    def fake(design, options=None):
        calls.append((design, options))
        return {"design": design, "n_random": options.n_random}

    monkeypatch.setattr(pamkin.audit.measure, "audit_design", fake)
    first = cli_opt.thesis_quick_audit()
    assert first == {"design": "thesis", "n_random": 500} and len(calls) == 1
    assert cli_opt.thesis_quick_audit() == first and len(calls) == 1            # from the cache
    entries = list((tmp_path / "audit").glob("thesis_quick_*.pickle"))
    assert len(entries) == 1
    assert cli_opt._audit_inputs_key(AuditOptions.quick()) != cli_opt._audit_inputs_key(AuditOptions.quick(n_random=501))
    entries[0].write_bytes(b"not a pickle")
    assert cli_opt.thesis_quick_audit() == first and len(calls) == 2            # damaged: computed again


def _untimed(audit) -> str:
    """An audit's dictionary as JSON without its run time."""
    import json

    d = audit.to_dict()
    d.pop("seconds", None)
    return json.dumps(d, default=float, sort_keys=True)


def test_background_audit_equals_the_audit_in_this_process(tmp_path, monkeypatch):
    """`pamkin optimize` audits its result in a forked process beside its own check and plot: the same
    audit as in this process (a small audit of the thesis design's routes, every part but the gait plan);
    an error in that process reaches the command as the same pamkin error (the run then says the audit was
    skipped), a process that dies leaves the audit to this one, and a run that fails stops it."""
    from pamkin.audit.measure import AuditOptions, audit_design
    from pamkin.cli import optimize as cli_opt
    from pamkin.robot.design import load_design, save_design

    small = AuditOptions(n_random=120, gait_ik=None, gait_plan=False, n_geometry=20, n_sweep=11, n_grid=5,
                         segment_step_m=0.01)
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    save_design(load_design("thesis"), run_dir / "design.yaml")
    try:
        direct = audit_design(run_dir, options=small)
    except DataFileError as e:
        pytest.skip(f"no bone meshes here: {e}")
    bg = cli_opt.BackgroundAudit(small)
    bg.start(run_dir)
    res = bg.result(run_dir)
    assert bg._pool is None                                   # the process is gone
    assert _untimed(res) == _untimed(direct)
    empty = tmp_path / "empty"
    empty.mkdir()
    bg.start(empty)                                           # no design.yaml: a DataFileError over there
    with pytest.raises(DataFileError, match="design.yaml"):
        bg.result(empty)
    bg.start(empty)
    monkeypatch.setattr(cli_opt, "thesis_quick_audit", lambda: direct)
    with open(os.devnull, "w") as quiet:
        text = cli_opt.audit_side_by_side(empty, quiet, bg)
    assert text.startswith("\nAudit skipped (") and "design.yaml" in text and bg._pool is None
    bg.start(run_dir)
    for proc in list(bg._pool._processes.values()):       # the process dies: audited here instead
        proc.kill()
    res = bg.result(run_dir)
    assert _untimed(res) == _untimed(direct)
    bg.start(run_dir)
    bg.close()
    assert bg._pool is None and bg._job is None


def test_pamkin_errors_cross_process_boundaries():
    """Every pamkin error pickles with its type, message and attributes (an error raised in a worker or in
    the background audit reaches the command intact, instead of breaking the process pool)."""
    import pickle

    from pamkin.errors import OsimError, StorageFileError, UnsupportedFeatureError

    for err in (StorageFileError("/a/trial.mot", "file not found", column="knee_angle_r"),
                UnsupportedFeatureError("/m.osim", "not supported", element="Ligament"),
                OsimError("/m.osim", "bad value", element="Body"), DataFileError("/d.yaml", "missing key"),
                ConfigurationError("bad key")):
        back = pickle.loads(pickle.dumps(err))
        assert type(back) is type(err) and str(back) == str(err) and back.__dict__ == err.__dict__
