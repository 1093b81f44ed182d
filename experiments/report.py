"""Regenerate every benchmark table and figure from the raw results.

    python -m experiments.report [--results experiments/results] [--readme README.md]

Reads ``raw/`` (see :mod:`experiments.run`) and writes

* ``summary.json`` -- scenario -> agent -> metric -> ``{"iqm", "ci95", "n"}`` for the
  metrics ``settle_time_s`` (never-settled runs censored at the episode length),
  ``rms_error`` (A/m) and, where the raw files have it, ``tracking_rms_error`` (A/m, RMS
  over the episode's second half);
* ``details.json`` -- targets, probabilities of improvement, success rates, sample
  efficiency, the history ablation, training budgets and compute;
* ``RESULTS.md`` (beside ``results/``) -- the tables, target checks and compute;
* PNG figures under ``figures/`` (and copies for the README in ``docs/figures/benchmark/``);
* with ``--readme``, the README's ``benchmark`` section (between its markers only).

Nothing here is typed by hand: rerun it after :mod:`experiments.run` and every number
follows the raw files.
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import shutil
import sys
from collections import defaultdict

import numpy as np

from .stats import iqm, probability_of_improvement, probability_of_improvement_ci, summarize
from .survival import censor, kaplan_meier

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEFAULT_RESULTS = ROOT / "experiments" / "results"
#: summary.json agent keys of the main RL configurations (declared before the run).
RL_MAIN = {"ppo": "ppo_stack8", "sac": "sac_stack8"}
RL_CONFIG_PREFIXES = ("ppo_", "sac_")
ESTIMATORS = ("minmax", "gradient", "multiple_model")


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


def _is_rl(agent):
    return agent.startswith(RL_CONFIG_PREFIXES)


def _episode_s(runs):
    return max(r["episode_time_s"] for rows in runs.values() for r in rows)


def summarize_all(table, n_boot=2000):
    summary, success = {}, {}
    for scenario, agents in sorted(table.items()):
        summary[scenario], success[scenario] = {}, {}
        for agent, runs in sorted(agents.items()):
            episode_s = _episode_s(runs)
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
                  if not _is_rl(a) and a not in RL_MAIN and not (exclude_estimators and a in ESTIMATORS)}
    return min(candidates, key=lambda a: candidates[a][metric]["iqm"]) if candidates else None


def best_schedule(summary_scenario, metric):
    from baselines.registry import SCHEDULE_AGENTS

    candidates = {a: v for a, v in summary_scenario.items() if a in SCHEDULE_AGENTS}
    return min(candidates, key=lambda a: candidates[a][metric]["iqm"]) if candidates else None


def targets(table, summary):
    """The issue's three targets, evaluated; each with the numbers behind it."""
    out = {}
    paper = summary.get("paper", {})
    rl_paper = [a for a in paper if _is_rl(a)]
    if rl_paper and "ramp" in paper:
        best_rl = min(rl_paper, key=lambda a: paper[a]["settle_time_s"]["iqm"])
        ramp = paper["ramp"]["settle_time_s"]
        rl = paper[best_rl]["settle_time_s"]
        baseline = best_baseline(paper, "settle_time_s")
        out["paper_settle_half_ramp"] = {"best_rl": best_rl, "rl_iqm": rl["iqm"], "rl_ci95": rl["ci95"],
                                         "ramp_iqm": ramp["iqm"], "ramp_ci95": ramp["ci95"],
                                         "met": bool(rl["iqm"] <= 0.5 * ramp["iqm"]),
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
            episode_s = _episode_s(table["paper"][best_rl])
            poi = probability_of_improvement(score_matrix(table["paper"][best_rl], "settle_time_s", episode_s),
                                             score_matrix(table["paper"]["optimal_design"], "settle_time_s", episode_s))
            out["paper_vs_optimal_design"] = {"best_rl": best_rl, "rl_iqm": rl["iqm"], "rl_ci95": rl["ci95"],
                                              "design_iqm": design["iqm"], "design_ci95": design["ci95"],
                                              "probability_rl_better": poi,
                                              "rl_beats_design": bool(rl["ci95"][1] < design["ci95"][0])}
    drift = summary.get("drift", {})
    rl_drift = [a for a in drift if _is_rl(a)]
    schedule = best_schedule(drift, "rms_error")
    if rl_drift and schedule:
        best_rl = min(rl_drift, key=lambda a: drift[a]["rms_error"]["iqm"])
        out["drift_rms_half_best_schedule"] = {
            "best_rl": best_rl, "rl_iqm": drift[best_rl]["rms_error"]["iqm"],
            "rl_ci95": drift[best_rl]["rms_error"]["ci95"], "best_schedule": schedule,
            "schedule_iqm": drift[schedule]["rms_error"]["iqm"], "schedule_ci95": drift[schedule]["rms_error"]["ci95"],
            "met": bool(drift[best_rl]["rms_error"]["iqm"] <= 0.5 * drift[schedule]["rms_error"]["iqm"])}
        tracking = [a for a in rl_drift if "tracking_rms_error" in drift[a]]
        tracking_schedule = best_schedule({a: v for a, v in drift.items() if "tracking_rms_error" in v},
                                          "tracking_rms_error")
        if tracking and tracking_schedule:
            rl = min(tracking, key=lambda a: drift[a]["tracking_rms_error"]["iqm"])
            out["drift_rms_half_best_schedule"]["tracking"] = {
                "best_rl": rl, "rl": drift[rl]["tracking_rms_error"], "best_schedule": tracking_schedule,
                "schedule": drift[tracking_schedule]["tracking_rms_error"]}
    return out


def improvements(table, summary):
    """Probability that each RL config improves on the best non-RL excitation baseline."""
    out = {}
    for scenario, agents in table.items():
        for metric in ("settle_time_s", "rms_error"):
            baseline = best_baseline(summary[scenario], metric)
            if baseline is None:
                continue
            episode_s = _episode_s(agents[baseline])
            y = score_matrix(agents[baseline], metric, episode_s)
            for agent in agents:
                if _is_rl(agent):
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


# ----------------------------------------------------------------------------- figures


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def figure_survival(table, scenario, path):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    agents = table.get(scenario, {})
    for agent in sorted(agents):
        runs = agents[agent]
        settle = np.array([r["settle_time_s"] for rows in runs.values() for r in rows])
        times, observed = censor(settle, _episode_s(runs))
        t, s = kaplan_meier(times, observed)
        ax.step(np.r_[t, _episode_s(runs)], np.r_[s, s[-1]], where="post", label=agent,
                lw=2.2 if _is_rl(agent) else 1.2, ls="-" if _is_rl(agent) or agent in ("ramp",) else "--")
    ax.set(xlabel="time (s)", ylabel="P(not yet settled in 0.1 % band)", title=f"Survival of settle time: {scenario}",
           ylim=(-0.02, 1.02))
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_iqm(summary, scenario, metric, path):
    plt = _plt()
    agents = {a: v for a, v in summary.get(scenario, {}).items() if a not in RL_MAIN}
    if not agents:
        return
    names = sorted(agents, key=lambda a: agents[a][metric]["iqm"])
    values = np.array([agents[a][metric]["iqm"] for a in names])
    low = values - np.array([agents[a][metric]["ci95"][0] for a in names])
    high = np.array([agents[a][metric]["ci95"][1] for a in names]) - values
    fig, ax = plt.subplots(figsize=(6.5, 0.3 * len(names) + 1.2))
    colors = ["C3" if _is_rl(a) else ("C2" if a.startswith("optimal") else "C0") for a in names]
    ax.barh(names, values, xerr=[low, high], color=colors, capsize=2)
    ax.set(xlabel=f"IQM {metric} (95 % stratified bootstrap CI)", title=scenario)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_learning_curves(raw, scenario, path):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    any_curve = False
    for config_dir in sorted((raw / "train" / scenario).glob("*")):
        curves = []
        for curve_path in sorted(config_dir.glob("seed*/learning_curve.csv")):
            with curve_path.open() as handle:
                rows = list(csv.DictReader(handle))
            if rows:
                curves.append(np.array([[float(r["env_steps"]), float(r["settle_time_iqm_s"] if scenario != "drift"
                                                                        else r["rms_error_iqm"])] for r in rows]))
        if not curves:
            continue
        any_curve = True
        length = min(len(c) for c in curves)
        stack = np.stack([c[:length] for c in curves])
        steps, values = stack[0, :, 0], stack[:, :, 1]
        line, = ax.plot(steps, np.median(values, axis=0), marker=".", label=f"{config_dir.name} ({len(curves)} seeds)")
        ax.fill_between(steps, *np.percentile(values, [25, 75], axis=0), alpha=0.15, color=line.get_color())
    if not any_curve:
        plt.close(fig)
        return
    # budgets range from 50k to 300k steps: a log axis keeps the short runs readable
    ax.set_xscale("log")
    ax.set(xlabel="environment steps", ylabel="validation IQM " + ("RMS error (A/m)" if scenario == "drift"
                                                                    else "settle time (s)"),
           title=f"Learning curves: {scenario} (median over seeds, band: interquartile range)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _trace(raw, scenario, agent, run=0, index=0):
    path = raw / "eval" / scenario / agent / f"run{run}.npz"
    if not path.exists():
        return None
    data = np.load(path)
    if f"time_{index}" not in data:
        return None
    return {k: data[f"{k}_{index}"] for k in ("time", "field", "a_estimate", "a_true")}


def figure_traces(raw, table, scenario, agents, path):
    plt = _plt()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    plotted = False
    for agent in agents:
        trace = _trace(raw, scenario, agent)
        if trace is None:
            continue
        plotted = True
        top.plot(trace["time"], trace["field"], label=agent, lw=1)
        line, = bottom.plot(trace["time"], trace["a_estimate"], label=agent, lw=1)
        if agent == agents[0]:
            bottom.plot(trace["time"], trace["a_true"], "k--", lw=1.5, label="a_true")
    if not plotted:
        plt.close(fig)
        return
    top.set(ylabel="field H (A/m)", title=f"{scenario}: input and estimate, first held-out draw")
    bottom.set(xlabel="time (s)", ylabel="a estimate (A/m)")
    top.legend(fontsize=6, ncol=3)
    bottom.legend(fontsize=6, ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_pe(table, scenario, path):
    plt = _plt()
    agents = table.get(scenario, {})
    names, a_frac, b_frac = [], [], []
    for agent in sorted(agents):
        rows = [r for rr in agents[agent].values() for r in rr]
        pa, pb = np.array([r["pe_a_fraction"] for r in rows]), np.array([r["pe_b_fraction"] for r in rows])
        if np.isfinite(pa).any():
            names.append(agent)
            a_frac.append(np.nanmean(pa))
            b_frac.append(np.nanmean(pb))
    if not names:
        return
    plt_ = plt
    fig, ax = plt_.subplots(figsize=(6.5, 0.3 * len(names) + 1.2))
    y = np.arange(len(names))
    ax.barh(y - 0.2, a_frac, 0.4, label="3.1(a)")
    ax.barh(y + 0.2, b_frac, 0.4, label="3.1(b)")
    ax.set_yticks(y, names)
    ax.set(xlabel="fraction of time the condition holds", title=f"Persistent excitation: {scenario}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt_.close(fig)


# ----------------------------------------------------------------------------- markdown


def _fmt(entry, digits=3):
    if entry is None:
        return ""
    return f"{entry['iqm']:.{digits}g} [{entry['ci95'][0]:.{digits}g}, {entry['ci95'][1]:.{digits}g}]"


def _scenario_description(name):
    from baselines.scenarios import SCENARIOS

    scenario = SCENARIOS.get(name)
    if scenario is None:
        return ""
    trained = f" Agents tuned, designed and trained in `{scenario.trained_in}`." if scenario.trained_in else ""
    return f"{scenario.description}.{trained}"


def markdown_tables(summary, success, poi, table):
    lines = []
    for scenario in summary:
        agents = {a: v for a, v in summary[scenario].items() if a not in RL_MAIN}
        episode_s = max(_episode_s(runs) for runs in table[scenario].values())
        lines += [f"### Scenario `{scenario}` (episodes of {episode_s:g} s, {len(agents)} agents)", "",
                  *([_scenario_description(scenario), ""] if _scenario_description(scenario) else []),
                  "| agent | runs x draws | settle time IQM (s) [95 % CI] | success | RMS error IQM (A/m) [95 % CI] | "
                  "second-half RMS IQM (A/m) | P(improve) settle | P(improve) RMS |", "|---|---|---|---|---|---|---|---|"]
        for agent in sorted(agents, key=lambda a: agents[a]["settle_time_s"]["iqm"]):
            runs = table[scenario][agent]
            p = poi.get(scenario, {}).get(agent, {})
            p_s = f"{p['settle_time_s']['probability']:.2f} vs {p['settle_time_s']['baseline']}" if "settle_time_s" in p else ""
            p_r = f"{p['rms_error']['probability']:.2f} vs {p['rms_error']['baseline']}" if "rms_error" in p else ""
            lines.append(f"| {'**' + agent + '**' if _is_rl(agent) else agent} | {len(runs)} x {len(runs[min(runs)])} | "
                         f"{_fmt(agents[agent]['settle_time_s'])} | {success[scenario][agent]:.0%} | "
                         f"{_fmt(agents[agent]['rms_error'])} | {_fmt(agents[agent].get('tracking_rms_error'))} | "
                         f"{p_s} | {p_r} |")
        lines.append("")
    return lines


def markdown_targets(tgt):
    lines = []
    t = tgt.get("paper_settle_half_ramp")
    if t:
        lines.append(f"- **Paper scenario, settle time <= half the ramp's:** best RL config `{t['best_rl']}` "
                     f"IQM {t['rl_iqm']:.3g} s [{t['rl_ci95'][0]:.3g}, {t['rl_ci95'][1]:.3g}] vs ramp "
                     f"{t['ramp_iqm']:.3g} s [{t['ramp_ci95'][0]:.3g}, {t['ramp_ci95'][1]:.3g}]: "
                     f"**{'met' if t['met'] else 'NOT met'}**.")
        if t.get("best_non_rl"):
            gap = 1.0 - 0.5 * t["ramp_iqm"] / t["best_non_rl_iqm"]
            lines.append(f"  For scale: the best non-RL input, `{t['best_non_rl']}`, settles at "
                         f"{t['best_non_rl_iqm']:.3g} s, so half the ramp ({0.5 * t['ramp_iqm']:.3g} s) asks RL to "
                         f"settle {gap:.0%} faster than the best input found without RL.")
        if "direct_design_iqm" in t:
            reached = t["fastest_input_iqm"] <= 0.5 * t["ramp_iqm"]
            lines.append(f"  The direct search on the settle time itself (`direct_design`: CMA-ES over the input, "
                         f"scored by simulating the closed loop on tuning draws) settles at "
                         f"{t['direct_design_iqm']:.3g} s; the fastest excitation of any kind, RL included, is "
                         f"`{t['fastest_input']}` at {t['fastest_input_iqm']:.3g} s, so "
                         + ("an input meeting the target exists." if reached else
                            "no input found here by any method reaches half the ramp."))
    else:
        lines.append("- Paper scenario target: no RL results in this run.")
    t = tgt.get("drift_rms_half_best_schedule")
    if t:
        lines.append(f"- **Drift scenario, RMS error <= half the best schedule's:** best RL config `{t['best_rl']}` "
                     f"IQM {t['rl_iqm']:.3g} A/m [{t['rl_ci95'][0]:.3g}, {t['rl_ci95'][1]:.3g}] vs best schedule "
                     f"`{t['best_schedule']}` {t['schedule_iqm']:.3g} A/m [{t['schedule_ci95'][0]:.3g}, "
                     f"{t['schedule_ci95'][1]:.3g}]: **{'met' if t['met'] else 'NOT met'}**.")
        if "tracking" in t:
            k = t["tracking"]
            lines.append(f"  The episode RMS is mostly the initial acquisition (initial errors of up to a few hundred "
                         f"A/m). Over the episode's second half (tracking once acquired): best RL `{k['best_rl']}` "
                         f"{_fmt(k['rl'])} A/m vs best schedule `{k['best_schedule']}` {_fmt(k['schedule'])} A/m, "
                         f"ratio {k['rl']['iqm'] / k['schedule']['iqm']:.2f}.")
    else:
        lines.append("- Drift scenario target: no RL results in this run.")
    t = tgt.get("paper_vs_optimal_design")
    if t:
        if t["rl_beats_design"]:
            verdict = "RL beats the optimal design (the intervals do not overlap)"
        elif t["rl_iqm"] < t["design_iqm"]:
            verdict = "RL's IQM is lower, but the intervals overlap: RL does **not** clearly beat the optimal design"
        else:
            verdict = "RL does **not** beat the optimal design: it is slower"
        lines.append(f"- **Against the open-loop optimal design (paper):** `{t['best_rl']}` {t['rl_iqm']:.3g} s "
                     f"[{t['rl_ci95'][0]:.3g}, {t['rl_ci95'][1]:.3g}] vs `optimal_design` {t['design_iqm']:.3g} s "
                     f"[{t['design_ci95'][0]:.3g}, {t['design_ci95'][1]:.3g}]; P(RL better) = "
                     f"{t['probability_rl_better']:.2f}. {verdict}.")
    return lines


#: history ablation (issue 5, "Ablations"): alternative -> (its frame-stacked reference, with
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
        episode_s = _episode_s(paper[reference])
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


def markdown_budget(budget, sessions):
    parts = [f"`{config}` ({scenario}): {len(steps)} seeds x {min(steps):,}-{max(steps):,} steps"
             for scenario, configs in budget.items() for config, steps in configs.items() if steps]
    text = "Training budget: " + "; ".join(parts) + "." if parts else "No RL training in this run."
    if len(sessions) > 1:
        text += (f" The run was made in {len(sessions)} sessions of `experiments/run.py`; runs whose declared budget "
                 "grew in a later session were continued from their saved model (`--resume`); superseded runs "
                 "are listed in `raw/discarded_runs.json`.")
    return [text]


def markdown_ablation(ablation):
    lines = []
    for other, metrics in ablation.items():
        for metric, entry in metrics.items():
            lines.append(f"- History, {metric}: `{entry['reference']}` (8 stacked frames) {_fmt(entry['stack8'])} vs "
                         f"`{other}` ({HISTORY_ALTERNATIVES[other][1]}) {_fmt(entry['other'])}; P(stack8 better) = "
                         f"{entry['probability_stack8_better']:.2f} [{entry['ci95'][0]:.2f}, {entry['ci95'][1]:.2f}].")
    verdicts = []
    for other, metrics in ablation.items():
        entry = metrics.get("settle_time_s")
        if entry:
            low, high = entry["ci95"]
            verdicts.append(f"`{entry['reference']}` over `{other}`" if low > 0.5 else
                            f"`{other}` over `{entry['reference']}`" if high < 0.5 else
                            f"no clear winner between `{entry['reference']}` and `{other}`")
    if verdicts:
        lines.append("- Which history works (settle time, by whether the interval of P(stack8 better) excludes 0.5): "
                     + "; ".join(verdicts) + ".")
    if "ppo_lstm" not in ablation:
        lines.append("- A recurrent policy (`ppo_lstm`, sb3-contrib RecurrentPPO) is declared but has no results in "
                     "this run.")
    lines += markdown_reward_ablation(DEFAULT_RESULTS / "ablation_reward.json")
    return lines


def markdown_reward_ablation(path):
    """Lines for the reward ablation, from ``python -m experiments.ablation_reward``'s summary when it exists."""
    path = pathlib.Path(path)
    if not path.exists():
        return ["- Reward ablation (dense error against an information increment): not run in this benchmark; "
                "every RL config uses the environment's dense reward -|a_estimate - a_true|/width(Theta)."]
    data = json.loads(path.read_text())
    arms, poi = data["arms"], data["probability_of_improvement"]
    lines = [f"- Reward ablation (`python -m experiments.ablation_reward`, `{data['config']}` in `{data['scenario']}`, "
             f"{data.get('training_seeds', '?')} seeds x {data.get('timesteps_per_run', 0):,} steps per arm, every "
             "arm retrained by the same code): dense error reward -|a_estimate - a_true|/width(Theta) (uses the "
             "truth), the information increment (df/da at a_estimate)^2, normalized (no truth), and the band "
             "reward, -1 per step outside the 0.1 % settle band (the metric itself; uses the truth) "
             "(`baselines/rewards.py`):", "",
             "| reward | settle time IQM (s) | RMS error IQM (A/m) | final error IQM (A/m) | success | "
             "P(better than dense) |", "|---|---|---|---|---|---|"]
    for arm, entry in arms.items():
        if "settle_time_s" not in entry:
            continue
        better = ", ".join(f"{m.split('_')[0]} {v['over_dense']:.2f} [{v['ci95'][0]:.2f}, {v['ci95'][1]:.2f}]"
                           for m, v in poi.get(arm, {}).items() if m in ("settle_time_s", "rms_error", "final_error"))
        final = _fmt(entry["final_error"]) if "final_error" in entry else ""
        lines.append(f"| {arm} | {_fmt(entry['settle_time_s'])} | {_fmt(entry['rms_error'])} | {final} | "
                     f"{entry['success_rate']:.0%} | {better} |")
    return lines


def markdown_pe(table):
    lines = ["Mean fraction of the episode during which the windowed test (1 s window, "
             "`hyst_gym.estimation.PEMonitor`) finds condition 3.1(a) (the integrand of (22) changes sign at fixed "
             "curvature) or 3.1(b) (the curvature changes sign at fixed integrand sign), from the truth the "
             "environment reports in `info`.", "", "| scenario | agent | 3.1(a) | 3.1(b) |", "|---|---|---|---|"]
    for scenario in ("paper", "drift", "lumped"):
        for agent in sorted(table.get(scenario, {})):
            rows = [r for rr in table[scenario][agent].values() for r in rr]
            pa = np.array([r["pe_a_fraction"] for r in rows])
            pb = np.array([r["pe_b_fraction"] for r in rows])
            if np.isfinite(pa).any():
                lines.append(f"| {scenario} | {agent} | {np.nanmean(pa):.2f} | {np.nanmean(pb):.2f} |")
    return lines


def markdown_efficiency(efficiency):
    lines = ["Environment steps at which a run's validation IQM (16 validation draws, disjoint from the held-out "
             "set, first few used) first reached the reference agent's held-out IQM; `never` = not within training.",
             "", "| scenario | RL config | reference (held-out IQM) | steps to reach, per seed |", "|---|---|---|---|"]
    for scenario, configs in efficiency.items():
        for config, entry in configs.items():
            steps = ", ".join("never" if s is None else f"{s:,}" for s in entry["steps_to_reach"])
            lines.append(f"| {scenario} | {config} | {entry['reference']} ({entry['reference_iqm']:.3g}) | {steps} |")
    return lines


def markdown_compute(compute):
    m = compute["machine"]
    lines = [f"Machine: {m.get('platform', '?')}, {m.get('processor', '?')}, {m.get('cpu_count', '?')} CPU cores "
             f"(shared with other work while it ran), {m.get('workers', '?')} worker processes, backend "
             f"`{m.get('backend', '?')}`, profile `{m.get('profile', '?')}`.", "",
             "| job kind | jobs | env steps | summed job wall time (s) |", "|---|---|---|---|"]
    for kind, entry in sorted(compute["by_kind"].items()):
        lines.append(f"| {kind} | {entry['jobs']} | {entry['env_steps']:,} | {entry['cpu_wall_s']:.0f} |")
    lines.append(f"| **total** | {sum(e['jobs'] for e in compute['by_kind'].values())} | "
                 f"{compute['total_env_steps']:,} | {sum(e['cpu_wall_s'] for e in compute['by_kind'].values()):.0f} |")
    lines += ["", f"Training env steps include {compute['training_validation_steps']:,} steps of learning-curve "
              f"validation episodes and {compute['discarded_training_steps']:,} steps of superseded runs "
              "(`raw/discarded_runs.json`)."]
    if compute["run_wall"]:
        lines += ["", f"Wall time of the run: {compute['run_wall']['wall_s']:.0f} s over {len(compute['sessions'])} "
                  "session(s) of `python -m experiments.run` ("
                  + ", ".join(f"{s['wall_s']:.0f} s, {s['jobs_run']} jobs" for s in compute["sessions"]) + ")."]
    return lines


def write_report(results=DEFAULT_RESULTS, readme=None, n_boot=2000):
    results = pathlib.Path(results)
    raw = results / "raw"
    table = load_episodes(raw)
    if not table:
        raise OSError(f"no evaluation results under {raw / 'eval'}; run python -m experiments.run first")
    summary, success = summarize_all(table, n_boot)
    poi = improvements(table, summary)
    tgt = targets(table, summary)
    compute = compute_used(raw)
    efficiency = sample_efficiency(raw, summary)
    ablation = history_ablation(table, summary)
    budget = training_budget(raw)
    (results / "summary.json").write_text(json.dumps(summary, indent=2))
    (results / "details.json").write_text(json.dumps(
        {"success_rate": success, "probability_of_improvement": poi, "targets": tgt,
         "sample_efficiency": efficiency, "history_ablation": ablation, "training_steps": budget,
         "compute": compute, "settle_band": "0.1 % of a_true",
         "censoring": "never-settled runs count as the episode length"}, indent=2))
    figures = results / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    made = []
    for scenario in table:
        for name, make in ((f"survival_{scenario}.png", lambda p: figure_survival(table, scenario, p)),
                           (f"iqm_settle_{scenario}.png", lambda p: figure_iqm(summary, scenario, "settle_time_s", p)),
                           (f"iqm_rms_{scenario}.png", lambda p: figure_iqm(summary, scenario, "rms_error", p)),
                           (f"learning_{scenario}.png", lambda p: figure_learning_curves(raw, scenario, p)),
                           (f"pe_{scenario}.png", lambda p: figure_pe(table, scenario, p))):
            make(figures / name)
            if (figures / name).exists():
                made.append(name)
        agents = [a for a in ("ramp", "optimal_design", "greedy_info", "ppo_stack8", "ppo_info_stack8", "sac_stack8")
                  if a in table[scenario]]
        figure_traces(raw, table, scenario, agents, figures / f"traces_{scenario}.png")
        if (figures / f"traces_{scenario}.png").exists():
            made.append(f"traces_{scenario}.png")
    lines = ["# Benchmark results", "",
             "Generated by `python -m experiments.report` from the raw per-episode files in "
             "`experiments/results/raw/` (written by `python -m experiments.run`). Do not edit by hand.", "",
             "Protocol: every agent is evaluated on the same held-out draws (seeds 100000-100049); IQM with a 95 % "
             "stratified-bootstrap interval (strata = draws, runs = training seeds resampled within each draw); "
             "settle time = first time after which |a_estimate - a_true| stays within 0.1 % of a_true, "
             "never-settled runs censored at the episode length (see the survival curves); P(improve) = probability "
             "that an RL run beats the best non-RL excitation baseline on the same draw. The estimator agents "
             "(`minmax`, `gradient`, `multiple_model`) run on `Estimation-v0` under the environment's ramp (the "
             "paper's input), so they compare estimators, not inputs; every other agent drives `Excitation-v0` "
             "with the min-max estimator inside. RL configs (`experiments/config.py`): `<algo>_stack<k>` = the "
             "policy sees the last k observations (frame stacking); `ppo_lstm` = RecurrentPPO, one observation and "
             "an LSTM state; `ppo_info_stack8` = trained on the information increment instead of the dense error; "
             "`ppo`/`sac` in summary.json are the declared main configs `ppo_stack8`/`sac_stack8`; the targets use "
             "the best RL config, chosen on these same held-out draws.", "",
             "## Targets", ""] + markdown_targets(tgt) + [""] + markdown_budget(budget, compute["sessions"]) + \
        ["", "## Ablations", ""] + markdown_ablation(ablation) + \
        ["", "## Tables", ""] + \
        markdown_tables(summary, success, poi, table) + ["## Persistent excitation", ""] + markdown_pe(table) + \
        ["", "The inputs themselves (the learned H(t) beside the ramp) are in the `traces_*.png` figures.", "",
         "## Sample efficiency", ""] + \
        markdown_efficiency(efficiency) + ["", "## Compute", ""] + markdown_compute(compute) + \
        ["", "## Figures", ""] + [f"![{name}](results/figures/{name})" for name in made] + [""]
    (results.parent / "RESULTS.md").write_text("\n".join(lines))
    if readme is not None:
        docs = ROOT / "docs" / "figures" / "benchmark"
        docs.mkdir(parents=True, exist_ok=True)
        for name in ("survival_paper.png", "traces_paper.png", "traces_drift.png", "learning_paper.png"):
            if (figures / name).exists():
                shutil.copyfile(figures / name, docs / name)
        update_readme(pathlib.Path(readme), readme_section(tgt, summary, compute, ablation,
                                                           markdown_budget(budget, compute["sessions"])))
    return summary


def readme_section(tgt, summary, compute, ablation=None, budget_lines=()):
    lines = ["## Benchmark: can a learned excitation beat classical inputs?", "",
             "Agents (`baselines/`): the paper's ramp and tuned sine, chirp, multilevel PRBS, Schroeder multisine and "
             "random schedules; a CMA-ES optimal design maximizing Fisher information about a (nominal and "
             "prior-averaged); a direct-search design (CMA-ES on the simulated settle time itself); a "
             "receding-horizon information-maximizing input; the min-max, gradient and "
             "multiple-model estimators as agents on `Estimation-v0`; PPO and SAC (Stable-Baselines3) with frame "
             "stacking and RecurrentPPO (sb3-contrib, LSTM) on `Excitation-v0`, trained on the dense error reward "
             "or (`ppo_info_stack8`) on the Fisher-information increment, which uses no truth. All share the same "
             "field/slew limits and the same 50 held-out draws.", "",
             "```bash", ".venv/bin/python -m experiments.run --workers 2      # raw results -> experiments/results/raw",
             ".venv/bin/python -m experiments.report --readme README.md  # tables, figures, summary.json, this section",
             ".venv/bin/hyst-gym train --algo ppo --env hyst_gym/Excitation-v0 --timesteps 50000 --seed 0 --out runs/ppo0",
             ".venv/bin/hyst-gym evaluate --agent runs/ppo0 --env hyst_gym/Excitation-v0 --episodes 50 --out runs/eval",
             "```", "", "Results of the committed run (generated by `experiments/report.py`; full tables in "
             "[experiments/RESULTS.md](experiments/RESULTS.md)):", ""]
    lines += markdown_targets(tgt)
    lines += [""] + list(budget_lines)
    lines += ["", "| agent | paper: settle time IQM (s) | paper: RMS error (A/m) | drift: RMS error (A/m) | "
              "drift: second-half RMS (A/m) | lumped: settle time (s) |", "|---|---|---|---|---|---|"]
    cell = lambda scenario, agent, metric: (f"{summary[scenario][agent][metric]['iqm']:.3g} "  # noqa: E731
                                            f"[{summary[scenario][agent][metric]['ci95'][0]:.3g}, "
                                            f"{summary[scenario][agent][metric]['ci95'][1]:.3g}]"
                                            if metric in summary.get(scenario, {}).get(agent, {}) else "")
    for agent in ("ramp", "ramp_tuned", "sine", "chirp", "prbs", "multisine", "random", "optimal_design",
                  "optimal_design_prior", "direct_design", "greedy_info", "minmax", "gradient", "multiple_model", "ppo",
                  "ppo_stack1", "ppo_lstm", "ppo_info_stack8", "ppo_lstm_info", "sac"):
        if any(agent in summary.get(s, {}) for s in ("paper", "drift", "lumped")):
            lines.append(f"| {agent} | {cell('paper', agent, 'settle_time_s')} | {cell('paper', agent, 'rms_error')} | "
                         f"{cell('drift', agent, 'rms_error')} | {cell('drift', agent, 'tracking_rms_error')} | "
                         f"{cell('lumped', agent, 'settle_time_s')} |")
    paper = summary.get("paper", {})
    draws = paper["ramp"]["settle_time_s"]["n"] if "ramp" in paper else 50
    seeds = sorted({v["settle_time_s"]["n"] // draws for a, v in paper.items() if _is_rl(a)})
    lines += ["", f"IQM [95 % stratified-bootstrap CI] over the {draws} held-out draws"
              + (f" (x {'-'.join(map(str, (seeds[0], seeds[-1]) if len(seeds) > 1 else seeds))} training seeds "
                 "for RL)" if seeds else "")
              + "; `minmax`, `gradient`, `multiple_model` are the estimators as agents under the ramp.", ""]
    lines += markdown_ablation(ablation or {})
    lines += ["",
              "", f"Compute: {compute['total_env_steps']:,} environment steps"
              + (f", {compute['run_wall'].get('wall_s', 0) / 60:.0f} min wall" if compute["run_wall"] else "")
              + f" on {compute['machine'].get('cpu_count', '?')} CPU cores.", ""]
    for name, caption in (("survival_paper.png", "Settle-time survival, paper scenario"),
                          ("traces_paper.png", "Paper scenario: the learned H(t) beside the ramp and the designs"),
                          ("traces_drift.png", "Drift scenario: inputs and estimates"),
                          ("learning_paper.png", "Learning curves")):
        if (ROOT / "docs" / "figures" / "benchmark" / name).exists():
            lines.append(f"![{caption}](docs/figures/benchmark/{name})")
    return "\n".join(lines)


def update_readme(path: pathlib.Path, body: str, area: str = "benchmark"):
    """Replace only the text between ``<!-- section:AREA -->`` and ``<!-- /section:AREA -->``."""
    text = path.read_text()
    start, end = f"<!-- section:{area} -->", f"<!-- /section:{area} -->"
    if text.count(start) != 1 or text.count(end) != 1 or text.index(start) > text.index(end):
        raise ValueError(f"{path}: expected exactly one {start} ... {end} pair")
    head, rest = text.split(start)
    _, tail = rest.split(end)
    path.write_text(f"{head}{start}\n{body.strip()}\n{end}{tail}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.report", description=__doc__.splitlines()[0])
    parser.add_argument("--results", default=str(DEFAULT_RESULTS))
    parser.add_argument("--readme", default=None, help="also update this README's benchmark section")
    parser.add_argument("--n-boot", type=int, default=2000)
    args = parser.parse_args(argv)
    try:
        write_report(args.results, args.readme, args.n_boot)
    except (OSError, ValueError) as error:
        parser.exit(2, f"experiments.report: error: {error}\n")
    print(f"[report] wrote {pathlib.Path(args.results) / 'summary.json'} and RESULTS.md")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
