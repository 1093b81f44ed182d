"""A receding-horizon information-maximizing input: the adaptive non-RL baseline.

At every control step the agent tries a few constant slew rates
``u*slew_max`` (u in ``directions``) held for ``horizon`` steps and applies the first
step of the one that collects the most Fisher information about a at the current
estimate, ``sum_j (dy_j/da)^2`` (see :mod:`baselines.information`). It then replans
(receding horizon). The sensitivity is evaluated on its own model bank over a grid of a
across Theta, driven by the fields it has applied: ``dM/da`` at the estimate is the
slope of the piecewise-linear interpolant of the bank, and ``dy/da`` follows by the
first-order plant. The estimate comes from the observation through ``estimate_of``
(the env's built-in estimator); without one it plans at the nominal a.
"""

from __future__ import annotations

import numpy as np

from hyst_gym.physics import FirstOrderPlant, HysteresisParams
from hyst_gym.physics.hysteresis import DEFAULT_MAX_FIELD_STEP, advance_each

from .agents import Agent
from .information import zero_order_hold
from .schedules import ExcitationLimits

#: the default models of the signatures below (frozen dataclasses: one shared instance is safe)
DEFAULT_HYSTERESIS = HysteresisParams()
DEFAULT_PLANT = FirstOrderPlant()


class GreedyInformationAgent(Agent):
    """See module doc. ``theta`` = (low, high) bounds of a in A/m; ``nominal_a`` in A/m."""

    name = "greedy_info"

    def __init__(self, limits: ExcitationLimits, theta=(6300.0, 7300.0), nominal_a=7012.0,
                 params: HysteresisParams = DEFAULT_HYSTERESIS, plant: FirstOrderPlant = DEFAULT_PLANT,
                 grid_size: int = 5, horizon: int = 5, directions=(-1.0, -0.5, 0.0, 0.5, 1.0),
                 estimate_of=None, max_field_step: float = 4 * DEFAULT_MAX_FIELD_STEP):
        super().__init__()
        self.limits, self.params, self.plant = limits, params, plant
        self.a_grid = np.linspace(theta[0], theta[1], int(grid_size))
        self.nominal_a = float(nominal_a)
        self.horizon, self.directions = int(horizon), np.asarray(directions, dtype=np.float64)
        self.estimate_of = estimate_of
        self.max_field_step = float(max_field_step)
        self._pole, self._gain = zero_order_hold(plant, limits.dt)
        self._n = 0

    def _init(self, n):
        self._n = n
        self._field = np.zeros(n)
        self._bank = np.zeros((n, self.a_grid.size))
        self._sensitivity = np.zeros(n)

    def _slope_at(self, bank, estimate):
        index = np.clip(np.searchsorted(self.a_grid, estimate) - 1, 0, self.a_grid.size - 2)
        rows = np.arange(bank.shape[0])
        return (bank[rows, index + 1] - bank[rows, index]) / (self.a_grid[index + 1] - self.a_grid[index])

    def _advance(self, bank, field_from, field_to):
        n, k = bank.shape
        flat = bank.reshape(-1).copy()
        p = self.params
        ones = np.ones(n * k)
        advance_each(flat, np.repeat(field_from, k), np.repeat(field_to, k), np.tile(self.a_grid, n),
                     p.k * ones, p.alpha * ones, p.Ms * ones, p.c * ones, p.kind, self.max_field_step)
        return flat.reshape(n, k)

    def act_batch(self, observations, episode_start):
        n = observations.shape[0]
        if self._n != n:
            self._init(n)
        if np.any(episode_start):
            self._field[episode_start] = 0.0
            self._bank[episode_start] = 0.0
            self._sensitivity[episode_start] = 0.0
        if self.estimate_of is None:
            estimate = np.full(n, self.nominal_a)
        else:
            estimate = np.clip(np.asarray(self.estimate_of(observations), dtype=np.float64).reshape(n),
                               self.a_grid[0], self.a_grid[-1])
        step = self.limits.max_field_change
        scores = np.empty((self.directions.size, n))
        for c, u in enumerate(self.directions):
            field, bank, sensitivity = self._field.copy(), self._bank, self._sensitivity.copy()
            total = np.zeros(n)
            for _ in range(self.horizon):
                target = np.clip(field + u * step, -self.limits.field_max, self.limits.field_max)
                bank = self._advance(bank, field, target)
                field = target
                sensitivity = self._pole * sensitivity + self._gain * self._slope_at(bank, estimate)
                total += sensitivity ** 2
            scores[c] = total
        # Ties (e.g. a flat start) go to the largest upward slew, so the agent never stalls at H = 0.
        best = np.argmax(scores + 1e-12 * self.directions[:, None], axis=0)
        target = np.clip(self._field + self.directions[best] * step, -self.limits.field_max, self.limits.field_max)
        new_bank = self._advance(self._bank, self._field, target)
        self._sensitivity = self._pole * self._sensitivity + self._gain * self._slope_at(new_bank, estimate)
        self._bank, self._field = new_bank, target
        return (target / self.limits.field_max).reshape(n, 1).astype(np.float32)


__all__ = ["GreedyInformationAgent"]
