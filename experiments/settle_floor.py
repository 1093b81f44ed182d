"""The convergence floor: how fast can *any* input make the min-max estimator converge?

    python -m experiments.settle_floor [--rl-seeds 10]

The paper scenario's targets ask the best RL policy for half the ramp's settle time in ``paper`` and
half the best schedule's RMS error in ``drift``. This script computes, from the physics
and the estimator alone, the linearized bound of :mod:`hyst_gym.estimation.convergence`:
under the common slew limit the field, and with it the sensitivity ``|dM/da|`` that drives
the estimator, can only grow so fast, and the estimator's gain turns that sensitivity into
a convergence rate. The bound is then checked against independent computations:

* the full nonlinear closed loop (hysteresis bank, min-max covers, dead zone), noise off,
  under the input the bound calls optimal: a ramp at the slew limit to the field of peak
  sensitivity, then held (``slew_ramp``);
* every benchmark agent's own closed loop, noise off (schedules, designs, greedy, every
  trained RL run): its error must never fall below the bound, and the sensitivity along its
  field trace must not exceed the envelope the bound assumes;
* in ``drift``, the bound on the episode RMS error for each held-out draw against every
  agent's noise-free RMS on the same draw.

Last, a sweep over the estimator's adaptation gain shows how the paper target (a ratio of
two inputs' settle times under one estimator) depends on the gain the paper chose.

Writes ``experiments/results/settle_floor.json`` and ``figures/settle_floor.png``;
``python -m experiments.report`` quotes it beside the targets.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import numpy as np

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
#: time step of the bound while the envelope still grows, s (the bound is exact per step
#: for a frozen sensitivity; 1 ms puts its settle time within 1 ms of the continuous one)
FINE_DT = 1e-3
#: the non-RL agents checked against the bound (in drift, greedy_info -- over 3x the bound's RMS
#: there and the slowest to simulate -- and the estimators under the fixed ramp are left out)
BASELINES = {"paper": ("ramp", "ramp_tuned", "sine", "chirp", "prbs", "multisine", "random", "optimal_design",
                       "optimal_design_prior", "direct_design", "greedy_info"),
             "drift": ("ramp_tuned", "sine", "chirp", "prbs", "multisine", "random", "optimal_design",
                       "optimal_design_prior", "direct_design")}


def estimator_of(scenario):
    """The estimator configuration the scenario's environment runs."""
    from hyst_gym.envs.core import estimator_config

    return estimator_config(scenario.env_config)


def bound_grid(scenario) -> np.ndarray:
    """Fine steps while the envelope grows (until the slew limit reaches the field limit), control steps after."""
    limits = scenario.limits
    growth_s = limits.field_max / limits.slew_max
    fine = np.arange(0.0, growth_s + FINE_DT, FINE_DT)
    coarse = np.arange(0, scenario.episode_steps + 1) * limits.dt
    return np.unique(np.round(np.concatenate([fine, coarse]), 9))


def error_bound_for(scenario, config, a_true: float):
    """Time grid, sensitivity envelope and error bound for one true a; plus the sensitivity curve."""
    from hyst_gym.estimation.convergence import error_bound, sensitivity_curve, sensitivity_envelope

    limits = scenario.limits
    fields, sensitivity = sensitivity_curve(config, a_true, limits.field_max)
    time = bound_grid(scenario)
    envelope = sensitivity_envelope(time, fields, sensitivity, limits.slew_max, limits.field_max)
    error = error_bound(time, envelope, abs(config.initial_estimate - a_true), config.plant, config.gamma)
    return time, envelope, error, fields, sensitivity


def slew_ramp(scenario, peak_field: float):
    """The bound's optimal input: a ramp at the slew limit to ``peak_field`` (A/m), then held."""
    from baselines.agents import ScheduleAgent
    from baselines.schedules import Ramp

    duration = peak_field / scenario.limits.slew_max
    return ScheduleAgent(Ramp(peak=peak_field, duration=duration), scenario.limits, scenario.episode_steps,
                         name="slew_ramp")


def noise_free(scenario):
    from baselines.environment import EpisodeSpec

    spec = scenario.spec()
    return EpisodeSpec(spec.env_id, {**spec.env_kwargs, "output_noise": 0.0}, spec.dt)


