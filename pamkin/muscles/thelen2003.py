"""Static equilibrium of OpenSim 4.6's ``Thelen2003Muscle``, compiled with numba.

At zero fibre velocity the force-velocity multiplier of the Thelen (2003) model
is exactly 1, so the musculotendon equilibrium that OpenSim's
``Thelen2003Muscle::computeInitialFiberEquilibrium`` finds (with zero speeds)
is the root, in fibre length ``l``, of::

    Fmax·(a·fL(l/l0) + fPE(l/l0))·cos(alpha(l)) = Fmax·fT((lMT − l·cos(alpha(l)))/lTs)

with the fixed-width pennation model ``l·sin(alpha) = l0·sin(alpha0)`` (constant
parallelogram height ``h``). The curves are OpenSim's (see
:func:`force_length_active`, :func:`force_length_passive`,
:func:`tendon_force_length`); activation is clamped to
``[minimum_activation, 1]`` as OpenSim's activation model does (activation outside [0, 1]
is an error).

**Minimum fibre length.** OpenSim keeps the fibre at or above the length at
which the pennation angle reaches ``maximum_pennation_angle`` (default
``acos(0.1)`` ≈ 84.26°): ``l_min = h / sin(alpha_max)``. For an unpennated
muscle (``h = 0``) this is 0. When even the shortest admissible fibre pulls
harder along the tendon than the tendon does (always the case when the whole
musculotendon is shorter than ``lTs + l_min·cos(alpha_max)``, i.e. the tendon
is slack), OpenSim's Newton search stops at ``l_min`` without raising and
reports the fibre *clamped* there: tendon force ``Fmax·fT(tendon strain)``
with the tendon length that this fibre length leaves (0 for a slack tendon),
zero active fibre force. :func:`equilibrium` reproduces exactly that and
flags those entries in :attr:`Equilibrium.clamped`.

One path-dependent quirk of OpenSim is reproduced too: for an unpennated muscle
(``l_min = 0``) whose equilibrium fibre would be very short (under 0.3 mm on
Gait2392), OpenSim's Newton search can land on ``l = 0``, where its slope is 0/0,
and stay there; it then reports the fibre clamped at 0 and the tendon force
``Fmax·fT(lMT/lTs)``.
:func:`equilibrium` replays OpenSim's search (from OpenSim's own starting guess) to
find those entries (``opensim_search=False`` skips this and keeps the force
continuous in ``lMT``).

**No equilibrium.** OpenSim's search gives up after 20 Newton iterations without
reaching its tolerance ``max(1e-8·Fmax, 10·SignificantReal)`` with the fibre above its
minimum length; ``computeInitialFiberEquilibrium`` then raises ``MuscleCannotEquilibrate``
(and ``Model.equilibrateMuscles`` rethrows it). This happens where the tendon is stretched
to several times its slack length (e.g. Leg39 with its knee translations uncoupled, tibia
moved by up to 5 m; never within Gait2392's ranges): the search starts from a fibre far
longer than the equilibrium one and each Newton step on the exponential passive curve
shortens it by only about ``e0M/kPE·l0``. :func:`equilibrium` reproduces OpenSim's
criterion by replaying its search wherever it can end elsewhere than at the root: for
unpennated fibres and wherever OpenSim's first fibre lies beyond l0 along the tendon
(descending limb or passive region; on the ascending limb the force error increases with
the fibre length and the search never took more than 9 of its 20 iterations on 1.2·10⁶ random
(muscle, length) pairs, see :data:`pamkin.muscles._thelen_kernel.SEARCH_START_MAX`). It returns NaN for those
entries with :attr:`Equilibrium.failed` set (:func:`tendon_force` NaN too);
:meth:`pamkin.Model.tendon_forces` also warns (:class:`pamkin.errors.EquilibriumWarning`).
A true equilibrium may exist there (pamkin's own root search would find it, with forces up
to ~10⁶ N), but OpenSim reports none, and neither does pamkin.

The root itself is then found with a bracketed, safeguarded Newton iteration on the
fibre length along the tendon (bisection whenever a Newton step would leave the
bracket), to a residual far below OpenSim's own tolerance of ``1e-8·Fmax``, started
from the replayed search's answer (or, with ``opensim_search=False``, from one
fixed-point step away from the rigid-tendon solution; then no entry fails and the
true equilibrium is always returned).

**Implementation.** Every formula (curves, pennation geometry, the search replay,
clamping) is written once, as scalar numba functions in
:mod:`pamkin.muscles._thelen_kernel`; :func:`equilibrium` runs them over all
(configuration, muscle) pairs in one compiled kernel, in parallel over chunks of
configurations (``NUMBA_NUM_THREADS`` threads), and the public curve functions are
numba ufuncs built on the same definitions. The first call in a fresh environment
compiles the kernel (a few seconds; cached on disk afterwards).

Parameters that only matter away from zero fibre velocity (``af``, ``flen``,
``max_contraction_velocity``, ``fv_linear_extrap_threshold``) are carried in
:class:`ThelenParams` so that a model's muscles round-trip, but do not change
any result here.

Reference: D. G. Thelen, "Adjustment of muscle mechanics model parameters to
simulate dynamic contractions in older adults", J. Biomech. Eng. 125 (2003);
OpenSim 4.6 ``Thelen2003Muscle`` and ``MuscleFixedWidthPennationModel``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, fields
from pathlib import Path

import numba
import numpy as np

from pamkin.errors import (
    ConfigurationError,
    OsimError,
    ParameterError,
    UnsupportedFeatureError,
)
from pamkin.muscles import _thelen_kernel as _k

__all__ = [
    "Equilibrium",
    "ThelenParams",
    "equilibrium",
    "force_length_active",
    "force_length_passive",
    "minimum_fiber_length",
    "params_from_osim_xml",
    "tendon_force",
    "tendon_force_failed",
    "tendon_force_length",
]

#: ThelenParams field -> (Thelen2003Muscle property name in the .osim file, OpenSim 4.6 default).
#: ``None`` as default means the property is required.
OSIM_PROPERTIES: dict[str, tuple[str, float | None]] = {
    "max_isometric_force": ("max_isometric_force", None),
    "optimal_fiber_length": ("optimal_fiber_length", None),
    "tendon_slack_length": ("tendon_slack_length", None),
    "pennation_angle_at_optimal": ("pennation_angle_at_optimal", 0.0),
    "fmax_tendon_strain": ("FmaxTendonStrain", 0.04),
    "fmax_muscle_strain": ("FmaxMuscleStrain", 0.6),
    "kshape_active": ("KshapeActive", 0.45),
    "kshape_passive": ("KshapePassive", 5.0),
    "af": ("Af", 0.25),
    "flen": ("Flen", 1.4),
    "max_contraction_velocity": ("max_contraction_velocity", 10.0),
    "fv_linear_extrap_threshold": ("fv_linear_extrap_threshold", 0.95),
    "maximum_pennation_angle": ("maximum_pennation_angle", math.acos(0.1)),
    "minimum_activation": ("minimum_activation", 0.01),
}


# ----------------------------------------------------------------------------------------------
# Curves
# ----------------------------------------------------------------------------------------------


def tendon_force_length(normalized_tendon_length: np.ndarray,
                        fmax_tendon_strain: float | np.ndarray = 0.04) -> np.ndarray:
    """Thelen2003 tendon force-length curve fT, as in OpenSim 4.6 (``calcfse``).

    With strain ``e = lT/lTs − 1`` and ``e0 = fmax_tendon_strain``: 0 for ``e ≤ 0``;
    an exponential toe ``0.33·(exp(3·e/e_toe) − 1)/(exp(3) − 1)`` up to
    ``e_toe = 99·e0·exp(3)/(166·exp(3) − 67)`` (≈ 0.609·e0), where fT = 0.33; then the
    line ``k_lin·(e − e_toe) + 0.33`` with ``k_lin = 0.67/(e0 − e_toe)``, which reaches
    fT = 1 at ``e = e0`` and continues unbounded. Value and slope are continuous at e_toe.

    Args:
        normalized_tendon_length: Tendon length over tendon slack length, lT/lTs [-].
        fmax_tendon_strain: Tendon strain at maximum isometric force, e0 [-]; broadcasts.

    Returns:
        Tendon force over maximum isometric force [-], broadcast shape.
    """
    return _k.tendon_force_length_ufunc(_f(normalized_tendon_length), _f(fmax_tendon_strain))


def force_length_active(normalized_fiber_length: np.ndarray,
                        kshape_active: float | np.ndarray = 0.45) -> np.ndarray:
    """Thelen2003 active force-length curve fL (OpenSim ``calcfal``): a Gaussian.

    ``fL = exp(−(lM/l0 − 1)² / kshape_active)``; 1 at optimal fibre length, never 0.

    Args:
        normalized_fiber_length: Fibre length over optimal fibre length, lM/l0 [-].
        kshape_active: Shape factor (variance) of the Gaussian [-]; broadcasts.

    Returns:
        Active force multiplier [-], broadcast shape.
    """
    return _k.force_length_active_ufunc(_f(normalized_fiber_length), _f(kshape_active))


def force_length_passive(normalized_fiber_length: np.ndarray,
                         fmax_muscle_strain: float | np.ndarray = 0.6,
                         kshape_passive: float | np.ndarray = 5.0) -> np.ndarray:
    """Thelen2003 passive fibre force-length curve fPE (OpenSim ``calcfpe``).

    ``fPE = (exp(kPE·(lM/l0 − 1)/e0M) − 1)/(exp(kPE) − 1)`` for ``lM/l0 > 1``, else 0;
    it equals 1 at ``lM/l0 = 1 + e0M``.

    Args:
        normalized_fiber_length: Fibre length over optimal fibre length, lM/l0 [-].
        fmax_muscle_strain: Passive fibre strain at maximum isometric force, e0M [-].
        kshape_passive: Exponential shape factor kPE [-].

    Returns:
        Passive force multiplier [-], broadcast shape.
    """
    return _k.force_length_passive_ufunc(_f(normalized_fiber_length), _f(fmax_muscle_strain),
                                         _f(kshape_passive))


def _f(x) -> np.ndarray:
    """Float array view of ``x`` (one compiled ufunc loop, float64)."""
    return np.asarray(x, dtype=float)


# ----------------------------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ThelenParams:
    """Per-muscle parameters of OpenSim's ``Thelen2003Muscle``; one entry per muscle.

    Every array field has shape ``(n_muscles,)`` (scalars broadcast); arrays are stored
    as read-only float copies and checked on construction (:meth:`validate`). Optional
    fields default to OpenSim 4.6's property defaults (see :data:`OSIM_PROPERTIES`).

    Attributes:
        max_isometric_force: Fmax [N].
        optimal_fiber_length: l0 [m].
        tendon_slack_length: lTs [m].
        pennation_angle_at_optimal: alpha0, pennation at optimal fibre length [rad].
        fmax_tendon_strain: Tendon strain at Fmax, e0 (``FmaxTendonStrain``) [-].
        fmax_muscle_strain: Passive fibre strain at Fmax, e0M (``FmaxMuscleStrain``) [-].
        kshape_active: Gaussian shape factor of fL (``KshapeActive``) [-].
        kshape_passive: Exponential shape factor of fPE (``KshapePassive``) [-].
        af: Force-velocity shape factor (``Af``) [-]; no effect at zero velocity.
        flen: Maximum normalized lengthening force (``Flen``) [-]; no effect at zero velocity.
        max_contraction_velocity: [l0/s]; no effect at zero velocity.
        fv_linear_extrap_threshold: Force-velocity extrapolation threshold [-]; no effect
            at zero velocity.
        maximum_pennation_angle: alpha_max; sets the minimum fibre length [rad].
        minimum_activation: Lower clamp of activation [-].
        names: Muscle names (empty, or one per muscle), used in error messages.
    """

    max_isometric_force: np.ndarray
    optimal_fiber_length: np.ndarray
    tendon_slack_length: np.ndarray
    pennation_angle_at_optimal: np.ndarray
    fmax_tendon_strain: np.ndarray
    fmax_muscle_strain: np.ndarray
    kshape_active: np.ndarray
    kshape_passive: np.ndarray
    af: np.ndarray | None = None
    flen: np.ndarray | None = None
    max_contraction_velocity: np.ndarray | None = None
    fv_linear_extrap_threshold: np.ndarray | None = None
    maximum_pennation_angle: np.ndarray | None = None
    minimum_activation: np.ndarray | None = None
    names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        arrays = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "names"}
        sizes = [np.size(v) for v in arrays.values() if v is not None and np.ndim(v) > 0]
        n = max(sizes, default=1)
        for key, value in arrays.items():
            if value is None:
                value = OSIM_PROPERTIES[key][1]
            arr = np.asarray(value, dtype=float)
            if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != n):
                raise ParameterError(f"{key} has shape {arr.shape}, expected ({n},)")
            arr = np.array(np.broadcast_to(arr, (n,)), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)
        names = tuple(str(s) for s in self.names)
        if names and len(names) != n:
            raise ParameterError(f"names has {len(names)} entries for {n} muscles")
        object.__setattr__(self, "names", names)
        self.validate()

    @property
    def n_muscles(self) -> int:
        """Number of muscles."""
        return int(self.max_isometric_force.shape[0])

    def muscle_name(self, i: int) -> str:
        """Name of muscle ``i`` (``"muscle #i"`` when no names were given)."""
        return self.names[i] if self.names else f"muscle #{i}"

    def validate(self) -> None:
        """Check every parameter's range (OpenSim 4.6's checks plus physical ones).

        Raises:
            ParameterError: naming the first offending muscle and parameter, e.g. for a
                non-positive ``optimal_fiber_length``, ``max_isometric_force`` or
                ``tendon_slack_length``, a pennation angle outside ``[0, pi/2)``, a
                non-finite value, ``flen <= 1``, ``maximum_pennation_angle`` not above
                ``pennation_angle_at_optimal`` or ``minimum_activation`` outside ``[0, 1)``.
        """
        half_pi = math.pi / 2
        checks: list[tuple[str, np.ndarray, str]] = [
            ("max_isometric_force", self.max_isometric_force > 0, "must be > 0 N"),
            ("optimal_fiber_length", self.optimal_fiber_length > 0, "must be > 0 m"),
            ("tendon_slack_length", self.tendon_slack_length > 0, "must be > 0 m"),
            ("pennation_angle_at_optimal",
             (self.pennation_angle_at_optimal >= 0) & (self.pennation_angle_at_optimal < half_pi),
             "must lie in [0, pi/2) rad"),
            ("fmax_tendon_strain", self.fmax_tendon_strain > 0, "must be > 0"),
            ("fmax_muscle_strain", self.fmax_muscle_strain > 0, "must be > 0"),
            ("kshape_active", self.kshape_active > 0, "must be > 0"),
            ("kshape_passive", self.kshape_passive > 0, "must be > 0"),
            ("af", self.af > 0, "must be > 0"),
            ("flen", self.flen > 1, "must be > 1"),
            ("max_contraction_velocity", self.max_contraction_velocity > 0, "must be > 0"),
            ("fv_linear_extrap_threshold", self.fv_linear_extrap_threshold > 1 / self.flen,
             "must be > 1/flen"),
            ("maximum_pennation_angle",
             (self.maximum_pennation_angle > self.pennation_angle_at_optimal)
             & (self.maximum_pennation_angle <= half_pi),
             "must exceed pennation_angle_at_optimal and be <= pi/2 rad"),
            ("minimum_activation", (self.minimum_activation >= 0) & (self.minimum_activation < 1),
             "must lie in [0, 1)"),
        ]
        for key, ok, rule in checks:
            values = getattr(self, key)
            bad = np.flatnonzero(~(ok & np.isfinite(values)))
            if bad.size:
                i = int(bad[0])
                raise ParameterError(f"{self.muscle_name(i)}: {key} {rule} (got {float(values[i]):g})")

    @classmethod
    def from_osim_properties(cls, properties: list[dict[str, float]],
                             names: tuple[str, ...] | list[str] = ()) -> ThelenParams:
        """Build from one dict per muscle keyed by OpenSim property names.

        Args:
            properties: e.g. ``{"max_isometric_force": 819.0, "FmaxTendonStrain": 0.033, ...}``;
                absent optional properties take OpenSim 4.6's defaults, other keys are ignored.
            names: Muscle names.

        Raises:
            ParameterError: a required property is missing or a value is out of range.
        """
        names = tuple(names)
        columns: dict[str, list[float]] = {key: [] for key in OSIM_PROPERTIES}
        for i, props in enumerate(properties):
            for key, (osim_name, default) in OSIM_PROPERTIES.items():
                if osim_name in props:
                    columns[key].append(float(props[osim_name]))
                elif default is None:
                    who = names[i] if names else f"muscle #{i}"
                    raise ParameterError(f"{who}: missing required property {osim_name}")
                else:
                    columns[key].append(default)
        return cls(**{k: np.asarray(v, dtype=float) for k, v in columns.items()}, names=names)


def minimum_fiber_length(params: ThelenParams) -> np.ndarray:
    """OpenSim's minimum fibre length of each muscle (fixed-width pennation model) [m].

    ``h / sin(alpha_max)`` with parallelogram height ``h = l0·sin(alpha0)``: the fibre
    length at which the pennation angle reaches ``maximum_pennation_angle``. It is 0 for
    an unpennated muscle (OpenSim 4.6 applies no other lower bound).

    Args:
        params: Muscle parameters.

    Returns:
        (n_muscles,) minimum fibre length [m].
    """
    return _k.minimum_fiber_length_ufunc(params.optimal_fiber_length,
                                         params.pennation_angle_at_optimal,
                                         params.maximum_pennation_angle)


# ----------------------------------------------------------------------------------------------
# Equilibrium
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """Static musculotendon equilibrium; every array has the shape of ``lmt``.

    Attributes:
        fiber_length: Fibre length lM [m] (the minimum fibre length where clamped).
        normalized_fiber_length: lM/l0 [-].
        pennation_angle: alpha [rad].
        tendon_length: lT = lMT − lM·cos(alpha) [m].
        tendon_force: Fmax·fT(lT/lTs) [N]; the musculotendon force.
        active_fiber_force: Fmax·a·fL along the fibre [N]; 0 where clamped (as OpenSim).
        passive_fiber_force: Fmax·fPE along the fibre [N].
        clamped: True where the fibre sits at its minimum length (no equilibrium above it).
        failed: True where OpenSim's search finds no equilibrium (it raises
            ``MuscleCannotEquilibrate``); every float field is NaN there.
    """

    fiber_length: np.ndarray
    normalized_fiber_length: np.ndarray
    pennation_angle: np.ndarray
    tendon_length: np.ndarray
    tendon_force: np.ndarray
    active_fiber_force: np.ndarray
    passive_fiber_force: np.ndarray
    clamped: np.ndarray
    failed: np.ndarray


#: Default iteration limit of the root search.
_MAX_ITERATIONS = 100


def _prepare(lmt: np.ndarray, params: ThelenParams,
             activation: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Check the inputs; return the lengths as (N, n_muscles) and the activation as an
    (N or 1, n_muscles or 1) array that broadcasts to them (clamped to
    [minimum_activation, 1] by the kernel). Both are writable C arrays: one compiled
    kernel serves every input."""
    lmt = np.asarray(lmt, dtype=float)
    if lmt.ndim == 0 or lmt.shape[-1] != params.n_muscles:
        raise ConfigurationError(
            f"musculotendon lengths have shape {lmt.shape}; the last axis must have "
            f"{params.n_muscles} entries (one per muscle)")
    act = np.asarray(activation, dtype=float)
    try:
        act = np.broadcast_to(act, lmt.shape)
    except ValueError:
        raise ConfigurationError(f"activation of shape {np.shape(activation)} does not broadcast "
                                 f"to the lengths' shape {lmt.shape}") from None
    if not np.all(np.isfinite(np.asarray(activation, dtype=float))):
        raise ConfigurationError("activation must be finite")
    outside = (act < 0.0) | (act > 1.0)
    if np.any(outside):
        raise ConfigurationError(f"activation must lie in [0, 1] (got {float(act[outside].flat[0]):g}); "
                                 "values below minimum_activation are raised to it, as in OpenSim")
    m = params.n_muscles
    act = act.reshape(-1, m)
    if act.strides[0] == 0:  # the same for every configuration
        act = act[:1]
    if act.strides[1] == 0:  # the same for every muscle
        act = act[:, :1]
    return np.require(lmt.reshape(-1, m), float, ["C", "W"]), np.array(act, dtype=float)


