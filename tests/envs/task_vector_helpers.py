"""Checks shared by the tests of the tasks with their own vector env (dual control, discriminate)."""

import gymnasium
import numpy as np
from gymnasium.utils.env_checker import check_env


def assert_single_is_sub_env(task: str, single_class, seed: int, scale: float, steps: int = 30) -> None:
    """``gymnasium.make(task)`` is ``single_class``, passes Gymnasium's checker, and gives sub-env 0's numbers of
    the native vector env seeded alike, under random actions in [-scale, scale] (until its episode ends)."""
    single = gymnasium.make(task)
    assert type(single.unwrapped) is single_class
    check_env(single.unwrapped, skip_render_check=True)
    vector = gymnasium.make_vec(task, num_envs=2, vectorization_mode="vector_entry_point")
    obs_s, _ = single.reset(seed=seed)
    obs_v, _ = vector.reset(seed=[seed, seed + 1])
    assert np.array_equal(obs_s, obs_v[0])
    rng = np.random.default_rng(0)
    for _ in range(steps):
        action = rng.uniform(-scale, scale, (2, 1)).astype(np.float32)
        obs_s, r_s, term_s, trunc_s, _ = single.step(action[0])
        obs_v, r_v, *_ = vector.step(action)
        assert np.array_equal(obs_s, obs_v[0]) and r_s == r_v[0]
        if term_s or trunc_s:
            break
