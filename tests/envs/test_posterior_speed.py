"""The grid posterior's fast paths give the numbers of the plain ones bit for bit: the restart from a stored
start state against a simulator reset, the step in two threads against one call, the compiled marginal (numpy's
exp and log, numpy's order of summation, the underflowing exps skipped) against its numpy form, and the
start-temperature quantile of all reset rows at once against one row at a time."""

import gymnasium
import numpy as np
import pytest

import hyst_gym  # noqa: F401
from hyst_gym.envs import posterior as posterior_module
from hyst_gym.envs.core import IDENTIFICATION, BatchSimulator
from hyst_gym.envs.kernels import pairwise_sum, posterior_step
from hyst_gym.envs.posterior import GridPosterior
from hyst_gym.envs.suite_v2 import K_PRIOR, task_config_v2
from hyst_gym.estimation.information_bound import raised_cosine_quantile

NODE_ARRAYS = ("field", "magnetization", "state", "temperature", "ambient0", "drift_rate", "steps", "a_true",
               "measured", "measured_temperature")
#: the node-plant arrays that stay current at the width nodes when they are dead (posterior_step)
WIDTH_NODE_ARRAYS = ("field", "temperature", "ambient0", "drift_rate", "steps", "a_true", "measured_temperature")


def _bits(array) -> np.ndarray:
    return np.ascontiguousarray(array, dtype=np.float64).view(np.int64)


def test_pairwise_sum_is_numpys_sum_bit_for_bit():
    rng = np.random.default_rng(0)
    for length in list(range(0, 300)) + [511, 512, 513, 1000, 4097]:
        rows = np.exp(rng.normal(0.0, 8.0, (3, length)))
        numpy_sums = rows.sum(axis=1)
        for row in range(3):
            assert pairwise_sum(rows.reshape(-1), row * length, length) == numpy_sums[row], length


def _numpy_marginal(joint, a_nodes):
    """The grid posterior's marginal, weights, mean and spread as numpy computes them (the code they replace)."""
    peak = joint.max(axis=2)
    log_post = peak + np.log(np.exp(joint - peak[:, :, None]).sum(axis=2))
    weights = np.exp(log_post - log_post.max(axis=1, keepdims=True))
    weights /= weights.sum(axis=1, keepdims=True)
    mean = (weights * a_nodes).sum(axis=1)
    spacing = np.abs(a_nodes[:, 1] - a_nodes[:, 0])
    variance = (weights * (a_nodes - mean[:, None]) ** 2).sum(axis=1)
    return log_post, weights, mean, np.sqrt(variance + spacing ** 2 / 12.0)


@pytest.mark.parametrize("prune", [False, True])
@pytest.mark.parametrize("task, k_prior", [("hyst_gym/HotCalibrate-v0", None),
                                           ("hyst_gym/HotCalibrateUnknownK-v0", K_PRIOR)])
def test_the_compiled_marginal_is_the_numpy_form_bit_for_bit(task, k_prior, prune):
    posterior = GridPosterior(task_config_v2(task), [0], 40, k_prior, prune=prune)
    posterior.restart(np.arange(40))
    _drive(posterior, 5, np.random.default_rng(8))
    alive = posterior.alive()
    assert alive.all() != prune  # pruned: some rows are dead (the made-up outputs fit few nodes)
    rng = np.random.default_rng(9)
    shape = posterior.log_post.shape
    cases = [posterior.log_post.copy(),  # a posterior as the env makes it
             -rng.random(shape) * 3.0,  # spread over every node
             -np.exp(rng.uniform(0.0, 18.0, shape)),  # most entries underflow, a few near the peak
             -745.13321910194 + rng.normal(0.0, 1.0, shape)]  # around the underflow edge, relative to the peak
    cases[3][:, 0, 0] = 0.0
    zero, positive = 0, 0
    for joint in cases:
        joint[~alive] = posterior_module.DEAD_LOG_POST  # where the pruned posterior's dead nodes hold it
        posterior.log_post[...] = joint
        posterior._results_valid = False
        results = posterior._marginal()
        with np.errstate(under="ignore"):
            expected = _numpy_marginal(joint, posterior._a_nodes)
        for got, want in zip([results[name] for name in ("log_post", "weights", "mean", "spread")], expected):
            assert np.array_equal(_bits(got), _bits(want))
        assert np.array_equal(_bits(posterior.spread()), _bits(expected[3]))
        zero, positive = zero + (expected[1] == 0.0).sum(), positive + (expected[1] > 0.0).sum()
    assert zero > 100 and positive > 100  # weights that underflow and weights that do not


