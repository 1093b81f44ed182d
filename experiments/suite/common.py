"""What both benchmark suites do alike: play agents on a task's native vector env, the design family,
the design searches, the noise-replicate oracle, the bootstrap helpers, the env speed.

Every function takes a task as a :class:`~experiments.suite.kinds.TaskKind` (``task_kind(task_id)``), which
holds what differs between the kinds (the metric, the agents' estimator, the draws recorded).
"""

from __future__ import annotations

import argparse
import itertools
import pathlib
import time

import numpy as np

from hyst_gym.physics.background_compile import foreground_compiles

ROOT = pathlib.Path(__file__).resolve().parents[2]
RESULTS = ROOT / "experiments" / "results"
FIGURES = ROOT / "docs" / "figures"
DOCS_PAGE = ROOT / "docs" / "results" / "suite.md"
HEADROOM_TARGET = 0.25
#: seeds of the oracle's noise replicates start here (disjoint from every other seed set)
REPLICATE_OFFSET = 10_000_000


class UsageError(Exception):
    """A bad command-line argument (one line at the CLI, status 2)."""


# ---------------------------------------------------------------------------- the design family

#: the design family (A/m, Hz, s)
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
PROPORTIONAL_AMPLITUDE = 8.0e4
PROPORTIONAL_FREQUENCIES = (0.25, 0.5)
PROPORTIONAL_MARGINS = (2.0, 5.0, 10.0)
PROPORTIONAL_SPANS = (10.0, 20.0, 40.0)
GATE_AMPLITUDES = (4.0e4, 8.0e4)
GATE_FREQUENCY = 0.5
GATE_TAILS = (0.1, 0.25)
GATE_TUNING = (0.05, 0.1, 0.2)   # |normalized tuning error| at most this: identified
GATE_ERRORS = (10.0, 25.0, 50.0)  # A/m, the clairvoyant version: |a_estimate - a_true| at most this
GATE_MARGIN = 2.0                # K: every gated design also stops 2 K below the limit


def _dither_designs():
    from baselines.suite_agents import Design, RampDither

    designs = []
    for peak, dither_amplitude, frequency in itertools.product(DITHER_PEAKS, DITHER_AMPLITUDES, DITHER_FREQUENCIES):
        dither = RampDither(peak, DITHER_DURATION, dither_amplitude, frequency)
        label = f"{dither.peak:g}_{dither.dither:g}_{dither.frequency:g}"
        designs.append(Design(f"dither_{label}", dither))
        designs.append(Design(f"oracle_dither_{label}", dither, GATE_MARGIN, True))
        # ramp to the peak, dither until a is identified, then back off to a quarter of the field
        for gate in DITHER_GATE_TUNING:
            designs.append(Design(f"gate_dither_{label}_{gate:g}", dither, GATE_MARGIN, gate=gate, tail=DITHER_TAIL))
        for gate in DITHER_GATE_ERRORS:
            designs.append(Design(f"oracle_gate_dither_{label}_{gate:g}", dither, GATE_MARGIN, True, gate=gate,
                                  tail=DITHER_TAIL))
    return designs


def _feedback_designs(truth: bool):
    from baselines.schedules import Sine
    from baselines.suite_agents import Design

    designs = []
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
    for amplitude, tail, gate in itertools.product(GATE_AMPLITUDES, GATE_TAILS, GATE_ERRORS if truth else GATE_TUNING):
        label = "oracle_gate" if truth else "gate"
        designs.append(Design(f"{label}_{amplitude:g}_{tail:g}_{gate:g}",
                              Sine(amplitude=amplitude, frequency=GATE_FREQUENCY), GATE_MARGIN, truth,
                              gate=gate, tail=tail))
    return designs


def design_family():
    """Every design of the family: open-loop sines and ramps; on/off and proportional thermostats on the
    estimate, and the same on the true temperature (the oracle's)."""
    from baselines.schedules import Ramp, Sine
    from baselines.suite_agents import Design

    designs = [Design("idle", Sine(amplitude=0.0))]  # no excitation at all: the coil stays cool
    designs += _dither_designs()
    for offset, amplitude, frequency in itertools.product(SINE_OFFSETS, SINE_AMPLITUDES, SINE_FREQUENCIES):
        if offset + amplitude <= 1.0e5:
            designs.append(Design(f"sine_{offset:g}_{amplitude:g}_{frequency:g}",
                                  Sine(amplitude=amplitude, frequency=frequency, offset=offset)))
    for peak, duration in itertools.product(RAMP_PEAKS, RAMP_DURATIONS):
        designs.append(Design(f"ramp_{peak:g}_{duration:g}", Ramp(peak=peak, duration=duration)))
    for truth in (False, True):
        designs += _feedback_designs(truth)
    return designs


# ---------------------------------------------------------------------------- playing


def vector_env(task_id: str, n: int, **overrides):
    """The task's native vector env of ``n`` sub-envs (``overrides``: EnvConfig fields)."""
    import gymnasium

    import hyst_gym  # noqa: F401  (registers the ids)

    return gymnasium.make_vec(task_id, num_envs=int(n), vectorization_mode="vector_entry_point", **overrides)


