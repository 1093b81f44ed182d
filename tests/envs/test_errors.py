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
    with pytest.raises(ValueError, match=r"reset option a_true = -1.0 A/m is out of range: it must be in \(0, "):
        env.reset(seed=0, options={"a_true": -1.0})


@pytest.mark.parametrize("options, pattern", [
    ({"a_true": 1e9}, r"a_true = 1000000000.0 A/m is out of range: it must be in \(0, 7968.78\] A/m \(a = "
                      r"a_reference\*T/T_ref for T in \(0, temperature_limit = 333.15 K\]\)"),
    ({"a_true": float("nan")}, "a_true = nan A/m is out of range"),
    ({"a_true": "7012"}, "reset option a_true must be a number, got str '7012'"),
    ({"initial_temperature": 400.0}, r"initial_temperature = 400.0 K is out of range: it must be in \(0, 333.15\] K"),
    ({"initial_temperature": 0.0}, "initial_temperature = 0.0 K is out of range"),
    ({"a_estimate": 100.0}, r"a_estimate = 100.0 A/m is out of range: it must be in \[6300, 7300\] A/m \(Theta"),
    ({"ambient_drift_rate": float("inf")}, "ambient_drift_rate = inf K/s is out of range: it must be finite"),
    ({"ambient_drift_rate": None}, "ambient_drift_rate must be a number, got NoneType None"),
])
def test_reset_options_outside_their_physical_range_raise(env_id, options, pattern):
    env = gymnasium.make(env_id)
    with pytest.raises(ValueError, match=pattern) as raised:
        env.reset(seed=0, options=options)
    assert "\n" not in str(raised.value)
    env.reset(seed=0, options={"a_true": 7012.0, "a_estimate": 7000.0, "ambient_drift_rate": 0.1})  # in range


def test_reset_options_must_be_a_dict():
    env = gymnasium.make("hyst_gym/Excitation-v0")
    with pytest.raises(ValueError, match="reset: options must be a dict or None, got list"):
        env.reset(seed=0, options=[("a_true", 7012.0)])


@pytest.mark.parametrize("action, pattern", [
    (None, r"action is None; expected an array of numbers of shape \(1,\)"),
    ("0.5", r"action must be an array of numbers of shape \(1,\), got str '0.5'"),
    (np.array([True]), "action must be an array of numbers"),
    ([[0.1], [0.2, 0.3]], "action must be an array of numbers"),
    (np.zeros((1, 1)), r"action must have shape \(1,\), got shape \(1, 1\)"),
    (np.float32(0.5), r"action must have shape \(1,\), got shape \(\)"),
    (np.zeros(2), r"action must have shape \(1,\), got shape \(2,\)"),
])
def test_action_of_wrong_type_or_shape_raises(action, pattern):
    env = gymnasium.make("hyst_gym/Excitation-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=pattern):
        env.step(action)
    env.step([0.5])  # a list of numbers of the right shape is fine


def test_vector_action_of_wrong_shape_raises():
    venv = gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=4, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions must have shape \(4, 1\), got shape \(4,\)"):
        venv.step(np.zeros(4))
    with pytest.raises(ValueError, match=r"actions is None; expected an array of numbers of shape \(4, 1\)"):
        venv.step(None)
    venv.step(np.zeros((4, 1), dtype=np.float32))


def test_episode_steps_beyond_the_default_are_not_cut_short():
    # no TimeLimit is registered: the env itself truncates at episode_steps (here 2000,
    # twice the default that used to be registered as max_episode_steps)
    assert gymnasium.spec("hyst_gym/Excitation-v0").max_episode_steps is None
    env = gymnasium.make("hyst_gym:hyst_gym/Excitation-v0", episode_steps=2000, output_noise=0.0)
    env.reset(seed=0)
    action = np.zeros(1, dtype=np.float32)
    truncations = [env.step(action)[3] for _ in range(2000)]
    assert truncations == [False] * 1999 + [True]

    venv = gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=2, vectorization_mode="vector_entry_point",
                              episode_steps=2000, output_noise=0.0)
    venv.reset(seed=0)
    actions = np.zeros((2, 1), dtype=np.float32)
    truncations = [venv.step(actions)[3].copy() for _ in range(2000)]
    assert not np.any(truncations[:1999]) and np.all(truncations[1999])


def test_max_episode_steps_must_be_a_positive_integer():
    with pytest.raises(ValueError, match="max_episode_steps must be an integer >= 1 or None, got 0"):
        gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=2, vectorization_mode="vector_entry_point",
                           max_episode_steps=0)
