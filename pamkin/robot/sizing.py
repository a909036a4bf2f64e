"""Sizing Festo PAMs (diameter, resting length, tendon) from a muscle's path-length range.

Both functions take the path (musculotendon) lengths [m] of one actuator route over the range
of motion — a 1-D array (any array is flattened, like the thesis's length matrix) — and the
force the PAM must replace [N].

:func:`thesis_size` reproduces the thesis's ``Size.m`` (section 2.5) exactly:

* Diameter, with safety factor Fc = 0.9 on Festo's theoretical forces 630/1500/6000 N::

      mif <  0.9·630               → 10 mm
      0.9·630  <= mif < 0.9·1500   → 20 mm
      0.9·1500 <= mif <= 0.9·6000  → 40 mm
      otherwise                    → 'Use additional muscles' (diameter None)

* Resting length, with Δ = longest − shortest, fittings x = 0.0125 m::

      size = Δ/(1 − 1/1.09)
      if size + 2x > longest:
          for def = 1.09:0.001:1.25          (MATLAB colon)
              if size + 2x > longest and def <= 1.25: size = Δ/(1 − 1/def)
              elseif size + 2x <= longest: break

  ``def`` is a length *ratio* l0/(l0 − Δ): the thesis's "9 %" and "25 %" are contractions
  Δ/l0 = 1 − 1/def of 8.26 % and 20 %. This is reproduced as written.

Defect decisions (thesis ``Size()``):

* When even def = 1.25 does not fit (size + 2x > longest), the thesis silently returns
  size = 5·Δ, a PAM longer than its route allows (negative artificial tendon). pamkin returns
  the same number — so that thesis results can be reproduced — but flags it: ``fallback=True``
  and a :class:`SizingFallbackWarning`. Use :func:`size_pam` for designs.
* Δ = 0 ("display an error" in the thesis, which then returned 0) raises ParameterError.
* mif above 0.9·6000 N: the thesis returns the string 'Use additional muscles'; here
  ``diameter_mm=None`` and ``use_additional_muscles=True`` (the resting length is still
  computed, as in the thesis).

:func:`size_pam` is the sizing pamkin designs with. It states its constraints and reports
infeasibility instead of returning a number. For each candidate diameter d (10, 20, 40 mm, or
the one asked for) and number of parallel PAMs n = 1 … max_parallel, with fittings f per end,
artificial tendon t = ``min_tendon`` ≥ 0 and a chosen stretch s = ``pretension`` ≥ 0 at the
longest path length L_max::

    a        = 2·f + t                         (everything in the path that is not PAM)
    l0       = (L_max − a)/(1 + s)             (resting length)
    L_ref    = l0 + 2·f + t                    (path length at which the PAM is at rest)
    ε(L)     = (L_ref − L)/l0 = 1 − (L − a)/l0 (contraction at path length L)

so ε(L_max) = −s and the largest contraction is ε(L_min) = 1 − (L_min − a)·(1 + s)/(L_max − a).
For a fixed tendon and stretch this is the choice that keeps the contraction at the shortest
path length — where every model's force is lowest — as small as the stretch limit allows
(s = 0 puts the PAM at rest at the longest path length, like the thesis). The candidate is
feasible iff all of these hold (each violated one is named in ``violations``):

* ``path``: l0 > 0 (the path is longer than fittings and tendon);
* ``nominal length``: Festo's nominal-length range, l_min(d) ≤ l0 ≤ 9 m;
* ``contraction``: ε(L_min) ≤ min(max_relative_strain·kmax(l0, d), max_contraction(d))
  (kmax from :func:`pamkin.robot.festo.kmax`, v3 defaults, unless given; max_contraction 25 %);
* ``pretension``: s ≤ max_pretension(d) (3/4/5 % for 10/20/40 mm);
* ``force``: n·safety_factor·F(d, l0) ≥ required force, with F = F620(l0) of the v3 model
  (``force_basis="v3"``, the force a PAM of that length really reaches at ε = 0 and 620 kPa)
  or Festo's theoretical 630/1500/6000 N (``force_basis="festo"``, the thesis's basis).

The first feasible candidate in the order (n = 1: 10, 20, 40 mm; n = 2: …) is returned, i.e.
parallel PAMs only when no single one is strong enough. If none is feasible the result has
``feasible=False``, NaN numbers, and a ``reason`` naming the violated limits of every
diameter; all candidates with their numbers are in ``candidates``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from pamkin.errors import ParameterError
from pamkin.robot import festo

__all__ = [
    "FITTING_LENGTH",
    "Candidate",
    "Sizing",
    "SizingFallbackWarning",
    "ThesisSize",
    "size_pam",
    "thesis_size",
]

FITTING_LENGTH = 0.0125
"""Length of one air fitting [m] (thesis Size.m: ``x = 0.0125``)."""

THESIS_SAFETY_FACTOR = 0.9
"""Thesis Size.m ``Fc``: fraction of Festo's theoretical force a PAM may be sized for."""

