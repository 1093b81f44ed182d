"""The suite v2 script's statistics and decisions (issue 23), on synthetic per-draw scores whose
answers are computed here by hand; the command line's errors."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from experiments.suite import command
from experiments.suite import v2 as suite_v2
from experiments.suite.common import ROOT, play
from experiments.suite.kinds import task_kind

CALIBRATE = "hyst_gym/HotCalibrate-v0"


def test_bootstrap_value_is_the_statistic_and_the_interval_holds_it():
    rng = np.random.default_rng(0)
    scores = rng.gamma(4.0, 1.0, size=(3, 40))
    stat = lambda m: float(np.sqrt(np.mean(m)))  # noqa: E731
    value, (low, high) = suite_v2.bootstrap(stat, 400, scores)
    assert value == pytest.approx(stat(scores)) and low < value < high
    assert suite_v2.bootstrap(stat, 400, scores) == (value, [low, high])   # seeded: the same numbers


def _evaluated(floor_rms, per_draw_rms, n_draws, seed=1):
    """Per-draw mean squares that scatter around the given RMS values, one run per agent."""
    rng = np.random.default_rng(seed)
    agents = {}
    for name, (kind, rms) in per_draw_rms.items():
        agents[name] = (kind, (rms ** 2) * rng.uniform(0.9, 1.1, n_draws))
    return {"floor": {"kind": "bound", "value": floor_rms}, "agents": agents, "rl": {}, "tuned": {},
            "designs": {}, "draws": {}, "wall_s": 0.0}


def test_headroom_normalized_score_and_rl_gap_match_hand_computation():
    """Floor 100 (a bound), best open loop 150, a feedback rule 140, RL 120: headroom 150/100 - 1 = 0.5,
    the RL agent's normalized score (150 - 120)/(150 - 100) = 0.6, so it leaves 40 % of the gap."""
    profile = suite_v2.PROFILES["quick"]
    evaluated = _evaluated(100.0, {"ramp": ("open_loop", 150.0), "tuned": ("open_loop", 160.0),
                                   "thermostat": ("feedback", 140.0), "ppo": ("rl", 120.0)}, profile.heldout)
    summary = suite_v2.summarize_task(CALIBRATE, evaluated, profile)
    assert summary["reference"] == "ramp" and summary["statistic"] == "rms"
    assert summary["headroom"]["value"] == pytest.approx(0.5, abs=0.02)
    assert summary["in_suite"] and summary["headroom"]["ci"][0] > 0.25
    ppo = summary["agents"]["ppo"]["normalized"]
    assert ppo["value"] == pytest.approx(0.6, abs=0.04) and ppo["ci"][0] < 0.6 < ppo["ci"][1]
    gap = summary["rl_gap"]
    assert gap["best"] == "ppo" and gap["leaves_30_percent"]
    assert summary["agents"]["ramp"]["normalized"]["value"] == pytest.approx(0.0, abs=1e-12)


def test_a_task_without_headroom_stays_out():
    profile = suite_v2.PROFILES["quick"]
    summary = suite_v2.summarize_task(CALIBRATE, _evaluated(100.0, {"ramp": ("open_loop", 110.0)}, profile.heldout),
                                     profile)
    assert not summary["in_suite"] and "does not lie above 25 %" in summary["reason"]
    assert summary["rl_gap"] is None


def test_flatness_runs_follow_the_profile():
    """Every algorithm at its budget on every seed, plus each flatness run (factor x budget) on the first seeds."""
    profile = suite_v2.PROFILES["reduced"]
    runs = suite_v2.rl_runs(profile, CALIBRATE)
    for algo, steps in profile.rl_steps.items():
        assert sum(1 for a, _, s in runs if a == algo and s == steps) == profile.rl_seeds
        factor, seeds, tasks = profile.flat[algo]
        longer = [seed for a, seed, s in runs if a == algo and s == factor * steps]
        assert longer == (list(range(seeds)) if tasks is None or CALIBRATE in tasks else [])