def agents_of(scenario_name, raw, rl_seeds):
    """(label, agent factory) for every baseline and every trained RL run of the scenario."""
    from baselines.registry import make_agent
    from baselines.scenarios import SCENARIOS
    from experiments.config import RL_CONFIGS

    scenario = SCENARIOS[scenario_name]
    out = [(name, lambda name=name: make_agent(name, scenario, raw)) for name in BASELINES[scenario_name]]
    for config in sorted(RL_CONFIGS):
        for seed in range(rl_seeds):
            path = raw / "train" / scenario_name / config / f"seed{seed}"
            if (path / "model.zip").exists():
                out.append((f"{config}/seed{seed}", lambda path=path: make_agent(str(path), scenario)))
    return out


def paper_floor(raw, rl_seeds, progress):
    from baselines.evaluation import run_episodes
    from baselines.scenarios import HELDOUT_SEEDS, SCENARIOS
    from hyst_gym.estimation.convergence import first_passage, sensitivity_along
    from baselines.stats import summarize
    from baselines.survival import censor

    scenario = SCENARIOS["paper"]
    config = estimator_of(scenario)
    a_true = scenario.settings["a_true"]
    band = 1e-3 * a_true
    time, envelope, bound, fields, sensitivity = error_bound_for(scenario, config, a_true)
    peak_field = float(fields[np.argmax(sensitivity)])
    result = {"a_true": a_true, "initial_error": abs(config.initial_estimate - a_true), "band": band,
              "plant_lam": config.plant.decay_rate, "gamma": config.gamma, "slew_max": scenario.limits.slew_max,
              "peak_field": peak_field, "peak_sensitivity": float(sensitivity.max()),
              "bound_settle_s": first_passage(time, bound, band)}
    ramp = slew_ramp(scenario, peak_field)
    records, ramp_trace = run_episodes(ramp, noise_free(scenario), HELDOUT_SEEDS[:1], keep_traces=1)
    result["slew_ramp_noise_free_settle_s"] = records[0]["settle_time_s"]
    records, _ = run_episodes(ramp, scenario.spec(), HELDOUT_SEEDS)
    result["slew_ramp_heldout"] = summarize(censor([r["settle_time_s"] for r in records], scenario.episode_s)[0])
    checks, traces = {}, {"slew_ramp": ramp_trace[0]}
    for label, factory in progress(agents_of("paper", raw, rl_seeds), "paper agents, noise off"):
        records, trace = run_episodes(factory(), noise_free(scenario), HELDOUT_SEEDS[:1], keep_traces=1)
        trace = trace[0]
        error = np.abs(trace["a_estimate"] - trace["a_true"])
        allowed = np.interp(trace["time"], time, bound)
        reached = sensitivity_along(config, trace["field"], a_true)
        cap = np.interp(trace["time"], time, envelope)
        checks[label] = {"noise_free_settle_s": records[0]["settle_time_s"],
                         "min_margin": float(np.min(error - allowed)),
                         "max_sensitivity_ratio": float(np.max(reached / np.maximum(cap, 1e-12)))}
        traces[label] = trace
    result["agents"] = checks
    curves = {"time": time, "envelope": envelope, "bound": bound, "fields": fields, "sensitivity": sensitivity}
    return result, curves, traces


