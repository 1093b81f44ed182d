"""The convergence floor through the environment: the bound against the env's own closed loop."""

import json

import numpy as np
import pytest

from baselines.agents import ScheduleAgent
from baselines.evaluation import run_episodes
from baselines.scenarios import HELDOUT_SEEDS, SCENARIOS
from baselines.schedules import Ramp
from experiments import settle_floor
from experiments.report_data import convergence_floor
from experiments.report_markdown import markdown_floor
from hyst_gym.estimation.convergence import first_passage


def test_bound_matches_the_environment_closed_loop_under_its_fastest_input():
    scenario = SCENARIOS["paper"]
    config = settle_floor.estimator_of(scenario)
    assert config.grid_size == 32 and config.gamma == 1.0  # the env's estimator, not the class defaults
    time, envelope, bound, fields, sensitivity = settle_floor.error_bound_for(scenario, config, 7012.0)
    bound_settle = first_passage(time, bound, 7.012)
    peak = float(fields[np.argmax(sensitivity)])
    records, traces = run_episodes(settle_floor.slew_ramp(scenario, peak), settle_floor.noise_free(scenario),
                                   HELDOUT_SEEDS[:1], keep_traces=1)
    # Excitation-v0 (plant, bank, covers, dead zone, sampled data) against the linear comparison system
    assert records[0]["settle_time_s"] == pytest.approx(bound_settle, abs=0.011)
    error = np.abs(traces[0]["a_estimate"] - traces[0]["a_true"])
    assert np.all(error >= np.interp(traces[0]["time"], time, bound) - 0.1)
    # a slower input (the paper's ramp) stays well above the bound
    paper_ramp = ScheduleAgent(Ramp(), scenario.limits, scenario.episode_steps)
    ramp_records, _ = run_episodes(paper_ramp, settle_floor.noise_free(scenario), HELDOUT_SEEDS[:1])
    assert ramp_records[0]["settle_time_s"] > bound_settle + 1.0


def test_report_quotes_the_floor_file(tmp_path):
    floor = {"paper": {"bound_settle_s": 2.25, "peak_field": 81200.0, "peak_sensitivity": 9.9, "slew_max": 5e4,
                       "slew_ramp_noise_free_settle_s": 2.25, "band": 7.012,
                       "slew_ramp_heldout": {"iqm": 2.23, "ci95": [2.21, 2.26], "n": 50},
                       "gain_sweep": [{"gamma": 0.5, "bound_settle_s": 3.4, "ramp_settle_s": float("nan"),
                                       "slew_ramp_settle_s": 3.4},
                                      {"gamma": 1.0, "bound_settle_s": 2.25, "ramp_settle_s": 4.4,
                                       "slew_ramp_settle_s": 2.25},
                                      {"gamma": 2.0, "bound_settle_s": 1.67, "ramp_settle_s": 3.6,
                                       "slew_ramp_settle_s": 1.67}],
                       "agents": {"a": {"noise_free_settle_s": 2.3, "min_margin": -0.05, "max_sensitivity_ratio": 1.0},
                                  "b": {"noise_free_settle_s": float("nan"), "min_margin": 1.0,
                                        "max_sensitivity_ratio": 0.9}}},
             "drift": {"initial_a": [7100.0, 6900.0], "initial_error": [110.0, 90.0],
                       "rms_bound_per_draw": [15.0, 20.0], "rms_bound": {"iqm": 17.5, "ci95": [15.0, 20.0], "n": 2},
                       "agents": {"ppo_info_stack8/seed0": {"noise_free_rms_iqm": 17.6, "min_ratio_to_bound": 0.99,
                                                            "draws_below_bound": 1}}}}
    (tmp_path / "settle_floor.json").write_text(json.dumps(floor))
    targets = {"paper_settle_half_ramp": {"ramp_iqm": 4.36},
               "drift_rms_half_best_schedule": {"best_rl": "ppo_info_stack8", "schedule_iqm": 21.5}}
    numbers = convergence_floor(tmp_path, targets)
    assert numbers["paper"]["fastest_noise_free"] == "a" and numbers["paper"]["worst_margin"] == -0.05
    assert numbers["paper"]["reach_peak_s"] == pytest.approx(1.624)
    assert numbers["drift"]["pairs"] == 2 and numbers["drift"]["largest_initial_error"] == 110.0
    assert numbers["drift"]["best_rl_worst_run_ratio"] == pytest.approx(17.6 / 17.5)
    text = "\n".join(markdown_floor(numbers, targets))
    assert "2.25 s for any input" in text and "3% below it" in text and "10.8 A/m" in text
    assert "worst `ppo_info_stack8` run is 0.6% above it" in text
    assert "gamma = 0.5: 3.4 s vs never" in text and "(ratio 0.51)" in text
    assert "within reach from gamma = 2" in text
    assert convergence_floor(tmp_path / "missing", targets) is None
    assert "not computed" in markdown_floor(None, targets)[0]


def test_settle_floor_script_checks_every_committed_baseline(tmp_path):
    # the committed designs and tunings, no RL runs: the bound must hold for every input
    (tmp_path / "raw").symlink_to(settle_floor.RESULTS / "raw", target_is_directory=True)
    assert settle_floor.main(["--rl-seeds", "0", "--results", str(tmp_path)]) == 0
    floor = json.loads((tmp_path / "settle_floor.json").read_text())
    paper, drift = floor["paper"], floor["drift"]
    assert set(paper["agents"]) == set(settle_floor.BASELINES["paper"])
    assert paper["slew_ramp_noise_free_settle_s"] == pytest.approx(paper["bound_settle_s"], abs=0.011)
    for name, check in paper["agents"].items():
        settle = check["noise_free_settle_s"]
        assert np.isnan(settle) or settle >= paper["bound_settle_s"] - 0.011, name
        assert check["min_margin"] > -0.1 and check["max_sensitivity_ratio"] < 1.01, name
    for name, check in drift["agents"].items():
        assert check["min_ratio_to_bound"] > 0.99, name
    sweep = {row["gamma"]: row for row in paper["gain_sweep"]}
    # a larger gain converges faster, under the bound and in the closed loop alike
    assert sweep[1.0]["bound_settle_s"] > sweep[4.0]["bound_settle_s"] > sweep[16.0]["bound_settle_s"]
    assert (tmp_path / "figures" / "settle_floor.png").stat().st_size > 10_000
