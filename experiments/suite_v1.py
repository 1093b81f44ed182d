"""Benchmark suite v1 (issue 13): tasks with headroom, floors, baselines and RL, one command.

    hyst-gym benchmark --suite v1 [--quick] [--tasks ID,ID] [--out DIR] [--no-readme]
    python -m experiments.suite_v1 [same options]

The tasks are the presets of :mod:`hyst_gym.envs.suite` (registered ids ``hyst_gym/*-v1``): a
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

import argparse
import itertools
import json
import pathlib
import sys
import time
from dataclasses import dataclass

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results"
FIGURES = ROOT / "docs" / "figures"
RAW = RESULTS / "raw" / "suite_v1"
#: the documentation page whose ``suite-v1`` section the full run rewrites
README = ROOT / "docs" / "results" / "suite.md"
README_AREA = "suite-v1"
HEADROOM_TARGET = 0.25
#: wall seconds per timed case of the env speed measurement (hyst_gym.envs.benchmark)
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

#: the design family (A/m, Hz, s); see the module docstring
SINE_OFFSETS = (0.0, 2.0e4, 4.0e4, 6.0e4)
SINE_AMPLITUDES = (1.0e4, 2.0e4, 4.0e4, 8.0e4)
SINE_FREQUENCIES = (0.1, 0.25, 0.5)
RAMP_PEAKS = (5.0e4, 8.0e4, 1.0e5)
RAMP_DURATIONS = (1.6, 4.0, 6.0)
DITHER_PEAKS = (3.0e4, 5.0e4, 7.0e4)
DITHER_AMPLITUDES = (5.0e3, 1.0e4, 2.0e4)
DITHER_FREQUENCIES = (0.5, 1.0)
DITHER_DURATION = 1.5  # s to reach the peak
DITHER_GATE_TUNING = (0.05, 0.1)
DITHER_GATE_ERRORS = (10.0, 25.0)
DITHER_TAIL = 0.25
THERMOSTAT_OFFSETS = (4.0e4, 6.0e4)
THERMOSTAT_AMPLITUDES = (2.0e4, 4.0e4)
THERMOSTAT_FREQUENCIES = (0.25, 0.5)
THERMOSTAT_MARGINS = (2.0, 5.0, 10.0)  # K below the limit
#: the proportional rule: a zero-mean sine scaled by the budget read (K of span)
PROPORTIONAL_AMPLITUDE = 8.0e4
PROPORTIONAL_FREQUENCIES = (0.25, 0.5)
PROPORTIONAL_MARGINS = (2.0, 5.0, 10.0)
PROPORTIONAL_SPANS = (10.0, 20.0, 40.0)
#: the identification gate: a zero-mean sine, idled to ``tail`` of itself once a is identified
GATE_AMPLITUDES = (4.0e4, 8.0e4)
GATE_FREQUENCY = 0.5
GATE_TAILS = (0.1, 0.25)
GATE_TUNING = (0.05, 0.1, 0.2)   # |normalized tuning error| at most this: identified
GATE_ERRORS = (10.0, 25.0, 50.0)  # A/m, the clairvoyant version: |a_estimate - a_true| at most this
GATE_MARGIN = 2.0                # K: every gated design also stops 2 K below the limit


def design_family():
    """Every design of the family: open-loop sines and ramps; on/off and proportional thermostats on the
    estimate, and the same on the true temperature (the oracle's)."""
    from baselines.schedules import Ramp, Sine
    from baselines.suite_agents import Design, RampDither

    designs = [Design("idle", Sine(amplitude=0.0))]  # no excitation at all: the coil stays cool
    dithers = [RampDither(peak, DITHER_DURATION, dither, frequency) for peak, dither, frequency in
               itertools.product(DITHER_PEAKS, DITHER_AMPLITUDES, DITHER_FREQUENCIES)]
    for dither in dithers:
        label = f"{dither.peak:g}_{dither.dither:g}_{dither.frequency:g}"
        designs.append(Design(f"dither_{label}", dither))
        designs.append(Design(f"oracle_dither_{label}", dither, GATE_MARGIN, True))
        # ramp to the peak, dither until a is identified, then back off to a quarter of the field
        for gate in DITHER_GATE_TUNING:
            designs.append(Design(f"gate_dither_{label}_{gate:g}", dither, GATE_MARGIN, gate=gate,
                                  tail=DITHER_TAIL))
        for gate in DITHER_GATE_ERRORS:
            designs.append(Design(f"oracle_gate_dither_{label}_{gate:g}", dither, GATE_MARGIN, True, gate=gate,
                                  tail=DITHER_TAIL))
    for offset, amplitude, frequency in itertools.product(SINE_OFFSETS, SINE_AMPLITUDES, SINE_FREQUENCIES):
        if offset + amplitude <= 1.0e5:
            designs.append(Design(f"sine_{offset:g}_{amplitude:g}_{frequency:g}",
                                  Sine(amplitude=amplitude, frequency=frequency, offset=offset)))
    for peak, duration in itertools.product(RAMP_PEAKS, RAMP_DURATIONS):
        designs.append(Design(f"ramp_{peak:g}_{duration:g}", Ramp(peak=peak, duration=duration)))
    for truth in (False, True):
        for offset, amplitude, frequency, margin in itertools.product(
                THERMOSTAT_OFFSETS, THERMOSTAT_AMPLITUDES, THERMOSTAT_FREQUENCIES, THERMOSTAT_MARGINS):
            label = "oracle_thermostat" if truth else "thermostat"
            designs.append(Design(f"{label}_{offset:g}_{amplitude:g}_{frequency:g}_{margin:g}",
                                  Sine(amplitude=amplitude, frequency=frequency, offset=offset), margin, truth))
        for frequency, margin, span in itertools.product(PROPORTIONAL_FREQUENCIES, PROPORTIONAL_MARGINS,
                                                          PROPORTIONAL_SPANS):
            label = "oracle_proportional" if truth else "proportional"
            designs.append(Design(f"{label}_{frequency:g}_{margin:g}_{span:g}",
                                  Sine(amplitude=PROPORTIONAL_AMPLITUDE, frequency=frequency), margin, truth, span))
        for amplitude, tail, gate in itertools.product(GATE_AMPLITUDES, GATE_TAILS,
                                                       GATE_ERRORS if truth else GATE_TUNING):
            label = "oracle_gate" if truth else "gate"
            designs.append(Design(f"{label}_{amplitude:g}_{tail:g}_{gate:g}",
                                  Sine(amplitude=amplitude, frequency=GATE_FREQUENCY), GATE_MARGIN, truth,
                                  gate=gate, tail=tail))
    return designs


# ---------------------------------------------------------------------------- playing


def make_env(task_id: str, n: int, **overrides):
    import gymnasium

    import hyst_gym  # noqa: F401  (registers the ids)

    return gymnasium.make_vec(task_id, num_envs=int(n), vectorization_mode="vector_entry_point", **overrides)


def estimate_index(config) -> int:
    from hyst_gym.envs.core import EXCITATION, observation_names

    return observation_names(config, EXCITATION).index("a_estimate")


def play(agent, task_id: str, seeds, options=None, overrides=None, keep_trace: bool = False):
    """Play ``agent`` once per seed (one sub-env each). Returns the per-episode metric (n,),
    the initial temperature and ambient drift of each draw, and (``keep_trace``) the traces."""
    seeds = [int(s) for s in seeds]
    n = len(seeds)
    env = make_env(task_id, n, **(overrides or {}))
    config = env.config
    sim = env.sim
    steps = config.episode_steps
    error = np.zeros((steps, n))
    trace = {key: np.zeros((steps, n)) for key in ("field", "a_estimate", "a_true", "temperature")}
    try:
        agent.reset(seeds[0])
        observations, infos = env.reset(seed=seeds, options=options)
        draws = {"temperature": sim.temperature.copy(), "drift_rate": sim.drift_rate.copy()}
        alive = np.ones(n, dtype=bool)
        episode_start = np.ones(n, dtype=bool)
        for t in range(steps):
            if getattr(agent, "reads_truth", False):
                agent.observe(infos)
            actions, _ = agent.predict(observations, episode_start=episode_start, deterministic=True)
            observations, _, terminated, truncated, infos = env.step(np.asarray(actions, dtype=np.float32))
            episode_start = np.zeros(n, dtype=bool)
            step_error = np.abs(infos["a_estimate"] - infos["a_true"])
            error[t] = np.where(alive, step_error, config.theta_width)
            if keep_trace:
                for key in trace:
                    trace[key][t] = np.where(alive, infos[key], np.nan)
            alive &= ~np.asarray(terminated)
    finally:
        env.close()
    return error.mean(axis=0), draws, (trace if keep_trace else None)


def design_agent(designs, config):
    from baselines.suite_agents import DesignBank

    return DesignBank(designs, config, estimate_index(config))


#: sub-envs per batched play of the design family (each sub-env's numbers do not depend on the batch)
FAMILY_BATCH = 4096


def family_scores(task_id, designs, seeds):
    """(n_designs, n_seeds) metric of every design on every seed, and the draws. The pairs are played
    in batches of sub-envs, one (design, seed) each: a sub-env's numbers do not depend on its batch."""
    from hyst_gym.envs.suite import task_config

    config = task_config(task_id)
    seeds = [int(s) for s in seeds]
    pairs = [(d, s) for d in range(len(designs)) for s in range(len(seeds))]
    per_batch = max(FAMILY_BATCH // len(seeds), 1) * len(seeds)
    scores = np.zeros(len(pairs))
    draws = None
    for start in range(0, len(pairs), per_batch):
        chunk = pairs[start:start + per_batch]
        agent = design_agent([designs[d] for d, _ in chunk], config)
        metric, chunk_draws, _ = play(agent, task_id, [seeds[s] for _, s in chunk])
        scores[start:start + len(chunk)] = metric
        if draws is None:
            draws = {key: value[:len(seeds)] for key, value in chunk_draws.items()}
    return scores.reshape(len(designs), len(seeds)), draws


def oracle_scores(task_id, designs, heldout_scores, draws, seeds):
    """Per held-out draw: the design best on a noise replicate of the draw, scored on the draw."""
    from hyst_gym.envs.suite import task_config

    config = task_config(task_id)
    agent = design_agent(designs, config)
    choice = np.zeros(len(seeds), dtype=np.int64)
    for j, seed in enumerate(seeds):
        options = {"initial_temperature": float(draws["temperature"][j]),
                   "ambient_drift_rate": float(draws["drift_rate"][j])}
        replicate = [REPLICATE_OFFSET + 1000 * int(seed) + i for i in range(len(designs))]
        metric, _, _ = play(agent, task_id, replicate, options=options)
        choice[j] = int(np.argmin(metric))
    return heldout_scores[choice, np.arange(len(seeds))], choice


#: seeds of the oracle's noise replicates start here (disjoint from every other seed set)
REPLICATE_OFFSET = 10_000_000


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
    for seed, folder in seeds:
        n_stack = json.loads((folder / "config.json").read_text()).get("n_stack", 1)
        cls = algorithm_class(algo)
        paths = sorted((folder / "checkpoints").glob("model_*_steps.zip"), key=lambda p: int(p.stem.split("_")[1]))
        keep = sorted(set(np.linspace(0, len(paths) - 1, min(CURVE_POINTS, len(paths))).round().astype(int)))
        for path in [paths[i] for i in keep] if paths else []:
            steps = int(path.stem.split("_")[1])
            model = cls.load(path, device="cpu")
            metric, _, _ = play(PolicyAgent(model, n_stack), task_id, draws)
            by_steps.setdefault(steps, []).append(metric)
    return [{"env_steps": steps, "iqm": iqm(np.array(rows)), "seeds": len(rows)}
            for steps, rows in sorted(by_steps.items())]


# ---------------------------------------------------------------------------- baselines


def task_prior(config, points: int = 5):
    """Quantiles of a over the task's start temperatures up to its temperature limit, A/m."""
    low = config.initial_temperature_range[0]
    return tuple(float(a) for a in config.a_of(np.linspace(low, config.temperature_limit, points)))


def fisher_design(config, profile: Profile):
    """The prior-averaged Fisher-information multisine (:mod:`baselines.optimal_design`)."""
    from baselines.optimal_design import design_input
    from baselines.schedules import ExcitationLimits

    limits = ExcitationLimits(config.field_limit, config.slew_rate_limit, config.dt)
    return design_input(limits, task_prior(config), period=config.episode_duration,
                        max_evaluations=profile.fisher_evaluations).design


def direct_design(task_id: str, config, tuning_seeds, profile: Profile):
    """CMA-ES over a 9-knot field on the task metric (IQM over the tuning draws)."""
    from baselines.direct_design import search_direct_design
    from baselines.schedules import ExcitationLimits
    from baselines.stats import iqm
    from baselines.suite_agents import Design

    limits = ExcitationLimits(config.field_limit, config.slew_rate_limit, config.dt)

    def score(schedule):
        metric, _, _ = play(design_agent([Design("direct_design", schedule)], config), task_id, tuning_seeds)
        return iqm(metric)

    return search_direct_design(score, limits, config.episode_duration, n_knots=9,
                                max_evaluations=profile.cma_evaluations).schedule


def evaluate_task(task_id: str, profile: Profile, raw: pathlib.Path = RAW, log=print) -> dict:
    """Every agent's per-draw metric on the held-out draws, the oracle, and the tuning choices."""
    from baselines.rl import PolicyAgent
    from baselines.scenarios import HELDOUT_SEEDS, TUNING_SEEDS, VALIDATION_SEEDS
    from baselines.schedules import Ramp
    from baselines.stats import iqm
    from baselines.suite_agents import Design
    from hyst_gym.envs.suite import task_config

    start = time.time()
    config = task_config(task_id)
    tuning, heldout = TUNING_SEEDS[:profile.tuning], HELDOUT_SEEDS[:profile.heldout]
    family = design_family()
    kinds = np.array([design.kind for design in family])
    tune_scores, _ = family_scores(task_id, family, tuning)
    held_scores, draws = family_scores(task_id, family, heldout)
    oracle, choice = oracle_scores(task_id, family, held_scores, draws, heldout)
    tuned_iqm = np.array([iqm(row) for row in tune_scores])

    def tuned(kind, prefix=""):
        members = [i for i in np.flatnonzero(kinds == kind) if family[i].name.startswith(prefix)]
        return members[int(np.argmin(tuned_iqm[members]))]

    best_open = tuned("open_loop")
    best_thermostat, best_proportional = tuned("feedback", "thermostat_"), tuned("feedback", "proportional_")
    best_gate = tuned("feedback", "gate_")
    agents = {"ramp": ("open_loop", play(design_agent([Design("ramp", Ramp())], config), task_id, heldout)[0]),
              "tuned_open_loop": ("open_loop", held_scores[best_open]),
              "thermostat": ("feedback", held_scores[best_thermostat]),
              "proportional": ("feedback", held_scores[best_proportional]),
              "identify_then_idle": ("feedback", held_scores[best_gate])}
    log(f"[suite] {task_slug(task_id)}: family of {len(family)} tuned and played ({time.time() - start:.0f} s)")
    fisher = Design("optimal_design_prior", fisher_design(config, profile))
    agents["optimal_design_prior"] = ("open_loop", play(design_agent([fisher], config), task_id, heldout)[0])
    direct = Design("direct_design", direct_design(task_id, config, tuning, profile))
    agents["direct_design"] = ("open_loop", play(design_agent([direct], config), task_id, heldout)[0])
    log(f"[suite] {task_slug(task_id)}: designs searched ({time.time() - start:.0f} s)")
    for estimator in ("gradient", "multiple_model"):
        metric, _, _ = play(design_agent([family[best_open]], config), task_id, heldout,
                            overrides={"estimator": estimator})
        agents[estimator] = ("estimator", metric)
    curves = {}
    for algo in RL_ALGORITHMS:
        found = rl_agents(task_id, algo, profile.rl_seeds, raw)
        if not found:
            continue
        rows = [play(PolicyAgent.load(folder), task_id, heldout)[0] for _, folder in found]
        agents[algo] = ("rl", np.array(rows))
        configs = [json.loads((folder / "config.json").read_text()) for _, folder in found]
        curves[algo] = {"seeds": [seed for seed, _ in found],
                        "steps": [config.get("trained_steps") for config in configs],
                        "train_wall_s": sum(config.get("wall_s_last_session", 0.0) for config in configs),
                        "points": (learning_curve(task_id, algo, found, VALIDATION_SEEDS[:8], raw)
                                   if profile.curves else [])}
    log(f"[suite] {task_slug(task_id)}: agents played ({time.time() - start:.0f} s)")
    return {"agents": agents, "oracle": oracle, "oracle_choice": [family[i].name for i in choice],
            "tuned": {"tuned_open_loop": family[best_open].name, "thermostat": family[best_thermostat].name,
                      "proportional": family[best_proportional].name, "identify_then_idle": family[best_gate].name,
                      "estimators_input": family[best_open].name},
            "designs": {"optimal_design_prior": list(fisher.schedule.coefficients),
                        "direct_design_knots": list(direct.schedule.knots)},
            "curves": curves, "draws": {k: v.tolist() for k, v in draws.items()},
            "wall_s": time.time() - start}


# ---------------------------------------------------------------------------- statistics


def _matrix(scores) -> np.ndarray:
    scores = np.asarray(scores, dtype=np.float64)
    return scores[None, :] if scores.ndim == 1 else scores


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
    from hyst_gym.envs.suite import TASKS

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
    for name, (kind, scores) in evaluated["agents"].items():
        value, ci = normalized_ci(scores, reference_scores, oracle, profile.bootstrap)
        agents[name]["normalized"] = {"iqm": value, "ci": ci}
    beats = {name: float(np.mean(_matrix(scores).mean(axis=0) < oracle))
             for name, (_, scores) in evaluated["agents"].items()}
    spec = TASKS[task_id]
    return {
        "metric": "mean |a_estimate - a_true| over the episode, A/m (width(Theta) per step after an overheat)",
        "lower_is_better": True,
        "description": spec["description"], "difficulty": spec["difficulty"], "in_suite": accepted,
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
    """The committed scenarios (issue 5) as the suite's solved tier: best agent against its floor."""
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
    from hyst_gym.envs.suite import SUITE_V1

    from hyst_gym.envs.benchmark import SUITE_TARGETS, run_suite_benchmark

    start = time.time()
    if profile.train:
        train_all([t for t in task_ids if t in SUITE_V1], profile, raw)
    speeds = run_suite_benchmark(log, SPEED_BUDGET_S, task_ids)
    tasks = {}
    for task_id in task_ids:
        evaluated = evaluate_task(task_id, profile, raw, log)
        summary = summarize_task(task_id, evaluated, profile, accepted=False)
        summary["in_suite"] = bool(task_id in SUITE_V1 and summary["headroom"]["met"])
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


# ---------------------------------------------------------------------------- command line


def configure_parser(parser) -> None:
    parser.add_argument("--suite", default="v1", help="suite version (only v1)")
    parser.add_argument("--quick", action="store_true",
                        help="quick profile: 16 held-out draws, small design searches, committed RL models, no "
                             "README edit (writes suite_v1_quick.*)")
    parser.add_argument("--tasks", default="", help="comma list of task ids (default: the suite and the rejected "
                        "candidates; quick: the suite)")
    parser.add_argument("--out", default=str(RESULTS), help="folder of the JSON and markdown results")
    parser.add_argument("--figure", default=None, help="figure path (default docs/figures/suite_v1[_quick].png)")
    parser.add_argument("--no-readme", action="store_true", help="do not rewrite the suite section of docs/results/suite.md")


class UsageError(Exception):
    pass


def _options(args):
    from hyst_gym.envs.suite import SUITE_V1, TASKS, suite_tasks

    try:
        suite_tasks(args.suite)
    except ValueError as error:
        raise UsageError(f"--suite: {error}") from None
    profile = PROFILES["quick" if args.quick else "full"]
    if args.tasks:
        task_ids = [t.strip() for t in args.tasks.split(",") if t.strip()]
        unknown = [t for t in task_ids if t not in TASKS]
        if unknown or not task_ids:
            raise UsageError(f"--tasks: unknown task id(s) {unknown or args.tasks!r}; expected some of {sorted(TASKS)}")
    else:
        task_ids = list(suite_tasks()) + ([] if args.quick else [t for t in TASKS if t not in SUITE_V1])
    stem = "suite_v1" if profile.name == "full" else f"suite_v1_{profile.name}"
    figure_path = pathlib.Path(args.figure) if args.figure else FIGURES / f"{stem}.png"
    readme = None if (args.no_readme or args.quick) else README
    return profile, task_ids, pathlib.Path(args.out), figure_path, readme


def main(args) -> int:
    try:
        profile, task_ids, out, figure_path, readme = _options(args)
    except UsageError as error:
        print(f"hyst-gym benchmark: error: {error}", file=sys.stderr)
        return 2
    run_suite(profile, task_ids, out, figure_path, readme=readme)
    return 0


if __name__ == "__main__":
    _parser = argparse.ArgumentParser(prog="python -m experiments.suite_v1", description=__doc__.split("\n")[0])
    configure_parser(_parser)
    sys.exit(main(_parser.parse_args()))
