"""The domain-wall (Jiles-Atherton type) hysteresis model, eq. (6), batched and compiled.

The model is rate independent: the magnetization ``M`` (A/m) changes only when the
applied field ``H`` (A/m) changes, by::

    dM/dH = [ dhat*(Man - M)/(k*delta - alphahat*(Man - M)) + c*Man' ] / (1 - alpha*c*Man')

with ``He = H + alpha*M``, ``Man = Man(He)`` (Ising or Langevin), ``Man' = dMan/dHe``,
``alphahat = alpha/(1 - c)``, ``delta = sign(dH)`` and ``dhat`` the switch that makes
the change purely reversible after a reversal until ``M`` meets ``Man``. This is the
derivative of ``M = (1 - c)*Mirr + c*Man`` (5) with the irreversible law
``dMirr/dH = dhat*(Man - Mirr)/(k*delta - alpha*(Man - Mirr))``; the paper's printed
denominator ``1 + c*alpha*Man'`` is a transcription error (derivation in ``docs/model.md``).

Integration: each increment of H between two samples is cut into equal substeps of at
most ``max_field_step`` A/m and integrated by the explicit midpoint rule with ``delta``
frozen over the step (it cannot change inside a monotone increment). Cost therefore
follows the variation of the input, not wall-clock time. The irreversible term is
clamped to the side of ``delta`` so the model never shows negative susceptibility and
never emits NaN, even on stiff parameter sets.

Two batch layouts are provided, both over a leading batch axis of independent models:

* :func:`advance_shared` -- many parameter sets under one shared field (the estimator's
  model bank);
* :func:`advance_each` -- every model has its own field (vector environments).

Both layouts use the same strict IEEE arithmetic, so a model gives the same numbers bit
for bit in either layout and alone. The bank loop over models compiles to SIMD code
(about 9 ns per model-substep for 64 models on one core; ``hyst-gym bench --only physics``).
"""

from __future__ import annotations

import dataclasses
import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit

from .anhysteretic import ISING, LANGEVIN, anhysteretic_curve_unit, anhysteretic_kind

#: Default largest field substep in A/m. Chosen from the convergence study in
#: ``tests/physics/test_hysteresis.py`` (major loop to +-1.2e5 A/m, then nested minor
#: loops): the midpoint rule converges at second order, and against a 128x finer
#: solution this step gives a max error of 3.5e-6 Ms on the paper's (stiff, alpha*Ms/a
#: = -11) parameters and 7.2e-7 / 2.1e-7 Ms on the visibly hysteretic sets
#: (k = 4000, alpha = -0.01 / the "soft" set); the test asserts < 5e-6 and < 1e-6 Ms.
#: That is 2.7 A/m on the paper's set, against the ~1e-2 Ms by which M moves when a
#: changes from 7012 to 6300 A/m. Halving the step divides the error by ~4 and doubles the cost.
DEFAULT_MAX_FIELD_STEP = 50.0


@dataclass(frozen=True)
class HysteresisParams:
    """Parameters of the domain-wall model (6). Defaults: Terfenol-D, paper §4.

    Attributes
    ----------
    a : float
        Anhysteretic shape parameter, A/m (> 0). Temperature dependent, eq. (4).
    k : float
        Pinning (domain-wall loss) parameter, A/m (> 0).
    alpha : float
        Mean-field coupling, dimensionless; ``He = H + alpha*M``.
    Ms : float
        Saturation magnetization, A/m (> 0).
    c : float
        Reversibility coefficient, dimensionless, ``0 <= c < 1``.
    anhysteretic : str
        ``"ising"`` (eq. 2) or ``"langevin"`` (eq. 3).
    chi_r : float
        Reversible low-field susceptibility of the small-loop extension, dimensionless
        (``>= 0``; see :data:`SMALL_LOOP_EXTENSION`). 0, the default, is model (6) itself,
        computed by the same kernels as before, bit for bit.
    rayleigh_field : float
        Field change after a reversal over which the irreversible susceptibility of (6) builds
        up, A/m (``>= 0``; see :data:`REVERSAL_PINNING`). 0, the default, is model (6) itself
        (irreversible change at full strength right away), computed by the unchanged kernels.
    """

    a: float = 7012.0
    k: float = 400.0
    alpha: float = -0.1
    Ms: float = 7.65e5
    c: float = 0.18
    anhysteretic: str = "ising"
    chi_r: float = 0.0
    rayleigh_field: float = 0.0

    def __post_init__(self):
        validate_hysteresis_parameters(
            self.a, self.k, self.alpha, self.Ms, self.c, self.anhysteretic, owner="HysteresisParams"
        )
        _validate_chi_r(self.chi_r, "HysteresisParams")
        _validate_nonnegative(self.rayleigh_field, "rayleigh_field", "A/m", "HysteresisParams")
        for name in ("a", "k", "alpha", "Ms", "c", "chi_r", "rayleigh_field"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "anhysteretic", str(self.anhysteretic).lower())

    @property
    def kind(self) -> int:
        """Integer code of the anhysteretic curve used by the compiled kernels."""
        return anhysteretic_kind(self.anhysteretic)

    def replace(self, **changes) -> "HysteresisParams":
        """Return a copy with some fields changed (validated)."""
        return dataclasses.replace(self, **changes)


