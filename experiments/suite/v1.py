"""Benchmark suite v1: tasks with headroom, floors, baselines and RL, one command.

    hyst-gym benchmark --suite v1 [--quick] [--tasks ID,ID] [--out DIR] [--no-readme]
    python -m experiments.suite --suite v1 [same options]

The tasks are the presets of :mod:`hyst_gym.envs.suite_v1` (registered ids ``hyst_gym/*-v1``): a
milling actuator's coil that heats while it excites, with a temperature limit. Every agent
plays the task's native vector env on the same draws (one sub-env per draw, the benchmark's
seeds: tuning :data:`~baselines.scenarios.TUNING_SEEDS`, held-out
:data:`~baselines.scenarios.HELDOUT_SEEDS`), deterministic actions.

Metric (per episode, lower is better): the mean of |a_estimate - a_true| over the task's
whole horizon, A/m, with width(Theta) for each step after the coil passed its temperature
limit (the episode ends there; the env's reward charges the same).

Agents (kind in the JSON):

* ``open_loop``: the paper's ramp (1e5 A/m in 6 s, untuned); the best of the design family
  below tuned on the tuning draws (``tuned_open_loop``: biased sines ``H0 + A sin(2 pi f t)``
  and slew-limited ramps to a held peak); ``optimal_design_prior`` (the Fisher-information
  multisine of :mod:`baselines.optimal_design`, averaged over the task's prior of a, which
  ignores heating); ``direct_design`` (CMA-ES over a 9-knot piecewise-linear field on the task
  metric of the tuning draws, :mod:`baselines.direct_design`);
* ``estimator``: the other estimators of the estimation layer (``gradient``,
  ``multiple_model``) as the env's built-in estimator, under the tuned open-loop input. The
  tasks benchmark the *input* for the env's min-max estimator (14)-(16); swapping the
  estimator changes the task, so these rows are context and not candidates for the
  reference (the multiple-model estimator, which picks the bank's best node, tracks a far
  better on these tasks whatever the input: see the JSON);
* ``feedback``: ``thermostat``, the tuned biased sine switched off while the temperature
  read from the estimate (a is proportional to T) is within a margin of the limit, and
  ``proportional``, a +-80 kA/m sine scaled by the thermal budget read from the estimate, and
  ``identify_then_idle``, a sine that idles once the estimator's tuning error (observed) says a
  is identified (:class:`baselines.suite_agents.DesignBank`), each tuned on the tuning draws;
* ``rl``: PPO and SAC (:mod:`baselines.train`, dense env reward, 8 stacked frames), 10 seeds
  in the full profile, scored per seed on the held-out draws.

Floor (kind ``oracle``): per held-out draw, the best design of the whole family (open-loop
designs, the feedback rules, and their clairvoyant versions that read the *true* temperature and
the *true* estimation error)
given the truth of that draw: the design is chosen on a replicate of the draw with the same
initial temperature and ambient drift and independent measurement noise (so the choice uses
the plant's truth, not the noise's luck), then scored on the draw itself.

Headroom: ``IQM(best no-feedback baseline) / IQM(oracle) - 1`` (the reference: the best
``open_loop`` agent by held-out IQM) with a 95 % stratified-
bootstrap CI over the held-out draws (both statistics recomputed on each resample). A task
enters the suite only if the CI lies above 25 %.

Normalized score of an agent: ``(reference - agent) / (reference - floor)``, reference =
the best no-feedback baseline's IQM (1 = the oracle, 0 = the reference), with the agent's
runs (seeds) and the draws resampled together (stratified bootstrap).

Writes ``experiments/results/suite_v1.json`` (``suite_v1_quick.json`` for ``--quick``),
``suite_v1.md``, ``docs/figures/suite_v1.png`` and the section ``suite-v1`` of the documentation
page ``docs/results/suite.md`` (full profile only).
"""

from __future__ import annotations

import json
import pathlib
import time
from dataclasses import dataclass

