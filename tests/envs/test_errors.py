"""Bad actions and configs raise a clear ValueError naming the offending value."""

import gymnasium
import numpy as np
import pytest

from hyst_gym.envs import EnvConfig
from hyst_gym.physics import HysteresisParams


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 1.5, -2.0])
def test_bad_actions_raise(env_id, bad):
    env = gymnasium.make(env_id)
    env.reset(seed=0)
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    action[-1] = bad
    with pytest.raises(ValueError, match=str(float(bad)).replace("+", r"\+")):
        env.step(action)


def test_bad_vector_action_raises():
    venv = gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="nan"):
        venv.step(np.array([[0.0], [np.nan], [0.0]]))
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros((3, 2)))


@pytest.mark.parametrize("field, value, pattern", [
    ("dt", -0.01, "dt must be > 0, got -0.01"),
    ("dt", float("nan"), "dt must be finite"),
    ("episode_steps", 0, "episode_steps must be an integer >= 1, got 0"),
    ("field_limit", 0.0, "field_limit must be > 0"),
    ("slew_rate_limit", -1.0, "slew_rate_limit must be > 0, got -1.0"),
    ("theta_min", 8000.0, r"Theta = \[theta_min, theta_max\] = \[8000.0, 7300.0\] is empty"),
    ("initial_estimate", 9000.0, "initial_estimate = 9000.0 lies outside Theta"),
    ("initial_temperature_range", (-5.0, 300.0), r"initial_temperature_range\[0\] must be > 0, got -5.0"),
    ("initial_temperature_range", (300.0, 290.0), "high < low"),
    ("transducer", "piezo", "transducer 'piezo' is unknown"),
    ("estimator", "kalman", "estimator 'kalman' is unknown"),
    ("schedule", "square", "schedule must be one of"),
    ("temperature_mode", "cold", "temperature_mode must be one of"),
    ("output_noise", -0.1, "output_noise must be >= 0, got -0.1"),
    ("stroke_limit", 0.0, "stroke_limit must be > 0"),
    ("estimator_grid_size", 4, "estimator_grid_size must be an integer >= 16, got 4"),
    ("temperature_limit", 280.0, "temperature_limit = 280.0 K is not above"),
])
def test_bad_config_raises(field, value, pattern):
    with pytest.raises(ValueError, match=pattern):
        EnvConfig(**{field: value})
    with pytest.raises(ValueError, match=pattern):
        gymnasium.make("hyst_gym/Excitation-v0", **{field: value})


def test_unphysical_temperature_gives_invalid_hysteresis():
    # a(T) is proportional to T: at 5 K, a = 120 A/m, and a positive alpha that is fine
    # at room temperature makes the denominator of (6) vanish; the physics layer names alpha
    hysteresis = HysteresisParams(alpha=0.001)
    EnvConfig(hysteresis=hysteresis)
    with pytest.raises(ValueError, match="alpha=0.001 makes the denominator"):
        EnvConfig(hysteresis=hysteresis, initial_temperature_range=(5.0, 5.0))


def test_unknown_override_and_reset_option_raise():
    with pytest.raises(ValueError, match=r"unknown EnvConfig field\(s\) \['dtt'\]"):
        gymnasium.make("hyst_gym/Excitation-v0", dtt=0.1)
    env = gymnasium.make("hyst_gym/Excitation-v0")
    with pytest.raises(ValueError, match="unknown option"):
        env.reset(seed=0, options={"temperatur": 300})
    with pytest.raises(ValueError, match="a_true must be finite and > 0, got -1.0"):
        env.reset(seed=0, options={"a_true": -1.0})
