"""Tests of :mod:`pamkin.muscles.thelen2003`: curves by hand, properties, and OpenSim 4.6 itself.

The OpenSim comparison never imports ``opensim`` here: :func:`opensim_reference` runs
it in a child process. Tolerances (from the brief): tendon force within 1e-4 relative
or 1e-3 N absolute; fibre length within 1e-8 m (OpenSim's own Newton tolerance is
1e-8·Fmax on force, which is ~1e-10 m of fibre length on Gait2392).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from opensim_ref import GAIT2392, opensim_reference

from pamkin.errors import ConfigurationError, ParameterError, UnsupportedFeatureError
from pamkin.muscles.thelen2003 import (
    Equilibrium,
    ThelenParams,
    equilibrium,
    force_length_active,
    force_length_passive,
    minimum_fiber_length,
    params_from_osim_xml,
    tendon_force,
    tendon_force_length,
)

E3 = math.exp(3.0)

# Gait2392's curve constants (every muscle has these).
GAIT_CURVES = dict(fmax_tendon_strain=0.033, fmax_muscle_strain=0.6, kshape_active=0.5,
                   kshape_passive=4.0)


def one_muscle(fmax=1000.0, l0=0.1, lts=0.2, alpha0=0.0, **kw) -> ThelenParams:
    curves = {**GAIT_CURVES, **kw}
    return ThelenParams(max_isometric_force=[fmax], optimal_fiber_length=[l0],
                        tendon_slack_length=[lts], pennation_angle_at_optimal=[alpha0],
                        names=("m",), **curves)


# ----------------------------------------------------------------------------------------------
# Curves against hand calculations
# ----------------------------------------------------------------------------------------------


def test_active_force_length_by_hand():
    assert force_length_active(1.0, 0.45) == 1.0
    assert force_length_active(1.5, 0.45) == pytest.approx(math.exp(-0.25 / 0.45), rel=1e-15)
    assert force_length_active(0.5, 0.5) == pytest.approx(math.exp(-0.5), rel=1e-15)
    assert force_length_active(0.0, 0.5) == pytest.approx(math.exp(-2.0), rel=1e-15)


def test_passive_force_length_by_hand():
    assert force_length_passive(np.array([0.0, 0.5, 1.0]), 0.6, 5.0).tolist() == [0.0, 0.0, 0.0]
    assert force_length_passive(1.6, 0.6, 5.0) == pytest.approx(1.0, rel=1e-14)  # fPE(1+e0M)=1
    by_hand = (math.exp(2.5) - 1.0) / (math.exp(5.0) - 1.0)  # lM/l0 = 1.3: kPE·0.3/0.6 = 2.5
    assert force_length_passive(1.3, 0.6, 5.0) == pytest.approx(by_hand, rel=1e-14)
    assert by_hand == pytest.approx(0.075858, abs=1e-6)


def test_tendon_force_length_by_hand():
    e0 = 0.033
    e_toe = 99 * e0 * E3 / (166 * E3 - 67)
    assert e_toe / e0 == pytest.approx(0.6086, abs=1e-4)  # Thelen's rounded "0.609·e0"
    k_lin = 0.67 / (e0 - e_toe)
    f = lambda e: float(tendon_force_length(1.0 + e, e0))  # noqa: E731
    assert f(-0.1) == 0.0 and f(0.0) == 0.0
    assert f(e_toe) == pytest.approx(0.33, rel=1e-14)
    assert f(e0) == pytest.approx(1.0, rel=1e-14)  # fT = 1 at FmaxTendonStrain
    assert f(0.5 * e_toe) == pytest.approx(0.33 * (math.exp(1.5) - 1) / (E3 - 1), rel=1e-14)
    assert f(3 * e0) == pytest.approx(0.33 + k_lin * (3 * e0 - e_toe), rel=1e-14)
    # value and slope are continuous at the end of the toe region
    d = 1e-7
    left = (f(e_toe) - f(e_toe - d)) / d
    assert left == pytest.approx(k_lin, rel=1e-5)
    assert f(e_toe + d) - f(e_toe) == pytest.approx(k_lin * d, rel=1e-6)


def test_minimum_fiber_length():
    p = ThelenParams(max_isometric_force=[1.0, 1.0], optimal_fiber_length=[0.1, 0.1],
                     tendon_slack_length=[0.2, 0.2], pennation_angle_at_optimal=[0.0, 0.3],
                     **GAIT_CURVES)
    # unpennated: 0 (no other bound in OpenSim 4.6); pennated: h / sin(acos(0.1))
    np.testing.assert_allclose(minimum_fiber_length(p),
                               [0.0, 0.1 * math.sin(0.3) / math.sqrt(1 - 0.01)], rtol=1e-15)


# ----------------------------------------------------------------------------------------------
# Equilibrium against hand calculations
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("alpha0", [0.0, 0.3])
def test_equilibrium_with_fiber_at_optimal_length(alpha0):
    """Choose lMT so that the fibre sits at l0: fibre force along the tendon is cos(alpha0)·Fmax,
    so the tendon strain must be the one where fT = cos(alpha0) (linear region)."""
    l0, lts, e0, fmax = 0.1, 0.2, 0.033, 1000.0
    e_toe = 99 * e0 * E3 / (166 * E3 - 67)
    strain = e_toe + (math.cos(alpha0) - 0.33) * (e0 - e_toe) / 0.67
    lmt = l0 * math.cos(alpha0) + lts * (1 + strain)
    eq = equilibrium(np.array([[lmt]]), one_muscle(fmax, l0, lts, alpha0))
    assert eq.fiber_length[0, 0] == pytest.approx(l0, rel=1e-12)
    assert eq.pennation_angle[0, 0] == pytest.approx(alpha0, abs=1e-12)
    assert eq.tendon_force[0, 0] == pytest.approx(fmax * math.cos(alpha0), rel=1e-10)
    assert eq.active_fiber_force[0, 0] == pytest.approx(fmax, rel=1e-10)
    assert eq.passive_fiber_force[0, 0] == pytest.approx(0.0, abs=1e-9 * fmax)
    assert not eq.clamped[0, 0]


def test_slack_muscle_is_clamped_with_zero_force():
    p = one_muscle(alpha0=0.3)
    lmin = minimum_fiber_length(p)[0]
    lmt = np.array([[0.19], [0.2 + 0.999 * lmin * 0.1]])  # shorter than lTs + lmin·cos(alpha_max)
    eq = equilibrium(lmt, p)
    assert eq.clamped.all()
    np.testing.assert_array_equal(eq.tendon_force, 0.0)
    np.testing.assert_array_equal(eq.fiber_length, lmin)
    np.testing.assert_allclose(eq.pennation_angle, math.acos(0.1), rtol=1e-15)
    np.testing.assert_array_equal(eq.active_fiber_force, 0.0)


def test_rigid_tendon_by_hand():
    fmax, l0, lts, alpha0 = 800.0, 0.1, 0.2, 0.3
    p = one_muscle(fmax, l0, lts, alpha0)
    h = l0 * math.sin(alpha0)
    x = 0.13  # fibre length along the tendon
    lm = math.hypot(x, h)
    n = lm / l0
    by_hand = fmax * (math.exp(-((n - 1) ** 2) / 0.5)
                      + (math.exp(4 * (n - 1) / 0.6) - 1) / (math.exp(4) - 1)) * x / lm
    eq = equilibrium(np.array([[lts + x], [lts + 0.05 * h], [0.1]]), p, rigid_tendon=True)
    assert eq.tendon_force[0, 0] == pytest.approx(by_hand, rel=1e-13)
    assert eq.fiber_length[0, 0] == pytest.approx(lm, rel=1e-14)
    assert eq.tendon_length[0, 0] == lts
    # fibre along the tendon below l_min·cos(alpha_max): clamped, slack tendon, no force
    assert eq.clamped[:, 0].tolist() == [False, True, True]
    np.testing.assert_array_equal(eq.tendon_force[1:, 0], 0.0)
    assert (eq.tendon_length[1:, 0] < lts).all()
    # activation scales the active part only
    half = tendon_force(np.array([[lts + x]]), p, activation=0.5, rigid_tendon=True)[0, 0]
    fl = math.exp(-((n - 1) ** 2) / 0.5)
    assert half == pytest.approx(by_hand - 0.5 * fmax * fl * x / lm, rel=1e-13)


def test_activation_is_clamped_to_minimum_activation():
    p = one_muscle(alpha0=0.2)
    lmt = np.linspace(0.25, 0.36, 12)[:, None]
    np.testing.assert_array_equal(tendon_force(lmt, p, activation=0.0),
                                  tendon_force(lmt, p, activation=0.01))
    for bad in (2.0, -0.1, np.r_[np.full(11, 0.5), 1.5][:, None]):   # outside [0, 1]: an error, not a silent clamp
        with pytest.raises(ConfigurationError, match=r"activation must lie in \[0, 1\]"):
            tendon_force(lmt, p, activation=bad)


def test_shapes_and_nan_propagation():
    p = one_muscle()
    lmt = np.full((2, 3, 1), 0.33)
    lmt[1, 2, 0] = np.nan
    eq = equilibrium(lmt, p, activation=np.array([[[0.2]], [[0.9]]]))
    assert eq.tendon_force.shape == (2, 3, 1)
    assert np.isnan(eq.tendon_force[1, 2, 0]) and not eq.clamped[1, 2, 0]
    assert np.isfinite(eq.tendon_force[0]).all()
    assert tendon_force(np.array([0.33]), p).shape == (1,)


def test_input_errors():
    p = one_muscle()
    with pytest.raises(ConfigurationError, match="last axis"):
        tendon_force(np.ones((4, 2)), p)
    with pytest.raises(ConfigurationError, match="broadcast"):
        tendon_force(np.ones((4, 1)), p, activation=np.ones(3))
    with pytest.raises(ConfigurationError, match="finite"):
        tendon_force(np.ones((4, 1)), p, activation=np.nan)


def _gait_like_muscles() -> ThelenParams:
    """Five muscles spanning Gait2392's range (unpennated, pennated, short and long tendons)."""
    return ThelenParams(max_isometric_force=[500.0, 800.0, 1500.0, 200.0, 3000.0],
                        optimal_fiber_length=[0.1, 0.08, 0.05, 0.2, 0.03],
                        tendon_slack_length=[0.2, 0.3, 0.05, 0.1, 0.35],
                        pennation_angle_at_optimal=[0.0, 0.2, 0.35, 0.0, 0.4],
                        **GAIT_CURVES)