import numpy as np

from experiments.suite import common
from experiments.suite.common import HEADROOM_TARGET, RESULTS, matrix as _matrix
from experiments.suite.kinds import task_kind

RAW = RESULTS / "raw" / "suite_v1"
README = common.DOCS_PAGE
README_AREA = "suite-v1"
#: wall seconds per timed case of the env speed measurement (hyst_gym.envs.step_speed)
SPEED_BUDGET_S = 1.0
RL_TARGET = 0.5


@dataclass(frozen=True)
class Profile:
    """How much of everything a run does."""

    name: str
    heldout: int        # held-out draws per agent (<= 50)
    tuning: int         # tuning draws (<= 10)
    cma_evaluations: int
    fisher_evaluations: int
    rl_seeds: int
    rl_steps: dict      # algo -> env steps per seed
    bootstrap: int
    train: bool         # train missing RL models (False: evaluate the committed ones)
    curves: bool = True  # score the saved checkpoints for learning curves


PROFILES = {
    "full": Profile("full", 50, 10, 240, 200, 10, {"ppo": 100_000, "sac": 6_000}, 2000, True),
    "quick": Profile("quick", 16, 6, 40, 40, 10, {"ppo": 100_000, "sac": 6_000}, 300, False, False),
}


# ---------------------------------------------------------------------------- RL

RL_ALGORITHMS = ("ppo", "sac")
#: checkpoints saved per training run, evenly spaced (the learning curves are scored on them)
CURVE_POINTS = 5


def task_slug(task_id: str) -> str:
    return task_id.split("/")[-1]


def model_dir(task_id: str, algo: str, seed: int, raw: pathlib.Path = RAW) -> pathlib.Path:
    return raw / "train" / task_slug(task_id) / algo / f"seed{seed}"


def train_rl(task_id: str, algo: str, seed: int, steps: int, raw: pathlib.Path = RAW) -> pathlib.Path:
    """Train one seed (dense env reward, 8 envs, 8 stacked frames, baselines.train defaults),
    unless a model of at least ``steps`` steps is already there (then None)."""
    from baselines.environment import EpisodeSpec
    from baselines.train import train

    out = model_dir(task_id, algo, seed, raw)
    config_path = out / "config.json"
    if (out / "model.zip").exists() and config_path.exists():
        if json.loads(config_path.read_text()).get("trained_steps", 0) >= steps:
            return None
    spec = EpisodeSpec(task_id, {}, 0.05)
    train(algo, spec, int(steps), int(seed), out, n_envs=8, checkpoint_every=int(steps) // CURVE_POINTS, progress=False,
          scenario=task_slug(task_id))
    return out


def train_all(task_ids, profile: Profile, raw: pathlib.Path = RAW):
    """Every seed of every algorithm on every task, seed-major (a run cut short has as many seeds
    of both algorithms on every task)."""
    for seed in range(profile.rl_seeds):
        for task_id in task_ids:
            for algo in RL_ALGORITHMS:
                start = time.time()
                if train_rl(task_id, algo, seed, profile.rl_steps[algo], raw) is not None:
                    print(f"[suite] trained {task_slug(task_id)} {algo} seed {seed} in {time.time() - start:.0f} s",
                          flush=True)


def rl_agents(task_id: str, algo: str, seeds: int, raw: pathlib.Path = RAW):
    """The trained models of ``algo`` on ``task_id`` found for seeds 0..seeds-1, as (seed, folder)."""
    found = []
    for seed in range(seeds):
        folder = model_dir(task_id, algo, seed, raw)
        if (folder / "model.zip").exists():
            found.append((seed, folder))
    return found


