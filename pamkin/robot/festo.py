"""Force models of Festo DMSP fluidic muscles (PAMs) of 10, 20 and 40 mm inner diameter.

Definitions (used throughout pamkin):

* ``rest_length`` l0 [m]: the PAM's resting (nominal) length, unpressurised and unloaded,
  fittings excluded.
* ``strain`` ε = (l0 − l)/l0 [-]: contraction of the active length l, **positive when
  contracted**, negative when the PAM is stretched (pretension).
* ``kmax`` [-]: the free contraction at 620 kPa (the dissertation's ε620); relative strain
  ε* = ε / kmax.
* ``pressure`` P [Pa] (gauge) in the public API; the models are written in kPa and P* = P/620 kPa.

Models (``model=`` argument of :func:`force`):

``"v3"`` (default) — the lab's current measured model (Bolen et al., Actuators 2026)::

    F*(ε*, P*) = c0·(exp(−c1·ε*) − 1) + P*·exp(−c2·ε*²)
    F          = max(F*, 0) · F620(l0)
    F620(l0)   = a1·620·atan(a2·620·(l0 − offset))   (10, 20 mm; 40 mm: constant 6398.4 N)

  Coefficients per diameter (10/20 mm measured, 40 mm fitted to Festo MuscleSIM).

``"v0"`` — the thesis model: Hunt's 2017 10 mm force table at 620 kPa, linearly interpolated
  in ε* = ε/kmax(l0), zero outside 0 ≤ ε* ≤ 1 (the thesis reads that as buckling or breaking),
  scaled by 1500/630 and 6000/630 for 20 and 40 mm. kmax comes from Hunt's resting-length
  table (10 mm, used for every diameter as in the thesis).

``"hunt2017"`` — Hunt's 2017 implicit equation (thesis eq. 7, Table 4), 10 mm only::

    P = a0 + a1·tan(a2·(ε/(a4·F + kmax) + a3)) + a5·F + a6·S      [P kPa, F N]

  :func:`hunt_pressure` evaluates it; :func:`hunt_force` solves it for F (vectorised
  bracketed Newton–bisection). It reproduces Hunt's whole 10 mm table (all 19 pressure columns) to
  0.43 N with kmax = 0.175, and serves as that table's cross-check.

Behaviour beyond the limits (``out_of_range`` chooses what happens outside
−max_pretension(d) ≤ ε ≤ kmax):

* ``"model"`` (default) — each model's own, documented behaviour:

  - v0: force 0 for ε < 0 (stretched) and ε > kmax (over-contracted), as the thesis.
  - v3: the formula as measured. Stretched PAMs (ε < 0) get the formula's extrapolation
    (force grows above F620 — physically right, validated only to Festo's pretension limit);
    over-contraction: F* decreases monotonically in ε* > 0 and is clipped at 0 where the PAM
    goes slack (at 620 kPa F*(1, 1) = 0.011, so at ε = kmax the force is ≈ 1 % of F620).
    The festo4.m variant that forces F* = 0 for ε* > 1 is *not* applied: it would add a jump
    of ≈ 5 N for a 10 mm PAM and break gradients.
  - hunt2017: NaN for ε < 0 (the equation is not defined for stretched PAMs), solved force
    clipped at 0 otherwise (negative solutions mean slack).

* ``"nan"`` — NaN outside the range, ``"raise"`` — :class:`~pamkin.errors.ParameterError`.
  Both only for numeric (numpy) inputs.

Pressure: negative or NaN pressures are rejected (numeric inputs). P = 0 is allowed (v3:
only the stretched PAM carries force; hunt2017: the equation's value). Above 620 kPa v3 and
hunt2017 extrapolate. v0 is defined only at 620 kPa (the thesis used only that column) and
rejects any other pressure: use v3, or hunt2017 for Hunt's data at other pressures.

Backends and smoothness: every formula is written once, against a tiny backend shim
(``xp`` = numpy or a CasADi namespace). Give any input as a CasADi ``SX``/``MX``/``DM`` and the
result is a CasADi expression; CasADi is imported only then. Hard cuts (``max(F*, 0)`` in v3,
the ε* ∈ [0, 1] window of v0) have kinks or jumps; ``smoothing > 0`` replaces them by smooth
versions for gradient-based optimisation: v3 uses softplus ``s·log(1 + exp(F*/s))`` with width
``s`` in units of normalised force F*; v0 multiplies the (clamped) table by logistic steps
``σ(ε*/s)·σ((1 − ε*)/s)`` with width ``s`` in units of relative strain. ``smoothing = 0``
(default) is exact. The piecewise-linear table itself keeps its kinks (gradients are
piecewise constant) and F620 is clipped at 0 for l0 below the end-cap offset. hunt_force is
numpy only.

Decisions on the known source defects (shared/bipedal-robot/README.md and beyond):

1. Thesis ``festo()`` compares the resting length in metres with Hunt's kmax table in cm, so
   kmax is always 0.1491. Here the table is converted to metres (0.1531…0.2809 m → kmax
   0.1491…0.175, clamped at the ends); ``thesis_unit_slip=True`` (v0 only) reproduces the
   thesis's constant 0.1491 on request.
2. The README writes v3 as F = F*·Fmax(l0, P). With Fmax(l0, P) = a1·P·atan(a2·P·(l0 − off))
   the pressure would count twice (F*(0, P*) = P* already). The dissertation's total force
   line and the lab's code (``maxBPAforce(l0, dia, 620)``) use F620(l0) = Fmax(l0, 620 kPa);
   so does pamkin. A 0.485 m 10 mm PAM then has F620 = 443.4 N (the dissertation's check).
3. The generic Fmax formula lists the 10 mm end-cap offset 0.0075 m; the 20 mm PAM has its
   own offset 0.013 m (dissertation), used here. 40 mm: 6398.4 N from maxBPAforce.m (the
   Festo tool), not the older 6000 N.
4. Hunt's equation: thesis Table 4 labels a4 and a5 per mN; HuntEq.m's coefficients are
   for F in mN. Converted to F in N (a4 = −3.31e-4 /N, a5 = 1.229 kPa/N); HuntEq.m's
   corrected a3 = −0.4609 and a5 = 1.229 are used, not Table 4's −0.461 and 1.230 (those
   reproduce the table to 0.34 N and 0.75 N respectively; HuntEq.m's to 0.43 N).
5. kmax for v3 has no predictive relation to l0 (dissertation); defaults are Hunt's table
   for 10 mm, 0.255 for 20 mm (the lab's 20 mm robot PAMs) and 0.275 for 40 mm (the
   normalisation of the MuscleSIM fit). Every function takes an explicit ``kmax``.
6. festo3.m's stretched-region fit (a variable-name bug) and its 20-column pressure grid
   misalignment are not reproduced: v0 is the thesis's 620 kPa model only.

All numbers live in ``pamkin/data/festo_models.json`` with a source per number.
"""