def validate_hysteresis_parameters(a, k, alpha, Ms, c, anhysteretic="ising", owner="hysteresis"):
    """Raise ``ValueError`` naming the first parameter outside its physical range.

    Works on scalars and arrays. ``alpha`` must keep the denominator
    ``1 - alpha*c*Man'`` of (6) positive for every field; since ``Man'`` peaks at
    ``Ms/a`` (Ising) or ``Ms/(3a)`` (Langevin), that means ``alpha*c*max(Man') < 1``.
    """
    kind = anhysteretic_kind(anhysteretic)
    values = {name: np.asarray(v, dtype=np.float64) for name, v in
              (("a", a), ("k", k), ("alpha", alpha), ("Ms", Ms), ("c", c))}
    for name, v in values.items():
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{owner}: {name} must be finite, got {_show(v)}")
    checks = (
        ("a", values["a"] > 0, "must be > 0 A/m"),
        ("k", values["k"] > 0, "must be > 0 A/m"),
        ("Ms", values["Ms"] > 0, "must be > 0 A/m"),
        ("c", (values["c"] >= 0) & (values["c"] < 1), "must satisfy 0 <= c < 1"),
    )
    for name, ok, problem in checks:
        if not np.all(ok):
            raise ValueError(f"{owner}: {name} {problem}, got {_show(values[name][~ok])}")
    peak_slope = values["Ms"] / values["a"] / (3.0 if kind == LANGEVIN else 1.0)
    singular = values["alpha"] * values["c"] * peak_slope >= 1.0
    if np.any(singular):
        raise ValueError(
            f"{owner}: alpha={_show(np.broadcast_to(values['alpha'], singular.shape)[singular])} makes the "
            f"denominator 1 - alpha*c*dMan/dHe of (6) vanish; need alpha*c*Ms/a < 1"
            + (" (x3 for Langevin)" if kind == LANGEVIN else "")
        )


def _validate_chi_r(chi_r, owner):
    _validate_nonnegative(chi_r, "chi_r", "dimensionless", owner)


def _validate_nonnegative(values, name, unit, owner):
    values = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(values) & (values >= 0.0)):
        raise ValueError(f"{owner}: {name} must be finite and >= 0 ({unit}), got {_show(values)}")


def _show(values) -> str:
    flat = np.atleast_1d(values).ravel()
    return repr(float(flat[0])) if flat.size else "[]"


@dataclass(frozen=True)
class HysteresisBatch:
    """Parameter arrays of a batch of models, each of shape ``(size,)``.

    Build with :meth:`from_params` (one parameter set repeated), :meth:`grid`
    (a bank over ``a``) or :meth:`stack` (a list of parameter sets). Units as in
    :class:`HysteresisParams`. All models in a batch share one anhysteretic curve.
    """

    a: np.ndarray
    k: np.ndarray
    alpha: np.ndarray
    Ms: np.ndarray
    c: np.ndarray
    anhysteretic: str = "ising"
    chi_r: np.ndarray | float = 0.0
    rayleigh_field: np.ndarray | float = 0.0

    def __post_init__(self):
        arrays = np.broadcast_arrays(*(np.asarray(getattr(self, n), dtype=np.float64)
                                       for n in ("a", "k", "alpha", "Ms", "c", "chi_r", "rayleigh_field")))
        if arrays[0].ndim != 1:
            raise ValueError(f"HysteresisBatch: parameters must be 1-D arrays, got shape {arrays[0].shape}")
        validate_hysteresis_parameters(*arrays[:5], self.anhysteretic, owner="HysteresisBatch")
        _validate_chi_r(arrays[5], "HysteresisBatch")
        _validate_nonnegative(arrays[6], "rayleigh_field", "A/m", "HysteresisBatch")
        for name, arr in zip(("a", "k", "alpha", "Ms", "c", "chi_r", "rayleigh_field"), arrays):
            arr = np.array(arr, dtype=np.float64)  # own, contiguous copy
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def size(self) -> int:
        return self.a.shape[0]

    @property
    def small_loop(self) -> bool:
        """Whether any model uses the small-loop extension (``chi_r > 0``)."""
        return bool(np.any(self.chi_r != 0.0))

    @property
    def reversal_pinning(self) -> bool:
        """Whether any model uses the reversal-dependent pinning (``rayleigh_field > 0``)."""
        return bool(np.any(self.rayleigh_field != 0.0))

    @property
    def kind(self) -> int:
        return anhysteretic_kind(self.anhysteretic)

    @classmethod
    def from_params(cls, params: HysteresisParams, size: int = 1) -> "HysteresisBatch":
        one = np.ones(int(size))
        return cls(params.a * one, params.k * one, params.alpha * one, params.Ms * one,
                   params.c * one, params.anhysteretic, params.chi_r * one, params.rayleigh_field * one)

    @classmethod
    def grid(cls, params: HysteresisParams, a_values) -> "HysteresisBatch":
        """A bank of models that differ only in ``a`` (A/m)."""
        a_values = np.asarray(a_values, dtype=np.float64).ravel()
        one = np.ones(a_values.shape[0])
        return cls(a_values, params.k * one, params.alpha * one, params.Ms * one,
                   params.c * one, params.anhysteretic, params.chi_r * one, params.rayleigh_field * one)

    @classmethod
    def stack(cls, params_list) -> "HysteresisBatch":
        params_list = list(params_list)
        if not params_list:
            raise ValueError("HysteresisBatch.stack: empty list of parameter sets")
        curves = {p.anhysteretic for p in params_list}
        if len(curves) != 1:
            raise ValueError(f"HysteresisBatch.stack: mixed anhysteretic curves {sorted(curves)}")
        return cls(*(np.array([getattr(p, n) for p in params_list]) for n in ("a", "k", "alpha", "Ms", "c")),
                   curves.pop(), np.array([p.chi_r for p in params_list]),
                   np.array([p.rayleigh_field for p in params_list]))

    def with_a(self, a_values) -> "HysteresisBatch":
        """Same batch with ``a`` replaced (A/m), e.g. after a temperature change."""
        return HysteresisBatch(a_values, self.k, self.alpha, self.Ms, self.c, self.anhysteretic, self.chi_r,
                               self.rayleigh_field)


