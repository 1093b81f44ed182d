"""The discriminate task (hyst_gym/Discriminate-v0): the candidates' fit, the exact Bayes posterior against an
independent recomputation, the reward that sums to the score, the overheat, single == vector, errors."""

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import hyst_gym  # noqa: F401
from task_vector_helpers import assert_single_is_sub_env
from hyst_gym.envs.discriminate import (CANDIDATES, DECIDED, CandidateModels, DiscriminateEnv,
                                        DiscriminateVectorEnv, discriminate_candidates, recording_drive)
from hyst_gym.physics import ThermalParams
from hyst_gym.physics.hysteresis import simulate_shared_small_loop

TASK = "hyst_gym/Discriminate-v0"


def _trajectories(config, candidates, field, a_scale=1.0):
    """Each candidate's M/Ms along ``field`` (from 0, a fixed), by the physics' whole-trajectory simulator."""
    hyst = config.hysteresis
    path = np.concatenate([[0.0], field])
    out = simulate_shared_small_loop(path, np.zeros(3), np.array(candidates.a) * a_scale, np.array(candidates.k),
                                     np.full(3, hyst.alpha), np.full(3, hyst.Ms), np.full(3, hyst.c),
                                     np.array(candidates.chi_r), hyst.kind, config.max_field_step)
    return out[1:] / hyst.Ms


def test_the_fitted_candidates_explain_the_recording_better_than_the_nominal_model():
    """k and a fitted to the small-loop candidate on the recording drive sit closer to it than model (6) with
    the nominal k and a (the same model without chi_r)."""
    env = DiscriminateVectorEnv(1, TASK)
    config, candidates = env.config, env.candidates
    field = recording_drive(config.episode_steps)
    traces = _trajectories(config, candidates, field)
    nominal = _trajectories(config, discriminate_candidates(config, chi_r=0.0), field)[:, 0]
    miss_nominal = np.sqrt(np.mean((nominal - traces[:, 0]) ** 2))
    for column in (1, 2):
        distance = np.sqrt(np.mean((traces[:, column] - traces[:, 0]) ** 2))
        assert distance == pytest.approx(candidates.recording_distance[column], rel=1e-9)
        assert distance < miss_nominal


def test_the_posterior_is_bayes_over_the_candidates_recomputed_independently():
    """With the coil's heating switched off (a constant), the env's log-posterior equals the Gaussian
    log-likelihood of its measured outputs against the physics' own trajectories of the three candidates."""
    cold = ThermalParams(heat_capacity=5.0, thermal_resistance=4.0, coil_resistance=1e-12)
    env = DiscriminateVectorEnv(2, TASK, thermal=cold)
    env.reset(seed=3, options={"truth": ["pinning", 2]})
    assert list(env.truth) == [1, 2]
    rng = np.random.default_rng(0)
    fields, measured = [], []
    for _ in range(40):
        action = rng.uniform(-0.3, 0.3, (2, 1)).astype(np.float32)
        _, _, terminated, truncated, _ = env.step(action)
        fields.append(env.field.copy())
        measured.append(env.measured.copy())
        assert not np.any(terminated | truncated)
    fields, measured = np.array(fields), np.array(measured)
    sigma = env.config.output_noise
    for row in range(2):
        scale = env.start_temperature[row] / env.config.thermal.reference_temperature
        traces = _trajectories(env.config, env.candidates, fields[:, row], scale)
        log_like = -0.5 * np.sum((measured[:, row, None] - traces) ** 2, axis=0) / sigma ** 2
        assert np.allclose(log_like - log_like.max(), env.log_post[row] - env.log_post[row].max(), atol=1e-6)


def test_the_reward_sums_to_minus_the_time_to_the_decision():
    env = DiscriminateVectorEnv(6, TASK)
    env.reset(seed=4)
    total, alive = np.zeros(6), np.ones(6, dtype=bool)
    steps_to_decision, ended = np.zeros(6), np.zeros(6, dtype=bool)
    for _ in range(200):
        _, reward, terminated, truncated, info = env.step(np.full((6, 1), 0.6, dtype=np.float32) *
                                                          np.sign(np.sin(env.steps[:, None] * 0.3) + 1e-9))
        total += np.where(alive, reward, 0.0)
        steps_to_decision += np.where(alive, 1, 0)  # the deciding step counts
        assert np.all(info["posterior_truth"][info["decided"]] >= DECIDED)
        ended |= alive & (terminated | truncated)
        alive &= ~(terminated | truncated)
        if not alive.any():
            break
    assert ended.all() and np.all(~info["overheated"])
    assert np.allclose(total, -steps_to_decision / 200, rtol=0, atol=1e-12)


def test_an_overheat_charges_every_step_left_and_ends_the_episode():
    env = DiscriminateVectorEnv(1, TASK)
    env.reset(seed=0, options={"initial_temperature": 333.0, "truth": "pinning"})
    total, steps = 0.0, 0
    while True:
        _, reward, terminated, truncated, info = env.step(np.ones((1, 1), dtype=np.float32))
        total += reward[0]
        steps += 1
        if terminated[0] or truncated[0]:
            break
    assert info["overheated"][0] and steps < 200
    assert total == pytest.approx(-1.0, abs=1e-12)  # the whole episode, decided on that step or not


