"""The report script on synthetic raw results: schema, numbers traceable to the raw files."""

import csv
import json

import numpy as np
import pytest

from experiments import report
from baselines.stats import iqm


def _write_runs(raw, scenario, agent, runs, rng, settle_scale, episode_s=6.0, tracking=False):
    """Synthetic eval CSVs; ``tracking`` adds the second-half RMS column (rms/10)."""
    folder = raw / "eval" / scenario / agent
    folder.mkdir(parents=True)
    expected = []
    for run in range(runs):
        settle = rng.exponential(settle_scale, 50)
        settle[settle > episode_s] = np.nan  # never settled
        rms = rng.exponential(settle_scale * 10, 50)
        rows = [{"scenario": scenario, "agent": agent, "run": run, "env": "x", "seed": 100_000 + i, "steps": 600,
                 "episode_time_s": episode_s, "settle_time_s": settle[i], "integrated_error": 1.0,
                 "rms_error": rms[i], "final_error": 0.0, "pe_a_fraction": 0.5, "pe_b_fraction": 0.1}
                for i in range(50)]
        if tracking:
            for row in rows:
                row["tracking_rms_error"] = row["rms_error"] / 10
        with (folder / f"run{run}.csv").open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        expected.append((np.where(np.isnan(settle), episode_s, settle), rms))
    return expected


def test_report_summary_matches_raw_and_checks_targets(tmp_path):
    rng = np.random.default_rng(0)
    results = tmp_path / "results"
    raw = results / "raw"
    ramp = _write_runs(raw, "paper", "ramp", 1, rng, 4.0)
    _write_runs(raw, "paper", "optimal_design", 1, rng, 2.0)
    ppo = _write_runs(raw, "paper", "ppo_stack8", 5, rng, 1.0)
    sine = _write_runs(raw, "drift", "sine", 1, rng, 3.0, 60.0, tracking=True)
    _write_runs(raw, "drift", "ppo_stack8", 5, rng, 3.0, 60.0, tracking=True)
    (raw / "jobs.jsonl").write_text(json.dumps({"job": "eval/paper/ramp/run0", "kind": "eval", "env_steps": 30000,
                                                "wall_s": 2.0}) + "\n")
    readme = tmp_path / "README.md"
    readme.write_text("top\n<!-- section:benchmark -->\nold\n<!-- /section:benchmark -->\nbottom\n"
                      "<!-- section:other -->\nkeep\n<!-- /section:other -->\n")
    report.write_report(results, readme=None, n_boot=200)
    summary = json.loads((results / "summary.json").read_text())
    details = json.loads((results / "details.json").read_text())
    assert set(summary) == {"paper", "drift"}
    assert all(set(metrics) == {"settle_time_s", "rms_error"} for metrics in summary["paper"].values())
    # the second-half RMS is summarized where the raw files have it (written since it exists)
    assert all(set(metrics) == {"settle_time_s", "rms_error", "tracking_rms_error"}
               for metrics in summary["drift"].values())
    assert summary["drift"]["sine"]["tracking_rms_error"]["iqm"] == pytest.approx(iqm(sine[0][1] / 10))
    entry = summary["paper"]["ramp"]["settle_time_s"]
    assert entry["iqm"] == pytest.approx(iqm(ramp[0][0])) and entry["n"] == 50
    assert entry["ci95"][0] <= entry["iqm"] <= entry["ci95"][1]
    rl = summary["paper"]["ppo"]["settle_time_s"]  # the declared main config is published as "ppo"
    assert rl["n"] == 250 and rl["iqm"] == pytest.approx(iqm(np.array([p[0] for p in ppo])))
    target = details["targets"]["paper_settle_half_ramp"]
    assert target["met"] == (rl["iqm"] <= 0.5 * entry["iqm"])
    tracking = details["targets"]["drift_rms_half_best_schedule"]["tracking"]
    assert tracking["best_schedule"] == "sine"
    assert tracking["schedule"] == summary["drift"]["sine"]["tracking_rms_error"]
    # second-half RMS = RMS/10 in every synthetic episode: the first half holds 1 - 1/200 of the squared error
    assert tracking["first_half_share_of_squared_error"] == pytest.approx(1 - 0.01 / 2)
    text = (tmp_path / "RESULTS.md").read_text()
    assert f"{entry['iqm']:.3g}" in text
    assert ("**met**" if target["met"] else "**NOT met**") in text
    assert (results / "figures" / "survival_paper.png").stat().st_size > 1000

    report.update_readme(readme, "new body")
    assert readme.read_text() == ("top\n<!-- section:benchmark -->\nnew body\n<!-- /section:benchmark -->\nbottom\n"
                                  "<!-- section:other -->\nkeep\n<!-- /section:other -->\n")


def test_report_without_results_is_a_clear_error(tmp_path):
    with pytest.raises(OSError, match="no evaluation results"):
        report.write_report(tmp_path)


def test_history_ablation_covers_no_history_and_recurrent_and_targets_name_the_best_input(tmp_path):
    rng = np.random.default_rng(1)
    results = tmp_path / "results"
    raw = results / "raw"
    ramp = _write_runs(raw, "paper", "ramp", 1, rng, 4.0)
    design = _write_runs(raw, "paper", "optimal_design", 1, rng, 1.5)
    _write_runs(raw, "paper", "sine", 1, rng, 3.0)
    _write_runs(raw, "paper", "ppo_stack8", 5, rng, 1.0)
    _write_runs(raw, "paper", "ppo_stack1", 5, rng, 5.0)
    lstm = _write_runs(raw, "paper", "ppo_lstm", 5, rng, 0.5)
    _write_runs(raw, "paper", "ppo_lstm_info", 5, rng, 2.0)  # its reference ppo_info_stack8 was not run
    report.write_report(results, readme=None, n_boot=200)
    details = json.loads((results / "details.json").read_text())
    ablation = details["history_ablation"]
    assert set(ablation) == {"ppo_stack1", "ppo_lstm"}
    assert {entry["settle_time_s"]["reference"] for entry in ablation.values()} == {"ppo_stack8"}
    entry = ablation["ppo_lstm"]["settle_time_s"]
    assert entry["other"]["iqm"] == pytest.approx(iqm(np.array([run[0] for run in lstm])))
    # stack8 (scale 1.0) beats no history (scale 5.0) and loses to the faster recurrent runs (scale 0.5)
    assert ablation["ppo_stack1"]["settle_time_s"]["probability_stack8_better"] > 0.5
    assert entry["probability_stack8_better"] < 0.5
    target = details["targets"]["paper_settle_half_ramp"]
    assert target["best_non_rl"] == "optimal_design" and target["fastest_input"] == "ppo_lstm"
    assert target["best_non_rl_iqm"] == pytest.approx(iqm(design[0][0]))
    text = (tmp_path / "RESULTS.md").read_text()
    assert "`ppo_lstm` (recurrent" in text and "no results in this run" not in text
    assert f"half the ramp ({0.5 * iqm(ramp[0][0]):.3g} s)" in text