def _muscle_table(params: ThelenParams) -> np.ndarray:
    """Per-muscle constants for the kernel (:func:`pamkin.muscles._thelen_kernel.muscle_table`)."""
    return _k.muscle_table(
        params.max_isometric_force, params.optimal_fiber_length, params.tendon_slack_length,
        params.pennation_angle_at_optimal, params.fmax_tendon_strain, params.fmax_muscle_strain,
        params.kshape_active, params.kshape_passive, params.maximum_pennation_angle,
        params.minimum_activation)


def equilibrium(lmt: np.ndarray, params: ThelenParams, activation: float | np.ndarray = 1.0,
                rigid_tendon: bool = False, *, opensim_search: bool = True,
                max_iterations: int = _MAX_ITERATIONS) -> Equilibrium:
    """Static (zero fibre velocity) equilibrium of OpenSim 4.6 Thelen2003 muscles.

    Args:
        lmt: (..., n_muscles) musculotendon lengths [m], e.g. (N configurations, n_muscles).
            NaN entries give NaN results.
        params: Muscle parameters.
        activation: Activation in [0, 1], scalar or broadcastable to ``lmt``; values below
            ``minimum_activation`` are raised to it like OpenSim; outside [0, 1] is an error.
        rigid_tendon: If True, the tendon is inextensible at its slack length: the fibre
            length follows from geometry (``lM·cos(alpha) = lMT − lTs``) and the force is
            ``Fmax·(a·fL + fPE)·cos(alpha)``. Where ``lMT − lTs`` is at or below the minimum
            fibre length along the tendon (``l_min·cos(alpha_max)``), the fibre is clamped at
            ``l_min``, the tendon is slack (``lT = lMT − l_min·cos(alpha_max) ≤ lTs``) and
            the force is 0 (OpenSim's ``calcInextensibleTendonActiveFiberForce`` also gives
            0 there).
        opensim_search: If True (default), replay OpenSim's own Newton search to decide
            where OpenSim leaves the fibre clamped at its minimum length although an
            equilibrium exists above it (only seen for unpennated muscles whose fibre would
            be a fraction of a millimetre long; see
            :func:`pamkin.muscles._thelen_kernel.search_update`) and where it finds no equilibrium
            (``failed``, NaN results). If False, the fibre is clamped only where no
            equilibrium exists above the minimum length and no entry fails, which makes the
            force a continuous function of ``lmt``.
        max_iterations: Iteration limit of the root search (it normally stops after 1–2
            iterations when started from OpenSim's answer, under 10 otherwise).

    Returns:
        The equilibrium, every field shaped like ``lmt``; where OpenSim finds none,
        ``failed`` is set and the float fields are NaN.

    Raises:
        ConfigurationError: ``lmt``'s last axis does not match the number of muscles, or
            ``activation`` is not finite or does not broadcast.
    """
    shape = np.shape(lmt)
    out, status = _solve(lmt, params, activation, rigid_tendon, opensim_search, max_iterations,
                         _k.N_OUTPUTS)
    return Equilibrium(**{key: out[row].reshape(shape) for key, row in _OUTPUT_ROWS.items()},
                       clamped=(status == _k.AT_LOWER_BOUND).reshape(shape),
                       failed=(status == _k.FAILED).reshape(shape))


