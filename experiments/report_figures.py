"""The benchmark report's figures (PNG), drawn from the raw results and their summaries."""

from __future__ import annotations

import csv

import numpy as np

from .report_data import RL_MAIN, episode_length_s, is_rl_agent
from baselines.survival import censor, kaplan_meier


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
        times, observed = censor(settle, episode_length_s(runs))
        t, s = kaplan_meier(times, observed)
        ax.step(np.r_[t, episode_length_s(runs)], np.r_[s, s[-1]], where="post", label=agent,
                lw=2.2 if is_rl_agent(agent) else 1.2, ls="-" if is_rl_agent(agent) or agent in ("ramp",) else "--")
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
    colors = ["C3" if is_rl_agent(a) else ("C2" if a.startswith("optimal") else "C0") for a in names]
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
