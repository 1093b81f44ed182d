"""The agent interface shared by every baseline and by trained RL policies.

An agent has ``reset(seed)`` and ``act(observation) -> action`` for one environment,
and ``predict(observation, state, episode_start, deterministic) -> (actions, state)``
for a batch, which is the ``PolicyPredictor`` protocol of Stable-Baselines3, so any
agent can be passed to ``stable_baselines3.common.evaluation.evaluate_policy``.

Agents that follow a schedule need time: they count control steps since the start of
their episode (``episode_start`` resets the count of that sub-environment), so they
never read time from the observation.
"""

from __future__ import annotations

import numpy as np

from .schedules import ExcitationLimits, Schedule


class Agent:
    """Base class. Subclasses implement :meth:`act_batch`."""

    name = "agent"

    def __init__(self):
        self._seed = None
        self._n_envs = 0

    def reset(self, seed=None) -> None:
        """Start a new episode (all sub-environments); ``seed`` seeds any randomness."""
        self._seed = seed
        self._n_envs = 0

    def act_batch(self, observations: np.ndarray, episode_start: np.ndarray) -> np.ndarray:
        raise NotImplementedError  # pragma: no cover

    def act(self, observation) -> np.ndarray:
        """Action for one environment's observation."""
        observation = np.asarray(observation, dtype=np.float64)
        start = np.array([self._n_envs == 0])
        self._n_envs = 1
        return self.act_batch(observation[None], start)[0]

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """SB3 ``PolicyPredictor``: batched actions for a ``VecEnv`` observation."""
        observation = np.asarray(observation, dtype=np.float64)
        batched = observation.ndim >= 2
        observations = observation if batched else observation[None]
        n = observations.shape[0]
        if episode_start is None:
            episode_start = np.zeros(n, dtype=bool) if self._n_envs == n else np.ones(n, dtype=bool)
        episode_start = np.asarray(episode_start, dtype=bool).reshape(n)
        if self._n_envs != n:
            episode_start = np.ones(n, dtype=bool)
            self._n_envs = n
        actions = self.act_batch(observations, episode_start)
        return (actions if batched else actions[0]), state


class ScheduleAgent(Agent):
    """Plays a :class:`~baselines.schedules.Schedule`, normalized by ``limits.field_max``.

    The action is the field command ``H/field_max`` in [-1, 1] at the control instants
    ``dt, 2*dt, ...`` after each episode start, already slew-limited by
    :func:`~baselines.schedules.apply_limits`.
    """

    def __init__(self, schedule: Schedule, limits: ExcitationLimits, horizon_steps: int, name=None):
        super().__init__()
        self.schedule = schedule
        self.limits = limits
        self.name = name or schedule.name
        self._commands = schedule.sampled(horizon_steps, limits) / limits.field_max
        self._steps = np.zeros(0, dtype=np.int64)

    def reset(self, seed=None):
        super().reset(seed)
        self._steps = np.zeros(0, dtype=np.int64)

    def act_batch(self, observations, episode_start):
        n = observations.shape[0]
        if self._steps.shape[0] != n:
            self._steps = np.zeros(n, dtype=np.int64)
        self._steps[episode_start] = 0
        index = np.minimum(self._steps, self._commands.shape[0] - 1)
        self._steps += 1
        return self._commands[index].reshape(n, 1).astype(np.float32)


class ConstantAgent(Agent):
    """Always returns the same action (used for ``Estimation-v0`` no-op checks and tests)."""

    def __init__(self, action, name="constant"):
        super().__init__()
        self.action = np.asarray(action, dtype=np.float32).ravel()
        self.name = name

    def act_batch(self, observations, episode_start):
        return np.tile(self.action, (observations.shape[0], 1))


__all__ = ["Agent", "ScheduleAgent", "ConstantAgent"]