from __future__ import annotations

import functools
import itertools
import json
import math
import types
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np

from pamkin.errors import DataFileError, ParameterError

__all__ = [
    "DEFAULT_PRESSURE",
    "DIAMETERS_MM",
    "F_MAX_THEORETICAL",
    "MODELS",
    "FestoForceModel",
    "FestoModel",
    "ForceLaw",
    "canonical_model",
    "force_law",
    "check_diameter",
    "f620",
    "force",
    "hunt_force",
    "hunt_pressure",
    "kmax",
    "max_contraction",
    "kmax_is_measured",
    "max_pretension",
    "measured_rest_length_range",
    "nominal_length_range",
    "outer_diameter",
    "outer_diameter_source",
    "pam_mass",
    "transmission_mass",
]

Array = Any
"""A numpy array (or float), or a CasADi ``SX``/``MX``/``DM`` expression."""

OutOfRange = Literal["model", "nan", "raise"]

DEFAULT_PRESSURE = 620e3
"""The pressure [Pa] all models are normalised to (620 kPa)."""

MODELS: tuple[str, ...] = ("v3", "v0", "hunt2017")
"""Model names accepted by :func:`force`, default first."""

_P_REF_KPA = 620.0
_DATA_FILE = "festo_models.json"


# --------------------------------------------------------------------------- data file


def _data_path() -> str:
    return str(resources.files("pamkin") / "data" / _DATA_FILE)


def _value(entry: Any, where: str) -> float:
    """The number of a ``{"value": x, "source": ...}`` entry (or a bare number)."""
    if isinstance(entry, Mapping):
        if "source" not in entry and "value" in entry:
            raise DataFileError(_data_path(), f"{where}: number without a 'source' note")
        entry = entry.get("value")
    if isinstance(entry, bool) or not isinstance(entry, (int, float)) or not math.isfinite(entry):
        raise DataFileError(_data_path(), f"{where}: expected a finite number, got {entry!r}")
    return float(entry)


def _vector(entry: Any, where: str, *, increasing: bool = False) -> tuple[float, ...]:
    if not isinstance(entry, list) or len(entry) < 2:
        raise DataFileError(_data_path(), f"{where}: expected a list of at least 2 numbers")
    out = tuple(_value(v, f"{where}[{i}]") for i, v in enumerate(entry))
    if increasing and any(b <= a for a, b in itertools.pairwise(out)):
        raise DataFileError(_data_path(), f"{where}: must be strictly increasing")
    return out


@dataclass(frozen=True)
class _Data:
    f_theoretical: Mapping[int, float]
    pretension: Mapping[int, float]
    contraction: Mapping[int, float]
    nominal: Mapping[int, tuple[float, float]]
    hunt_l0: tuple[float, ...]
    hunt_kmax: tuple[float, ...]
    slip_kmax: float
    v0_rel: tuple[float, ...]
    v0_force: tuple[float, ...]
    v3_coeffs: Mapping[int, tuple[float, float, float]]
    v3_f620: Mapping[int, tuple[str, tuple[float, ...]]]
    v3_kmax: Mapping[int, float | None]  # None: Hunt's table
    hunt: Mapping[str, float]


