"""The numbers of the benchmark report, computed from the raw results (no text, no plots).

Loads the per-episode CSVs under ``raw/eval`` and derives everything the report shows:
IQM summaries with stratified-bootstrap intervals, the issue's targets, probabilities of
improvement, sample efficiency, the history ablation, training budgets and compute.
:mod:`experiments.report` assembles them; :mod:`experiments.report_markdown` and
:mod:`experiments.report_figures` present them.
"""

from __future__ import annotations

import csv
import json
import pathlib
from collections import defaultdict

import numpy as np

from baselines.registry import ESTIMATOR_AGENTS
from baselines.stats import probability_of_improvement, probability_of_improvement_ci, summarize
from baselines.survival import censor
from experiments.targets import BY_KEY as TARGETS_BY_KEY

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEFAULT_RESULTS = ROOT / "experiments" / "results"
#: summary.json agent keys of the main RL configurations (declared before the run).
RL_MAIN = {"ppo": "ppo_stack8", "sac": "sac_stack8"}
RL_CONFIG_PREFIXES = ("ppo_", "sac_")
ESTIMATORS = ESTIMATOR_AGENTS  # the estimators run as agents (baselines.registry)
#: the targets' ratios (best RL over the ramp's settle time; over the best schedule's RMS error),
#: from the one source of targets, experiments/targets.py
PAPER_SETTLE_RATIO = TARGETS_BY_KEY["paper_settle_half_ramp"].bound
DRIFT_RMS_RATIO = TARGETS_BY_KEY["drift_rms_half_best_schedule"].bound


def _float(value):
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def load_episodes(raw: pathlib.Path) -> dict:
    """scenario -> agent -> run -> list of episode dicts (sorted by seed)."""
    table = defaultdict(lambda: defaultdict(dict))
    for path in sorted((raw / "eval").glob("*/*/run*.csv")):
        with path.open() as handle:
            rows = list(csv.DictReader(handle))
        if not rows:
            continue
        for row in rows:
            for key, value in row.items():
                if key not in ("scenario", "agent", "env"):
                    row[key] = _float(value)
        rows.sort(key=lambda r: r["seed"])
        table[path.parent.parent.name][path.parent.name][int(path.stem[3:])] = rows
    return table


def score_matrix(runs: dict, metric: str, episode_s: float) -> np.ndarray:
    """(runs, draws) matrix of a metric; settle times censored at ``episode_s``."""
    matrix = np.array([[r[metric] for r in runs[k]] for k in sorted(runs)], dtype=np.float64)
    if metric == "settle_time_s":
        matrix = censor(matrix, episode_s)[0]
    return matrix


#: metrics summarized per scenario and agent (the last only where the raw files have it)
SUMMARY_METRICS = ("settle_time_s", "rms_error", "tracking_rms_error")


def is_rl_agent(agent):
    return agent.startswith(RL_CONFIG_PREFIXES)


def episode_length_s(runs):
    return max(r["episode_time_s"] for rows in runs.values() for r in rows)


def summarize_all(table, n_boot=2000):
    summary, success = {}, {}
    for scenario, agents in sorted(table.items()):
        summary[scenario], success[scenario] = {}, {}
        for agent, runs in sorted(agents.items()):
            episode_s = episode_length_s(runs)
            metrics = SUMMARY_METRICS if all("tracking_rms_error" in r for rows in runs.values() for r in rows) \
                else SUMMARY_METRICS[:2]  # raw files written before the tracking metric existed
            entry = {metric: summarize(score_matrix(runs, metric, episode_s), n_boot=n_boot) for metric in metrics}
            summary[scenario][agent] = entry
            success[scenario][agent] = float(np.mean([np.isfinite(r["settle_time_s"])
                                                      for rows in runs.values() for r in rows]))
        for key, config in RL_MAIN.items():
            if config in summary[scenario]:
                summary[scenario][key] = summary[scenario][config]
                success[scenario][key] = success[scenario][config]
    return summary, success


def best_baseline(summary_scenario, metric, exclude_estimators=True):
    """The non-RL excitation agent with the lowest IQM of ``metric``."""
    candidates = {a: v for a, v in summary_scenario.items()
                  if not is_rl_agent(a) and a not in RL_MAIN and not (exclude_estimators and a in ESTIMATORS)}
    return min(candidates, key=lambda a: candidates[a][metric]["iqm"]) if candidates else None


