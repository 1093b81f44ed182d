"""Anhysteretic magnetization curves: Ising (2), Langevin (3) and the knee family that holds Ising.

All are written in the reduced argument ``x = He / a`` with ``He = H + alpha*M``
the effective field (A/m) and ``a`` the shape parameter (A/m)::

    Ising     Man = Ms * tanh(x)
    Langevin  Man = Ms * (coth(x) - 1/x)
    knee      Man = Ms * sign(x) * tanh(|x|^p)^(1/p)      (p > 0, the knee exponent)

and each comes with its derivative ``dMan/dHe`` (dimensionless, A/m per A/m).

Numerics: the Langevin function cancels catastrophically near ``x = 0``; below
:data:`LANGEVIN_SERIES_SWITCH` (and :data:`LANGEVIN_SLOPE_SERIES_SWITCH` for the
derivative) a Taylor series is used instead. ``coth`` is evaluated as ``1/tanh``
and ``1/sinh^2`` as ``coth^2 - 1`` so that nothing overflows at large ``|x|``.
The knee family is the Ising curve at p = 1, has the Ising curve's unit slope at x = 0 for every p (so
``a`` keeps its meaning, the width of the initial slope), is odd, monotone and saturates at 1; p > 1
sharpens the knee toward ``min(|x|, 1)`` (p -> infinity) and p < 1 softens it. It is evaluated through
``tanh(u)/u`` (u = |x|^p), which is 1 at u = 0 and comes from its series below
:data:`KNEE_SERIES_SWITCH`, so that neither the value nor the slope meets 0/0 or 0 to a negative power.
``tanh`` itself is :func:`tanh_expm1`, an inlined, branch-free evaluation (relative
error ~1e-15) that lets the compiler vectorize the bank of models.

Reference: Nealis & Smith, "Nonlinear adaptive parameter estimation techniques
for magnetic transducers operating in hysteretic regimes", eqs. (2)-(3).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit
from numba.core import types
from numba.extending import overload

ISING = 0
LANGEVIN = 1
ANHYSTERETIC_KINDS = {"ising": ISING, "langevin": LANGEVIN}

#: |x| below which L(x) and L'(x) come from their Taylor series. The closed forms lose
#: about ``3*eps/x**2`` relative accuracy to cancellation (2.7e-15 at 0.5); the 11-term
#: series has truncation error below 2e-18 relative there (radius of convergence pi).
LANGEVIN_SERIES_SWITCH = 0.5
LANGEVIN_SLOPE_SERIES_SWITCH = 0.5
#: Taylor coefficients of L(x) = sum_n c_n x^(2n-1), c_n = 2^(2n) B_2n / (2n)! (n = 1..11).
LANGEVIN_SERIES = (
    0.3333333333333333, -0.022222222222222223, 0.0021164021164021165, -0.00021164021164021165,
    2.1377799155576935e-05, -2.1644042808063972e-06, 2.1925947851873778e-07, -2.2214608789979678e-08,
    2.2507846516808994e-09, -2.2805151204592183e-10, 2.3106432599002624e-11,
)
#: (2n-1) c_n: the series of L'(x) in powers x^(2n-2).
LANGEVIN_SLOPE_SERIES = tuple((2 * n + 1) * coefficient for n, coefficient in enumerate(LANGEVIN_SERIES))
#: u = |x|^p below which tanh(u)/u comes from its series 1 - u^2/3 + 2u^4/15 - 17u^6/315 (truncation error
#: 62u^8/2835 < 3e-18 relative at 1e-2); above it the quotient of :func:`tanh_expm1` (relative error ~1e-15).
KNEE_SERIES_SWITCH = 1e-2
KNEE_SERIES = (1.0, -1.0 / 3.0, 2.0 / 15.0, -17.0 / 315.0)

#: The knee family as the curve argument of the hysteresis kernels, in place of the code ISING or LANGEVIN:
#: its exponent p (dimensionless, > 0; p = 1 is the Ising curve). A type of its own, not a third code, so that
#: the kernels compiled for the two textbook curves hold no trace of it (:func:`anhysteretic_curve_unit`).
KneeCurve = namedtuple("KneeCurve", ("exponent",))


def anhysteretic_kind(name: str) -> int:
    """Map ``"ising"``/``"langevin"`` to the integer code used by the kernels."""
    try:
        return ANHYSTERETIC_KINDS[str(name).lower()]
    except KeyError:
        raise ValueError(
            f"anhysteretic must be one of {sorted(ANHYSTERETIC_KINDS)}, got {name!r}"
        ) from None


# The kernels use strict IEEE arithmetic (no fastmath): FMA contraction would be 15-25 %
# faster but rounds the SIMD lanes differently from the scalar remainder loop, and a
# bank node must equal a single-model run bit for bit. error_model="numpy" drops
# Python's division-by-zero branch, which is what lets the bank loop vectorize.
# The small functions here are inlined by LLVM (forceinline=True), not by numba's IR
# inliner: see the note on inlining in hysteresis.py.

#: |x| above which tanh(x) is +-1 in double precision (tanh(20) = 1 - 8.5e-18)
_TANH_SATURATION = 20.0
#: expm1 of the argument scaled down by 2**_TANH_SQUARINGS, then doubled back up
_TANH_SQUARINGS = 8
_EXPM1_TAYLOR = tuple(1.0 / math.factorial(n) for n in range(1, 11))


@njit(cache=True, forceinline=True)
def _horner(coefficients, y):
    total = 0.0
    for i in range(len(coefficients) - 1, -1, -1):
        total = total * y + coefficients[i]
    return total


@njit(cache=True, forceinline=True, error_model="numpy")
def tanh_expm1(x):
    """tanh(x) from ``e = expm1(2|x|)`` as ``sign(x)*e/(e + 2)``, branch free.

    ``expm1`` is a degree-10 Taylor polynomial at ``2|x|/256`` followed by 8 exact
    doublings ``e -> e*(e + 2)``, which keeps full relative accuracy near 0 (max
    relative error 1e-15 against libm over the whole line, tested). Unlike a libm call
    it inlines, so the compiler vectorizes the bank loop over models (SIMD).
    """
    y = min(abs(x), _TANH_SATURATION) * (2.0 / 2.0 ** _TANH_SQUARINGS)
    e = _horner(_EXPM1_TAYLOR, y) * y
    for _ in range(_TANH_SQUARINGS):
        e = e * (e + 2.0)
    return math.copysign(e / (e + 2.0), x)


@njit(cache=True, forceinline=True, error_model="numpy")
def langevin(x):
    """Langevin function L(x) = coth(x) - 1/x, accurate for all finite x."""
    series = x * _horner(LANGEVIN_SERIES, x * x)
    # evaluate the closed form at a safe argument so the discarded lane never divides by 0
    safe = x if abs(x) >= LANGEVIN_SERIES_SWITCH else LANGEVIN_SERIES_SWITCH
    closed = 1.0 / tanh_expm1(safe) - 1.0 / safe
    return series if abs(x) < LANGEVIN_SERIES_SWITCH else closed


@njit(cache=True, forceinline=True, error_model="numpy")
def langevin_slope(x):
    """dL/dx = 1/x^2 - 1/sinh(x)^2 (positive everywhere, max 1/3 at x = 0)."""
    series = _horner(LANGEVIN_SLOPE_SERIES, x * x)
    safe = x if abs(x) >= LANGEVIN_SLOPE_SERIES_SWITCH else LANGEVIN_SLOPE_SERIES_SWITCH
    coth = 1.0 / tanh_expm1(safe)
    closed = 1.0 / (safe * safe) - (coth * coth - 1.0)
    return series if abs(x) < LANGEVIN_SLOPE_SERIES_SWITCH else closed


@njit(cache=True, forceinline=True, error_model="numpy")
def anhysteretic_unit(x, kind):
    """``(Man/Ms, dMan/dHe * a/Ms)`` at the reduced field ``x = He/a``."""
    if kind == ISING:
        t = tanh_expm1(x)
        return t, 1.0 - t * t
    return langevin(x), langevin_slope(x)


@njit(cache=True, forceinline=True, error_model="numpy")
def knee_unit(x, exponent):
    """``(m, dm/dx)`` of the knee family ``m = sign(x)*tanh(|x|^p)^(1/p)`` at ``x = He/a``, p = ``exponent``.

    With u = |x|^p and r = tanh(u)/u: ``m = |x|*r^(1/p)`` and ``dm/dx = r^(1/p - 1)*(1 - tanh(u)^2)``, both
    finite and smooth at x = 0 (r -> 1: m -> x, slope -> 1). Above u = 20 tanh(u) is 1 in double precision:
    u is held there, so that neither |x|^p overflowing nor r -> 0 can make a NaN (m = 1, slope 0)."""
    size = abs(x)
    u = min(size ** exponent, _TANH_SATURATION)
    t = tanh_expm1(u)
    # the quotient at a safe argument, so that the lane that takes the series never divides 0 by 0
    safe = u if u >= KNEE_SERIES_SWITCH else KNEE_SERIES_SWITCH
    ratio = _horner(KNEE_SERIES, u * u) if u < KNEE_SERIES_SWITCH else t / safe
    inverse = 1.0 / exponent
    # above the switch t^(1/p) itself: the Ising curve's value to the last bit at p = 1
    value = size * ratio ** inverse if u < KNEE_SERIES_SWITCH else t ** inverse
    slope = ratio ** (inverse - 1.0) * (1.0 - t * t)
    return math.copysign(value, x), slope


def anhysteretic_curve_unit(x, curve):
    """``(Man/Ms, dMan/dHe * a/Ms)`` at ``x = He/a`` for ``curve``: a code (ISING, LANGEVIN) or a
    :data:`KneeCurve`. Compiled code resolves the curve's type when it compiles (the overload below)."""
    if isinstance(curve, KneeCurve):
        return knee_unit.py_func(x, curve.exponent)
    return anhysteretic_unit.py_func(x, curve)


