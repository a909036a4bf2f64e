"""Ranges of motion and coordinate grids.

A :class:`RangeOfMotion` holds box limits per coordinate plus coupled limits: the
range of one coordinate as a linear function of another (the thesis's hip adduction
limits as functions of hip flexion). :meth:`RangeOfMotion.grid` builds 1-D, 2-D or
N-D grids of configurations; a coupled coordinate is swept between its limits at
each value of the coordinate it depends on (as the thesis's surface plots do).
All angles in the public API are radians.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from pamkin._resources import data_file
from pamkin.errors import ConfigurationError, DataFileError
from pamkin.yamlio import safe_load

ROM_FILE = data_file("rom.yaml")


@dataclass(frozen=True)
class CoupledLimit:
    """Limits of ``coordinate`` linear in ``depends_on``.

    Attributes:
        coordinate: The limited coordinate.
        depends_on: The coordinate the limits depend on.
        at: (x0, x1) values of ``depends_on`` [rad] where the limits are given.
        lower: Lower limits at x0 and x1 [rad].
        upper: Upper limits at x0 and x1 [rad].
    """

    coordinate: str
    depends_on: str
    at: tuple[float, float]
    lower: tuple[float, float]
    upper: tuple[float, float]

    def limits(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) limits [rad] at values ``x`` of ``depends_on`` (linear, extrapolated)."""
        t = (np.asarray(x, float) - self.at[0]) / (self.at[1] - self.at[0])
        lo = self.lower[0] + t * (self.lower[1] - self.lower[0])
        hi = self.upper[0] + t * (self.upper[1] - self.upper[0])
        return lo, hi


