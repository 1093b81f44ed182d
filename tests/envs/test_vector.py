"""The native vector env equals a SyncVectorEnv of single envs, step for step, autoreset included."""

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from hyst_gym.envs.vector import HystVectorEnv

from envs_helpers import SHORT, random_actions


def _pair(env_id, n, mode=AutoresetMode.NEXT_STEP, **kwargs):
    native = gymnasium.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                                autoreset_mode=mode, **kwargs)
    sync = SyncVectorEnv([lambda: gymnasium.make(env_id, **kwargs) for _ in range(n)], autoreset_mode=mode)
    return native, sync


def _assert_infos_equal(a, b, keys):
    for key in keys:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        np.testing.assert_array_equal(a["_" + key], b["_" + key], err_msg="_" + key)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_native_equals_sync_step_for_step(env_id, mode):
    n = 4
    # a PRBS schedule so that the scheduled field of Estimation-v0 ends episodes both ways
    native, sync = _pair(env_id, n, mode, **SHORT, schedule="prbs", schedule_offset=0.03, schedule_amplitude=0.03,
                         schedule_period=0.1)
    assert isinstance(native.unwrapped, HystVectorEnv)
    obs_n, info_n = native.reset(seed=42)
    obs_s, info_s = sync.reset(seed=42)
    np.testing.assert_array_equal(obs_n, obs_s)
    keys = [k for k in info_s if not k.startswith("_")]
    _assert_infos_equal(info_n, info_s, keys)
    actions = random_actions(native.action_space, 150, seed=1)
    ends = {"terminated": 0, "truncated": 0}
    for action in actions:
        out_n = native.step(action)
        out_s = sync.step(action)
        for a, b in zip(out_n[:4], out_s[:4]):
            np.testing.assert_array_equal(a, b)
        _assert_infos_equal(out_n[4], out_s[4], keys)
        if mode == AutoresetMode.SAME_STEP and "final_obs" in out_s[4]:
            np.testing.assert_array_equal(out_n[4]["_final_obs"], out_s[4]["_final_obs"])
            for i in np.flatnonzero(out_s[4]["_final_obs"]):
                np.testing.assert_array_equal(out_n[4]["final_obs"][i], out_s[4]["final_obs"][i])
            _assert_infos_equal(out_n[4]["final_info"], out_s[4]["final_info"], keys)
        ends["terminated"] += int(out_s[2].sum())
        ends["truncated"] += int(out_s[3].sum())
    # the comparison covered both kinds of episode end (and so the autoreset paths)
    assert ends["terminated"] > 0 and ends["truncated"] > 0


def test_sub_envs_have_their_own_seed_streams():
    native = gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=3, vectorization_mode="vector_entry_point")
    _, info = native.reset(seed=9)
    assert len(set(info["a_true"].tolist())) == 3
    single = gymnasium.make("hyst_gym/Excitation-v0")
    for i in range(3):
        assert single.reset(seed=9 + i)[1]["a_true"] == info["a_true"][i]
    # seeding by list, and one sub-env's stream does not depend on the batch size
    wide = gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=5, vectorization_mode="vector_entry_point")
    _, info_wide = wide.reset(seed=[9, 10, 11, 3, 4])
    np.testing.assert_array_equal(info_wide["a_true"][:3], info["a_true"])
    _, again = native.reset()
    assert not np.any(again["a_true"] == info["a_true"])


def test_vector_time_limit_follows_max_episode_steps():
    native = gymnasium.make_vec("hyst_gym/Estimation-v0", num_envs=2, vectorization_mode="vector_entry_point",
                                max_episode_steps=5)
    native.reset(seed=0)
    for _step in range(5):
        _, _, terminated, truncated, _ = native.step(np.zeros((2, 1)))
    assert truncated.all() and not terminated.any()


def test_an_identification_step_in_two_threads_gives_the_one_kernel_step_and_survives_a_copy(monkeypatch):
    # the simulator moves its plants and model bank in two blocks of sub-envs in two threads (core, _split_plants,
    # from SPLIT_MIN_NODES bank models): the numbers of the one-kernel step (identification_step), and a pickled copy
    # makes blocks of its own arrays (a pickled view would be an array no longer the copy's)
    import pickle

    from hyst_gym.envs import core as core_module

    def make():
        env = gymnasium.make_vec("hyst_gym/Identification-v0", num_envs=16, vectorization_mode="vector_entry_point")
        env.reset(seed=5)
        return env

    def assert_same_bits(a, b):
        for x, y in zip(a[:4], b[:4]):
            assert x.tobytes() == y.tobytes()
        for key in a[4]:
            assert a[4][key].tobytes() == b[4][key].tobytes(), key

    one = make()
    monkeypatch.setattr(core_module, "SPLIT_MIN_NODES", 1)
    monkeypatch.setattr(core_module, "step_threads", lambda: 2)
    two = make()
    assert not one.unwrapped.sim._plant_blocks and len(two.unwrapped.sim._plant_blocks) == 2
    actions = random_actions(one.action_space, 120, seed=2)
    for action in actions[:60]:
        assert_same_bits(one.step(action), two.step(action))
    copy = pickle.loads(pickle.dumps(two))
    sim = copy.unwrapped.sim
    assert np.shares_memory(sim._plant_blocks[1][1][0][0], sim.field)  # views of the copy's own arrays
    for action in actions[60:]:
        results = [env.step(action) for env in (one, two, copy)]
        assert_same_bits(results[0], results[1])
        assert_same_bits(results[0], results[2])