# --------------------------------------------------------------------------- kernels


# The kernels below are written so that the loop over the models of a bank compiles to
# SIMD code: per-model constants are formed in the loop (no allocation per call), the
# switch dhat and the guard are selects rather than branches, tanh is inlined
# (anhysteretic.tanh_expm1), and error_model="numpy" drops Python's division-by-zero
# check (a division that can only yield a discarded lane never raises).
#
# Inlining: the small functions (here and in anhysteretic.py) are forceinline=True, which
# numba passes to LLVM as `alwaysinline`, rather than inline="always", numba's own IR
# inliner. Both give the same SIMD bank loop (same machine code, same numbers), but the IR
# inliner translates the callee's whole tree again at every call site -- with both curves
# in every copy of anhysteretic_unit -- and cost about half of an environment's first-step
# compilation (docs/speed.md). With LLVM inlining each function is compiled once,
# and where the call site knows the curve LLVM drops the other one. inline="always" is kept
# where it is cheap: on the layers (_advance_bank, advance_shared, advance_each) whose
# callees are all ordinary calls, so that a caller does not build, optimize and emit them as
# a library of their own. Their bodies hold no division, so the caller's error model does
# not matter. Python calls them as usual.


#: The constants of (6) for one model in one direction of travel, formed once per lane so that
#: the bank loop over models vectorizes; fields in A/m or dimensionless as in HysteresisParams.
#: A namedtuple, not positional arguments: numba compiles it to a plain struct and caches it.
LaneConstants = namedtuple("LaneConstants",
                           ("alpha", "inv_a", "Ms", "ms_over_a", "k_delta", "alphahat", "c", "alpha_c"))


@njit(cache=True, forceinline=True, error_model="numpy")
def lane_constants(a, k, alpha, Ms, c, delta):
    """:data:`LaneConstants` of one model moving in direction ``delta`` (+-1)."""
    inv_a = 1.0 / a
    return LaneConstants(alpha, inv_a, Ms, Ms * inv_a, k * delta, alpha / (1.0 - c), c, alpha * c)


@njit(cache=True, forceinline=True, error_model="numpy")
def _slope_terms(field, magnetization, delta, lane, kind):
    """The two terms of (6): the irreversible ``dhat*(Man - M)/(k*delta - alphahat*(Man - M))``
    and ``Man'`` (both per A/m of H), from a model's :data:`LaneConstants`."""
    unit, unit_slope = anhysteretic_curve_unit((field + lane.alpha * magnetization) * lane.inv_a, kind)
    return _terms_of_unit(magnetization, delta, lane, unit, unit_slope)


@njit(cache=True, forceinline=True, error_model="numpy")
def _terms_of_unit(magnetization, delta, lane, unit, unit_slope):
    """:func:`_slope_terms` from the anhysteretic curve's ``(Man/Ms, dMan/dHe * a/Ms)`` at the model's state."""
    man_slope = lane.ms_over_a * unit_slope
    gap = lane.Ms * unit - magnetization
    denominator = lane.k_delta - lane.alphahat * gap
    # dhat = 1 when M lags Man in the direction of travel. Guard: a denominator on the
    # wrong side of delta (possible for alpha > 0) would mean negative susceptibility;
    # the irreversible change is then 0.
    irreversible_on = (gap * delta > 0.0) & (denominator * delta > 0.0)
    irreversible = gap / (denominator if irreversible_on else delta)
    irreversible = irreversible if irreversible_on else 0.0
    return irreversible, man_slope


@njit(cache=True, forceinline=True, error_model="numpy")
def _slope(field, magnetization, delta, lane, kind):
    """dM/dH of (6) from a model's :data:`LaneConstants`."""
    irreversible, man_slope = _slope_terms(field, magnetization, delta, lane, kind)
    return (irreversible + lane.c * man_slope) / (1.0 - lane.alpha_c * man_slope)


