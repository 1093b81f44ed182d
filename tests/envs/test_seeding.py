"""Seeding: same seed identical, different seeds differ, unseeded resets fresh, global RNG untouched."""

import numpy as np

from envs_helpers import make, random_actions, rollout


def _trajectory(env, actions, seed):
    return rollout(env, actions, seed)


def _same(a, b):
    assert len(a) == len(b)
    for (o1, r1, te1, tr1, i1), (o2, r2, te2, tr2, i2) in zip(a, b):
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2 and te1 == te2 and tr1 == tr2
        assert i1 == i2


def test_same_seed_gives_identical_trajectories(env_id):
    actions = random_actions(make(env_id).action_space, 60, seed=3)
    first = _trajectory(make(env_id), actions, seed=11)
    second = _trajectory(make(env_id), actions, seed=11)
    _same(first, second)
    env = make(env_id)  # and on the same env object, after other episodes
    _trajectory(env, actions, seed=5)
    _trajectory(env, actions, seed=None)
    _same(first, _trajectory(env, actions, seed=11))


def test_different_seeds_differ(env_id):
    actions = random_actions(make(env_id).action_space, 20, seed=3)
    a = _trajectory(make(env_id), actions, seed=1)
    b = _trajectory(make(env_id), actions, seed=2)
    assert a[0][4]["a_true"] != b[0][4]["a_true"]
    assert not np.array_equal(a[-1][0], b[-1][0])


def test_noise_stream_is_independent_of_episode_stream():
    # The episode draws (temperature) do not move when the noise level changes.
    quiet = make("hyst_gym/Excitation-v0", output_noise=0.0).reset(seed=4)[1]
    noisy = make("hyst_gym/Excitation-v0", output_noise=1e-2).reset(seed=4)[1]
    assert quiet["a_true"] == noisy["a_true"]


def test_unseeded_resets_do_not_repeat():
    env = make("hyst_gym/Excitation-v0")
    draws = [env.reset()[1]["temperature"] for _ in range(5)]
    assert len(set(draws)) == 5
    fresh = [make("hyst_gym/Excitation-v0").reset()[1]["temperature"] for _ in range(3)]
    assert len(set(fresh)) == 3
    env.reset(seed=7)
    after_seed = [env.reset()[1]["temperature"] for _ in range(3)]
    env.reset(seed=7)
    again = [env.reset()[1]["temperature"] for _ in range(3)]
    assert after_seed == again and len(set(after_seed)) == 3


def test_global_numpy_rng_untouched(env_id):
    state = np.random.get_state()
    env = make(env_id)
    rollout(env, random_actions(env.action_space, 30, seed=0), seed=None)
    rollout(env, random_actions(env.action_space, 30, seed=1), seed=5)
    after = np.random.get_state()
    assert state[0] == after[0] and np.array_equal(state[1], after[1]) and state[2:] == after[2:]