@pytest.mark.parametrize("argv, message", [
    (["--suite", "v2", "--tasks", "hyst_gym/Nope-v0"], "--tasks: unknown v2 task id"),
    (["--suite", "v2", "--quick", "--reduced"], "--quick and --reduced exclude each other"),
    (["--suite", "v3"], "--suite: unknown suite version"),
    (["--suite", "v2", "--tasks", "hyst_gym/DualControl-v0"], "is measured by its own script"),
    (["--suite", "v2", "--tasks", "hyst_gym/Discriminate-v0"], "experiments.suite.discriminate"),
])
def test_bad_arguments_give_one_line_and_status_2(argv, message, capsys):
    parser = argparse.ArgumentParser()
    command.configure_parser(parser)
    assert command.main(parser.parse_args(argv)) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_the_suite_harness_plays_the_tasks_that_are_not_rejected_by_default():
    """The rejected candidates (dual control, discriminate: measured by their own scripts) are registered v2
    ids but not in the harness's default task list."""
    from hyst_gym.envs.tasks import TASKS, suite_ids

    parser = argparse.ArgumentParser()
    command.configure_parser(parser)
    _, task_ids, *_ = command._v2_options(parser.parse_args(["--suite", "v2", "--quick"]))
    rejected = {t for t in suite_ids("v2") if TASKS[t].rejected}
    assert {"hyst_gym/DualControl-v0", "hyst_gym/Discriminate-v0"} <= rejected
    assert task_ids == [t for t in suite_ids("v2") if t not in rejected]


def test_speed_only_rewrites_the_speed_and_keeps_the_rest(tmp_path):
    """--speed-only re-measures steps/s of the tasks in a stored suite JSON: the speed changes to a fresh
    measurement (positive, single below n = 1024's aggregate), every other field is kept, and the table
    says where the speed came from."""
    import json

    from experiments.suite.v2 import remeasure_speed

    stored = json.loads((ROOT / "experiments" / "results" / "suite_v2_reduced.json").read_text())
    task_id = "hyst_gym/HotCalibrate-v0"
    stored["tasks"] = {task_id: stored["tasks"][task_id]}
    path = tmp_path / "suite_v2_reduced.json"
    path.write_text(json.dumps(stored))
    data = remeasure_speed(path, tmp_path / "fig.png", None, "hyst-gym benchmark --suite v2 --reduced --speed-only")
    again = json.loads(path.read_text())
    speed = again["tasks"][task_id]["steps_per_s"]
    assert 0 < speed["single"] < speed["1024"]
    kept = [key for key in stored["tasks"][task_id] if key != "steps_per_s"]
    assert "agents" in kept
    for key in kept:
        assert again["tasks"][task_id][key] == stored["tasks"][task_id][key]
    assert again["speed_remeasured"]["command"].endswith("--speed-only") and data == again
    table = path.with_suffix(".md").read_text()
    assert "re-measured by `hyst-gym benchmark --suite v2 --reduced --speed-only`" in table


def test_posterior_that_marginalizes_k_beats_the_one_that_assumes_nominal_k():
    """On draws with k at the edge of its prior (330 A/m), the (T0, k) grid posterior reports a far closer to
    the truth over the scored steps than the posterior that assumes k = 400 A/m under the same input; with
    k = 400 both are close."""
    from baselines.calibration_agents import PosteriorCalibration
    from baselines.schedules import Sine
    from baselines.suite_agents import Design

    task = "hyst_gym/HotCalibrateUnknownK-v0"
    design = [Design("sine", Sine(amplitude=60000.0, frequency=0.5, offset=0.0))]
    seeds = [5, 6, 7, 8]

    def rms(k_nodes, k):
        agent = PosteriorCalibration(task_kind(task).field_agent(design), task, k_nodes=k_nodes,
                                     nodes=64 if k_nodes == 1 else None)
        return float(np.sqrt(play(agent, task_kind(task), seeds, options={"pinning_k": k},
                                  overrides={"reporter": "agent"})[0].mean()))

    marginal, nominal = rms(None, 330.0), rms(1, 330.0)
    assert marginal < 15.0 and 3 * marginal < nominal
    assert rms(1, 400.0) < 15.0 and rms(None, 400.0) < 15.0
    with pytest.raises(ValueError, match="k_nodes"):
        PosteriorCalibration(task_kind(CALIBRATE).field_agent(design), CALIBRATE, k_nodes=5)


def _stored(task_ids, profile, wall=60.0):
    record = suite_v2.run_record(profile)
    return {"suite": "v2", "profile": profile.name, "package_version": "0", "env_ids": list(task_ids),
            "tasks": {t: {"description": "old", "difficulty": 9, "family": "old", "agents": {"x": t}}
                      for t in task_ids},
            "wall_s": wall, "train_wall_s": 1.0, "speed_remeasured": {"command": "c"}, **record}


