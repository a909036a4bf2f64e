"""Muscle path lengths, moment arms, forces and torques of Gait2392 against OpenSim 4.6."""

from __future__ import annotations

import numpy as np
import pytest

import pamkin
from pamkin.errors import ParameterError, RangeWarning
from pamkin.opensim.model_file import ConditionalPathPoint
from pamkin.human.paths import CONDITIONAL_TOLERANCE, path_length, path_moment_arm, point_velocity

from opensim_ref import opensim_reference


def _switch_configs(model, n_per=6, seed=0):
    """Configurations right at both sides of every conditional point's switching angle."""
    rng = np.random.default_rng(seed)
    rows = []
    for mu in model.osim.muscles:
        for p in mu.points:
            if isinstance(p, ConditionalPathPoint):
                c = model.coordinates.index(p.coordinate)
                lo_c, hi_c = model.coordinate_ranges[c]
                for edge in (p.range[0] - CONDITIONAL_TOLERANCE, p.range[1] + CONDITIONAL_TOLERANCE):
                    for off in (-3e-6, 3e-6, -4e-7, 4e-7)[: n_per]:
                        if lo_c <= edge + off <= hi_c:
                            q = model.random_q(1, seed=int(rng.integers(1 << 30)))[0]
                            q[c] = edge + off
                            rows.append(q)
    return np.array(rows)


@pytest.fixture(scope="module")
def samples(gait2392):
    q = np.vstack([gait2392.random_q(300, seed=31), _switch_configs(gait2392)])
    return q


@pytest.fixture(scope="module")
def reference(gait2392_path, samples):
    return opensim_reference(gait2392_path, samples, what=("lengths", "moment_arms", "tendon_forces"))


def _near_switch(model, q, tol=1e-6):
    """(N, n_muscles) True where a conditional point of the muscle is within tol of switching."""
    near = np.zeros((len(q), len(model.muscles)), dtype=bool)
    for m, mu in enumerate(model.osim.muscles):
        for p in mu.points:
            if isinstance(p, ConditionalPathPoint):
                v = q[:, model.coordinates.index(p.coordinate)]
                for edge in (p.range[0] - CONDITIONAL_TOLERANCE, p.range[1] + CONDITIONAL_TOLERANCE):
                    near[:, m] |= np.abs(v - edge) < tol
    return near


@pytest.mark.opensim
@pytest.mark.parametrize("engine", ["compiled", "numpy"])
def test_lengths_match_opensim(gait2392_path, samples, reference, engine):
    model = pamkin.load_osim(gait2392_path, engine=engine)
    assert list(reference["muscles"]) == model.muscles
    err = np.abs(model.lengths(samples) - reference["lengths"]).max()
    print(f"{engine}: max length error {err:.2e} m over {len(samples)} configurations x 92 muscles")
    assert err <= 1e-8


@pytest.mark.opensim
@pytest.mark.parametrize("engine", ["compiled", "numpy"])
def test_moment_arms_match_opensim(gait2392_path, samples, reference, engine):
    model = pamkin.load_osim(gait2392_path, engine=engine)
    pairs = reference["pairs"]
    assert {tuple(p) for p in pairs} == {tuple(p) for p in model.paths.pairs}
    ma = model.moment_arms(samples)[:, pairs[:, 0], pairs[:, 1]]
    err = np.abs(ma - reference["moment_arms"])
    skip = _near_switch(model, samples)[:, pairs[:, 0]]
    print(f"{engine}: max moment-arm error {err[~skip].max():.2e} m over {err.size - skip.sum()} samples; "
          f"{int(skip.sum())} samples within 1e-6 rad of a conditional switch skipped")
    assert err[~skip].max() <= 1e-7
    assert skip.sum() < err.size * 0.01


def test_engines_agree(gait2392):
    numpy_model = pamkin.gait2392(engine="numpy")
    q = np.vstack([gait2392.random_q(500, seed=32), _switch_configs(gait2392)])
    a, b = gait2392.path_result(q), numpy_model.path_result(q)
    assert np.array_equal(a.pairs, b.pairs)
    assert np.abs(a.lengths - b.lengths).max() < 1e-13
    assert np.abs(a.moment_arms - b.moment_arms).max() < 1e-12


def test_moment_arms_are_minus_dL_dq(gait2392):
    q = gait2392.random_q(40, seed=33)
    near = _near_switch(gait2392, q, tol=1e-4)
    R = gait2392.moment_arms(q)
    h = 1e-6
    fd = np.empty_like(R)
    for c in range(len(gait2392.coordinates)):
        dq = np.zeros(len(gait2392.coordinates))
        dq[c] = h
        Lp = gait2392.path_result(q + dq, moment_arms=False).lengths
        Lm = gait2392.path_result(q - dq, moment_arms=False).lengths
        fd[:, :, c] = -(Lp - Lm) / (2 * h)
    err = np.abs(R - fd)[~near]
    assert err.max() < 1e-7


def test_conditional_point_switches_length(gait2392):
    """semimem_r's conditional point leaves the path below knee angle -0.558505 (-1e-5)."""
    m = gait2392.muscles.index("semimem_r")
    edge = -0.558505 - CONDITIONAL_TOLERANCE
    L = gait2392.lengths({"knee_angle_r": np.array([edge - 1e-9, edge + 1e-9])})[:, m]
    assert L[1] - L[0] > 1e-6   # the via point makes the path longer where present