THESIS_OPT_MAX = 1.09
"""Thesis Size.m ``opt_max``: 'maximum allowable length change for optimal performance'."""

THESIS_MAX_DEF = 1.25
"""Thesis Size.m ``max_def``: 'maximum allowable length change'."""

THESIS_DEF_STEP = 0.001
"""Thesis Size.m loop step of ``def``."""


class SizingFallbackWarning(UserWarning):
    """The thesis Size() could not fit the PAM and fell back to 5·Δ (kept only for reproduction)."""


def _lengths(lengths: Iterable[float] | np.ndarray, min_size: int) -> np.ndarray:
    try:
        a = np.asarray(lengths, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"lengths must be numbers [m]: {exc}") from exc
    if a.ndim == 0:
        raise ParameterError("lengths must be an array of path lengths [m], got a scalar")
    a = a.ravel()
    if a.size < min_size:
        raise ParameterError(f"lengths needs at least {min_size} path length(s), got {a.size}")
    if np.isnan(a).any():
        raise ParameterError("lengths contains NaN")
    if not np.isfinite(a).all():
        raise ParameterError("lengths contains infinite values")
    if (a <= 0).any():
        raise ParameterError(f"lengths must be positive [m], got min {a.min()}")
    return a


def _positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if math.isnan(v):
        raise ParameterError(f"{name} is NaN")
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ParameterError(f"{name} must be {'>= 0' if allow_zero else '> 0'} and finite, got {v}")
    return v


def _matlab_colon(a: float, step: float, b: float) -> np.ndarray:
    """``a:step:b`` as MATLAB computes it (first half a + k·step, second half from the end)."""
    n = math.floor((b - a) / step + 1e-10)
    last = a + n * step
    if abs(last - b) < 1e-10 * step:
        last = b
    k = np.arange(n + 1)
    return np.where(k < n / 2, a + k * step, last - (n - k) * step)


# --------------------------------------------------------------------------- thesis Size()


@dataclass(frozen=True)
class ThesisSize:
    """Result of :func:`thesis_size` (the thesis's ``Size.m``).

    Attributes:
        diameter_mm: 10, 20 or 40; None for 'Use additional muscles'.
        use_additional_muscles: True when the force exceeds 0.9·6000 N.
        rest_length: The thesis's ``size``: PAM resting length [m].
        longest: Longest path length [m] (the thesis's ``longest`` output).
        shortest: Shortest path length [m].
        delta: longest − shortest [m].
        deformation: The ``def`` ratio that produced ``rest_length`` (1.09 … 1.25).
        fallback: True when the PAM does not fit (rest_length + 2·fittings > longest): the
            thesis's silent 5·Δ fallback. Never use such a result for a design.
        fitting_length: Length of one air fitting [m] (0.0125).
    """

    diameter_mm: int | None
    use_additional_muscles: bool
    rest_length: float
    longest: float
    shortest: float
    delta: float
    deformation: float
    fallback: bool
    fitting_length: float = FITTING_LENGTH

    @property
    def tendon_length(self) -> float:
        """Artificial tendon [m]: longest − rest_length − 2·fittings (negative on fallback)."""
        return self.longest - self.rest_length - 2 * self.fitting_length

    @property
    def contraction(self) -> float:
        """Contraction at the shortest path length, Δ/rest_length = 1 − 1/deformation [-]."""
        return self.delta / self.rest_length

    def strain(self, path_length: np.ndarray | float) -> np.ndarray:
        """Contraction ε [-] at path lengths [m] (thesis eq. 8): (longest − L)/rest_length."""
        return (self.longest - np.asarray(path_length, dtype=float)) / self.rest_length


