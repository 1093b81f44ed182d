"""Agents of suite v2's calibration tasks (:mod:`hyst_gym.envs.suite_v2`): a field design plus the
Bayes estimate of a from a grid posterior over the start temperature.

In most calibration tasks the only unknown is the start temperature T0 (the ambient equals it and
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

In the "several unknowns" task (a task with a ``k_prior``) the pinning constant k is unknown too. With
``k_nodes`` >= 3 the grid is (T0, k): k nodes at the midpoints of equal cells of its uniform prior (flat
log-prior), the posterior mean of a *marginalizes* k, and the concentrated estimate is the vertex of a
quadratic through the log-posterior's 3 x 3 neighbourhood of the best node (a in its T0 coordinate).
With ``k_nodes`` = 1 the posterior *assumes the nominal k* of the preset (a misspecified, weaker
estimator where k is drawn).

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
#: grid nodes (start temperature, k) per sub-environment on a task with a k prior
K_TASK_NODES = (24, 9)


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
        if nodes is None:
            nodes = POSTERIOR_NODES if k_prior is None else K_TASK_NODES[0]
        if k_nodes is None:
            k_nodes = 1 if k_prior is None else K_TASK_NODES[1]
        if isinstance(k_nodes, bool) or not isinstance(k_nodes, (int, np.integer)) or k_nodes == 2 or k_nodes < 1 \
                or (k_nodes > 1 and k_prior is None):
            raise ValueError(f"k_nodes must be 1 or (on a task with a k prior) an integer >= 3, got {k_nodes!r}")
        self.field_agent = field_agent
        self.config = spec.env_config()
        self.nodes = int(nodes)
        self.k_nodes = int(k_nodes)
        self.node_k = np.array([self.config.hysteresis.k]) if k_nodes == 1 else k_prior.nodes(self.k_nodes)
        self.name = name or f"{field_agent.name}+posterior"
        hidden = spec.sensors_hidden
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

        per = self.nodes * self.k_nodes
        if self._sim is None or self._sim.n != n * per:
            self._sim = BatchSimulator(self.config.replace(output_noise=0.0), IDENTIFICATION, n * per)
            for row in range(n * per):
                self._sim.set_generator(row, np.random.default_rng(row))
            self._sim.set_pinning(np.arange(n * per), np.tile(self.node_k, n * self.nodes))
            self._log_post = np.zeros((n, self.nodes, self.k_nodes))

    def _restart(self, rows):
        sim, per = self._sim, self.nodes * self.k_nodes
        sub = (rows[:, None] * per + np.arange(per)[None, :]).ravel()
        # every node simulator starts at its grid node's temperature (the reset option, one value per row)
        sim.reset(sub, {"initial_temperature": np.tile(np.repeat(self.node_temperature, self.k_nodes), rows.shape[0])})
        self._log_post[rows] = self.log_prior[:, None]

    def _update(self, observations, rows):
        sim = self._sim
        sigma = self.config.output_noise
        predicted = (sim.measured[:, self.channels] / sim.scales[self.channels]).reshape(
            -1, self.nodes, self.k_nodes, len(self.channels))
        measured = observations[:, :len(self.channels)].astype(np.float64)
        residual = measured[rows, None, None, :] - predicted[rows]
        self._log_post[rows] -= 0.5 * np.sum(residual ** 2, axis=3) / sigma ** 2

    def estimate(self) -> np.ndarray:
        """The current estimate of a per sub-environment (A/m), from the nodes' a after their last step
        (module doc: the posterior mean, or the vertex once one node holds most of the mass)."""
        joint = self._log_post
        a_nodes = self._sim.a_true.reshape(-1, self.nodes, self.k_nodes)[:, :, 0]  # a depends on T0 only
        peak = joint.max(axis=2)  # the log-posterior marginal over k (itself when k is one node)
        log_post = peak + np.log(np.exp(joint - peak[:, :, None]).sum(axis=2))
        weights = np.exp(log_post - log_post.max(axis=1, keepdims=True))
        weights /= weights.sum(axis=1, keepdims=True)
        mean = (weights * a_nodes).sum(axis=1)
        best = np.clip(np.argmax(log_post, axis=1), 1, self.nodes - 2)
        rows = np.arange(log_post.shape[0])
        left, centre, right = (log_post[rows, best - 1], log_post[rows, best], log_post[rows, best + 1])
        curvature = left - 2 * centre + right
        offset = np.where(curvature < 0, 0.5 * (left - right) / np.where(curvature < 0, curvature, -1.0), 0.0)
        if self.k_nodes > 1:
            best, offset = self._joint_vertex(joint, best, offset)
        offset = np.clip(offset, -1.0, 1.0)
        spacing = a_nodes[rows, best + 1] - a_nodes[rows, best]
        vertex = a_nodes[rows, best] + offset * spacing
        return np.where(weights.max(axis=1) > CONCENTRATED, vertex, mean)

    def _joint_vertex(self, joint, best_marginal, offset_marginal):
        """(T0 node, offset in T0 cells) of the vertex of the quadratic through the joint log-posterior's
        3 x 3 neighbourhood of its best (interior) node; the marginal parabola's where that quadratic has no
        maximum."""
        n = joint.shape[0]
        flat = np.argmax(joint.reshape(n, -1), axis=1)
        i = np.clip(flat // self.k_nodes, 1, self.nodes - 2)
        j = np.clip(flat % self.k_nodes, 1, self.k_nodes - 2)
        rows = np.arange(n)

        def at(di, dj):
            return joint[rows, i + di, j + dj]

        centre = at(0, 0)
        g_t, g_k = 0.5 * (at(1, 0) - at(-1, 0)), 0.5 * (at(0, 1) - at(0, -1))
        h_tt, h_kk = at(1, 0) - 2 * centre + at(-1, 0), at(0, 1) - 2 * centre + at(0, -1)
        h_tk = 0.25 * (at(1, 1) - at(1, -1) - at(-1, 1) + at(-1, -1))
        det = h_tt * h_kk - h_tk ** 2
        peaked = (h_tt < 0) & (det > 0)
        safe = np.where(peaked, det, 1.0)
        offset = -(h_kk * g_t - h_tk * g_k) / safe
        return np.where(peaked, i, best_marginal), np.where(peaked, offset, offset_marginal)

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
        commands = np.zeros((n * self.nodes * self.k_nodes, 2))
        commands[:, 0] = np.repeat(np.clip(field, -1.0, 1.0), self.nodes * self.k_nodes)
        self._sim.step(commands)
        config = self.config
        normalized = 2.0 * (self.estimate() - config.theta_min) / config.theta_width - 1.0
        return np.stack([field, np.clip(normalized, -1.0, 1.0)], axis=1).astype(np.float32)


__all__ = ["CONCENTRATED", "K_TASK_NODES", "POSTERIOR_NODES", "PosteriorCalibration"]
