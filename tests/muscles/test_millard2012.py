"""Tests of :mod:`pamkin.muscles.millard2012`: curves and static equilibrium against OpenSim 4.6 itself.

OpenSim runs in a child process (:mod:`millard_ref`). Tolerances: curve values within 1e-12
(derivatives within 1e-12 of the curve's largest slope); tendon force within 1e-4 relative or
1e-3 N absolute (issue 10); fibre length within 1e-8 m; OpenSim's failures ("no equilibrium") and
clamped fibres reproduced exactly.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from millard_ref import opensim_curves, opensim_forces
from opensim_ref import SHARED

import pamkin
from pamkin.muscles import millard2012 as mm
from pamkin.errors import ConfigurationError, EquilibriumWarning, ParameterError
from pamkin.opensim.model_file import SkippedComponentsWarning

MODELS = SHARED / "opensim-models" / "Models"

# ----------------------------------------------------------------------------------------------
# Curves
# ----------------------------------------------------------------------------------------------

RAJAGOPAL_AFL = dict(min_norm_active_fiber_length=0.25, transition_norm_fiber_length=0.77,
                     max_norm_active_fiber_length=1.9, shallow_ascending_slope=0.75, minimum_value=0.0)
CURVE_SPECS = [
    ("ActiveForceLengthCurve", {}),
    ("ActiveForceLengthCurve", RAJAGOPAL_AFL),
    ("FiberForceLengthCurve", {}),
    ("FiberForceLengthCurve", dict(strain_at_zero_force=0.05, strain_at_one_norm_force=0.5,
                                   stiffness_at_low_force=0.3, stiffness_at_one_norm_force=5.0, curviness=0.3)),
    ("TendonForceLengthCurve", {}),
    ("TendonForceLengthCurve", dict(strain_at_one_norm_force=0.033, stiffness_at_one_norm_force=50.0,
                                    norm_force_at_toe_end=0.5, curviness=0.8)),
    ("FiberCompressiveForceLengthCurve", {}),
    ("FiberCompressiveForceLengthCurve", dict(norm_length_at_zero_force=0.6, stiffness_at_zero_length=-4.0,
                                              curviness=0.2)),
    ("FiberCompressiveForceCosPennationCurve", {}),
]
FACTORIES = {"ActiveForceLengthCurve": mm.active_force_length_curve,
             "FiberForceLengthCurve": mm.fiber_force_length_curve,
             "TendonForceLengthCurve": mm.tendon_force_length_curve,
             "FiberCompressiveForceLengthCurve": mm.fiber_compressive_force_length_curve,
             "FiberCompressiveForceCosPennationCurve": mm.fiber_compressive_force_cos_pennation_curve}


@pytest.mark.opensim
def test_curves_match_opensim_curve_objects():
    x = np.concatenate([np.linspace(-0.5, 2.5, 3001), [0.4441, 0.73, 1.0, 1.049, 1.7, 1.8123]])
    ref = opensim_curves(CURVE_SPECS, x)
    worst = []
    for k, (cls, props) in enumerate(CURVE_SPECS):
        curve = FACTORIES[cls](**props)
        y, dy = curve(x), curve.derivative(x)
        ev = np.abs(y - ref["value"][k]).max()
        ed = np.abs(dy - ref["derivative"][k]).max() / max(1.0, np.abs(ref["derivative"][k]).max())
        worst.append((ev, ed))
        assert ev <= 1e-12, (cls, props, ev)
        assert ed <= 1e-12, (cls, props, ed)
    print(f"\ncurves: max value error {max(w[0] for w in worst):.2g}, "
          f"max derivative error / max slope {max(w[1] for w in worst):.2g}")


def test_curve_shapes_by_hand():
    fal = mm.active_force_length_curve(minimum_value=0.0)
    assert fal(1.0) == pytest.approx(1.0, abs=1e-15) and abs(fal.derivative(1.0)) < 1e-12
    assert fal(0.4441) == 0.0 and fal(1.8123) == pytest.approx(0.0, abs=1e-15)
    assert fal(0.2) == 0.0 and fal(2.5) == 0.0 and fal.derivative(2.5) == 0.0   # flat outside
    e1 = 0.6
    fpe = mm.fiber_force_length_curve(0.0, e1)
    assert fpe(1.0) == 0.0 and fpe(0.5) == 0.0
    assert fpe(1 + e1) == pytest.approx(1.0, abs=1e-14)
    k = 2.0 / e1                                                   # OpenSim's fitted stiffness
    assert fpe(2.0) == pytest.approx(1.0 + k * (1.0 - e1), rel=1e-14)   # linear beyond the curve
    assert fpe.derivative(1 + e1) == pytest.approx(k, rel=1e-12)
    e0 = 0.049
    fse = mm.tendon_force_length_curve(e0)
    assert fse(1.0) == 0.0 and fse(0.9) == 0.0 and fse.derivative(0.99) == 0.0
    assert fse(1 + e0) == pytest.approx(1.0, rel=1e-14)               # one normalized force
    assert fse.derivative(1.2) == pytest.approx(1.375 / e0, rel=1e-14)
    x_toe = fse.x1                                                   # end of the toe region
    assert fse(x_toe) == pytest.approx(2.0 / 3.0, rel=1e-14)
    assert np.all(np.diff(fse(np.linspace(1.0, 1.1, 1001))) >= 0.0)
    assert np.isnan(fse(np.nan))
    assert fse(np.ones((2, 3))).shape == (2, 3)


@pytest.mark.parametrize("factory, kwargs, match", [
    (mm.fiber_force_length_curve, dict(stiffness_at_low_force=0.2), "all be set or all be empty"),
    (mm.tendon_force_length_curve, dict(curviness=0.5), "all be set or all be empty"),
    (mm.tendon_force_length_curve, dict(strain_at_one_norm_force=-0.1), "strain_at_one_norm_force"),
    (mm.active_force_length_curve, dict(transition_norm_fiber_length=0.3), "min_norm_active_fiber_length"),
    (mm.active_force_length_curve, dict(shallow_ascending_slope=5.0), "shallow_ascending_slope"),
    (mm.fiber_compressive_force_length_curve, dict(curviness=0.5), "both be set"),
])
def test_curve_parameter_errors(factory, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        factory(**kwargs)


# ----------------------------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------------------------


def one(**kw) -> mm.MillardParams:
    base = dict(max_isometric_force=[1000.0], optimal_fiber_length=[0.1], tendon_slack_length=[0.2],
                names=("m",))
    base.update({k: np.atleast_1d(v) if k != "names" else v for k, v in kw.items()})
    return mm.MillardParams(**base)


def test_opensim_adjustments_on_load():
    # damped model (default 0.1): active curve minimum lowered to 0; undamped elastic: raised to 0.1
    damped, undamped = one(), one(fiber_damping=0.0)
    assert damped.curves(0)[0](0.3) == 0.0
    assert undamped.curves(0)[0](0.3) == pytest.approx(0.1, abs=1e-15)
    assert one(fiber_damping=0.0005).table(None)[0, mm.C_BETA] == 0.0      # below 0.001: no damping
    assert undamped.curves(0, rigid=True)[0](0.3) == 0.0                  # rigid tendon: as damped
    # minimum fibre length: the active curve's end or the pennation limit, whichever is longer
    np.testing.assert_allclose(mm.minimum_fiber_length(one()), 0.4441 * 0.1, rtol=1e-15)
    p = one(pennation_angle_at_optimal=0.7, maximum_pennation_angle=0.8)
    np.testing.assert_allclose(mm.minimum_fiber_length(p), 0.1 * math.sin(0.7) / math.sin(0.8), rtol=1e-15)


@pytest.mark.parametrize("kw, match", [
    (dict(optimal_fiber_length=0.0), "m: optimal_fiber_length must be > 0"),
    (dict(pennation_angle_at_optimal=math.pi / 2), "pennation_angle_at_optimal"),
    (dict(minimum_activation=0.05), "min_control must be >= minimum_activation"),
    (dict(fiber_damping=0.0, minimum_activation=0.005, min_control=0.005), "minimum_activation must be >= 0.01"),
    (dict(fse_curviness=0.5), "m: .*all be set or all be empty"),
])
def test_parameter_errors_name_the_muscle(kw, match):
    with pytest.raises(ParameterError, match=match):
        one(**kw)


def test_params_from_xml(millard_path):
    p = mm.params_from_osim_xml(millard_path)
    assert p.n_muscles == 92 and p.names[0] == "glut_med1_r"
    assert (p.fiber_damping == 0.1).all() and (p.afl_minimum_value == 0.0).all()
    assert np.isnan(p.fse_curviness).all() and (p.fse_strain_at_one_norm_force == 0.049).all()
    raj = mm.osim_properties(MODELS / "Rajagopal" / "Rajagopal2016.osim")
    assert len(raj) == 80
    assert raj["addbrev_r"]["ActiveForceLengthCurve.min_norm_active_fiber_length"] == 0.25
    assert sum(v.get("ignore_tendon_compliance", 0.0) for v in raj.values()) == 34


# ----------------------------------------------------------------------------------------------
# Equilibrium without OpenSim
# ----------------------------------------------------------------------------------------------


def test_rigid_tendon_by_hand():
    fmax, l0, lts, alpha0 = 800.0, 0.1, 0.2, 0.3
    p = one(max_isometric_force=fmax, pennation_angle_at_optimal=alpha0)
    fal, fpe, _ = p.curves(0, rigid=True)
    h = l0 * math.sin(alpha0)
    x = 0.09
    lm = math.hypot(x, h)
    a = 0.6
    by_hand = fmax * (a * fal(lm / l0) + fpe(lm / l0)) * x / lm
    eq = mm.equilibrium(np.array([[lts + x], [lts + 0.01]]), p, a, rigid_tendon=True)
    assert eq.tendon_force[0, 0] == pytest.approx(by_hand, rel=1e-13)
    assert eq.fiber_length[0, 0] == pytest.approx(lm, rel=1e-14) and eq.tendon_length[0, 0] == pytest.approx(lts)
    # shorter than the minimum fibre: clamped, no force
    assert eq.clamped[:, 0].tolist() == [False, True] and eq.tendon_force[1, 0] == 0.0
    assert eq.fiber_length[1, 0] == mm.minimum_fiber_length(p)[0]
    # the file's ignore_tendon_compliance does the same
    q = one(max_isometric_force=fmax, pennation_angle_at_optimal=alpha0, ignore_tendon_compliance=1.0)
    assert mm.tendon_force(np.array([[lts + x]]), q, a)[0][0, 0] == eq.tendon_force[0, 0]


def test_no_equilibrium_is_nan_and_flagged():
    """Undamped elastic muscle just longer than its tendon: even the shortest fibre pulls (the active
    curve's minimum is 0.1), the tendon is slack, OpenSim's search fails -> NaN + failed."""
    p = one(optimal_fiber_length=0.2826, tendon_slack_length=0.3142, fiber_damping=0.0)
    lmt = np.array([[0.3264], [0.6]])
    eq = mm.equilibrium(lmt, p, 0.8)
    assert eq.failed[:, 0].tolist() == [True, False]
    assert np.isnan(eq.tendon_force[0, 0]) and np.isnan(eq.fiber_length[0, 0]) and not eq.clamped[0, 0]
    assert np.isfinite(eq.tendon_force[1, 0])
    f, failed = mm.tendon_force(lmt, p, 0.8)
    assert failed.tolist() == eq.failed.tolist() and np.isnan(f[0, 0])


def test_slack_and_clamped():
    p = one(pennation_angle_at_optimal=0.4)
    eq = mm.equilibrium(np.array([[0.15], [0.2]]), p, 1.0)     # shorter than the tendon
    assert eq.clamped.all() and (eq.tendon_force == 0.0).all() and not eq.failed.any()
    np.testing.assert_array_equal(eq.fiber_length, mm.minimum_fiber_length(p)[0])
    np.testing.assert_array_equal(eq.active_fiber_force, 0.0)


def test_inputs_and_shapes():
    p = mm.MillardParams(max_isometric_force=[500.0, 800.0], optimal_fiber_length=[0.1, 0.08],
                         tendon_slack_length=[0.2, 0.3], pennation_angle_at_optimal=[0.0, 0.2])
    lmt = np.full((2, 3, 2), 0.33)
    lmt[1, 2, 0] = np.nan
    eq = mm.equilibrium(lmt, p, activation=np.array([0.2, 0.9]))
    assert eq.tendon_force.shape == (2, 3, 2) and np.isnan(eq.tendon_force[1, 2, 0])
    assert not eq.failed[1, 2, 0] and not eq.clamped[1, 2, 0]
    # activation below minimum_activation is raised to it
    np.testing.assert_array_equal(mm.tendon_force(lmt, p, 0.0)[0], mm.tendon_force(lmt, p, 0.01)[0])
    with pytest.raises(ConfigurationError, match="last axis"):
        mm.tendon_force(np.ones((4, 3)), p)
    with pytest.raises(ConfigurationError, match=r"activation must lie in \[0, 1\]"):
        mm.tendon_force(lmt, p, 1.5)
    with pytest.raises(ConfigurationError, match="broadcast"):
        mm.tendon_force(lmt, p, np.ones(3))


@settings(max_examples=60, deadline=None)
@given(l0=st.floats(0.02, 0.3), lts=st.floats(0.01, 0.5), alpha0=st.sampled_from([0.0]) | st.floats(0.0, 0.6),
       s=st.lists(st.floats(0.3, 2.0), min_size=1, max_size=20), a=st.floats(0.0, 1.0))
def test_converged_entries_are_in_force_balance(l0, lts, alpha0, s, a):
    p = one(optimal_fiber_length=l0, tendon_slack_length=lts, pennation_angle_at_optimal=alpha0)
    lmt = (np.array(s) * (l0 + lts))[:, None]
    eq = mm.equilibrium(lmt, p, a)
    assert not eq.failed.any()                         # the damped model always finds one here
    free = ~eq.clamped[:, 0]
    along = ((eq.active_fiber_force + eq.passive_fiber_force) * np.cos(eq.pennation_angle))[:, 0]
    # OpenSim stops at |force error| < 1e-8·Fmax (Fmax = 1000 N here); a little slack for rounding
    np.testing.assert_allclose(along[free], eq.tendon_force[free, 0], rtol=0, atol=1.1e-8 * 1000.0)
    np.testing.assert_allclose(eq.tendon_length + eq.fiber_length * np.cos(eq.pennation_angle), lmt,
                               rtol=1e-13, atol=1e-15)
    assert (eq.tendon_force >= 0).all()


# ----------------------------------------------------------------------------------------------
# OpenSim 4.6
# ----------------------------------------------------------------------------------------------


def _compare(eq, ref, label):
    """Assert the equilibrium matches OpenSim's; return (max rel error, max abs error, fibre error)."""
    np.testing.assert_array_equal(eq.failed, ref["failed"])
    ok = ~ref["failed"]
    F, Fr = eq.tendon_force[ok], ref["tendon_forces"][ok]
    err = np.abs(F - Fr)
    rel = err / np.maximum(np.abs(Fr), np.finfo(float).tiny)
    bad = (rel > 1e-4) & (err > 1e-3)
    assert not bad.any(), (label, np.argwhere(ok)[bad][:5])
    fib = np.abs(eq.fiber_length[ok] - ref["fiber_lengths"][ok]).max()
    assert fib <= 1e-8, (label, fib)
    big = np.abs(Fr) > 1e-3
    return rel[big].max() if big.any() else 0.0, err.max(), fib


@pytest.fixture(scope="module")
def gait2392_millard_configurations(millard_path):
    from test_thelen2003 import reference_configurations  # noqa: PLC0415

    return reference_configurations(millard_path)


@pytest.mark.opensim
@pytest.mark.parametrize("activation", ["full", "random"])
def test_gait2392_millard_matches_opensim(millard_path, gait2392_millard_configurations, activation):
    q = gait2392_millard_configurations
    p = mm.params_from_osim_xml(millard_path)
    act = 1.0 if activation == "full" else np.random.default_rng(7).uniform(0.0, 1.0, (len(q), p.n_muscles))
    ref = opensim_forces(millard_path, q, act)
    assert tuple(ref["muscles"]) == p.names
    eq = mm.equilibrium(ref["lengths"], p, act)
    rel, err, fib = _compare(eq, ref, activation)
    print(f"\nGait2392 Millard, activation {activation}: {q.shape[0]} configurations x {p.n_muscles} muscles: "
          f"max rel error {rel:.2g}, max abs error {err:.2g} N, fibre length {fib:.2g} m, "
          f"max F/Fmax {np.nanmax(ref['tendon_forces'] / p.max_isometric_force):.2f}")


# Hand-built model: every muscle on its own slider, length q_k + c_k; variants of every option.
CURVE_TAGS = {"ActiveForceLengthCurve": ("min_norm_active_fiber_length", "transition_norm_fiber_length",
                                         "max_norm_active_fiber_length", "shallow_ascending_slope",
                                         "minimum_value"),
              "FiberForceLengthCurve": ("strain_at_zero_force", "strain_at_one_norm_force",
                                        "stiffness_at_low_force", "stiffness_at_one_norm_force", "curviness"),
              "TendonForceLengthCurve": ("strain_at_one_norm_force", "stiffness_at_one_norm_force",
                                         "norm_force_at_toe_end", "curviness")}


def slider_model(muscles: list[dict]) -> str:
    """``.osim`` text: muscle k runs along x from (-c_k, 0, 0) in ground to body b_k on SliderJoint
    coordinate q_k, so its length is q_k + c_k. ``muscles``: OpenSim properties per muscle (curve
    properties as ``"Curve.property"``) and ``"c"``."""
    bodies, joints, forces = [], [], []
    for k, m in enumerate(muscles):
        c = m["c"]
        bodies.append(f'<Body name="b{k}"><mass>1</mass><mass_center>0 0 0</mass_center>'
                      '<inertia>0.01 0.01 0.01 0 0 0</inertia></Body>')
        joints.append(f'<SliderJoint name="j{k}"><socket_parent_frame>/ground</socket_parent_frame>'
                      f'<socket_child_frame>/bodyset/b{k}</socket_child_frame><coordinates>'
                      f'<Coordinate name="q{k}"><default_value>0</default_value>'
                      f'<range>{-0.95 * c!r} {1.5 * c!r}</range><clamped>false</clamped>'
                      '<locked>false</locked></Coordinate></coordinates></SliderJoint>')
        props = "".join(f"<{key}>{value}</{key}>" for key, value in m.items() if key != "c" and "." not in key)
        for curve, keys in CURVE_TAGS.items():
            inner = "".join(f"<{key}>{m[f'{curve}.{key}']}</{key}>" for key in keys if f"{curve}.{key}" in m)
            if inner:
                props += f'<{curve} name="m{k}_{curve}">{inner}</{curve}>'
        forces.append(f'<Millard2012EquilibriumMuscle name="m{k}"><GeometryPath name="path"><PathPointSet>'
                      f'<objects><PathPoint name="o"><socket_parent_frame>/ground</socket_parent_frame>'
                      f'<location>{-c!r} 0 0</location></PathPoint><PathPoint name="i">'
                      f'<socket_parent_frame>/bodyset/b{k}</socket_parent_frame><location>0 0 0</location>'
                      f'</PathPoint></objects></PathPointSet></GeometryPath>{props}'
                      '</Millard2012EquilibriumMuscle>')
    return ('<?xml version="1.0" encoding="UTF-8" ?><OpenSimDocument Version="40000"><Model name="sliders">'
            '<Ground name="ground"/><gravity>0 -9.80665 0</gravity>'
            f'<BodySet name="bodyset"><objects>{"".join(bodies)}</objects></BodySet>'
            f'<JointSet name="jointset"><objects>{"".join(joints)}</objects></JointSet>'
            f'<ForceSet name="forceset"><objects>{"".join(forces)}</objects></ForceSet>'
            '</Model></OpenSimDocument>')


#: Variant k % 8: fibre damping, rigid tendon.
DAMPING = [0.1, 0.0, 0.05, 0.0005, 0.1, 0.0, 0.1, 0.3]
RIGID = {4, 5}


def variant_muscles(n: int, seed: int) -> list[dict]:
    """``n`` muscles cycling through damped/undamped (incl. below OpenSim's 0.001 threshold), rigid
    and elastic tendons, default / Rajagopal / fully specified curves, pennation and activation limits."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        l0, lts = rng.uniform(0.02, 0.3), rng.uniform(0.01, 0.5)
        m = dict(max_isometric_force=rng.uniform(100, 3000), optimal_fiber_length=l0, tendon_slack_length=lts,
                 pennation_angle_at_optimal=0.0 if rng.random() < 0.3 else rng.uniform(0, 0.7),
                 fiber_damping=DAMPING[k % 8], c=l0 + lts)
        if k % 8 in RIGID:
            m["ignore_tendon_compliance"] = "true"
        if k % 3 == 0:
            m.update({f"ActiveForceLengthCurve.{key}": v for key, v in RAJAGOPAL_AFL.items()})
            m.update({"FiberForceLengthCurve.strain_at_zero_force": 0.0,
                      "FiberForceLengthCurve.strain_at_one_norm_force": 0.7})
        elif k % 3 == 1:
            m.update({"ActiveForceLengthCurve.minimum_value": 0.2, "FiberForceLengthCurve.strain_at_zero_force": 0.05,
                      "FiberForceLengthCurve.strain_at_one_norm_force": 0.5,
                      "FiberForceLengthCurve.stiffness_at_low_force": 0.3,
                      "FiberForceLengthCurve.stiffness_at_one_norm_force": 5.0, "FiberForceLengthCurve.curviness": 0.3,
                      "TendonForceLengthCurve.strain_at_one_norm_force": 0.033,
                      "TendonForceLengthCurve.stiffness_at_one_norm_force": 50.0,
                      "TendonForceLengthCurve.norm_force_at_toe_end": 0.5, "TendonForceLengthCurve.curviness": 0.8,
                      "maximum_pennation_angle": 1.2, "minimum_activation": 0.05, "min_control": 0.05})
        if k % 5 == 2:
            m["TendonForceLengthCurve.strain_at_one_norm_force"] = 0.1
        m = {key: (repr(float(v)) if not isinstance(v, str) and key != "c" else v) for key, v in m.items()}
        out.append(m)
    return out


@pytest.fixture(scope="module")
def slider_case(tmp_path_factory):
    muscles = variant_muscles(48, seed=2)
    path = tmp_path_factory.mktemp("millard") / "sliders.osim"
    path.write_text(slider_model(muscles))
    c = np.array([m["c"] for m in muscles])
    rng = np.random.default_rng(11)
    n = 400
    q = c * (rng.uniform(0.3, 2.0, (n, len(c))) - 1.0)
    act = np.where(rng.random(q.shape) < 0.2, rng.choice([0.0, 1.0], q.shape), rng.uniform(0.0, 1.0, q.shape))
    return path, muscles, q, act


@pytest.mark.opensim
def test_every_option_matches_opensim(slider_case):
    """Damped, undamped, rigid; default, Rajagopal's and fully specified curves; pennation; minimum
    activation; extreme lengths (clamped fibres, slack tendons, OpenSim's failures)."""
    path, muscles, q, act = slider_case
    p = mm.params_from_osim_xml(path)
    ref = opensim_forces(path, q, act)
    np.testing.assert_allclose(ref["lengths"], q + np.array([m["c"] for m in muscles]), rtol=0, atol=1e-15)
    eq = mm.equilibrium(ref["lengths"], p, act)
    rel, err, fib = _compare(eq, ref, "sliders")
    lmin = mm.minimum_fiber_length(p)
    at_lmin = np.abs(ref["fiber_lengths"] - lmin) <= 1e-12
    np.testing.assert_array_equal(eq.clamped & ~ref["failed"], at_lmin & ~ref["failed"])
    variant = np.arange(p.n_muscles) % 8
    rigid = np.isin(variant, list(RIGID))
    print(f"\nsliders: {eq.failed.size} states: max rel error {rel:.2g}, abs {err:.2g} N, fibre {fib:.2g} m; "
          f"OpenSim fails {int(ref['failed'].sum())} (pamkin the same), clamped {int(eq.clamped.sum())}, "
          f"rigid-tendon states {int(rigid.sum()) * len(q)}")
    # the sample exercises every outcome
    assert ref["failed"].sum() > 20 and eq.clamped.sum() > 100
    assert (eq.clamped & (ref["tendon_forces"] > 0)).any()
    assert (~eq.clamped[:, rigid] & (eq.tendon_force[:, rigid] > 0)).any()
    # failures happen only in the undamped elastic model (OpenSim's search diverges there)
    assert set(variant[np.nonzero(ref["failed"].any(axis=0))[0]]) <= {1, 3}


@pytest.mark.opensim
def test_model_api_end_to_end(slider_case, millard_path):
    """pamkin.load_osim + Model.tendon_forces on the hand-built model (lengths from pamkin's own path
    engine) and on Gait2392's Millard variant, with the NaN + warning convention for failures."""
    path, _, q, act = slider_case
    model = pamkin.load_osim(path)
    ref = opensim_forces(path, q[:150], act[:150])
    with pytest.warns(EquilibriumWarning, match="no static equilibrium"):
        F = model.tendon_forces(q[:150], activation=act[:150])
    assert np.isnan(F).sum() == ref["failed"].sum() > 0
    with pytest.warns(EquilibriumWarning):
        eq = model.evaluate(q[:150], activation=act[:150]).equilibrium
    _compare(eq, ref, "sliders via Model")
    np.testing.assert_array_equal(F[~eq.failed], eq.tendon_force[~eq.failed])
    gait = pamkin.load_osim(millard_path)
    qg = gait.random_q(30, seed=4)
    ref = opensim_forces(millard_path, qg, 0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error", EquilibriumWarning)
        eq = gait.evaluate(qg, activation=0.5).equilibrium
    rel, _, _ = _compare(eq, ref, "gait2392 via Model")
    assert rel < 1e-8


@pytest.mark.opensim
@pytest.mark.needs_shared
@pytest.mark.parametrize("name, n", [("Gait10dof18musc/gait10dof18musc.osim", 100),
                                     ("Tug_of_War/Tug_of_War_Millard.osim", 100),
                                     ("Rajagopal/Rajagopal2016.osim", 150)])   # 34 rigid tendons, wrapping
def test_shared_millard_models_match_opensim(name, n):
    path = MODELS / name
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        model = pamkin.load_osim(path)
    q = model.random_q(n, seed=9)
    act = np.random.default_rng(3).uniform(0.0, 1.0, (n, len(model.muscles)))
    ref = opensim_forces(path, q, act)
    assert list(ref["muscles"]) == model.muscles
    L = model.lengths(q)
    np.testing.assert_allclose(L, ref["lengths"], rtol=0, atol=1e-9)
    eq = mm.equilibrium(L, model.millard_params, act)
    rel, err, fib = _compare(eq, ref, name)
    np.testing.assert_array_equal(model.tendon_forces(q, activation=act), eq.tendon_force)
    rigid = model.millard_params.ignore_tendon_compliance > 0
    print(f"\n{name}: {n} configurations x {len(model.muscles)} muscles ({int(rigid.sum())} rigid tendons): "
          f"max rel error {rel:.2g}, abs {err:.2g} N, fibre length {fib:.2g} m, clamped {int(eq.clamped.sum())}")


def test_mixed_thelen_and_millard_model(tmp_path):
    """A model with both muscle classes: each column from its own model."""
    text = slider_model(variant_muscles(4, seed=5))
    i = text.index('<Millard2012EquilibriumMuscle name="m1">')
    j = text.index("</Millard2012EquilibriumMuscle>", i) + len("</Millard2012EquilibriumMuscle>")
    thelen = text[i:j].replace("Millard2012EquilibriumMuscle", "Thelen2003Muscle")
    for tag in ("fiber_damping", "ignore_tendon_compliance", "minimum_activation", "min_control",
                "maximum_pennation_angle"):
        thelen = thelen.split(f"<{tag}>")[0] + thelen.split(f"</{tag}>")[-1] if f"<{tag}>" in thelen else thelen
    for curve in CURVE_TAGS:
        if f"<{curve} " in thelen:
            thelen = thelen.split(f"<{curve} ")[0] + thelen.split(f"</{curve}>")[-1]
    path = tmp_path / "mixed.osim"
    path.write_text(text[:i] + thelen + text[j:])
    model = pamkin.load_osim(path)
    q = model.random_q(20, seed=1)
    L = model.lengths(q)
    F = model.tendon_forces(q, activation=0.7)
    from pamkin.muscles import thelen2003  # noqa: PLC0415

    np.testing.assert_array_equal(F[:, [1]], thelen2003.tendon_force(L[:, [1]], model.thelen_params, 0.7))
    np.testing.assert_array_equal(F[:, [0, 2, 3]], mm.tendon_force(L[:, [0, 2, 3]], model.millard_params, 0.7)[0])
    eq = model.evaluate(q, activation=0.7).equilibrium
    np.testing.assert_array_equal(eq.tendon_force, F)
    # the Thelen muscle (m1) has no OpenSim equilibrium where the slider stretches its tendon far:
    # NaN there too (checked against OpenSim 4.6 on 200 configurations: the same 83 fail)
    np.testing.assert_array_equal(eq.failed[:, 1], np.isnan(F[:, 1]))
    Fr = model.tendon_forces(q, activation=0.7, rigid_tendon=True)
    np.testing.assert_array_equal(Fr[:, [0, 2, 3]],
                                  mm.tendon_force(L[:, [0, 2, 3]], model.millard_params, 0.7, True)[0])