def _thesis_diameter(mif: float) -> int | None:
    f1, f2, f3 = (festo.F_MAX_THEORETICAL[d] for d in festo.DIAMETERS_MM)
    fc = THESIS_SAFETY_FACTOR
    if mif < fc * f1:
        return 10
    if fc * f1 <= mif < fc * f2:
        return 20
    if fc * f2 <= mif <= fc * f3:
        return 40
    return None


def thesis_size(lengths: Iterable[float] | np.ndarray, max_isometric_force: float) -> ThesisSize:
    """The thesis's ``Size.m``: diameter and resting length of a Festo PAM, reproduced exactly.

    Args:
        lengths: Path (musculotendon) lengths [m] over the range of motion.
        max_isometric_force: Maximum isometric force of the human muscle(s) replaced [N].

    Returns:
        The thesis's diameter and resting length, with ``fallback`` set (and a
        :class:`SizingFallbackWarning` issued) when the thesis's 5·Δ fallback was taken.

    Raises:
        ParameterError: NaN, non-positive or fewer than two lengths; constant length (Δ = 0);
            non-positive or NaN force.
    """
    a = _lengths(lengths, 2)
    mif = _positive("max_isometric_force", max_isometric_force)
    longest, shortest = float(a.max()), float(a.min())
    delta = longest - shortest
    if delta == 0:
        raise ParameterError("path length is constant over the range of motion (delta = 0): "
                             "the thesis Size() cannot size a PAM from it")
    diameter = _thesis_diameter(mif)
    x = FITTING_LENGTH
    size = delta / (1 - 1 / THESIS_OPT_MAX)
    used = THESIS_OPT_MAX
    if size + 2 * x > longest:
        for d in _matlab_colon(THESIS_OPT_MAX, THESIS_DEF_STEP, THESIS_MAX_DEF):
            d = float(d)
            if size + 2 * x > longest and d <= THESIS_MAX_DEF:
                size = delta / (1 - 1 / d)
                used = d
            elif size + 2 * x <= longest:
                break
    fallback = size + 2 * x > longest
    if fallback:
        warnings.warn(
            f"thesis Size(): even def = {THESIS_MAX_DEF} does not fit; returning the thesis's "
            f"5*delta = {size:.4g} m, longer than the route allows ({longest:.4g} m - 2 fittings)",
            SizingFallbackWarning, stacklevel=2)
    return ThesisSize(diameter_mm=diameter, use_additional_muscles=diameter is None,
                      rest_length=float(size), longest=longest, shortest=shortest,
                      delta=delta, deformation=used, fallback=fallback)


# --------------------------------------------------------------------------- better sizing


@dataclass(frozen=True)
class Candidate:
    """One (diameter, n_parallel) option evaluated by :func:`size_pam`.

    Attributes:
        diameter_mm: 10, 20 or 40.
        n_parallel: Number of identical PAMs side by side.
        rest_length: l0 [m] (≤ 0 when the path is too short).
        tendon_length: Artificial tendon t [m].
        max_contraction: ε at the shortest path length [-].
        max_stretch: −ε at the longest path length [-] (the pretension s).
        contraction_limit: min(max_relative_strain·kmax(l0), max_contraction(d)) [-].
        pretension_limit: Festo's max_pretension(d) [-].
        force_capacity: n·safety_factor·F(d, l0) [N].
        violations: Names and numbers of the violated limits; empty when feasible.
    """

    diameter_mm: int
    n_parallel: int
    rest_length: float
    tendon_length: float
    max_contraction: float
    max_stretch: float
    contraction_limit: float
    pretension_limit: float
    force_capacity: float
    violations: tuple[str, ...]

    @property
    def feasible(self) -> bool:
        """True when no limit is violated."""
        return not self.violations