def _solve(lmt, params: ThelenParams, activation, rigid_tendon: bool, opensim_search: bool,
           max_iterations: int, n_outputs: int) -> tuple[np.ndarray, np.ndarray]:
    """Run the compiled kernel: (n_outputs, N, n_muscles) float results (all of
    :data:`_OUTPUT_ROWS`, or the tendon force only) and the (N, n_muscles) int8 status
    (``_k.CONVERGED``, ``_k.AT_LOWER_BOUND`` = clamped, ``_k.FAILED``)."""
    lmt2, act2 = _prepare(lmt, params, activation)
    out = np.empty((n_outputs, *lmt2.shape))
    status = np.empty(lmt2.shape, dtype=np.int8)
    # hand out work dynamically (balances threads when another process shares a core)
    chunksize = numba.set_parallel_chunksize(_k.CHUNKS_PER_GRAB)
    try:
        _k.equilibrium_kernel(lmt2, act2, _muscle_table(params), bool(rigid_tendon),
                              _search_mode(opensim_search), int(max_iterations), out, status)
    finally:
        numba.set_parallel_chunksize(chunksize)
    return out, status


def _search_mode(opensim_search) -> int:
    """Kernel search mode: True -> replay OpenSim's search, left once sure to converge
    (``_k.SEARCH_FAST``), False -> no replay; an int ``_k.SEARCH_*`` is used as given
    (``_k.SEARCH_FULL``, the replay to its end, is the reference the default is tested against)."""
    if opensim_search is True:
        return _k.SEARCH_FAST
    if opensim_search is False:
        return _k.SEARCH_NONE
    return int(opensim_search)


