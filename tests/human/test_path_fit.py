"""Fitted path functions: exact reproduction of polynomials, OpenSim 4.6 loads and simulates the written model
with pamkin's fitted lengths, and `pamkin fit-paths` refuses to write a fit that misses its tolerance."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from locations import load_model as _load
from opensim_ref import SHARED, opensim_reference

import pamkin
from pamkin.cli import main
from pamkin.human.path_fit import FitTolerance, fit_paths, uniform_poses
from pamkin.opensim.function_path_xml import with_function_paths

GAIT10 = SHARED / "opensim-models" / "Models" / "Gait10dof18musc" / "gait10dof18musc.osim"
pytestmark = pytest.mark.needs_shared



@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    model = _load(GAIT10)
    fit = fit_paths(model, max_order=7, n_samples=1500, n_test=300)
    path = tmp_path_factory.mktemp("fit") / "gait10_fitted.osim"
    path.write_text(with_function_paths(GAIT10, model.osim, fit.paths()))
    return model, fit, path


def test_fit_reports_held_out_errors_it_measures(fitted):
    model, fit, path = fitted
    assert len(fit.muscles) == 18 and not fit.skipped
    # the muscles with a conditional path point (iliopsoas: a length jump at hip flexion) miss
    assert {"iliopsoas_r", "iliopsoas_l"} <= {m.name for m in fit.missed}
    passed = [m for m in fit.muscles if m.passed]
    assert len(passed) >= 8
    fitted_model = _load(path)
    qt = uniform_poses(model, 300, 1)              # the held-out poses of seed 0
    exact, approx = model.path_result(qt), fitted_model.path_result(qt)
    for m in passed:
        i = model.muscles.index(m.name)
        e = approx.lengths[:, i] - exact.lengths[:, i]
        assert np.sqrt(np.mean(e ** 2)) == pytest.approx(m.length_rms, rel=1e-6, abs=1e-12)
        assert np.abs(e).max() <= m.length_max * (1 + 1e-6) <= 5e-4
    # unfitted muscles keep their exact paths
    for m in fit.missed:
        i = model.muscles.index(m.name)
        assert np.array_equal(approx.lengths[:, i], exact.lengths[:, i])


def test_refitting_a_polynomial_path_reproduces_it(fitted):
    """A path that *is* a polynomial of order <= max_order is fitted exactly (round-off)."""
    _, fit, path = fitted
    poly_model = _load(path)
    names = [m.name for m in fit.muscles if m.passed][:4]
    again = fit_paths(poly_model, names, max_order=7, n_samples=600, n_test=200,
                      tolerance=FitTolerance(1e-9, 1e-9, 1e-8))
    for m in again.muscles:
        assert m.passed and m.length_max < 1e-9 and m.moment_arm_max < 1e-8, m.name


@pytest.mark.opensim
def test_opensim_loads_the_fitted_model_with_pamkins_lengths(fitted):
    _, _, path = fitted
    fm = _load(path)
    q = fm.random_q(15, seed=5)
    ref = opensim_reference(path, q, ("lengths", "moment_arms"), pairs=fm.pairs)
    assert np.abs(fm.lengths(q) - ref["lengths"]).max() < 1e-10
    assert np.abs(fm.path_result(q).moment_arms - ref["moment_arms"]).max() < 1e-10


_SIMULATE = """
import sys, opensim as osim
osim.Logger.setLevelString("Error")
m = osim.Model(sys.argv[1])
s = m.initSystem()
m.equilibrateMuscles(s)
manager = osim.Manager(m)
manager.setIntegratorAccuracy(1e-4)
manager.initialize(s)
s = manager.integrate(0.05)
m.realizeDynamics(s)
print(s.getTime(), sum(1 for i in range(m.getMuscles().getSize())
                        if m.getMuscles().get(i).getPath().getConcreteClassName() == "FunctionBasedPath"))