def learning_curve(task_id: str, algo: str, seeds, draws, raw: pathlib.Path = RAW) -> list:
    """IQM of the task metric over the given draws, per saved checkpoint (env steps), across seeds."""
    from baselines.rl import PolicyAgent, algorithm_class
    from baselines.stats import iqm

    by_steps = {}
    for _seed, folder in seeds:
        n_stack = json.loads((folder / "config.json").read_text()).get("n_stack", 1)
        cls = algorithm_class(algo)
        paths = sorted((folder / "checkpoints").glob("model_*_steps.zip"), key=lambda p: int(p.stem.split("_")[1]))
        keep = sorted(set(np.linspace(0, len(paths) - 1, min(CURVE_POINTS, len(paths))).round().astype(int)))
        for path in [paths[i] for i in keep] if paths else []:
            steps = int(path.stem.split("_")[1])
            model = cls.load(path, device="cpu")
            metric, _, _ = common.play(PolicyAgent(model, n_stack), task_kind(task_id), draws)
            by_steps.setdefault(steps, []).append(metric)
    return [{"env_steps": steps, "iqm": iqm(np.array(rows)), "seeds": len(rows)}
            for steps, rows in sorted(by_steps.items())]


# ---------------------------------------------------------------------------- baselines


def evaluate_task(task_id: str, profile: Profile, raw: pathlib.Path = RAW, log=print) -> dict:
    """Every agent's per-draw metric on the held-out draws, the oracle, and the tuning choices."""
    from baselines.rl import PolicyAgent
    from baselines.scenarios import HELDOUT_SEEDS, TUNING_SEEDS, VALIDATION_SEEDS
    from baselines.schedules import Ramp
    from baselines.stats import iqm
    from baselines.suite_agents import Design

    start = time.time()
    task = task_kind(task_id)
    config = task.config
    tuning, heldout = TUNING_SEEDS[:profile.tuning], HELDOUT_SEEDS[:profile.heldout]
    family = task.family()
    tune_scores, _ = common.family_scores(task, family, tuning)
    held_scores, draws = common.family_scores(task, family, heldout)
    oracle, choice = common.oracle_scores(task, family, held_scores, draws, heldout)
    tuned_iqm = np.array([iqm(row) for row in tune_scores])
    best_open = common.pick_tuned(family, tuned_iqm, "open_loop")
    picks = {name: common.pick_tuned(family, tuned_iqm, "feedback", prefix) for name, prefix in task.feedback_picks}
    agents = {"ramp": ("open_loop", common.play(task.design_agent([Design("ramp", Ramp())]), task, heldout)[0]),
              "tuned_open_loop": ("open_loop", held_scores[best_open])}
    agents.update({name: ("feedback", held_scores[index]) for name, index in picks.items()})
    log(f"[suite] {task.spec.slug}: family of {len(family)} tuned and played ({time.time() - start:.0f} s)")
    fisher = Design("optimal_design_prior", common.fisher_design(config, profile.fisher_evaluations))
    agents["optimal_design_prior"] = ("open_loop", common.play(task.design_agent([fisher]), task, heldout)[0])
    direct = Design("direct_design", common.direct_design(task, tuning, profile.cma_evaluations))
    agents["direct_design"] = ("open_loop", common.play(task.design_agent([direct]), task, heldout)[0])
    log(f"[suite] {task.spec.slug}: designs searched ({time.time() - start:.0f} s)")
    agents.update(task.context_agents(family[best_open], heldout))
    curves = {}
    for algo in RL_ALGORITHMS:
        found = rl_agents(task_id, algo, profile.rl_seeds, raw)
        if not found:
            continue
        rows = [common.play(PolicyAgent.load(folder), task, heldout)[0] for _, folder in found]
        agents[algo] = ("rl", np.array(rows))
        configs = [json.loads((folder / "config.json").read_text()) for _, folder in found]
        curves[algo] = {"seeds": [seed for seed, _ in found],
                        "steps": [config.get("trained_steps") for config in configs],
                        "train_wall_s": sum(config.get("wall_s_last_session", 0.0) for config in configs),
                        "points": (learning_curve(task_id, algo, found, VALIDATION_SEEDS[:8], raw)
                                   if profile.curves else [])}
    log(f"[suite] {task.spec.slug}: agents played ({time.time() - start:.0f} s)")
    return {"agents": agents, "oracle": oracle, "oracle_choice": [family[i].name for i in choice],
            "tuned": {"tuned_open_loop": family[best_open].name,
                      **{name: family[index].name for name, index in picks.items()},
                      "estimators_input": family[best_open].name},
            "designs": {"optimal_design_prior": list(fisher.schedule.coefficients),
                        "direct_design_knots": list(direct.schedule.knots)},
            "curves": curves, "draws": {k: v.tolist() for k, v in draws.items()},
            "wall_s": time.time() - start}


