"""Two simple references of the calibration tasks, sized from the thermal model (no search):

* :class:`RampHold` (open loop): ramp to a peak field at the slew limit, hold it, then back to zero,
  the hold as long as the *hottest* start of the task's prior allows without passing the temperature
  limit (less a margin), from the lumped thermal model the env integrates (:func:`safe_hold_steps`). It is
  worst-case safe by construction: no start of the prior overheats.
* :class:`BangHold` (feedback): drive the full field at the slew limit while the coil, braked now, would
  stay a margin below the limit; then hold the field whose Joule heating balances the cooling at the rise
  reached. The coil's rise above its ambient is a known function of the input (the ambient equals the start
  temperature and does not drift), so the rule integrates it itself; the start temperature it reads from the
  estimator (a is proportional to T, eq. (4)): the estimate plus two posterior standard deviations, less the
  rise. "Braked now": the rise the coil still gains while the field slews down from where it is, which peaks
  where the falling field meets the hold field.

Both play through :class:`~baselines.suite_agents.DesignBank`-like ``act_batch`` (the field only), on the
tasks' estimator-in-the-loop envs.
"""

from __future__ import annotations

import numpy as np

from hyst_gym.physics.thermal import mean_square_linear

from .agents import Agent
from .schedules import Schedule

#: K below the temperature limit that the hottest start of the prior may reach (the references' margin)
SAFETY_MARGIN = 1.0


def _slewed(target, steps: int, step_change: float, hold_steps: int) -> np.ndarray:
    """Field at the end of each step: up to ``target`` at ``step_change`` per step, held for ``hold_steps``
    steps after reaching it, then down to 0 at the slew limit, then 0 (A/m, ``steps`` values)."""
    field = np.zeros(steps)
    h, held = 0.0, 0
    for k in range(steps):
        if h < target and held == 0:
            h = min(target, h + step_change)
            if h >= target:
                held = 1
        elif held and held <= hold_steps:
            held += 1
        else:
            h = max(0.0, h - step_change)
        field[k] = h
    return field


def peak_temperature(config, field: np.ndarray, start: float) -> float:
    """The highest coil temperature (K) along ``field`` (A/m at the end of each step, from 0) from ``start``,
    the ambient equal to it and constant: the lumped thermal model the env integrates exactly per step."""
    thermal = config.thermal
    decay = np.exp(-config.dt / thermal.time_constant)
    temperature, previous, peak = start, 0.0, start
    for h in field:
        offset = thermal.thermal_resistance * thermal.power_per_square_field * mean_square_linear(previous, h)
        temperature = (start + offset) + (temperature - (start + offset)) * decay
        previous = h
        peak = max(peak, temperature)
    return peak


def safe_hold_steps(config, peak: float, margin: float = SAFETY_MARGIN) -> int:
    """The longest hold (steps) of a ramp to ``peak`` A/m that keeps the hottest start of the prior
    (``initial_temperature_range[1]``) at least ``margin`` K below the temperature limit (0: the ramp alone
    is too hot; the ramp then is not safe and a ValueError says so)."""
    hottest = config.initial_temperature_range[1]
    ceiling = config.temperature_limit - margin
    steps = config.episode_steps

    def safe(hold):
        return peak_temperature(config, _slewed(peak, steps, config.max_field_change, hold), hottest) <= ceiling

    if not safe(0):
        raise ValueError(f"a ramp to {peak:g} A/m overheats the hottest start ({hottest:g} K) even without a hold")
    low, high = 0, steps
    while low < high:  # the peak temperature grows with the hold: bisect the longest safe one
        middle = (low + high + 1) // 2
        low, high = (middle, high) if safe(middle) else (low, middle - 1)
    return low