def test_quantile_of_all_rows_at_once_is_the_quantile_row_by_row():
    # BatchSimulator.reset draws the start temperatures of all reset rows in one call: a row's value must not
    # depend on the rows beside it
    u = np.concatenate([np.random.default_rng(1).random(3001), [0.0, 1.0, 0.5, 2.0 ** -52]])
    together = raised_cosine_quantile(u)
    alone = np.array([float(raised_cosine_quantile(np.array([value]))[0]) for value in u])
    assert np.array_equal(_bits(together), _bits(alone))
    assert np.array_equal(_bits(together[5:9]), _bits(raised_cosine_quantile(u[5:9])))


def _slow_nodes(posterior):
    """A plain simulator per node of one sub-env, reset the ordinary way at its grid node."""
    per = posterior.nodes * posterior.k_nodes
    sim = BatchSimulator(posterior.config.replace(output_noise=0.0, temperature_sensor_noise=0.0), IDENTIFICATION,
                         per)
    for row in range(per):
        sim.set_generator(row, np.random.default_rng(500 + row))
    sim.set_pinning(np.arange(per), np.tile(posterior.node_k, posterior.nodes))
    sim.reset(np.arange(per), {"initial_temperature": np.repeat(posterior.node_temperature, posterior.k_nodes)})
    return sim


def _drive(posterior, steps, rng, restart_at=()):
    """Update with made-up outputs and step with random fields; restart sub-envs at the given steps."""
    n, channels = posterior.n, len(posterior.channels)
    for t in range(steps):
        measured = rng.normal(0.0, 0.05, (n, channels)) + 0.2
        rows = np.flatnonzero(rng.random(n) < 0.8)
        posterior.advance(measured, rows, rng.uniform(-1.0, 1.0, n))
        for at, restarted in restart_at:
            if at == t:
                posterior.restart(restarted)


@pytest.mark.parametrize("task, k_prior", [("hyst_gym/HotCalibrate-v0", None),
                                           ("hyst_gym/HotCalibrateUnknownK-v0", K_PRIOR)])
def test_restart_puts_the_node_plants_where_a_simulator_reset_puts_them(task, k_prior):
    posterior = GridPosterior(task_config_v2(task), [0], 5, k_prior)
    posterior.restart(np.arange(5))
    _drive(posterior, 30, np.random.default_rng(2))
    per = posterior.nodes * posterior.k_nodes
    before = {name: getattr(posterior.sim, name).copy() for name in NODE_ARRAYS}
    posterior.estimate()  # the results are up to date: the restart gives its rows the start's
    posterior.restart(np.array([1, 3]))
    kept = {name: values.copy() for name, values in posterior._marginal().items()}
    posterior._results_valid = False
    for name, values in posterior._marginal().items():  # computed afresh
        assert np.array_equal(_bits(values), _bits(kept[name])), name
    slow = _slow_nodes(posterior)
    for name in NODE_ARRAYS:
        now = getattr(posterior.sim, name).reshape((5, per) + before[name].shape[1:])
        for row in (1, 3):
            assert np.array_equal(now[row], getattr(slow, name)), name
        was = before[name].reshape(now.shape)
        assert np.array_equal(now[[0, 2, 4]], was[[0, 2, 4]]), name  # the others untouched
    assert np.array_equal(posterior.log_post[1], np.repeat(posterior.log_prior, posterior.k_nodes).reshape(
        posterior.nodes, posterior.k_nodes))
    alive = posterior.alive()
    assert alive[[1, 3]].all() and not alive[[0, 2, 4]].all()  # the restart revived every node of its rows only


