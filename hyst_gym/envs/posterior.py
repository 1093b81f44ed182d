"""The grid posterior of a calibration task: the Bayes estimate of a from the measured outputs.

In a calibration task the only unknown is the start temperature T0 (the ambient equals it and does not
drift, so the heating is a known function of the field); in the "several unknowns" task the pinning
constant k of model (6) is unknown too. :class:`GridPosterior` runs, for every sub-environment, a
noise-free copy of the task's simulator per grid node of T0 (and of k) (the same compiled kernels,
driven by the same field commands), scores each node by the Gaussian log-likelihood of the measured
normalized outputs (noise ``output_noise``), adds the log-prior (raised cosine over T0, flat over k)
and reports

* the posterior mean of a while the posterior is spread over several nodes, and
* the vertex of a parabola through the log-posterior at the best node and its neighbours once one
  node holds more than half the mass (the grid spacing, 0.6 K or 15 A/m at 64 nodes, would
  otherwise limit the error); with a k grid, the vertex of the quadratic through the joint
  log-posterior's 3 x 3 neighbourhood of the best node (the marginal parabola where it has no maximum).

With ``k_nodes`` = 1 on a task with a k prior the posterior *assumes the nominal k* (a misspecified,
weaker estimator). The estimate after :meth:`GridPosterior.step` with the field of step t predicts a at
the end of step t from the outputs up to step t - 1. Its spread is the posterior standard deviation of
a over the T0 nodes (A/m).
"""

from __future__ import annotations

import numpy as np

from ..estimation import as_kernel_tuples
from .kernels import LikelihoodParams, posterior_step, posterior_vertex

#: grid nodes of the start temperature per sub-environment
POSTERIOR_NODES = 64
#: a node holding more than this posterior mass switches the estimate to the parabola vertex
CONCENTRATED = 0.5
#: grid nodes (start temperature, k) per sub-environment on a task with a k prior
K_TASK_NODES = (24, 9)


def grid_sizes(k_prior, nodes: int | None = None, k_nodes: int | None = None) -> tuple[int, int]:
    """The grid's ``(nodes, k_nodes)``, checked, with the defaults filled in: :data:`POSTERIOR_NODES` T0 nodes and
    k known without a k prior, :data:`K_TASK_NODES` with one."""
    if nodes is None:
        nodes = POSTERIOR_NODES if k_prior is None else K_TASK_NODES[0]
    if k_nodes is None:
        k_nodes = 1 if k_prior is None else K_TASK_NODES[1]
    if isinstance(k_nodes, bool) or not isinstance(k_nodes, (int, np.integer)) or k_nodes == 2 or k_nodes < 1 \
            or (k_nodes > 1 and k_prior is None):
        raise ValueError(f"k_nodes must be 1 or (on a task with a k prior) an integer >= 3, got {k_nodes!r}")
    if isinstance(nodes, bool) or not isinstance(nodes, (int, np.integer)) or nodes < 3:
        raise ValueError(f"nodes must be an integer >= 3, got {nodes!r}")
    return int(nodes), int(k_nodes)


