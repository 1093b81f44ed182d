"""PolicyAgent rebuilds SB3's VecFrameStack exactly, so trained policies see what they were trained on."""

import numpy as np


def test_policy_agent_frame_stack_matches_vecframestack():
    import gymnasium
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecFrameStack

    from baselines.rl import PolicyAgent

    n_stack = 4
    venv = VecFrameStack(DummyVecEnv([lambda: gymnasium.make("Pendulum-v1", max_episode_steps=7)] * 2), n_stack)
    venv.seed(3)
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, seed=0, device="cpu",
                policy_kwargs={"net_arch": [8]})
    agent = PolicyAgent(model, n_stack)
    stacked = venv.reset()
    raw_obs = stacked[:, -3:]  # newest frame is last
    episode_start = np.ones(2, dtype=bool)
    for _ in range(20):  # crosses the 7-step episode boundary
        expected, _ = model.predict(stacked, deterministic=True)
        actions, _ = agent.predict(raw_obs, episode_start=episode_start, deterministic=True)
        np.testing.assert_allclose(actions, expected, rtol=1e-6)
        stacked, _, dones, infos = venv.step(expected)
        raw_obs = stacked[:, -3:]
        episode_start = dones