"""


@pytest.mark.opensim
def test_opensim_simulates_the_fitted_model(fitted):
    _, fit, path = fitted
    proc = subprocess.run([sys.executable, "-c", _SIMULATE, str(path)], capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    t, n = proc.stdout.split()
    assert float(t) == pytest.approx(0.05) and int(n) == len(fit.paths())


def test_cli_refuses_a_fit_that_misses(tmp_path, capsys):
    out = tmp_path / "fitted.osim"
    code = main(["fit-paths", str(GAIT10), "--out", str(out), "--max-order", "4", "--samples", "600",
                 "--test-poses", "100"])
    text = capsys.readouterr().out
    assert code == 1 and not out.exists()
    assert "misses: iliopsoas_r" in text and "nothing written" in text
    code = main(["fit-paths", str(GAIT10), "--out", str(out), "--max-order", "4", "--samples", "600",
                 "--test-poses", "100", "--keep-unfitted", "--report", str(tmp_path / "rep")])
    text = capsys.readouterr().out
    assert code == 0 and out.exists() and "keep their GeometryPath" in text
    assert {p.name for p in (tmp_path / "rep").iterdir()} == {"errors.csv", "errors.md", "errors.png", "fit.json"}
    import re
    n = int(re.search(r"(\d+) FunctionBasedPaths", text).group(1))
    assert 0 < n < 18 and out.read_text().count("<FunctionBasedPath") == n


@pytest.mark.parametrize("args, message", [
    (["--max-order", "0"], "--max-order must lie in [1, 12]"),
    (["--samples", "5"], "--samples must lie in [100, 200000]"),
    (["--length-max", "-1"], "--length-max must be a positive number"),
    (["--muscles", "nope"], "has no muscle 'nope'"),
])
def test_cli_bad_requests_exit_2(args, message, tmp_path, capsys):
    code = main(["fit-paths", str(GAIT10), "--out", str(tmp_path / "x.osim"), *args])
    assert code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "x.osim").exists()


def test_poses_from_a_range_of_motion_stay_in_it():
    from pamkin.human.rom import load_rom

    model = pamkin.gait2392()
    roms = (load_rom("robot_thesis", "r"), load_rom("robot_thesis", "l"))
    q = uniform_poses(model, 500, 3, roms)
    for r in roms:
        cols = [c for c in r.coordinates if c in model.coordinates]
        assert r.contains(cols, q[:, [model.coordinates.index(c) for c in cols]]).all()
    k = model.coordinates.index("hip_flexion_l")
    lo, hi = roms[1].limits["hip_flexion_l"]
    assert q[:, k].min() < lo + 0.1 * (hi - lo) and q[:, k].max() > hi - 0.1 * (hi - lo)   # spans it
    # coordinates the range does not name keep the model's range
    j = model.coordinates.index("pelvis_tx")
    assert q[:, j].min() < -4 and q[:, j].max() > 4


def test_cli_unknown_range_of_motion_exits_2(tmp_path, capsys):
    code = main(["fit-paths", str(GAIT10), "--rom", "nope", "--out", str(tmp_path / "x.osim")])
    assert code == 2 and "no range of motion 'nope'" in capsys.readouterr().err


def test_cli_never_writes_over_the_model_and_says_when_nothing_fits(tmp_path, capsys):
    src = tmp_path / "g.osim"
    src.write_bytes(GAIT10.read_bytes())
    assert main(["fit-paths", str(src), "--out", str(src)]) == 2
    assert "is the model file itself" in capsys.readouterr().err and src.read_bytes() == GAIT10.read_bytes()
    walker = SHARED / "opensim-models" / "Models" / "WalkerModel" / "WalkerModel.osim"
    assert main(["fit-paths", str(walker), "--out", str(tmp_path / "w.osim")]) == 2
    assert "no muscle path to fit" in capsys.readouterr().err and not (tmp_path / "w.osim").exists()