@pytest.mark.parametrize("task, k_prior", [("hyst_gym/HotCalibrate-v0", None),
                                           ("hyst_gym/HotCalibrateUnknownK-v0", K_PRIOR)])
def test_the_step_in_two_threads_is_the_step_in_one_call(task, k_prior, monkeypatch):
    config = task_config_v2(task)
    one = GridPosterior(config, [0], 7, k_prior)
    monkeypatch.setattr(posterior_module, "SPLIT_MIN_NODES", 1)
    monkeypatch.setattr(posterior_module, "step_threads", lambda: 2)
    two = GridPosterior(config, [0], 7, k_prior)
    assert one._blocks == [] and len(two._blocks) == 2
    results = []
    for posterior in (one, two):
        posterior.restart(np.arange(7))
        _drive(posterior, 45, np.random.default_rng(4), restart_at=[(20, np.array([2, 5]))])
        assert posterior_step.overloads  # compiled: the blocks did run in threads
        assert not posterior.alive().all()  # nodes died: the pruning ran in both
        results.append([posterior.log_post, posterior.estimate(), posterior.spread()]
                       + [getattr(posterior.sim, name) for name in NODE_ARRAYS])
        results[-1] = [np.asarray(values, dtype=np.float64) for values in results[-1] + list(posterior._alive)]
    for a, b in zip(*results):
        assert np.array_equal(_bits(a), _bits(b))
    assert np.isfinite(results[0][1]).all() and np.ptp(results[0][0]) > 1.0  # the posterior did move


@pytest.mark.parametrize("prune", [False, True])
@pytest.mark.parametrize("task, k_prior", [("hyst_gym/HotCalibrate-v0", None),
                                           ("hyst_gym/DisplacementOnly-v0", None),
                                           ("hyst_gym/HotCalibrateUnknownK-v0", K_PRIOR)])
def test_the_node_plants_step_as_a_plain_simulator_per_node_bit_for_bit(task, k_prior, prune, monkeypatch):
    # posterior_step moves a sub-env's node plants as one bank under their shared field: every node-plant array
    # must stay what the simulator's own step (plant_step, one plant at a time) makes of each node, under moving,
    # held and saturated fields, across a restart, in two threads; pruned, at every alive node, and the field and
    # thermal state at the width nodes (k node 0 of T0 nodes 0 and 1: the spread's cell width reads a there)
    monkeypatch.setattr(posterior_module, "SPLIT_MIN_NODES", 1)
    monkeypatch.setattr(posterior_module, "step_threads", lambda: 2)
    n = 3
    posterior = GridPosterior(task_config_v2(task), [0], n, k_prior, prune=prune)
    assert len(posterior._blocks) == 2
    posterior.restart(np.arange(n))
    slow = [_slow_nodes(posterior) for _ in range(n)]
    per = posterior.nodes * posterior.k_nodes
    rng = np.random.default_rng(12)
    pruned = False
    for t in range(100):
        # random, then commands held: the field reaches 30 kA/m and stays there, or its limits (commands past them)
        field = rng.uniform(-1.0, 1.0, n) if t < 25 else np.array([0.3, 2.0, -3.0])
        posterior.advance(rng.normal(0.0, 0.05, (n, 1)), np.arange(n), field)
        for row in range(n):
            slow[row].step(np.column_stack([np.full(per, min(max(field[row], -1.0), 1.0)), np.zeros(per)]))
        if t == 30:
            posterior.restart(np.array([1]))
            slow[1] = _slow_nodes(posterior)
        alive = posterior.alive().reshape(n, per)
        pruned |= not alive.all()
        width = np.zeros(per, dtype=bool)
        width[[0, posterior.k_nodes]] = True
        for name in NODE_ARRAYS:
            now = getattr(posterior.sim, name)
            now = now.reshape((n, per) + now.shape[1:])
            for row in range(n):
                compared = alive[row] | width if name in WIDTH_NODE_ARRAYS else alive[row]
                assert np.array_equal(_bits(now[row][compared]), _bits(getattr(slow[row], name)[compared])), \
                    (t, name, row)
    assert pruned == prune
    field_limit = posterior.config.field_limit
    assert np.array_equal(posterior.sim.field.reshape(n, per)[:, 0], [0.3 * field_limit, field_limit, -field_limit])
    assert posterior.sim.steps.max() == 100 and np.ptp(posterior.sim.temperature) > 1.0


