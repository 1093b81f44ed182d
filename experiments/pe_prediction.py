"""Which persistent-excitation test predicts that the estimate settles?

    python -m experiments.pe_prediction [--episodes N] [--json FILE] [--markdown FILE] [--figure FILE]
                                        [--scenarios paper,drift] [--rl-seeds N] [--agents A,B,...]

Every benchmark agent of the scalar-plant scenarios (``paper``, ``drift``) is played on the
held-out draws: the paper's ramp, the classical schedules at their untuned first grid point,
the tuned schedules, the designs, the greedy information input, the estimators as agents on
``Estimation-v0`` and every committed RL checkpoint. :func:`play` runs the benchmark's native
vector env with the benchmark's seeds and deterministic actions, like
:func:`baselines.evaluation.run_episodes`, so the settle times are the benchmark's; it also
keeps the plant's own M and the environment's integrand of (22). Each field trace is replayed
through the estimation layer's model bank
(:func:`hyst_gym.estimation.integral_condition.bank_trace`; the replayed integrand is checked
against the environment's, ``check_integrand_vs_environment`` in the JSON), and on the
recorded ``(bank, thetahat, a)`` the tests of :mod:`hyst_gym.estimation.integral_condition`
are run over moving windows ``[t1, t1 + T0]``:

* ``22_beta``: Theorem 1's condition (22), ``integral beta*nu*(f(u, thetahat(t2)) - f(u, a))
  >= 2*eps + eps0*|theta_tilde(t2)|`` on some subinterval of length delta0, eps0 sized by
  :func:`~hyst_gym.estimation.integral_condition.required_eps0`;
* ``22_beta_plant``: the same with the plant's own M in place of ``f(u, a)`` (they differ
  when a drifts: the bank's model at a(t) has had a(t) all along, the material has not);
* ``22_no_beta``: the integral without beta; ``22_magnitude``: its absolute value (the
  sign requirement dropped);
* ``31a``, ``31b_beta``, ``31b_raw``: the sign tests 3.1(a) and both readings of 3.1(b)
  (the integrand's sign with beta, and without it); ``31a`` and ``31b_beta`` are the
  benchmark's windowed :class:`~hyst_gym.estimation.PEMonitor` test on full windows;
* ``22_beta_truth_free``: (22) with the bank's envelope of the candidates
  ``thetahat -/+ band`` in place of a, both sides (what an agent can compute), and
  ``22_beta_observed_side``: only the side the observed tuning error points to.

An episode's score for a test is the fraction of its windows that meet it; for the
truth-based (22) tests also over the windows that start while the estimate is still outside
the settle band (``..._unsettled``: they read only the present error, never the future).
Each score is scored against the benchmark's outcome, settled within the episode or not, as
a ROC AUC with a 95 % bootstrap CI that resamples whole agent runs (the episodes of one input
are not independent), and against the censored settle time as Harrell's concordance.

Writes ``experiments/results/pe_prediction.json``, the table
``experiments/results/pe_prediction.md`` and ``docs/figures/pe_prediction.png`` (ROC curves).
The lumped scenario is left out: the paper states (22) for the scalar plant only.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results"
RAW = RESULTS / "raw"
DEFAULT_JSON = RESULTS / "pe_prediction.json"
DEFAULT_MARKDOWN = RESULTS / "pe_prediction.md"
DEFAULT_FIGURE = ROOT / "docs" / "figures" / "pe_prediction.png"

SCENARIO_NAMES = ("paper", "drift")
#: window T0 of Theorem 1 (s): the benchmark's PE window (baselines.evaluation.PE_WINDOW_S)
WINDOW_S = 1.0
#: subinterval delta0 of (22), s
DELTA_S = 0.5
#: eps0 of (22) (units of y per A/m) is sized per episode by
#: :func:`~hyst_gym.estimation.integral_condition.required_eps0`: the sensitivity the
#: linearized estimator needs to settle from its initial error within the episode (truth-free
#: tests: from the farthest a in Theta). The JSON also holds a sweep of fixed values, 0 being
#: "(22) holds for some eps0 > 0" (the theorem's eps0 may be arbitrarily small).
EPS0_SWEEP = (0.0, 0.5, 1.0, 2.0, 4.0)
BAND_FRACTION = 1e-3
BOOTSTRAP = 1000
#: ROC points kept per curve in the JSON (evenly thinned, ends kept)
ROC_POINTS = 200
SEED = 0

TESTS = {
    "22_beta": "(22) with beta, all windows",
    "22_beta_unsettled": "(22) with beta, windows while outside the band",
    "22_beta_plant": "(22) with beta, the plant's own M in place of f(u, a), all windows",
    "22_beta_plant_unsettled": "(22) with beta, the plant's own M, windows while outside the band",
    "22_no_beta": "(22) without beta, all windows",
    "22_no_beta_unsettled": "(22) without beta, windows while outside the band",
    "22_magnitude": "(22) on abs(integral) (sign dropped), all windows",
    "22_magnitude_unsettled": "(22) on abs(integral), windows while outside the band",
    "31a": "3.1(a): integrand sign reverses, beta fixed (the benchmark's windowed test)",
    "31b_beta": "3.1(b), integrand with beta: beta reverses, sign of beta*integrand fixed (the benchmark's)",
    "31b_raw": "3.1(b), integrand without beta: beta reverses, sign of integrand fixed",
    "22_beta_truth_free": "(22) with beta, truth-free: bank envelope thetahat -/+ band, both sides",
    "22_beta_observed_side": "(22) with beta, truth-free: the envelope side picked by the observed tuning error",
}
#: tests that need no truth (the others read a or the plant's M)
TRUTH_FREE = ("22_beta_truth_free", "22_beta_observed_side")


def fail(message: str):
    print(f"pe_prediction: error: {message}", file=sys.stderr)
    raise SystemExit(2)


# ---------------------------------------------------------------------------------------- agents


def agent_runs(scenario_name: str, raw: pathlib.Path, rl_seeds: int):
    """(label, kind, env_id, factory) of every agent played in the scenario."""
    from baselines.agents import ScheduleAgent
    from baselines.registry import DESIGN_AGENTS, ESTIMATOR_AGENTS, SCHEDULE_AGENTS, default_schedule_params, make_agent
    from baselines.scenarios import ESTIMATION_ID, EXCITATION_ID, SCENARIOS
    from baselines.schedules import make_schedule
    from experiments.config import RL_CONFIGS

    scenario = SCENARIOS[scenario_name]
    runs = [("ramp", "paper_ramp", EXCITATION_ID, lambda: make_agent("ramp", scenario, raw))]
    for name in SCHEDULE_AGENTS[1:]:
        if not name.endswith("_tuned"):
            def untuned(name=name):
                schedule = make_schedule(name, **default_schedule_params(name))
                return ScheduleAgent(schedule, scenario.limits, scenario.episode_steps, name=f"{name}_untuned")
            runs.append((f"{name}_untuned", "classical", EXCITATION_ID, untuned))
        runs.append((name, "tuned", EXCITATION_ID, lambda name=name: make_agent(name, scenario, raw)))
    runs += [(name, "design", EXCITATION_ID, lambda name=name: make_agent(name, scenario, raw))
             for name in DESIGN_AGENTS]
    runs.append(("greedy_info", "feedback", EXCITATION_ID, lambda: make_agent("greedy_info", scenario, raw)))
    runs += [(name, "estimator", ESTIMATION_ID, lambda name=name: make_agent(name, scenario, raw))
             for name in ESTIMATOR_AGENTS]
    for config in sorted(RL_CONFIGS):
        for seed in range(rl_seeds):
            path = raw / "train" / scenario_name / config / f"seed{seed}"
            if (path / "model.zip").exists():
                runs.append((f"{config}/seed{seed}", "rl", EXCITATION_ID,
                             lambda path=path: make_agent(str(path), scenario)))
    return runs


# ---------------------------------------------------------------------------------------- scores


def episode_scores(config, trace, dt: float, episode_s: float, eps0_sweep=EPS0_SWEEP):
    """Every test's score for one episode (fractions of windows in [0, 1]), the eps0 sweep, the
    eps0 used and the largest gap between the replayed integrand of (22) and the environment's."""
    from hyst_gym.estimation import integral_condition as ic

    grid = config.theta_grid
    gain = config.plant.gain
    bank = trace["bank"] if "bank" in trace else ic.bank_trace(config, trace["field"])
    theta_hat, a_true = trace["a_estimate"], trace["a_true"]
    delta = max(1, int(round(DELTA_S / dt)))
    span = max(0, int(round(WINDOW_S / dt)) - delta)
    frozen = ic.frozen_estimate(grid, bank, theta_hat, delta)
    parts = ic.frozen_integrals(grid, bank, theta_hat, a_true, dt, delta, gain, frozen=frozen)
    plant = ic.frozen_integrals(grid, bank, theta_hat, a_true, dt, delta, gain,
                                reference_values=trace["magnetization"], frozen=frozen)
    band = BAND_FRACTION * np.abs(a_true)
    starts = parts["error"].size - span
    outside = parts["error"][:starts] > band[:starts]
    lam, gamma = config.plant.decay_rate, config.gamma
    eps0 = ic.required_eps0(abs(config.initial_estimate - a_true[0]), band[0], episode_s, delta * dt, lam, gamma, gain)

    def fractions(name, integral, eps0=eps0):
        window = ic.exists_in_window(ic.margin(integral, parts["error"], config.eps, eps0), span) >= 0.0
        return {name: float(window.mean()),
                f"{name}_unsettled": float(window[outside].mean()) if outside.any() else 1.0}

    scores = {}
    scores.update(fractions("22_beta", parts["with_beta"]))
    scores.update(fractions("22_beta_plant", plant["with_beta"]))
    scores.update(fractions("22_no_beta", parts["without_beta"]))
    scores.update(fractions("22_magnitude", np.abs(parts["without_beta"])))
    f_hat, slope, curvature = ic.interpolate(grid, bank, theta_hat)
    f_true, _, _ = ic.interpolate(grid, bank, a_true)
    beta = ic.curvature_sign(curvature)
    signs = ic.sign_conditions(gain * (f_hat - f_true), beta, delta + span)
    scores.update({f"31{key}": float(value.mean()) for key, value in signs.items()})
    # truth-free: candidates at the band's distance; eps0 for the farthest a in Theta
    radius = float(BAND_FRACTION * config.initial_estimate)
    far = max(config.initial_estimate - config.theta_min, config.theta_max - config.initial_estimate)
    eps0_free = ic.required_eps0(far, radius, episode_s, delta * dt, lam, gamma, gain)
    margins = ic.candidate_margins(grid, bank, theta_hat, radius, dt, delta, config.eps, eps0_free, gain,
                                   frozen=frozen)
    both = ic.truth_free_condition(grid, bank, theta_hat, radius, dt, delta, span, config.eps, eps0_free, gain,
                                   margins=margins)
    scores["22_beta_truth_free"] = float(np.mean(both >= 0.0))
    if np.any(trace["tuning_sign"] != 0):
        # sign(ytilde) = sign(f(thetahat) - f(a)); with df/dtheta it says on which side a lies
        side = (-trace["tuning_sign"] * np.sign(slope))[:starts + span]
        observed = ic.truth_free_condition(grid, bank, theta_hat, radius, dt, delta, span, config.eps, eps0_free,
                                           gain, side=side, margins=margins)
        scores["22_beta_observed_side"] = float(np.mean(observed >= 0.0))
    else:  # Estimation-v0: the estimator (and its tuning error) is the agent's own
        scores["22_beta_observed_side"] = scores["22_beta_truth_free"]
    sweep = {f"{value:g}": fractions("22_beta", parts["with_beta"], value)["22_beta"] for value in eps0_sweep}
    # Excitation-v0 reports the integrand of (22) at the running estimate; Estimation-v0 at the
    # agent's estimate too (its bank evaluates the action): both must match the replay
    check = float(np.max(np.abs(beta * gain * (f_hat - f_true) - trace["pe_integrand"])))
    return scores, sweep, eps0, check


