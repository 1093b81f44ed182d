"""A Van Trees (Bayesian Cramér–Rao) floor on the error of *any* identification of a.

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
not. The thermal limit is dropped here (a relaxation: fewer constraints, more information, so the
bound stays valid, but loose: at full field the hot coil's heat budget binds after 1..4 s, before
the scored window). :func:`heated_floor` keeps it (section below).

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

**The floor with the heat budget** (:func:`heated_floor`; the derivation in full is in
``experiments/results/floors.md``). Three changes to the above, each keeping the bound valid:

1. *Current-field envelope.* ``|dM/da|`` is nearly proportional to the *current* ``|H|`` (about
   1.3e-4 per A/m, on the way up and down alike), so :func:`current_field_envelope` bins it by the
   current ``|H|`` (the largest over histories under the field limit whose present ``|H|`` is at most
   the bin's field), not by the largest ``|H|`` so far. Its sampling is corrected *bin by bin* by an
   independent second set of histories and checked on a third.
2. *Heat as a constraint.* With no ambient drift the temperature rise ``D_s`` of the coil is a known
   linear recursion in the field's mean square (:class:`ThermalBudget`, the env's exact step), and a
   start T0 leaves ``B = T_limit - T0``. The largest ``G^2 sum_{j<=t} Psi(|H_j|)^2/sigma^2`` over
   slew- and field-limited paths with ``D_s <= B`` for ``s < t`` (an overheat at step t still scores
   step t) is bounded by Lagrangian duality: for any multipliers ``lambda_s >= 0`` the path maximum
   of ``sum Psi^2 - sum lambda_s (D_s - B)`` (a dynamic programme over a field grid, rewards
   rounded up and heat rounded down) is an upper bound (:func:`heated_information_ceiling`).
3. *The prior split by start temperature.* The Bayes risk is concave in the prior, so writing the
   raised cosine as ``p = sum_k w_k p_k`` with ``p_k = p*phi_k/w_k`` (``phi_k`` raised-cosine bumps of half
   width d centred every d, a partition of unity) gives ``risk >= sum_k w_k * risk(p_k)``; on each piece
   Van Trees holds with the piece's own Fisher information ``J_k`` (quadrature) and the heat budget of
   the coolest start of the piece. A policy that overheats
   on a fraction ``q`` of a piece's draws gains at most ``q*I_free`` of information and pays
   ``q*(e_over^2 - (2 d_a)^2)`` (the metric counts ``e_over`` = width(Theta) per step after an
   overheat): :func:`heated_floor` checks that this never pays, so the floor holds for every policy,
   adaptive or not, overheating or not.

The envelope is sampled, as before; its caveat (one-step near-switch events of model (6) that an input
tuned to the true a could repeat) is in :func:`calibration_heated_floor`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from numba import njit

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




# ---------------------------------------------------------------------------- the floor with the heat budget


@dataclass(frozen=True)
class CurrentFieldEnvelope:
    """``envelope[i]`` (dimensionless): the largest ``|dM/da|`` found on any history kept under the field
    limit at a moment when its present ``|H| <= fields[i]`` (A/m; ``fields[0] = 0``), over the a range
    (and the k values) it was built for; non-decreasing. ``sampled``: the same from the initial curve
    and the first set of random histories alone; ``correction_ratio``: the
    largest factor by which a second, independent set raised a bin of ``sampled``; ``residual_ratio``:
    the largest factor by which a third set then raised a bin (1: it raised none; the envelope is
    raised by both, bin by bin: ``corrected_bins`` bins of ``fields.size`` moved above ``sampled``)."""

    fields: np.ndarray
    envelope: np.ndarray
    sampled: np.ndarray
    correction_ratio: float
    corrected_bins: int
    residual_ratio: float

    def at(self, field) -> np.ndarray:
        """The envelope at ``|field|`` (A/m): the value of the first bin whose field is at least it (an
        upper bound, since the envelope is non-decreasing); ValueError above the last bin."""
        field = np.abs(np.asarray(field, dtype=np.float64))
        if np.any(field > self.fields[-1] * (1 + 1e-12)):
            raise ValueError(f"CurrentFieldEnvelope.at: |field| above the envelope's {self.fields[-1]:g} A/m")
        return self.envelope[np.minimum(np.searchsorted(self.fields, field * (1 - 1e-12)), self.fields.size - 1)]


def structured_admissible_fields(field_limit: float, max_change: float, steps: int) -> np.ndarray:
    """Slew-limited fields (A/m), shape (steps, n), from H = 0: to a peak R at the slew limit, back to a level
    L <= R, then a square dither of amplitude A and period P about L (R, L on tenths of the limit; A of
    0.04, 0.12, 0.4 and 1 slew step; P of 2, 4 and 8 steps): shapes random histories reach rarely. Not
    part of the envelope: a dither tuned to a particular a makes ``|dM/da|`` at that a jump for one
    step (up to about 25 at 20 kA/m on the hot coil, over a window of a few A/m of a; a near-switch of
    model (6)'s irreversible branch); see the caveat of :func:`calibration_heated_floor`."""
    paths = []
    tenths = field_limit * np.arange(1, 11) / 10
    for peak in tenths:
        for level in tenths[tenths <= peak]:
            for amplitude in (0.04, 0.12, 0.4, 1.0):
                for period in (2, 4, 8):
                    current, phase, dither_start = 0.0, "up", 0
                    field = np.empty(steps)
                    for t in range(steps):
                        if phase == "up" and current >= peak:
                            phase = "down"
                        if phase == "down" and abs(current - level) < 1e-9 * field_limit:
                            phase, dither_start = "dither", t
                        if phase == "up":
                            target = peak
                        elif phase == "down":
                            target = level
                        else:
                            sign = 1.0 if ((t - dither_start) // (period // 2)) % 2 == 0 else -1.0
                            target = min(level + sign * amplitude * max_change, field_limit)
                        current += float(np.clip(target - current, -max_change, max_change))
                        field[t] = current
                    paths.append(field)
    return np.array(paths).T


def _fields_maximum(params_list, a_values, fields, max_field_step, paths):
    """Per bin i: the largest |dM/da| seen on ``paths`` (steps, n) at moments when the present |H| was in
    (fields[i-1], fields[i]] (bin 0: H = 0), before the running maximum over bins."""
    bins = np.minimum(np.searchsorted(fields, np.abs(paths)), fields.shape[0] - 1)
    found = np.zeros(fields.shape[0])
    for params in params_list:
        for path in range(paths.shape[1]):
            seen = magnetization_sensitivity(paths[:, path], a_values, params, max_field_step).max(axis=1)
            np.maximum.at(found, bins[:, path], seen)
    return found


def current_field_envelope(params_list, a_range, field_limit: float, max_change: float, max_field_step: float,
                           field_step: float, n_a: int = 5, n_paths: int = 64, steps: int = 200,
                           seed: int = 0) -> CurrentFieldEnvelope:
    """The current-field envelope (module doc, point 1) of the models ``params_list`` (a list of
    :class:`~hyst_gym.physics.HysteresisParams`, e.g. several k) for a in ``a_range`` (A/m, ``n_a``
    values), on bins every ``field_step`` A/m up to ``field_limit``: the initial curve and ``n_paths``
    random slew-limited histories of
    ``steps`` steps (``max_change`` A/m per step, seed ``seed``), then raised bin by bin to ``n_paths``
    histories of seed ``seed + 1`` (``correction_ratio``) and again to ``n_paths`` of seed ``seed + 2``
    (``residual_ratio``: how far sampling still moved it)."""
    if not (field_step > 0 and field_limit > 0):
        raise ValueError(f"current_field_envelope: field_step and field_limit must be > 0, got {field_step!r}, "
                         f"{field_limit!r}")
    params_list = list(params_list)
    a_values = np.linspace(float(a_range[0]), float(a_range[1]), n_a)
    fields = np.append(np.arange(0.0, field_limit * (1 - 1e-12), field_step), field_limit)
    curve = np.zeros(fields.shape[0])
    for params in params_list:
        curve[1:] = np.maximum(curve[1:], magnetization_sensitivity(fields[1:], a_values, params,
                                                                    max_field_step).max(axis=1))

    def sampled_set(set_seed):
        paths = random_admissible_fields(n_paths, steps, max_change, field_limit, set_seed)
        return np.maximum.accumulate(_fields_maximum(params_list, a_values, fields, max_field_step, paths))

    sampled = np.maximum.accumulate(np.maximum(curve, sampled_set(seed)))
    corrected = np.maximum(sampled, sampled_set(seed + 1))
    envelope = np.maximum(corrected, sampled_set(seed + 2))
    correction = float(np.max(corrected[sampled > 0] / sampled[sampled > 0]))
    residual = float(np.max(envelope[corrected > 0] / corrected[corrected > 0]))
    return CurrentFieldEnvelope(fields, envelope, sampled, correction, int(np.sum(envelope > sampled)), residual)


@dataclass(frozen=True)
class ThermalBudget:
    """The coil's heating as the env steps it (no ambient drift): after a step from field ``h0`` to ``h1``
    (A/m, moving linearly) the rise ``D = T - T0`` (K) becomes ``decay*D + (1 - decay)*R_th*kappa*ms``, with
    ``ms = (h0^2 + h0 h1 + h1^2)/3`` the step's mean square field, ``decay = exp(-dt/(R_th C_th))``.

    ``dt`` (s), ``thermal_resistance`` R_th (K/W), ``heat_capacity`` C_th (J/K), ``power_per_square_field``
    kappa = R/n^2 (W per (A/m)^2), ``temperature_limit`` (K: above it the episode ends), ``start_low``,
    ``start_high`` (K: the raised-cosine prior of the start T0, which is also the ambient),
    ``a_reference`` (A/m) at ``reference_temperature`` (K): ``a = a_reference*T/reference_temperature``, eq. (4)."""

    dt: float
    thermal_resistance: float
    heat_capacity: float
    power_per_square_field: float
    temperature_limit: float
    start_low: float
    start_high: float
    a_reference: float
    reference_temperature: float

    def __post_init__(self):
        for name in ("dt", "thermal_resistance", "heat_capacity", "power_per_square_field", "temperature_limit",
                     "start_low", "start_high", "a_reference", "reference_temperature"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or \
                    value <= 0:
                raise ValueError(f"ThermalBudget: {name} must be a finite number > 0, got {value!r}")
        if not self.start_low < self.start_high < self.temperature_limit:
            raise ValueError(f"ThermalBudget: need start_low < start_high < temperature_limit, got "
                             f"{self.start_low!r}, {self.start_high!r}, {self.temperature_limit!r}")

    @classmethod
    def from_thermal(cls, thermal, dt: float, temperature_limit: float, start_range) -> "ThermalBudget":
        """From a :class:`~hyst_gym.physics.ThermalParams` (its coil, heat path and a(T)), the control period
        ``dt`` (s), the ``temperature_limit`` (K) and the start prior's ``(low, high)`` (K)."""
        return cls(float(dt), float(thermal.thermal_resistance), float(thermal.heat_capacity),
                   float(thermal.power_per_square_field), float(temperature_limit), float(start_range[0]),
                   float(start_range[1]), float(thermal.a_reference), float(thermal.reference_temperature))

    @property
    def decay(self) -> float:
        """``exp(-dt/(R_th C_th))`` per step."""
        return math.exp(-self.dt / (self.thermal_resistance * self.heat_capacity))

    @property
    def rise_per_mean_square(self) -> float:
        """K of rise per (A/m)^2 of a step's mean square field: ``(1 - decay)*R_th*kappa``."""
        return (1.0 - self.decay) * self.thermal_resistance * self.power_per_square_field

    @property
    def a_per_kelvin(self) -> float:
        """da/dT, A/m per K (eq. (4))."""
        return self.a_reference / self.reference_temperature

    def rise(self, field) -> np.ndarray:
        """The rise D_s (K) after each step of ``field`` (A/m, shape (steps, ...)), from 0 at H = 0."""
        field = np.asarray(field, dtype=np.float64)
        previous = np.zeros(field.shape[1:])
        rise = np.zeros(field.shape[1:])
        out = np.empty_like(field)
        for s in range(field.shape[0]):
            mean_square = (previous * previous + previous * field[s] + field[s] * field[s]) / 3.0
            rise = self.decay * rise + self.rise_per_mean_square * mean_square
            out[s] = rise
            previous = field[s]
        return out


@njit(cache=True)
def _path_maxima(reward, heat, reach, multipliers):
    """Per row of ``multipliers`` (batch, steps): the largest ``sum_j reward[f_j] - m_j*heat[f_{j-1}, f_j]``
    over grid paths from f_0 = 0 moving by at most ``reach`` cells per step."""
    n = reward.shape[0]
    out = np.empty(multipliers.shape[0])
    value = np.empty(n)
    new = np.empty(n)
    for b in range(multipliers.shape[0]):
        value[:] = -np.inf
        value[0] = 0.0
        for j in range(multipliers.shape[1]):
            m = multipliers[b, j]
            for g in range(n):
                best = -np.inf
                for f in range(max(0, g - reach), min(n, g + reach + 1)):
                    v = value[f] - m * heat[f, g]
                    if v > best:
                        best = v
                new[g] = best + reward[g]
            value[:] = new
        out[b] = value.max()
    return out


#: the multiplier family of the dual (:func:`heated_information_ceiling`): onsets every this many steps,
#: and these levels (1/(A/m)^2 of information per K, times the largest per-step reward); level 0 included
DUAL_ONSET_STRIDE = 2
DUAL_LEVELS = np.concatenate([[0.0], np.geomspace(1e-3, 1e2, 61)])


def _multipliers(horizon: int, onset: int, level: float, decay: float):
    """The family member: ``lambda_s = level*(1 - decay)`` for onset <= s < horizon - 1, ``lambda_{horizon-1} =
    level``, 0 before onset; returns the per-step heat weights ``mu_i = sum_{s>=i} lambda_s decay^(s-i)``
    (level from the onset on, level*decay^(onset-i) before; the heat of step ``horizon`` is free) and
    ``sum_s lambda_s``."""
    i = np.arange(1, horizon + 1)
    weights = np.where(i >= onset, level, level * decay ** np.maximum(onset - i, 0))
    weights[-1] = 0.0
    return weights, level * (1.0 - decay) * max(horizon - 1 - onset, 0) + level


@dataclass(frozen=True)
class HeatedCeiling:
    """Upper bounds on ``sum_{j<=t} Psi(|H_j|)^2`` (dimensionless; times ``G^2/sigma^2`` it is the Fisher
    information in 1/(A/m)^2) over admissible paths, per horizon t in ``horizons`` (steps): ``free`` with
    the field and slew limits only, and through :meth:`at` with a heat budget too. ``values[h, m]`` and
    ``sums[h, m]`` hold the path maximum and ``sum lambda`` of the m-th multiplier of the family at horizon
    h: the bound for a budget B is ``min_m values + B*sums`` (weak duality, any m is valid)."""

    horizons: np.ndarray
    free: np.ndarray
    values: np.ndarray
    sums: np.ndarray

    def at(self, budget: float) -> np.ndarray:
        """Per horizon, the bound with the temperature rise kept at or below ``budget`` (K) before the
        horizon's step."""
        if not budget >= 0:
            raise ValueError(f"HeatedCeiling.at: budget must be >= 0 K, got {budget!r}")
        return np.min(self.values + budget * self.sums, axis=1)


def heated_information_ceiling(envelope: CurrentFieldEnvelope, thermal: ThermalBudget, max_change: float,
                               horizons, cells_per_step: int = 2) -> HeatedCeiling:
    """The dual bound of the module doc (point 2) on a field grid of ``max_change/cells_per_step`` A/m
    (``max_change``: the slew limit per step, A/m; the envelope's bins must be that grid). A path's
    field ``|H_j|`` is replaced by its grid floor f_j (which moves by at most ``cells_per_step`` cells per
    step): the reward is the envelope at the cell's top and the heat is the mean square of the floors
    (``(x^2 + y^2)/6`` when ``x + y`` is within one slew step, where the field may change sign), so every
    admissible path is dominated by a grid path."""
    fields = envelope.fields
    cell = max_change / cells_per_step
    expected = np.append(np.arange(0.0, fields[-1] * (1 - 1e-12), cell), fields[-1])
    if expected.shape != fields.shape or not np.allclose(expected, fields, rtol=0, atol=1e-9 * fields[-1]):
        raise ValueError(f"heated_information_ceiling: the envelope's bins must be every max_change/cells_per_step "
                         f"= {cell:g} A/m up to {fields[-1]:g} A/m")
    horizons = np.asarray(horizons, dtype=np.int64)
    if horizons.ndim != 1 or horizons.size == 0 or np.any(horizons < 1):
        raise ValueError("heated_information_ceiling: horizons must be a non-empty list of steps >= 1")
    if abs(fields[-1] / cell - round(fields[-1] / cell)) > 1e-9:
        raise ValueError(f"heated_information_ceiling: the field limit {fields[-1]:g} A/m must be a whole number "
                         f"of cells of {cell:g} A/m")
    floors = fields  # cell f covers [fields[f], fields[f + 1]); the last cell is the limit itself
    reward = envelope.envelope[np.minimum(np.arange(fields.size) + 1, fields.size - 1)] ** 2
    x, y = floors[:, None], floors[None, :]
    mean_square = np.where(x + y > max_change, (x * x + x * y + y * y) / 3.0, (x * x + y * y) / 6.0)
    heat = thermal.rise_per_mean_square * mean_square
    levels = DUAL_LEVELS * reward.max()
    free, values, sums = [], [], []
    onsets = np.arange(1, int(horizons.max()) + 1, DUAL_ONSET_STRIDE)
    for horizon in horizons:
        rows, lams = [], []
        for onset in np.minimum(onsets, max(int(horizon) - 1, 1)):
            for level in levels:
                weights, lam = _multipliers(int(horizon), int(onset), float(level), thermal.decay)
                rows.append(weights)
                lams.append(lam)
        maxima = _path_maxima(reward, heat, int(cells_per_step), np.array(rows))
        free.append(_path_maxima(reward, heat, int(cells_per_step), np.zeros((1, int(horizon))))[0])
        values.append(maxima)
        sums.append(np.array(lams))
    return HeatedCeiling(horizons, np.array(free), np.array(values), np.array(sums))


@dataclass(frozen=True)
class HeatedFloor:
    """The floor of :func:`heated_floor`: ``value`` (A/m), the RMS over the scored steps and the prior;
    ``per_step`` ((A/m)^2, one per scored step); ``pieces`` the start temperatures (K) at the centres of
    the prior's pieces, ``weights`` their w_k (summing to ``prior_mass``, 1 up to quadrature),
    ``piece_fisher`` their J_k (1/(A/m)^2), ``piece_floor`` (A/m) the RMS bound within each piece;
    ``hottest_start`` (A/m): the same floor as if every start were the hottest of the prior (what an
    input that must be safe for every start faces; not a bound on feedback); ``free`` (A/m): the floor
    with the heat budget dropped; ``overheat_margin``: the smallest ratio of ``e_over^2 - (2 d_a)^2`` to
    the largest marginal gain of overheating ``I_free/(J_k + I_k)^2`` (> 1: overheating never pays)."""

    value: float
    per_step: np.ndarray
    pieces: np.ndarray
    weights: np.ndarray
    piece_fisher: np.ndarray
    piece_floor: np.ndarray
    prior_mass: float
    hottest_start: float
    free: float
    overheat_margin: float


def _prior_pieces(thermal: ThermalBudget, half_width: float, nodes: int = 4001):
    """The prior split by a partition of unity (module doc, point 3): raised-cosine bumps ``phi_k`` of half
    width d (K) centred every d from ``start_low`` to ``start_high`` (summing to 1 there), pieces
    ``p_k = p*phi_k/w_k``, ``w_k = integral p*phi_k`` (summing to 1). Returns the centres (K), the weights,
    the coolest start of each piece (K) and each piece's location Fisher information in a (1/(A/m)^2,
    by the midpoint rule on ``nodes`` points: ``integral (p_k')^2/p_k``)."""
    low, high = thermal.start_low, thermal.start_high
    width = high - low
    count = int(round(width / half_width))
    if count < 2 or abs(width / half_width - count) > 1e-9:
        raise ValueError(f"heated_floor: piece_half_width {half_width!r} K must divide the prior's width "
                         f"{width:g} K at least twice")
    centres = low + half_width * np.arange(count + 1)
    u = (np.arange(nodes) + 0.5) / nodes  # midpoints over each piece's support
    weights, coolest, fisher = [], [], []
    for centre in centres:
        start, stop = max(centre - half_width, low), min(centre + half_width, high)
        x = start + (stop - start) * u
        z = (x - low) / width
        density = (1.0 - np.cos(2.0 * np.pi * z)) / width
        slope = 2.0 * np.pi * np.sin(2.0 * np.pi * z) / width ** 2
        angle = np.pi * (x - centre + half_width) / half_width
        bump = 0.5 * (1.0 - np.cos(angle))
        bump_slope = 0.5 * np.pi / half_width * np.sin(angle)
        mass = density * bump
        step = (stop - start) / nodes
        weight = float(np.sum(mass) * step)
        score_squared = (slope * bump + density * bump_slope) ** 2 / mass
        weights.append(weight)
        coolest.append(start)
        fisher.append(float(np.sum(score_squared) * step) / weight / thermal.a_per_kelvin ** 2)
    return centres, np.array(weights), np.array(coolest), np.array(fisher)


def heated_floor(setting: BoundSetting, ceiling: HeatedCeiling, thermal: ThermalBudget, first_step: int,
                 overheat_error: float, piece_half_width: float = 1.0) -> HeatedFloor:
    """Floor (A/m) on the RMS error over steps ``first_step + 1 .. setting.steps`` and the start prior of any
    estimate under any input, adaptive or not (module doc, point 3): ``sqrt(mean_t sum_k w_k/(J_k + I_k,t))``
    with ``I_k,t = G^2/sigma^2 * ceiling`` at the budget of the piece's coolest start, the ceiling of a
    horizon taken at the next horizon computed (the information only grows). ``overheat_error`` (A/m):
    what the metric counts per step after an overheat (width(Theta)); ``piece_half_width`` (K)."""
    if not 0 <= first_step < setting.steps:
        raise ValueError(f"heated_floor: first_step must be in [0, {setting.steps}), got {first_step!r}")
    if not piece_half_width > 0:
        raise ValueError(f"heated_floor: piece_half_width must be > 0 K, got {piece_half_width!r}")
    steps = np.arange(first_step + 1, setting.steps + 1)
    horizons = ceiling.horizons
    if horizons.max() < setting.steps:
        raise ValueError(f"heated_floor: the ceiling's horizons end at {horizons.max()}, before step {setting.steps}")
    column = np.searchsorted(horizons, steps)  # the first horizon at or after each step
    scale = setting.gain ** 2 / setting.sigma ** 2
    centres, weights, coolest, fishers = _prior_pieces(thermal, piece_half_width)
    half_a = piece_half_width * thermal.a_per_kelvin
    free = scale * ceiling.free[column]
    per_step = np.zeros(steps.size)
    piece_floor, margins = [], []
    for weight, start, piece_fisher in zip(weights, coolest, fishers):
        info = scale * ceiling.at(thermal.temperature_limit - start)[column]
        bound = 1.0 / (piece_fisher + info)
        per_step += weight * bound
        piece_floor.append(math.sqrt(float(np.mean(bound))))
        margins.append((overheat_error ** 2 - (2 * half_a) ** 2) / float(np.max(free * bound ** 2)))
    hottest = scale * ceiling.at(thermal.temperature_limit - thermal.start_high)[column]
    prior_fisher = raised_cosine_fisher((thermal.start_high - thermal.start_low) * thermal.a_per_kelvin)
    return HeatedFloor(math.sqrt(float(np.mean(per_step))), per_step, centres, weights, fishers, np.array(piece_floor),
                       float(weights.sum()), math.sqrt(float(np.mean(1.0 / (prior_fisher + hottest)))),
                       math.sqrt(float(np.mean(1.0 / (prior_fisher + free)))), float(min(margins)))


#: the piece half widths (K) :func:`calibration_heated_floor` tries (each gives a valid floor; it keeps the highest)
PIECE_HALF_WIDTHS = (0.5, 1.0, 2.0, 4.0)


@dataclass(frozen=True)
class CalibrationFloor:
    """What :func:`calibration_heated_floor` returns: ``floor`` (over the scored steps) and ``whole_episode``
    (over every step), each a :class:`HeatedFloor` at its best piece half width (K, ``piece_half_width``
    and ``whole_episode_half_width``), with the ``envelope`` and ``ceiling`` they stand on."""

    floor: HeatedFloor
    piece_half_width: float
    whole_episode: HeatedFloor
    whole_episode_half_width: float
    envelope: CurrentFieldEnvelope
    ceiling: HeatedCeiling


def _best_floor(setting, ceiling, thermal, first_step, overheat_error, half_widths):
    width = thermal.start_high - thermal.start_low
    usable = [w for w in half_widths if abs(width / w - round(width / w)) < 1e-9 and round(width / w) >= 2]
    if not usable:
        raise ValueError(f"calibration_heated_floor: no piece half width in {half_widths} divides the prior's "
                         f"width {width:g} K at least twice")
    floors = [(heated_floor(setting, ceiling, thermal, first_step, overheat_error, w), w) for w in usable]
    return max(floors, key=lambda pair: pair[0].value)


def calibration_heated_floor(params_list, setting: BoundSetting, thermal: ThermalBudget, max_field_step: float,
                             first_step: int, overheat_error: float, n_paths: int = 256, n_a: int = 5, seed: int = 0,
                             cells_per_step: int = 4, horizon_stride: int = 5,
                             half_widths=PIECE_HALF_WIDTHS) -> CalibrationFloor:
    """The floor of a calibration task with the field, slew and heat limits all kept (module doc).

    ``params_list``: the models the envelope covers (:class:`~hyst_gym.physics.HysteresisParams`; several
    when a nuisance such as k is unknown: the largest over them); ``setting``: noise, gain, limits and
    steps (its ``a_lo``/``a_hi`` are not used: the prior is ``thermal``'s); ``max_field_step`` (A/m): the
    hysteresis substep; ``first_step``: the scored steps are ``first_step + 1 .. setting.steps``;
    ``overheat_error`` (A/m): the error the metric counts per step after an overheat; ``n_paths``
    random histories per set and model (seed ``seed``) at ``n_a`` values of a; the ceiling on a grid of
    ``max_change/cells_per_step`` A/m at every ``horizon_stride``-th step; ``half_widths``: the piece half
    widths (K) tried, the highest floor kept (each is valid).

    Caveat (what the envelope, being sampled at ``n_a`` values of a, does not hold): a small dither about
    a level, tuned to the true a to within a few A/m, can make ``|dM/da|`` jump for one step near a switch
    of model (6)'s irreversible branch (:func:`structured_admissible_fields`); an input that knew a that
    well and produced such steps over and over could collect more than the ceiling. No agent of the suite
    does; a bound that admits them would need the prior-averaged, not the pointwise, sensitivity."""
    if not 0 <= first_step < setting.steps:
        raise ValueError(f"calibration_heated_floor: first_step must be in [0, {setting.steps}), got {first_step!r}")
    a_range = (thermal.a_per_kelvin * thermal.start_low, thermal.a_per_kelvin * thermal.temperature_limit)
    envelope = current_field_envelope(params_list, a_range, setting.field_limit, setting.max_change, max_field_step,
                                      setting.max_change / cells_per_step, n_a=n_a, n_paths=n_paths,
                                      steps=setting.steps, seed=seed)
    horizons = np.unique(np.append(np.arange(horizon_stride, setting.steps, horizon_stride), setting.steps))
    ceiling = heated_information_ceiling(envelope, thermal, setting.max_change, horizons, cells_per_step)
    floor, width = _best_floor(setting, ceiling, thermal, first_step, overheat_error, half_widths)
    whole, whole_width = _best_floor(setting, ceiling, thermal, 0, overheat_error, half_widths)
    return CalibrationFloor(floor, width, whole, whole_width, envelope, ceiling)


__all__ = ["BoundSetting", "CalibrationFloor", "CurrentFieldEnvelope", "HeatedCeiling", "HeatedFloor",
           "PIECE_HALF_WIDTHS", "SensitivityTable", "ThermalBudget", "calibration_heated_floor",
           "current_field_envelope", "episode_floor", "heated_floor", "heated_information_ceiling",
           "information_ceiling", "magnetization_sensitivity", "random_admissible_fields", "raised_cosine_fisher",
           "raised_cosine_quantile", "sensitivity_table", "structured_admissible_fields", "van_trees_mse"]