# ---------------------------------------------------------------------------- statistics


def ratio_ci(numerator, denominator, n_boot: int, seed: int = 0):
    """IQM(numerator)/IQM(denominator) - 1 over shared draws, with a stratified-bootstrap 95 % CI."""
    from baselines.stats import iqm

    num, den = _matrix(numerator), _matrix(denominator)
    rng = np.random.default_rng(seed)
    n_draws = num.shape[1]
    values = np.empty(n_boot)
    for b in range(n_boot):
        columns = rng.integers(0, n_draws, n_draws)
        rows_n = rng.integers(0, num.shape[0], (num.shape[0], n_draws))
        rows_d = rng.integers(0, den.shape[0], (den.shape[0], n_draws))
        values[b] = iqm(num[rows_n, columns]) / iqm(den[rows_d, columns]) - 1.0
    low, high = np.percentile(values, [2.5, 97.5])
    return iqm(num) / iqm(den) - 1.0, [float(low), float(high)]


def normalized_ci(agent, reference, floor, n_boot: int, seed: int = 0):
    """(IQM(reference) - IQM(agent)) / (IQM(reference) - IQM(floor)) with a stratified-bootstrap
    95 % CI: the draws are resampled jointly, the agent's runs within each drawn column."""
    from baselines.stats import iqm

    agent = _matrix(agent)
    reference, floor = np.asarray(reference, dtype=np.float64), np.asarray(floor, dtype=np.float64)

    def score(a, r, f):
        gap = iqm(r) - iqm(f)
        return (iqm(r) - iqm(a)) / gap if gap != 0 else float("nan")

    rng = np.random.default_rng(seed)
    n_runs, n_draws = agent.shape
    values = np.empty(n_boot)
    for b in range(n_boot):
        columns = rng.integers(0, n_draws, n_draws)
        rows = rng.integers(0, n_runs, (n_runs, n_draws))
        values[b] = score(agent[rows, columns], reference[columns], floor[columns])
    finite = values[np.isfinite(values)]
    low, high = np.percentile(finite, [2.5, 97.5]) if finite.size else (float("nan"), float("nan"))
    return score(agent, reference, floor), [float(low), float(high)]


