"""Registration from a fresh interpreter, pickling / SubprocVecEnv, SB3 adapter + PPO, rendering."""

import os
import pickle
import subprocess
import sys
import textwrap

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from envs_helpers import random_actions


def test_make_in_fresh_interpreter_importing_nothing_of_ours():
    script = textwrap.dedent("""
        import sys, gymnasium
        assert "hyst_gym" not in sys.modules
        env = gymnasium.make("hyst_gym:hyst_gym/Excitation-v0")
        obs, info = env.reset(seed=0)
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        venv = gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=3, vectorization_mode="vector_entry_point")
        print(type(env.unwrapped).__name__, type(venv).__name__, obs.shape, venv.reset(seed=0)[0].shape)
    """)
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd="/", env=env,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["ExcitationEnv", "ExcitationVectorEnv", "(7,)", "(3,", "7)"]


def test_pickle_round_trip_continues_identically(env_id):
    env = gymnasium.make(env_id)
    env.reset(seed=3)
    actions = random_actions(env.action_space, 40, seed=0)
    for action in actions[:20]:
        env.step(action)
    clone = pickle.loads(pickle.dumps(env))
    for action in actions[20:]:
        a = env.step(action)
        b = clone.step(action)
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:] == b[1:]


def test_subproc_vec_env():
    from stable_baselines3.common.vec_env import SubprocVecEnv
    venv = SubprocVecEnv([lambda: gymnasium.make("hyst_gym/Excitation-v0") for _ in range(2)], start_method="fork")
    try:
        venv.seed(5)
        obs = venv.reset()
        assert obs.shape == (2, 7)
        obs, rewards, dones, infos = venv.step(np.zeros((2, 1), dtype=np.float32))
        assert np.all(np.isfinite(rewards)) and "a_true" in infos[0]
    finally:
        venv.close()


def test_sb3_adapter_semantics():
    from hyst_gym.envs import make_sb3_vec_env
    venv = make_sb3_vec_env("hyst_gym/Excitation-v0", num_envs=3, seed=0, info_keys=("a_true",),
                            episode_steps=5)
    obs = venv.reset()
    assert obs.shape == (3, 7) and obs.dtype == np.float32
    for _step in range(5):
        obs, rewards, dones, infos = venv.step(np.zeros((3, 1), dtype=np.float32))
    assert dones.all()
    for info in infos:
        assert info["TimeLimit.truncated"] is True
        assert info["terminal_observation"].shape == (7,)
        assert info["terminal_observation"][2] == pytest.approx(1.0)  # elapsed fraction at the end
    assert np.allclose(obs[:, 2], 0.0)  # already reset
    with pytest.raises(ValueError, match="SAME_STEP"):
        from hyst_gym.envs import SB3VecEnvAdapter
        SB3VecEnvAdapter(gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=2,
                                            vectorization_mode="vector_entry_point"))


def test_short_ppo_run_on_native_vector_env():
    from stable_baselines3 import PPO
    from hyst_gym.envs import make_sb3_vec_env
    venv = make_sb3_vec_env("hyst_gym/Excitation-v0", num_envs=8, seed=0, episode_steps=200)
    model = PPO("MlpPolicy", venv, n_steps=128, batch_size=256, n_epochs=2, seed=0, device="cpu", verbose=0)
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(total_timesteps=4096)
    assert model.num_timesteps >= 4096
    # the rollouts from the native vector env reached the optimizer: the policy moved
    assert any(not np.allclose(b.numpy(), p.detach().numpy()) for b, p in zip(before, model.policy.parameters()))
    obs = venv.reset()
    assert obs.shape == (8,) + venv.observation_space.shape and np.all(np.isfinite(obs))
    action, _ = model.predict(obs, deterministic=True)
    assert action.shape == (8, 1)


def test_rgb_array_frame_and_png(tmp_path):
    from hyst_gym.envs import record_episode
    env = gymnasium.make("hyst_gym/Excitation-v0", render_mode="rgb_array", episode_steps=60)
    history = record_episode(env, policy=lambda obs: np.array([0.8], dtype=np.float32), seed=0,
                             path=tmp_path / "episode.png")
    assert len(history) == 61
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    assert frame.std() > 10  # something was drawn
    with open(tmp_path / "episode.png", "rb") as handle:
        assert handle.read(8) == b"\x89PNG\r\n\x1a\n"
    venv = gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=2, vectorization_mode="vector_entry_point",
                              render_mode="rgb_array", autoreset_mode=AutoresetMode.NEXT_STEP)
    venv.reset(seed=0)
    venv.step(np.zeros((2, 1)))
    frames = venv.render()
    assert len(frames) == 2 and frames[0].shape == frame.shape