@functools.cache
def _data() -> _Data:
    path = _data_path()
    try:
        with open(path, encoding="utf-8") as fh:
            raw = json.load(fh)
    except (OSError, json.JSONDecodeError) as exc:
        raise DataFileError(path, f"cannot read: {exc}") from exc
    try:
        cat = raw["festo_catalogue"]
        per_d = {}
        for key in ("max_theoretical_force_N", "max_pretension_fraction", "max_contraction_fraction"):
            per_d[key] = types.MappingProxyType(
                {d: _value(cat[key][str(d)], f"festo_catalogue.{key}.{d}") for d in DIAMETERS_MM})
        nominal = {}
        for d in DIAMETERS_MM:
            e = cat["nominal_length_m"][str(d)]
            if "source" not in e:
                raise DataFileError(path, f"festo_catalogue.nominal_length_m.{d}: no 'source' note")
            nominal[d] = (_value(e["min"], "nominal min"), _value(e["max"], "nominal max"))
        hk = raw["hunt2017_kmax_vs_rest_length"]
        hunt_l0 = _vector(hk["rest_length_m"], "hunt2017_kmax_vs_rest_length.rest_length_m",
                          increasing=True)
        hunt_kmax = _vector(hk["kmax"], "hunt2017_kmax_vs_rest_length.kmax")
        t0 = raw["v0_thesis_table_10mm"]
        v0_rel = _vector(t0["relative_strain"], "v0_thesis_table_10mm.relative_strain",
                         increasing=True)
        v0_force = _vector(t0["force_N"], "v0_thesis_table_10mm.force_N")
        if _value(t0["pressure_kPa"], "v0 pressure") != _P_REF_KPA:
            raise DataFileError(path, "v0_thesis_table_10mm.pressure_kPa must be 620")
        v3 = raw["v3_measured"]
        coeffs, f620s, kdef = {}, {}, {}
        for d in DIAMETERS_MM:
            c = v3["normalized_force"][str(d)]
            coeffs[d] = tuple(_value(c[n], f"v3 c{n} {d} mm") for n in ("c0", "c1", "c2"))
            f = v3["f620"][str(d)]
            if f["kind"] == "atan":
                f620s[d] = ("atan", (_value(f["a1_N_per_kPa"], f"v3 f620 a1 {d}"),
                                     _value(f["a2_per_kPa_per_m"], f"v3 f620 a2 {d}"),
                                     _value(f["offset_m"], f"v3 f620 offset {d}")))
            elif f["kind"] == "constant":
                f620s[d] = ("constant", (_value(f["value"], f"v3 f620 {d}"),))
            else:
                raise DataFileError(path, f"v3 f620 {d} mm: unknown kind {f['kind']!r}")
            k = v3["kmax_default"][str(d)]
            if "source" not in k:
                raise DataFileError(path, f"v3 kmax_default {d} mm: no 'source' note")
            kdef[d] = None if k["kind"] == "hunt2017_table" else _value(k["value"], f"v3 kmax {d}")
        he = raw["hunt2017_equation"]
        hunt = {n: _value(he[k], f"hunt2017_equation.{k}") for n, k in (
            ("a0", "a0_kPa"), ("a1", "a1_kPa"), ("a2", "a2"), ("a3", "a3"), ("a4", "a4_per_N"),
            ("a5", "a5_kPa_per_N"), ("a6", "a6_kPa"), ("table_kmax", "table_kmax"))}
        slip = _value(raw["thesis_unit_slip_kmax"], "thesis_unit_slip_kmax")
    except (KeyError, TypeError) as exc:
        raise DataFileError(path, f"missing or malformed entry: {exc!r}") from exc
    if len(hunt_l0) != len(hunt_kmax):
        raise DataFileError(path, "hunt2017_kmax_vs_rest_length: length and kmax lists differ")
    if len(v0_rel) != len(v0_force) or v0_rel[0] != 0.0 or v0_rel[-1] != 1.0:
        raise DataFileError(path, "v0_thesis_table_10mm: lists differ or do not span 0..1")
    return _Data(
        f_theoretical=per_d["max_theoretical_force_N"],
        pretension=per_d["max_pretension_fraction"],
        contraction=per_d["max_contraction_fraction"],
        nominal=types.MappingProxyType(nominal),
        hunt_l0=hunt_l0, hunt_kmax=hunt_kmax, slip_kmax=slip, v0_rel=v0_rel, v0_force=v0_force,
        v3_coeffs=types.MappingProxyType(coeffs), v3_f620=types.MappingProxyType(f620s),
        v3_kmax=types.MappingProxyType(kdef), hunt=types.MappingProxyType(hunt),
    )


DIAMETERS_MM: tuple[int, ...] = (10, 20, 40)
"""Inner diameters [mm] of the Festo DMSP muscles pamkin models."""

F_MAX_THEORETICAL: Mapping[int, float] = _data().f_theoretical
"""Festo's maximum theoretical force [N] per diameter: {10: 630, 20: 1500, 40: 6000}."""


# --------------------------------------------------------------------------- backend shim


class _NumpyBackend:
    """numpy namespace of the shim."""

    name = "numpy"
    exp = staticmethod(np.exp)
    tan = staticmethod(np.tan)
    atan = staticmethod(np.arctan)
    tanh = staticmethod(np.tanh)
    log1p = staticmethod(np.log1p)
    fabs = staticmethod(np.abs)
    fmax = staticmethod(np.maximum)
    fmin = staticmethod(np.minimum)
    where = staticmethod(np.where)
    logical_and = staticmethod(np.logical_and)

    @staticmethod
    def asarray(x: Any) -> Any:
        return np.asarray(x, dtype=float)


_NUMPY = _NumpyBackend()


@functools.cache
def _casadi_backend() -> Any:
    import casadi as ca  # lazy: only when CasADi symbols are given

    class _CasadiBackend:
        name = "casadi"
        exp = staticmethod(ca.exp)
        tan = staticmethod(ca.tan)
        atan = staticmethod(ca.atan)
        tanh = staticmethod(ca.tanh)
        log1p = staticmethod(ca.log1p)
        fabs = staticmethod(ca.fabs)
        fmax = staticmethod(ca.fmax)
        fmin = staticmethod(ca.fmin)
        where = staticmethod(ca.if_else)
        logical_and = staticmethod(ca.logic_and)

        @staticmethod
        def asarray(x: Any) -> Any:
            if _is_casadi(x):
                return x
            a = np.asarray(x, dtype=float)
            return float(a) if a.ndim == 0 else ca.DM(a)

    return _CasadiBackend()


def _is_casadi(x: Any) -> bool:
    return type(x).__module__.split(".")[0] == "casadi"


def _backend(*args: Any) -> Any:
    return _casadi_backend() if any(_is_casadi(a) for a in args) else _NUMPY


def _numeric(x: Any) -> np.ndarray | None:
    """``x`` as a float array, or None if it is symbolic (CasADi SX/MX)."""
    if _is_casadi(x):
        if type(x).__name__ != "DM":
            return None
        return np.asarray(x, dtype=float)
    try:
        return np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"expected numbers, got {type(x).__name__}: {exc}") from exc