def test_merge_keeps_the_other_tasks_and_replaces_the_run_s(tmp_path):
    import json

    from hyst_gym.envs.tasks import suite_ids

    profile = suite_v2.PROFILES["reduced"]
    path = tmp_path / "suite_v2_reduced.json"
    path.write_text(json.dumps(_stored(["hyst_gym/DriftJump-v0", CALIBRATE], profile)))
    new = "hyst_gym/HotCalibrateUnknownK-v0"
    run = _stored([new, CALIBRATE], profile, wall=30.0)
    run["tasks"][CALIBRATE]["agents"] = {"x": "rerun"}
    merged = suite_v2.merge_stored(run, path)
    assert merged["env_ids"] == [t for t in suite_ids("v2") if t in (new, CALIBRATE, "hyst_gym/DriftJump-v0")]
    assert merged["tasks"][CALIBRATE]["agents"] == {"x": "rerun"}                     # replaced by the run
    kept = merged["tasks"]["hyst_gym/DriftJump-v0"]
    assert kept["agents"] == {"x": "hyst_gym/DriftJump-v0"} and kept["family"] == "drift events"  # labels refreshed
    assert [r["tasks"] for r in merged["runs"]] == [["hyst_gym/DriftJump-v0"], [new, CALIBRATE]]
    assert merged["wall_s"] == 90.0 and "speed_remeasured" not in merged
    assert "2 runs merged" in suite_v2._wall(merged)
    other = suite_v2.run_record(suite_v2.PROFILES["quick"])
    with pytest.raises(ValueError, match="merge: .* other settings"):
        suite_v2.check_mergeable(json.loads(path.read_text()), other, path)


def test_a_merge_keeps_each_calibration_task_s_track(tmp_path):
    """A task kept from a stored JSON of another calibration track keeps that track, the run's tasks carry this
    code's, and the results line then names the track per task."""
    import json

    profile = suite_v2.PROFILES["reduced"]
    path = tmp_path / "suite_v2_reduced.json"
    kept = "hyst_gym/HotCalibrateNoisy-v0"
    stored = _stored([kept, "hyst_gym/DriftJump-v0"], profile)  # a JSON that does not say: the agent-reports track
    stored["tasks"][kept]["statistic"] = "rms"
    stored["tasks"]["hyst_gym/DriftJump-v0"]["statistic"] = "iqm"
    path.write_text(json.dumps(stored))
    run = {**_stored([CALIBRATE], profile), "track": suite_v2.TRACK}
    run["tasks"][CALIBRATE].update(statistic="rms", track=suite_v2.TRACK)
    merged = suite_v2.merge_stored(run, path)
    assert merged["tasks"][kept]["track"] == suite_v2.OLD_TRACK
    assert merged["tasks"][CALIBRATE]["track"] == suite_v2.TRACK
    assert "track" not in merged["tasks"]["hyst_gym/DriftJump-v0"] and merged["track"].startswith("per task")
    line = suite_v2.calibration_tracks(merged)
    assert line.startswith("Calibration track, per task") and "`HotCalibrateNoisy-v0`: the agent reports" in line
    assert suite_v2.calibration_tracks(run) == f"Calibration track: {suite_v2.TRACK}."


def test_k_task_reference_also_plays_the_design_searched_with_k_known():
    """On the k task the inputs without feedback include the direct design searched on its k-known
    sibling (same coil, limits and sensors; k does not enter the heating), played here as an open-loop
    agent; the nominal-k posterior is context, not a candidate reference."""
    from experiments.suite.v2 import Profile, searched_designs

    assert task_kind("hyst_gym/HotCalibrateUnknownK-v0").k_known_sibling().id == "hyst_gym/HotCalibrate-v0"
    assert task_kind("hyst_gym/HotCalibrate-v0").k_known_sibling() is None
    tiny = Profile("test", 2, 2, 2, 2, 0, {}, {}, 10, False)
    agents, designs = searched_designs(task_kind("hyst_gym/HotCalibrateUnknownK-v0"), tiny, [1000, 1001])
    assert agents["direct_design_k_known"][0] == "open_loop" and agents["direct_design_nominal_k"][0] == "estimator"
    assert len(designs["direct_design_k_known_knots"]) == 9
    assert all(scores.shape == (2,) and np.all(scores >= 0) for _, scores in agents.values())