def best_schedule(summary_scenario, metric):
    from baselines.registry import SCHEDULE_AGENTS

    candidates = {a: v for a, v in summary_scenario.items() if a in SCHEDULE_AGENTS}
    return min(candidates, key=lambda a: candidates[a][metric]["iqm"]) if candidates else None


def targets(table, summary):
    """The issue's three targets, evaluated; each with the numbers behind it."""
    out = {}
    paper = summary.get("paper", {})
    rl_paper = [a for a in paper if is_rl_agent(a)]
    if rl_paper and "ramp" in paper:
        best_rl = min(rl_paper, key=lambda a: paper[a]["settle_time_s"]["iqm"])
        ramp = paper["ramp"]["settle_time_s"]
        rl = paper[best_rl]["settle_time_s"]
        baseline = best_baseline(paper, "settle_time_s")
        out["paper_settle_half_ramp"] = {"best_rl": best_rl, "rl_iqm": rl["iqm"], "rl_ci95": rl["ci95"],
                                         "ramp_iqm": ramp["iqm"], "ramp_ci95": ramp["ci95"],
                                         "met": bool(rl["iqm"] <= PAPER_SETTLE_RATIO * ramp["iqm"]),
                                         "best_non_rl": baseline,
                                         "best_non_rl_iqm": paper[baseline]["settle_time_s"]["iqm"]}
        inputs = [a for a in paper if a not in ESTIMATORS and a not in RL_MAIN]
        fastest = min(inputs, key=lambda a: paper[a]["settle_time_s"]["iqm"])
        out["paper_settle_half_ramp"].update({"fastest_input": fastest,
                                              "fastest_input_iqm": paper[fastest]["settle_time_s"]["iqm"]})
        if "direct_design" in paper:
            out["paper_settle_half_ramp"]["direct_design_iqm"] = paper["direct_design"]["settle_time_s"]["iqm"]
        design = paper.get("optimal_design", {}).get("settle_time_s")
        if design:
            episode_s = episode_length_s(table["paper"][best_rl])
            poi = probability_of_improvement(score_matrix(table["paper"][best_rl], "settle_time_s", episode_s),
                                             score_matrix(table["paper"]["optimal_design"], "settle_time_s", episode_s))
            out["paper_vs_optimal_design"] = {"best_rl": best_rl, "rl_iqm": rl["iqm"], "rl_ci95": rl["ci95"],
                                              "design_iqm": design["iqm"], "design_ci95": design["ci95"],
                                              "probability_rl_better": poi,
                                              "rl_beats_design": bool(rl["ci95"][1] < design["ci95"][0])}
    drift = summary.get("drift", {})
    rl_drift = [a for a in drift if is_rl_agent(a)]
    schedule = best_schedule(drift, "rms_error")
    if rl_drift and schedule:
        best_rl = min(rl_drift, key=lambda a: drift[a]["rms_error"]["iqm"])
        out["drift_rms_half_best_schedule"] = {
            "best_rl": best_rl, "rl_iqm": drift[best_rl]["rms_error"]["iqm"],
            "rl_ci95": drift[best_rl]["rms_error"]["ci95"], "best_schedule": schedule,
            "schedule_iqm": drift[schedule]["rms_error"]["iqm"], "schedule_ci95": drift[schedule]["rms_error"]["ci95"],
            "met": bool(drift[best_rl]["rms_error"]["iqm"] <= DRIFT_RMS_RATIO * drift[schedule]["rms_error"]["iqm"])}
        tracking = [a for a in rl_drift if "tracking_rms_error" in drift[a]]
        tracking_schedule = best_schedule({a: v for a, v in drift.items() if "tracking_rms_error" in v},
                                          "tracking_rms_error")
        if tracking and tracking_schedule:
            rl = min(tracking, key=lambda a: drift[a]["tracking_rms_error"]["iqm"])
            # mean square over the episode = mean of the two halves' mean squares, so the first
            # half's share of the squared error is 1 - tracking**2 / (2 * rms**2)
            episodes = [r for rows in table["drift"][best_rl].values() for r in rows]
            first_half_share = float(np.median([1.0 - r["tracking_rms_error"] ** 2 / (2.0 * r["rms_error"] ** 2)
                                                for r in episodes if r["rms_error"] > 0]))
            out["drift_rms_half_best_schedule"]["tracking"] = {
                "best_rl": rl, "rl": drift[rl]["tracking_rms_error"], "best_schedule": tracking_schedule,
                "schedule": drift[tracking_schedule]["tracking_rms_error"],
                "first_half_share_of_squared_error": first_half_share}
    return out