def summarize_task(task_id: str, evaluated: dict, profile: Profile, accepted: bool) -> dict:
    """The JSON entry of one task (see the module docstring)."""
    from baselines.stats import iqm, stratified_bootstrap_ci
    from hyst_gym.envs.tasks import task_spec

    oracle = evaluated["oracle"]
    agents = {}
    for name, (kind, scores) in evaluated["agents"].items():
        scores = _matrix(scores)
        agents[name] = {"iqm": iqm(scores), "ci": list(stratified_bootstrap_ci(scores, n_boot=profile.bootstrap)),
                        "kind": kind, "runs": int(scores.shape[0])}
    # the task's estimator is the env's built-in min-max law: the reference is the best input
    # without feedback for it (an estimator swap is another task, reported for context)
    no_feedback = [name for name, entry in agents.items() if entry["kind"] == "open_loop"]
    reference = min(no_feedback, key=lambda name: agents[name]["iqm"])
    reference_scores = _matrix(evaluated["agents"][reference][1])[0]
    headroom, headroom_ci = ratio_ci(reference_scores, oracle, profile.bootstrap)
    for name, (_, scores) in evaluated["agents"].items():
        value, ci = normalized_ci(scores, reference_scores, oracle, profile.bootstrap)
        agents[name]["normalized"] = {"iqm": value, "ci": ci}
    beats = {name: float(np.mean(_matrix(scores).mean(axis=0) < oracle))
             for name, (_, scores) in evaluated["agents"].items()}
    spec = task_spec(task_id)
    return {
        "metric": "mean |a_estimate - a_true| over the episode, A/m (width(Theta) per step after an overheat)",
        "lower_is_better": True,
        "description": spec.description, "difficulty": spec.difficulty, "in_suite": accepted,
        "floor": {"value": iqm(oracle), "kind": "oracle",
                  "ci": list(stratified_bootstrap_ci(oracle, n_boot=profile.bootstrap)),
                  "how": "per draw, the best design of the family (open loop, the feedback rules, and their "
                         "versions that read the true temperature and error) chosen on a noise replicate of the "
                         "draw, scored on the draw",
                  "draws_where_agent_beats_oracle": beats},
        "reference": reference,
        "headroom": {"value": headroom, "ci": headroom_ci, "target": HEADROOM_TARGET,
                     "met": bool(headroom_ci[0] > HEADROOM_TARGET)},
        "agents": agents,
        "tuned": evaluated["tuned"], "designs": evaluated["designs"], "learning_curves": evaluated["curves"],
        "oracle_choice": evaluated["oracle_choice"], "draws": evaluated["draws"],
        "wall_s": evaluated["wall_s"],
    }


# ---------------------------------------------------------------------------- report

AGENT_ORDER = ("ramp", "tuned_open_loop", "optimal_design_prior", "direct_design", "gradient", "multiple_model",
               "thermostat", "proportional", "identify_then_idle", "ppo", "sac")


def solved_tier(results: pathlib.Path = RESULTS) -> list:
    """The committed scenarios as the suite's solved tier: best agent against its floor."""
    summary_path, floor_path = results / "summary.json", results / "settle_floor.json"
    if not (summary_path.exists() and floor_path.exists()):
        return []
    summary, floors = json.loads(summary_path.read_text()), json.loads(floor_path.read_text())
    rows = []
    for scenario, metric, floor in (("paper", "settle_time_s", floors["paper"]["bound_settle_s"]),
                                    ("drift", "rms_error", floors["drift"]["rms_bound"]["iqm"]),
                                    ("lumped", "settle_time_s", None)):
        agents = {name: entry[metric]["iqm"] for name, entry in summary.get(scenario, {}).items() if metric in entry}
        if not agents:
            continue
        best = min(agents, key=agents.get)
        rows.append({"scenario": scenario, "metric": metric, "floor": floor, "best_agent": best,
                     "best": agents[best], "ramp_tuned": agents.get("ramp_tuned")})
    return rows


def _cell(entry, normalized=False):
    if entry is None:
        return "—"
    text = f"{entry['iqm']:.1f} [{entry['ci'][0]:.1f}, {entry['ci'][1]:.1f}]"
    if normalized:
        norm = entry["normalized"]
        text += f"; {norm['iqm']:+.2f} [{norm['ci'][0]:+.2f}, {norm['ci'][1]:+.2f}]"
    return text


