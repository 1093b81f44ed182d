"""Agents of suite v2's calibration tasks in the agent-reports track (:mod:`hyst_gym.envs.suite_v2`, option
``estimator="agent"``): a field design plus the Bayes estimate of a from the grid posterior
(:class:`hyst_gym.envs.posterior.GridPosterior`, the estimator the tasks' own envs run in the loop).

The field comes from another agent (a :class:`~baselines.suite_agents.DesignBank`), which sees the
observation with the previous estimate, so a thermostat design can read the temperature from it.
The estimate reported with the action of step t predicts a at the end of step t from the outputs
up to step t - 1 (the heating of step t is known from the command).
"""

from __future__ import annotations

import numpy as np

from hyst_gym.envs.posterior import CONCENTRATED, K_TASK_NODES, POSTERIOR_NODES, GridPosterior, grid_sizes

from .agents import Agent


class PosteriorCalibration(Agent):
    """``field_agent``'s field, and the grid-posterior estimate of a (module doc).

    ``task_id``: a calibration task of :data:`hyst_gym.envs.tasks.TASKS`; ``nodes``: grid
    nodes over the task's start temperatures (K), default :data:`POSTERIOR_NODES` (the first of
    :data:`K_TASK_NODES` on a task with a k prior); ``k_nodes``: grid nodes over k (A/m), 1 (the preset's
    k, assumed known) or >= 3 (over the task's k prior), default 1 without a k prior and the second of
    :data:`K_TASK_NODES` with one."""

    def __init__(self, field_agent: Agent, task_id: str, nodes: int | None = None, name: str | None = None,
                 k_nodes: int | None = None):
        super().__init__()
        from hyst_gym.envs.tasks import TASKS

        spec = TASKS.get(task_id)
        if spec is None or not spec.calibrates:
            raise ValueError(f"PosteriorCalibration needs a calibration task, got {task_id!r}")
        k_prior = spec.k_prior
        nodes, k_nodes = grid_sizes(k_prior, nodes, k_nodes)
        self.field_agent = field_agent
        self.config = spec.env_config()
        self.k_prior = k_prior
        self.nodes = int(nodes)
        self.k_nodes = int(k_nodes)
        self.name = name or f"{field_agent.name}+posterior"
        hidden = spec.sensors_hidden
        outputs = ["displacement", "velocity"] if self.config.is_mechanical else ["output"]
        self.channels = [i for i, name in enumerate(outputs) if name not in hidden]  # == observation columns
        self.reads_truth = False
        self._posterior = None

    def reset(self, seed=None):
        super().reset(seed)
        self.field_agent.reset(seed)
        self._posterior = None

    def _ensure(self, n: int):
        if self._posterior is None or self._posterior.n != n:
            self._posterior = GridPosterior(self.config, self.channels, n, self.k_prior, self.nodes, self.k_nodes)

    def estimate(self) -> np.ndarray:
        """The current estimate of a per sub-environment (A/m): :meth:`GridPosterior.estimate`."""
        return self._posterior.estimate()

    def act_batch(self, observations, episode_start):
        n = observations.shape[0]
        self._ensure(n)
        starting = np.flatnonzero(episode_start)
        going = np.flatnonzero(~np.asarray(episode_start, dtype=bool))
        if going.size:
            self._posterior.update(observations[:, :len(self.channels)].astype(np.float64), going)
        if starting.size:
            self._posterior.restart(starting)
        field = np.asarray(self.field_agent.act_batch(observations, episode_start), dtype=np.float64)[:, 0]
        self._posterior.step(field)
        config = self.config
        normalized = 2.0 * (self.estimate() - config.theta_min) / config.theta_width - 1.0
        return np.stack([field, np.clip(normalized, -1.0, 1.0)], axis=1).astype(np.float32)


__all__ = ["CONCENTRATED", "K_TASK_NODES", "POSTERIOR_NODES", "PosteriorCalibration"]
