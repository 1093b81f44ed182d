"""terminated vs truncated, limits, thermal model cross-check, observation/info separation."""

import gymnasium
import numpy as np
import pytest

from hyst_gym.envs import EnvConfig
from hyst_gym.envs.core import BatchSimulator
from hyst_gym.physics import ThermalParams, advance_temperature


def test_truncated_at_time_limit_not_terminated(env_id):
    env = gymnasium.make(env_id, episode_steps=25)
    env.reset(seed=0)
    for step in range(25):
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        assert not terminated
        assert truncated == (step == 24)
    assert info["time"] == pytest.approx(25 * 0.01)


def test_make_time_limit_shorter_than_config_truncates_first():
    env = gymnasium.make("hyst_gym/Excitation-v0", max_episode_steps=7)
    env.reset(seed=0)
    flags = [env.step(np.zeros(1, dtype=np.float32))[3] for _ in range(7)]
    assert flags == [False] * 6 + [True]


def test_stroke_violation_terminates_and_costs_the_rest_of_the_episode():
    env = gymnasium.make("hyst_gym/Excitation-v0", stroke_limit=300.0, episode_steps=100, output_noise=0.0)
    env.reset(seed=1)
    for step in range(1, 101):  # noqa: B007  (read after the loop: the step of the termination)
        _, reward, terminated, truncated, info = env.step(np.ones(1, dtype=np.float32))
        if terminated:
            break
    assert terminated and not truncated and step < 100
    assert abs(info["output"]) > 300.0 and info["stroke_margin"] < 0
    # reward = -error - penalty - remaining steps: never better than staying until the limit
    assert reward == pytest.approx(-info["estimation_error"] - info["penalty"] - (100 - step))
    assert info["penalty"] > 0


def test_over_temperature_terminates():
    # a hot ambient drifting up fast: the coil limit is crossed, not the time limit
    env = gymnasium.make("hyst_gym/Estimation-v0", initial_temperature_range=(300.0, 300.0),
                         ambient_drift_rate_range=(20.0, 20.0), temperature_limit=303.0, theta_max=7400.0)
    env.reset(seed=0)
    for _step in range(1, 1001):
        _, _, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
        if terminated or truncated:
            break
    assert terminated and not truncated
    assert info["temperature"] > 303.0 and info["temperature_margin"] < 0


def test_field_and_slew_limits():
    env = gymnasium.make("hyst_gym/Excitation-v0", episode_steps=500)
    env.reset(seed=0)
    fields = [0.0]
    rng = np.random.default_rng(0)
    for _ in range(400):
        action = np.array([rng.choice([-1.0, 1.0])], dtype=np.float32)
        fields.append(env.step(action)[4]["field"])
    fields = np.array(fields)
    assert np.max(np.abs(np.diff(fields))) <= 5e4 * 0.01 * (1 + 1e-12)
    assert np.max(np.abs(fields)) <= 1e5


def test_thermal_update_matches_physics_layer():
    """Joule heating + ambient drift: the env's fused kernel equals physics.advance_temperature."""
    config = EnvConfig(initial_temperature_range=(290.0, 290.0), ambient_drift_rate_range=(0.03, 0.03),
                       output_noise=0.0)
    sim = BatchSimulator(config, "excitation", 1)
    sim.set_generator(0, np.random.default_rng(0))
    sim.reset([0])
    params = ThermalParams(ambient_temperature=290.0, ambient_drift_rate=0.03)
    temperature = 290.0
    rng = np.random.default_rng(1)
    for step in range(300):
        field0 = sim.field[0]
        sim.step(rng.uniform(-1, 1, (1, 1)))
        temperature = float(advance_temperature(temperature, field0, sim.field[0], config.dt, params,
                                                time=step * config.dt))
        assert sim.temperature[0] == pytest.approx(temperature, rel=1e-13, abs=1e-10)
    assert sim.a_true[0] == pytest.approx(config.a_of(temperature), rel=1e-13)


def test_fixed_temperature_keeps_a_true():
    env = gymnasium.make("hyst_gym/Excitation-v0", temperature_mode="fixed", a_true=7012.0)
    _, info = env.reset(seed=0)
    assert info["a_true"] == pytest.approx(7012.0)
    for _ in range(50):
        info = env.step(np.ones(1, dtype=np.float32))[4]
    assert info["a_true"] == pytest.approx(7012.0)


def _ramp_magnetization(max_field_step):
    sim = BatchSimulator(EnvConfig(output_noise=0.0, max_field_step=max_field_step), "estimation", 1)
    sim.set_generator(0, np.random.default_rng(3))
    sim.reset([0])
    out = []
    for _ in range(700):  # the paper's ramp and a plateau
        sim.step(np.zeros((1, 1)))
        out.append(sim.magnetization[0])
    return np.array(out)


def test_plant_substep_error_is_second_order_and_small():
    """The env's hysteresis substep (250 A/m) against a 20x finer one: the midpoint rule
    converges at second order, and the default's error stays below 1e-4 Ms."""
    reference = _ramp_magnetization(12.5)
    errors = [np.max(np.abs(_ramp_magnetization(h) - reference)) for h in (250.0, 125.0)]
    assert 3.0 < errors[0] / errors[1] < 5.0
    assert errors[0] < 1e-4 * 7.65e5


def test_truth_only_in_info_unless_sensor():
    env = gymnasium.make("hyst_gym/Excitation-v0")
    names = env.unwrapped.observation_names
    assert names == ["output", "field", "elapsed", "a_estimate", "tuning_error", "curvature_sign", "minmax_gap"]
    sensed = gymnasium.make("hyst_gym/Excitation-v0", temperature_sensor=True).unwrapped.observation_names
    assert sensed[-1] == "temperature"
    # with no noise and a_true moved only through the temperature, observations before the
    # field moves are identical: nothing of a_true or T leaks in
    a = gymnasium.make("hyst_gym/Estimation-v0", output_noise=0.0)
    b = gymnasium.make("hyst_gym/Estimation-v0", output_noise=0.0)
    obs_a, info_a = a.reset(seed=0, options={"a_true": 6500.0})
    obs_b, info_b = b.reset(seed=0, options={"a_true": 7200.0})
    assert info_a["a_true"] != info_b["a_true"]
    np.testing.assert_array_equal(obs_a, obs_b)


def test_pe_integrand_matches_estimator():
    env = gymnasium.make("hyst_gym/Excitation-v0", temperature_mode="fixed", a_true=7012.0)
    env.reset(seed=0)
    sim = env.unwrapped.sim
    for _ in range(100):
        info = env.step(np.ones(1, dtype=np.float32))[4]
    expected = sim.estimator.pe_integrand(np.array([7012.0]))[0]
    assert info["pe_integrand"] == pytest.approx(expected, rel=1e-12, abs=1e-9)
    assert info["curvature_sign"] == sim.estimator.curvature_sign[0]


@pytest.mark.parametrize("transducer", ["lumped", "lumped_nonlinear", "fem"])
def test_mechanical_transducers_run(transducer):
    env = gymnasium.make("hyst_gym/Excitation-v0", transducer=transducer, dt=0.001, slew_rate_limit=5e5)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (8,)
    for _ in range(50):
        obs, reward, *_ = env.step(np.ones(1, dtype=np.float32))
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)
    assert env.unwrapped.sim.measured[0, 0] > 0  # pushed out by a positive M (or M**2)
