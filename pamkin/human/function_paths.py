"""Function-based paths (OpenSim's ``FunctionBasedPath``): lengths and moment arms from functions of q.

A function-based path has no points: its length is a function l(q_a, q_b, ...) of the coordinates it
names, and its moment arms are either functions of their own (when the file gives
``moment_arm_functions``: OpenSim then uses them) or −∂l/∂q_i (OpenSim's rule otherwise).

Polynomials (``MultivariatePolynomialFunction``) of paths over the same coordinates share one table of
monomials: lengths and moment arms are then matrix products ``T @ C`` over a batch of configurations,
which is what makes fitted paths (:mod:`pamkin.human.path_fit`) fast. Scalar functions of one coordinate
are evaluated one by one.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from pamkin.opensim.functions import MultivariatePolynomial, OneVariable, monomial_table, polynomial_exponents
from pamkin.opensim.model_file import FunctionPath


@dataclass
class _PolyGroup:
    """Paths over the same coordinates: one monomial basis, coefficient matrices over it."""

    columns: np.ndarray          # (d,) coordinate indices (argument order)
    members: np.ndarray          # (m,) local path indices
    exponents: np.ndarray        # (n_terms, d) basis exponents
    length: np.ndarray           # (n_terms, m) length coefficients
    arms: np.ndarray             # (n_terms, d*m) moment-arm coefficients, argument-major columns
    arm_pairs: np.ndarray | None = None   # (d*m,) their columns in the pair list


def _embed(poly: MultivariatePolynomial, index: dict[tuple[int, ...], int], n_terms: int) -> np.ndarray:
    """Coefficients of ``poly`` in a larger basis (``index``: exponent tuple -> basis row)."""
    out = np.zeros(n_terms)
    for e, c in zip(poly.exponents, poly.coefficients):
        out[index[tuple(int(v) for v in e)]] += c
    return out


def _negative_derivative(poly: MultivariatePolynomial, i: int, index: dict, n_terms: int) -> np.ndarray:
    """Coefficients of −∂poly/∂x_i in the basis ``index``."""
    out = np.zeros(n_terms)
    for e, c in zip(poly.exponents, poly.coefficients):
        if e[i] > 0:
            d = [int(v) for v in e]
            d[i] -= 1
            out[index[tuple(d)]] -= c * e[i]
    return out


def _build_group(columns: tuple[int, ...], members: list[int], paths: list[FunctionPath]) -> _PolyGroup:
    polys = [paths[k].length for k in members] + [f for k in members for f in paths[k].moment_arms]
    order = max(p.order for p in polys)
    d = len(columns)
    exps = polynomial_exponents(d, order)
    index = {tuple(int(v) for v in e): r for r, e in enumerate(exps)}
    n = len(exps)
    C = np.stack([_embed(paths[k].length, index, n) for k in members], axis=1)
    A = np.zeros((d, n, len(members)))
    for j, k in enumerate(members):
        p = paths[k]
        for i in range(d):
            A[i, :, j] = (_embed(p.moment_arms[i], index, n) if p.moment_arms
                          else _negative_derivative(p.length, i, index, n))
    return _PolyGroup(np.array(columns, dtype=int), np.array(members, dtype=int), exps, C,
                      A.transpose(1, 0, 2).reshape(n, d * len(members)))


class FunctionPaths:
    """Lengths and moment arms of function-based paths.

    Args:
        coordinates: The model's coordinate names (the columns of ``q``).
        paths: One :class:`~pamkin.opensim.model_file.FunctionPath` per path.
    """

    def __init__(self, coordinates: list[str], paths: list[FunctionPath]) -> None:
        col = {c: i for i, c in enumerate(coordinates)}
        self.paths = list(paths)
        self.columns = [tuple(col[c] for c in p.coordinates) for p in paths]
        by_coords: dict[tuple[int, ...], list[int]] = defaultdict(list)
        self._scalar: list[int] = []
        for k, p in enumerate(paths):
            fns = (p.length,) + p.moment_arms
            if all(isinstance(f, MultivariatePolynomial) for f in fns):
                by_coords[self.columns[k]].append(k)
            else:
                self._scalar.append(k)
        self._groups = [_build_group(cols, ks, self.paths) for cols, ks in by_coords.items()]
        #: (K, 2) (local path index, coordinate index) pairs, path-major.
        self.pairs = np.array([(k, c) for k, cols in enumerate(self.columns) for c in cols],
                              dtype=int).reshape(-1, 2)
        self._pair_of = {(int(k), int(c)): j for j, (k, c) in enumerate(self.pairs)}
        for g in self._groups:
            g.arm_pairs = np.array([self._pair_of[(int(k), int(c))] for c in g.columns for k in g.members], dtype=int)

    def evaluate(self, q: np.ndarray, moment_arms: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Lengths (N, n_paths) [m] and moment arms of :attr:`pairs` (N, K) [m or m/m] at (N, n_coordinates) q."""
        q = np.asarray(q, dtype=float)
        N = len(q)
        L = np.zeros((N, len(self.paths)))
        R = np.zeros((N, len(self.pairs))) if moment_arms else None
        for g in self._groups:
            T, _ = monomial_table(q[:, g.columns], g.exponents, derivatives=False)
            L[:, g.members] = T @ g.length
            if R is not None:
                R[:, g.arm_pairs] = T @ g.arms
        for k in self._scalar:
            self._evaluate_one(k, q, L, R)
        return L, R

    def _evaluate_one(self, k: int, q: np.ndarray, L: np.ndarray, R: np.ndarray | None) -> None:
        p, cols = self.paths[k], list(self.columns[k])
        x = q[:, cols]
        L[:, k] = p.length.value(x)
        if R is None:
            return
        arms = (np.stack([f.value(x) for f in p.moment_arms], axis=1) if p.moment_arms
                else -p.length.gradient(x))
        for i, c in enumerate(cols):
            R[:, self._pair_of[(k, c)]] = arms[:, i]


__all__ = ["FunctionPaths", "OneVariable"]
