"""Tests of pamkin.robot.sizing: the thesis Size() reproduced, and the constrained sizing."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pamkin.robot import festo

from pamkin.robot import sizing
from pamkin.errors import ParameterError


def _quiet_thesis_size(lengths, mif):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no fallback warning expected
        return sizing.thesis_size(lengths, mif)


# --------------------------------------------------------------------------- thesis Size()


def test_thesis_size_fits_at_nine_percent() -> None:
    # Hand: longest 0.43, shortest 0.40 -> delta 0.03; size = 0.03/(1 - 1/1.09) = 0.03·1.09/0.09
    # = 0.363333 m; size + 2·0.0125 = 0.388333 <= 0.43, so no loop. Tendon 0.43 - 0.38833 =
    # 0.041667 m; contraction at the shortest length 0.03/0.36333 = 0.09/1.09 = 8.257 %.
    # mif 500 < 0.9·630 = 567 -> 10 mm.
    r = _quiet_thesis_size(np.array([0.41, 0.43, 0.40, 0.42]), 500.0)
    assert r.diameter_mm == 10 and not r.use_additional_muscles
    assert r.rest_length == pytest.approx(0.03 * 1.09 / 0.09, rel=1e-12)
    assert r.deformation == 1.09 and not r.fallback
    assert r.longest == 0.43 and r.shortest == 0.40
    assert r.tendon_length == pytest.approx(0.041666667, abs=1e-9)
    assert r.contraction == pytest.approx(0.09 / 1.09, rel=1e-12)
    np.testing.assert_allclose(r.strain([0.43, 0.40]), [0.0, 0.09 / 1.09], atol=1e-12)


def test_thesis_size_loop() -> None:
    # Hand: longest 0.40, delta 0.05. At def = 1.09 size = 0.05·1.09/0.09 = 0.6056 m: too long.
    # It fits when 0.05/(1 - 1/def) <= 0.40 - 0.025 = 0.375, i.e. 1 - 1/def >= 0.13333,
    # def >= 1.153846. On the 0.001 grid: def = 1.153 gives 0.05·1.153/0.153 = 0.376797 (no),
    # def = 1.154 gives 0.05·1.154/0.154 = 0.374675 m (yes). mif 600 in [567, 1350) -> 20 mm.
    r = _quiet_thesis_size([0.35, 0.40], 600.0)
    assert r.diameter_mm == 20
    assert r.deformation == pytest.approx(1.154, abs=1e-12)
    assert r.rest_length == pytest.approx(0.05 * 1.154 / 0.154, rel=1e-12)
    assert r.tendon_length == pytest.approx(0.40 - 0.025 - 0.05 * 1.154 / 0.154, abs=1e-12)
    assert not r.fallback


def test_thesis_size_fallback_is_flagged() -> None:
    # Hand: longest 0.30, delta 0.06: even def = 1.25 gives 0.06/(1 - 0.8) = 0.30 m = 5·delta,
    # and 0.30 + 0.025 > 0.30. The thesis silently returns 0.30 m (tendon -0.025 m).
    with pytest.warns(sizing.SizingFallbackWarning, match="5\\*delta"):
        r = sizing.thesis_size([0.24, 0.27, 0.30], 1400.0)
    assert r.fallback
    assert r.rest_length == pytest.approx(5 * 0.06, rel=1e-12)
    assert r.deformation == 1.25
    assert r.tendon_length == pytest.approx(-0.025, abs=1e-12)
    assert r.diameter_mm == 40  # 1350 <= 1400 <= 5400


def test_thesis_size_fits_late_in_the_loop() -> None:
    # Hand: longest 0.53, delta 0.10. It fits when 0.1·def/(def - 1) <= 0.53 - 0.025 = 0.505,
    # i.e. def >= 0.505/0.405 = 1.246914 -> def = 1.247, size 0.1·1.247/0.247 = 0.504858 m
    # (def = 1.246 gives 0.1·1.246/0.246 = 0.506504 m, too long).
    r = _quiet_thesis_size([0.43, 0.53], 100.0)
    assert r.deformation == pytest.approx(1.247, abs=1e-12)
    assert r.rest_length == pytest.approx(0.1 * 1.247 / 0.247, rel=1e-12)
    assert not r.fallback


def test_thesis_diameter_thresholds() -> None:
    # Fc = 0.9: 0.9·630 = 567, 0.9·1500 = 1350, 0.9·6000 = 5400.
    expected = {100: 10, 566.9: 10, 567: 20, 1349.9: 20, 1350: 40, 5400: 40, 5400.1: None}
    for mif, d in expected.items():
        r = _quiet_thesis_size([0.40, 0.43], mif)
        assert r.diameter_mm == d, mif
        assert r.use_additional_muscles == (d is None)


def test_thesis_size_bad_input() -> None:
    with pytest.raises(ParameterError, match="constant"):
        sizing.thesis_size([0.4, 0.4, 0.4], 500)
    with pytest.raises(ParameterError, match="at least 2"):
        sizing.thesis_size([0.4], 500)
    with pytest.raises(ParameterError, match="NaN"):
        sizing.thesis_size([0.4, np.nan], 500)
    with pytest.raises(ParameterError, match="positive"):
        sizing.thesis_size([0.4, -0.1], 500)
    with pytest.raises(ParameterError, match="scalar"):
        sizing.thesis_size(0.4, 500)
    with pytest.raises(ParameterError, match="max_isometric_force"):
        sizing.thesis_size([0.3, 0.4], float("nan"))
    with pytest.raises(ParameterError, match="max_isometric_force"):
        sizing.thesis_size([0.3, 0.4], -5)


# --------------------------------------------------------------------------- size_pam


def test_size_pam_hand_example() -> None:
    # Hand: L 0.35..0.40, fittings 2·0.0125, no tendon, no pretension -> l0 = 0.375 m,
    # contraction at 0.35 m: 0.05/0.375 = 0.13333.
    # 10 mm: kmax(0.375) = 0.175 (>= 0.2809 m) OK; force 0.9·303.49·atan(19.0216·0.3675)
    #   = 0.9·303.49·1.42867 = 390.2 N < 600 N -> infeasible.
    # 20 mm: limit min(0.255, 0.25) = 0.25 OK; force 0.9·922.37·atan(15.376·0.362)
    #   = 0.9·922.37·1.39301 = 1156.4 N >= 600 N -> chosen.
    s = sizing.size_pam([0.36, 0.35, 0.40], 600.0)
    assert s.feasible and s.reason == ""
    assert (s.diameter_mm, s.n_parallel) == (20, 1)
    assert s.rest_length == pytest.approx(0.375, rel=1e-12)
    assert s.tendon_length == 0.0
    assert s.max_contraction == pytest.approx(0.05 / 0.375, rel=1e-12)
    assert s.max_stretch == pytest.approx(0.0, abs=1e-15)
    assert s.contraction_limit == 0.25
    assert s.force_capacity == pytest.approx(1156.4, abs=0.1)
    assert s.reference_length == pytest.approx(0.40, rel=1e-12)
    np.testing.assert_allclose(s.strain([0.40, 0.35]), [0.0, 0.05 / 0.375], atol=1e-12)
    c10 = s.candidates[0]
    assert c10.diameter_mm == 10 and not c10.feasible
    assert c10.force_capacity == pytest.approx(390.2, abs=0.1)
    assert any(v.startswith("force") for v in c10.violations)


def test_size_pam_parallel() -> None:
    # 10 mm only, 700 N: one PAM gives 390.2 N (above), two give 780.4 N >= 700 N.
    s = sizing.size_pam([0.35, 0.40], 700.0, diameter_mm=10)
    assert s.feasible and (s.diameter_mm, s.n_parallel) == (10, 2)
    assert s.force_capacity == pytest.approx(780.4, abs=0.2)
    s1 = sizing.size_pam([0.35, 0.40], 700.0, diameter_mm=10, max_parallel=1)
    assert not s1.feasible and "force" in s1.reason


def test_size_pam_pretension_and_tendon() -> None:
    # Hand: L 0.30..0.36, f 0.0125, t 0.05, s 0.03 (20 mm):
    # a = 0.075, l0 = (0.36 - 0.075)/1.03 = 0.276699 m, eps(0.30) = 1 - 0.225/0.276699 = 0.186842,
    # eps(0.36) = -0.03, reference length l0 + a = 0.351699 m.
    s = sizing.size_pam([0.30, 0.36], 900.0, diameter_mm=20, min_tendon=0.05, pretension=0.03)
    assert s.feasible
    assert s.rest_length == pytest.approx(0.285 / 1.03, rel=1e-12)
    assert s.max_contraction == pytest.approx(1 - 0.225 * 1.03 / 0.285, rel=1e-12)
    assert s.max_stretch == pytest.approx(0.03, rel=1e-12)
    assert s.tendon_length == 0.05
    assert s.reference_length == pytest.approx(0.285 / 1.03 + 0.075, rel=1e-12)
    # The same stretch is beyond the 10 mm limit (3 % is allowed, 4 % is not).
    s10 = sizing.size_pam([0.30, 0.36], 100.0, diameter_mm=10, pretension=0.04)
    assert not s10.feasible and "pretension" in s10.reason


def test_size_pam_infeasible_is_reported_not_returned() -> None:
    # L 0.20..0.30: l0 = 0.275, contraction 0.1/0.275 = 0.364 > 0.25 for every diameter.
    s = sizing.size_pam([0.20, 0.30], 300.0)
    assert not s.feasible
    assert "contraction" in s.reason and all(f"{d} mm" in s.reason for d in (10, 20, 40))
    assert s.diameter_mm is None and s.n_parallel is None
    assert math.isnan(s.rest_length) and math.isnan(s.force_capacity)
    assert len(s.candidates) == 9 and not any(c.feasible for c in s.candidates)
    # Path shorter than the fittings.
    s = sizing.size_pam([0.01, 0.02], 10.0)
    assert not s.feasible and "path" in s.reason
    # Too short for Festo's 40 mm (nominal length >= 0.12 m): l0 = 0.1 - 0.025 = 0.075 m.
    s = sizing.size_pam([0.095, 0.1], 3000.0, diameter_mm=40)
    assert not s.feasible and "nominal length" in s.reason


def test_thesis_robot_case_that_thesis_size_cannot_fit() -> None:
    # The thesis's fallback case above: size_pam says why (contraction 0.06/0.275 = 0.218 fits
    # 40 mm's 25 % but not 10 mm's kmax 0.1692..0.175), instead of a too-long PAM.
    s = sizing.size_pam([0.24, 0.30], 1400.0)
    assert s.feasible and s.diameter_mm == 40
    assert s.rest_length + 2 * s.fitting_length <= 0.30 + 1e-12


def test_size_pam_bad_input() -> None:
    with pytest.raises(ParameterError, match="NaN"):
        sizing.size_pam([0.3, np.nan], 100)
    with pytest.raises(ParameterError, match="positive"):
        sizing.size_pam([-0.3, 0.4], 100)
    with pytest.raises(ParameterError, match="diameter"):
        sizing.size_pam([0.3, 0.4], 100, diameter_mm=30)
    with pytest.raises(ParameterError, match="max_parallel"):
        sizing.size_pam([0.3, 0.4], 100, max_parallel=4)
    with pytest.raises(ParameterError, match="max_isometric_force"):
        sizing.size_pam([0.3, 0.4], float("nan"))
    with pytest.raises(ParameterError, match="min_tendon"):
        sizing.size_pam([0.3, 0.4], 100, min_tendon=-0.01)
    with pytest.raises(ParameterError, match="force_basis"):
        sizing.size_pam([0.3, 0.4], 100, force_basis="guess")
    with pytest.raises(ParameterError, match="at least 1"):
        sizing.size_pam([], 100)


# --------------------------------------------------------------------------- property


@settings(max_examples=300, deadline=None)
@given(
    shortest=st.floats(0.03, 1.5),
    spread=st.floats(0.0, 0.6),  # delta as a fraction of the shortest path length
    inner=st.lists(st.floats(0.0, 1.0), max_size=5),
    mif=st.floats(1.0, 12000.0),
    pretension=st.sampled_from([0.0, 0.01, 0.03, 0.045, 0.06]),
    min_tendon=st.floats(0.0, 0.2),
    fitting=st.sampled_from([0.0, 0.0125, 0.02]),
    max_rel=st.floats(0.3, 1.0),
    force_basis=st.sampled_from(["v3", "festo"]),
    diameter=st.sampled_from([None, 10, 20, 40]),
    max_parallel=st.integers(1, 3),
)
def test_size_pam_never_violates_its_limits(shortest, spread, inner, mif, pretension, min_tendon,
                                            fitting, max_rel, force_basis, diameter,
                                            max_parallel) -> None:
    delta = spread * shortest
    lengths = np.array([shortest, shortest + delta] + [shortest + u * delta for u in inner])
    s = sizing.size_pam(lengths, mif, pretension=pretension, min_tendon=min_tendon,
                        fitting_length=fitting, max_relative_strain=max_rel,
                        force_basis=force_basis, diameter_mm=diameter, max_parallel=max_parallel)
    if not s.feasible:
        assert s.reason.startswith("no feasible PAM")
        assert math.isnan(s.rest_length) and s.diameter_mm is None
        assert all(c.violations for c in s.candidates)
        return
    d, n, l0 = s.diameter_mm, s.n_parallel, s.rest_length
    assert d in festo.DIAMETERS_MM and 1 <= n <= max_parallel
    assert diameter is None or d == diameter
    tol = 1e-12
    # Geometry: rest length + fittings + tendon = path length at the reference; tendon >= min.
    assert s.tendon_length >= min_tendon >= 0
    assert l0 > 0
    lo, hi = festo.nominal_length_range(d)
    assert lo <= l0 <= hi
    # Strains recomputed from the lengths themselves, not from the result's fields.
    eps = (l0 + 2 * fitting + s.tendon_length - lengths) / l0
    km = float(festo.kmax(l0, d))
    assert eps.max() <= min(max_rel * km, festo.max_contraction(d)) + tol
    assert -eps.min() <= festo.max_pretension(d) + tol
    # Force: n PAMs at the safety factor carry the required force.
    f_one = float(festo.f620(l0, d)) if force_basis == "v3" else festo.F_MAX_THEORETICAL[d]
    assert n * 0.9 * f_one >= mif * (1 - tol)
    # Smallest choice first: no earlier candidate was feasible.
    order = [(c.n_parallel, festo.DIAMETERS_MM.index(c.diameter_mm)) for c in s.candidates]
    chosen = order.index((n, festo.DIAMETERS_MM.index(d)))
    assert not any(c.feasible for c in s.candidates[:chosen])
