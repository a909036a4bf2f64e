"""Polynomial path functions fitted from pamkin's exact paths (OpenSim's ``FunctionBasedPath``).

Each muscle's length is fitted as a multivariate polynomial of the independent coordinates it spans
(:attr:`pamkin.human.model.Model.pairs`) over the model's coordinate ranges, by least squares on its
exact lengths *and* moment arms at random poses (a moment arm is −∂l/∂q of the same polynomial, so
one coefficient vector fits both). The order rises from 1 until the muscle meets its tolerances on a
set of validation poses, up to ``max_order``; its errors are then measured on held-out poses that neither
the fit nor the choice of order saw. The fitted model evaluates lengths and
moment arms as matrix products (:mod:`pamkin.human.function_paths`).

A path whose length jumps (OpenSim's ``ConditionalPathPoint``, e.g. Gait2392's iliacus and psoas at
hip flexion) cannot be one polynomial: such muscles miss their tolerance and are reported, never
written silently (:func:`fit_paths` returns them in :attr:`PathFit.missed`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pamkin.errors import ConfigurationError
from pamkin.human.model import Model
from pamkin.human.rom import RangeOfMotion
from pamkin.opensim.functions import MultivariatePolynomial, monomial_table, polynomial_exponents
from pamkin.opensim.model_file import FunctionPath


@dataclass(frozen=True)
class FitTolerance:
    """Accuracy a fitted path must reach on held-out poses (per muscle).

    Attributes:
        length_rms: Length RMS error [m].
        length_max: Largest length error [m].
        moment_arm_rms: Moment-arm RMS error over the muscle's coordinates [m or m/m].
    """

    length_rms: float = 1e-4
    length_max: float = 5e-4
    moment_arm_rms: float = 1e-3

    def met(self, errors: tuple[float, ...]) -> bool:
        """Whether (length RMS, length max, moment-arm RMS, ...) meet the tolerance."""
        return errors[0] <= self.length_rms and errors[1] <= self.length_max and errors[2] <= self.moment_arm_rms


@dataclass(frozen=True)
class MuscleFit:
    """One muscle's fitted path and its errors on the held-out poses.

    Attributes:
        name: The muscle.
        path: The fitted function-based path.
        length_rms, length_max: Length errors [m].
        moment_arm_rms, moment_arm_max: Moment-arm errors over its coordinates [m or m/m].
        passed: Whether it meets the tolerance.
    """

    name: str
    path: FunctionPath
    length_rms: float
    length_max: float
    moment_arm_rms: float
    moment_arm_max: float
    passed: bool

    @property
    def order(self) -> int:
        """Polynomial order."""
        return self.path.length.order

    @property
    def n_terms(self) -> int:
        """Number of polynomial coefficients."""
        return len(self.path.length.coefficients)


@dataclass
class PathFit:
    """The fitted paths of a model.

    Attributes:
        muscles: One :class:`MuscleFit` per fitted muscle (model order).
        tolerance: The tolerance they were held to.
        n_samples: Fitting poses; n_test: held-out poses.
        seconds: Wall time of the fit (exact evaluation included) [s].
        skipped: Muscles that span no coordinate (nothing to fit).
        ranges: Where the poses were drawn (the model's coordinate ranges, or a named range of motion).
    """

    muscles: list[MuscleFit]
    tolerance: FitTolerance
    n_samples: int
    n_test: int
    seconds: float = 0.0
    skipped: list[str] = field(default_factory=list)
    ranges: str = "the model's coordinate ranges"

    @property
    def missed(self) -> list[MuscleFit]:
        """The muscles that miss the tolerance."""
        return [m for m in self.muscles if not m.passed]

    def paths(self, only_passed: bool = True) -> dict[str, FunctionPath]:
        """``{muscle: FunctionPath}`` (by default only the ones that meet the tolerance)."""
        return {m.name: m.path for m in self.muscles if m.passed or not only_passed}

    def table(self) -> list[dict]:
        """Per-muscle rows for reports (errors in millimetres)."""
        return [{"muscle": m.name, "coordinates": " ".join(m.path.coordinates), "order": m.order,
                 "terms": m.n_terms, "length_rms_mm": 1e3 * m.length_rms, "length_max_mm": 1e3 * m.length_max,
                 "moment_arm_rms_mm": 1e3 * m.moment_arm_rms, "moment_arm_max_mm": 1e3 * m.moment_arm_max,
                 "passed": m.passed} for m in self.muscles]


def spanned_coordinates(model: Model) -> dict[int, list[int]]:
    """``{muscle index: coordinate indices}`` of the independent coordinates each path depends on."""
    out: dict[int, list[int]] = {}
    for m, c in model.pairs.tolist():
        out.setdefault(m, []).append(c)
    return out


def uniform_poses(model: Model, n: int, seed: int, rom: Sequence[RangeOfMotion] = ()) -> np.ndarray:
    """``n`` poses uniform over every independent coordinate's range, locked ones included (a fitted path
    must hold when a user unlocks them); dependent coordinates follow their couplers.

    Args:
        rom: Ranges of motion (e.g. :func:`pamkin.human.rom.load_rom` of each side) replacing the model's
            ranges for the coordinates they name (coupled limits honoured; a coordinate named twice takes the
            first).
    """
    rng = np.random.default_rng(seed)
    lo, hi = model.coordinate_ranges.T
    q = lo + (hi - lo) * rng.random((n, len(lo)))
    done: set[str] = set()
    for r in rom:
        cols = [c for c in r.coordinates if c in model.coordinates and c not in done]
        for c, v in r.from_unit(cols, rng.random((n, len(cols)))).items():
            q[:, model.coordinates.index(c)] = v
        done |= set(cols)
    if rom and not done:
        raise ConfigurationError(f"the range of motion {rom[0].name!r} names none of the model's coordinates "
                                 f"({', '.join(rom[0].coordinates)})")
    return model.kinematics.fill_dependent(q)


@dataclass
class _Basis:
    """Monomials of d variables up to ``max_order``, sorted by total degree: the terms of every lower order
    are a leading block, so one QR factorisation gives the least-squares fit of every order."""

    d: int
    max_order: int

    def __post_init__(self) -> None:
        exps = polynomial_exponents(self.d, self.max_order)
        order = np.argsort(exps.sum(axis=1), kind="stable")
        self.exps = exps[order]
        self.index = {tuple(int(v) for v in e): k for k, e in enumerate(self.exps)}

    def n_terms(self, order: int) -> int:
        return len(polynomial_exponents(self.d, order))

    def polynomial(self, coef: np.ndarray, order: int) -> MultivariatePolynomial:
        """The coefficients of the leading block of ``order`` in OpenSim's term order."""
        exps = polynomial_exponents(self.d, order)
        return MultivariatePolynomial(self.d, order, tuple(float(coef[self.index[tuple(int(v) for v in e)]])
                                                           for e in exps))