def test_an_overheat_on_the_deciding_step_counts_the_whole_episode():
    """A step both decided and overheated pays for every step left, the deciding one included."""
    env = DiscriminateVectorEnv(1, TASK)
    env.reset(seed=0, options={"initial_temperature": env.config.temperature_limit - 1e-6})
    env.log_post[0] = -50.0
    env.log_post[0, env.truth[0]] = 0.0  # decided already: the first step decides, and it overheats
    _, reward, terminated, _, info = env.step(np.ones((1, 1), dtype=np.float32))
    assert terminated[0] and info["decided"][0] and info["overheated"][0]
    assert reward[0] == pytest.approx(-1.0, abs=1e-12)


def test_a_next_step_autoreset_reports_the_new_episode_in_infos():
    """The step that starts a sub-env's new episode (NEXT_STEP) reports that episode, as its observation does:
    its truth, start temperature and uniform posterior, neither decided nor overheated."""
    env = DiscriminateVectorEnv(2, TASK)
    env.reset(seed=0, options={"initial_temperature": [333.0, 300.0], "truth": ["pinning", 0]})
    terminated = np.zeros(2, dtype=bool)
    while not terminated[0]:
        _, _, terminated, _, info = env.step(np.ones((2, 1), dtype=np.float32))
    assert info["overheated"][0]
    obs, reward, terminated, truncated, info = env.step(np.ones((2, 1), dtype=np.float32))
    assert reward[0] == 0.0 and not terminated[0] and not truncated[0]
    assert not info["overheated"][0] and not info["decided"][0]
    assert info["truth"][0] == env.truth[0] and info["temperature"][0] == env.temperature[0] == env.start_temperature[0]
    assert info["posterior_truth"][0] == pytest.approx(1.0 / 3.0) and np.allclose(obs[0, 4:], 1.0 / 3.0)


def test_the_candidate_models_are_named_and_published():
    env = DiscriminateVectorEnv(1, TASK)
    models = env.models
    assert isinstance(models, CandidateModels)
    assert np.array_equal(models.a_reference, env.candidates.a) and np.array_equal(models.k, env.candidates.k)
    assert np.array_equal(models.chi_r, env.candidates.chi_r)
    assert np.all(models.Ms == env.config.hysteresis.Ms) and models.max_field_step == env.config.max_field_step


def test_single_env_is_the_vector_sub_env_and_passes_the_checker():
    assert_single_is_sub_env(TASK, DiscriminateEnv, seed=9, scale=0.5)


def test_bad_input_is_a_one_line_error():
    env = DiscriminateVectorEnv(1, TASK)
    with pytest.raises(ValueError, match="reset option truth must be one of"):
        env.reset(seed=0, options={"truth": "eddy"})
    with pytest.raises(ValueError, match="unknown option"):
        env.reset(seed=0, options={"a_true": 7000.0})
    with pytest.raises(ValueError, match="initial_temperature must be numbers in"):
        env.reset(seed=0, options={"initial_temperature": 400.0})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="must be a finite number in"):
        env.step(np.array([[np.nan]]))
    with pytest.raises(ValueError, match="not a discriminate task"):
        DiscriminateVectorEnv(1, "hyst_gym/HotCalibrate-v0")
    with pytest.raises(ValueError, match="SAME_STEP is not supported"):
        DiscriminateVectorEnv(1, TASK, autoreset_mode=AutoresetMode.SAME_STEP)
    assert CANDIDATES == ("small_loop", "pinning", "anhysteretic_width")


def test_a_per_sub_env_option_of_the_wrong_length_is_a_one_line_error():
    env = DiscriminateVectorEnv(3, TASK)
    with pytest.raises(ValueError, match=r"^reset option truth must be one value or 3 \(one per sub-env\), got 2$"):
        env.reset(seed=0, options={"truth": ["pinning", 0]})
    with pytest.raises(ValueError, match=r"^reset option initial_temperature must be one value or 3 .*got 4$"):
        env.reset(seed=0, options={"initial_temperature": [300.0] * 4})
    env.reset(seed=0, options={"truth": [0, 1, 2], "initial_temperature": 300.0})
    assert list(env.truth) == [0, 1, 2] and np.all(env.start_temperature == 300.0)


@pytest.mark.parametrize("override, name", [({"ambient_drift_rate_range": (-0.05, 0.05)}, "ambient_drift_rate_range"),
                                            ({"thermal": ThermalParams(ambient_temperature=300.0)},
                                             "thermal.ambient_temperature"),
                                            ({"transducer": "lumped"}, "transducer"),
                                            ({"temperature_sensor": True}, "temperature_sensor")])
def test_settings_the_task_does_not_use_are_refused(override, name):
    with pytest.raises(ValueError, match=rf"does not use {name};"):
        DiscriminateVectorEnv(1, TASK, **override)