@njit(cache=True, forceinline=True, error_model="numpy")
def _slope_of_unit(magnetization, delta, lane, unit, unit_slope):
    """:func:`_slope` from the anhysteretic curve's ``(Man/Ms, dMan/dHe * a/Ms)`` at the model's state."""
    irreversible, man_slope = _terms_of_unit(magnetization, delta, lane, unit, unit_slope)
    return (irreversible + lane.c * man_slope) / (1.0 - lane.alpha_c * man_slope)


@njit(cache=True, forceinline=True, error_model="numpy")
def _midpoint(field, magnetization, step, delta, lane, kind):
    slope_start = _slope(field, magnetization, delta, lane, kind)
    half = magnetization + (0.5 * step) * slope_start
    slope_mid = _slope(field + 0.5 * step, half, delta, lane, kind)
    return magnetization + step * slope_mid


@njit(cache=True, forceinline=True, error_model="numpy")
def magnetization_slope(field, magnetization, delta, a, k, alpha, Ms, c, kind):
    """dM/dH of eq. (6) at one state, for a field moving in direction ``delta`` (+-1)."""
    return _slope(field, magnetization, delta, lane_constants(a, k, alpha, Ms, c, delta), kind)


@njit(cache=True, forceinline=True, error_model="numpy")
def advance_one(magnetization, field_from, field_to, a, k, alpha, Ms, c, kind, max_field_step):
    """One model moved from ``field_from`` to ``field_to`` (A/m): returns its new M (A/m) and the
    number of substeps taken (0 when the field did not move). The arithmetic of every layout."""
    n, step, delta = monotone_substeps(field_to - field_from, max_field_step)
    lane = lane_constants(a, k, alpha, Ms, c, delta)
    for s in range(n):
        magnetization = _midpoint(field_from + s * step, magnetization, step, delta, lane, kind)
    return magnetization, n


@njit(cache=True, forceinline=True)
def substep_count(field_change, max_field_step):
    """Number of equal substeps of at most ``max_field_step`` covering ``field_change``."""
    n = int(math.ceil(abs(field_change) / max_field_step))
    return n if n > 0 else 1


@njit(cache=True, forceinline=True, error_model="numpy")
def monotone_substeps(field_change, max_field_step):
    """(count, length, direction) of the equal substeps covering one monotone field change;
    count 0 when the field does not move."""
    if field_change == 0.0:
        return 0, 0.0, 0.0
    n = substep_count(field_change, max_field_step)
    return n, field_change / n, 1.0 if field_change > 0.0 else -1.0


#: rows of :func:`bank_constants`' array: five constants per model, then the work rows of :func:`_bank_substeps`
#: (per model: the anhysteretic curve's value and slope, M at the half step)
BANK_ROWS = 8


@njit(cache=True, error_model="numpy")
def bank_constants(a, k, alpha, Ms, c):
    """Per-model constants of the bank kernel, shape ``(BANK_ROWS, B)``: 1/a, Ms/a, k, alpha/(1-c), alpha*c, then
    three work rows of :func:`_bank_substeps` (uninitialized; one array, one allocation per bank step)."""
    out = np.empty((BANK_ROWS, a.shape[0]))
    for b in range(a.shape[0]):
        # the formulas of lane_constants (delta = +1: k itself), so both layouts round alike
        lane = lane_constants(a[b], k[b], alpha[b], Ms[b], c[b], 1.0)
        out[0, b] = lane.inv_a
        out[1, b] = lane.ms_over_a
        out[2, b] = lane.k_delta
        out[3, b] = lane.alphahat
        out[4, b] = lane.alpha_c
    return out


@njit(cache=True, forceinline=True, error_model="numpy")
def _bank_substeps(magnetization, field_from, n, step, delta, alpha, Ms, c, constants, kind):
    """The ``n`` midpoint substeps of :func:`_advance_bank`: substeps outer, models inner;
    ``constants`` as :func:`bank_constants` returns them (its work rows are overwritten).

    Each substep is four passes over the models (the curve at the start, the half step, the curve at the
    midpoint, the full step) through a work array, where one pass per substep would hold one model's whole
    midpoint step: every model's arithmetic is the same, in the same order (:func:`_midpoint`: the same
    numbers bit for bit), but one model's midpoint step is a chain of about 80 dependent operations (the
    polynomial and the squarings of :func:`~.anhysteretic.tanh_expm1`, twice), too long for the processor to
    overlap the next models' chains with it; in passes of about 20 it does, about 1.7x faster on a bank of
    200 models (measured; ``tests/physics/test_hysteresis.py`` holds them equal to :func:`advance_one`)."""
    inv_a, ms_over_a, k, alphahat, alpha_c = constants[0], constants[1], constants[2], constants[3], constants[4]
    unit, unit_slope, half = constants[5], constants[6], constants[7]
    for s in range(n):
        field = field_from + s * step
        middle = field + 0.5 * step
        _curve_pass(field, magnetization, alpha, inv_a, kind, unit, unit_slope)
        for b in range(magnetization.shape[0]):  # the SIMD loops
            lane = LaneConstants(alpha[b], inv_a[b], Ms[b], ms_over_a[b], k[b] * delta, alphahat[b], c[b],
                                 alpha_c[b])
            half[b] = magnetization[b] + (0.5 * step) * _slope_of_unit(magnetization[b], delta, lane, unit[b],
                                                                       unit_slope[b])
        _curve_pass(middle, half, alpha, inv_a, kind, unit, unit_slope)
        for b in range(magnetization.shape[0]):
            lane = LaneConstants(alpha[b], inv_a[b], Ms[b], ms_over_a[b], k[b] * delta, alphahat[b], c[b],
                                 alpha_c[b])
            magnetization[b] = magnetization[b] + step * _slope_of_unit(half[b], delta, lane, unit[b],
                                                                        unit_slope[b])