def markdown(data: dict) -> str:
    tasks = data["tasks"]
    suite = [t for t in tasks if tasks[t]["in_suite"]]
    note = "" if data["profile"] == "full" else (" The `in suite` column is measured on this profile's draws "
                                                  "only; the suite's own decision is the full profile's.")
    lines = [f"Profile `{data['profile']}`: {data['heldout_draws']} held-out draws per agent, RL "
             f"{data['rl_budget']}; wall time {data['wall_s'] / 60:.1f} min. Metric: mean |a_estimate - a_true| "
             "over the 10 s episode, A/m (width(Theta) per step after an overheat), IQM [95 % stratified-bootstrap "
             "CI]; lower is better." + note, "",
             "| task (difficulty) | floor: oracle | reference (best without feedback) | headroom [CI] | in suite "
             "| agents with an IQM below the oracle | steps/s single, n=1024 |",
             "|---|---|---|---|---|---|---|"]
    for task_id, task in sorted(tasks.items(), key=lambda item: (not item[1]["in_suite"], item[1]["difficulty"])):
        floor, head = task["floor"], task["headroom"]
        lines.append(f"| `{task_id}` ({task['difficulty'] or 'rejected'}) | {floor['value']:.1f} "
                     f"[{floor['ci'][0]:.1f}, {floor['ci'][1]:.1f}] | {task['reference']} "
                     f"{task['agents'][task['reference']]['iqm']:.1f} | {100 * head['value']:.0f} % "
                     f"[{100 * head['ci'][0]:.0f}, {100 * head['ci'][1]:.0f}] | "
                     f"{'yes' if task['in_suite'] else 'no (CI not above 25 %)'} | "
                     f"{', '.join(n for n, a in task['agents'].items() if a['iqm'] < floor['value']) or 'none'} | "
                     f"{task['steps_per_s']['single']:,.0f}, {task['steps_per_s']['1024']:,.0f} |")
    lines += ["", "Leaderboard (suite tasks): metric IQM [CI]; normalized score (reference - agent)/(reference - "
              "floor) IQM [CI] (1 = the oracle, 0 = the best input without feedback).", "",
              "| agent (kind) | " + " | ".join(f"`{t.split('/')[-1]}`" for t in suite) + " |",
              "|---|" + "---|" * len(suite)]
    names = [n for n in AGENT_ORDER if any(n in tasks[t]["agents"] for t in suite)]
    for name in names:
        kind = next(tasks[t]["agents"][name]["kind"] for t in suite if name in tasks[t]["agents"])
        cells = [_cell(tasks[t]["agents"].get(name), normalized=True) for t in suite]
        lines.append(f"| {name} ({kind}) | " + " | ".join(cells) + " |")
    rl = data.get("rl_target", {})
    if rl:
        lines += ["", f"RL target (best RL config closes >= 50 % of the gap with a CI excluding 0 on >= 2 tasks): "
                  f"met on {rl['tasks_met']} of {len(suite)} suite tasks -> {'met' if rl['met'] else 'not met'}."]
    tier = data.get("solved_tier", [])
    if tier:
        lines += ["", "Solved tier (the committed scenarios, `experiments/results/summary.json`): the best agent "
                  "against the floor of `experiments/results/settle_floor.json`.", "",
                  "| scenario | metric | floor | best agent | ramp_tuned |", "|---|---|---|---|---|"]
        for row in tier:
            floor = "—" if row["floor"] is None else f"{row['floor']:.2f}"
            ramp = "—" if row["ramp_tuned"] is None else f"{row['ramp_tuned']:.2f}"
            lines.append(f"| {row['scenario']} | {row['metric']} | {floor} | {row['best_agent']} "
                         f"{row['best']:.2f} | {ramp} |")
    return "\n".join(lines) + "\n"