@dataclass(frozen=True)
class RangeOfMotion:
    """Box and coupled limits of coordinates [rad or m].

    Attributes:
        limits: Coordinate -> (min, max).
        coupled: Limits depending on another coordinate.
        name: A label (e.g. ``robot_thesis``).
    """

    limits: Mapping[str, tuple[float, float]]
    coupled: tuple[CoupledLimit, ...] = ()
    name: str = ""
    _coupled_by: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_coupled_by", {c.coordinate: c for c in self.coupled})
        for c in self.coupled:
            if c.coordinate in self.limits:
                raise ConfigurationError(f"{c.coordinate} has both box and coupled limits")

    @property
    def coordinates(self) -> list[str]:
        """Every coordinate with a limit."""
        return list(self.limits) + [c.coordinate for c in self.coupled]

    def bounds(self, coordinate: str, q: Mapping[str, np.ndarray] | None = None) -> tuple:
        """(min, max) of ``coordinate``; for a coupled one, at the values in ``q``."""
        if coordinate in self.limits:
            return self.limits[coordinate]
        if coordinate in self._coupled_by:
            c = self._coupled_by[coordinate]
            if q is None or c.depends_on not in q:
                raise ConfigurationError(f"{coordinate} limits depend on {c.depends_on}: give its value")
            return c.limits(q[c.depends_on])
        raise ConfigurationError(f"no range of motion for {coordinate!r}; known: {self.coordinates}")

    def contains(self, coordinates: Sequence[str], q: np.ndarray, tol: float = 1e-12) -> np.ndarray:
        """(N,) mask of configurations ``q`` (columns named by ``coordinates``) inside the range."""
        q = np.atleast_2d(np.asarray(q, float))
        col = {c: q[:, i] for i, c in enumerate(coordinates)}
        ok = np.ones(q.shape[0], dtype=bool)
        for c, v in col.items():
            if c in self.limits:
                lo, hi = self.limits[c]
            elif c in self._coupled_by:
                lo, hi = self.bounds(c, col)
            else:
                continue
            ok &= (v >= lo - tol) & (v <= hi + tol)
        return ok

    def from_unit(self, coordinates: Sequence[str], u: np.ndarray) -> dict[str, np.ndarray]:
        """Values of ``coordinates`` from numbers ``u`` (N, len(coordinates)) in [0, 1]: each box-limited
        coordinate ``lo + u·(hi − lo)``; a coupled one between its limits at the value given to the
        coordinate it depends on (which must be among ``coordinates``). With uniform random ``u``:
        uniform random poses within the range.

        Returns:
            {coordinate: (N,) values} [rad or m].
        """
        u = np.asarray(u, float)
        out: dict[str, np.ndarray] = {}
        for i in sorted(range(len(coordinates)), key=lambda i: coordinates[i] in self._coupled_by):
            c = coordinates[i]
            lo, hi = self.bounds(c, out)
            out[c] = lo + u[:, i] * (np.asarray(hi) - np.asarray(lo))
        return out

    def grid(self, coordinates: Sequence[str], n: int | Sequence[int] = 21,
             base: Mapping[str, float] | None = None) -> np.ndarray:
        """Grid over ``coordinates`` (M, len(coordinates)), last coordinate varying fastest.

        A coupled coordinate whose ``depends_on`` is in the grid is swept between its
        limits at each value of that coordinate (so every point lies in the range); if
        ``depends_on`` is not in the grid, its limits are taken at ``base[depends_on]``.

        Args:
            coordinates: Names; box-limited or coupled.
            n: Points per coordinate (one number, or one per coordinate).
        """
        coordinates = list(coordinates)
        ns = [n] * len(coordinates) if isinstance(n, int) else list(n)
        if len(ns) != len(coordinates):
            raise ConfigurationError("give one grid size per coordinate")
        if any(k < 1 for k in ns):
            raise ConfigurationError("grid sizes must be >= 1")
        unit = [np.linspace(0.0, 1.0, k) if k > 1 else np.array([0.5]) for k in ns]
        pts = np.array(list(itertools.product(*unit)), dtype=float).reshape(-1, len(coordinates))
        out = np.empty_like(pts)
        done: dict[str, np.ndarray] = {}
        order = sorted(range(len(coordinates)), key=lambda i: coordinates[i] in self._coupled_by)
        for i in order:
            c = coordinates[i]
            if c in self._coupled_by:
                dep = self._coupled_by[c].depends_on
                if dep in done:
                    lo, hi = self._coupled_by[c].limits(done[dep])
                elif base is not None and dep in base:
                    lo, hi = self._coupled_by[c].limits(np.full(len(pts), float(base[dep])))
                else:
                    raise ConfigurationError(f"grid over {c} needs {dep} in the grid or a base value")
            else:
                lo, hi = self.bounds(c)
            out[:, i] = lo + pts[:, i] * (np.asarray(hi) - np.asarray(lo))
            done[c] = out[:, i]
        return out

    def for_side(self, side: str) -> RangeOfMotion:
        """Resolve side-less names (``hip_flexion``) to ``hip_flexion_<side>``; others unchanged."""
        def rn(c: str) -> str:
            return c if c.startswith("lumbar") or c.endswith(("_r", "_l")) else f"{c}_{side}"
        return RangeOfMotion({rn(k): v for k, v in self.limits.items()},
                             tuple(CoupledLimit(rn(c.coordinate), rn(c.depends_on), c.at, c.lower, c.upper)
                                   for c in self.coupled), name=f"{self.name}_{side}")


def load_rom(name: str = "robot_thesis", side: str = "r", path: str | Path = ROM_FILE) -> RangeOfMotion:
    """A named range of motion from ``robot/data/rom.yaml`` (degrees there, radians here).

    Args:
        name: ``human_thesis``, ``robot_thesis`` or ``robot_2026``.
        side: ``r`` or ``l`` (names without a side get this suffix, lumbar ones none).
    """
    path = Path(path)
    try:
        data = safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise DataFileError(str(path), f"cannot read: {e}") from None
    if name not in data:
        raise DataFileError(str(path), f"no range of motion {name!r}; known: {sorted(data)}")
    d = data[name]
    try:
        limits = {k: (float(np.radians(v[0])), float(np.radians(v[1]))) for k, v in d["limits"].items()}
        coupled = tuple(
            CoupledLimit(k, c["depends_on"], tuple(np.radians(c["at"]).tolist()),
                         tuple(np.radians(c["lower"]).tolist()), tuple(np.radians(c["upper"]).tolist()))
            for k, c in d.get("coupled", {}).items())
    except (KeyError, TypeError, IndexError) as e:
        raise DataFileError(str(path), f"{name}: malformed entry ({e})") from None
    return RangeOfMotion(limits, coupled, name=name).for_side(side)