@njit(cache=True, forceinline=True, error_model="numpy")
def _curve_pass(field, magnetization, alpha, inv_a, kind, unit, unit_slope):
    """The anhysteretic curve of every model at the field ``field`` (A/m, shared) and its M, into ``unit`` and
    ``unit_slope`` (the arguments of :func:`_slope_of_unit`; :func:`_slope_terms`' arithmetic)."""
    for b in range(magnetization.shape[0]):
        unit[b], unit_slope[b] = anhysteretic_curve_unit((field + alpha[b] * magnetization[b]) * inv_a[b], kind)


@njit(cache=True, inline="always", error_model="numpy")
def _advance_bank(magnetization, field_from, field_to, alpha, Ms, c, constants, kind, max_field_step):
    n, step, delta = monotone_substeps(field_to - field_from, max_field_step)
    if n == 0:
        return 0
    # One copy of the loop per curve: behind the test of ``kind``, the compiler (LLVM, after
    # inlining) knows the curve and drops the other one from the SIMD loop. ``kind`` stays a
    # run-time integer for numba, so the chain below is compiled once, not once per curve
    # (passing the constants ISING/LANGEVIN would type them as literals: two more chains).
    if kind == ISING:
        _bank_substeps(magnetization, field_from, n, step, delta, alpha, Ms, c, constants, kind)
    else:
        _bank_substeps(magnetization, field_from, n, step, delta, alpha, Ms, c, constants, kind)
    return n


@njit(cache=True, inline="always", error_model="numpy")
def advance_shared(magnetization, field_from, field_to, a, k, alpha, Ms, c, kind, max_field_step):
    """Move every model of a bank from ``field_from`` to ``field_to`` (A/m, shared).

    ``magnetization`` (A/m, shape ``(B,)``) is updated in place; parameter arrays have
    shape ``(B,)``. Returns the number of substeps taken (0 if the field did not move).
    Substeps are the outer loop and models the inner, vectorized loop.
    """
    if field_to == field_from:
        return 0
    return _advance_bank(magnetization, field_from, field_to, alpha, Ms, c, bank_constants(a, k, alpha, Ms, c),
                         kind, max_field_step)


@njit(cache=True, inline="always", error_model="numpy")
def advance_each(magnetization, field_from, field_to, a, k, alpha, Ms, c, kind, max_field_step):
    """Move model ``b`` from ``field_from[b]`` to ``field_to[b]`` (A/m), in place.

    All arrays have shape ``(B,)``. Returns the total number of model-substeps. Same
    arithmetic as :func:`advance_shared`: a model gives the same numbers in both layouts.
    """
    total = 0
    for b in range(magnetization.shape[0]):
        m, n = advance_one(magnetization[b], field_from[b], field_to[b], a[b], k[b], alpha[b], Ms[b], c[b], kind,
                           max_field_step)
        magnetization[b] = m
        total += n
    return total


@njit(cache=True)
def simulate_shared(field, magnetization0, a, k, alpha, Ms, c, kind, max_field_step):
    """Trajectories of a bank under one sampled field: returns M of shape ``(T, B)``."""
    n_samples = field.shape[0]
    out = np.empty((n_samples, magnetization0.shape[0]))
    state = magnetization0.copy()
    out[0] = state
    constants = bank_constants(a, k, alpha, Ms, c)
    for t in range(1, n_samples):
        _advance_bank(state, field[t - 1], field[t], alpha, Ms, c, constants, kind, max_field_step)
        out[t] = state
    return out


# --------------------------------------------------------------- small-loop extension

#: The small-loop extension of (6), chosen by its amplitude hold-out on the measured ferrite
#: loops (``experiments/real_loops.py``; README, "Measured loops"). Model (6) fitted to a major
#: loop has no mechanism for the low-field (Rayleigh) region: after a reversal its change is
#: purely reversible, ``c*Man'``, and a fit to the major loop drives ``c`` down, so loops a tenth
#: of the major amplitude come out far too flat. The extension adds the Rayleigh initial
#: susceptibility chi_r -- the reversible bowing of pinned walls that makes the low-field
#: permeability ``mu_i = 1 + chi_r`` (Rayleigh, Phil. Mag. 23, 225 (1887); Bertotti,
#: *Hysteresis in Magnetism*, Academic Press 1998, ch. 9; Jiles and Atherton, J. Magn. Magn.
#: Mater. 61, 48 (1986), for the bowing term of (5)) -- and lets it fade as the material
#: saturates, where no wall is left to bow::
#:
#:     dM/dH = (6) + chi_r * max(0, 1 - (M/Ms)^2)
#:
#: It needs no state beyond M, so the kernels keep their layout. Candidates measured and not
#: chosen (same hold-out): an irreversible Rayleigh term ``eta*|H - H_rev|`` (worse on the
#: high-permeability ferrite) and a field-dependent fading ``1/(1 + (H/h_r)^2)`` (no better,
#: one more parameter).
SMALL_LOOP_EXTENSION = "dM/dH = (6) + chi_r * max(0, 1 - (M/Ms)^2)"