def concordance(scores, times, observed) -> float:
    """Harrell's C of ``scores`` (higher = faster settling) against censored settle times.

    A pair is usable when the episode with the shorter time settled; it is concordant when
    that episode has the higher score (ties in score count 1/2)."""
    scores = np.asarray(scores, dtype=np.float64)
    times = np.asarray(times, dtype=np.float64)
    observed = np.asarray(observed, dtype=bool)
    usable = concordant = 0.0
    for i in np.flatnonzero(observed):
        later = times > times[i]
        usable += later.sum()
        concordant += np.sum(later & (scores[i] > scores)) + 0.5 * np.sum(later & (scores[i] == scores))
    return float(concordant / usable) if usable else float("nan")


# ---------------------------------------------------------------------------------------- main


def play(agent, spec, seeds, tuning_column):
    """Play ``agent`` on one episode per seed with the benchmark's own episode loop
    (:func:`baselines.evaluation.play_batch`: same env, same seeds, deterministic actions),
    keeping per step what the tests need besides the benchmark's fields: the plant's own M and
    the sign of the observed tuning error."""
    from baselines.evaluation import play_batch
    from baselines.survival import settle_time

    n = len(seeds)

    def extra(observations, infos):
        return {"magnetization": np.asarray(infos["magnetization"], dtype=np.float64).reshape(n),
                "tuning_sign": (np.sign(np.asarray(observations, dtype=np.float64)[:, tuning_column])
                                if tuning_column is not None else np.zeros(n))}

    columns, lengths = play_batch(agent, spec, seeds, extra)
    episodes = []
    for i, seed in enumerate(seeds):
        trace = {key: column[:lengths[i], i] for key, column in columns.items()}
        trace["seed"] = int(seed)
        trace["settle_time_s"] = settle_time(trace["time"], trace["a_estimate"], trace["a_true"], BAND_FRACTION)
        episodes.append(trace)
    return episodes


