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

Pruning (same estimate, spread and mean bit for bit, ``tests/envs/test_posterior_pruning.py``). Under an informative
input most nodes' log-posterior falls hundreds of nats below the best node's within a few dozen steps, where their
weight is exactly 0.0. A node more than :data:`DEAD_GAP` (1000 nats) below its sub-env's best node is *dead*: its node
plant is no longer simulated and its log-posterior is :data:`DEAD_LOG_POST`. A sub-env keeps an interval of alive T0
nodes (:class:`~.kernels.AliveRows`; a T0 node's k nodes live and die together, as its marginal over k reads them
all): the T0 nodes of its nodes within the gap, widened by one T0 node on each side, so that the values the vertex
reads (the marginal at the best T0 node and its neighbours, the joint's 3 x 3 about its best node) are always
current. It only narrows; a restart (and the vector env's auto-reset) revives every node of its sub-env, and
nothing else does. A dead node's weight in the unpruned posterior is 0.0, and it stays 0.0 unless the node gains
about 250 nats on the best one (:data:`DEAD_GAP` less the 746 of exp's underflow, :data:`EXP_ZERO_BELOW`, and
the log(k_nodes) of the marginal); a dead T0 node is read by the vertex only once its neighbour, more than
:data:`DEAD_GAP` below the best node when it died, has become the best: evidence of that size against what the
posterior has seen, so the pruned posterior reports the unpruned one's numbers. Measured: bit for bit at every
step of 256 episodes of each of the suite's tuned agents (thermostat, tuned sine, proportional, ramp_hold,
bang_hold, idle) and of 1,000 steps x 256 sub-envs of random actions, on this task and on HotCalibrate-v0 (no
value differed). The decision reads its sub-env's numbers alone: it is the same in any split into threads. The
*width nodes* (k node 0 of T0 nodes 0 and 1) step their field and thermal model on when dead: the spread's cell
width reads a there. Alive share of the node-steps (same runs): 31-38 % under the tuned agents on the k task,
25-30 % on HotCalibrate-v0, 100 % under ``idle`` (no excitation, nothing learned), and 70 % and 67 % under the
benchmark's random actions (the field wanders +-2500 A/m a step about 0 and reveals little).

Speed (same numbers bit for bit, ``tests/envs/test_posterior_speed.py`` and, for the k task's whole env,
``tests/envs/test_k_task_trajectory.py``). Nearly all of a calibration env's step is model (6) in the node plants:
n*nodes*k_nodes of them (65,536 at n = 1024 with 64 nodes, 221,184 with the k task's 24 x 9); pruning steps only the
alive ones. A sub-env's node plants are one bank under one field, stepped in passes over the bank
(:func:`~hyst_gym.physics.hysteresis.advance_shared`: the anhysteretic curve, the half step, the curve, the full
step; about 1.7x faster than one model's whole midpoint step at a time); its update, pruning and step are one pass
over its node plants (:func:`~.kernels.posterior_step`), its thermal model is stepped once per T0 node (the k nodes of
a T0 node share it) and its first-order transducer without the state loops. A restart copies a start state stored
once (a node's start draws nothing); from :data:`SPLIT_MIN_NODES` node plants the step runs in two blocks of
sub-envs in two threads (its kernels release the GIL; a row's numbers depend on its row alone), and so do the
simulator's own plants and model bank (:meth:`~.core.BatchSimulator.step`); the marginal, weights, mean, spread and
estimate are compiled kernels around numpy's exp and log (numpy's order of summation kept, exp left out where it
underflows to 0, numpy's slow path, and dead T0 nodes left out). History at n = 1024 under random actions (the
benchmark's input), each change measured before and after alternately in one process on 2 cores: pruning took the
k task from 112,000-135,000 to 147,000-151,000 steps/s (1-min load 1.4-1.9 from another job; under a sine of 40 +
40 kA/m at 0.5 Hz, HotCalibrate-v0's tuned open-loop design, 126,000-131,000 -> 181,000-191,000; HotCalibrate-v0
unchanged within the noise); the passes, the one pass per sub-env and the simulator's threads then took it 1.46x
faster (medians over 6 rounds, 86,500 -> 126,400 steps/s, 1.40-1.48 per round, 1-min load 0.4-0.6 on a machine
slower than the one above; 1.50x at a load of 3.8-4.1 from another job on the same 2 cores) and HotCalibrate-v0
1.08x.
"""

from __future__ import annotations

import numpy as np

from ..estimation import as_kernel_tuples
from .kernels import (AliveRows, LikelihoodParams, PruneParams, marginal_sums, marginal_terms, posterior_moments,
                      posterior_step, posterior_vertex, weight_terms)
# SPLIT_MIN_NODES: the node plants of a grid posterior from which its step runs in step_threads() threads
from .threads import SPLIT_MIN_NODES, WorkerThreads, block_edges, step_threads

#: grid nodes of the start temperature per sub-environment
POSTERIOR_NODES = 64
#: a node holding more than this posterior mass switches the estimate to the parabola vertex
CONCENTRATED = 0.5
#: grid nodes (start temperature, k) per sub-environment on a task with a k prior
K_TASK_NODES = (24, 9)
#: the node simulators' plant parameters that are per node plant (the others are shared by all)
PER_NODE_PARAMS = ("k", "alpha", "Ms", "c")


#: below this, exp(x) is 0.0 in double precision (it is for every x below about -745.13): the posterior's exps
#: skip those entries, where numpy's exp takes a slow path (about 10x per entry; most of a concentrated
#: posterior's nodes lie there)
EXP_ZERO_BELOW = -746.0

#: a grid node whose log-posterior lies more than this (nats) below its sub-env's best node is dead: its node plant is
#: no longer simulated (module doc, "Pruning"). Its weight is then 0.0 exactly (its T0 node's marginal lies at most
#: log(k_nodes) above it, and exp underflows below :data:`EXP_ZERO_BELOW`), and it stays 0.0 unless the node gains
#: the rest of this gap, about 250 nats, on the best node: evidence the posterior has already seen the other way
DEAD_GAP = 1000.0
#: the log-posterior of a dead node: far below any live node's, so that its weight is 0.0, and finite, so that the
#: log-sum-exp over k of a T0 node whose nodes are all dead is a number (-inf - (-inf) would be NaN)
DEAD_LOG_POST = -1.0e300


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
    config's) or >= 3 (over the k prior; default the second of :data:`K_TASK_NODES` with a k prior); ``prune``: stop
    simulating the dead nodes (module doc, "Pruning"; False: every node plant is simulated at every step, the
    reference the pruned posterior is tested against).

    ``log_post`` (n, nodes, k_nodes): the log-posterior per node; a pruned node holds :data:`DEAD_LOG_POST` (a
    finite stand-in far below any live node, whose weight is exactly 0.0 as the dead node's was), not its own
    log-posterior, which stops being updated."""

    def __init__(self, config, channels, n: int, k_prior=None, nodes: int | None = None,
                 k_nodes: int | None = None, prune: bool = True):
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
        d_lo, d_hi = config.ambient_drift_rate_range
        if d_lo != d_hi:
            raise ValueError("GridPosterior: the grid posterior assumes a known ambient drift rate (the ends of "
                             f"ambient_drift_rate_range equal), got ambient_drift_rate_range {(d_lo, d_hi)}")
        # noise-free in every channel (the temperature sensor's too: its draws would be read by nobody)
        self.sim = BatchSimulator(config.replace(output_noise=0.0, temperature_sensor_noise=0.0), IDENTIFICATION,
                                  self.n * per)
        self.sim.set_pinning(np.arange(self.n * per), np.tile(self.node_k, self.n * self.nodes))
        self._fresh_plants = self._start_state(per)
        self.log_post = np.zeros((self.n, self.nodes, self.k_nodes))
        self._commands = np.zeros((self.n * per, 2))
        self.prune = bool(prune)
        self._alive = AliveRows(first=np.zeros(self.n, dtype=np.int64),
                                stop=np.full(self.n, self.nodes, dtype=np.int64))
        self._pruning = PruneParams(nodes=self.nodes, k_nodes=self.k_nodes, dead_gap=DEAD_GAP if prune else np.inf,
                                    dead_log_post=DEAD_LOG_POST)
        # The compiled step (kernels.posterior_step) moves only the node plants: the simulator's estimator
        # bank, score, info and observation are never read here, and skipping them is most of the step's cost.
        channels = np.array(self.channels, dtype=np.int64)
        self._likelihood = LikelihoodParams(channels=channels, scales=self.sim.scales[channels],
                                            variance=float(config.output_noise) ** 2,
                                            per=per)
        self._kernel_args = as_kernel_tuples(self._alive, self.sim._plant, self.sim._plant_params, self._likelihood,
                                             self._pruning)
        self._blocks = self._split(per)
        self._threads = WorkerThreads(step_threads() - 1, "hyst-gym-posterior")
        self._no_rows = np.zeros(0, dtype=np.int64)
        self._updating = np.zeros(self.n, dtype=bool)
        self._no_field = np.zeros(self.n)
        self._log_post_flat = self.log_post.reshape(self.n, per)  # a view: the kernel writes log_post
        self._a_nodes = self.sim.a_true.reshape(self.n, self.nodes, self.k_nodes)[:, :, 0]  # a depends on T0 only
        self._scratch = self._scratch_for(self.n)
        self._results = {"log_post": self.log_post[:, :, 0] if self.k_nodes == 1 else np.empty((self.n, self.nodes)),
                         "weights": np.empty((self.n, self.nodes)), "mean": np.empty(self.n),
                         "spread": np.empty(self.n), "estimate": np.empty(self.n)}
        self._results_valid = False
        self._start_results = self._results_at_start()

    def _results_at_start(self) -> dict:
        """The results of :meth:`_marginal_rows` of a restarted sub-env (they depend on its row alone, and a restart
        puts every row in the same state), from sub-env 0 at its start (:meth:`_start_state`)."""
        self.log_post[0] = self.log_prior[:, None]
        self._marginal_rows(slice(0, 1), self._scratch_for(1))
        self.log_post[0] = 0.0
        return {name: values[0].copy() for name, values in self._results.items()
                if not (name == "log_post" and self.k_nodes == 1)}  # with one k node it is log_post itself

    def _start_state(self, per: int) -> list:
        """(view (n, per, ...) of a node-plant array, its value at a restart (per, ...)) for every array of the
        node plants that a reset sets: the values of one :meth:`BatchSimulator.reset` of sub-env 0's nodes at
        their grid nodes (the reset option ``initial_temperature``, one value per node), taken once here.

        A node's start is the same at every restart: nothing of it is drawn. Its start temperature is the
        option, its drift rate the one value of ``ambient_drift_rate_range`` (checked above), k is set once
        (no k prior on the node simulator), and the node simulator is noise-free, so its random streams are
        never read (only rows 0..per-1 get one, for this reset). The node simulator's model bank, info and
        observation are not node-plant state: :func:`~.kernels.posterior_step` neither reads nor writes them."""
        sim = self.sim
        for row in range(per):
            sim.set_generator(row, np.random.default_rng(row))
        sim.reset(np.arange(per), {"initial_temperature": np.repeat(self.node_temperature, self.k_nodes)})
        n = self.n
        plants = [sim.field, sim.magnetization, sim.state, sim.temperature, sim.ambient0, sim.drift_rate, sim.steps,
                  sim.a_true, sim.measured, sim.measured_temperature]
        views = [array.reshape((n, per) + array.shape[1:]) for array in plants]  # C-contiguous: views
        return [(view, view[0].copy()) for view in views]

    def _split(self, per: int) -> list:
        """The blocks of sub-envs that :meth:`advance` steps in :func:`step_threads` threads at once: (slice of
        sub-envs, the kernel's arguments after ``stepping`` for their node plants: views of the arrays); empty
        (one call for all) with one thread or fewer than :data:`SPLIT_MIN_NODES` node plants."""
        threads = min(step_threads(), self.n)
        if threads < 2 or self.n * per < SPLIT_MIN_NODES:
            return []
        plant, params = self.sim._plant, self.sim._plant_params
        blocks = []
        for lo, hi in block_edges(self.n, threads):
            nodes = slice(lo * per, hi * per)
            block_plant = plant._replace(**{name: getattr(plant, name)[nodes] for name in plant._fields})
            block_params = params._replace(**{name: getattr(params, name)[nodes] for name in PER_NODE_PARAMS})
            block_alive = AliveRows(first=self._alive.first[lo:hi], stop=self._alive.stop[lo:hi])
            blocks.append((slice(lo, hi), as_kernel_tuples(block_alive, block_plant, block_params, self._likelihood,
                                                           self._pruning),
                           self._scratch_for(hi - lo)))
        return blocks

    def restart(self, rows) -> None:
        """New episodes in sub-envs ``rows``: every node simulator at its grid node (:meth:`_start_state`) and alive,
        the log-prior."""
        rows = np.asarray(rows, dtype=np.int64)
        for view, start in self._fresh_plants:
            view[rows] = start
        self._alive.first[rows] = 0
        self._alive.stop[rows] = self.nodes
        self.log_post[rows] = self.log_prior[:, None]
        if self._results_valid:  # a restarted row's results are the start's (a row's depend on that row alone)
            for name, start in self._start_results.items():
                self._results[name][rows] = start

    def alive(self) -> np.ndarray:
        """Whether each grid node's plant is simulated, (n, nodes, k_nodes) bool (module doc, "Pruning")."""
        rows = np.arange(self.nodes)
        alive = (rows >= self._alive.first[:, None]) & (rows < self._alive.stop[:, None])
        return np.repeat(alive[:, :, None], self.k_nodes, axis=2)

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
        if measured.shape != (self.n, len(self.channels)):
            raise ValueError(f"GridPosterior.update: measured must have shape {(self.n, len(self.channels))}, got "
                             f"{measured.shape}")
        updating = self._updating
        updating[:] = False
        updating[rows] = True
        self._results_valid = False
        stepping = field is not None
        field = self._no_field if field is None else np.asarray(field, dtype=np.float64)
        if field.shape != (self.n,):
            raise ValueError(f"GridPosterior.step: field must have shape {(self.n,)}, got {field.shape}")
        if stepping and np.isnan(field).any():  # before any block moves (the kernel would refuse it too)
            self._commands[:, 0] = np.repeat(field, self.nodes * self.k_nodes)
            self.sim.check_actions(self._commands)  # raises, naming the value
        # the blocks in threads once the kernel runs compiled (without the GIL; its first call, which may compile
        # it or stand in with its Python twin, and the twin itself run here, one call for all)
        if not self._blocks or not getattr(posterior_step, "overloads", None):
            posterior_step(updating, measured, self._log_post_flat, field, stepping, *self._kernel_args)
            return
        self._threads.run(self._advance_block, [(updating[rows], measured[rows], field[rows], stepping, rows,
                                                 arguments, scratch) for rows, arguments, scratch in self._blocks])
        self._results_valid = True

    def _advance_block(self, updating, measured, field, stepping, rows, arguments, scratch) -> None:
        """:func:`~.kernels.posterior_step` and then :meth:`_marginal_rows` of one block of sub-envs (in a thread)."""
        posterior_step(updating, measured, self._log_post_flat[rows], field, stepping, *arguments)
        self._marginal_rows(rows, scratch)

    def _marginal_rows(self, rows: slice, scratch: dict) -> None:
        """The marginal of sub-envs ``rows`` into the results (:meth:`_marginal`): the log-posterior marginal over k,
        the weights over the T0 nodes, the posterior mean and spread of a, and the estimate. The numbers of the numpy
        form ``peak = joint.max(axis=2)``, ``log_post = peak + log(exp(joint - peak).sum(axis=2))``,
        ``w = exp(log_post - log_post.max(axis=1))``, ``w /= w.sum(axis=1)``, ``mean = (w*a).sum(axis=1)``,
        ``sqrt((w*(a - mean)**2).sum(axis=1) + spacing**2/12)`` bit for bit: numpy's exp and log, the rest in compiled
        kernels that keep numpy's order of summation (:func:`~.kernels.pairwise_sum`), and exp only where it does not
        underflow (:data:`EXP_ZERO_BELOW`). Each row's numbers depend on that row alone. ``scratch``: the block's
        (:meth:`_scratch_for`)."""
        results = self._results
        joint, a_nodes, log_post = self.log_post[rows], self._a_nodes[rows], results["log_post"][rows]
        values, index = scratch["gather"]
        exps = scratch["exps"]  # numpy's exp into a kept array, not a new one per call
        first, stop = self._alive.first[rows], self._alive.stop[rows]
        if self.k_nodes > 1:  # with one k node, log_post is a view of the joint (the node itself: peak + log(1))
            peak, sums = scratch["peak"], scratch["sums"]
            count = marginal_terms(joint, peak, EXP_ZERO_BELOW, first, stop, values, index)
            marginal_sums(np.exp(values[:count], out=exps[:count]), index, first, stop, scratch["terms"], sums)
            np.add(peak, np.log(sums), out=log_post)
        count = weight_terms(log_post, EXP_ZERO_BELOW, values, index)
        weights, mean = results["weights"][rows], results["mean"][rows]
        posterior_moments(np.exp(values[:count], out=exps[:count]), index, a_nodes, weights, scratch["row"], mean,
                          results["spread"][rows])
        posterior_vertex(log_post, joint, weights, a_nodes, mean, CONCENTRATED, first, stop,
                         results["estimate"][rows])

    def _scratch_for(self, rows: int) -> dict:
        """Work arrays of :meth:`_marginal_rows` for a block of ``rows`` sub-envs."""
        size = rows * self.nodes * self.k_nodes
        return {"peak": np.empty((rows, self.nodes)), "sums": np.empty((rows, self.nodes)),
                "terms": np.empty(self.k_nodes),
                "row": np.empty(self.nodes), "gather": (np.empty(size), np.empty(size, dtype=np.int64)),
                "exps": np.empty(size)}

    def _marginal(self) -> dict:
        """The results of :meth:`_marginal_rows` for every sub-env (``log_post``, ``weights``, ``mean``, ``spread``,
        ``estimate``); computed once per step (in the step's threads where it has them) and kept across a restart
        (the restarted rows get the start's, :attr:`_start_results`)."""
        if not self._results_valid:
            self._marginal_rows(slice(0, self.n), self._scratch)
            self._results_valid = True
        return self._results

    def estimate(self) -> np.ndarray:
        """The estimate of a per sub-environment (A/m), from the nodes' a after their last step (module doc;
        the mean and the vertex are :func:`~.kernels.posterior_vertex`'s)."""
        return self._marginal()["estimate"].copy()

    def spread(self) -> np.ndarray:
        """The posterior standard deviation of a per sub-environment (A/m; at least the node spacing's
        uniform-cell width, spacing/sqrt(12), once the mass sits on one node)."""
        return self._marginal()["spread"].copy()


__all__ = ["CONCENTRATED", "K_TASK_NODES", "POSTERIOR_NODES", "GridPosterior"]
