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


# --- recurrent policy (sb3-contrib RecurrentPPO): the LSTM state is the history ---------------

def _untrained_recurrent_model():
    """An untrained RecurrentPPO on Pendulum (3-D observation): its LSTM is random but real."""
    import gymnasium
    from sb3_contrib import RecurrentPPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    venv = DummyVecEnv([lambda: gymnasium.make("Pendulum-v1")])
    return RecurrentPPO("MlpLstmPolicy", venv, n_steps=16, batch_size=16, seed=0, device="cpu",
                        policy_kwargs={"lstm_hidden_size": 8, "net_arch": [8]})


def _observations(steps, n, seed=0):
    return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(steps, n, 3)).astype(np.float32)


def _play(agent, observations, starts):
    agent.reset()
    return np.stack([agent.predict(obs, episode_start=start, deterministic=True)[0]
                     for obs, start in zip(observations, starts)])


def test_recurrent_agent_is_deterministic_and_history_dependent():
    from baselines.rl import PolicyAgent

    agent = PolicyAgent(_untrained_recurrent_model())
    assert agent.recurrent
    observations = _observations(12, 1)
    starts = [np.array([i == 0]) for i in range(12)]
    first, second = _play(agent, observations, starts), _play(agent, observations, starts)
    np.testing.assert_array_equal(first, second)  # reset() clears the LSTM state
    agent.reset()  # ... even when the caller flags no episode start
    no_flags = np.stack([agent.act_batch(obs, np.zeros(1, dtype=bool)) for obs in observations])
    np.testing.assert_array_equal(no_flags, first)

    # the same observation after two different histories: the LSTM state makes the action differ
    repeated = observations.copy()
    repeated[:, 0] = observations[-1, 0]  # constant input: a different history for the last frame
    other = _play(agent, repeated, starts)
    np.testing.assert_array_equal(repeated[-1], observations[-1])
    assert np.abs(other[-1] - first[-1]).max() > 1e-6

    # and it matches RecurrentPPO's own predict loop with the state threaded by hand
    state, expected = None, []
    for obs, start in zip(observations, starts):
        action, state = agent.model.predict(obs, state=state, episode_start=start, deterministic=True)
        expected.append(action)
    np.testing.assert_allclose(first, np.stack(expected), rtol=1e-6)


def test_recurrent_episode_start_resets_only_that_sub_env():
    from baselines.rl import PolicyAgent

    agent = PolicyAgent(_untrained_recurrent_model())
    steps, restart = 10, 6
    observations = _observations(steps, 2, seed=1)
    starts = [np.array([i == 0, i in (0, restart)]) for i in range(steps)]
    batch = _play(agent, observations, starts)

    single = PolicyAgent(_untrained_recurrent_model())
    untouched = _play(single, observations[:, :1], [np.array([i == 0]) for i in range(steps)])
    restarted = _play(single, observations[restart:, 1:], [np.array([i == 0]) for i in range(steps - restart)])
    np.testing.assert_allclose(batch[:, :1], untouched, rtol=1e-6)  # sub-env 0 kept its state
    np.testing.assert_allclose(batch[restart:, 1:], restarted, rtol=1e-6)  # sub-env 1 began afresh
    continued = _play(single, observations[:, 1:], [np.array([i == 0]) for i in range(steps)])
    assert np.abs(continued[restart:] - restarted).max() > 1e-6  # so the restart did change something


def test_recurrent_agent_rejects_frame_stack():
    import pytest

    from baselines.rl import PolicyAgent

    with pytest.raises(ValueError, match="n_stack must be 1"):
        PolicyAgent(_untrained_recurrent_model(), n_stack=4)