class RampHold(Schedule):
    """Ramp to ``peak`` A/m at the slew limit, hold for ``hold_steps`` steps, then back to 0 (a schedule of
    the step-end times ``k*dt``, k = 1, 2, ...; :func:`safe_hold_steps` sizes the hold)."""

    def __init__(self, peak: float, hold_steps: int, step_change: float, dt: float, steps: int):
        self.peak, self.hold_steps = float(peak), int(hold_steps)
        self._dt = float(dt)
        self._field = _slewed(self.peak, int(steps), float(step_change), self.hold_steps)

    def field(self, time):
        index = np.clip(np.round(np.asarray(time) / self._dt).astype(np.int64) - 1, 0, self._field.shape[0] - 1)
        return self._field[index]

    def __repr__(self):
        return f"RampHold(peak={self.peak:g}, hold_steps={self.hold_steps})"


def ramp_hold(config, peak: float, margin: float = SAFETY_MARGIN) -> RampHold:
    """The worst-case-safe ramp-and-hold of a task's config to ``peak`` A/m (module doc)."""
    return RampHold(peak, safe_hold_steps(config, peak, margin), config.max_field_change, config.dt,
                    config.episode_steps)


class BangHold(Agent):
    """The bang-hold feedback rule (module doc): ``estimate_index`` is the observation column of the estimate
    of a (mapped from Theta onto [-1, 1]); ``margin`` K below the limit it stops the bang and holds."""

    def __init__(self, config, estimate_index: int, margin: float = 2.0, name: str = "bang_hold",
                 spread_index: int | None = None):
        super().__init__()
        self.config = config
        self.estimate_index = int(estimate_index)
        self.spread_index = spread_index
        self.margin = float(margin)
        self.name = name
        self.reads_truth = False
        thermal = config.thermal
        self._decay = np.exp(-config.dt / thermal.time_constant)
        self._gain = thermal.thermal_resistance * thermal.power_per_square_field  # K per (A/m)^2 at steady state
        self._rise = np.zeros(0)
        self._field = np.zeros(0)
        self._holding = np.zeros(0, dtype=bool)

    def reset(self, seed=None):
        super().reset(seed)
        self._rise = np.zeros(0)

    def act_batch(self, observations, episode_start):
        config = self.config
        n = observations.shape[0]
        if self._rise.shape[0] != n:
            self._rise, self._field, self._holding = np.zeros(n), np.zeros(n), np.zeros(n, dtype=bool)
        start = np.asarray(episode_start, dtype=bool)
        self._rise[start], self._field[start], self._holding[start] = 0.0, 0.0, False
        estimate = config.theta_min + 0.5 * (observations[:, self.estimate_index] + 1.0) * config.theta_width
        if self.spread_index is not None:  # a cautious start temperature: two standard deviations warmer
            estimate = estimate + 2.0 * observations[:, self.spread_index] * config.theta_width
        start_temperature = config.temperature_for_a(estimate) - self._rise
        self._holding |= start_temperature + self._braked_rise() >= config.temperature_limit - self.margin
        # the field whose heating keeps the rise above the ambient where it is: R*P(H) = rise
        hold = np.sqrt(np.maximum(self._rise, 0.0) / self._gain)
        target = np.where(self._holding, np.minimum(hold, config.field_limit), config.field_limit)
        step = config.max_field_change
        field = np.clip(target, self._field - step, self._field + step)
        power = mean_square_linear(self._field, field)
        self._rise = self._gain * power + (self._rise - self._gain * power) * self._decay
        self._field = field
        return (field / config.field_limit)[:, None].astype(np.float32)

    def _braked_rise(self) -> np.ndarray:
        """The highest rise (K) if the field slews down to 0 from now on (module doc)."""
        step = self.config.max_field_change
        field, rise = self._field.copy(), self._rise.copy()
        peak = rise.copy()
        while np.any(field > 0):
            lower = np.maximum(field - step, 0.0)
            power = mean_square_linear(field, lower)
            rise = self._gain * power + (rise - self._gain * power) * self._decay
            peak = np.maximum(peak, rise)
            field = lower
        return peak


__all__ = ["SAFETY_MARGIN", "BangHold", "RampHold", "peak_temperature", "ramp_hold", "safe_hold_steps"]
