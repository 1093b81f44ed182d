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
A field that starts at 0 under the slew limit has ``max_{s<=j} |H_s| <= min(slew*j*dt, field_limit)``,
so ``|m_j| <= Phi(min(slew*j*dt, field_limit))``, the *sensitivity envelope*: the largest ``|dM/da|``
of any history whose field stayed within that bound, over every a the episode can reach
(:func:`sensitivity_table`). Hence ``I_t <= G^2 sum_{j<=t} Phi_j^2/sigma^2`` for any input, adaptive or
not. The thermal limit is dropped (a relaxation: fewer constraints, more information, so the
bound stays valid; for the hot coil the heat budget would bind only late in the episode, when the
floor is already small).

**What is assumed, and checked.** ``Phi`` is not derived in closed form: it is the running maximum,
binned by the largest ``|H|`` reached so far, of ``|dM/da|`` on the initial magnetization curve and on
random slew-limited histories (minor loops inside a bound can exceed the initial curve's
sensitivity at that bound). A field that starts at 0 under the slew limit has ``max |H| <=
min(slew*t, field_limit)`` by step t, which is what makes the binning valid. That no history exceeds it is
checked, not proven: :func:`sensitivity_table` reports the largest ratio of a second, independent set of
histories to the envelope (``check_ratio``), and the envelope is multiplied by that ratio when it exceeds 1.
The tests cross-check the finite-difference sensitivity against the estimator bank's
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
    """``n_paths`` random slew-limited fields (A/m), shape (steps, n_paths), each from H = 0 and confined
    to its own bound (uniform in (0, field_limit]): each step moves towards a target redrawn with
    probability 0.1 (uniform within the bound) by at most ``max_change``."""
    rng = np.random.default_rng(seed)
    bound = rng.uniform(0.0, 1.0, n_paths) * field_limit
    field = np.zeros((steps, n_paths))
    current = np.zeros(n_paths)
    target = rng.uniform(-1.0, 1.0, n_paths) * bound
    for t in range(steps):
        redraw = rng.random(n_paths) < 0.1
        target[redraw] = rng.uniform(-1.0, 1.0, int(redraw.sum())) * bound[redraw]
        current = current + np.clip(target - current, -max_change, max_change)
        field[t] = current
    return field


@dataclass(frozen=True)
class SensitivityTable:
    """The largest ``|dM/da|`` (dimensionless) known for histories that kept ``|H| <= field`` (A/m), over
    the a range: ``envelope`` (running max of the initial curve and of random admissible histories,
    binned by their largest ``|H|`` so far), ``rho`` (1/(A/m)^2) and ``phi0`` (at H = 0, any history) of the
    thermal term,
    ``curve_ratio`` (how far the histories exceed the initial curve alone, the largest ratio) and
    ``check_ratio``: the largest ratio of a *second, independent* set of histories to the envelope
    (<= 1 means the check found no history above it)."""

    fields: np.ndarray
    envelope: np.ndarray
    curve_ratio: float
    check_ratio: float


def _history_maximum(params, a_values, fields, max_change, max_field_step, n_paths, steps, seed):
    """Per field bin i: the largest |dM/da| seen on random admissible histories (each from the
    demagnetized state) while their largest |H| so far was at most ``fields[i]``."""
    paths = random_admissible_fields(n_paths, steps, max_change, fields[-1], seed)
    bins = np.minimum(np.searchsorted(fields, np.maximum.accumulate(np.abs(paths), axis=0)), fields.shape[0] - 1)
    found = np.zeros(fields.shape[0])
    for path in range(n_paths):
        seen = magnetization_sensitivity(paths[:, path], a_values, params, max_field_step).max(axis=1)
        np.maximum.at(found, bins[:, path], seen)
    return found


def sensitivity_table(params: HysteresisParams, a_range, field_limit: float, max_change: float,
                      max_field_step: float, n_a: int = 5, n_paths: int = 64, steps: int = 200,
                      seed: int = 0) -> SensitivityTable:
    """The envelope of the relaxation (module doc) for a in ``a_range`` (A/m), fields up to
    ``field_limit`` (A/m): the initial curve and ``n_paths`` random histories of ``steps`` steps of at most
    ``max_change`` A/m (seed ``seed``), checked on as many histories of seed ``seed + 1``."""
    a_values = np.linspace(float(a_range[0]), float(a_range[1]), n_a)
    fields = np.linspace(0.0, field_limit, 401)[1:]
    curve = magnetization_sensitivity(fields, a_values, params, max_field_step).max(axis=1)
    histories = _history_maximum(params, a_values, fields, max_change, max_field_step, n_paths, steps, seed)
    envelope = np.maximum.accumulate(np.maximum(curve, histories))
    check = _history_maximum(params, a_values, fields, max_change, max_field_step, n_paths, steps, seed + 1)
    check_ratio = float(np.max(np.maximum.accumulate(check) / envelope))
    curve_ratio = float(np.max(envelope / np.maximum.accumulate(curve)))
    return SensitivityTable(fields, envelope * max(1.0, check_ratio), curve_ratio, check_ratio)


@dataclass(frozen=True)
class BoundSetting:
    """Everything the floor needs: control period ``dt`` (s), ``steps``, ``field_limit`` (A/m),
    ``max_change`` (A/m per step), ``sigma`` (noise of the normalized output), ``gain`` G (1/(A/m):
    sum |h| / output scale), the a prior's support ``a_lo``, ``a_hi`` (A/m)."""

    dt: float
    steps: int
    field_limit: float
    max_change: float
    sigma: float
    gain: float
    a_lo: float
    a_hi: float


def information_ceiling(setting: BoundSetting, table: SensitivityTable) -> np.ndarray:
    """Upper bound on the Fisher information I_t (1/(A/m)^2) after each step t = 1..steps, for any
    admissible input (module doc)."""
    t = np.arange(1, setting.steps + 1)
    reach = np.minimum(setting.max_change * t, setting.field_limit)
    phi = np.interp(reach, table.fields, table.envelope)
    return np.cumsum(phi ** 2) * setting.gain ** 2 / setting.sigma ** 2


def van_trees_mse(setting: BoundSetting, table: SensitivityTable) -> np.ndarray:
    """Per step, the lower bound on the Bayes MSE of any estimate of a, (A/m)^2."""
    prior = raised_cosine_fisher(setting.a_hi - setting.a_lo)
    return 1.0 / (prior + information_ceiling(setting, table))


def episode_floor(setting: BoundSetting, table: SensitivityTable, first_step: int = 0) -> float:
    """Floor on the RMS error over steps ``first_step + 1 .. steps`` and the prior, A/m:
    ``sqrt(mean_t bound_t)``; no agent's ``sqrt(E[mean_t (a_hat_t - a_t)^2])`` over those steps can be
    lower (the overheat penalty only adds error)."""
    if not 0 <= first_step < setting.steps:
        raise ValueError(f"episode_floor: first_step must be in [0, {setting.steps}), got {first_step!r}")
    return float(np.sqrt(np.mean(van_trees_mse(setting, table)[first_step:])))


__all__ = ["BoundSetting", "SensitivityTable", "episode_floor", "information_ceiling",
           "magnetization_sensitivity", "random_admissible_fields", "raised_cosine_fisher",
           "raised_cosine_quantile", "sensitivity_table", "van_trees_mse"]