@dataclass
class _Poses:
    """Coordinates (N, d), lengths (N, m) and moment arms (N, d, m) of a group's m muscles at N poses."""

    x: np.ndarray
    L: np.ndarray
    R: np.ndarray


def _errors(basis: _Basis, T: np.ndarray, D: list[np.ndarray], k: int, c: np.ndarray, at: _Poses,
            j: int) -> tuple[float, float, float, float]:
    """(length RMS, length max, moment-arm RMS, moment-arm max) of muscle j's fit (first k terms)."""
    eL = T[:, :k] @ c[:k] - at.L[:, j]
    eR = np.stack([-(Di[:, :k] @ c[:k]) for Di in D], axis=1) - at.R[:, :, j]
    return (float(np.sqrt(np.mean(eL ** 2))), float(np.abs(eL).max()),
            float(np.sqrt(np.mean(eR ** 2))), float(np.abs(eR).max()))


def _fit_group(names: list[str], coords: list[str], fit: _Poses, val: _Poses, test: _Poses, tol: FitTolerance,
               max_order: int, arm_weight: float) -> list[MuscleFit]:
    """Fit the muscles spanning the same coordinates: shared samples, one QR of the design matrix.

    The order is chosen on the validation poses ``val`` (the lowest that meets the tolerance there, else the one
    with the smallest largest length error); the errors reported, and ``passed``, are those on ``test``, poses
    the fit and the choice never saw.
    """
    d = fit.x.shape[1]
    while max_order > 1 and len(polynomial_exponents(d, max_order)) * 2 > len(fit.x) * (1 + d):
        max_order -= 1                                 # too few samples for this many coefficients
    basis = _Basis(d, max_order)
    T, D = monomial_table(fit.x, basis.exps)
    A = np.vstack([T] + [-arm_weight * Di for Di in D])
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    Q, Rq = np.linalg.qr(A / scale)
    QtB = Q.T @ np.vstack([fit.L] + [arm_weight * fit.R[:, i] for i in range(d)])
    Tv, Dv = monomial_table(val.x, basis.exps)
    Tt, Dt = monomial_table(test.x, basis.exps)
    out = []
    for j, name in enumerate(names):
        best = None
        for order in range(1, max_order + 1):
            k = basis.n_terms(order)
            c = np.zeros(len(basis.exps))
            c[:k] = np.linalg.lstsq(Rq[:k, :k], QtB[:k, j], rcond=None)[0] / scale[:k]
            e = _errors(basis, Tv, Dv, k, c, val, j)
            ok = tol.met(e)
            if ok or best is None or e[1] < best[0][1]:
                best = (e, order, c, k)
            if ok:
                break
        _, order, c, k = best
        e = _errors(basis, Tt, Dt, k, c, test, j)
        out.append(MuscleFit(name, FunctionPath(tuple(coords), basis.polynomial(c, order)), *e, passed=tol.met(e)))
    return out