class GridPosterior:
    """The grid posterior over T0 (and k) of ``n`` sub-environments of a calibration task (module doc).

    ``config``: the task's EnvConfig; ``channels``: the measured output columns the estimator reads (the
    sensors of the task: 0 output or displacement, 1 velocity); ``k_prior``: the task's
    :class:`~hyst_gym.envs.task_spec.PinningPrior` or None; ``nodes``: T0 nodes (default
    :data:`POSTERIOR_NODES`, the first of :data:`K_TASK_NODES` with a k prior); ``k_nodes``: 1 (k known at the
    config's) or >= 3 (over the k prior; default the second of :data:`K_TASK_NODES` with a k prior)."""

    def __init__(self, config, channels, n: int, k_prior=None, nodes: int | None = None,
                 k_nodes: int | None = None):
        from .core import IDENTIFICATION, BatchSimulator

        nodes, k_nodes = grid_sizes(k_prior, nodes, k_nodes)
        self.config = config
        self.channels = list(channels)
        self.n = int(n)
        self.nodes = int(nodes)
        self.k_nodes = int(k_nodes)
        self.node_k = np.array([config.hysteresis.k]) if k_nodes == 1 else k_prior.nodes(self.k_nodes)
        low, high = config.initial_temperature_range
        self.node_temperature = low + (high - low) * (np.arange(self.nodes) + 0.5) / self.nodes
        self.log_prior = np.log(1.0 - np.cos(2 * np.pi * (np.arange(self.nodes) + 0.5) / self.nodes))
        per = self.nodes * self.k_nodes
        # noise-free in every channel (the temperature sensor's too: its draws would be read by nobody)
        self.sim = BatchSimulator(config.replace(output_noise=0.0, temperature_sensor_noise=0.0), IDENTIFICATION,
                                  self.n * per)
        for row in range(self.n * per):
            self.sim.set_generator(row, np.random.default_rng(row))
        self.sim.set_pinning(np.arange(self.n * per), np.tile(self.node_k, self.n * self.nodes))
        self.log_post = np.zeros((self.n, self.nodes, self.k_nodes))
        self._commands = np.zeros((self.n * per, 2))
        # The compiled step (kernels.posterior_step) moves only the node plants: the simulator's estimator
        # bank, score, info and observation are never read here, and skipping them is most of the step's cost.
        channels = np.array(self.channels, dtype=np.int64)
        self._likelihood = LikelihoodParams(channels=channels, scales=self.sim.scales[channels],
                                            variance=float(config.output_noise) ** 2,
                                            per=per)
        self._kernel_args = (np.ones(self.n * per, dtype=bool),
                             *as_kernel_tuples(self.sim._plant, self.sim._plant_params, self._likelihood))
        self._node_command = np.zeros(self.n * per)
        self._no_rows = np.zeros(0, dtype=np.int64)
        self._no_field = np.zeros(self.n)
        self._log_post_flat = self.log_post.reshape(self.n, per)  # a view: the kernel writes log_post
        self._marginal_cache = None

    def restart(self, rows) -> None:
        """New episodes in sub-envs ``rows``: every node simulator at its grid node, the log-prior."""
        rows = np.asarray(rows, dtype=np.int64)
        per = self.nodes * self.k_nodes
        sub = (rows[:, None] * per + np.arange(per)[None, :]).ravel()
        # every node simulator starts at its grid node's temperature (the reset option, one value per row)
        temperatures = np.tile(np.repeat(self.node_temperature, self.k_nodes), rows.shape[0])
        self.sim.reset(sub, {"initial_temperature": temperatures})
        self.log_post[rows] = self.log_prior[:, None]
        self._marginal_cache = None

    def update(self, measured: np.ndarray, rows) -> None:
        """Add the log-likelihood of the normalized outputs ``measured`` ((n, channels), the sensors'
        observation columns of the last step) of sub-envs ``rows`` against the nodes' noise-free outputs."""
        self.advance(measured, rows, None)

    def step(self, field: np.ndarray) -> None:
        """Step every node simulator of every sub-env with its sub-env's normalized field command (n,)."""
        self.advance(None, self._no_rows, field)

    def advance(self, measured, rows, field) -> None:
        """:meth:`update` with ``measured`` of sub-envs ``rows`` (skipped where ``rows`` is empty), then
        :meth:`step` with ``field`` (skipped where None), in one compiled call (:func:`~.kernels.posterior_step`).
        A NaN field raises the simulator's one-line error, with nothing changed."""
        rows = np.asarray(rows, dtype=np.int64)
        if rows.shape[0] and not self.config.output_noise > 0:
            raise ValueError("GridPosterior.update: the likelihood needs output_noise > 0, got "
                             f"{self.config.output_noise!r}")
        measured = np.zeros((self.n, len(self.channels))) if measured is None else \
            np.asarray(measured, dtype=np.float64)
        self._marginal_cache = None
        stepping = field is not None
        field = self._no_field if field is None else np.asarray(field, dtype=np.float64)
        if posterior_step(rows, measured, self._log_post_flat, field, stepping, self._node_command,
                          *self._kernel_args):
            self._commands[:, 0] = np.repeat(field, self.nodes * self.k_nodes)
            self.sim.check_actions(self._commands)  # raises, naming the value

    def _marginal(self):
        """(a at the T0 nodes (n, nodes), the log-posterior marginal over k (n, nodes), its weights); computed
        once per step or restart (estimate and spread both read it)."""
        if self._marginal_cache is not None:
            return self._marginal_cache
        joint = self.log_post
        a_nodes = self.sim.a_true.reshape(-1, self.nodes, self.k_nodes)[:, :, 0]  # a depends on T0 only
        if self.k_nodes == 1:  # the log-sum-exp over one k node is the node itself: peak + log(1)
            log_post = joint[:, :, 0]
        else:
            peak = joint.max(axis=2)
            log_post = peak + np.log(np.exp(joint - peak[:, :, None]).sum(axis=2))
        weights = np.exp(log_post - log_post.max(axis=1, keepdims=True))
        weights /= weights.sum(axis=1, keepdims=True)
        self._marginal_cache = (a_nodes, log_post, weights)
        return self._marginal_cache

    def estimate(self) -> np.ndarray:
        """The estimate of a per sub-environment (A/m), from the nodes' a after their last step (module doc;
        the mean and the vertex are :func:`~.kernels.posterior_vertex`'s)."""
        a_nodes, log_post, weights = self._marginal()
        mean = (weights * a_nodes).sum(axis=1)
        estimate = np.empty(self.n)
        posterior_vertex(log_post, self.log_post, weights, a_nodes, mean, CONCENTRATED, estimate)
        return estimate

    def spread(self) -> np.ndarray:
        """The posterior standard deviation of a per sub-environment (A/m; at least the node spacing's
        uniform-cell width, spacing/sqrt(12), once the mass sits on one node)."""
        a_nodes, _, weights = self._marginal()
        mean = (weights * a_nodes).sum(axis=1, keepdims=True)
        spacing = np.abs(a_nodes[:, 1] - a_nodes[:, 0])
        variance = (weights * (a_nodes - mean) ** 2).sum(axis=1)
        return np.sqrt(variance + spacing ** 2 / 12.0)


__all__ = ["CONCENTRATED", "K_TASK_NODES", "POSTERIOR_NODES", "GridPosterior"]
