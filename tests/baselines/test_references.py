"""The calibration tasks' references (baselines.references) against the env's own thermal integration, and
the estimator in the loop against the agent-reports track with the same posterior."""

import gymnasium
import numpy as np
import pytest

import hyst_gym  # noqa: F401
from baselines.calibration_agents import PosteriorCalibration
from baselines.references import SAFETY_MARGIN, BangHold, peak_temperature, ramp_hold, safe_hold_steps
from baselines.schedules import Sine
from baselines.suite_agents import Design, DesignBank

TASK = "hyst_gym/HotCalibrate-v0"


def _run(agent, options, seed=0, **make):
    """Play one episode of the in-loop env; (temperatures, infos' estimation errors, terminated)."""
    env = gymnasium.make(TASK, **make)
    obs, info = env.reset(seed=seed, options=options)
    agent.reset(seed)
    temperatures, start, terminated = [], np.ones(1, dtype=bool), False
    for _ in range(env.unwrapped.config.episode_steps):
        action, _ = agent.predict(obs[None, :], episode_start=start, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action[0])
        start[:] = False
        temperatures.append(info["temperature"])
        if terminated or truncated:
            break
    return np.array(temperatures), terminated


def test_ramp_hold_is_sized_to_the_hottest_start_and_no_longer():
    """The hold is the longest that keeps the hottest start of the prior SAFETY_MARGIN below the limit: the
    env's own temperature from that start peaks within 1 mK of what the sizing predicted, below the ceiling,
    and one more step of hold would pass it."""
    env = gymnasium.make(TASK)
    config = env.unwrapped.config
    hottest = config.initial_temperature_range[1]
    ceiling = config.temperature_limit - SAFETY_MARGIN
    schedule = ramp_hold(config, 8.0e4)
    hold = safe_hold_steps(config, 8.0e4)
    assert 0 < hold == schedule.hold_steps < config.episode_steps
    bank = DesignBank([Design("ramp_hold", schedule)], config, env.unwrapped.observation_names.index("a_estimate"))
    temperatures, terminated = _run(bank, {"initial_temperature": hottest})
    assert not terminated and temperatures.max() <= ceiling
    predicted = peak_temperature(config, schedule.field(config.dt * np.arange(1, config.episode_steps + 1)), hottest)
    assert temperatures.max() == pytest.approx(predicted, abs=1e-3)
    longer = ramp_hold(config, 8.0e4)
    longer.__init__(8.0e4, hold + 1, config.max_field_change, config.dt, config.episode_steps)
    field = longer.field(config.dt * np.arange(1, config.episode_steps + 1))
    assert peak_temperature(config, field, hottest) > ceiling
    with pytest.raises(ValueError, match="overheats the hottest start"):
        safe_hold_steps(config.replace(temperature_limit=hottest + 0.5), 1.0e5)


def test_bang_hold_tracks_the_heating_it_causes_and_stops_short_of_the_limit():
    """From the hottest start the rule bangs until the estimate's temperature is within its margin, then holds
    the coil there: its own record of the rise above the ambient equals the env's temperature minus the start,
    and the coil never overheats."""
    env = gymnasium.make(TASK)
    config = env.unwrapped.config
    hottest = config.initial_temperature_range[1]
    names = env.unwrapped.observation_names
    rule = BangHold(config, names.index("a_estimate"), margin=2.0, spread_index=names.index("estimate_spread"))
    temperatures, terminated = _run(rule, {"initial_temperature": hottest})
    assert not terminated and temperatures.max() < config.temperature_limit
    assert temperatures[-1] - hottest == pytest.approx(rule._rise[0], abs=1e-6)
    assert temperatures.max() > config.temperature_limit - 5.0  # it did use the budget


def test_the_estimator_in_the_loop_scores_as_the_agent_reporting_the_same_posterior():
    """A field design on the in-loop env and the same design with PosteriorCalibration on the agent-reports
    track report the same estimates (the same grid posterior, the same data)."""
    env = gymnasium.make(TASK)
    config = env.unwrapped.config
    design = [Design("sine", Sine(amplitude=6.0e4, frequency=0.5))]
    in_loop = DesignBank(design, config, env.unwrapped.observation_names.index("a_estimate"))
    reports = gymnasium.make(TASK, reporter="agent").unwrapped.observation_names.index("previous_estimate")
    agent = PosteriorCalibration(DesignBank(design, config, reports), TASK)
    for seed in (0, 1):
        estimates = []
        for policy, make in ((in_loop, {}), (agent, {"reporter": "agent"})):
            env = gymnasium.make(TASK, **make)
            obs, _ = env.reset(seed=seed)
            policy.reset(seed)
            start, trace = np.ones(1, dtype=bool), []
            for _ in range(60):
                action, _ = policy.predict(obs[None, :], episode_start=start, deterministic=True)
                obs, _, _, _, info = env.step(action[0])
                start[:] = False
                trace.append(info["a_estimate"])
            estimates.append(np.array(trace))
        assert np.array_equal(estimates[0], estimates[1])
