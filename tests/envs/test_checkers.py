"""Gymnasium's and Stable-Baselines3's env checkers pass on every id, with every warning an error."""

import warnings

import gymnasium
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from envs_helpers import ENV_IDS


def test_ids_registered_with_vector_entry_point_and_time_limit():
    for env_id in ENV_IDS:
        spec = gymnasium.spec(env_id)
        assert spec.vector_entry_point is not None
        # no registered limit: the env truncates itself at its own episode_steps (issue 14)
        assert spec.max_episode_steps is None


def test_gymnasium_check_env(env_id):
    env = gymnasium.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gym_check_env(env.unwrapped)


def test_gymnasium_check_env_with_sensor_and_mechanical_transducer():
    env = gymnasium.make("hyst_gym/Excitation-v0", transducer="lumped", dt=0.001, temperature_sensor=True,
                         stroke_limit=2e-4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gym_check_env(env.unwrapped)


def test_sb3_check_env(env_id):
    env = gymnasium.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_check_env(env, warn=True)
