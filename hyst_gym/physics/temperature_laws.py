"""Temperature laws for the parameters of the domain-wall model (6) and of the homogenized energy model.

A :class:`TemperatureLaws` maps an absolute temperature ``T`` (K, scalar or array) to
the five parameters ``a, k, c, Ms, alpha`` of :func:`hyst_gym.physics.hysteresis.
simulate_magnetization`. Each parameter follows one small, frozen law object; all laws
are pure and vectorized over ``T``. Units of a law's output are those of the parameter
it is attached to (a, k: A/m; Ms: A/m; c, alpha: dimensionless).

Laws (pick one per parameter):

* :class:`Constant` -- temperature independent.
* :class:`LinearInT` -- eq. (4) of the paper, ``a(T) = a_ref * T / T_ref`` (T in K):
  the thermal-energy form of the anhysteretic shape parameter, ``a = k_B T / (mu0 m)``
  for a fixed moment ``m`` of the effective domain. The default law for ``a``.
* :class:`CriticalPowerLaw` -- ``Ms(T) = Ms0 * (1 - T/Tc)**beta`` below the Curie
  temperature ``Tc`` and 0 above: the critical behaviour of the spontaneous
  magnetization. Mean-field theory gives ``beta = 1/2``, the 3-D Heisenberg model
  ``beta ~ 0.37`` (e.g. C. Kittel, *Introduction to Solid State Physics*, ch. on
  ferromagnetism; S. Blundell, *Magnetism in Condensed Matter*, 2001, sec. 6);
  the gadolinium source of ``data/real/gd-temperature`` fits ``beta = 0.281``
  (Nowicki, Szewczyk, Kolano-Burian, Charubin, Zenodo 10.5281/zenodo.21431501). With a negative
  exponent ``-gamma`` it is the critical divergence of a susceptibility (gamma = 1.39 for the 3-D
  Heisenberg class, 1 in mean-field theory).
* :class:`FollowsMs` -- ``p(T) = p0 * (Ms(T)/Ms(0))**n``: a parameter tied to the
  reduced spontaneous magnetization, as in the temperature-dependent Jiles-Atherton
  models where ``a``, ``k`` and ``alpha`` scale with powers of the reduced
  magnetization or of ``1 - T/Tc`` (A. Raghunathan, Y. Melikhov, J. E. Snyder,
  D. C. Jiles, "Modeling the temperature dependence of hysteresis based on
  Jiles-Atherton theory", IEEE Trans. Magn. 45(10), 3954-3957, 2009; and
  "Theoretical model of temperature dependence of hysteresis based on mean field
  theory", IEEE Trans. Magn. 46(6), 1507-1510, 2010).
* :class:`LogPolynomial` -- a smooth empirical law,
  ``p(T) = exp(sum_i coef[i] * x**i)`` with ``x = (T - T_ref)/T_scale``: positive by
  construction; for interpolation between measured temperatures, not extrapolation.

Above ``Tc`` a :class:`CriticalPowerLaw` (and any :class:`FollowsMs` with ``n > 0``)
returns 0, which is not a valid model parameter: the model (6) describes the ordered
phase only, and callers must keep ``T < Tc``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Tuple

import numpy as np

from .thermal import a_law

#: 0 degrees C in K.
ZERO_CELSIUS_K = 273.15
#: Curie temperature of the gadolinium sample of ``data/real/gd-temperature``, K (18.3 C).
GD_CURIE_K = 18.3 + ZERO_CELSIUS_K


def celsius_to_kelvin(T_C):
    """Temperature in K from degrees C (vectorized)."""
    return np.asarray(T_C, dtype=np.float64) + ZERO_CELSIUS_K


def _kelvin(T):
    T = np.asarray(T, dtype=np.float64)
    if np.any(~np.isfinite(T)) or np.any(T <= 0):
        raise ValueError("temperature must be finite and > 0 K")
    return T


# --------------------------------------------------------------------------- pure functions


def linear_in_temperature(T, ref_value, T_ref):
    """Eq. (4): ``ref_value * T / T_ref``; T and T_ref in K, output in the unit of ref_value."""
    return a_law(ref_value, _kelvin(T), float(T_ref))


def critical_power_law(T, value0, Tc, beta):
    """``value0 * (1 - T/Tc)**beta`` for ``T < Tc``, 0 for ``T >= Tc`` (T, Tc in K)."""
    reduced = 1.0 - _kelvin(T) / float(Tc)
    return value0 * np.where(reduced > 0, np.maximum(reduced, 0.0) ** beta, 0.0)


def power_of_ratio(ratio, value0, exponent):
    """``value0 * ratio**exponent`` (ratio >= 0, dimensionless)."""
    ratio = np.asarray(ratio, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return value0 * np.power(ratio, exponent)


def log_polynomial(T, coefficients, T_ref, T_scale):
    """``exp(sum_i coefficients[i] * x**i)``, ``x = (T - T_ref)/T_scale`` (K)."""
    x = (_kelvin(T) - float(T_ref)) / float(T_scale)
    return np.exp(np.polynomial.polynomial.polyval(x, np.asarray(coefficients, dtype=np.float64)))


# --------------------------------------------------------------------------- law objects
# Every law is called as law(T, reduced_ms) with T in K and reduced_ms = Ms(T)/Ms(0 K);
# laws that do not need reduced_ms ignore it.


@dataclass(frozen=True)
class Constant:
    """Temperature-independent value (unit of the parameter)."""

    value: float

    def __call__(self, T, reduced_ms=None):
        return np.full(np.shape(_kelvin(T)), float(self.value))


@dataclass(frozen=True)
class LinearInT:
    """Eq. (4): ``ref_value * T / T_ref``. ``ref_value`` at ``T_ref`` (K)."""

    ref_value: float
    T_ref: float

    def __call__(self, T, reduced_ms=None):
        return linear_in_temperature(T, self.ref_value, self.T_ref)


@dataclass(frozen=True)
class CriticalPowerLaw:
    """``value0 * (1 - T/Tc)**beta`` below ``Tc`` (K), 0 above; ``value0`` is the 0 K value."""

    value0: float
    Tc: float = GD_CURIE_K
    beta: float = 0.281

    def __call__(self, T, reduced_ms=None):
        return critical_power_law(T, self.value0, self.Tc, self.beta)


@dataclass(frozen=True)
class FollowsMs:
    """``value0 * (Ms(T)/Ms(0 K))**exponent``: ``value0`` is the 0 K value (Raghunathan et al.)."""

    value0: float
    exponent: float

    def __call__(self, T, reduced_ms):
        if reduced_ms is None:
            raise ValueError("FollowsMs needs the reduced magnetization Ms(T)/Ms(0)")
        return power_of_ratio(reduced_ms, self.value0, self.exponent)


@dataclass(frozen=True)
class LogPolynomial:
    """``exp(sum_i coefficients[i] * ((T - T_ref)/T_scale)**i)``; T_ref, T_scale in K."""

    coefficients: Tuple[float, ...]
    T_ref: float
    T_scale: float = 10.0

    def __call__(self, T, reduced_ms=None):
        return log_polynomial(T, self.coefficients, self.T_ref, self.T_scale)


PARAMETER_NAMES = ("a", "k", "c", "Ms", "alpha", "chi_r")


@dataclass(frozen=True)
class TemperatureLaws:
    """One law per model parameter; :meth:`__call__` maps T (K) to parameter arrays.

    Defaults: ``a`` follows eq. (4) with the paper's Terfenol-D values (7012 A/m at
    263 K) and everything else is constant, so that ``TemperatureLaws()`` reproduces
    the paper's temperature model. ``chi_r`` is the small-loop extension's reversible
    susceptibility (``hysteresis.SMALL_LOOP_EXTENSION``); its default 0 is model (6).
    """

    a: object = field(default_factory=lambda: LinearInT(7012.0, 263.0))
    k: object = field(default_factory=lambda: Constant(400.0))
    c: object = field(default_factory=lambda: Constant(0.18))
    Ms: object = field(default_factory=lambda: Constant(7.65e5))
    alpha: object = field(default_factory=lambda: Constant(-0.1))
    chi_r: object = field(default_factory=lambda: Constant(0.0))

    def reduced_ms(self, T):
        """``Ms(T)/Ms(0 K)`` (dimensionless); 1 for a constant Ms."""
        T = _kelvin(T)
        ms0 = float(np.asarray(self.Ms(np.array(1e-12), None)))
        return self.Ms(T, None) / ms0

    def __call__(self, T):
        """Dict ``{a, k, c, Ms, alpha, chi_r}`` of float arrays shaped like ``T`` (K)."""
        T = _kelvin(T)
        reduced = self.reduced_ms(T)
        return {name: np.broadcast_to(np.asarray(getattr(self, name)(T, reduced), dtype=np.float64),
                                      T.shape).copy()
                for name in PARAMETER_NAMES}

    def batch(self, T, anhysteretic="langevin"):
        """A :class:`~hyst_gym.physics.hysteresis.HysteresisBatch` with one model per temperature."""
        from .hysteresis import HysteresisBatch

        values = self(np.atleast_1d(np.asarray(T, dtype=np.float64)).ravel())
        return HysteresisBatch(values["a"], values["k"], values["alpha"], values["Ms"], values["c"],
                               anhysteretic, values["chi_r"])


HEM_PARAMETER_NAMES = ("relay_magnetization", "reversible_susceptibility", "coercive_median", "coercive_spread",
                       "interaction_scale")


@dataclass(frozen=True)
class HEMTemperatureLaws:
    """One law per parameter of the homogenized energy model (:class:`~hyst_gym.physics.hem.HEMParams`);
    :meth:`__call__` maps T (K) to parameter arrays. The reduced magnetization that :class:`FollowsMs`
    laws see is ``relay_magnetization(T)/relay_magnetization(0 K)``.

    Defaults are the critical scaling a physicist uses near the Curie point ``Tc`` (gadolinium's):
    the relay magnetization, the spontaneous one, as ``(1 - T/Tc)^beta``; the pinning -- coercive
    median and interaction scale -- following it, ``Hc ~ Ms^n`` (n = 2 is the anisotropy-controlled
    pinning of domain walls, K1 ~ Ms^3 over the Ms of the Zeeman energy, Callen-Callen); the reversible
    susceptibility diverging as ``(1 - T/Tc)^-gamma`` (gamma = 1.39 for the 3-D Heisenberg class; a
    :class:`CriticalPowerLaw` with a negative exponent). Values are illustrative, not fitted.
    """

    relay_magnetization: object = field(default_factory=lambda: CriticalPowerLaw(2.0e6, GD_CURIE_K, 0.3))
    reversible_susceptibility: object = field(default_factory=lambda: CriticalPowerLaw(1.0, GD_CURIE_K, -1.39))
    coercive_median: object = field(default_factory=lambda: FollowsMs(2000.0, 2.0))
    coercive_spread: object = field(default_factory=lambda: Constant(0.6))
    interaction_scale: object = field(default_factory=lambda: FollowsMs(5000.0, 1.0))
    #: field scale of the saturating reversible part (``hem.SATURATING_REVERSIBLE``), A/m; 0: linear
    reversible_saturation: object = field(default_factory=lambda: Constant(0.0))

    def reduced_ms(self, T):
        """``relay_magnetization(T)/relay_magnetization(0 K)`` (dimensionless)."""
        T = _kelvin(T)
        return self.relay_magnetization(T, None) / float(np.asarray(self.relay_magnetization(np.array(1e-12), None)))

    def __call__(self, T):
        """Dict of the HEM parameters (HEM_PARAMETER_NAMES and ``reversible_saturation``), float arrays
        shaped like ``T`` (K); valid below ``Tc`` only."""
        T = _kelvin(T)
        reduced = self.reduced_ms(T)
        return {name: np.broadcast_to(np.asarray(getattr(self, name)(T, reduced), dtype=np.float64), T.shape).copy()
                for name in HEM_PARAMETER_NAMES + ("reversible_saturation",)}

    def batch(self, T, interaction_density="normal", coercive_nodes=16):
        """A :class:`~hyst_gym.physics.hem.HEMBatch` with one model per temperature (K)."""
        from .hem import HEMBatch

        values = self(np.atleast_1d(np.asarray(T, dtype=np.float64)).ravel())
        return HEMBatch(*(values[n] for n in HEM_PARAMETER_NAMES), interaction_density, coercive_nodes,
                        values["reversible_saturation"])


__all__ = [
    "GD_CURIE_K", "HEM_PARAMETER_NAMES", "HEMTemperatureLaws", "ZERO_CELSIUS_K", "Constant", "CriticalPowerLaw",
    "FollowsMs", "LinearInT",
    "LogPolynomial", "PARAMETER_NAMES", "TemperatureLaws", "celsius_to_kelvin", "critical_power_law",
    "linear_in_temperature", "log_polynomial", "power_of_ratio",
]