def drift_floor(raw, rl_seeds, progress):
    from baselines.agents import ConstantAgent
    from baselines.evaluation import run_episodes
    from baselines.scenarios import HELDOUT_SEEDS, SCENARIOS
    from baselines.stats import summarize

    scenario = SCENARIOS["drift"]
    config = estimator_of(scenario)
    spec = noise_free(scenario)
    step_times = np.arange(1, scenario.episode_steps + 1) * scenario.limits.dt
    # the draws' true a at the start, read after one step at zero field: no Joule heating,
    # and the ambient drift (<= 0.05 K/s) moves a by under 0.1 A/m in one 50 ms step
    _, traces = run_episodes(ConstantAgent([0.0]), spec, HELDOUT_SEEDS, keep_traces=len(HELDOUT_SEEDS))
    initial_a = np.array([trace["a_true"][0] for trace in traces])
    rms_bound = np.empty(len(HELDOUT_SEEDS))
    for draw, a_true in enumerate(progress(initial_a, "drift bounds")):
        time, _, bound, _, _ = error_bound_for(scenario, config, float(a_true))
        rms_bound[draw] = np.sqrt(np.mean(np.interp(step_times, time, bound) ** 2))
    checks, per_draw = {}, {}
    for label, factory in progress(agents_of("drift", raw, rl_seeds), "drift agents, noise off"):
        records, _ = run_episodes(factory(), spec, HELDOUT_SEEDS)
        rms = np.array([r["rms_error"] for r in records])
        per_draw[label] = rms
        checks[label] = {"noise_free_rms_iqm": summarize(rms[None, :])["iqm"],
                         "min_ratio_to_bound": float(np.min(rms / rms_bound)),
                         "draws_below_bound": int(np.sum(rms < rms_bound))}
    return {"initial_a": initial_a.tolist(), "initial_error": np.abs(config.initial_estimate - initial_a).tolist(),
            "rms_bound_per_draw": rms_bound.tolist(),
            "rms_bound": summarize(rms_bound[None, :]), "agents": checks}, per_draw


#: adaptation gains of the sweep (the paper's is 1); all keep the comparison system
#: overdamped at the peak sensitivity of the paper's parameters (gamma*9.9**2 < 2500)
SWEEP_GAINS = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0)


def gain_sweep(progress):
    """Settle time of the paper's ramp and of the bound's fastest input against the estimator gain.

    The targets compare two inputs under one estimator; the ratio depends on its gain. For
    each gain: the bound, and the environment's own closed loop (noise off) under the paper's
    ramp and under ``slew_ramp``, so one sees where half the ramp would become reachable.
    """
    import dataclasses

    from baselines.agents import ScheduleAgent
    from baselines.evaluation import run_episodes
    from baselines.scenarios import HELDOUT_SEEDS, SCENARIOS
    from baselines.schedules import Ramp
    from hyst_gym.estimation.convergence import first_passage

    base = SCENARIOS["paper"]
    rows = []
    for gain in progress(SWEEP_GAINS, "gain sweep"):
        scenario = dataclasses.replace(base, settings={**base.settings, "estimator_gamma": gain})
        config = estimator_of(scenario)
        a_true = scenario.settings["a_true"]
        time, _, bound, fields, sensitivity = error_bound_for(scenario, config, a_true)
        spec = noise_free(scenario)
        ramp = ScheduleAgent(Ramp(), scenario.limits, scenario.episode_steps, name="ramp")
        fastest = slew_ramp(scenario, float(fields[np.argmax(sensitivity)]))
        settle = {agent.name: run_episodes(agent, spec, HELDOUT_SEEDS[:1])[0][0]["settle_time_s"]
                  for agent in (ramp, fastest)}
        rows.append({"gamma": gain, "bound_settle_s": first_passage(time, bound, 1e-3 * a_true),
                     "ramp_settle_s": settle["ramp"], "slew_ramp_settle_s": settle["slew_ramp"]})
    return rows