#: Float fields of :class:`Equilibrium` -> row of the kernel's output array.
_OUTPUT_ROWS = {"fiber_length": _k.O_FIBER_LENGTH,
                "normalized_fiber_length": _k.O_NORMALIZED_FIBER_LENGTH,
                "pennation_angle": _k.O_PENNATION_ANGLE, "tendon_length": _k.O_TENDON_LENGTH,
                "tendon_force": _k.O_TENDON_FORCE, "active_fiber_force": _k.O_ACTIVE_FIBER_FORCE,
                "passive_fiber_force": _k.O_PASSIVE_FIBER_FORCE}


def tendon_force(lmt: np.ndarray, params: ThelenParams, activation: float | np.ndarray = 1.0,
                 rigid_tendon: bool = False, *, opensim_search: bool = True) -> np.ndarray:
    """Static equilibrium tendon force of OpenSim 4.6 Thelen2003 muscles.

    Equals ``equilibrium(lmt, params, activation, rigid_tendon).tendon_force`` but stores
    nothing else (a fraction of the memory traffic); matches ``Model.equilibrateMuscles`` +
    ``Muscle.getTendonForce`` at zero speeds.

    Args:
        lmt: (..., n_muscles) musculotendon lengths [m].
        params: Muscle parameters.
        activation: Activation, scalar or broadcastable to ``lmt`` [-].
        rigid_tendon: Inextensible tendon (see :func:`equilibrium`).
        opensim_search: Replay OpenSim's search (see :func:`equilibrium`).

    Returns:
        Tendon force [N], shaped like ``lmt``; NaN where OpenSim finds no equilibrium
        (:attr:`Equilibrium.failed`; :func:`tendon_force_failed` also returns those flags).

    Raises:
        ConfigurationError: as :func:`equilibrium`.
    """
    return tendon_force_failed(lmt, params, activation, rigid_tendon,
                               opensim_search=opensim_search)[0]