def _check(name: str, x: Any, *, low: float | None = None, low_open: bool = False,
           high: float | None = None, high_open: bool = False) -> None:
    """Validate numeric input: finite and within [low, high] (open ends if asked)."""
    a = _numeric(x)
    if a is None:
        return
    if np.isnan(a).any():
        raise ParameterError(f"{name} contains NaN")
    if not np.isfinite(a).all():
        raise ParameterError(f"{name} must be finite, got {a[~np.isfinite(a)].ravel()[0]}")
    if low is not None and ((a <= low).any() if low_open else (a < low).any()):
        raise ParameterError(f"{name} must be {'>' if low_open else '>='} {low}, got min {a.min()}")
    if high is not None and ((a >= high).any() if high_open else (a > high).any()):
        raise ParameterError(f"{name} must be {'<' if high_open else '<='} {high}, got max {a.max()}")


def _result(xp: Any, value: Any) -> Array:
    if xp is _NUMPY:
        return np.asarray(value, dtype=float)[()]
    return value


def check_diameter(diameter_mm: Any) -> int:
    """Validate a Festo DMSP diameter: returns 10, 20 or 40, else raises ParameterError."""
    if isinstance(diameter_mm, bool) or not isinstance(diameter_mm, (int, float, np.integer, np.floating)):
        raise ParameterError(f"diameter_mm must be one of {DIAMETERS_MM}, got {diameter_mm!r}")
    for d in DIAMETERS_MM:
        if diameter_mm == d:
            return d
    raise ParameterError(f"unknown Festo DMSP diameter {diameter_mm!r} mm; known: {DIAMETERS_MM}")


def canonical_model(model: str) -> str:
    """The force model's canonical name (``"v3"``, ``"v0"`` or ``"hunt2017"``) for a name or alias; raises
    ParameterError for an unknown one."""
    return _check_model(model)


def _check_model(model: str) -> str:
    aliases = {"thesis": "v0", "measured": "v3", "hunt": "hunt2017"}
    m = aliases.get(model, model)
    if m not in MODELS:
        raise ParameterError(f"unknown PAM force model {model!r}; known: {MODELS}")
    return m


# --------------------------------------------------------------------------- catalogue


def max_pretension(diameter_mm: int) -> float:
    """Festo's maximum permissible pretension (stretch) as a fraction of the nominal length.

    Args:
        diameter_mm: 10, 20 or 40.

    Returns:
        0.03, 0.04 or 0.05 [-] (thesis Table 3).
    """
    return _data().pretension[check_diameter(diameter_mm)]


def max_contraction(diameter_mm: int) -> float:
    """Festo's maximum permissible contraction as a fraction of the nominal length.

    Args:
        diameter_mm: 10, 20 or 40.

    Returns:
        0.25 [-] (thesis Table 3).
    """
    return _data().contraction[check_diameter(diameter_mm)]


def nominal_length_range(diameter_mm: int) -> tuple[float, float]:
    """Festo's range of nominal (resting) lengths [m]: (0.04, 9), (0.06, 9), (0.12, 9)."""
    return _data().nominal[check_diameter(diameter_mm)]


@functools.lru_cache(maxsize=1)
def _raw() -> dict:
    with open(_data_path(), encoding="utf-8") as fh:
        return json.load(fh)


def measured_rest_length_range(diameter_mm: int, model: str = "v3") -> tuple[float, float] | None:
    """Range of resting lengths [m] the force model was *measured* on (``None``: never measured).

    v3: 10 mm 0.112–0.518 m, 20 mm 0.300–0.509 m (the lab's 537 isometric tests); 40 mm is a fit to
    Festo MuscleSIM curves, not a measurement. Other models: ``None`` (no measured range recorded).
    """
    d = check_diameter(diameter_mm)
    if _check_model(model) != "v3":
        return None
    r = _raw()["v3_measured"]["measured_rest_length_m"][str(d)]
    return None if r is None else (float(r[0]), float(r[1]))


def kmax_is_measured(diameter_mm: int, model: str = "v3") -> bool:
    """Whether the default kmax of ``diameter_mm`` comes from measurements (10 mm: Hunt's table) or is
    an assumed constant (20, 40 mm; see the module docstring, decision 5)."""
    return check_diameter(diameter_mm) == 10


def pam_mass(rest_length: Array, diameter_mm: int) -> np.ndarray:
    """Estimated mass [kg] of one PAM with its fittings: base + per-metre × resting length.

    The numbers are an **assumption** (``festo_catalogue.assumed_mass`` in the data file: no Festo
    catalogue weights were available), for bulk comparisons between designs.
    """
    d = check_diameter(diameter_mm)
    m = _raw()["festo_catalogue"]["assumed_mass"]
    return m["base_kg"][str(d)] + m["per_m_kg"][str(d)] * np.asarray(rest_length, float)


def transmission_mass(rest_length: Array, diameter_mm: int, transmission: int = 1) -> np.ndarray:
    """Estimated mass [kg] a transmission adds to one PAM: 0 for a direct PAM (1); for a k:1 pulley block
    (k = 2, 3) k − 1 pulleys with bearings and the cable anchor (``base_kg`` each) plus a frame along the PAM
    (per metre of resting length). An **assumption** (``festo_catalogue.assumed_pulley_block_mass``)."""
    d = check_diameter(diameter_mm)
    k = int(transmission)
    if k == 1:
        return np.zeros_like(np.asarray(rest_length, float))
    m = _raw()["festo_catalogue"]["assumed_pulley_block_mass"]
    return (k - 1) * m["base_kg"][str(d)] + m["per_m_kg"][str(d)] * np.asarray(rest_length, float)


def outer_diameter(diameter_mm: int) -> float:
    """Assumed outer diameter [m] of a contracted PAM with fittings (PAM–PAM clearance); an
    **assumption** (``festo_catalogue.assumed_outer_diameter_mm``)."""
    d = check_diameter(diameter_mm)
    return float(_raw()["festo_catalogue"]["assumed_outer_diameter_mm"][str(d)]) / 1000.0


