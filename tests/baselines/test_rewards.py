"""The information-increment reward wrapper (baselines/rewards.py)."""

import numpy as np
import pytest

from baselines.rewards import InformationRewardVecEnv, information_increment
from baselines.scenarios import SCENARIOS


def _wrapped(n, seed=0):
    from hyst_gym.envs.sb3 import make_sb3_vec_env

    spec = SCENARIOS["paper"].spec()
    adapter = make_sb3_vec_env(spec.env_id, num_envs=n, seed=seed, max_episode_steps=spec.max_episode_steps,
                               **spec.env_kwargs)
    return InformationRewardVecEnv(adapter)


def _sweep(amplitude, steps):
    """Normalized field command: up to +amplitude, down to -amplitude, and back (slew-limited by the env)."""
    phase = np.linspace(0.0, 1.0, steps, endpoint=False)
    return amplitude * np.sin(2 * np.pi * phase)


def test_reward_is_the_squared_normalized_slope():
    assert information_increment(-5.0, 10.0) == pytest.approx(0.25)
    assert information_increment(0.0) == 0.0
    with pytest.raises(ValueError, match="slope_scale"):
        information_increment(1.0, 0.0)


def test_reward_nonnegative_zero_at_rest_and_larger_for_a_wider_sweep():
    # sub-env 0 holds H = 0 (demagnetized: M = 0 for every a, so no information);
    # sub-envs 1 and 2 sweep at 20 % and 100 % of the field limit
    env = _wrapped(3)
    env.reset()
    steps = 400
    totals = np.zeros(3)
    dense = np.zeros(3)
    for k in range(steps):
        actions = np.array([[0.0], [_sweep(0.2, steps)[k]], [_sweep(1.0, steps)[k]]], dtype=np.float32)
        _, rewards, dones, infos = env.step(actions)
        assert not dones.any()
        assert np.all(rewards >= 0.0) and np.all(np.isfinite(rewards))
        totals += rewards
        dense += [info["dense_reward"] for info in infos]
    env.close()
    assert totals[0] == 0.0
    assert 0.0 < totals[1] < totals[2]
    assert np.all(dense < 0.0)  # the env's own error reward is still reported, and differs


def test_rejects_an_env_without_the_built_in_estimator():
    from stable_baselines3.common.vec_env import DummyVecEnv

    spec = SCENARIOS["paper"].spec()
    with pytest.raises(ValueError, match="built-in estimator"):
        InformationRewardVecEnv(DummyVecEnv([spec.make]))