TRACE_KEYS = ("field", "a_estimate", "a_true", "temperature")


def play(agent, task, seeds, options=None, overrides=None, keep_trace: bool = False):
    """Play ``agent`` once per seed on ``task`` (a :class:`~experiments.suite.kinds.TaskKind`; one sub-env each,
    deterministic actions). Returns the per-draw metric (:meth:`TaskKind.metric`: A/m units, width(Theta) per
    step after an overheat), the draws (start temperature, drift, and what the kind draws besides) and, with
    ``keep_trace``, the per-step traces (NaN after an overheat)."""
    seeds = [int(s) for s in seeds]
    n = len(seeds)
    env = vector_env(task.id, n, **(overrides or {}))
    inner = env.unwrapped
    config = inner.config
    steps = config.episode_steps
    errors = np.zeros((steps, n))
    trace = {key: np.zeros((steps, n)) for key in TRACE_KEYS} if keep_trace else None
    try:
        agent.reset(seeds[0])
        observations, infos = env.reset(seed=seeds, options=options)
        draws = task.draws(inner)
        alive = np.ones(n, dtype=bool)
        start = np.ones(n, dtype=bool)
        for step in range(steps):
            if getattr(agent, "reads_truth", False):
                agent.observe(infos)
            actions, _ = agent.predict(observations, episode_start=start, deterministic=True)
            observations, _, terminated, _, infos = env.step(np.asarray(actions, dtype=np.float32))
            start = np.zeros(n, dtype=bool)
            errors[step] = np.where(alive, np.abs(infos["a_estimate"] - infos["a_true"]), config.theta_width)
            if keep_trace:
                for key in trace:
                    trace[key][step] = np.where(alive, infos[key], np.nan)
            alive &= ~np.asarray(terminated)
    finally:
        env.close()
    return task.metric(errors), draws, trace