def improvements(table, summary):
    """Probability that each RL config improves on the best non-RL excitation baseline."""
    out = {}
    for scenario, agents in table.items():
        for metric in ("settle_time_s", "rms_error"):
            baseline = best_baseline(summary[scenario], metric)
            if baseline is None:
                continue
            episode_s = episode_length_s(agents[baseline])
            y = score_matrix(agents[baseline], metric, episode_s)
            for agent in agents:
                if is_rl_agent(agent):
                    x = score_matrix(agents[agent], metric, episode_s)
                    out.setdefault(scenario, {}).setdefault(agent, {})[metric] = {
                        "baseline": baseline, "probability": probability_of_improvement(x, y),
                        "ci95": list(probability_of_improvement_ci(x, y, n_boot=500))}
    return out


def sample_efficiency(raw, summary):
    """Env steps at which each RL run's validation IQM first reaches the ramp's (paper: settle
    time) or the best schedule's (drift: RMS error) held-out IQM; ``None`` if never."""
    out = {}
    for scenario, metric, column in (("paper", "settle_time_s", "settle_time_iqm_s"),
                                     ("drift", "rms_error", "rms_error_iqm")):
        if scenario not in summary:
            continue
        reference = "ramp" if scenario == "paper" else best_schedule(summary[scenario], metric)
        if reference is None or reference not in summary[scenario]:
            continue
        target = summary[scenario][reference][metric]["iqm"]
        for config_dir in sorted((raw / "train" / scenario).glob("*")):
            reached = []
            for curve_path in sorted(config_dir.glob("seed*/learning_curve.csv")):
                with curve_path.open() as handle:
                    rows = list(csv.DictReader(handle))
                hit = [int(float(r["env_steps"])) for r in rows if float(r[column]) <= target]
                reached.append(hit[0] if hit else None)
            if reached:
                out.setdefault(scenario, {})[config_dir.name] = {"reference": reference, "reference_iqm": target,
                                                                  "steps_to_reach": reached}
    return out


def compute_used(raw):
    """Env steps and wall time over every session of the runner (resumed jobs included).

    Training jobs count their total trained steps once (a resumed run continues the same
    model) plus the validation episodes of their learning curves; every other job counts
    each time it ran.
    """
    jobs = [json.loads(line) for line in (raw / "jobs.jsonl").read_text().splitlines() if line.strip()] \
        if (raw / "jobs.jsonl").exists() else []
    by_kind = defaultdict(lambda: {"jobs": set(), "env_steps": 0, "cpu_wall_s": 0.0})
    trained = {}
    for job in jobs:
        entry = by_kind[job["kind"]]
        entry["jobs"].add(job["job"])
        entry["cpu_wall_s"] += job["wall_s"]
        if job["kind"] == "train":
            trained[job["job"]] = max(trained.get(job["job"], 0), job["env_steps"])
        else:
            entry["env_steps"] += job["env_steps"]
    validation_steps = 0
    for config_path in (raw / "train").glob("*/*/seed*/config.json"):
        config = json.loads(config_path.read_text())
        curve = config_path.parent / "learning_curve.csv"
        points = max(len(curve.read_text().splitlines()) - 1, 0) if curve.exists() else 0
        validation_steps += points * config["eval_episodes"] * config["env_kwargs"].get("episode_steps", 0)
    discarded = json.loads((raw / "discarded_runs.json").read_text()) if (raw / "discarded_runs.json").exists() else []
    discarded_steps = sum(r["trained_steps"] + r["validation_steps"] for r in discarded)
    if "train" in by_kind:
        # superseded runs (retrained from scratch later) still cost their steps
        by_kind["train"]["env_steps"] = sum(trained.values()) + validation_steps + discarded_steps
    by_kind = {k: {**v, "jobs": len(v["jobs"])} for k, v in by_kind.items()}
    machine = json.loads((raw / "machine.json").read_text()) if (raw / "machine.json").exists() else {}
    sessions = [json.loads(line) for line in (raw / "run_sessions.jsonl").read_text().splitlines() if line.strip()] \
        if (raw / "run_sessions.jsonl").exists() else []
    return {"by_kind": by_kind, "machine": machine, "sessions": sessions,
            "run_wall": {"wall_s": sum(s["wall_s"] for s in sessions)} if sessions else {},
            "training_validation_steps": validation_steps, "discarded_training_steps": discarded_steps,
            "total_env_steps": int(sum(v["env_steps"] for v in by_kind.values()))}


