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

from pamkin import festo
from pamkin.design import Pam
from pamkin.errors import RangeWarning
from pamkin.paths import PathSet

from .samples import OPTIMIZE_STREAM, STRAIN_MARGIN, boundary_poses, with_dependencies

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
    q = np.zeros((n - n // 2, len(model.coordinates)))
    for c, v in rom.from_unit(coords, rng.random((len(q), len(coords)))).items():
        q[:, model.coordinates.index(c)] = v
    return np.vstack([q, boundary_poses(model, rom, coords, rng, n // 2)])


def limit_excess(pam: Pam, model, q: np.ndarray, cfg, fitting_length: float) -> dict[str, float]:
    """By how much the PAM ``pam`` (its route, sizes, diameter, parallel count) exceeds each limit of
    the problem at the poses ``q`` (the same limits and margins as :class:`optimize.problem.ActuatorProblem`);
    only the exceeded ones, in the rows' units (strain, or N per PAM)."""
    from .problem import RATED_MARGIN  # noqa: PLC0415  (casadi: workers only)

    kin = model.kinematics
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        L = PathSet(kin, ["route"], [pam.points]).evaluate(kin.forward(q, warn_range=False)).lengths[:, 0]
    l0, d = pam.resting_length_m, pam.diameter_mm
    eps = (l0 - (L - 2 * fitting_length - pam.tendon_length_m)) / l0
    kmax = float(festo.kmax(l0, d, model=cfg.force_model))
    out = {CONTRACTION_KMAX: float(eps.max() - (cfg.kmax_scale * kmax - STRAIN_MARGIN)),
           STRETCH: float(-eps.min() - max(cfg.pretension_scale * festo.max_pretension(d) - STRAIN_MARGIN, 0.0))}
    if cfg.rated_force:
        out[CONTRACTION_FESTO] = float(eps.max() - (festo.max_contraction(d) - STRAIN_MARGIN))
        F = festo.force(eps, l0, cfg.pressure_Pa, d, model=cfg.force_model)
        out[RATED] = float(np.max(F) - festo.F_MAX_THEORETICAL[d] * (1.0 - RATED_MARGIN))
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
