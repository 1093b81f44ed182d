"""The discriminate agents (triangles, the recording's replay, the greedy separation rule, its clairvoyant
variant) and the script."""

import json

import numpy as np
import pytest

from baselines.discriminate_agents import GreedySeparation, replay_recording, triangle
from hyst_gym.envs.discriminate import DiscriminateVectorEnv, recording_drive

TASK = "hyst_gym/Discriminate-v0"


def test_open_loop_drives_keep_the_slew_and_field_limits():
    config = DiscriminateVectorEnv(1, TASK).config
    for agent in (triangle(config, 1.0, 0.5), triangle(config, 0.3, 2.0, 0.3), replay_recording(config)):
        field = np.concatenate([[0.0], agent._field]) * config.field_limit
        assert np.all(np.abs(np.diff(field)) <= config.max_field_change * (1 + 1e-12))
        assert np.all(np.abs(field) <= config.field_limit)
    assert np.allclose(replay_recording(config)._field * config.field_limit, recording_drive(config.episode_steps))
    with pytest.raises(ValueError, match="amplitude in"):
        triangle(config, 1.5, 1.0)


def test_the_greedy_rule_brakes_before_the_temperature_limit():
    """From a warm start (45 C) the rule drives hard but its braking guard keeps every draw below the limit."""
    env = DiscriminateVectorEnv(8, TASK, episode_steps=200)
    agent = GreedySeparation(env, margin=1.0)
    observations, _ = env.reset(seed=1, options={"initial_temperature": 318.15})
    agent.reset(1)
    peak, start = np.zeros(8), np.ones(8, dtype=bool)
    alive = np.ones(8, dtype=bool)
    for _ in range(200):
        actions, _ = agent.predict(observations, episode_start=start)
        start[:] = False
        observations, _, terminated, truncated, info = env.step(actions)
        peak = np.maximum(peak, np.where(alive, info["temperature"], 0.0))
        assert not np.any(alive & info["overheated"])
        alive &= ~(terminated | truncated)
        if not alive.any():
            break
    assert peak.max() < env.config.temperature_limit


def test_the_script_writes_its_table_and_refuses_bad_arguments(tmp_path, capsys, monkeypatch):
    from experiments.suite import discriminate

    # a small envelope search: the script's plumbing, not the bound's value (tests/envs/test_discriminate_bound.py)
    monkeypatch.setattr(discriminate, "RANDOM_PATHS", 16)
    monkeypatch.setattr(discriminate, "CLIMB_GENERATIONS", 1)
    monkeypatch.setattr(discriminate, "CLIMB_HORIZONS", (4,))
    monkeypatch.setattr(discriminate, "SETTLE_REPLICATES", 4)
    assert discriminate.main(["--tuning", "0"]) == 2
    assert "must be >= 1" in capsys.readouterr().err
    assert discriminate.main(["--heldout", "3", "--tuning", "2", "--bootstrap", "50", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "suite_v2_discriminate.json").read_text())
    assert set(data["agents"]) == {"replay_recording", "tuned_open_loop", "greedy_separation"}
    for entry in data["agents"].values():
        times = np.array(entry["per_draw"])
        assert np.all((times >= 0) & (times <= 10.0 + 1e-9))
    floor = np.array(data["floor"]["per_draw"])
    assert len(floor) == 3 and data["floor"]["kind"] == "search_bound" and not data["floor"]["proven"]
    assert np.all((floor > 0) & (floor < 10.0)) and not data["in_suite"]
    assert len(data["oracle"]["per_draw"]) == 3 and data["oracle"]["kind"] == "oracle"
    assert data["floor"]["adversarial_check"]["single_runs"] == 5 * 3 * (len(data["tuning"]) + 1)
    assert "Discriminate measured" in (tmp_path / "suite_v2_discriminate.md").read_text()


def test_the_clairvoyant_rule_weighs_only_the_truths_pairs():
    """The check's rule that reads the truth: its pair weights are the alternatives' posteriors on the truth's
    two pairs and 0 on the third."""
    from baselines.discriminate_agents import ClairvoyantSeparation

    env = DiscriminateVectorEnv(2, TASK)
    truth = np.array([0, 2])
    agent = ClairvoyantSeparation(env, lambda: truth)
    assert agent.reads_truth
    posterior = np.array([[0.5, 0.3, 0.2], [0.1, 0.6, 0.3]])
    weights = agent._pair_weights(posterior)
    assert np.allclose(weights[(0, 1)], [0.3, 0.0]) and np.allclose(weights[(0, 2)], [0.2, 0.1])
    assert np.allclose(weights[(1, 2)], [0.0, 0.6])


@pytest.mark.slow
def test_the_bound_lies_below_the_decision_time_of_an_open_loop_agent():
    """Per draw, the bound at the searched envelope lies below the mean over noise replicates of an open-loop
    triangle's decision time (the expectation the bound bounds). It can fail: the envelope is a search's."""
    from experiments.suite import discriminate as measured

    env = DiscriminateVectorEnv(1)
    agent = triangle(env.config, 1.0, 2.0)
    replicates = 24
    for truth, temperature in ((0, 283.15), (1, 303.15), (2, 313.15)):
        seeds = [7_000 + 100 * truth + r for r in range(replicates)]
        options = {"truth": np.full(replicates, truth), "initial_temperature": np.full(replicates, temperature)}
        times = measured.play(agent, seeds, options)["time_s"]
        envelope = measured.separation_envelope(env, temperature, seed=truth)
        bound = measured.information_bound(envelope, truth, env.config.episode_steps).steps * env.config.dt
        assert 0.0 < bound < times.mean()