#: history ablation: alternative -> (its frame-stacked reference, with
#: the same reward and step budget; what the alternative is)
HISTORY_ALTERNATIVES = {
    "ppo_stack1": ("ppo_stack8", "no history, 1 frame"),
    "ppo_lstm": ("ppo_stack8", "recurrent: sb3-contrib RecurrentPPO, LSTM"),
    "ppo_lstm_info": ("ppo_info_stack8", "recurrent, information reward"),
}


def history_ablation(table, summary):
    """Frame stacking (8 frames) against no history and against a recurrent policy, PPO, paper
    scenario: ``{alternative: {metric: {"reference", "stack8", "other", ...}}}`` for the
    alternatives run beside their reference."""
    paper = table.get("paper", {})
    out = {}
    for other, (reference, _) in HISTORY_ALTERNATIVES.items():
        if other not in paper or reference not in paper:
            continue
        episode_s = episode_length_s(paper[reference])
        for metric in ("settle_time_s", "rms_error"):
            x = score_matrix(paper[reference], metric, episode_s)
            y = score_matrix(paper[other], metric, episode_s)
            out.setdefault(other, {})[metric] = {
                "reference": reference, "stack8": summary["paper"][reference][metric],
                "other": summary["paper"][other][metric],
                "probability_stack8_better": probability_of_improvement(x, y),
                "ci95": list(probability_of_improvement_ci(x, y, n_boot=500))}
    return out


def training_budget(raw):
    """scenario -> RL config -> trained steps per seed (from each run's config.json)."""
    out = defaultdict(dict)
    for config_dir in sorted((raw / "train").glob("*/*")):
        steps = [json.loads(p.read_text()).get("trained_steps") for p in sorted(config_dir.glob("seed*/config.json"))]
        out[config_dir.parent.name][config_dir.name] = steps
    return dict(out)


def convergence_floor(results, targets_: dict):
    """The bound of ``experiments/settle_floor.py`` set beside the targets; None if it was not run."""
    path = pathlib.Path(results) / "settle_floor.json"
    if not path.exists():
        return None
    floor = json.loads(path.read_text())
    paper, drift = floor["paper"], floor["drift"]
    runs = paper["agents"]
    settled = {k: v["noise_free_settle_s"] for k, v in runs.items() if np.isfinite(v["noise_free_settle_s"])}
    fastest = min(settled, key=settled.get)
    out = {"paper": {
        "bound_settle_s": paper["bound_settle_s"], "peak_field": paper["peak_field"],
        "peak_sensitivity": paper["peak_sensitivity"], "reach_peak_s": paper["peak_field"] / paper["slew_max"],
        "slew_ramp_noise_free_settle_s": paper["slew_ramp_noise_free_settle_s"],
        "slew_ramp_heldout": paper["slew_ramp_heldout"], "runs_checked": len(runs), "fastest_noise_free": fastest,
        "fastest_noise_free_settle_s": settled[fastest], "band": paper["band"],
        "worst_margin": min(v["min_margin"] for v in runs.values()),
        "max_sensitivity_ratio": max(v["max_sensitivity_ratio"] for v in runs.values()),
        "gain_sweep": [dict(row, ratio=row["slew_ramp_settle_s"] / row["ramp_settle_s"])
                       for row in paper.get("gain_sweep", [])]}}
    runs = drift["agents"]
    out["drift"] = {"rms_bound": drift["rms_bound"], "largest_initial_error": max(drift["initial_error"]),
                    "runs_checked": len(runs), "pairs": len(runs) * len(drift["rms_bound_per_draw"]),
                    "pairs_below": sum(v["draws_below_bound"] for v in runs.values()),
                    "min_ratio": min(v["min_ratio_to_bound"] for v in runs.values())}
    target = targets_.get("drift_rms_half_best_schedule")
    if target:
        best = target["best_rl"]
        mine = [v["noise_free_rms_iqm"] for k, v in runs.items() if k.split("/")[0] == best]
        if mine:
            out["drift"].update({"best_rl": best, "best_rl_worst_run_ratio": max(mine) / drift["rms_bound"]["iqm"]})
    return out
