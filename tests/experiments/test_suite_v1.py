"""Benchmark suite v1 (issue 13): the registered tasks, the agents, and a tiny run of the suite."""

import json
import subprocess
import sys

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hyst_gym  # noqa: F401
from baselines.schedules import Ramp, Sine
from baselines.suite_agents import Design, DesignBank
from experiments.suite import common
from experiments.suite import v1 as suite_v1
from experiments.suite.kinds import task_kind
from hyst_gym.envs.registration import SUITE_IDS
from hyst_gym.envs.suite_v1 import TASKS, suite_tasks, task_config

ROOT = common.ROOT
HOT_COIL = task_kind("hyst_gym/HotCoil-v1")


def _estimate_column(config):
    from hyst_gym.envs.core import EXCITATION, observation_names

    return observation_names(config, EXCITATION).index("a_estimate")


def test_every_task_is_a_registered_versioned_id_with_its_preset():
    assert set(SUITE_IDS) == set(TASKS) and len(suite_tasks()) >= 4
    assert [spec.difficulty for spec in suite_tasks().values()] == sorted(spec.difficulty
                                                                          for spec in suite_tasks().values())
    for task_id in TASKS:
        assert task_id.endswith("-v1")
        env = gymnasium.make(task_id)
        assert env.unwrapped.config == task_config(task_id)
        venv = gymnasium.make_vec(task_id, num_envs=3, vectorization_mode="vector_entry_point")
        assert venv.config == task_config(task_id)
        # a preset field can still be overridden at make time
        assert gymnasium.make(task_id, output_noise=0.0).unwrapped.config.output_noise == 0.0
        env.close()
        venv.close()


def test_a_suite_env_passes_the_gymnasium_checker():
    check_env(gymnasium.make("hyst_gym/HotCoil-v1").unwrapped, skip_render_check=True)


def test_full_excitation_overheats_a_warm_hot_coil_but_not_a_cold_one():
    """The physics the suite is built on: a held 81 kA/m heats the hot coil to its limit from 45 C
    within the episode, and the metric charges width(Theta) per step after the overheat."""
    config = task_config("hyst_gym/HotCoil-v1")
    hold = Design("hold", Ramp(peak=8.1e4, duration=1.62))
    warm, _, trace = common.play(HOT_COIL.design_agent([hold]), HOT_COIL, [1],
                                 options={"initial_temperature": 318.15, "ambient_drift_rate": 0.0},
                                 keep_trace=True)
    ended = np.flatnonzero(np.isnan(trace["temperature"][:, 0]))
    assert ended.size and ended[0] < config.episode_steps
    assert np.nanmax(trace["temperature"]) > config.temperature_limit - 1.0
    cold, _, _ = common.play(HOT_COIL.design_agent([hold]), HOT_COIL, [1],
                             options={"initial_temperature": 278.15, "ambient_drift_rate": 0.0})
    assert warm[0] > cold[0] and warm[0] > 0.1 * config.theta_width


def test_thermostat_gates_on_the_estimate_and_the_oracle_on_the_truth():
    config = task_config("hyst_gym/HotCoil-v1")
    index = _estimate_column(config)
    sine = Sine(amplitude=2e4, frequency=0.25, offset=6e4)
    # margin so large that every temperature counts as hot: always 0
    always_off = DesignBank([Design("off", sine, margin=1e3)], config, index)
    observations = np.zeros((2, 7), dtype=np.float32)
    assert np.all(always_off.predict(observations, episode_start=np.ones(2, bool))[0] == 0.0)
    oracle = DesignBank([Design("oracle", sine, margin=5.0, truth=True)], config, index)
    with pytest.raises(ValueError, match="observe"):
        oracle.predict(observations, episode_start=np.ones(2, bool))
    oracle.observe({"temperature": np.array([300.0, config.temperature_limit]), "a_estimate": np.zeros(2),
                    "a_true": np.zeros(2)})
    actions = oracle.predict(observations, episode_start=np.ones(2, bool))[0]
    assert actions[0, 0] == pytest.approx(config.max_field_change / config.field_limit) and actions[1, 0] == 0.0