@njit(cache=True, forceinline=True, error_model="numpy")
def _small_loop_slope(field, magnetization, delta, lane, chi_r, kind):
    """dM/dH of the small-loop extension: the slope of (6) plus the fading reversible term."""
    return _slope(field, magnetization, delta, lane, kind) + chi_r * _small_loop_fading(magnetization, lane)


@njit(cache=True, forceinline=True, error_model="numpy")
def _small_loop_fading(magnetization, lane):
    """``max(0, 1 - (M/Ms)^2)``: the share of the small-loop term left as the material saturates."""
    ratio = magnetization / lane.Ms
    fading = 1.0 - ratio * ratio
    return fading if fading > 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def small_loop_magnetization_slope(field, magnetization, delta, a, k, alpha, Ms, c, chi_r, kind):
    """dM/dH of :data:`SMALL_LOOP_EXTENSION` at one state (fields in A/m), for a field moving in direction
    ``delta`` (+-1): :func:`magnetization_slope` plus the fading reversible term (the kernels' arithmetic)."""
    return _small_loop_slope(field, magnetization, delta, lane_constants(a, k, alpha, Ms, c, delta), chi_r, kind)


def initial_susceptibility(params: HysteresisParams) -> float:
    """Relative susceptibility dM/dH (dimensionless) at the demagnetized state, H = 0 and M = 0.

    There M equals Man, so the irreversible term of (6) is off and only the reversible part acts:
    ``c*Man'(0)/(1 - alpha*c*Man'(0)) + chi_r`` with ``Man'(0) = Ms/a`` (Ising) or ``Ms/(3a)`` (Langevin) --
    the slope that loops of vanishing amplitude around the demagnetized state tend to (the initial
    permeability is ``1 +`` this). The factor ``1/(1 - alpha*c*Man'(0))`` is the mean-field feedback on the
    reversible part. Unchanged by the reversal-dependent pinning, which weighs only the irreversible term.
    """
    return float(small_loop_magnetization_slope(0.0, 0.0, 1.0, params.a, params.k, params.alpha, params.Ms,
                                                params.c, params.chi_r, anhysteretic_kind(params.anhysteretic)))


@njit(cache=True, error_model="numpy")
def _advance_bank_small_loop(magnetization, field_from, field_to, alpha, Ms, c, chi_r, constants, kind,
                             max_field_step):
    """:func:`_advance_bank` with the small-loop slope; ``constants`` from :func:`bank_constants`."""
    n, step, delta = monotone_substeps(field_to - field_from, max_field_step)
    inv_a, ms_over_a, k, alphahat, alpha_c = constants[0], constants[1], constants[2], constants[3], constants[4]
    for s in range(n):
        field = field_from + s * step
        for b in range(magnetization.shape[0]):
            lane = LaneConstants(alpha[b], inv_a[b], Ms[b], ms_over_a[b], k[b] * delta, alphahat[b], c[b],
                                 alpha_c[b])
            m = magnetization[b]
            slope_start = _small_loop_slope(field, m, delta, lane, chi_r[b], kind)
            slope_mid = _small_loop_slope(field + 0.5 * step, m + (0.5 * step) * slope_start, delta, lane,
                                          chi_r[b], kind)
            magnetization[b] = m + step * slope_mid
    return n


@njit(cache=True, error_model="numpy")
def advance_shared_small_loop(magnetization, field_from, field_to, a, k, alpha, Ms, c, chi_r, kind,
                              max_field_step):
    """:func:`advance_shared` for the small-loop extension (``chi_r`` of shape ``(B,)``).

    Same substeps and midpoint rule as (6); with ``chi_r = 0`` it gives the numbers of
    :func:`advance_shared`. Returns the number of substeps taken.
    """
    if field_to == field_from:
        return 0
    return _advance_bank_small_loop(magnetization, field_from, field_to, alpha, Ms, c, chi_r,
                                    bank_constants(a, k, alpha, Ms, c), kind, max_field_step)


@njit(cache=True)
def simulate_shared_small_loop(field, magnetization0, a, k, alpha, Ms, c, chi_r, kind, max_field_step):
    """:func:`simulate_shared` for the small-loop extension: M of shape ``(T, B)``."""
    n_samples = field.shape[0]
    out = np.empty((n_samples, magnetization0.shape[0]))
    state = magnetization0.copy()
    out[0] = state
    constants = bank_constants(a, k, alpha, Ms, c)  # once per trajectory, as in simulate_shared
    for t in range(1, n_samples):
        _advance_bank_small_loop(state, field[t - 1], field[t], alpha, Ms, c, chi_r, constants, kind,
                                 max_field_step)
        out[t] = state
    return out


# ------------------------------------------------------- reversal-dependent pinning