def outer_diameter_source() -> str:
    """The ``source`` note of :func:`outer_diameter`'s table (what the figures rest on)."""
    return str(_raw()["festo_catalogue"]["assumed_outer_diameter_mm"]["source"])


# --------------------------------------------------------------------------- formulas (xp)


def _interp_clamped(xp: Any, x: Any, knots_x: tuple[float, ...], knots_y: tuple[float, ...]) -> Any:
    """Piecewise-linear interpolation through the knots, clamped to the end values.

    Exact at the knots; the same operations on both backends.
    """
    out: Any = knots_y[-1]
    for i in range(len(knots_x) - 2, -1, -1):
        x0, x1, y0, y1 = knots_x[i], knots_x[i + 1], knots_y[i], knots_y[i + 1]
        out = xp.where(x < x1, y0 + ((y1 - y0) / (x1 - x0)) * (x - x0), out)
    return xp.where(x < knots_x[0], knots_y[0], out)


def _relu(xp: Any, x: Any, smoothing: float) -> Any:
    """max(x, 0), or its softplus of width ``smoothing`` (stable form)."""
    if smoothing == 0.0:
        return xp.fmax(x, 0.0)
    return xp.fmax(x, 0.0) + smoothing * xp.log1p(xp.exp(-xp.fabs(x) / smoothing))


def _sigmoid(xp: Any, z: Any) -> Any:
    return 0.5 * (1.0 + xp.tanh(0.5 * z))


def _kmax_expr(xp: Any, rest_length: Any, d: int, model: str, thesis_unit_slip: bool) -> Any:
    data = _data()
    if thesis_unit_slip:
        if model != "v0":
            raise ParameterError("thesis_unit_slip reproduces the thesis festo() and applies to "
                                 f"model='v0' only, not {model!r}")
        return data.slip_kmax + 0.0 * rest_length
    if model == "v3" and data.v3_kmax[d] is not None:
        return data.v3_kmax[d] + 0.0 * rest_length
    return _interp_clamped(xp, rest_length, data.hunt_l0, data.hunt_kmax)


def _f620_expr(xp: Any, rest_length: Any, d: int) -> Any:
    kind, p = _data().v3_f620[d]
    if kind == "constant":
        return p[0] + 0.0 * rest_length
    a1, a2, offset = p
    return xp.fmax(a1 * _P_REF_KPA * xp.atan(a2 * _P_REF_KPA * (rest_length - offset)), 0.0)


def _v3_normalized(xp: Any, rel: Any, p_star: Any, d: int, smoothing: float) -> Any:
    c0, c1, c2 = _data().v3_coeffs[d]
    fstar = c0 * (xp.exp(-c1 * rel) - 1.0) + p_star * xp.exp(-c2 * (rel * rel))
    return _relu(xp, fstar, smoothing)


def _v0_force(xp: Any, rel: Any, d: int, smoothing: float) -> Any:
    data = _data()
    table = _interp_clamped(xp, rel, data.v0_rel, data.v0_force)
    if smoothing == 0.0:
        f = xp.where(xp.logical_and(rel >= 0.0, rel <= 1.0), table, 0.0)
    else:
        f = table * _sigmoid(xp, rel / smoothing) * _sigmoid(xp, (1.0 - rel) / smoothing)
    return f * (data.f_theoretical[d] / data.f_theoretical[10])


def _hunt_pressure_kpa(xp: Any, strain: Any, force_n: Any, km: Any, direction: float) -> Any:
    h = _data().hunt
    x = strain / (h["a4"] * force_n + km)
    return (h["a0"] + h["a1"] * xp.tan(h["a2"] * (x + h["a3"])) + h["a5"] * force_n
            + h["a6"] * direction)


# --------------------------------------------------------------------------- public API


def kmax(rest_length: Array, diameter_mm: int = 10, *, model: str = "v3",
         thesis_unit_slip: bool = False) -> Array:
    """Free contraction at 620 kPa (kmax, the dissertation's ε620) of a PAM.

    v0 (thesis) uses Hunt's 2017 10 mm resting-length table, in metres, for every diameter;
    v3 uses it for 10 mm and constants for 20 mm (0.255) and 40 mm (0.275). The table is
    interpolated linearly and clamped at its ends (0.1531 m → 0.1491, 0.2809 m → 0.175).

    Args:
        rest_length: Resting length l0 [m], > 0 (numpy or CasADi).
        diameter_mm: 10, 20 or 40.
        model: ``"v3"``, ``"v0"`` or ``"hunt2017"`` (10 mm table).
        thesis_unit_slip: Reproduce the thesis's unit bug (kmax always 0.1491); v0 only.

    Returns:
        kmax [-], shaped like ``rest_length``.

    Raises:
        ParameterError: Unknown diameter or model, non-positive or NaN length.
    """
    d = check_diameter(diameter_mm)
    m = _check_model(model)
    _check("rest_length", rest_length, low=0.0, low_open=True)
    xp = _backend(rest_length)
    return _result(xp, _kmax_expr(xp, xp.asarray(rest_length), d, m, thesis_unit_slip))


def f620(rest_length: Array, diameter_mm: int = 10) -> Array:
    """v3 maximum force F620(l0) [N]: isometric force at ε = 0 and 620 kPa.

    ``a1·620·atan(a2·620·(l0 − offset))`` for 10 and 20 mm (clipped at 0 below the end-cap
    offset), 6398.4 N for 40 mm. E.g. a 0.485 m 10 mm PAM: 443.4 N.

    Args:
        rest_length: Resting length l0 [m], > 0 (numpy or CasADi).
        diameter_mm: 10, 20 or 40.

    Returns:
        F620 [N], shaped like ``rest_length``.
    """
    d = check_diameter(diameter_mm)
    _check("rest_length", rest_length, low=0.0, low_open=True)
    xp = _backend(rest_length)
    return _result(xp, _f620_expr(xp, xp.asarray(rest_length), d))