def test_the_grid_posterior_refuses_a_drifting_ambient_of_unknown_rate():
    config = task_config_v2("hyst_gym/HotCalibrate-v0", ambient_drift_rate_range=(-0.05, 0.05))
    with pytest.raises(ValueError, match="ambient_drift_rate_range"):
        GridPosterior(config, [0], 2)


def test_a_nan_field_changes_no_block(monkeypatch):
    monkeypatch.setattr(posterior_module, "SPLIT_MIN_NODES", 1)
    monkeypatch.setattr(posterior_module, "step_threads", lambda: 2)
    posterior = GridPosterior(task_config_v2("hyst_gym/HotCalibrate-v0"), [0], 4)
    posterior.restart(np.arange(4))
    _drive(posterior, 3, np.random.default_rng(5))
    before = posterior.sim.magnetization.copy(), posterior.log_post.copy()
    with pytest.raises(ValueError, match="nan"):
        posterior.advance(np.zeros((4, 1)), np.arange(4), np.array([0.5, 0.5, 0.5, np.nan]))
    assert np.array_equal(posterior.sim.magnetization, before[0]) and np.array_equal(posterior.log_post, before[1])


def test_vector_env_with_threads_matches_the_single_envs():
    # sub-env i of a vector env big enough for the threaded step behaves as a single env seeded seed + i
    n = 70  # 70 x 64 node plants: above SPLIT_MIN_NODES
    assert n * 64 >= posterior_module.SPLIT_MIN_NODES
    venv = gymnasium.make_vec("hyst_gym/HotCalibrate-v0", num_envs=n, vectorization_mode="vector_entry_point")
    observation, _ = venv.reset(seed=11)
    rng = np.random.default_rng(6)
    actions = rng.uniform(-1.0, 1.0, (60, n, 1)).astype(np.float32)
    vector = [observation]
    for action in actions:
        vector.append(venv.step(action)[0])
    for row in (0, 37, n - 1):
        env = gymnasium.make("hyst_gym/HotCalibrate-v0")
        single = [env.reset(seed=11 + row)[0]]
        for action in actions[:, row]:
            single.append(env.step(action)[0])
        assert np.array_equal(np.array(single), np.array(vector)[:, row])


def _step_in_child(queue):
    posterior = GridPosterior(task_config_v2("hyst_gym/HotCalibrate-v0"), [0], 4)
    posterior.restart(np.arange(4))
    _drive(posterior, 3, np.random.default_rng(5))
    queue.put(posterior.estimate().tolist())


def test_a_forked_child_steps_in_threads_of_its_own(monkeypatch):
    # the parent's worker thread is not in a forked child: the child makes its own pool (else it would wait forever)
    import multiprocessing

    monkeypatch.setattr(posterior_module, "SPLIT_MIN_NODES", 1)
    monkeypatch.setattr(posterior_module, "step_threads", lambda: 2)
    _step_in_child(parent := multiprocessing.get_context("fork").SimpleQueue())
    expected = parent.get()
    queue = multiprocessing.get_context("fork").SimpleQueue()
    child = multiprocessing.get_context("fork").Process(target=_step_in_child, args=(queue,))
    child.start()
    child.join(timeout=60)
    if child.is_alive():
        child.kill()
    assert child.exitcode == 0
    assert queue.get() == expected
