"""CasADi path functions equal pamkin's numpy evaluation: straight-line paths (Gait2392: custom joints with
spline translations, conditional and moving points) and function-based paths (fitted, with and without
moment-arm functions, a coupled model)."""

from __future__ import annotations

import numpy as np
import pytest
from locations import load_model as _load
from opensim_ref import SHARED

import pamkin
from pamkin.errors import UnsupportedFeatureError
from pamkin.human.casadi_paths import path_functions
from pamkin.human.path_fit import fit_paths
from pamkin.opensim.function_path_xml import with_function_paths
from pamkin.opensim.functions import MultivariatePolynomial
from pamkin.opensim.model_file import FunctionPath

MODELS = SHARED / "opensim-models" / "Models"



def _compare(model, f, q, names=None):
    res = model.path_result(q)
    cols = [model.muscles.index(n) for n in names] if names else slice(None)
    Rd = res.dense_moment_arms(len(model.coordinates))[:, cols]
    Ls, Rs = [], []
    for k in range(len(q)):
        L, R = f(q[k])
        Ls.append(np.array(L).ravel())
        Rs.append(np.array(R))
    return np.abs(np.array(Ls) - res.lengths[:, cols]).max(), np.abs(np.array(Rs) - Rd).max()


def test_straight_paths_of_gait2392():
    model = pamkin.gait2392()
    f = path_functions(model)
    eL, eR = _compare(model, f, model.random_q(12, seed=5))
    assert eL < 1e-12 and eR < 1e-12
    # a conditional point switching: semimembranosus across its knee range, both sides of the switch
    q = np.tile(model.default_q, (40, 1))
    k = model.coordinates.index("knee_angle_r")
    q[:, k] = np.linspace(-2.09, 0.17, 40)
    eL, eR = _compare(model, f, q)
    assert eL < 1e-12 and eR < 1e-12


@pytest.mark.needs_shared
def test_fitted_paths_of_a_coupled_model(tmp_path):
    """Rajagopal2016 (patella coupled to knee angle): its fitted knee-spanning paths as CasADi functions."""
    path = MODELS / "Rajagopal" / "Rajagopal2016.osim"
    model = _load(path)
    names = ["vasint_r", "recfem_r", "bfsh_r", "soleus_r"]
    fit = fit_paths(model, names, max_order=4, n_samples=400, n_test=50)
    out = tmp_path / "raj.osim"
    out.write_text(with_function_paths(path, model.osim, fit.paths(only_passed=False)))
    fitted = _load(out)
    f = path_functions(fitted, names)
    eL, eR = _compare(fitted, f, fitted.random_q(10, seed=2), names)
    assert eL < 1e-12 and eR < 1e-11
    with pytest.raises(UnsupportedFeatureError, match="fit it first"):
        path_functions(model, ["vasint_r", "glmax1_r"])        # exact wrapped paths have no closed form


@pytest.mark.needs_shared
def test_moment_arm_functions_are_used(tmp_path):
    path = MODELS / "Gait10dof18musc" / "gait10dof18musc.osim"
    model = _load(path)
    length = MultivariatePolynomial(1, 2, (0.2, 0.03, 0.01))
    arm = MultivariatePolynomial(1, 1, (-0.03, 0.005))          # deliberately not -dl/dq
    out = tmp_path / "g.osim"
    out.write_text(with_function_paths(path, model.osim, {"vasti_r": FunctionPath(("knee_angle_r",), length,
                                                                                   (arm,))}))
    fm = _load(out)
    f = path_functions(fm, ["vasti_r", "hamstrings_r"])
    eL, eR = _compare(fm, f, fm.random_q(8, seed=1), ["vasti_r", "hamstrings_r"])
    assert eL < 1e-12 and eR < 1e-12
    L, R = f(fm.default_q)
    k = fm.coordinates.index("knee_angle_r")
    assert float(R[0, k]) == pytest.approx(float(arm.value(fm.default_q[[k]][None])[0]), abs=1e-15)
