"""Suite v2 task envs (issue 23): registration, prior, sensors, jumps, single == vector, errors."""

import gymnasium
import numpy as np
import pytest

import hyst_gym  # noqa: F401
from hyst_gym.envs.registration import SUITE_V2_IDS
from hyst_gym.envs.suite_v2 import TASKS_V2


def _vec(task_id, n, **kw):
    return gymnasium.make_vec(task_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)


def test_every_task_is_registered_and_documented():
    assert set(SUITE_V2_IDS) == set(TASKS_V2)
    for task_id in SUITE_V2_IDS:
        doc = type(gymnasium.make(task_id).unwrapped).__doc__
        for section in ("## Description", "## Action Space", "## Observation Space", "## Rewards",
                        "## Starting State", "## Episode End", "## Arguments", "## Version History"):
            assert section in doc, (task_id, section)


def test_calibration_prior_is_the_raised_cosine():
    venv = _vec("hyst_gym/HotCalibrate-v0", 2000)
    venv.reset(seed=0)
    low, high = venv.unwrapped.config.initial_temperature_range
    x = (venv.unwrapped.sim.temperature - low) / (high - low)
    # raised cosine on [0, 1]: mean 1/2, variance 1/12 - 1/(2 pi^2) = 0.0327 (uniform: 0.0833)
    assert abs(x.mean() - 0.5) < 0.01
    assert abs(x.var() - (1 / 12 - 1 / (2 * np.pi ** 2))) < 0.003


def test_displacement_only_hides_the_velocity():
    env = gymnasium.make("hyst_gym/DisplacementOnly-v0")
    assert env.unwrapped.observation_names == ["displacement", "field", "elapsed", "previous_estimate"]
    obs, _ = env.reset(seed=3)
    assert obs.shape == env.observation_space.shape == (4,)
    full = env.unwrapped.sim.observation()[0]
    assert full.shape == (5,) and np.array_equal(obs, full[[0, 2, 3, 4]])


def test_jump_moves_a_at_the_drawn_step():
    env = gymnasium.make("hyst_gym/DriftJump-v0").unwrapped
    env.reset(seed=5, options={"ambient_drift_rate": 0.0})
    step, change = int(env.jump_step[0]), float(env.jump_change[0])
    assert 40 <= step < 160 and 5 <= abs(change) <= 12
    a = []
    for _ in range(step + 2):
        a.append(env.step(np.zeros(1, dtype=np.float32))[4]["a_true"])
    slope = 7012.0 / 293.15
    assert abs(a[step] - a[step - 1] - slope * change) < 1.0      # the jump, within a step of cooling
    assert abs(a[step - 1] - a[step - 2]) < 0.5
    env.reset(seed=5, options={"jump_step": 7, "jump_change": -6.0})
    assert env.jump_step[0] == 7 and env.jump_change[0] == -6.0


@pytest.mark.parametrize("task_id", ["hyst_gym/DriftJump-v0", "hyst_gym/DisplacementOnly-v0"])
def test_single_equals_vector_and_is_deterministic(task_id):
    n, steps = 3, 120
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (steps, n, 2 if "Displacement" in task_id else 1)).astype(np.float32)
    venv = _vec(task_id, n)
    vobs, _ = venv.reset(seed=11)
    singles = [gymnasium.make(task_id) for _ in range(n)]
    sobs = [env.reset(seed=11 + i)[0] for i, env in enumerate(singles)]
    assert np.array_equal(vobs, np.array(sobs))
    for t in range(steps):
        vobs, vrew, _, _, vinfo = venv.step(actions[t])
        for i, env in enumerate(singles):
            obs, reward, _, _, info = env.step(actions[t, i])
            assert np.array_equal(obs, vobs[i]) and reward == vrew[i] and info["a_true"] == vinfo["a_true"][i]


def test_bad_jump_option_is_one_error():
    env = gymnasium.make("hyst_gym/DriftJump-v0")
    with pytest.raises(ValueError, match="jump_step"):
        env.reset(seed=0, options={"jump_step": 0.5})
    with pytest.raises(ValueError, match="unknown suite v2 task"):
        gymnasium.make("hyst_gym/DriftJump-v0", task="hyst_gym/Nope-v0")


@pytest.mark.parametrize("task_id", ["hyst_gym/DriftJump-v0", "hyst_gym/DisplacementOnly-v0"])
def test_sb3_adapter_trains_a_few_steps(task_id):
    """Stable-Baselines3 on the native vector env (SAME_STEP autoreset): episodes end and restart with the
    task's own observation size and a fresh jump."""
    from stable_baselines3 import PPO

    from hyst_gym.envs import make_sb3_vec_env

    venv = make_sb3_vec_env(task_id, num_envs=2, seed=0, episode_steps=30)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(128)
    assert venv.observation_space.shape == gymnasium.make(task_id).observation_space.shape
