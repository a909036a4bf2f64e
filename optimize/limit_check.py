"""The strain and force limits of a solved route, checked on many more poses than it was solved on.

The problem imposes the contraction, stretch and rated-force limits at its constraint samples (grids,
training poses, range corners). Between them a route can still exceed a limit: held-out poses gave
rectus femoris a contraction of 0.258 (limit 0.25) where its range corners gave at most 0.243. After
the bone-mesh rounds, :func:`limit_excess` evaluates the saved route at :data:`N_CHECK` poses of the
coordinates it crosses (half uniform, half on the range boundary; the optimiser's own random stream,
never the audit's); where a limit is exceeded, :func:`tighten` lowers that limit in the problem by the
excess (plus :data:`EXTRA`) and the rounds run again — an exchange of the worst poses for a margin.
"""

from __future__ import annotations

import warnings

import numpy as np
from pamkin.optimize.samples import (
    OPTIMIZE_STREAM,
    RATED_MARGIN,
    STRAIN_MARGIN,
    boundary_poses,
    poses_from_unit,
    with_dependencies,
)

from pamkin.errors import RangeWarning
from pamkin.human.paths import PathSet
from pamkin.robot import festo
from pamkin.robot.design import Pam, pam_length

#: Check poses per actuator (half uniform, half on the range boundary).
N_CHECK = 2000
#: Added to a tightening beyond the measured excess [strain; N for forces: EXTRA × rated force].
EXTRA = 0.002
#: Families of the problem's limit rows (``ActuatorProblem.family``) and what they bound.
CONTRACTION_KMAX = "contraction <= kmax"
CONTRACTION_FESTO = "contraction <= Festo maximum contraction"
STRETCH = "stretch <= Festo pretension limit"
RATED = "force per PAM <= Festo rated force"


def check_poses(model, rom, coords: list[str], seed: int, actuator: int, n: int = N_CHECK) -> np.ndarray:
    """``n`` poses of ``coords``: half uniform within the range, half on its boundary (others 0)."""
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(OPTIMIZE_STREAM, int(actuator), 3)))
    coords = with_dependencies(model, rom, coords)
    uniform = poses_from_unit(model, rom, coords, rng.random((n - n // 2, len(coords))))
    return np.vstack([uniform, boundary_poses(model, rom, coords, rng, n // 2)])


def rated_bound(diameter: int) -> float:
    """The force per PAM [N] the rated-force rows (:data:`RATED`) allow: 98 % of Festo's rating."""
    return festo.F_MAX_THEORETICAL[diameter] * (1.0 - RATED_MARGIN)


def limit_rows(cfg, diameter: int, strain, unit_force, kmax) -> list[tuple]:
    """The strain and force limits of one PAM as rows ``(family, g, lower, upper)`` with lower ≤ g ≤ upper:
    contraction ≤ kmax (scaled) and stretch ≤ Festo's pretension, and with ``cfg.limits.rated_force`` force per
    PAM ≤ 98 % of Festo's rating and contraction ≤ Festo's maximum, each less its margin. ``strain``,
    ``unit_force`` [N] and ``kmax`` are numpy arrays or CasADi expressions alike: the one definition of
    these limits for the problem (:class:`optimize.problem.ActuatorProblem`) and for :func:`limit_excess`."""
    pre = max(cfg.limits.pretension_scale * festo.max_pretension(diameter) - STRAIN_MARGIN, 0.0)
    rows = [(CONTRACTION_KMAX, strain - (cfg.limits.kmax_scale * kmax - STRAIN_MARGIN), -np.inf, 0.0),
            (STRETCH, strain, -pre, np.inf)]
    if cfg.limits.rated_force:
        rows.append((RATED, unit_force - rated_bound(diameter), -np.inf, 0.0))
        # Festo's permissible contraction (0.25) is below the force model's kmax for 20 and 40 mm
        rows.append((CONTRACTION_FESTO, strain, -np.inf, festo.max_contraction(diameter) - STRAIN_MARGIN))
    return rows


def limit_excess(pam: Pam, model, q: np.ndarray, cfg, fitting_length: float) -> dict[str, float]:
    """By how much the PAM ``pam`` (its route, sizes, diameter, parallel count) exceeds each limit of
    the problem (:func:`limit_rows`) at the poses ``q``; only the exceeded ones, in the rows' units
    (strain, or N per PAM)."""
    kin = model.kinematics
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        L = PathSet(kin, ["route"], [pam.points]).evaluate(kin.forward(q, warn_range=False)).lengths[:, 0]
    l0, d = pam.resting_length_m, pam.diameter_mm
    eps = (l0 - pam_length(L, pam.tendon_length_m, pam.transmission, fitting_length)) / l0
    F = festo.force(eps, l0, cfg.pressure_Pa, d, model=cfg.force_model)
    out = {fam: float(max(np.max(g) - hi, lo - np.min(g)))
           for fam, g, lo, hi in limit_rows(cfg, d, eps, F, float(festo.kmax(l0, d, model=cfg.force_model)))}
    return {k: v for k, v in out.items() if v > 1e-9}


def tighten(prob, excess: dict[str, float]) -> None:
    """Lower the limits of ``prob`` (its ``lbg``/``ubg``, in place) by each family's excess + :data:`EXTRA`."""
    fam = np.array(prob.family)
    for name, amount in excess.items():
        rows = fam == name
        if name == STRETCH:
            prob.lbg[rows] += amount + EXTRA
        elif name == RATED:
            prob.ubg[rows] -= amount + EXTRA * festo.F_MAX_THEORETICAL[prob.d]
        else:
            prob.ubg[rows] -= amount + EXTRA