def parse(argv):
    parser = argparse.ArgumentParser(prog="python -m experiments.pe_prediction", description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", default="50", help="held-out draws per agent run (1-50, default 50)")
    parser.add_argument("--json", default=str(DEFAULT_JSON), help="results file (JSON)")
    parser.add_argument("--markdown", default=str(DEFAULT_MARKDOWN), help="table (markdown)")
    parser.add_argument("--figure", default=str(DEFAULT_FIGURE), help="ROC figure (PNG)")
    parser.add_argument("--scenarios", default=",".join(SCENARIO_NAMES), help="comma list of paper, drift")
    parser.add_argument("--rl-seeds", default="10", help="RL training seeds per config (0-10, default 10)")
    parser.add_argument("--agents", default="", help="comma list of agent labels or kinds to keep (default all)")
    parser.add_argument("--bootstrap", default=str(BOOTSTRAP), help="bootstrap resamples (>= 10)")
    args = parser.parse_args(argv)
    for name, low, high in (("episodes", 1, 50), ("rl_seeds", 0, 10), ("bootstrap", 10, 100000)):
        value = getattr(args, name)
        try:
            number = int(value)
        except ValueError:
            fail(f"--{name.replace('_', '-')} must be an integer, got {value!r}")
        if not low <= number <= high:
            fail(f"--{name.replace('_', '-')} must lie in [{low}, {high}], got {number}")
        setattr(args, name, number)
    args.scenarios = [s for s in args.scenarios.split(",") if s]
    bad = [s for s in args.scenarios if s not in SCENARIO_NAMES]
    if bad or not args.scenarios:
        fail(f"--scenarios must be a comma list of {', '.join(SCENARIO_NAMES)}, got {bad or args.scenarios}")
    args.agents = [a for a in args.agents.split(",") if a]
    return args


def collect(args, progress):
    """Play every agent run; returns the per-episode rows and the integrand check."""
    from baselines.observation import observation_index
    from baselines.scenarios import EXCITATION_ID, HELDOUT_SEEDS, SCENARIOS
    from hyst_gym.envs.config import EnvConfig
    from hyst_gym.envs.core import estimator_config
    from hyst_gym.estimation import integral_condition as ic

    try:
        import torch
        torch.set_num_threads(1)  # single core; many threads on a shared machine run 10x slower
    except ImportError:
        pass
    plan = []
    for scenario_name in args.scenarios:
        for run in agent_runs(scenario_name, RAW, args.rl_seeds):
            label, kind = run[0], run[1]
            if args.agents and label not in args.agents and kind not in args.agents \
                    and label.split("/")[0] not in args.agents:
                continue
            plan.append((scenario_name, *run))
    if not plan:
        fail(f"no agent matches --agents {','.join(args.agents)}")
    seeds = HELDOUT_SEEDS[:args.episodes]
    rows, sweeps, env_check = [], [], []
    for scenario_name, label, kind, env_id, factory in progress(plan):
        scenario = SCENARIOS[scenario_name]
        config = estimator_config(EnvConfig(**scenario.settings))
        try:
            agent = factory()
        except (OSError, ImportError) as error:
            print(f"pe_prediction: skipped {scenario_name}/{label}: {error}", file=sys.stderr)
            continue
        column = observation_index(scenario, "tuning_error") if env_id == EXCITATION_ID else None
        traces = play(agent, scenario.spec(env_id), seeds, column)
        if len({trace["field"].size for trace in traces}) == 1:  # one bank replay for the whole batch
            banks = ic.bank_trace(config, np.stack([trace["field"] for trace in traces]))
            for trace, bank in zip(traces, banks):
                trace["bank"] = bank
        for trace in traces:
            scores, sweep, eps0, check = episode_scores(config, trace, scenario.limits.dt, scenario.episode_s)
            rows.append({"scenario": scenario_name, "agent": label, "kind": kind, "seed": trace["seed"],
                         "settle_time_s": trace["settle_time_s"], "episode_s": scenario.episode_s,
                         "settled": bool(np.isfinite(trace["settle_time_s"])), "eps0": eps0, "scores": scores})
            sweeps.append(sweep)
            env_check.append(check)
    return rows, sweeps, env_check


def evaluate(rows, sweeps, n_boot: int):
    from hyst_gym.estimation import integral_condition as ic

    groups = {"all": list(range(len(rows)))}
    for scenario in sorted({r["scenario"] for r in rows}):
        groups[scenario] = [i for i, r in enumerate(rows) if r["scenario"] == scenario]
    out = {}
    for group, index in groups.items():
        members = [rows[i] for i in index]
        labels = np.array([r["settled"] for r in members])
        clusters = np.array([f"{r['scenario']}/{r['agent']}" for r in members])
        times = np.array([r["settle_time_s"] if r["settled"] else r["episode_s"] for r in members])
        entry = {"episodes": len(members), "settled": int(labels.sum()), "agent_runs": int(np.unique(clusters).size),
                 "tests": {}}
        for test in TESTS:
            scores = np.array([r["scores"][test] for r in members])
            auc = ic.roc_auc(scores, labels)
            lo, hi = ic.bootstrap_auc(scores, labels, clusters, n_boot, SEED) if np.isfinite(auc) else (np.nan,) * 2
            fpr, tpr = ic.roc_curve(scores, labels)
            keep = np.unique(np.linspace(0, fpr.size - 1, min(fpr.size, ROC_POINTS)).round().astype(int))
            entry["tests"][test] = {"auc": auc, "ci": [lo, hi], "c_index": concordance(scores, times, labels),
                                    "roc": {"fpr": fpr[keep].round(4).tolist(), "tpr": tpr[keep].round(4).tolist()}}
        entry["eps0_sweep_22_beta"] = {
            key: ic.roc_auc(np.array([sweeps[i][key] for i in index]), labels) for key in sweeps[0]}
        out[group] = entry
    return out


def best_test(evaluation) -> str:
    """The test with the highest pooled AUC (every test here is taken from the paper's theory)."""
    return max(TESTS, key=lambda t: np.nan_to_num(evaluation["all"]["tests"][t]["auc"], nan=-1.0))


def per_agent(rows, test: str, threshold: float):
    table = {}
    for r in rows:
        key = (r["scenario"], r["agent"].split("/")[0])
        entry = table.setdefault(key, {"kind": r["kind"], "episodes": 0, "settled": 0, "scores": []})
        entry["episodes"] += 1
        entry["settled"] += r["settled"]
        entry["scores"].append(r["scores"][test])
    out = []
    for (scenario, agent), entry in sorted(table.items()):
        scores = np.array(entry["scores"])
        out.append({"scenario": scenario, "agent": agent, "kind": entry["kind"], "episodes": entry["episodes"],
                    "settled_fraction": entry["settled"] / entry["episodes"],
                    "median_score": float(np.median(scores)),
                    "satisfied_fraction": float(np.mean(scores >= threshold))})
    return out


def youden_threshold(rows, test: str) -> float:
    """Score threshold maximizing TPR - FPR over all episodes (the operating point reported)."""
    scores = np.array([r["scores"][test] for r in rows])
    labels = np.array([r["settled"] for r in rows])
    best, best_j = 1.0, -np.inf
    for t in np.unique(scores):
        j = np.mean(scores[labels] >= t) - np.mean(scores[~labels] >= t) if (~labels).any() and labels.any() else 0
        if j > best_j:
            best, best_j = float(t), j
    return best


def columns(rows) -> dict:
    """The per-episode raw results as columns (scores rounded to 1e-4), for the JSON."""
    out = {key: [r[key] for r in rows] for key in ("scenario", "agent", "kind", "seed", "settled")}
    out["settle_time_s"] = [None if not r["settled"] else round(r["settle_time_s"], 4) for r in rows]
    out["eps0"] = [round(r["eps0"], 4) for r in rows]
    out["scores"] = {test: [round(r["scores"][test], 4) for r in rows] for test in TESTS}
    return out


def markdown(result) -> str:
    evaluation = result["evaluation"]
    groups = [g for g in ("all", "paper", "drift") if g in evaluation]
    lines = ["| test | " + " | ".join(f"AUC {g} [95 % CI]" for g in groups) + " | C-index all |",
             "|---|" + "---|" * (len(groups) + 1)]
    for test, description in TESTS.items():
        cells = []
        for g in groups:
            t = evaluation[g]["tests"][test]
            cells.append(f"{t['auc']:.2f} [{t['ci'][0]:.2f}, {t['ci'][1]:.2f}]" if np.isfinite(t["auc"]) else "n/a")
        lines.append(f"| `{test}`: {description} | " + " | ".join(cells)
                     + f" | {evaluation['all']['tests'][test]['c_index']:.2f} |")
    counts = ", ".join(f"{g}: {evaluation[g]['episodes']} episodes of {evaluation[g]['agent_runs']} agent runs, "
                       f"{evaluation[g]['settled']} settled" for g in groups)
    best = result["best_test"]
    eps0 = np.array(result["episodes"]["eps0"])
    lines += ["", f"Episodes: {counts}. Windows T0 = {WINDOW_S:g} s, delta0 = {DELTA_S:g} s, eps0 sized per episode "
              f"(median {np.median(eps0):.2f}, range {eps0.min():.2f}-{eps0.max():.2f} s); "
              f"CIs resample whole agent runs ({result['bootstrap']} resamples).", "",
              f"Best test from the theory (pooled AUC): `{best}`; operating point: score >= "
              f"{result['threshold']:.3f} (Youden). Per input (held-out episodes):", "",
              "| scenario | input | kind | settled | median score | meets the test |", "|---|---|---|---|---|---|"]
    for entry in result["per_agent"]:
        lines.append(f"| {entry['scenario']} | {entry['agent']} | {entry['kind']} | "
                     f"{100 * entry['settled_fraction']:.0f} % | {entry['median_score']:.2f} | "
                     f"{100 * entry['satisfied_fraction']:.0f} % |")
    sweep = evaluation["all"]["eps0_sweep_22_beta"]
    lines += ["", "eps0 sweep (one fixed eps0 for every episode), `22_beta`, pooled AUC: "
              + ", ".join(f"eps0 = {k}: {v:.2f}" for k, v in sweep.items()) + ".",
              f"Wall time: {result['wall_s']:.0f} s."]
    return "\n".join(lines) + "\n"


def figure(result, path: pathlib.Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    evaluation = result["evaluation"]
    groups = [g for g in ("all", "paper", "drift") if g in evaluation]
    fig, axes = plt.subplots(1, len(groups), figsize=(5 * len(groups), 4.6), squeeze=False)
    shown = ("22_beta", "22_beta_plant", "22_no_beta", "22_magnitude", "31a", "31b_beta", "31b_raw",
             "22_beta_truth_free", "22_beta_observed_side")
    for ax, group in zip(axes[0], groups):
        for test in shown:
            entry = evaluation[group]["tests"][test]
            if np.isfinite(entry["auc"]):
                # straight segments: a tie between classes is a diagonal (its area counts 1/2)
                ax.plot(entry["roc"]["fpr"], entry["roc"]["tpr"], lw=1.2, label=f"{test} ({entry['auc']:.2f})")
        ax.plot([0, 1], [0, 1], color="0.7", lw=0.8, ls="--")
        ax.set(title=f"{group}: {evaluation[group]['episodes']} episodes", xlabel="false positive rate",
               ylabel="true positive rate (settles)", xlim=(0, 1), ylim=(0, 1.01))
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle("Does a PE test predict that the min-max estimate settles? ROC over held-out episodes")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    args = parse(sys.argv[1:] if argv is None else argv)
    from tqdm import tqdm

    start = time.perf_counter()

    def progress(items):
        return tqdm(items, desc="agent runs", unit="run", file=sys.stderr)

    rows, sweeps, env_check = collect(args, progress)
    if not rows:
        fail("no episodes were played (every agent was skipped)")
    evaluation = evaluate(rows, sweeps, args.bootstrap)
    best = best_test(evaluation)
    threshold = youden_threshold(rows, best)
    result = {"settings": {"episodes": args.episodes, "scenarios": args.scenarios, "rl_seeds": args.rl_seeds,
                           "window_s": WINDOW_S, "delta_s": DELTA_S, "eps0": "required_eps0 per episode",
                           "band_fraction": BAND_FRACTION,
                           "seed": SEED},
              "tests": TESTS, "truth_free_tests": list(TRUTH_FREE), "bootstrap": args.bootstrap,
              "evaluation": evaluation, "best_test": best, "threshold": threshold,
              "per_agent": per_agent(rows, best, threshold),
              "check_integrand_vs_environment": {"max_abs_difference": float(np.max(env_check)),
                                                 "units": "A/m (nu = 1)"},
              "episodes": columns(rows)}
    result["wall_s"] = time.perf_counter() - start
    for path in (args.json, args.markdown, args.figure):
        pathlib.Path(path).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(args.json).write_text(json.dumps(result, separators=(",", ":"), allow_nan=True))
    pathlib.Path(args.markdown).write_text(markdown(result))
    figure(result, pathlib.Path(args.figure))
    print(markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