def force(strain: Array, rest_length: Array, pressure: Array = DEFAULT_PRESSURE,
          diameter_mm: int = 10, model: str = "v3", *, kmax: Array | None = None,
          smoothing: float = 0.0, out_of_range: OutOfRange = "model",
          thesis_unit_slip: bool = False) -> Array:
    """Isometric tension of one Festo PAM [N].

    Args:
        strain: Contraction ε = (l0 − l)/l0 [-], positive contracted, negative stretched.
        rest_length: Resting length l0 [m], > 0.
        pressure: Gauge pressure [Pa], ≥ 0 (default 620 kPa; v0 accepts only 620 kPa).
        diameter_mm: 10, 20 or 40.
        model: ``"v3"`` (default, measured), ``"v0"`` (thesis table) or ``"hunt2017"``
            (Hunt's equation solved for F; 10 mm, numpy only). Aliases: ``"measured"``,
            ``"thesis"``, ``"hunt"``.
        kmax: Free contraction at 620 kPa [-], 0 < kmax < 1; default :func:`kmax` of the model.
        smoothing: 0 for the exact model, > 0 for smooth cuts (see module docstring).
        out_of_range: ``"model"``, ``"nan"`` or ``"raise"`` for −max_pretension ≤ ε ≤ kmax
            being violated (``"nan"``/``"raise"`` numpy only).
        thesis_unit_slip: v0 only: kmax always 0.1491 as in the thesis.

    Returns:
        Force [N], the broadcast shape of the inputs (numpy), or a CasADi expression.

    Raises:
        ParameterError: Unknown diameter/model/option, NaN inputs, non-positive lengths,
            negative pressures, a pressure other than 620 kPa for v0, or (``"raise"``)
            strains outside the range.
    """
    d = check_diameter(diameter_mm)
    m = _check_model(model)
    if out_of_range not in ("model", "nan", "raise"):
        raise ParameterError(f"out_of_range must be 'model', 'nan' or 'raise', got {out_of_range!r}")
    if isinstance(smoothing, bool) or not isinstance(smoothing, (int, float)) \
            or not math.isfinite(smoothing) or smoothing < 0:
        raise ParameterError(f"smoothing must be a finite number >= 0, got {smoothing!r}")
    smoothing = float(smoothing)
    _check("strain", strain)
    _check("rest_length", rest_length, low=0.0, low_open=True)
    _check("pressure", pressure, low=0.0)
    if kmax is not None:
        _check("kmax", kmax, low=0.0, low_open=True, high=1.0, high_open=True)
    xp = _backend(strain, rest_length, pressure, kmax)
    if xp is not _NUMPY and out_of_range != "model":
        raise ParameterError("out_of_range='nan'/'raise' need numeric inputs; CasADi gets 'model'")
    if m == "hunt2017":
        if xp is not _NUMPY:
            raise ParameterError("model='hunt2017' is solved numerically: numpy inputs only")
        if d != 10:
            raise ParameterError("model='hunt2017' describes the 10 mm PAM only")
        if thesis_unit_slip:
            raise ParameterError("thesis_unit_slip applies to model='v0' only")
    if m == "v0":
        p = _numeric(pressure)
        if p is None or not np.all(p == DEFAULT_PRESSURE):
            raise ParameterError("model='v0' is the thesis's 620 kPa table: pressure must be "
                                 "620e3 Pa; use model='v3' (or 'hunt2017') for other pressures")

    eps = xp.asarray(strain)
    l0 = xp.asarray(rest_length)
    km = _kmax_expr(xp, l0, d, m, thesis_unit_slip) if kmax is None else xp.asarray(kmax)
    if m == "v3":
        p_star = xp.asarray(pressure) / (_P_REF_KPA * 1e3)
        f = _v3_normalized(xp, eps / km, p_star, d, smoothing) * _f620_expr(xp, l0, d)
    elif m == "v0":
        f = _v0_force(xp, eps / km, d, smoothing) + 0.0 * l0
    else:
        f = hunt_force(eps, pressure, l0, kmax=km)

    if out_of_range != "model":
        f, e, k = np.broadcast_arrays(np.asarray(f, float), np.asarray(eps, float),
                                      np.asarray(km, float))
        bad = (e < -max_pretension(d)) | (e > k)
        if bad.any():
            if out_of_range == "raise":
                raise ParameterError(
                    f"{int(bad.sum())} strain(s) outside -{max_pretension(d)} <= strain <= kmax "
                    f"for the {d} mm PAM (min {e.min():.4g}, max {e.max():.4g})")
            f = np.where(bad, np.nan, f)
    return _result(xp, f)


