"""The adaptive estimators as agents of ``Estimation-v0``.

In ``Estimation-v0`` the excitation is the environment's schedule (the paper's ramp by
default) and the action is the estimate of a, normalized to Theta. The agent decodes
the measured output and the applied field from the observation (with the environment's
own scales), runs one of the estimation layer's batched estimators on them -- min-max
(14)-(15), gradient, or the multiple-model estimator -- with exactly the settings of the
environment's built-in estimator, and returns its estimate.

Timing: the estimate sent with the action of step k+1 uses the measurements up to step k
(the agent cannot see the future output), so the estimate lags the built-in estimator of
``Excitation-v0`` by one control period.
"""

from __future__ import annotations

import numpy as np

from .agents import Agent
from .observation import observation_index


class EstimatorAgent(Agent):
    """``estimator_name`` in ``minmax``, ``gradient``, ``multiple_model``."""

    def __init__(self, estimator_name: str, scenario):
        from hyst_gym.envs.core import estimator_config, output_scales
        from hyst_gym.estimation import ESTIMATORS

        super().__init__()
        if estimator_name not in ESTIMATORS:
            raise ValueError(f"unknown estimator {estimator_name!r}; expected one of {sorted(ESTIMATORS)}")
        self.name = estimator_name
        self.config = scenario.env_config
        self.est_config = estimator_config(self.config)
        self.scales = output_scales(self.config, self.config.transducer.discretize(self.config.dt))
        self.n_outputs = self.scales.shape[0]
        self.field_index = observation_index(scenario, "field", "estimation")
        self._estimator = None

    def reset(self, seed=None):
        super().reset(seed)
        self._estimator = None

    def act_batch(self, observations, episode_start):
        from hyst_gym.estimation import make_estimator

        observations = np.asarray(observations, dtype=np.float64)
        n = observations.shape[0]
        episode_start = np.asarray(episode_start, dtype=bool).copy()
        if self._estimator is None or self._estimator.n_systems != n:
            self._estimator = make_estimator(self.name, self.est_config, n)
            episode_start[:] = True
        measured = observations[:, :self.n_outputs] * self.scales
        if not self.config.is_mechanical:
            measured = measured[:, 0]
        field = observations[:, self.field_index] * self.config.field_limit
        running = ~episode_start
        if running.any():
            # estimators step all systems together; restarted rows are reset right after
            self._estimator.update(field, measured, self.config.dt)
        rows = np.flatnonzero(episode_start)
        if rows.size:
            self._estimator.reset(a_estimate=self.config.initial_estimate, field=field[rows],
                                  output=measured[rows], magnetization=0.0, indices=rows)
        estimate = self._estimator.a_estimate
        action = 2.0 * (estimate - self.config.theta_min) / self.config.theta_width - 1.0
        return np.clip(action, -1.0, 1.0).reshape(n, 1).astype(np.float32)


__all__ = ["EstimatorAgent"]