def test_the_hottest_safe_direct_design_keeps_the_hottest_start_below_the_limit():
    """With hottest_safe the search returns an input whose peak temperature from the prior's hottest start,
    recomputed here by stepping the lumped thermal model, stays 1 K below the limit; a jump task refuses it."""
    from baselines.references import peak_temperature
    from experiments.suite.common import direct_design, excitation_limits

    task = task_kind(CALIBRATE)
    config = task.config
    schedule = direct_design(task, [300_000], 12, hottest_safe=True)
    field = schedule.sampled(config.episode_steps, excitation_limits(config))
    thermal = config.thermal
    start = config.initial_temperature_range[1]
    temperature, previous, peak = start, 0.0, start
    decay = np.exp(-config.dt / thermal.time_constant)
    for h in field:  # T' = -(T - T_start)/tau + R_th*P(H)/tau, exact per step for the mean square of a linear ramp
        power = thermal.power_per_square_field * (previous ** 2 + previous * h + h ** 2) / 3
        target = start + thermal.thermal_resistance * power
        temperature = target + (temperature - target) * decay
        previous, peak = h, max(peak, temperature)
    assert peak == pytest.approx(peak_temperature(config, field, start), rel=1e-12)
    assert peak <= config.temperature_limit - 1.0
    with pytest.raises(ValueError, match="hottest_safe needs a calibration task"):
        direct_design(task_kind("hyst_gym/DriftJump-v0"), [300_000], 2, hottest_safe=True)


def test_direct_budget_check_records_both_budgets_and_their_change(tmp_path, capsys):
    """The budget check searches at N and 3 N evaluations and says whether the held-out score moved by less
    than 2 %; its relative change is recomputed here from the two scores; a bad task is one line, status 2."""
    import json

    from experiments.suite import direct_budget

    out = tmp_path / "budget.json"
    assert direct_budget.main(["--evaluations", "2", "--tuning", "2", "--heldout", "2", "--out", str(out)]) == 0
    task = json.loads(out.read_text())["tasks"]["hyst_gym/HotCalibrate-v0"]
    low, high = (task["budgets"][key]["heldout_score"] for key in ("2", "6"))
    assert task["relative_change"] == pytest.approx(abs(high - low) / low)
    assert task["flat"] == (task["relative_change"] < 0.02) and all(np.isfinite([low, high]))
    assert direct_budget.main(["--tasks", "hyst_gym/DriftJump-v0"]) == 2
    assert "calibration tasks" in capsys.readouterr().err


def test_the_heat_budget_floor_is_read_from_its_results_file_only_where_it_has_the_task(tmp_path):
    """The calibration floor with the heat budget comes from experiments/results/floors.json: a task it has
    (a bound) is read back as stored, one it lacks, another kind or a missing file gives None (the suite then
    keeps the heat-dropped bound and says so)."""
    import json

    path = tmp_path / "floors.json"
    assert suite_v2.heated_floor(CALIBRATE, path) is None
    path.write_text(json.dumps({"tasks": {CALIBRATE: {"value": 0.86, "kind": "bound", "how": "h"},
                                          "hyst_gym/DriftJump-v0": {"value": 1.0, "kind": "oracle"}}}))
    assert suite_v2.heated_floor(CALIBRATE, path)["value"] == 0.86
    assert suite_v2.heated_floor("hyst_gym/DriftJump-v0", path) is None
    assert suite_v2.heated_floor("hyst_gym/HotCalibrateNoisy-v0", path) is None
    committed = suite_v2.heated_floor(CALIBRATE)
    assert committed is not None and committed["value"] > 0


def test_flatness_compares_the_longer_run_with_the_base_budget_s_interval():
    agent = {"kind": "rl", "rms": 2.0, "ci": [1.5, 2.5], "runs": 3, "normalized": {"value": 0.0, "ci": [0.0, 0.0]}}
    task = {"statistic": "rms", "agents": {"ppo": agent, "ppo_x3": {**agent, "rms": 2.4, "runs": 1},
                                           "sac": agent, "sac_x3": {**agent, "rms": 1.2, "runs": 1},
                                           "ramp_hold": {**agent, "kind": "open_loop"}}}
    rows = suite_v2.flatness(task)
    assert [(row[0], row[3], row[6]) for row in rows] == [("ppo (3 seeds)", "ppo_x3 (1 seed)", True),
                                                           ("sac (3 seeds)", "sac_x3 (1 seed)", False)]
    assert "(not flat)" in suite_v2.markdown({"profile": "reduced", "profile_note": "n", "heldout_draws": 1,
                                              "rl_budget": "b", "wall_s": 60.0, "package_version": "0",
                                              "tasks": {CALIBRATE: {**task, "difficulty": 1, "family": "f",
                                                                    "floor": {"value": 1.0, "kind": "bound"},
                                                                    "reference": "ramp_hold", "in_suite": True,
                                                                    "headroom": {"value": 1.0, "ci": [0.5, 1.5]},
                                                                    "rl_gap": None,
                                                                    "steps_per_s": {"single": 1, "1024": 1}}}})