def family_scores(task, designs, seeds):
    """(n_designs, n_seeds) per-draw metric of every design on every seed, and the draws. The (design, seed)
    pairs are played in batches of sub-envs, one pair each: a sub-env's numbers do not depend on its batch."""
    seeds = [int(s) for s in seeds]
    pairs = [(d, s) for d in range(len(designs)) for s in range(len(seeds))]
    per_batch = max(task.batch_size // len(seeds), 1) * len(seeds)
    scores = np.zeros(len(pairs))
    draws = None
    for first in range(0, len(pairs), per_batch):
        chunk = pairs[first:first + per_batch]
        metric, chunk_draws, _ = play(task.design_agent([designs[d] for d, _ in chunk]), task,
                                      [seeds[s] for _, s in chunk])
        scores[first:first + len(chunk)] = metric
        if draws is None:
            draws = {key: value[:len(seeds)] for key, value in chunk_draws.items()}
    return scores.reshape(len(designs), len(seeds)), draws


def oracle_scores(task, designs, heldout_scores, draws, seeds):
    """Per held-out draw, the design best on a noise replicate of the draw (the same plant truth:
    :meth:`TaskKind.replicate_options`), scored on the draw itself. Returns (scores, chosen design indices)."""
    agent = task.design_agent(designs)
    choice = np.zeros(len(seeds), dtype=np.int64)
    for j, seed in enumerate(seeds):
        replicate = [REPLICATE_OFFSET + 1000 * int(seed) + i for i in range(len(designs))]
        metric, _, _ = play(agent, task, replicate, options=task.replicate_options(draws, j))
        choice[j] = int(np.argmin(metric))
    return heldout_scores[choice, np.arange(len(seeds))], choice


def pick_tuned(family, tuned_value, kind: str, prefix: str = "") -> int:
    """The index of the design of ``kind`` (and name ``prefix``) best by ``tuned_value`` (lower is better)."""
    kinds = np.array([design.kind for design in family])
    members = [i for i in np.flatnonzero(kinds == kind) if family[i].name.startswith(prefix)]
    return members[int(np.argmin(tuned_value[members]))]


# ---------------------------------------------------------------------------- searched designs


def excitation_limits(config):
    from baselines.schedules import ExcitationLimits

    return ExcitationLimits(config.field_limit, config.slew_rate_limit, config.dt)


def task_prior(config, points: int = 5):
    """Quantiles of a over the task's start temperatures up to its temperature limit, A/m."""
    low = config.initial_temperature_range[0]
    return tuple(float(a) for a in config.a_of(np.linspace(low, config.temperature_limit, points)))


def fisher_design(config, evaluations: int):
    """The prior-averaged Fisher-information multisine (:mod:`baselines.optimal_design`)."""
    from baselines.optimal_design import design_input

    return design_input(excitation_limits(config), task_prior(config), period=config.episode_duration,
                        max_evaluations=evaluations).design


#: K below the temperature limit that the hottest start of a calibration task's prior may reach under the
#: direct design (the references' margin, :data:`baselines.references.SAFETY_MARGIN`)
DIRECT_DESIGN_MARGIN = 1.0


def hottest_start_excess(config, schedule) -> float:
    """How far (K) the applied field of ``schedule`` (through the field and slew limits) takes the coil above
    ``temperature_limit - DIRECT_DESIGN_MARGIN`` from the hottest start of the prior, the ambient equal to it
    (the lumped thermal model the env integrates); 0 where it stays below."""
    from baselines.references import peak_temperature

    field = schedule.sampled(config.episode_steps, excitation_limits(config))
    peak = peak_temperature(config, field, float(config.initial_temperature_range[1]))
    return max(0.0, peak - (config.temperature_limit - DIRECT_DESIGN_MARGIN))


def direct_design(task, tuning_seeds, evaluations: int, hottest_safe: bool = False):
    """CMA-ES over a 9-knot field on ``task``'s statistic of its metric over the tuning draws. ``hottest_safe``
    (calibration tasks only: no ambient drift, so the heating is a known function of the input): a design that
    would take the hottest start of the prior within :data:`DIRECT_DESIGN_MARGIN` of the limit scores
    width(Theta) (what an overheat costs per step) plus that much per K of excess, so the search stays among
    inputs safe for every start (without it, a longer search spent the heat the tuning draws' starts allowed
    and overheated hotter held-out starts)."""
    from baselines.direct_design import search_direct_design
    from baselines.suite_agents import Design

    config = task.config
    if hottest_safe and not task.spec.calibrates:
        raise ValueError(f"direct_design: hottest_safe needs a calibration task, got {task.id!r}")
    safe = hottest_safe

    def score(schedule):
        if safe:
            excess = hottest_start_excess(config, schedule)
            if excess > 0.0:
                return config.theta_width * (1.0 + excess)
        metric, _, _ = play(task.design_agent([Design("direct_design", schedule)]), task, tuning_seeds)
        return task.statistic(metric[None, :])

    return search_direct_design(score, excitation_limits(config), config.episode_duration, n_knots=9,
                                max_evaluations=evaluations).schedule


# ---------------------------------------------------------------------------- statistics and speed


def matrix(scores) -> np.ndarray:
    """``scores`` as a (runs, draws) float matrix (one run for a 1-D array)."""
    scores = np.asarray(scores, dtype=np.float64)
    return scores[None, :] if scores.ndim == 1 else scores


#: wall seconds per timed case of the env speed measurement
SPEED_BUDGET_S = 1.0
SPEED_TARGETS = {"single": 20_000, "1024": 200_000}


def env_speed(task_id: str, budget: float = SPEED_BUDGET_S) -> dict:
    """Env steps/s under random actions: one ``gymnasium.make`` env, and the native vector env at n = 1024, the
    kernels compiled before the clock starts (never their plain-Python twins)."""
    with foreground_compiles():
        return _time_env(task_id, budget)


def _time_env(task_id: str, budget: float) -> dict:
    import gymnasium

    import hyst_gym  # noqa: F401

    env = gymnasium.make(task_id)
    env.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, (500,) + env.action_space.shape).astype(np.float32)
    for action in actions[:100]:
        env.step(action)
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < budget:
        for action in actions:
            _, _, terminated, truncated, _ = env.step(action)
            steps += 1
            if terminated or truncated:
                env.reset()
    single = steps / (time.perf_counter() - start)
    venv = gymnasium.make_vec(task_id, num_envs=1024, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    batch = np.random.default_rng(0).uniform(-1, 1, (8, 1024) + venv.single_action_space.shape).astype(np.float32)
    venv.step(batch[0])
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < budget:
        venv.step(batch[calls % 8])
        calls += 1
    return {"single": single, "1024": calls * 1024 / (time.perf_counter() - start)}


class OneLineParser(argparse.ArgumentParser):
    """argparse with a one-line usage error (exit status 2)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def measurement_main(name: str, doc: str, measure, markdown, argv=None, heldout: int = 24) -> int:
    """The command line of a task's own measurement script (``python -m experiments.suite.NAME``): ``--heldout``,
    ``--tuning``, ``--bootstrap`` (each >= 1, else one line and exit status 2) and ``--out``; writes
    ``suite_v2_NAME.json`` (``measure(heldout, tuning, bootstrap)`` and the command) and ``.md``
    (``markdown(data)``)."""
    import json
    import sys

    parser = OneLineParser(prog=f"python -m experiments.suite.{name}", description=doc.split("\n")[0])
    parser.add_argument("--heldout", type=int, default=heldout)
    parser.add_argument("--tuning", type=int, default=10)
    parser.add_argument("--bootstrap", type=int, default=1000)
    parser.add_argument("--out", default=str(RESULTS))
    args = parser.parse_args(argv)
    if min(args.heldout, args.tuning, args.bootstrap) < 1:
        print(f"{name}: error: --heldout, --tuning and --bootstrap must be >= 1", file=sys.stderr)
        return 2
    data = measure(args.heldout, args.tuning, args.bootstrap)
    data["command"] = f"python -m experiments.suite.{name} " + " ".join(sys.argv[1:] if argv is None else argv)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"suite_v2_{name}.json").write_text(json.dumps(data, indent=1))
    (out / f"suite_v2_{name}.md").write_text(markdown(data))
    print(f"[{name}] wrote {out / f'suite_v2_{name}.json'}")
    return 0
