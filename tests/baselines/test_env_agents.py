"""Agents on the real environments: cross-checks between independent paths."""

import json
import pathlib

import numpy as np
import pytest

from baselines.agents import ConstantAgent
from baselines.evaluation import run_episodes
from baselines.registry import make_agent
from baselines.scenarios import ESTIMATION_ID, HELDOUT_SEEDS, SCENARIOS
from hyst_gym.envs import EnvConfig

PAPER = SCENARIOS["paper"]
SEEDS = HELDOUT_SEEDS[:2]


@pytest.fixture(scope="module")
def ramp_on_excitation():
    return run_episodes(make_agent("ramp", PAPER), PAPER.spec(), SEEDS, keep_traces=2)


def test_minmax_agent_reproduces_the_builtin_estimator_one_step_late(ramp_on_excitation):
    """The min-max estimator run by the agent on Estimation-v0's observations must give, at
    step k+1, the estimate that Excitation-v0's built-in estimator had at step k: two
    independent paths (decoding normalized observations vs the env's internal state)."""
    records, traces = ramp_on_excitation
    agent_records, agent_traces = run_episodes(make_agent("minmax", PAPER), PAPER.spec(ESTIMATION_ID), SEEDS,
                                               keep_traces=2)
    for builtin, agent in zip(traces, agent_traces):
        np.testing.assert_allclose(agent["field"], builtin["field"], atol=0.05)  # same ramp (float32 actions)
        np.testing.assert_allclose(agent["a_estimate"][1:], builtin["a_estimate"][:-1], atol=0.01)
    for builtin, agent in zip(records, agent_records):
        assert abs(agent["settle_time_s"] - builtin["settle_time_s"]) <= PAPER.limits.dt + 1e-9


def test_paper_ramp_converges_and_no_excitation_does_not(ramp_on_excitation):
    records, _ = ramp_on_excitation
    config = EnvConfig(**PAPER.spec().env_kwargs)
    for r in records:
        assert np.isfinite(r["settle_time_s"]) and r["final_error"] < 1e-3 * config.a_true
    idle, _ = run_episodes(ConstantAgent([0.0], name="idle"), PAPER.spec(), SEEDS)
    for r in idle:  # H = 0 forever: M = 0 carries no information about a, the estimate stays at 6990
        assert np.isnan(r["settle_time_s"])
        assert r["final_error"] == pytest.approx(config.a_true - config.initial_estimate, abs=0.5)


def test_evaluation_is_deterministic(ramp_on_excitation):
    again, _ = run_episodes(make_agent("ramp", PAPER), PAPER.spec(), SEEDS)
    assert again == ramp_on_excitation[0]


def test_agents_work_with_sb3_evaluate_policy():
    from stable_baselines3.common.evaluation import evaluate_policy

    from baselines.environment import make_sb3_vec_env

    venv = make_sb3_vec_env(PAPER.spec(), 2, seed=0)
    ramp, _ = evaluate_policy(make_agent("ramp", PAPER), venv, n_eval_episodes=2)
    idle, _ = evaluate_policy(ConstantAgent([0.0]), venv, n_eval_episodes=2)
    venv.close()
    # reward = -|a_estimate - a_true|/width per step: exciting the material must pay
    assert idle < ramp < 0.0
    config = EnvConfig(**PAPER.spec().env_kwargs)
    per_step = (config.a_true - config.initial_estimate) / (config.theta_max - config.theta_min)
    assert idle == pytest.approx(-per_step * PAPER.episode_steps, rel=0.05)


def test_tuned_schedule_without_its_tuning_is_an_error_not_the_untuned_default(tmp_path):
    # the untuned sine settles ~2x slower: playing it under the name "sine" was a silent substitution
    with pytest.raises(OSError, match=r"'sine' needs its tuned settings: missing .*tune/paper/sine.json"):
        make_agent("sine", PAPER, tmp_path)
    with pytest.raises(OSError, match="'chirp' needs its tuned settings"):
        make_agent("chirp", PAPER)
    committed = pathlib.Path(__file__).resolve().parents[2] / "experiments" / "results" / "raw"
    tuned = json.loads((committed / "tune" / "paper" / "sine.json").read_text())["best"]
    schedule = make_agent("sine", PAPER, committed).schedule
    assert {name: getattr(schedule, name) for name in tuned} == tuned  # the committed tuning is played
