"""Polynomial path functions fitted from pamkin's exact paths (OpenSim's ``FunctionBasedPath``).

Each muscle's length is fitted as a multivariate polynomial of the independent coordinates it spans
(:attr:`pamkin.human.model.Model.pairs`) over the model's coordinate ranges, by least squares on its
exact lengths *and* moment arms at random poses (a moment arm is −∂l/∂q of the same polynomial, so
one coefficient vector fits both). The order rises from 1 until the muscle meets its tolerances on a
separate set of held-out random poses, up to ``max_order``. The fitted model evaluates lengths and
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
from pamkin.opensim.functions import MultivariatePolynomial, polynomial_exponents
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


def _design(x: np.ndarray, exps: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Monomial values (N, T) and their derivatives along each variable [(N, T)] at (N, d) points."""
    order = int(exps.max(initial=0))
    P = np.ones((x.shape[0], x.shape[1], order + 1))
    for p in range(1, order + 1):
        P[:, :, p] = P[:, :, p - 1] * x
    cols = np.arange(x.shape[1])
    T = np.prod(P[:, cols, exps], axis=2)
    D = []
    for i in range(x.shape[1]):
        e = exps.copy()
        e[:, i] = np.maximum(e[:, i] - 1, 0)
        D.append(np.prod(P[:, cols, e], axis=2) * exps[:, i])
    return T, D


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


def _fit_group(names: list[str], coords: list[str], x: np.ndarray, L: np.ndarray, R: np.ndarray,
               xt: np.ndarray, Lt: np.ndarray, Rt: np.ndarray, tol: FitTolerance, max_order: int,
               arm_weight: float) -> list[MuscleFit]:
    """Fit the muscles spanning the same coordinates: shared samples, one QR of the design matrix.

    ``L``/``Lt``: (N, m) lengths; ``R``/``Rt``: (N, d, m) moment arms of the m muscles.
    """
    d = x.shape[1]
    while max_order > 1 and len(polynomial_exponents(d, max_order)) * 2 > len(x) * (1 + d):
        max_order -= 1                                 # too few samples for this many coefficients
    basis = _Basis(d, max_order)
    T, D = _design(x, basis.exps)
    A = np.vstack([T] + [-arm_weight * Di for Di in D])
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    Q, Rq = np.linalg.qr(A / scale)
    QtB = Q.T @ np.vstack([L] + [arm_weight * R[:, i] for i in range(d)])
    Tt, Dt = _design(xt, basis.exps)
    out = []
    for j, name in enumerate(names):
        best = None
        for order in range(1, max_order + 1):
            k = basis.n_terms(order)
            c = np.zeros(len(basis.exps))
            c[:k] = np.linalg.lstsq(Rq[:k, :k], QtB[:k, j], rcond=None)[0] / scale[:k]
            eL = Tt[:, :k] @ c[:k] - Lt[:, j]
            eR = np.stack([-(Di[:, :k] @ c[:k]) for Di in Dt], axis=1) - Rt[:, :, j]
            e = (float(np.sqrt(np.mean(eL ** 2))), float(np.abs(eL).max()),
                 float(np.sqrt(np.mean(eR ** 2))), float(np.abs(eR).max()))
            ok = e[0] <= tol.length_rms and e[1] <= tol.length_max and e[2] <= tol.moment_arm_rms
            if ok or best is None or e[1] < best[0][1]:
                best = (e, order, c, ok)
            if ok:
                break
        e, order, c, ok = best
        out.append(MuscleFit(name, FunctionPath(tuple(coords), basis.polynomial(c, order)), *e, passed=ok))
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
        n_test: Random held-out poses (another seed) the errors are measured on.
        tolerance: Per-muscle accuracy goals (default :class:`FitTolerance`).
        seed: Seed of the fitting poses (held-out: seed + 1).
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
    q, qt = uniform_poses(model, n_samples, seed, rom), uniform_poses(model, n_test, seed + 1, rom)
    res, rest = model.path_result(q), model.path_result(qt)
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
        for f in _fit_group([names[m] for m in ms], [model.coordinates[cc] for cc in cols], q[:, c],
                            res.lengths[:, ms], res.moment_arms[:, k], qt[:, c], rest.lengths[:, ms],
                            rest.moment_arms[:, k], tol, max_order, arm_weight):
            fits[f.name] = f
    fits = [fits[names[m]] for m in chosen if names[m] in fits]
    ranges = f"range of motion {', '.join(r.name for r in rom)}" if rom else "the model's coordinate ranges"
    return PathFit(fits, tol, n_samples, n_test, time.perf_counter() - t0, skipped, ranges)