@dataclass(frozen=True)
class Sizing:
    """Result of :func:`size_pam`.

    Numbers are NaN (and diameter/n None) when ``feasible`` is False; ``reason`` then names
    the violated limits and ``candidates`` holds every option with its numbers.

    Attributes:
        feasible: True when a PAM meets every stated limit.
        reason: Empty when feasible, else why no candidate is.
        diameter_mm: Chosen diameter [mm].
        n_parallel: Chosen number of parallel PAMs.
        rest_length: Resting length l0 [m] of each PAM.
        tendon_length: Artificial tendon t [m] (≥ 0).
        fitting_length: One air fitting [m].
        shortest: Shortest path length [m].
        longest: Longest path length [m].
        max_contraction: ε at the shortest path length [-].
        max_stretch: −ε at the longest path length [-].
        contraction_limit: The contraction limit that applied [-].
        pretension_limit: The stretch limit that applied [-].
        force_capacity: n·safety_factor·F(d, l0) [N].
        required_force: The force asked for [N].
        candidates: All evaluated options, in the order tried.
    """

    feasible: bool
    reason: str
    diameter_mm: int | None
    n_parallel: int | None
    rest_length: float
    tendon_length: float
    fitting_length: float
    shortest: float
    longest: float
    max_contraction: float
    max_stretch: float
    contraction_limit: float
    pretension_limit: float
    force_capacity: float
    required_force: float
    candidates: tuple[Candidate, ...]

    @property
    def reference_length(self) -> float:
        """Path length [m] at which the PAM is at rest: rest_length + 2·fittings + tendon."""
        return self.rest_length + 2 * self.fitting_length + self.tendon_length

    def strain(self, path_length: np.ndarray | float) -> np.ndarray:
        """Contraction ε [-] of each PAM at path lengths [m]: (reference_length − L)/rest_length."""
        return (self.reference_length - np.asarray(path_length, dtype=float)) / self.rest_length


def _candidate(d: int, n: int, lmin: float, lmax: float, mif: float, *, fitting: float,
               tendon: float, stretch: float, kmax: float | None, max_rel: float,
               force_basis: str, safety: float) -> Candidate:
    a = 2 * fitting + tendon
    l0 = (lmax - a) / (1 + stretch)
    violations: list[str] = []
    p_lim = festo.max_pretension(d)
    if l0 <= 0:
        violations.append(f"path: longest path length {lmax:.4g} m <= fittings + tendon {a:.4g} m")
        return Candidate(d, n, l0, tendon, math.nan, stretch, math.nan, p_lim, math.nan,
                         tuple(violations))
    eps_short = 1 - (lmin - a) / l0
    eps_long = 1 - (lmax - a) / l0
    km = float(festo.kmax(l0, d, model="v3")) if kmax is None else kmax
    c_lim = min(max_rel * km, festo.max_contraction(d))
    nom_lo, nom_hi = festo.nominal_length_range(d)
    if not nom_lo <= l0 <= nom_hi:
        violations.append(f"nominal length: l0 = {l0:.4g} m outside Festo's {nom_lo:g}..{nom_hi:g} m")
    if eps_short > c_lim:
        violations.append(f"contraction: {eps_short:.4g} at the shortest path length exceeds "
                          f"the limit {c_lim:.4g} (min(kmax·{max_rel:g}, 25 %))")
    if stretch > p_lim:
        violations.append(f"pretension: stretch {stretch:.4g} exceeds Festo's {p_lim:g}")
    f_one = float(festo.f620(l0, d)) if force_basis == "v3" else festo.F_MAX_THEORETICAL[d]
    capacity = n * safety * f_one
    if capacity < mif:
        violations.append(f"force: {n} x {safety:g} x {f_one:.4g} N = {capacity:.4g} N "
                          f"< required {mif:.4g} N")
    return Candidate(d, n, l0, tendon, eps_short, -eps_long, c_lim, p_lim, capacity,
                     tuple(violations))


