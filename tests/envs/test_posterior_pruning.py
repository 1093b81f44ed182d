"""The grid posterior's pruning (posterior.py, "Pruning") changes no estimate: side by side with the unpruned
posterior, over whole episodes of the calibration tasks under the inputs of the benchmark (random actions), an
open-loop sine and a feedback hold, with auto-resets (time limits and terminations), the estimate and the spread agree
bit for bit at every step of every sub-env."""

import gymnasium
import numpy as np
import pytest

import hyst_gym  # noqa: F401
from hyst_gym.envs.posterior import CONCENTRATED, DEAD_GAP, EXP_ZERO_BELOW, K_TASK_NODES, GridPosterior

#: sub-envs per env and steps per input: three episodes of 200 steps each
SUB_ENVS, STEPS = 32, 600


def _pair(task, seed):
    """Two native vector envs of the task seeded alike, the first's posterior unpruned, the second's pruned."""
    envs = []
    for prune in (False, True):
        env = gymnasium.make_vec(task, num_envs=SUB_ENVS, vectorization_mode="vector_entry_point")
        inner = env.unwrapped
        inner.posterior = GridPosterior(inner.config, inner.posterior.channels, SUB_ENVS, inner.k_prior,
                                        inner.posterior.nodes, inner.posterior.k_nodes, prune=prune)
        envs.append((env, env.reset(seed=seed)[0]))
    return envs


def _inputs(name, observation, heat_column, t, rng):
    """The field command of every sub-env at step ``t`` under input ``name``."""
    if name == "random":  # the benchmark's (experiments.suite.common.env_speed)
        return rng.uniform(-1.0, 1.0, (SUB_ENVS, 1))
    if name == "sine":  # the calibration tasks' tuned open-loop design: 40 kA/m + 40 kA/m sin(2 pi 0.5 Hz t)
        phase = 2.0 * np.pi * 0.5 * 0.05 * t + np.arange(SUB_ENVS)  # dt 0.05 s; the sub-envs out of phase
        return (0.4 + 0.4 * np.sin(phase))[:, None]
    # feedback: full field until the coil has used most of its heat margin, then off
    return np.where(observation[:, heat_column] < 0.8, 1.0, 0.0)[:, None]


@pytest.mark.parametrize("task", ["hyst_gym/HotCalibrate-v0", "hyst_gym/HotCalibrateUnknownK-v0"])
def test_the_pruned_posterior_reports_the_unpruned_numbers_bit_for_bit(task):
    alive_fractions, concentrated, resets, terminations = [], 0, 0, 0
    for seed, name in enumerate(("random", "sine", "hold")):
        (full, observation), (pruned, _) = _pair(task, 100 * seed)
        heat_column = full.unwrapped.kept_names.index("heat_used")
        rng = np.random.default_rng(seed)
        for t in range(STEPS):
            action = _inputs(name, observation, heat_column, t, rng).astype(np.float32)
            observation, _, terminated, truncated, _ = full.step(action)
            other, _, terminated_too, truncated_too, _ = pruned.step(action)
            resets += int(terminated.sum() + truncated.sum())
            terminations += int(terminated.sum())
            assert np.array_equal(observation, other) and np.array_equal(terminated, terminated_too), (name, t)
            assert np.array_equal(truncated, truncated_too), (name, t)
            reference, posterior = full.unwrapped.posterior, pruned.unwrapped.posterior
            for statistic in ("estimate", "spread"):
                want, got = getattr(reference, statistic)(), getattr(posterior, statistic)()
                assert np.array_equal(want.view(np.int64), got.view(np.int64)), (name, t, statistic)
            alive_fractions.append(posterior.alive().mean())
            concentrated += int((posterior._marginal()["weights"].max(axis=1) > CONCENTRATED).sum())
    # the comparison is not vacuous: most node-steps were pruned at times, the vertex estimate was reported, and
    # sub-envs were reset and revived in the middle of the batch, at time limits and at terminations (a coil past its
    # temperature limit or an output past its bound)
    assert min(alive_fractions) < 0.5 and concentrated > 0 and resets >= 3 * SUB_ENVS and terminations > 0


def test_the_dead_gap_lies_past_the_underflow_of_exp_for_every_k_marginal():
    # the marginal over k of a T0 node lies at most log(k_nodes) above its best k node: past DEAD_GAP, below the
    # underflow of exp, with room for a comeback of evidence
    assert DEAD_GAP > -EXP_ZERO_BELOW + np.log(K_TASK_NODES[1]) + 100.0
