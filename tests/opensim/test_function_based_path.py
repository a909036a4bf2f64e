"""OpenSim's FunctionBasedPath read exactly: lengths and moment arms against OpenSim 4.6."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from locations import load_model as _load
from opensim_ref import SHARED, opensim_reference

from pamkin.errors import OsimError, UnsupportedFeatureError
from pamkin.opensim.function_path_xml import with_function_paths
from pamkin.opensim.functions import (
    MultivariatePolynomial,
    OneVariable,
    SimmSpline,
    polynomial_exponents,
)
from pamkin.opensim.model_file import (
    FunctionPath,
    SkippedComponentsWarning,
    load_osim_file,
)

GAIT10 = SHARED / "opensim-models" / "Models" / "Gait10dof18musc" / "gait10dof18musc.osim"
pytestmark = pytest.mark.needs_shared


def _poly(rng, dim: int, order: int, base: float) -> MultivariatePolynomial:
    n = len(polynomial_exponents(dim, order))
    c = rng.normal(scale=0.01, size=n)
    c[0] = base
    return MultivariatePolynomial(dim, order, tuple(c))


def _paths(rng) -> dict[str, FunctionPath]:
    return {
        # two coordinates, moment arms = -dl/dq
        "hamstrings_r": FunctionPath(("hip_flexion_r", "knee_angle_r"), _poly(rng, 2, 4, 0.4)),
        # the file's own moment-arm functions (OpenSim uses them, not -dl/dq)
        "vasti_r": FunctionPath(("knee_angle_r",), _poly(rng, 1, 3, 0.2), (_poly(rng, 1, 2, 0.04),)),
        # three coordinates, order 5
        "gastroc_r": FunctionPath(("knee_angle_r", "ankle_angle_r", "hip_flexion_r"), _poly(rng, 3, 5, 0.5)),
        # a scalar function of one coordinate
        "soleus_r": FunctionPath(("ankle_angle_r",), OneVariable(SimmSpline((-1.0, -0.3, 0.2, 0.9),
                                                                            (0.28, 0.27, 0.25, 0.26)))),
    }


@pytest.fixture(scope="module")
def fbp_file(tmp_path_factory):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        osim = load_osim_file(GAIT10)
    path = tmp_path_factory.mktemp("fbp") / "gait10_fbp.osim"
    path.write_text(with_function_paths(GAIT10, osim, _paths(np.random.default_rng(4))))
    return path



@pytest.mark.opensim
def test_function_based_paths_equal_opensim(fbp_file):
    model = _load(fbp_file)
    kinds = {m.name: m.function_path is not None for m in model.osim.muscles}
    assert sum(kinds.values()) == 4 and len(kinds) == 18
    q = model.random_q(25, seed=8)
    ref = opensim_reference(fbp_file, q, ("lengths", "moment_arms"), pairs=model.pairs)
    assert list(ref["muscles"]) == model.muscles
    assert np.abs(model.lengths(q) - ref["lengths"]).max() < 1e-10
    res = model.path_result(q)
    assert np.abs(res.moment_arms - ref["moment_arms"]).max() < 1e-10
    # the function-based ones span exactly their coordinates
    fb = [i for i, m in enumerate(model.osim.muscles) if m.function_path is not None]
    spanned = {(int(m), model.coordinates[c]) for m, c in model.pairs if m in fb}
    assert spanned == {(i, c) for i in fb for c in model.osim.muscles[i].function_path.coordinates}


def test_moment_arms_are_minus_the_length_gradient(fbp_file):
    """Without moment-arm functions, −∂l/∂q (central differences); with them, their values."""
    model = _load(fbp_file)
    q = model.random_q(6, seed=2)
    R = model.moment_arms(q)
    h = 1e-6
    for name in ("hamstrings_r", "gastroc_r", "soleus_r"):
        m = model.muscles.index(name)
        for c in model.osim.muscles[m].function_path.coordinates:
            j = model.coordinates.index(c)
            qp, qm = q.copy(), q.copy()
            qp[:, j] += h
            qm[:, j] -= h
            fd = -(model.lengths(qp)[:, m] - model.lengths(qm)[:, m]) / (2 * h)
            assert np.abs(R[:, m, j] - fd).max() < 1e-8, (name, c)
    v = model.muscles.index("vasti_r")
    k = model.coordinates.index("knee_angle_r")
    arm = model.osim.muscles[v].function_path.moment_arms[0]
    assert np.allclose(R[:, v, k], arm.value(q[:, [k]]), rtol=0, atol=1e-15)


def test_polynomial_term_order_is_opensims():
    """OpenSim's documented table for (X, Y, Z), order 3: index 6 is Y·Z², index 15 is X·Y²."""
    e = polynomial_exponents(3, 3)
    assert len(e) == 20
    assert tuple(e[6]) == (0, 1, 2) and tuple(e[15]) == (1, 2, 0) and tuple(e[19]) == (3, 0, 0)
    p = MultivariatePolynomial(3, 3, tuple(np.arange(1.0, 21.0)))
    x = np.array([[2.0, 3.0, 5.0]])
    assert p.value(x)[0] == 4393.0                   # hand sum of c_k * terms
    assert np.allclose(p.gradient(x), [[1703.0, 1244.0, 1087.0]], rtol=0, atol=1e-12)