def size_pam(lengths: Iterable[float] | np.ndarray, max_isometric_force: float, *,
             diameter_mm: int | None = None, max_parallel: int = 3,
             fitting_length: float = FITTING_LENGTH, min_tendon: float = 0.0,
             pretension: float = 0.0, kmax: float | None = None,
             max_relative_strain: float = 1.0, force_basis: Literal["v3", "festo"] = "v3",
             safety_factor: float = THESIS_SAFETY_FACTOR) -> Sizing:
    """Size a Festo PAM that meets stated limits over the range of motion (see module docstring).

    Args:
        lengths: Path lengths [m] of the route over the range of motion.
        max_isometric_force: Force the PAM(s) must provide [N].
        diameter_mm: Only this diameter (10, 20 or 40); None tries all, smallest first.
        max_parallel: Most PAMs side by side (1–3).
        fitting_length: One air fitting [m] (two per PAM).
        min_tendon: Artificial tendon every route needs at least [m] (≥ 0).
        pretension: Stretch s [-] of the PAM at the longest path length (≥ 0; must stay
            within Festo's 3/4/5 %, else that diameter is infeasible).
        kmax: Free contraction at 620 kPa [-]; None uses :func:`pamkin.robot.festo.kmax` (v3).
        max_relative_strain: Fraction of kmax usable at the shortest path length (0 < · ≤ 1).
        force_basis: ``"v3"`` (measured F620(l0)) or ``"festo"`` (630/1500/6000 N).
        safety_factor: Fraction of that force the design may rely on (0 < · ≤ 1).

    Returns:
        The first feasible candidate, or ``feasible=False`` with the reason.

    Raises:
        ParameterError: Bad lengths (NaN, non-positive, empty), force, or options.
    """
    a = _lengths(lengths, 1)
    mif = _positive("max_isometric_force", max_isometric_force)
    fitting = _positive("fitting_length", fitting_length, allow_zero=True)
    tendon = _positive("min_tendon", min_tendon, allow_zero=True)
    stretch = _positive("pretension", pretension, allow_zero=True)
    if stretch >= 1:
        raise ParameterError(f"pretension is a strain (fraction), got {stretch}")
    max_rel = _positive("max_relative_strain", max_relative_strain)
    if max_rel > 1:
        raise ParameterError(f"max_relative_strain must be <= 1, got {max_rel}")
    safety = _positive("safety_factor", safety_factor)
    if safety > 1:
        raise ParameterError(f"safety_factor must be <= 1, got {safety}")
    if kmax is not None:
        kmax = _positive("kmax", kmax)
        if kmax >= 1:
            raise ParameterError(f"kmax must be < 1, got {kmax}")
    if force_basis not in ("v3", "festo"):
        raise ParameterError(f"force_basis must be 'v3' or 'festo', got {force_basis!r}")
    if isinstance(max_parallel, bool) or not isinstance(max_parallel, (int, np.integer)) \
            or not 1 <= max_parallel <= 3:
        raise ParameterError(f"max_parallel must be an integer 1..3, got {max_parallel!r}")
    diameters = festo.DIAMETERS_MM if diameter_mm is None else (festo.check_diameter(diameter_mm),)

    lmin, lmax = float(a.min()), float(a.max())
    candidates = [
        _candidate(d, n, lmin, lmax, mif, fitting=fitting, tendon=tendon, stretch=stretch,
                   kmax=kmax, max_rel=max_rel, force_basis=force_basis, safety=safety)
        for n in range(1, int(max_parallel) + 1) for d in diameters
    ]
    for c in candidates:
        if c.feasible:
            return Sizing(True, "", c.diameter_mm, c.n_parallel, c.rest_length, c.tendon_length,
                          fitting, lmin, lmax, c.max_contraction, c.max_stretch,
                          c.contraction_limit, c.pretension_limit, c.force_capacity, mif,
                          tuple(candidates))
    last_n = [c for c in candidates if c.n_parallel == int(max_parallel)]
    reason = "no feasible PAM: " + "; ".join(
        f"{c.diameter_mm} mm x {c.n_parallel}: " + ", ".join(c.violations) for c in last_n)
    nan = math.nan
    return Sizing(False, reason, None, None, nan, nan, fitting, lmin, lmax, nan, nan, nan, nan,
                  nan, mif, tuple(candidates))