def tendon_force_failed(lmt: np.ndarray, params: ThelenParams, activation: float | np.ndarray = 1.0,
                        rigid_tendon: bool = False, *,
                        opensim_search: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """:func:`tendon_force` and where OpenSim finds no equilibrium.

    Returns:
        (tendon force [N], failed): both shaped like ``lmt``; the force is NaN where ``failed``
        (as :func:`pamkin.muscles.millard2012.tendon_force`).
    """
    out, status = _solve(lmt, params, activation, rigid_tendon, opensim_search, _MAX_ITERATIONS, 1)
    shape = np.shape(lmt)
    return out[0].reshape(shape), (status == _k.FAILED).reshape(shape)


# ----------------------------------------------------------------------------------------------
# .osim reading
# ----------------------------------------------------------------------------------------------


def params_from_osim_xml(path: str | Path) -> ThelenParams:
    """Read the parameters of every ``<Thelen2003Muscle>`` in an ``.osim`` file's ForceSet.

    Properties absent from the file take OpenSim 4.6's defaults. Non-muscle forces are
    skipped; any other muscle class is refused.

    Args:
        path: The ``.osim`` file.

    Returns:
        Parameters in ForceSet order, with the muscles' names.

    Raises:
        UnsupportedFeatureError: the ForceSet holds a muscle of another class.
        OsimError: the file is not valid XML or a property is not a number.
        ParameterError: a required property is missing or a value is out of range.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise OsimError(str(path), f"not valid XML: {exc}") from None
    props: list[dict[str, float]] = []
    names: list[str] = []
    wanted = {osim_name for osim_name, _ in OSIM_PROPERTIES.values()}
    for objects in root.iterfind(".//ForceSet/objects"):
        for el in objects:
            name = el.get("name", "")
            if el.tag != "Thelen2003Muscle":
                if "Muscle" in el.tag:
                    raise UnsupportedFeatureError(
                        str(path), f"muscle class {el.tag} is not supported "
                        "(only Thelen2003Muscle)", element=el.tag, component=name)
                continue
            values: dict[str, float] = {}
            for child in el:
                if child.tag in wanted:
                    try:
                        values[child.tag] = float((child.text or "").strip())
                    except ValueError:
                        raise OsimError(str(path), f"<{child.tag}> is not a number: {child.text!r}",
                                        element=el.tag, component=name) from None
            props.append(values)
            names.append(name)
    return ThelenParams.from_osim_properties(props, names)