@overload(anhysteretic_curve_unit, jit_options={"forceinline": True, "error_model": "numpy"})
def _anhysteretic_curve_unit_compiled(x, curve):
    # an integer code compiles to anhysteretic_unit alone, as before the knee family existed
    if isinstance(curve, types.Integer):
        return lambda x, curve: anhysteretic_unit(x, curve)
    return lambda x, curve: knee_unit(x, curve.exponent)


@njit(cache=True, forceinline=True, error_model="numpy")
def anhysteretic_point(effective_field, a, Ms, kind):
    """Return ``(Man, dMan/dHe)`` at one effective field (A/m) for curve ``kind`` (a code or a :data:`KneeCurve`)."""
    value, slope = anhysteretic_curve_unit(effective_field / a, kind)
    return Ms * value, (Ms / a) * slope


@njit(cache=True)
def _anhysteretic_array(effective_field, a, Ms, kind, out_value, out_slope):
    for i in range(effective_field.size):
        value, slope = anhysteretic_point(effective_field[i], a, Ms, kind)
        out_value[i] = value
        out_slope[i] = slope


def anhysteretic_magnetization(effective_field, a=7012.0, Ms=7.65e5, anhysteretic="ising", knee_exponent=1.0):
    """Anhysteretic magnetization and its slope.

    Parameters
    ----------
    effective_field : array_like
        Effective field ``He`` in A/m.
    a : float
        Shape parameter in A/m (> 0).
    Ms : float
        Saturation magnetization in A/m (> 0).
    anhysteretic : {"ising", "langevin"}
    knee_exponent : float
        p of the knee family ``tanh(|x|^p)^(1/p)`` (> 0, dimensionless), which generalizes the Ising curve
        only; 1 is the curve itself.

    Returns
    -------
    magnetization, slope : ndarray
        ``Man`` in A/m and ``dMan/dHe`` (dimensionless), shaped like the input.
    """
    kind = anhysteretic_kind(anhysteretic)
    if not (a > 0 and Ms > 0):
        raise ValueError(f"a and Ms must be > 0, got a={a!r}, Ms={Ms!r}")
    if not (np.isfinite(knee_exponent) and knee_exponent > 0):
        raise ValueError(f"knee_exponent must be finite and > 0, got {knee_exponent!r}")
    if knee_exponent != 1.0:
        if kind != ISING:
            raise ValueError(f"the knee family generalizes the Ising curve, not {anhysteretic!r}")
        kind = KneeCurve(float(knee_exponent))
    field = np.asarray(effective_field, dtype=np.float64)
    flat = np.ascontiguousarray(field.ravel())
    value = np.empty_like(flat)
    slope = np.empty_like(flat)
    _anhysteretic_array(flat, float(a), float(Ms), kind, value, slope)
    return value.reshape(field.shape), slope.reshape(field.shape)
