"""tools/human_path_reference.py: the grid search recovers a PAM that made the target, and finds none where
the path's excursion exceeds what a PAM's strain allows."""

from __future__ import annotations

import importlib.util

import numpy as np

from pamkin.robot import festo
from locations import ROOT

_spec = importlib.util.spec_from_file_location(
    "human_path_reference", ROOT / "tools" / "human_path_reference.py")
hpr = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hpr)
FIT = 0.0125


def test_grid_search_recovers_the_pam_that_made_the_torque():
    u = np.linspace(-1, 1, 201)
    L = 0.45 + 0.03 * u                                  # path length [m]
    R = np.zeros((len(u), 2))
    R[:, 0] = 0.04 - 0.01 * u                            # moment arm about coordinate 0 [m]
    lo, hi = festo.nominal_length_range(20)
    l0 = np.linspace(lo, min(hi, L.max()), 60)[40]       # a resting length on the search grid
    t = L.max() - 2 * FIT - l0 * (1 + 0.01)              # stretched by 1 % at the longest
    eps = (l0 - (L - 2 * FIT - t)) / l0
    assert eps.max() < 0.2
    T = 2 * festo.force(eps, l0, hpr.PRESSURE, 20)[:, None] * R
    J, d, n, l0_found, _ = hpr.best_pam(L, R, T, 0, [0], FIT)
    assert (d, n) == (20, 2) and abs(l0_found - l0) < 0.008       # within one resting-length grid step
    assert J < 1e-3                                       # the strain grid is 40 steps: not exact


def test_no_pam_meets_the_limits_of_a_path_changing_by_sixty_percent():
    u = np.linspace(-1, 1, 101)
    L = 0.25 + 0.075 * u                                 # 150 of 325 mm: 46 %
    R = np.full((len(u), 1), 0.03)
    T = 100 * R
    assert hpr.best_pam(L, R, T, 0, [0], FIT) is None