def hunt_pressure(strain: Array, force: Array, rest_length: Array, *, kmax: Array | None = None,
                  direction: float = 0.0) -> Array:
    """Hunt 2017 equation: pressure [Pa] that holds a 10 mm PAM at ``strain`` under ``force``.

    ``P = a0 + a1·tan(a2·(ε/(a4·F + kmax) + a3)) + a5·F + a6·S`` (thesis eq. 7, units fixed
    to F in N). With numpy inputs, points outside the equation's branch (tan argument
    outside ±π/2, or a non-positive denominator at ε ≠ 0) give NaN.

    Args:
        strain: Contraction ε [-].
        force: Tension F [N].
        rest_length: Resting length l0 [m] > 0 (for kmax from Hunt's table).
        kmax: Override kmax [-] (e.g. 0.175, the table's).
        direction: S: +1 inflating, −1 deflating, 0 isometric (default).

    Returns:
        Pressure [Pa].
    """
    _check("strain", strain)
    _check("force", force)
    _check("rest_length", rest_length, low=0.0, low_open=True)
    if kmax is not None:
        _check("kmax", kmax, low=0.0, low_open=True, high=1.0, high_open=True)
    if direction not in (-1, 0, 1):
        raise ParameterError(f"direction must be -1, 0 or +1, got {direction!r}")
    xp = _backend(strain, force, rest_length, kmax)
    eps, f, l0 = xp.asarray(strain), xp.asarray(force), xp.asarray(rest_length)
    km = _kmax_expr(xp, l0, 10, "hunt2017", False) if kmax is None else xp.asarray(kmax)
    p = _hunt_pressure_kpa(xp, eps, f, km, float(direction)) * 1e3
    if xp is _NUMPY:
        h = _data().hunt
        den = h["a4"] * f + km
        with np.errstate(divide="ignore", invalid="ignore"):
            arg = h["a2"] * (eps / den + h["a3"])
        ok = (np.abs(arg) < np.pi / 2) & ((den > 0) | (eps == 0))
        p = np.where(ok, p, np.nan)
    return _result(xp, p)