#: Reversal-dependent pinning, an option of (6) for small loops and for states that a small
#: excursion does not wipe out. In (6) the irreversible change ``dhat*(Man - M)/(k*delta -
#: alphahat*(Man - M))`` is at full strength as soon as M lags Man; so a loop far smaller than the
#: coercive field still moves the irreversible magnetization by ``(Man - M)/k`` per A/m, and a
#: remanent state is erased by the first small excursion. Measured materials show the opposite in
#: the Rayleigh region: right after a reversal the walls sit in their pinning sites and only bow
#: (reversibly); the irreversible susceptibility grows in proportion to the field change since the
#: reversal, ``chi_irr = eta*|H - H_rev|`` (Rayleigh's law: Rayleigh, Phil. Mag. 23, 225 (1887);
#: G. Bertotti, *Hysteresis in Magnetism*, Academic Press 1998, sec. 9.1; the reversal-point
#: dependence of the irreversible term of the Jiles-Atherton model, K. H. Carpenter, "A
#: differential equation approach to minor loops in the Jiles-Atherton hysteresis model", IEEE
#: Trans. Magn. 27(6), 4404 (1991), and D. C. Jiles, "A self consistent generalized model for the
#: calculation of minor loop excursions in the theory of hysteresis", IEEE Trans. Magn. 28(5),
#: 2602 (1992)). This option weighs the irreversible term of (6) by the smooth onset
#:
#:     w = 1 - exp(-|H - H_rev| / rayleigh_field)
#:
#: (``H_rev``: the field at the last reversal, or at the first sample: a demagnetized or remanent
#: start is a state in the pinning sites too), which is ``|H - H_rev|/rayleigh_field`` -- Rayleigh's
#: linear growth -- for small excursions and 1 (model (6)) a few ``rayleigh_field`` after a
#: reversal. On a major loop the irreversible term is off anyway right after a reversal (M has to
#: cross Man first), so the option acts on small loops and on excursions from a remanent state.
#: Under one shared field every model of a bank reverses at the same samples, so ``H_rev`` is one
#: number per trajectory and the bank kernels need no per-model state.
REVERSAL_PINNING = ("dM/dH = [w*dhat*(Man - M)/(k*delta - alphahat*(Man - M)) + c*Man'] / (1 - alpha*c*Man')"
                    " + chi_r*max(0, 1 - (M/Ms)^2),  w = 1 - exp(-|H - H_rev|/rayleigh_field)")


@njit(cache=True, forceinline=True, error_model="numpy")
def reversal_weight(field, reversal_field, rayleigh_field):
    """Onset ``w`` of the irreversible term after a reversal at ``reversal_field`` (all A/m);
    1 (model (6)) when ``rayleigh_field`` is 0."""
    if rayleigh_field == 0.0:
        return 1.0
    return 1.0 - math.exp(-abs(field - reversal_field) / rayleigh_field)


@njit(cache=True, forceinline=True, error_model="numpy")
def _reversal_slope(field, magnetization, delta, lane, chi_r, weight, kind):
    """dM/dH of :data:`REVERSAL_PINNING`: (6) with its irreversible term weighted by ``weight``,
    plus the small-loop extension's reversible term."""
    irreversible, man_slope = _slope_terms(field, magnetization, delta, lane, kind)
    return ((weight * irreversible + lane.c * man_slope) / (1.0 - lane.alpha_c * man_slope)
            + chi_r * _small_loop_fading(magnetization, lane))


@njit(cache=True, error_model="numpy")
def simulate_shared_reversal(field, magnetization0, a, k, alpha, Ms, c, chi_r, rayleigh_field, kind,
                             max_field_step):
    """Trajectories of a bank under one sampled field with :data:`REVERSAL_PINNING` (and the
    small-loop term ``chi_r``): M of shape ``(T, B)``. Same substeps and midpoint rule as (6).

    The reversal field starts at ``field[0]`` and moves to ``field[t-1]`` whenever an increment
    runs against the previous non-zero one."""
    n_samples = field.shape[0]
    out = np.empty((n_samples, magnetization0.shape[0]))
    state = magnetization0.copy()
    out[0] = state
    constants = bank_constants(a, k, alpha, Ms, c)
    inv_a, ms_over_a, k_up, alphahat, alpha_c = constants[0], constants[1], constants[2], constants[3], constants[4]
    reversal = field[0]
    previous = 0.0
    for t in range(1, n_samples):
        n, step, delta = monotone_substeps(field[t] - field[t - 1], max_field_step)
        if n > 0:
            if previous != 0.0 and delta != previous:
                reversal = field[t - 1]
            previous = delta
        for s in range(n):
            start = field[t - 1] + s * step
            middle = start + 0.5 * step
            for b in range(state.shape[0]):
                lane = LaneConstants(alpha[b], inv_a[b], Ms[b], ms_over_a[b], k_up[b] * delta, alphahat[b], c[b],
                                     alpha_c[b])
                m = state[b]
                slope_start = _reversal_slope(start, m, delta, lane, chi_r[b],
                                              reversal_weight(start, reversal, rayleigh_field[b]), kind)
                slope_mid = _reversal_slope(middle, m + (0.5 * step) * slope_start, delta, lane, chi_r[b],
                                            reversal_weight(middle, reversal, rayleigh_field[b]), kind)
                state[b] = m + step * slope_mid
        out[t] = state
    return out