def fit_paths(model: Model, muscles: list[str] | None = None, max_order: int = 8, n_samples: int = 4000,
              n_test: int = 1000, tolerance: FitTolerance | None = None, seed: int = 0,
              arm_weight: float = 0.3, rom: Sequence[RangeOfMotion] = ()) -> PathFit:
    """Fit a polynomial path function to each muscle from pamkin's exact lengths and moment arms.

    Args:
        model: The model (exact wrapping and point paths).
        muscles: Muscles to fit (default: every muscle with points).
        max_order: Highest polynomial order tried.
        n_samples: Random fitting poses (uniform over every coordinate's range).
        n_test: Random held-out poses (seed + 1) the errors are measured on, and as many validation poses
            (seed + 2) on which each muscle's order is chosen: the reported errors come from poses neither the
            fit nor the choice of order saw.
        tolerance: Per-muscle accuracy goals (default :class:`FitTolerance`).
        seed: Seed of the fitting poses.
        rom: Fit (and measure) within these ranges of motion (e.g. one per side) instead of the model's
            coordinate ranges, for the coordinates they name (:func:`uniform_poses`).
        arm_weight: Weight of the moment-arm residuals against the length residuals in the least squares
            (0.3: the tolerances ask ten times more of lengths than of moment arms; 0.3 met the most muscles
            on Gait10dof18musc and Rajagopal2016).

    Returns:
        The fits, those that miss the tolerance included (:attr:`PathFit.missed`).
    """
    tol = tolerance or FitTolerance()
    t0 = time.perf_counter()
    names = model.muscles
    chosen = [i for i, m in enumerate(model.osim.muscles) if m.function_path is None]
    if muscles is not None:
        unknown = [m for m in muscles if m not in names]
        if unknown:
            raise KeyError(f"unknown muscle(s) {unknown}; the model has {names}")
        chosen = [names.index(m) for m in muscles]
    poses = [uniform_poses(model, n, seed + k, rom) for k, n in ((0, n_samples), (2, n_test), (1, n_test))]
    results = [model.path_result(q) for q in poses]
    pairs = {tuple(p): k for k, p in enumerate(model.pairs.tolist())}
    spans = spanned_coordinates(model)
    groups: dict[tuple[int, ...], list[int]] = {}
    skipped = []
    for m in chosen:
        if spans.get(m):
            groups.setdefault(tuple(spans[m]), []).append(m)
        else:           # spans no coordinate: a constant length is not a path function
            skipped.append(names[m])
    fits = {}
    for cols, ms in groups.items():
        c = list(cols)
        k = np.array([[pairs[(m, cc)] for m in ms] for cc in cols])          # (d, m)
        sets = [_Poses(q[:, c], r.lengths[:, ms], r.moment_arms[:, k]) for q, r in zip(poses, results)]
        for f in _fit_group([names[m] for m in ms], [model.coordinates[cc] for cc in cols], *sets, tol,
                            max_order, arm_weight):
            fits[f.name] = f
    fits = [fits[names[m]] for m in chosen if names[m] in fits]
    ranges = f"range of motion {', '.join(r.name for r in rom)}" if rom else "the model's coordinate ranges"
    return PathFit(fits, tol, n_samples, n_test, time.perf_counter() - t0, skipped, ranges)