def figure(data: dict, path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = sorted(data["tasks"], key=lambda t: (not data["tasks"][t]["in_suite"], data["tasks"][t]["difficulty"]))
    fig, axes = plt.subplots(2, len(shown), figsize=(4.2 * len(shown), 7.5), squeeze=False)
    for column, task_id in enumerate(shown):
        task = data["tasks"][task_id]
        ax = axes[0, column]
        names = [n for n in AGENT_ORDER if n in task["agents"]]
        values = [task["agents"][n]["iqm"] for n in names]
        errors = np.array([[task["agents"][n]["iqm"] - task["agents"][n]["ci"][0],
                            task["agents"][n]["ci"][1] - task["agents"][n]["iqm"]] for n in names]).T
        colors = {"open_loop": "tab:blue", "estimator": "tab:purple", "feedback": "tab:orange", "rl": "tab:green"}
        ax.barh(names, values, xerr=errors, color=[colors[task["agents"][n]["kind"]] for n in names])
        ax.axvline(task["floor"]["value"], color="k", ls="--", label="oracle floor")
        ax.set_xscale("log")
        ax.set_title(task_id.split("/")[-1] + ("" if task["in_suite"] else " (rejected)"), fontsize=10)
        ax.set_xlabel("mean |a error|, A/m (IQM, 95 % CI)")
        ax.invert_yaxis()
        if column == 0:
            ax.legend(fontsize=8)
        ax = axes[1, column]
        for algo, curve in task["learning_curves"].items():
            points = curve["points"]
            if points:
                ax.plot([p["env_steps"] for p in points], [p["iqm"] for p in points], "o-", label=algo)
        ax.axhline(task["floor"]["value"], color="k", ls="--", label="oracle floor")
        ax.axhline(task["agents"][task["reference"]]["iqm"], color="tab:blue", ls=":", label="reference")
        if any(curve["points"] for curve in task["learning_curves"].values()):
            ax.set_xscale("log")
        ax.set_xlabel("env steps (validation draws, IQM over seeds)")
        ax.set_ylabel("mean |a error|, A/m")
        ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def rl_target(tasks: dict) -> dict:
    per_task = {}
    for task_id, task in tasks.items():
        if not task["in_suite"]:
            continue
        rl = {name: entry["normalized"] for name, entry in task["agents"].items() if entry["kind"] == "rl"}
        if not rl:
            continue
        best = max(rl, key=lambda name: rl[name]["iqm"])
        per_task[task_id] = {"best": best, "normalized": rl[best]["iqm"], "ci": rl[best]["ci"],
                             "met": bool(rl[best]["iqm"] >= RL_TARGET and rl[best]["ci"][0] > 0)}
    met = sum(entry["met"] for entry in per_task.values())
    return {"per_task": per_task, "tasks_met": met, "met": met >= 2}


def run_suite(profile: Profile, task_ids, out: pathlib.Path, figure_path: pathlib.Path, raw: pathlib.Path = RAW,
              readme: pathlib.Path | None = None, log=print) -> dict:
    from hyst_gym.envs.suite_v1 import suite_tasks

    from hyst_gym.envs.step_speed import SUITE_TARGETS, run_suite_benchmark

    start = time.time()
    if profile.train:
        train_all([t for t in task_ids if t in suite_tasks()], profile, raw)
    speeds = run_suite_benchmark(log, SPEED_BUDGET_S, task_ids)
    tasks = {}
    for task_id in task_ids:
        evaluated = evaluate_task(task_id, profile, raw, log)
        summary = summarize_task(task_id, evaluated, profile, accepted=False)
        summary["in_suite"] = bool(task_id in suite_tasks() and summary["headroom"]["met"])
        summary["steps_per_s"] = speeds[task_id]
        tasks[task_id] = summary
    data = {"suite": "v1", "profile": profile.name, "heldout_draws": profile.heldout,
            "rl_budget": ", ".join(f"{algo.upper()} {steps:,} env steps x {profile.rl_seeds} seeds"
                                   for algo, steps in profile.rl_steps.items()),
            "tasks": tasks, "rl_target": rl_target(tasks), "solved_tier": solved_tier(),
            "speed_targets_steps_per_s": SUITE_TARGETS,
            "wall_s": time.time() - start}
    stem = "suite_v1" if profile.name == "full" else f"suite_v1_{profile.name}"
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{stem}.json").write_text(json.dumps(data, indent=1))
    text = markdown(data)
    (out / f"{stem}.md").write_text(text)
    figure(data, figure_path)
    if readme is not None:
        from experiments.report_markdown import update_readme

        update_readme(readme, text + f"\n![suite v1](../figures/{figure_path.name})\n", area=README_AREA)
    log(f"[suite] wrote {out / f'{stem}.json'} in {data['wall_s'] / 60:.1f} min")
    return data