def hunt_force(strain: Array, pressure: Array, rest_length: Array, *, kmax: Array | None = None,
               direction: float = 0.0, tol: float = 1e-10, max_iter: int = 200) -> np.ndarray:
    """Hunt 2017 equation solved for the tension F [N] of a 10 mm PAM (numpy only).

    For ε > 0 the equation's right side increases monotonically in F from −∞ to +∞ on the
    tan branch (F < (kmax − ε/x_hi)/|a4|, x_hi = π/(2·a2) − a3), so the root is unique; it is
    found by Newton steps safeguarded by bisection on the bracket [0, F_hi]. Negative roots
    (the PAM is slack) give 0. At ε = 0 the equation is linear in F. ε < 0 (stretched) is
    outside the equation: NaN.

    Args:
        strain: Contraction ε [-].
        pressure: Gauge pressure [Pa], ≥ 0.
        rest_length: Resting length l0 [m] > 0 (kmax from Hunt's table).
        kmax: Override kmax [-] (0.175 reproduces Hunt's force table).
        direction: S: +1 inflating, −1 deflating, 0 isometric (default).
        tol: Absolute tolerance on F [N].
        max_iter: Iteration limit.

    Returns:
        Force [N] ≥ 0 (NaN for ε < 0), the broadcast shape of the inputs.
    """
    for name, x in (("strain", strain), ("pressure", pressure), ("rest_length", rest_length),
                    ("kmax", kmax)):
        if x is not None and _numeric(x) is None:
            raise ParameterError(f"hunt_force is numeric only; {name} is a CasADi symbol")
    _check("strain", strain)
    _check("pressure", pressure, low=0.0)
    _check("rest_length", rest_length, low=0.0, low_open=True)
    if kmax is not None:
        _check("kmax", kmax, low=0.0, low_open=True, high=1.0, high_open=True)
    if direction not in (-1, 0, 1):
        raise ParameterError(f"direction must be -1, 0 or +1, got {direction!r}")
    h = _data().hunt
    a0, a1, a2, a3, a4, a5, a6 = (h[k] for k in ("a0", "a1", "a2", "a3", "a4", "a5", "a6"))
    l0 = _numeric(rest_length)
    km = _interp_clamped(_NUMPY, l0, _data().hunt_l0, _data().hunt_kmax) if kmax is None \
        else _numeric(kmax)
    try:
        k, p, km = (np.array(a, dtype=float) for a in np.broadcast_arrays(
            _numeric(strain), _numeric(pressure) / 1e3, km))
    except ValueError as exc:
        raise ParameterError(f"inputs do not broadcast: {exc}") from exc
    s = float(direction)
    out = np.full(k.shape, np.nan)

    zero = k == 0
    out[zero] = np.maximum((p[zero] - a0 - a1 * math.tan(a2 * a3) - a6 * s) / a5, 0.0)

    pos = k > 0
    x_hi = (math.pi / 2) / a2 - a3
    f_hi = np.where(pos, (km - k / x_hi) / (-a4), 0.0)

    def g(f: np.ndarray, kk: np.ndarray, pp: np.ndarray, kkm: np.ndarray) -> np.ndarray:
        return a0 + a1 * np.tan(a2 * (kk / (a4 * f + kkm) + a3)) + a5 * f + a6 * s - pp

    def dg(f: np.ndarray, kk: np.ndarray, kkm: np.ndarray) -> np.ndarray:
        den = a4 * f + kkm
        c = np.cos(a2 * (kk / den + a3))
        return a1 * a2 * (-kk * a4 / den**2) / c**2 + a5

    solve = pos & (f_hi > 0)
    out[pos & ~solve] = 0.0
    idx = np.flatnonzero(solve)
    kk, pp, kkm = k.ravel()[idx], p.ravel()[idx], km.ravel()[idx]
    g0 = g(np.zeros_like(kk), kk, pp, kkm)
    slack = g0 >= 0
    flat = out.reshape(-1)
    flat[idx[slack]] = 0.0
    idx, kk, pp, kkm = idx[~slack], kk[~slack], pp[~slack], kkm[~slack]
    lo = np.zeros_like(kk)
    hi = f_hi.ravel()[idx]
    f = 0.5 * (lo + hi)
    done = np.zeros(kk.shape, dtype=bool)
    for _ in range(max_iter):
        if done.all():
            break
        gf = g(f, kk, pp, kkm)
        lo = np.where(gf < 0, f, lo)
        hi = np.where(gf >= 0, f, hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            fn = f - gf / dg(f, kk, kkm)
        bisect = ~np.isfinite(fn) | (fn <= lo) | (fn >= hi)
        fn = np.where(bisect, 0.5 * (lo + hi), fn)
        done = done | (np.abs(fn - f) <= tol) | (hi - lo <= tol)
        f = np.where(done, f, fn)
    if not done.all():
        raise ParameterError(f"hunt_force did not converge in {max_iter} iterations")
    flat[idx] = f
    out[k < 0] = np.nan
    return out[()]


# --------------------------------------------------------------------------- model objects


@runtime_checkable
class FestoModel(Protocol):
    """A PAM force model: tension from strain, resting length and pressure."""

    @property
    def name(self) -> str:
        """Model name (``"v3"``, ``"v0"``, ``"hunt2017"``)."""

    @property
    def diameter_mm(self) -> int:
        """Inner diameter [mm]."""

    def force(self, strain: Array, rest_length: Array, pressure: Array = DEFAULT_PRESSURE) -> Array:
        """Tension [N] at contraction ``strain`` [-], resting length [m], pressure [Pa]."""

    def kmax(self, rest_length: Array) -> Array:
        """Free contraction at 620 kPa [-] for the resting length [m]."""


@dataclass(frozen=True)
class FestoForceModel:
    """A configured PAM force model (implements :class:`FestoModel`).

    Attributes:
        name: ``"v3"`` (default), ``"v0"`` or ``"hunt2017"``.
        diameter_mm: 10, 20 or 40.
        kmax_value: Fixed kmax [-], or None for the model's default :func:`kmax`.
        smoothing: See :func:`force`.
        out_of_range: See :func:`force`.
        thesis_unit_slip: See :func:`force`.
    """

    name: str = "v3"
    diameter_mm: int = 10
    kmax_value: float | None = None
    smoothing: float = 0.0
    out_of_range: OutOfRange = "model"
    thesis_unit_slip: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", _check_model(self.name))
        object.__setattr__(self, "diameter_mm", check_diameter(self.diameter_mm))

    def force(self, strain: Array, rest_length: Array, pressure: Array = DEFAULT_PRESSURE) -> Array:
        """Tension [N]; see :func:`force`."""
        return force(strain, rest_length, pressure, self.diameter_mm, self.name,
                     kmax=self.kmax_value, smoothing=self.smoothing,
                     out_of_range=self.out_of_range, thesis_unit_slip=self.thesis_unit_slip)

    def kmax(self, rest_length: Array) -> Array:
        """kmax [-]; see :func:`kmax`."""
        if self.kmax_value is not None:
            _check("rest_length", rest_length, low=0.0, low_open=True)
            return _result(_backend(rest_length), self.kmax_value + 0.0 * _backend(
                rest_length).asarray(rest_length))
        return kmax(rest_length, self.diameter_mm, model=self.name,
                    thesis_unit_slip=self.thesis_unit_slip)


@dataclass(frozen=True)
class ForceLaw:
    """The measured (v3) force law of a fixed set of PAMs, its inputs checked once: for simulations that
    evaluate it every step (:mod:`pamkin.sim.pams`). At a fixed strain the v3 tension is affine in pressure,
    ``F = max(a(ε) + b(ε)·p, 0)`` (module docstring); :meth:`affine` gives a and b, :meth:`__call__` the
    tension — both equal to :func:`force` (``model="v3"``, no smoothing) to round-off. Build with
    :func:`force_law`.

    Attributes (one entry per PAM):
        kmax: Free contraction at 620 kPa [-].
        f620: Force scale [N].
        c0, c1, c2: The size's v3 coefficients [-].
    """

    kmax: np.ndarray
    f620: np.ndarray
    c0: np.ndarray
    c1: np.ndarray
    c2: np.ndarray

    def affine(self, strain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(a, b) [N, N/Pa] at contractions ``strain`` (n,): the unclipped tension is a + b·p."""
        rel = np.asarray(strain, float) / self.kmax
        a = self.c0 * (np.exp(-self.c1 * rel) - 1.0) * self.f620
        b = np.exp(-self.c2 * rel * rel) * self.f620 / (_P_REF_KPA * 1e3)
        return a, b

    def __call__(self, strain: np.ndarray, pressure: np.ndarray) -> np.ndarray:
        """Tension [N] at contractions ``strain`` (n,) and gauge pressures ``pressure`` (..., n) [Pa]."""
        a, b = self.affine(strain)
        return np.maximum(a + b * np.asarray(pressure, float), 0.0)


def force_law(rest_length: Array, diameter_mm: Array, kmax: Array | None = None) -> ForceLaw:
    """:class:`ForceLaw` of PAMs with resting lengths [m] and Festo diameters (one per PAM, any mix of
    10/20/40), ``kmax`` as in :func:`force` (default: the v3 model's). Raises ParameterError on bad input."""
    l0 = np.atleast_1d(np.asarray(rest_length, float))
    dia = np.atleast_1d(np.asarray(diameter_mm))
    if l0.shape != dia.shape:
        raise ParameterError(f"one diameter per resting length: {dia.shape} vs {l0.shape}")
    _check("rest_length", l0, low=0.0, low_open=True)
    ds = [check_diameter(d) for d in dia.tolist()]
    km = np.array([_kmax_expr(np, l, d, "v3", False) for l, d in zip(l0, ds)], float).reshape(l0.shape) \
        if kmax is None else np.broadcast_to(np.asarray(kmax, float), l0.shape).copy()
    _check("kmax", km, low=0.0, low_open=True, high=1.0, high_open=True)
    f620_ = np.array([_f620_expr(np, l, d) for l, d in zip(l0, ds)], float).reshape(l0.shape)
    c = np.array([_data().v3_coeffs[d] for d in ds], float).reshape(l0.shape + (3,))
    return ForceLaw(km, f620_, c[..., 0], c[..., 1], c[..., 2])
