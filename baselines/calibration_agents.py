"""Agents of suite v2's calibration tasks (``hyst_gym.envs.suite_v2``): a field design plus the
Bayes estimate of a from a grid posterior over the start temperature.

In the calibration tasks the only unknown is the start temperature T0 (the ambient equals it and
does not drift, so the heating is known from the field), and the agent reports a every step. The
best estimate given the data is then the posterior over T0: :class:`PosteriorCalibration` runs,
for every sub-environment, a noise-free copy of the task's simulator per grid node of T0 (the
same compiled kernels, driven by the same field commands), scores each node by the Gaussian
log-likelihood of the measured normalized outputs (noise ``output_noise``), adds the
raised-cosine log-prior and reports

* the posterior mean of a while the posterior is spread over several nodes, and
* the vertex of a parabola through the log-posterior at the best node and its neighbours once one
  node holds more than half the mass (the grid spacing, 0.6 K or 15 A/m at 64 nodes, would
  otherwise limit the error).

The field comes from another agent (a :class:`~baselines.suite_agents.DesignBank`), which sees the
observation with the previous estimate, so a thermostat design can read the temperature from it.
The estimate reported with the action of step t predicts a at the end of step t from the outputs
up to step t - 1 (the heating of step t is known from the command).
"""

from __future__ import annotations

import numpy as np

from .agents import Agent

#: grid nodes of the start temperature per sub-environment
POSTERIOR_NODES = 64
#: a node holding more than this posterior mass switches the estimate to the parabola vertex
CONCENTRATED = 0.5


class PosteriorCalibration(Agent):
    """``field_agent``'s field, and the grid-posterior estimate of a (module doc).

    ``task_id``: a calibration task of :data:`hyst_gym.envs.suite_v2.TASKS_V2`; ``nodes``: grid
    nodes over the task's start temperatures (K)."""

    def __init__(self, field_agent: Agent, task_id: str, nodes: int = POSTERIOR_NODES, name: str | None = None):
        super().__init__()
        from hyst_gym.envs.suite_v2 import TASKS_V2, task_config_v2

        if TASKS_V2.get(task_id, {}).get("kind") != "calibrate":
            raise ValueError(f"PosteriorCalibration needs a calibration task, got {task_id!r}")
        self.field_agent = field_agent
        self.config = task_config_v2(task_id)
        self.nodes = int(nodes)
        self.name = name or f"{field_agent.name}+posterior"
        hidden = TASKS_V2[task_id]["sensors"] or ()
        outputs = ["displacement", "velocity"] if self.config.is_mechanical else ["output"]
        self.channels = [i for i, name in enumerate(outputs) if name not in hidden]  # == observation columns
        low, high = self.config.initial_temperature_range
        self.node_temperature = low + (high - low) * (np.arange(self.nodes) + 0.5) / self.nodes
        self.log_prior = np.log(1.0 - np.cos(2 * np.pi * (np.arange(self.nodes) + 0.5) / self.nodes))
        self.reads_truth = False
        self._sim = None
        self._log_post = None

    def reset(self, seed=None):
        super().reset(seed)
        self.field_agent.reset(seed)
        self._sim = None

    def _ensure(self, n: int):
        from hyst_gym.envs.core import IDENTIFICATION, BatchSimulator

        if self._sim is None or self._sim.n != n * self.nodes:
            self._sim = BatchSimulator(self.config.replace(output_noise=0.0), IDENTIFICATION, n * self.nodes)
            for row in range(n * self.nodes):
                self._sim.set_generator(row, np.random.default_rng(row))
            self._log_post = np.zeros((n, self.nodes))

    def _restart(self, rows):
        sim, nodes = self._sim, self.nodes
        sub = (rows[:, None] * nodes + np.arange(nodes)[None, :]).ravel()
        sim.reset(sub)
        temperature = np.tile(self.node_temperature, rows.shape[0])
        sim.temperature[sub] = temperature
        sim.ambient0[sub] = temperature
        sim.a_true[sub] = self.config.a_of(temperature)
        self._log_post[rows] = self.log_prior

    def _update(self, observations, rows):
        sim, nodes = self._sim, self.nodes
        sigma = self.config.output_noise
        predicted = (sim.measured[:, self.channels] / sim.scales[self.channels]).reshape(-1, nodes, len(self.channels))
        measured = observations[:, :len(self.channels)].astype(np.float64)
        residual = measured[rows, None, :] - predicted[rows]
        self._log_post[rows] -= 0.5 * np.sum(residual ** 2, axis=2) / sigma ** 2

    def estimate(self) -> np.ndarray:
        """The current estimate of a per sub-environment (A/m), from the nodes' a after their last step."""
        log_post = self._log_post
        a_nodes = self._sim.a_true.reshape(-1, self.nodes)
        weights = np.exp(log_post - log_post.max(axis=1, keepdims=True))
        weights /= weights.sum(axis=1, keepdims=True)
        mean = (weights * a_nodes).sum(axis=1)
        best = np.clip(np.argmax(log_post, axis=1), 1, self.nodes - 2)
        rows = np.arange(log_post.shape[0])
        left, centre, right = (log_post[rows, best - 1], log_post[rows, best], log_post[rows, best + 1])
        curvature = left - 2 * centre + right
        offset = np.where(curvature < 0, 0.5 * (left - right) / np.where(curvature < 0, curvature, -1.0), 0.0)
        offset = np.clip(offset, -1.0, 1.0)
        spacing = a_nodes[rows, best + 1] - a_nodes[rows, best]
        vertex = a_nodes[rows, best] + offset * spacing
        return np.where(weights.max(axis=1) > CONCENTRATED, vertex, mean)

    def act_batch(self, observations, episode_start):
        n = observations.shape[0]
        self._ensure(n)
        starting = np.flatnonzero(episode_start)
        going = np.flatnonzero(~np.asarray(episode_start, dtype=bool))
        if going.size:
            self._update(observations, going)
        if starting.size:
            self._restart(starting)
        field = np.asarray(self.field_agent.act_batch(observations, episode_start), dtype=np.float64)[:, 0]
        commands = np.zeros((n * self.nodes, 2))
        commands[:, 0] = np.repeat(np.clip(field, -1.0, 1.0), self.nodes)
        self._sim.step(commands)
        config = self.config
        normalized = 2.0 * (self.estimate() - config.theta_min) / config.theta_width - 1.0
        return np.stack([field, np.clip(normalized, -1.0, 1.0)], axis=1).astype(np.float32)


__all__ = ["CONCENTRATED", "POSTERIOR_NODES", "PosteriorCalibration"]