def test_train_recurrent_ppo_saves_loads_and_resumes(tmp_path):
    import json

    import pytest

    from baselines.evaluation import run_episodes
    from baselines.rl import PolicyAgent
    from baselines.scenarios import scenario_spec
    from baselines.train import train

    spec = scenario_spec("paper")
    small = {"n_steps": 32, "batch_size": 32}
    out = tmp_path / "rppo"
    path = train("recurrent_ppo", spec, 128, 0, out, n_envs=2, checkpoint_every=64, eval_every=128,
                 eval_episodes=1, hyperparams=small, progress=False)
    assert path == out / "model.zip" and path.exists()
    config = json.loads((out / "config.json").read_text())
    assert config["algo"] == "recurrent_ppo" and config["policy"] == "MlpLstmPolicy"
    assert config["n_stack"] == 1 and config["trained_steps"] == 128
    assert config["hyperparams"]["policy_kwargs"]["lstm_hidden_size"] == 64
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == ["model_128_steps.zip", "model_64_steps.zip"]
    assert len((out / "learning_curve.csv").read_text().strip().splitlines()) == 2  # header + one point
    assert_last_curve_point_scores_the_saved_model(out, spec)

    agent = PolicyAgent.load(out)
    assert agent.recurrent and agent.name == "recurrent_ppo"
    assert type(agent.model).__name__ == "RecurrentPPO"
    records, _ = run_episodes(agent, spec, [7])
    assert records[0]["steps"] == 1000 and np.isfinite(records[0]["rms_error"])
    actions, _ = agent.predict(np.zeros((3, agent.model.observation_space.shape[0])), deterministic=True)
    space = agent.model.action_space
    assert actions.shape == (3, *space.shape) and np.all((actions >= space.low) & (actions <= space.high))

    train("recurrent_ppo", spec, 192, 0, out, n_envs=2, checkpoint_every=0, hyperparams=small,
          resume=True, progress=False)
    assert json.loads((out / "config.json").read_text())["trained_steps"] == 192

    with pytest.raises(ValueError, match="--n-stack must be 1"):
        train("recurrent_ppo", spec, 64, 0, tmp_path / "bad", n_envs=2, n_stack=8, progress=False)


def assert_last_curve_point_scores_the_saved_model(out, spec):
    """The curve's last row is the validation score of model.zip itself, not of the policy
    before the last update (the periodic points fall inside rollouts)."""
    import csv

    from baselines.rl import PolicyAgent
    from baselines.train import record_learning_point

    with (out / "learning_curve.csv").open() as handle:
        last = list(csv.DictReader(handle))[-1]
    agent = PolicyAgent.load(out)
    rescored = record_learning_point(agent.model, out, spec, agent.n_stack, 1)
    assert int(last["env_steps"]) == rescored["env_steps"]
    assert float(last["rms_error_iqm"]) == rescored["rms_error_iqm"]
    assert float(last["settle_time_iqm_s"]) == rescored["settle_time_iqm_s"]


def test_final_point_and_resume_under_changed_settings(tmp_path):
    """PPO with eval_every a multiple of the rollout: the periodic point at the final step
    predates the last update and must be replaced. --resume with another reward or other
    hyperparameters is refused before anything is trained or written."""
    import json

    import pytest

    from baselines.scenarios import scenario_spec
    from baselines.train import train

    spec = scenario_spec("paper")
    out = tmp_path / "ppo"
    # a learning rate large enough that the last update changes the validation score
    small = {"n_steps": 32, "batch_size": 32, "learning_rate": 3e-3}
    train("ppo", spec, 128, 0, out, n_envs=2, n_stack=2, checkpoint_every=0, eval_every=64, eval_episodes=1,
          hyperparams=small, progress=False)
    steps = [int(line.split(",")[0]) for line in (out / "learning_curve.csv").read_text().splitlines()[1:]]
    assert steps == [64, 128]
    assert_last_curve_point_scores_the_saved_model(out, spec)

    saved = (out / "config.json").read_text()
    for changed, message in (({"reward": "information"}, "reward"),
                             ({"hyperparams": {**small, "learning_rate": 0.5}}, "hyperparams")):
        kwargs = {"hyperparams": small, **changed}
        with pytest.raises(ValueError, match=f"--resume under other settings \\({message}\\)"):
            train("ppo", spec, 256, 0, out, n_envs=2, n_stack=2, checkpoint_every=0, resume=True, progress=False,
                  **kwargs)
        assert (out / "config.json").read_text() == saved
    assert json.loads(saved)["trained_steps"] == 128



def test_training_leaves_the_default_hyperparameters_alone(tmp_path):
    """SB3's SAC writes use_sde into policy_kwargs: neither the module defaults nor the
    recorded config may pick that up (a resume compares the recorded config)."""
    import copy
    import json

    from baselines.scenarios import scenario_spec
    from baselines.train import DEFAULT_HYPERPARAMS, changed_settings, train

    before = copy.deepcopy(DEFAULT_HYPERPARAMS)
    small = {"learning_starts": 8, "batch_size": 8, "gradient_steps": 1}
    train("sac", scenario_spec("paper"), 16, 0, tmp_path, n_envs=2, checkpoint_every=0, hyperparams=small,
          progress=False)
    assert DEFAULT_HYPERPARAMS == before
    saved = json.loads((tmp_path / "config.json").read_text())
    assert saved["hyperparams"] == {**before["sac"], **small}
    assert changed_settings(tmp_path, "sac", 8, "dense", {**DEFAULT_HYPERPARAMS["sac"], **small}) == []
