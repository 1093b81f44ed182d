"""A Van Trees (Bayesian Cramér–Rao) floor on the error of *any* identification of a (issue 23).

Setting (suite v2's calibration tasks): the coil starts at an unknown temperature T0 drawn from a
raised-cosine prior over ``[T_lo, T_hi]`` (K), so ``a0 = a(T0)`` (A/m, eq. (4)) has the raised-cosine
prior over ``[a(T_lo), a(T_hi)]``. The ambient is the initial temperature and does not drift, so
the heating ``T_t - T0`` is a known function of the applied field: ``a_t = a0 + (a_ref/T_ref)*(T_t - T0)``
and the error of any estimate of ``a_t`` is the error of the implied estimate of ``a0``. Each
control step measures the normalized output ``y_t/scale`` with white Gaussian noise of standard
deviation ``sigma`` (the env's ``output_noise``).

**Van Trees.** For any estimator (biased or not, using any causal, even adaptive, input) the
Bayes MSE at step t satisfies ``E[(a_hat_t - a_t)^2] >= 1/(J + E_prior[I_t(a0)])``, with ``J`` the
location Fisher information of the prior (raised cosine of width W: ``J = 4 pi^2/W^2``, the smallest
of any density on an interval) and ``I_t`` the Fisher information of the first t samples. With
an adaptive input the chain rule still gives ``I_t = E[sum_s (d y_s/d a)^2]/sigma^2`` (the input at
s depends on the past samples only, not on a).

**Relaxation (an upper bound on I_t for every admissible input).** The output is a linear,
causal filter of M with impulse response h (the transducer), so by Cauchy–Schwarz
``sum_{s<=t} (dy_s/da)^2 <= G^2 sum_{j<=t} m_j^2`` with ``G = sum |h|/scale`` and ``m_j = dM_j/da``.
Each ``m_j^2`` is at most

* the sensitivity envelope ``Phi(t_j)^2``: the largest ``|dM/da|`` at any field reachable by then
  (``|H| <= min(slew*t, field_limit)``) and any a the episode can reach (:func:`sensitivity_table`);
* ``Phi0^2 + rho*H_j^2`` (``rho`` the largest ``(Phi(H)^2 - Phi0^2)/H^2``, ``Phi0`` the sensitivity at
  H = 0): a field costs heat, and the coil may heat only ``T_limit - T0`` before the episode ends;
  the exact discrete thermal step gives ``sum_{j<=t} H_j^2 <= (T_limit - T0)(1 + (1-d) t)/(R_th p (1-d))
  + F^2/2 + t*delta^2/6`` (d = exp(-dt/tau), p = Joule power per (A/m)^2, delta the largest field
  change per step, F the field limit).

So ``I_t(T0) <= G^2 min(sum_j Phi(t_j)^2, t Phi0^2 + rho E_t(T0))/sigma^2``. Dropping the thermal
term (``heating=None``) relaxes further and stays valid.

**What is assumed, and checked.** ``Phi`` is computed on the initial magnetization curve and,
as in :mod:`hyst_gym.estimation.convergence`, the claim that no other history reaches a larger
``|dM/da|`` at the same ``|H|`` is checked, not proven: :func:`sensitivity_table` returns the largest
ratio seen on random slew-limited histories, and the envelope is multiplied by it when it
exceeds 1. The tests cross-check the finite-difference sensitivity against the estimator bank's
interpolated slope, and the Van Trees formula against Monte-Carlo of the exact posterior mean
on a linear-Gaussian case, where the bound is attained.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..physics import HysteresisBatch, HysteresisParams, simulate_batch

#: relative step of the central difference dM/da
FD_STEP = 1e-3


def raised_cosine_quantile(u):
    """Inverse CDF of the raised-cosine density ``1 - cos(2 pi x)`` on [0, 1] (dimensionless): bisection
    on the increasing ``F(x) = x - sin(2 pi x)/(2 pi)`` to 2**-52; ``u`` in [0, 1]."""
    u = np.asarray(u, dtype=np.float64)
    if np.any(~np.isfinite(u)) or np.any((u < 0) | (u > 1)):
        raise ValueError("raised_cosine_quantile: u must lie in [0, 1]")
    low, high = np.zeros_like(u), np.ones_like(u)
    for _ in range(52):
        middle = 0.5 * (low + high)
        below = middle - np.sin(2 * np.pi * middle) / (2 * np.pi) < u
        low = np.where(below, middle, low)
        high = np.where(below, high, middle)
    return 0.5 * (low + high)


def raised_cosine_fisher(width: float) -> float:
    """Location Fisher information of the raised-cosine density over an interval of ``width``
    (same unit u as the width): ``4 pi^2/width^2``, in 1/u^2."""
    if not (math.isfinite(width) and width > 0):
        raise ValueError(f"raised_cosine_fisher: width must be > 0, got {width!r}")
    return 4.0 * math.pi ** 2 / width ** 2


def magnetization_sensitivity(field, a_values, params: HysteresisParams, max_field_step: float) -> np.ndarray:
    """``|dM/da|`` (dimensionless) after each sample of ``field`` (A/m, from M = 0 at H = 0) for each a
    (A/m), by a central difference of two banks at ``a*(1 -+ FD_STEP)``; shape (len(field), len(a))."""
    a_values = np.atleast_1d(np.asarray(a_values, dtype=np.float64))
    bank = HysteresisBatch.grid(params, np.concatenate([a_values * (1 - FD_STEP), a_values * (1 + FD_STEP)]))
    path = np.concatenate([[0.0], np.asarray(field, dtype=np.float64)])
    magnetization = simulate_batch(path, bank, max_field_step=max_field_step)[1:]
    n = a_values.shape[0]
    return np.abs(magnetization[:, n:] - magnetization[:, :n]) / (2 * FD_STEP * a_values)


def random_admissible_fields(n_paths: int, steps: int, max_change: float, field_limit: float,
                             seed: int = 0) -> np.ndarray:
    """``n_paths`` random slew-limited fields (A/m), shape (steps, n_paths): each step moves towards a
    target redrawn with probability 0.1 (uniform in +-field_limit) by at most ``max_change``."""
    rng = np.random.default_rng(seed)
    field = np.zeros((steps, n_paths))
    current = np.zeros(n_paths)
    target = rng.uniform(-field_limit, field_limit, n_paths)
    for t in range(steps):
        redraw = rng.random(n_paths) < 0.1
        target[redraw] = rng.uniform(-field_limit, field_limit, int(redraw.sum()))
        current = current + np.clip(target - current, -max_change, max_change)
        field[t] = current
    return field


@dataclass(frozen=True)
class SensitivityTable:
    """``|dM/da|`` on the initial curve, maximized over the a range: ``fields`` (A/m), ``envelope``
    (running max over |H| <= field), ``rho`` (1/(A/m)^2), ``phi0`` (at H = 0 after any history), and
    ``history_ratio``: the largest sensitivity seen on random admissible histories over the envelope
    at their |H| (the envelope used is ``max(1, history_ratio)`` times the initial curve's)."""

    fields: np.ndarray
    envelope: np.ndarray
    rho: float
    phi0: float
    history_ratio: float


def sensitivity_table(params: HysteresisParams, a_range, field_limit: float, max_change: float,
                      max_field_step: float, n_a: int = 5, n_paths: int = 64, steps: int = 200,
                      seed: int = 0) -> SensitivityTable:
    """The envelope of the relaxation (module doc) for a in ``a_range`` (A/m), fields up to
    ``field_limit`` (A/m), checked on ``n_paths`` random histories of ``steps`` steps of at most
    ``max_change`` A/m."""
    a_values = np.linspace(float(a_range[0]), float(a_range[1]), n_a)
    fields = np.linspace(0.0, field_limit, 401)[1:]
    curve = magnetization_sensitivity(fields, a_values, params, max_field_step).max(axis=1)
    envelope = np.maximum.accumulate(curve)
    paths = random_admissible_fields(n_paths, steps, max_change, field_limit, seed)
    worst_ratio, phi0 = 0.0, float(curve[0])
    for a in a_values:
        seen = magnetization_sensitivity(paths.ravel(order="F"), [a], params, max_field_step)[:, 0]
        seen = seen.reshape(n_paths, steps).T  # paths run one after another from the demagnetized state
        allowed = np.interp(np.abs(paths), np.concatenate([[0.0], fields]), np.concatenate([[curve[0]], envelope]))
        worst_ratio = max(worst_ratio, float(np.max(seen / allowed)))
        near_zero = np.abs(paths) <= fields[0]
        if near_zero.any():
            phi0 = max(phi0, float(seen[near_zero].max()))
    scale = max(1.0, worst_ratio)
    envelope = envelope * scale
    rho = float(np.max((envelope ** 2 - phi0 ** 2) / fields ** 2))
    return SensitivityTable(fields, envelope, max(rho, 0.0), phi0 * scale, worst_ratio)


@dataclass(frozen=True)
class Heating:
    """The thermal budget of the relaxation: prior support ``t_lo``..``t_hi`` and limit (K), the
    exact step's ``decay`` = exp(-dt/tau), ``r_power`` = R_th * Joule power per (A/m)^2 (K/(A/m)^2)."""

    t_lo: float
    t_hi: float
    t_limit: float
    decay: float
    r_power: float


@dataclass(frozen=True)
class BoundSetting:
    """Everything the floor needs: control period ``dt`` (s), ``steps``, ``field_limit`` (A/m),
    ``max_change`` (A/m per step), ``sigma`` (noise of the normalized output), ``gain`` G (1/(A/m):
    sum |h| / output scale), the a prior's support ``a_lo``, ``a_hi`` (A/m), ``heating`` (or None)."""

    dt: float
    steps: int
    field_limit: float
    max_change: float
    sigma: float
    gain: float
    a_lo: float
    a_hi: float
    heating: Heating | None


def information_ceiling(setting: BoundSetting, table: SensitivityTable, nodes: int = 33):
    """Upper bound on the Fisher information I_t (1/(A/m)^2) after each step, per prior node of T0
    (or a0): shape (steps, nodes), and the nodes' prior weights (raised cosine, sum 1)."""
    t = np.arange(1, setting.steps + 1)
    reach = np.minimum(setting.max_change * t, setting.field_limit)
    phi = np.interp(reach, table.fields, table.envelope)
    envelope_sum = np.cumsum(phi ** 2)
    u = (np.arange(nodes) + 0.5) / nodes
    weights = 1.0 - np.cos(2 * np.pi * u)
    weights /= weights.sum()
    scale = setting.gain ** 2 / setting.sigma ** 2
    if setting.heating is None:
        return np.repeat((scale * envelope_sum)[:, None], nodes, axis=1), weights
    heat = setting.heating
    t0 = heat.t_lo + (heat.t_hi - heat.t_lo) * u
    budget = np.maximum(heat.t_limit - t0, 0.0)
    energy = (budget[None, :] * (1 + (1 - heat.decay) * t[:, None]) / (heat.r_power * (1 - heat.decay))
              + setting.field_limit ** 2 / 2 + t[:, None] * setting.max_change ** 2 / 6)
    thermal = t[:, None] * table.phi0 ** 2 + table.rho * energy
    return scale * np.minimum(envelope_sum[:, None], thermal), weights


def van_trees_mse(setting: BoundSetting, table: SensitivityTable) -> np.ndarray:
    """Per step, the lower bound on the Bayes MSE of any estimate of a, (A/m)^2."""
    ceiling, weights = information_ceiling(setting, table)
    prior = raised_cosine_fisher(setting.a_hi - setting.a_lo)
    return 1.0 / (prior + ceiling @ weights)


def episode_floor(setting: BoundSetting, table: SensitivityTable) -> float:
    """Floor on the RMS error over the episode and the prior, A/m: ``sqrt(mean_t bound_t)``; no agent's
    ``sqrt(E[mean_t (a_hat_t - a_t)^2])`` can be lower (the overheat penalty only adds error)."""
    return float(np.sqrt(np.mean(van_trees_mse(setting, table))))


__all__ = ["BoundSetting", "Heating", "SensitivityTable", "episode_floor", "information_ceiling",
           "magnetization_sensitivity", "random_admissible_fields", "raised_cosine_fisher",
           "raised_cosine_quantile", "sensitivity_table", "van_trees_mse"]