def test_model_data_round_trip_keeps_function_paths(fbp_file):
    from pamkin.opensim.model_file import model_from_dict, model_to_dict
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        osim = load_osim_file(fbp_file)
    back = model_from_dict(model_to_dict(osim))
    assert [m.function_path for m in back.muscles] == [m.function_path for m in osim.muscles]


def _edit(fbp_file, tmp_path, old, new):
    text = fbp_file.read_text()
    assert old in text
    p = tmp_path / "bad.osim"
    p.write_text(text.replace(old, new, 1))
    return p


def test_bad_function_based_paths_name_the_element(fbp_file, tmp_path):
    cases = [
        ("<dimension>2</dimension>", "<dimension>3</dimension>", OsimError, "dimension 3 for 2 coordinate"),
        ("/jointset/knee_r/knee_angle_r</coordinate_paths>", "/jointset/knee_r/knee_nope</coordinate_paths>",
         OsimError, "unknown coordinate 'knee_nope'"),
        ("<order>4</order>", "<order>5</order>", OsimError, "needs 21 coefficients, has 15"),
    ]
    for old, new, cls, msg in cases:
        with pytest.raises(cls) as e:
            load_osim_file(_edit(fbp_file, tmp_path, old, new))
        assert msg in str(e.value) and 'name="hamstrings_r"' in str(e.value) and "bad.osim" in str(e.value)
    # a scalar function cannot take two coordinates
    text = fbp_file.read_text()
    i = text.index('name="hamstrings_r"')
    a = text.index("<length_function>", i)
    b = text.index("</length_function>", a)
    p = tmp_path / "bad2.osim"
    p.write_text(text[:a] + "<length_function><Constant><value>0.3</value></Constant>" + text[b:])
    with pytest.raises(UnsupportedFeatureError, match=r"<Constant> of 2 coordinates is not supported"):
        load_osim_file(p)


def test_unknown_path_class_is_named(fbp_file, tmp_path):
    text = fbp_file.read_text()
    i = text.index('name="hamstrings_r"')
    a = text.index("<FunctionBasedPath", i)
    b = text.index("</FunctionBasedPath>", a) + len("</FunctionBasedPath>")
    p = tmp_path / "bad3.osim"
    p.write_text(text[:a] + '<Scholz2015GeometryPath name="path"/>' + text[b:])
    with pytest.raises(UnsupportedFeatureError, match=r"path class <Scholz2015GeometryPath> is not supported") as e:
        load_osim_file(p)
    assert 'name="hamstrings_r"' in str(e.value)


@pytest.mark.opensim
def test_a_model_written_by_opensims_own_fitter(tmp_path):
    """OpenSim 4.6's PolynomialPathFitter + ModOpReplacePathsWithFunctionBasedPaths: pamkin reads the result and
    agrees with OpenSim on it to 1e-10 m."""
    import subprocess
    import sys

    from locations import ROOT

    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "opensim_path_fitter.py"), str(GAIT10),
                           str(tmp_path / "fit"), "2", "40", "3"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    path = tmp_path / "fit" / "fitted.osim"
    model = _load(path)
    assert all(m.function_path is not None for m in model.osim.muscles)
    q = model.random_q(20, seed=9)
    ref = opensim_reference(path, q, ("lengths", "moment_arms"), pairs=model.pairs)
    assert np.abs(model.lengths(q) - ref["lengths"]).max() < 1e-10
    assert np.abs(model.path_result(q).moment_arms - ref["moment_arms"]).max() < 1e-10