def test_generic_path_formulas_equal_engine(gait2392):
    """The single-path formulas (used with CasADi by the optimiser) give the engine's numbers."""
    q = gait2392.random_q(25, seed=34)
    st = gait2392.forward(q)
    W, T = gait2392.paths.body_jacobian(st)
    res = gait2392.path_result(q)
    for name in ("glut_max1_r", "bifemlh_r", "soleus_r", "ercspn_l"):
        m = gait2392.muscles.index(name)
        pts = gait2392.osim.muscles[m].points
        bodies = [gait2392.bodies.index(p.body) for p in pts]
        X = [gait2392.kinematics.point_positions(st, b, np.array([p.location]))[:, 0].T
             for p, b in zip(pts, bodies)]
        assert np.allclose(path_length(X), res.lengths[:, m], atol=1e-14)
        for k in np.nonzero(res.pairs[:, 0] == m)[0]:
            c = res.pairs[k, 1]
            V = [point_velocity(W[:, b, c].T, T[:, b, c].T, x) for b, x in zip(bodies, X)]
            assert np.allclose(path_moment_arm(X, V), res.moment_arms[:, k], atol=1e-13)


@pytest.mark.opensim
def test_tendon_forces_match_opensim(gait2392, samples, reference):
    F = gait2392.tendon_forces(samples)
    Fr = reference["tendon_forces"]
    err = np.abs(F - Fr)
    rel = err / np.maximum(np.abs(Fr), 1e-300)
    ok = (rel <= 1e-4) | (err <= 1e-3)
    st = gait2392.evaluate(samples)
    print(f"max tendon force error {err.max():.2e} N, max relative {rel[np.abs(Fr) > 1].max():.2e}; "
          f"{int(st.equilibrium.clamped.sum())} clamped fibre samples")
    assert ok.all()


def test_torques_are_force_times_moment_arm(gait2392):
    q = gait2392.random_q(30, seed=35)
    T = gait2392.torques(q)
    F = gait2392.tendon_forces(q)
    R = gait2392.moment_arms(q)
    assert np.allclose(T, F[:, :, None] * R, rtol=0, atol=1e-9)
    pos, neg = gait2392.capacity(q)
    assert np.allclose(pos - neg, np.abs(T).sum(axis=1))
    groups = gait2392.group_torques(q, {"quads": ["rect_fem_r", "vas_int_r", "vas_lat_r", "vas_med_r"]})
    idx = [gait2392.muscles.index(n) for n in ("rect_fem_r", "vas_int_r", "vas_lat_r", "vas_med_r")]
    assert np.allclose(groups["quads"], T[:, idx].sum(axis=1))
    knee = gait2392.coordinates.index("knee_angle_r")
    assert (groups["quads"][:, knee] > 0).all()     # knee extensors: positive knee torque


def test_rigid_tendon_option(gait2392):
    q = gait2392.random_q(10, seed=36)
    Fr = gait2392.tendon_forces(q, rigid_tendon=True)
    assert Fr.shape == (10, 92) and np.isfinite(Fr).all() and (Fr >= 0).all()


def test_millard_forces(millard_path):
    """Millard2012 forces (pamkin.muscles.millard2012; compared with OpenSim in test_millard2012.py)."""
    model = pamkin.load_osim(millard_path)
    q = model.default_q
    assert model.lengths(q).shape == (1, 92)      # paths work
    F = model.tendon_forces(q)
    assert F.shape == (1, 92) and np.isfinite(F).all() and (F >= 0).all()


@pytest.mark.parametrize("prop,value,match", [("optimal_fiber_length", "-0.05", "optimal_fiber_length"),
                                              ("max_isometric_force", "0", "max_isometric_force")])
def test_out_of_range_parameters(tmp_path, gait2392_path, prop, value, match):
    text = gait2392_path.read_text()
    i = text.index('<Thelen2003Muscle name="semimem_r">')
    j = text.index(f"<{prop}>", i)
    k = text.index(f"</{prop}>", j)
    bad = tmp_path / "bad_params.osim"
    bad.write_text(text[:j] + f"<{prop}>{value}" + text[k:])
    with pytest.raises(ParameterError, match=f"semimem_r.*{match}|{match}.*semimem_r"):
        pamkin.load_osim(bad)


def test_out_of_range_configuration_is_flagged(gait2392):
    q = gait2392.default_q
    q[gait2392.coordinates.index("hip_flexion_r")] = 3.0
    with pytest.warns(RangeWarning, match="hip_flexion_r"):
        gait2392.lengths(q)


def test_chunked_evaluation_equals_one_batch(gait2392):
    q = gait2392.random_q(250, seed=37)
    whole = gait2392.evaluate(q)
    parts = list(gait2392.evaluate_chunks(q, chunk=64))
    assert [sl.start for sl, _ in parts] == [0, 64, 128, 192]
    assert np.array_equal(np.vstack([st.tendon_forces for _, st in parts]), whole.tendon_forces)
    assert np.array_equal(np.vstack([st.pair_torques for _, st in parts]), whole.pair_torques)


@pytest.mark.opensim
def test_every_muscle_coordinate_pair_matches_opensim(gait2392, gait2392_path):
    """All 92 x 23 moment arms (not only the 262 spanned pairs) at a few configurations."""
    q = gait2392.random_q(4, seed=38)
    pairs = np.array([(m, c) for m in range(92) for c in range(23)])
    ref = opensim_reference(gait2392_path, q, what=("moment_arms",), pairs=pairs)
    R = gait2392.moment_arms(q)[:, pairs[:, 0], pairs[:, 1]]
    err = np.abs(R - ref["moment_arms"])
    print(f"all {len(pairs)} pairs: max moment-arm error {err.max():.2e} m")
    assert err.max() <= 1e-7