# --------------------------------------------------------------------------- user API


def _check_max_field_step(max_field_step):
    if not (np.isfinite(max_field_step) and max_field_step > 0):
        raise ValueError(f"max_field_step must be a finite number > 0 A/m, got {max_field_step!r}")
    return float(max_field_step)


def _as_field(field, name="field"):
    field = np.asarray(field, dtype=np.float64)
    if field.ndim != 1 or field.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty 1-D array of A/m, got shape {field.shape}")
    bad = ~np.isfinite(field)
    if bad.any():
        raise ValueError(f"{name}[{int(np.argmax(bad))}] is {field[bad][0]!r}; the field must be finite")
    return np.ascontiguousarray(field)


def simulate_batch(field, batch: HysteresisBatch, magnetization0=0.0,
                   max_field_step: float = DEFAULT_MAX_FIELD_STEP) -> np.ndarray:
    """Magnetization (A/m) of every model of ``batch`` under one sampled field.

    Returns an array of shape ``(len(field), batch.size)``; row 0 is ``magnetization0``. Models (6)
    alone, with the small-loop extension (``chi_r``) and with the reversal-dependent pinning
    (``rayleigh_field``) each run their own kernel, so the options leave (6)'s numbers untouched.
    """
    field = _as_field(field)
    start = np.ascontiguousarray(np.broadcast_to(np.asarray(magnetization0, dtype=np.float64),
                                                 (batch.size,)))
    step = _check_max_field_step(max_field_step)
    if batch.reversal_pinning:
        return simulate_shared_reversal(field, start.copy(), batch.a, batch.k, batch.alpha, batch.Ms, batch.c,
                                        batch.chi_r, batch.rayleigh_field, batch.kind, step)
    if batch.small_loop:
        return simulate_shared_small_loop(field, start.copy(), batch.a, batch.k, batch.alpha, batch.Ms, batch.c,
                                          batch.chi_r, batch.kind, step)
    # model (6) alone: the plain bank kernel, so that the default reproduces earlier numbers bit for bit
    return simulate_shared(field, start.copy(), batch.a, batch.k, batch.alpha, batch.Ms, batch.c,
                           batch.kind, step)


def simulate_magnetization(field, time=None, *, max_field_step: float = DEFAULT_MAX_FIELD_STEP,
                           magnetization0: float = 0.0, **params) -> np.ndarray:
    """Magnetization M (A/m) of the domain-wall model (6) at the samples of ``field``.

    Parameters
    ----------
    field : array_like, shape (T,)
        Applied field H in A/m, in time order.
    time : array_like, shape (T,), optional
        Sample times in s. The model is rate independent, so ``time`` only has to be
        strictly increasing and as long as ``field``; it is accepted so that recorded
        (time, field) pairs can be passed as they are.
    max_field_step : float
        Largest field substep in A/m (accuracy control, see :data:`DEFAULT_MAX_FIELD_STEP`).
    magnetization0 : float
        M at the first sample, A/m (default 0: the demagnetized state).
    **params
        Overrides of :class:`HysteresisParams`: ``a``, ``k``, ``alpha``, ``Ms``, ``c``,
        ``anhysteretic="ising"|"langevin"``, ``chi_r`` (the small-loop extension),
        ``rayleigh_field`` (the reversal-dependent pinning).

    Returns
    -------
    ndarray, shape (T,)

    Examples
    --------
    >>> import numpy as np, hyst_gym
    >>> H = 1e5 * np.sin(np.linspace(0, 4 * np.pi, 2001))
    >>> M = hyst_gym.simulate_magnetization(H, k=4000, alpha=-0.01)
    """
    unknown = set(params) - {f.name for f in dataclasses.fields(HysteresisParams)}
    if unknown:
        raise TypeError(f"simulate_magnetization: unknown parameter(s) {sorted(unknown)}; "
                        f"expected some of a, k, alpha, Ms, c, anhysteretic, chi_r, rayleigh_field")
    field = _as_field(field)
    if time is not None:
        time = np.asarray(time, dtype=np.float64)
        if time.shape != field.shape:
            raise ValueError(f"time has shape {time.shape} but field has shape {field.shape}")
        if not np.all(np.isfinite(time)) or np.any(np.diff(time) <= 0):
            raise ValueError("time must be finite and strictly increasing")
    params = HysteresisParams(**params)
    batch = HysteresisBatch.from_params(params, 1)
    return simulate_batch(field, batch, magnetization0, max_field_step)[:, 0]


__all__ = [
    "DEFAULT_MAX_FIELD_STEP", "HysteresisParams", "HysteresisBatch", "ISING", "LANGEVIN", "REVERSAL_PINNING",
    "SMALL_LOOP_EXTENSION", "reversal_weight", "simulate_shared_reversal",
    "advance_each", "advance_one", "advance_shared", "advance_shared_small_loop", "simulate_shared_small_loop",
    "initial_susceptibility", "magnetization_slope", "simulate_batch", "small_loop_magnetization_slope",
    "simulate_magnetization", "simulate_shared", "substep_count", "validate_hysteresis_parameters",
]