def test_the_identification_gate_idles_once_a_is_identified():
    config = task_config("hyst_gym/HotCoil-v1")
    ramp = Ramp(peak=1e5, duration=1e-3)
    index = _estimate_column(config)
    truth = DesignBank([Design("g", ramp, margin=2.0, truth=True, gate=25.0, tail=0.25)], config, index)
    truth.observe({"temperature": np.full(2, 300.0), "a_estimate": np.array([7000.0, 7000.0]),
                   "a_true": np.array([7100.0, 7010.0])})
    step = config.max_field_change / config.field_limit
    observations = np.zeros((2, 7), dtype=np.float32)
    actions = truth.predict(observations, episode_start=np.ones(2, bool))[0][:, 0]
    assert actions == pytest.approx([step, 0.25 * step])  # 100 A/m off: excite; 10 A/m: idle
    observed = DesignBank([Design("g", ramp, margin=2.0, gate=0.1, tail=0.25)], config, index)
    observations[0, observed.tuning_index] = -0.5  # the estimator still adapts
    actions = observed.predict(observations, episode_start=np.ones(2, bool))[0][:, 0]
    assert actions == pytest.approx([step, 0.25 * step])


def test_a_tiny_suite_run_has_the_shape_and_the_physics(tmp_path):
    profile = suite_v1.Profile("tiny", 4, 2, 6, 6, 1, {"ppo": 1, "sac": 1}, 100, False, False)
    task_id = "hyst_gym/HotCoil-v1"
    data = suite_v1.run_suite(profile, [task_id], tmp_path, tmp_path / "suite.png", raw=tmp_path / "raw",
                              log=lambda *_: None)
    written = json.loads((tmp_path / "suite_v1_tiny.json").read_text())
    assert written["tasks"].keys() == {task_id}
    task = written["tasks"][task_id]
    assert isinstance(task["metric"], str) and task["lower_is_better"] is True
    assert task["floor"]["kind"] == "oracle" and np.isfinite(task["floor"]["value"])
    kinds = {name: entry["kind"] for name, entry in task["agents"].items()}
    assert set(kinds.values()) == {"open_loop", "feedback", "estimator"}
    assert {"ramp", "tuned_open_loop", "optimal_design_prior", "direct_design", "thermostat", "proportional",
            "identify_then_idle", "gradient", "multiple_model"} <= set(kinds)
    for entry in task["agents"].values():
        low, high = entry["ci"]
        assert low <= entry["iqm"] <= high
    floor = task["floor"]["value"]
    # the oracle chooses on a noise replicate, so it may lose a little to a design on a draw
    for name, entry in task["agents"].items():
        if entry["kind"] in ("open_loop", "feedback"):
            assert floor <= 1.05 * entry["iqm"], name
    # the paper's ramp drives 1e5 A/m for seconds: it overheats warm starts; the oracle does not
    assert task["agents"]["ramp"]["iqm"] > 2 * floor
    assert task["agents"]["ramp"]["iqm"] > task["agents"]["tuned_open_loop"]["iqm"]
    reference = task["agents"][task["reference"]]
    assert reference["kind"] == "open_loop"
    assert task["headroom"]["value"] == pytest.approx(reference["iqm"] / floor - 1.0)
    assert reference["normalized"]["iqm"] == pytest.approx(0.0)
    assert (tmp_path / "suite.png").stat().st_size > 0
    assert task_id in (tmp_path / "suite_v1_tiny.md").read_text()
    assert data["tasks"][task_id]["in_suite"] == task["headroom"]["met"]


def test_bad_benchmark_input_is_one_line_and_status_2():
    for argv, expected in ((["--suite", "v9"], "--suite"), (["--tasks", "hyst_gym/Nope-v1"], "--tasks")):
        result = subprocess.run([sys.executable, "-m", "hyst_gym.cli", "benchmark", *argv], capture_output=True,
                                text=True, cwd=ROOT, timeout=120)
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        assert result.returncode == 2 and len(lines) == 1 and expected in lines[0], result.stderr


def test_the_proportional_rule_scales_the_input_with_the_budget_it_reads():
    config = task_config("hyst_gym/HotCoil-v1")
    ramp = Ramp(peak=1e5, duration=1e-3)  # full field at once (slew-limited to one step)
    rule = DesignBank([Design("p", ramp, margin=5.0, truth=True, span=20.0)], config, _estimate_column(config))
    limit = config.temperature_limit
    rule.observe({"temperature": np.array([limit - 5.0 - 40.0, limit - 5.0 - 10.0, limit - 5.0, limit]),
                  "a_estimate": np.zeros(4), "a_true": np.zeros(4)})
    actions = rule.predict(np.zeros((4, 7), dtype=np.float32), episode_start=np.ones(4, bool))[0][:, 0]
    step = config.max_field_change / config.field_limit
    assert actions == pytest.approx([step, 0.5 * step, 0.0, 0.0])
