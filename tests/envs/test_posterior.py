"""The calibration tasks' grid posterior (the estimator in the loop) against a slow, independent recomputation:
one plain simulator per grid node, stepped through the simulator's own full step, and the Gaussian
log-likelihood and the Bayes estimate written out in numpy here."""

import gymnasium
import numpy as np
import pytest

import hyst_gym  # noqa: F401
from hyst_gym.envs.core import IDENTIFICATION, BatchSimulator
from hyst_gym.envs.posterior import CONCENTRATED, EXP_ZERO_BELOW


def _slow_nodes(posterior):
    """A plain simulator per (T0, k) node, started at its node, noise-free, stepped the ordinary way."""
    per = posterior.nodes * posterior.k_nodes
    sim = BatchSimulator(posterior.config.replace(output_noise=0.0), IDENTIFICATION, per)
    for row in range(per):
        sim.set_generator(row, np.random.default_rng(1000 + row))
    sim.set_pinning(np.arange(per), np.tile(posterior.node_k, posterior.nodes))
    sim.reset(np.arange(per), {"initial_temperature": np.repeat(posterior.node_temperature, posterior.k_nodes)})
    return sim


def _bayes_estimate(log_joint, a_nodes):
    """The posterior mean of a, or the vertex once the best T0 node holds most of the mass: of the quadratic
    through the joint log-posterior (nodes, k_nodes) about its best interior node where that has a maximum,
    else of the parabola through the marginal at its best node and its neighbours."""
    peak = log_joint.max(axis=1)
    log_post = peak + np.log(np.exp(log_joint - peak[:, None]).sum(axis=1))
    weights = np.exp(log_post - log_post.max())
    weights /= weights.sum()
    if weights.max() <= CONCENTRATED:
        return float(weights @ a_nodes), False
    best = min(max(int(np.argmax(log_post)), 1), log_post.size - 2)
    left, centre, right = log_post[best - 1:best + 2]
    curvature = left - 2 * centre + right
    offset = 0.5 * (left - right) / curvature if curvature < 0 else 0.0
    if log_joint.shape[1] > 1:
        i, j = np.unravel_index(np.argmax(log_joint), log_joint.shape)
        i, j = min(max(i, 1), log_joint.shape[0] - 2), min(max(j, 1), log_joint.shape[1] - 2)
        around = log_joint[i - 1:i + 2, j - 1:j + 2]
        gradient = 0.5 * np.array([around[2, 1] - around[0, 1], around[1, 2] - around[1, 0]])
        hessian = np.array([[around[2, 1] - 2 * around[1, 1] + around[0, 1],
                             0.25 * (around[2, 2] - around[2, 0] - around[0, 2] + around[0, 0])],
                            [0.0, around[1, 2] - 2 * around[1, 1] + around[1, 0]]])
        hessian[1, 0] = hessian[0, 1]
        if hessian[0, 0] < 0 and np.linalg.det(hessian) > 0:  # a maximum: the Newton step to the vertex
            best, offset = i, float(-np.linalg.solve(hessian, gradient)[0])
    offset = min(max(offset, -1.0), 1.0)
    return float(a_nodes[best] + offset * (a_nodes[best + 1] - a_nodes[best])), True


@pytest.mark.parametrize("task", ["hyst_gym/HotCalibrate-v0", "hyst_gym/HotCalibrateNoisy-v0",
                                  "hyst_gym/DisplacementOnly-v0", "hyst_gym/HotCalibrateUnknownK-v0"])
def test_posterior_matches_a_slow_recomputation_per_node(task):
    env = gymnasium.make(task)
    posterior = env.unwrapped.posterior
    slow = _slow_nodes(posterior)
    channels, sigma = posterior.channels, posterior.config.output_noise
    log_post = np.repeat(posterior.log_prior, posterior.k_nodes).astype(float)
    observation, _ = env.reset(seed=7)
    rng = np.random.default_rng(3)
    concentrated, dead_gaps = [], []
    for t in range(40):  # up (the field moves 2.5 % of its limit per step), then random
        field = np.ones(1, np.float32) if t < 30 else rng.uniform(-1.0, 1.0, (1,)).astype(np.float32)
        if t > 0:  # the outputs of step t - 1 against the nodes' outputs after it
            predicted = slow.measured[:, channels] / slow.scales[channels]
            residual = observation[:len(channels)].astype(np.float64) - predicted
            log_post -= 0.5 * np.sum(residual ** 2, axis=1) / sigma ** 2
        slow.step(np.column_stack([np.full(slow.n, float(field[0])), np.zeros(slow.n)]))
        observation, _, terminated, truncated, info = env.step(field)
        assert not (terminated or truncated)
        # the same physics kernels move the alive node plants (the posterior prunes the dead ones, whose weight is
        # 0.0: their log-posterior lies far below the best node's): their outputs and a agree bit for bit
        alive = posterior.alive()[0].ravel()
        assert np.array_equal(posterior.sim.measured[alive], slow.measured[alive])
        assert np.array_equal(posterior.sim.a_true[alive], slow.a_true[alive])
        np.testing.assert_allclose(posterior.log_post.ravel()[alive], log_post[alive], rtol=1e-12, atol=1e-9)
        dead_gaps.append(log_post.max() - log_post[~alive].max() if not alive.all() else np.inf)
        log_joint = log_post.reshape(posterior.nodes, posterior.k_nodes)
        expected, peaked = _bayes_estimate(log_joint, slow.a_true[::posterior.k_nodes])
        concentrated.append(peaked)
        assert posterior.estimate()[0] == pytest.approx(expected, rel=1e-9)
        # the estimate reaches the simulator as the action's float32 on [-1, 1]: its rounding, no more
        float32_step = posterior.config.theta_width * 2.0 ** -23
        assert info["a_estimate"] == pytest.approx(expected, rel=0.0, abs=float32_step)
    # the estimate above is the full posterior's, dead nodes included: pruning changed it by nothing, and the dead
    # nodes' weight in the full posterior is 0.0 (their T0 nodes' marginals lie past exp's underflow)
    assert min(dead_gaps) > -EXP_ZERO_BELOW + np.log(posterior.k_nodes)
    if task in ("hyst_gym/HotCalibrate-v0", "hyst_gym/HotCalibrateUnknownK-v0"):  # mean, then vertex
        assert not concentrated[0] and any(concentrated)
        assert np.isfinite(dead_gaps[-1])  # nodes died: the pruned path was exercised