def plot(paper, curves, traces, drift, drift_rms, summary, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(20, 4.2))
    ax = axes[0]
    ax.plot(curves["fields"] / 1e3, curves["sensitivity"], color="k")
    ax.axvline(paper["peak_field"] / 1e3, color="tab:red", ls=":",
               label=f"peak at {paper['peak_field'] / 1e3:.1f} kA/m")
    ax.set(xlabel="field H on the initial curve (kA/m)", ylabel="|dM/da| at a = 7012",
           title="Sensitivity that drives the estimator")
    ax.legend(loc="upper left")
    ax = axes[1]
    ax.semilogy(curves["time"], curves["bound"], color="k", lw=2.5, label="linearized bound")
    shown = ["ramp", "optimal_design", "direct_design", "slew_ramp"]
    rl = [k for k in traces if k.startswith("ppo_info_stack8/")][:1]
    for label in shown + rl:
        if label in traces:
            trace = traces[label]
            ax.semilogy(trace["time"], np.abs(trace["a_estimate"] - trace["a_true"]), lw=1, label=label)
    ax.axhline(paper["band"], color="gray", ls="--", label="0.1 % band")
    target = (summary or {}).get("paper", {}).get("ramp", {}).get("settle_time_s", {}).get("iqm")
    if target:
        ax.axvline(target / 2, color="tab:red", ls=":", label=f"half the ramp ({target / 2:.2f} s)")
    ax.set(xlim=(0, 5), ylim=(1, 40), xlabel="time (s)", ylabel="|a_estimate - a| (A/m), noise off",
           title=f"paper: bound settles at {paper['bound_settle_s']:.2f} s")
    ax.legend(fontsize=7)
    ax = axes[2]
    bound = np.array(drift["rms_bound_per_draw"])
    order = np.argsort(bound)
    ax.plot(bound[order], color="k", lw=2.5, label="bound, per draw")
    shown = ["sine", "optimal_design"] + [k for k in drift_rms if k.startswith("ppo_info_stack8/")][:1]
    for label in shown:
        if label in drift_rms:
            ax.plot(drift_rms[label][order], ".", ms=5, label=f"{label} (noise off)")
    half = _half_best_schedule(summary, "drift")
    if half:
        ax.axhline(half, color="tab:red", ls=":", label=f"target: half the best schedule ({half:.1f} A/m)")
    ax.set(xlabel="held-out draw (sorted by bound)", ylabel="episode RMS error (A/m)",
           title=f"drift: RMS bound IQM {drift['rms_bound']['iqm']:.1f} A/m")
    ax.legend(fontsize=8)
    ax = axes[3]
    sweep = paper.get("gain_sweep", [])
    gains = np.array([row["gamma"] for row in sweep])
    ratio = np.array([row["slew_ramp_settle_s"] / row["ramp_settle_s"] for row in sweep])  # nan: ramp never settles
    ax.semilogx(gains, ratio, "o-", color="k", label="fastest input / paper's ramp")
    never = gains[~np.isfinite(ratio)]
    if never.size:
        ax.text(0.3, 0.55, "ramp never settles in the episode at gamma = " + ", ".join(f"{g:g}" for g in never),
                transform=ax.transAxes, fontsize=8)
    ax.axhline(0.5, color="tab:red", ls=":", label="target: half the ramp")
    ax.axvline(paper["gamma"], color="gray", ls="--", label=f"the paper's gain ({paper['gamma']:g})")
    ax.set(xlabel="adaptation gain gamma", ylabel="settle-time ratio (noise off)",
           title="paper target against the estimator gain")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _half_best_schedule(summary, scenario):
    from baselines.registry import SCHEDULE_AGENTS

    rows = (summary or {}).get(scenario, {})
    values = [rows[a]["rms_error"]["iqm"] for a in SCHEDULE_AGENTS if a in rows]
    return min(values) / 2 if values else None


def main(argv=None) -> int:
    from tqdm.auto import tqdm

    parser = argparse.ArgumentParser(prog="python -m experiments.settle_floor", description=__doc__.splitlines()[0])
    parser.add_argument("--rl-seeds", type=int, default=10, help="trained runs per RL config to check (committed: 10)")
    parser.add_argument("--results", default=str(RESULTS))
    args = parser.parse_args(argv)
    if args.rl_seeds < 0:
        parser.error(f"--rl-seeds must be >= 0, got {args.rl_seeds}")
    results = pathlib.Path(args.results)
    raw = results / "raw"

    def progress(items, desc):
        return tqdm(items, desc=desc, unit="item", leave=False)

    paper, curves, traces = paper_floor(raw, args.rl_seeds, progress)
    drift, drift_rms = drift_floor(raw, args.rl_seeds, progress)
    paper["gain_sweep"] = gain_sweep(progress)
    summary_path = results / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else None
    (results / "settle_floor.json").write_text(json.dumps({"paper": paper, "drift": drift}, indent=2) + "\n")
    (results / "figures").mkdir(parents=True, exist_ok=True)
    plot(paper, curves, traces, drift, drift_rms, summary, results / "figures" / "settle_floor.png")
    print(f"[settle_floor] paper: bound {paper['bound_settle_s']:.3f} s, slew_ramp noise-free "
          f"{paper['slew_ramp_noise_free_settle_s']:.3f} s; drift: RMS bound IQM {drift['rms_bound']['iqm']:.2f} A/m "
          f"-> {results / 'settle_floor.json'}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
