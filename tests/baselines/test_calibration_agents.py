"""The grid-posterior calibration agent of suite v2 (baselines.calibration_agents), on the agent-reports track."""

import gymnasium
import numpy as np
import pytest

import hyst_gym  # noqa: F401
from baselines.calibration_agents import PosteriorCalibration
from baselines.schedules import Sine
from baselines.suite_agents import Design, DesignBank
from hyst_gym.envs.suite_v2 import task_config_v2


def _play(task_id, seeds, steps=80):
    config = task_config_v2(task_id)
    venv = gymnasium.make_vec(task_id, num_envs=len(seeds), vectorization_mode="vector_entry_point", reporter="agent")
    column = venv.unwrapped.observation_names.index("previous_estimate")
    agent = PosteriorCalibration(DesignBank([Design("sine", Sine(amplitude=4e4, frequency=0.1, offset=2e4))],
                                            config, column), task_id)
    observations, _ = venv.reset(seed=seeds)
    agent.reset(0)
    start = np.ones(len(seeds), dtype=bool)
    errors = []
    for _ in range(steps):
        actions, _ = agent.predict(observations, episode_start=start)
        start[:] = False
        observations, _, _, _, infos = venv.step(actions)
        errors.append(infos["a_estimate"] - infos["a_true"])
    return np.array(errors)


def test_posterior_estimate_converges_and_beats_the_prior():
    """Within 4 s of excitation the Bayes estimate is within a few A/m (the prior's spread is 173 A/m),
    and it follows the heating: the error stays small while a moves by tens of A/m."""
    errors = _play("hyst_gym/HotCalibrate-v0", list(range(500, 508)))
    assert np.sqrt(np.mean(errors[0] ** 2)) > 50.0
    assert np.sqrt(np.mean(errors[-20:] ** 2)) < 5.0


def test_posterior_is_deterministic_and_checks_its_task():
    first = _play("hyst_gym/DisplacementOnly-v0", [3, 4], steps=30)
    assert np.array_equal(first, _play("hyst_gym/DisplacementOnly-v0", [3, 4], steps=30))
    with pytest.raises(ValueError, match="calibration task"):
        PosteriorCalibration(None, "hyst_gym/DriftJump-v0")