def _random_lengths(p: ThelenParams, n: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    stretch = rng.uniform(0.6, 1.4, (n, p.n_muscles))
    return (p.tendon_slack_length + p.optimal_fiber_length) * stretch


def test_rows_are_independent_of_batching():
    """Each (configuration, muscle) is solved on its own: the parallel chunking changes nothing."""
    p = _gait_like_muscles()
    lmt = _random_lengths(p, 301)
    lmt[7, 2] = np.nan
    a = np.random.default_rng(2).uniform(0.0, 1.0, lmt.shape)
    for search in (True, False):
        eq = equilibrium(lmt, p, activation=a, opensim_search=search)
        for i in (0, 7, 63, 64, 150, 300):
            row = equilibrium(lmt[i], p, activation=a[i], opensim_search=search)
            for f in ("tendon_force", "fiber_length", "pennation_angle", "clamped"):
                np.testing.assert_array_equal(getattr(row, f), getattr(eq, f)[i])


def test_tendon_force_equals_the_equilibrium_field():
    p = _gait_like_muscles()
    lmt = _random_lengths(p, 130)
    lmt[3, 1] = np.nan
    for kw in ({}, {"opensim_search": False}, {"rigid_tendon": True}, {"activation": 0.3}):
        np.testing.assert_array_equal(tendon_force(lmt, p, **kw),
                                      equilibrium(lmt, p, **kw).tendon_force)


def test_activation_broadcasting_and_input_layouts():
    p = _gait_like_muscles()
    lmt = _random_lengths(p, 40)
    per_muscle = np.array([0.0, 0.2, 0.5, 0.9, 1.0])
    ref = np.stack([tendon_force(lmt[:, j:j + 1].copy(),
                                 ThelenParams(**{f: getattr(p, f)[j:j + 1] for f in
                                                 ("max_isometric_force", "optimal_fiber_length",
                                                  "tendon_slack_length",
                                                  "pennation_angle_at_optimal")},
                                              **GAIT_CURVES),
                                 activation=per_muscle[j])[:, 0] for j in range(5)], axis=1)
    full = np.broadcast_to(per_muscle, lmt.shape).copy()
    readonly = lmt.copy()
    readonly.setflags(write=False)
    wide = np.zeros((40, 10))
    wide[:, ::2] = lmt  # non-contiguous view
    for lengths, act in ((lmt, per_muscle), (lmt, full), (np.asfortranarray(lmt), full.T.T),
                         (readonly, per_muscle), (wide[:, ::2], per_muscle[None, :])):
        np.testing.assert_array_equal(tendon_force(lengths, p, activation=act), ref)
    # (N, 1) activation: one value per configuration
    col = np.linspace(0.0, 1.0, 40)[:, None]
    f = tendon_force(lmt, p, activation=col)
    np.testing.assert_array_equal(f[5], tendon_force(lmt[5], p, activation=col[5, 0]))


def test_curves_broadcast_like_ufuncs():
    assert force_length_active(np.ones((2, 3)), [0.4, 0.5, 0.6]).shape == (2, 3)
    assert force_length_passive(1, 1, 4).dtype == np.float64  # integers are accepted
    assert tendon_force_length(np.array([1.0, 1.02]), np.array([[0.033], [0.04]])).shape == (2, 2)
    assert np.isnan(force_length_active(np.nan))


def test_tendon_strain_inverts_tendon_curve():
    from pamkin.muscles import _thelen_kernel as k

    for e0 in (0.02, 0.033, 0.1):
        constants = k.tendon_constants(e0)
        for e in np.concatenate([np.linspace(0.0, 3 * e0, 61)[1:], [1e-9, constants[0]]]):
            f = tendon_force_length(1.0 + e, e0)
            assert k.tendon_strain(f, *constants) == pytest.approx(e, rel=1e-9, abs=1e-15)
        assert k.tendon_strain(0.0, *constants) == 0.0


def test_opensim_search_only_adds_clamping_of_tiny_unpennated_fibres():
    """The replay of OpenSim's search changes results only where it leaves an unpennated fibre
    stuck at length 0 although an equilibrium exists (with a fibre well under 1% of l0), and where
    it gives up (failed: NaN), which needs a starting fibre far above the passive curve's onset."""
    p = _gait_like_muscles()
    lmt = _random_lengths(p, 2000, seed=3)
    # include lengths where an unpennated fibre is barely longer than 0 at equilibrium
    lmt[:400, 0] = np.linspace(0.2, 0.2 * 1.05, 400)
    replay = equilibrium(lmt, p)
    smooth = equilibrium(lmt, p, opensim_search=False)
    extra = replay.clamped & ~smooth.clamped
    assert not (smooth.clamped & ~replay.clamped).any()
    assert extra.any()
    muscle = np.nonzero(extra)[1]
    assert (p.pennation_angle_at_optimal[muscle] == 0.0).all()
    assert (smooth.fiber_length[extra] < 1e-2 * p.optimal_fiber_length[muscle]).all()
    np.testing.assert_array_equal(replay.fiber_length[extra], 0.0)
    assert not smooth.failed.any() and not (replay.failed & replay.clamped).any()
    assert np.isnan(replay.tendon_force[replay.failed]).all()
    start = (lmt - 1.01 * p.tendon_slack_length) / p.optimal_fiber_length   # OpenSim's first fibre
    assert replay.failed.any() and (start[replay.failed] > 3.0).all()
    same = ~extra & ~replay.failed
    np.testing.assert_allclose(replay.tendon_force[same], smooth.tendon_force[same],
                               rtol=1e-10, atol=1e-9)


# ----------------------------------------------------------------------------------------------
# Properties
# ----------------------------------------------------------------------------------------------

muscles = st.builds(
    one_muscle,
    fmax=st.floats(10.0, 5000.0),
    l0=st.floats(0.01, 0.5),
    lts=st.floats(0.005, 0.5),
    alpha0=st.sampled_from([0.0]) | st.floats(0.0, 0.5),
    fmax_tendon_strain=st.floats(0.02, 0.1),
)
stretch = st.floats(0.2, 1.8)  # lMT / (lTs + l0)


@settings(max_examples=150, deadline=None)
@given(p=muscles, s=st.lists(stretch, min_size=1, max_size=20), a=st.floats(0.0, 1.0))
def test_equilibrium_holds(p, s, a):
    """Non-negative force; geometry closes; unclamped fibres are in force balance; clamped
    fibres sit at the minimum length and pull at least as hard as the tendon; entries without
    OpenSim equilibrium (search replayed only) are NaN."""
    lmt_all = (np.array(s) * (p.tendon_slack_length + p.optimal_fiber_length))[:, None]
    for search in (True, False):
        eq = equilibrium(lmt_all, p, activation=a, opensim_search=search)
        ok = ~eq.failed[:, 0]
        assert search or ok.all()
        assert np.isnan(eq.tendon_force[~ok, 0]).all() and not eq.clamped[~ok, 0].any()
        eq = Equilibrium(**{k: v[ok] for k, v in vars(eq).items()})
        lmt = lmt_all[ok]
        f = eq.tendon_force[:, 0]
        assert np.all(np.isfinite(f)) and np.all(f >= 0.0)
        closure = eq.tendon_length + eq.fiber_length * np.cos(eq.pennation_angle)
        np.testing.assert_allclose(closure, lmt, rtol=1e-12, atol=1e-15)
        a_eff = max(a, 0.01)  # OpenSim's minimum activation
        fibre = eq.active_fiber_force + eq.passive_fiber_force
        along = (fibre * np.cos(eq.pennation_angle))[:, 0]
        free = ~eq.clamped[:, 0]
        fmax = p.max_isometric_force[0]
        np.testing.assert_allclose(along[free], f[free], rtol=1e-9, atol=1e-9 * fmax)
        lmin = minimum_fiber_length(p)[0]
        np.testing.assert_array_equal(eq.fiber_length[~free, 0], lmin)
        if not search:
            # with the fibre at l_min the active+passive force along the tendon is >= tendon's
            n = lmin / p.optimal_fiber_length[0]
            fm = a_eff * force_length_active(n, p.kshape_active[0]) + force_length_passive(
                n, p.fmax_muscle_strain[0], p.kshape_passive[0])
            cos = np.cos(eq.pennation_angle[~free, 0])  # cos(acos(0.1)), or 1 if unpennated
            assert np.all(fm * cos * fmax >= f[~free] * (1 - 1e-12))


@settings(max_examples=150, deadline=None)
@given(p=muscles, s=st.lists(stretch, min_size=2, max_size=30))
def test_force_non_decreasing_in_length(p, s):
    """dF/dlMT is the series stiffness of fibre (along the tendon) and tendon, so the force is
    non-decreasing wherever the fibre stiffness is >= 0: always at minimum activation (the
    passive curve outweighs 1% of the active Gaussian's slope), and at full activation on
    the ascending limb (lM <= l0) and in the clamped region. Checked with the smooth model
    (opensim_search=False); OpenSim's replayed quirk jumps up where it applies."""
    lmt = (np.sort(np.array(s)) * (p.tendon_slack_length + p.optimal_fiber_length))[:, None]
    fmax = p.max_isometric_force[0]
    passive = equilibrium(lmt, p, activation=0.0, opensim_search=False).tendon_force[:, 0]
    assert np.all(np.diff(passive) >= -1e-9 * np.maximum(passive[1:], fmax))
    full = equilibrium(lmt, p, activation=1.0, opensim_search=False)
    f = full.tendon_force[:, 0]
    ascending = full.clamped[:, 0] | (full.normalized_fiber_length[:, 0] <= 1.0)
    pair = ascending[:-1] & ascending[1:]
    assert np.all(np.diff(f)[pair] >= -1e-9 * fmax)


def test_force_decreases_on_descending_limb():
    """A documented exception to monotonicity: at full activation on the descending limb the
    fibre's stiffness is negative, and so is the musculotendon's (tendon in series)."""
    p = one_muscle(l0=0.1, lts=0.1)
    lmt = np.linspace(0.205, 0.235, 31)[:, None]
    eq = equilibrium(lmt, p)
    on_limb = (eq.normalized_fiber_length[:, 0] > 1.1) & (eq.normalized_fiber_length[:, 0] < 1.25)
    assert on_limb.sum() > 5
    assert np.all(np.diff(eq.tendon_force[:, 0])[on_limb[1:] & on_limb[:-1]] < 0.0)


# ----------------------------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------------------------


def _good(**changes) -> dict:
    kw = dict(max_isometric_force=[500.0, 800.0], optimal_fiber_length=[0.1, 0.08],
              tendon_slack_length=[0.2, 0.3], pennation_angle_at_optimal=[0.0, 0.2],
              names=("vas_int_r", "soleus_r"), **GAIT_CURVES)
    kw.update(changes)
    return kw


@pytest.mark.parametrize("key, value, match", [
    ("optimal_fiber_length", [0.1, 0.0], r"soleus_r: optimal_fiber_length must be > 0"),
    ("optimal_fiber_length", [-0.1, 0.1], r"vas_int_r: optimal_fiber_length"),
    ("max_isometric_force", [0.0, 800.0], r"vas_int_r: max_isometric_force must be > 0"),
    ("tendon_slack_length", [0.2, -1e-3], r"soleus_r: tendon_slack_length"),
    ("pennation_angle_at_optimal", [0.0, math.pi / 2], r"soleus_r: pennation_angle_at_optimal"),
    ("pennation_angle_at_optimal", [-0.1, 0.0], r"vas_int_r: pennation_angle_at_optimal"),
    ("max_isometric_force", [np.nan, 800.0], r"vas_int_r: max_isometric_force"),
    ("fmax_tendon_strain", 0.0, r"vas_int_r: fmax_tendon_strain"),
    ("kshape_active", [0.5, -0.5], r"soleus_r: kshape_active"),
    ("flen", 1.0, r"vas_int_r: flen must be > 1"),
    ("minimum_activation", 1.0, r"minimum_activation"),
    ("maximum_pennation_angle", [0.5, 0.1], r"soleus_r: maximum_pennation_angle must exceed"),
])
def test_parameter_errors_name_the_muscle(key, value, match):
    with pytest.raises(ParameterError, match=match):
        ThelenParams(**_good(**{key: value}))


def test_parameter_shape_errors():
    with pytest.raises(ParameterError, match="shape"):
        ThelenParams(**_good(tendon_slack_length=[0.2, 0.3, 0.4]))
    with pytest.raises(ParameterError, match="names"):
        ThelenParams(**_good(names=("a",)))
    with pytest.raises(ParameterError, match="muscle #1"):
        ThelenParams(**_good(names=(), optimal_fiber_length=[0.1, 0.0]))


def test_parameters_are_read_only_with_opensim_defaults():
    p = ThelenParams(**_good())
    p.validate()
    assert p.n_muscles == 2
    assert p.af.tolist() == [0.25, 0.25] and p.flen.tolist() == [1.4, 1.4]
    assert p.maximum_pennation_angle[0] == math.acos(0.1)
    assert p.minimum_activation[0] == 0.01
    with pytest.raises(ValueError):
        p.optimal_fiber_length[0] = 1.0


def test_params_from_gait2392_xml(gait2392_path):
    p = params_from_osim_xml(gait2392_path)
    assert p.n_muscles == 92
    i = p.names.index("glut_med1_r")
    assert p.max_isometric_force[i] == 819.0
    assert p.optimal_fiber_length[i] == 0.0535
    assert p.tendon_slack_length[i] == 0.078
    assert p.pennation_angle_at_optimal[i] == 0.13962634
    assert (p.fmax_tendon_strain == 0.033).all() and (p.kshape_active == 0.5).all()
    assert (p.kshape_passive == 4.0).all() and (p.af == 0.3).all() and (p.flen == 1.8).all()
    # absent from the file: OpenSim 4.6 defaults
    assert (p.minimum_activation == 0.01).all()
    assert (p.fv_linear_extrap_threshold == 0.95).all()


def test_params_from_xml_defaults_and_errors(tmp_path, millard_path):
    good = tmp_path / "m.osim"
    good.write_text(
        "<OpenSimDocument><Model><ForceSet><objects>"
        "<CoordinateLimitForce name='lim'/>"
        "<Thelen2003Muscle name='a'><max_isometric_force>100</max_isometric_force>"
        "<optimal_fiber_length>0.1</optimal_fiber_length>"
        "<tendon_slack_length>0.2</tendon_slack_length></Thelen2003Muscle>"
        "</objects></ForceSet></Model></OpenSimDocument>")
    p = params_from_osim_xml(good)
    assert p.names == ("a",)
    assert p.pennation_angle_at_optimal[0] == 0.0
    assert p.fmax_tendon_strain[0] == 0.04 and p.kshape_active[0] == 0.45
    assert p.kshape_passive[0] == 5.0 and p.flen[0] == 1.4

    missing = tmp_path / "missing.osim"
    missing.write_text(good.read_text().replace(
        "<tendon_slack_length>0.2</tendon_slack_length>", ""))
    with pytest.raises(ParameterError, match="a: missing required property tendon_slack_length"):
        params_from_osim_xml(missing)

    with pytest.raises(UnsupportedFeatureError) as info:
        params_from_osim_xml(millard_path)
    first = ET.parse(millard_path).getroot().find(".//ForceSet/objects")[0]
    assert info.value.element == "Millard2012EquilibriumMuscle"
    assert info.value.component == first.get("name")
    assert str(millard_path) in str(info.value)


# ----------------------------------------------------------------------------------------------
# OpenSim 4.6
# ----------------------------------------------------------------------------------------------

TRANSLATIONS = ("pelvis_tx", "pelvis_ty", "pelvis_tz")


def reference_configurations(osim) -> np.ndarray:
    """300 uniform random configurations over the coordinate ranges (fixed seed), plus
    extremes that make muscles slack or very short: each coordinate alone at either end
    of its range, everything at its lower / upper end, and 60 random corners."""
    ranges = []
    for c in ET.parse(osim).getroot().iter("Coordinate"):
        lo, hi = (float(v) for v in c.findtext("range").split())
        ranges.append((0.0, 0.0) if c.get("name") in TRANSLATIONS else (lo, hi))
    lo, hi = np.array(ranges).T
    rng = np.random.default_rng(20261122)
    uniform = lo + (hi - lo) * rng.random((300, lo.size))
    single = []
    for i in range(lo.size):
        if hi[i] > lo[i]:
            for end in (lo[i], hi[i]):
                q = np.zeros(lo.size)
                q[i] = end
                single.append(q)
    corners = np.where(rng.random((60, lo.size)) < 0.5, lo, hi)
    return np.vstack([uniform, single, lo, hi, corners])


@pytest.fixture(scope="module")
def gait2392_reference(gait2392_path):
    q = reference_configurations(gait2392_path)
    ref = opensim_reference(gait2392_path, q, what=("lengths", "tendon_forces"))
    params = params_from_osim_xml(gait2392_path)
    assert tuple(ref["muscles"]) == params.names
    return q, ref, params


def _force_errors(f, f_ref):
    err = np.abs(f - f_ref)
    rel = err / np.maximum(np.abs(f_ref), np.finfo(float).tiny)
    bad = (rel > 1e-4) & (err > 1e-3)
    big = np.abs(f_ref) > 1e-3
    return err.max(), rel[big].max(), bad


@pytest.mark.opensim
def test_tendon_force_matches_opensim(gait2392_reference):
    q, ref, params = gait2392_reference
    eq = equilibrium(ref["lengths"], params)
    abs_err, rel_err, bad = _force_errors(eq.tendon_force, ref["tendon_forces"])
    fib_err = np.abs(eq.fiber_length - ref["fiber_lengths"])
    lmin = minimum_fiber_length(params)
    at_lmin = np.abs(ref["fiber_lengths"] - lmin) <= 1e-12
    smooth = equilibrium(ref["lengths"], params, opensim_search=False)
    quirk = eq.clamped & ~smooth.clamped
    print(f"\n{q.shape[0]} configurations x {params.n_muscles} muscles: tendon force max abs "
          f"error {abs_err:.3g} N, max rel error {rel_err:.3g} (|F| > 1e-3 N); "
          f"fibre length max abs error {fib_err.max():.3g} m; clamped {eq.clamped.sum()} "
          f"(OpenSim at l_min: {at_lmin.sum()}), of which {quirk.sum()} only through "
          f"OpenSim's search (unpennated fibre stuck at 0); max F/Fmax "
          f"{(ref['tendon_forces'] / params.max_isometric_force).max():.2f}")
    assert not bad.any(), [(int(i), params.names[j]) for i, j in zip(*np.nonzero(bad))][:10]
    assert fib_err.max() <= 1e-8
    np.testing.assert_array_equal(eq.clamped, at_lmin)
    # the sample exercises slack tendons, clamping and OpenSim's quirk
    assert (eq.clamped & (ref["tendon_forces"] == 0)).sum() > 100
    assert (eq.clamped & (ref["tendon_forces"] > 0)).any()
    assert quirk.any()
    # without the replay exactly those entries differ
    _, _, bad_smooth = _force_errors(smooth.tendon_force, ref["tendon_forces"])
    assert not (bad_smooth & ~quirk).any()


@pytest.mark.opensim
@pytest.mark.parametrize("activation", [0.0, 0.4])
def test_tendon_force_matches_opensim_at_lower_activation(gait2392_reference, activation):
    """Activation 0 is clamped to minimum_activation (0.01) by OpenSim too."""
    q, _, params = gait2392_reference
    ref = opensim_reference(GAIT2392, q[:120], what=("lengths", "tendon_forces"),
                            activation=activation)
    eq = equilibrium(ref["lengths"], params, activation=activation)
    abs_err, rel_err, bad = _force_errors(eq.tendon_force, ref["tendon_forces"])
    print(f"\nactivation {activation}: max abs error {abs_err:.3g} N, max rel {rel_err:.3g}, "
          f"clamped {eq.clamped.sum()}")
    assert not bad.any()
    assert np.abs(eq.fiber_length - ref["fiber_lengths"]).max() <= 1e-8


# ----------------------------------------------------------------------------------------------
# No equilibrium: where OpenSim's search gives up (MuscleCannotEquilibrate), so does pamkin
# ----------------------------------------------------------------------------------------------


def _leg39_uncoupled(tmp_path):
    """Leg39 without its CoordinateCouplerConstraints: the knee translations (tib_tx_r in
    [-5, 5] m, ...) become free coordinates, so random configurations stretch tendons to many
    times their slack length (the issue's "uncoupled knee translations")."""
    import re  # noqa: PLC0415

    leg39 = GAIT2392.parent.parent / "Models" / "Leg39" / "leg39.osim"
    if not leg39.exists():
        pytest.skip("Leg39 not found")
    text = re.sub(r"<CoordinateCouplerConstraint .*?</CoordinateCouplerConstraint>", "",
                  leg39.read_text(), flags=re.S)
    path = tmp_path / "leg39_uncoupled.osim"
    path.write_text(text)
    return path


@pytest.mark.opensim
@pytest.mark.slow  # ~23 s without the OpenSim cache
def test_no_equilibrium_where_opensim_finds_none(tmp_path):
    """OpenSim 4.6 (each muscle's computeEquilibrium in turn, so that every failure is recorded)
    raises MuscleCannotEquilibrate on about half of the (configuration, muscle) pairs of the
    uncoupled Leg39; pamkin fails on exactly those (NaN, failed flag, EquilibriumWarning; without
    this it returned the true equilibrium, up to ~5e6 N) and matches the others."""
    import warnings  # noqa: PLC0415

    import pamkin  # noqa: PLC0415
    from millard_ref import opensim_forces  # noqa: PLC0415
    from pamkin.muscles import _thelen_kernel as k  # noqa: PLC0415
    from pamkin.errors import EquilibriumWarning  # noqa: PLC0415
    from pamkin.opensim.model_file import SkippedComponentsWarning  # noqa: PLC0415

    path = _leg39_uncoupled(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        model = pamkin.load_osim(path)
    assert not model.dependent_coordinates
    q = model.random_q(200, seed=1)
    act = np.random.default_rng(4).uniform(0.0, 1.0, (200, len(model.muscles)))
    act[:100] = 1.0
    ref = opensim_forces(path, q, act)
    assert tuple(ref["muscles"]) == tuple(model.muscles)
    L = model.lengths(q)
    assert np.abs(L - ref["lengths"]).max() < 1e-9
    failed = ref["failed"]
    assert 0.2 * failed.size < failed.sum() < 0.8 * failed.size
    with pytest.warns(EquilibriumWarning, match=r"no static equilibrium for \d+ of 1800"):
        F = model.tendon_forces(q, activation=act)
    with pytest.warns(EquilibriumWarning):
        st = model.evaluate(q, activation=act)
    for mode in (True, k.SEARCH_FULL):
        eq = equilibrium(L, model.thelen_params, act, opensim_search=mode)
        np.testing.assert_array_equal(eq.failed, failed)
        assert np.isnan(eq.tendon_force[failed]).all() and np.isnan(eq.fiber_length[failed]).all()
        ok = ~failed
        abs_err, rel_err, bad = _force_errors(eq.tendon_force[ok], ref["tendon_forces"][ok])
        assert not bad.any()
        assert np.abs(eq.fiber_length[ok] - ref["fiber_lengths"][ok]).max() <= 1e-8
    print(f"\nLeg39 uncoupled, 200 configurations x 9 muscles: OpenSim fails on {failed.sum()}, pamkin on "
          f"the same; others: tendon force max abs error {abs_err:.3g} N, max rel {rel_err:.3g}; "
          f"largest force OpenSim returns {np.nanmax(ref['tendon_forces']):.3g} N")
    np.testing.assert_array_equal(np.isnan(F), failed)
    np.testing.assert_array_equal(st.equilibrium.failed, failed)
    np.testing.assert_array_equal(F, equilibrium(L, model.thelen_params, act).tendon_force)
    # the smooth model (no replay) has no failures: there it returns the true equilibrium
    smooth = equilibrium(L, model.thelen_params, act, opensim_search=False)
    assert not smooth.failed.any() and smooth.tendon_force[failed].max() > 1e5


def test_search_replayed_where_needed_equals_replay_everywhere():
    """The default replays OpenSim's search only for unpennated muscles and where OpenSim's first
    fibre starts beyond l0 along the tendon (:data:`pamkin.muscles._thelen_kernel.SEARCH_START_MAX`);
    replaying it for every entry gives the same clamped and failed entries and the same forces, over
    random muscles (compliant tendons up to lTs·e0T = 5·l0) and musculotendon lengths from 0.2 to
    12 times lTs + l0 (about half of them fail)."""
    from pamkin.muscles import _thelen_kernel as k  # noqa: PLC0415

    rng = np.random.default_rng(7)
    m = 300
    p = ThelenParams(max_isometric_force=rng.uniform(10, 5000, m), optimal_fiber_length=rng.uniform(0.01, 0.5, m),
                     tendon_slack_length=rng.uniform(0.005, 0.5, m),
                     pennation_angle_at_optimal=np.where(rng.random(m) < 0.3, 0.0, rng.uniform(0, 0.6, m)),
                     fmax_tendon_strain=rng.uniform(0.02, 0.1, m), fmax_muscle_strain=rng.uniform(0.3, 1.0, m),
                     kshape_active=rng.uniform(0.3, 0.7, m), kshape_passive=rng.uniform(2, 8, m))
    stretch = np.concatenate([rng.uniform(0.2, 12.0, (300, m)), rng.uniform(0.8, 3.0, (300, m))])
    lmt = (p.optimal_fiber_length + p.tendon_slack_length) * stretch
    for a in (1.0, 0.0, rng.random(lmt.shape)):
        needed = equilibrium(lmt, p, a)
        always = equilibrium(lmt, p, a, opensim_search=k.SEARCH_FULL)
        np.testing.assert_array_equal(needed.failed, always.failed)
        np.testing.assert_array_equal(needed.clamped, always.clamped)
        np.testing.assert_allclose(needed.tendon_force, always.tendon_force, rtol=1e-9, atol=1e-9)
    assert needed.failed.mean() > 0.3 and needed.clamped.any()
