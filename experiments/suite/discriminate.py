"""The discriminate task measured (``hyst_gym/Discriminate-v0``): how fast can an input tell the three
explanations of a recording apart?

    python -m experiments.suite.discriminate [--heldout N] [--tuning N] [--bootstrap N] [--out DIR]

Agents (:mod:`baselines.discriminate_agents`): ``replay_recording`` (the recording's own drive, open loop),
``tuned_open_loop`` (the best on the tuning draws of a family of triangles: amplitudes
:data:`AMPLITUDES` x periods :data:`PERIODS` x biases :data:`BIASES` of the field limit, through the slew limit),
``greedy_separation`` (feedback, model-based: the field move whose predicted candidate outputs differ most,
weighted by the posterior, under a braking heat guard; its margin tuned from :data:`MARGINS`). Floor: the
**information bound** (:func:`hyst_gym.envs.discriminate.decision_time_bound`, derived on docs/envs/discriminate.md)
per held-out draw, at the separation envelope of an adversarial search (:func:`separation_envelope`) at the draw's
start temperature: kind ``search_bound``, proven given the envelope, the envelope not proven. Its check: every
agent's per-draw mean over the held-out run and :data:`REPLICATES` noise replicates (same truth and start
temperature), and the same for a greedy rule that reads the truth (the bound holds for it too). Kept as a
diagnostic: the replicate **oracle**, per held-out draw the family's agent best on the replicates, scored on the
draw itself (the decision time's noise makes it no floor: the greedy rule beats it on average).
Metric: the time to the decision (s; 10 s when undecided or overheated),
mean over draws; 95 % bootstrap CIs over the draws. Headroom: ``reference/floor - 1``, the reference the best
open-loop agent.

Writes ``experiments/results/suite_v2_discriminate.json`` and ``.md``. Bad arguments: one line, exit status 2.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from experiments.suite import common

TASK = "hyst_gym/Discriminate-v0"
AMPLITUDES = (0.1, 0.3, 0.6, 1.0)
PERIODS = (0.5, 1.0, 2.0, 4.0)
BIASES = (0.0, 0.3)
MARGINS = (1.0, 3.0)
#: noise replicates per held-out draw on which the oracle picks its agent (their mean time)
REPLICATES = 4


def play(agent, seeds, options=None) -> dict:
    """Per draw (one sub-env per seed): the time to the decision (s), whether it decided, whether it overheated,
    the draw (truth, start temperature), and the field path played ((n, N) A/m; the last field held after the
    episode's end)."""
    from hyst_gym.envs.discriminate import DiscriminateVectorEnv

    seeds = [int(s) for s in seeds]
    n = len(seeds)
    env = DiscriminateVectorEnv(n, TASK)
    if getattr(agent, "reads_truth", False):  # the bound's check: a clairvoyant rule reads this env's truth
        agent.truth_of = lambda: env.truth
    agent.reset(seeds[0])
    observations, _ = env.reset(seed=seeds, options=options)
    draws = {"truth": env.truth.tolist(), "start_temperature": env.start_temperature.tolist()}
    total, alive, start = np.zeros(n), np.ones(n, dtype=bool), np.ones(n, dtype=bool)
    decided, overheated = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    fields = np.zeros((n, env.config.episode_steps))
    for step in range(env.config.episode_steps):
        actions, _ = agent.predict(observations, episode_start=start, deterministic=True)
        observations, reward, terminated, truncated, info = env.step(np.asarray(actions, dtype=np.float32))
        start[:] = False
        total += np.where(alive, reward, 0.0)
        decided |= alive & info["decided"]
        overheated |= alive & info["overheated"]
        # a sub-env that ended autoresets on its next step: its path holds its last field
        fields[:, step] = np.where(alive, env.field, fields[:, step - 1] if step else 0.0)
        alive &= ~(terminated | truncated)
    return {"time_s": -total * env.config.episode_duration, "decided": decided, "overheated": overheated,
            "draws": draws, "fields": fields}


def family(env) -> dict:
    from baselines.discriminate_agents import GreedySeparation, replay_recording, triangle

    config = env.config
    agents = {"replay_recording": ("open_loop", replay_recording(config))}
    for amplitude in AMPLITUDES:
        for period in PERIODS:
            for bias in BIASES:
                if amplitude + bias <= 1.0:
                    agent = triangle(config, amplitude, period, bias)
                    agents[agent.name] = ("open_loop", agent)
    for margin in MARGINS:
        agent = GreedySeparation(env, margin)
        agents[agent.name] = ("feedback", agent)
    return agents


def mean(matrix) -> float:
    return float(np.mean(matrix))


def measure(heldout: int, tuning: int, n_boot: int, log=print) -> dict:
    from baselines.scenarios import HELDOUT_SEEDS, TUNING_SEEDS
    from baselines.discriminate_agents import ClairvoyantSeparation
    from experiments.suite.v2 import bootstrap
    from hyst_gym.envs.discriminate import DiscriminateVectorEnv

    start = time.time()
    env = DiscriminateVectorEnv(1, TASK)
    agents = family(env)
    tune, held = TUNING_SEEDS[:tuning], HELDOUT_SEEDS[:heldout]
    tuned = {name: float(np.mean(play(agent, tune)["time_s"])) for name, (_, agent) in agents.items()}
    played = {name: play(agent, held) for name, (_, agent) in agents.items()}
    draws = played["replay_recording"]["draws"]
    log(f"[discriminate] {len(agents)} agents tuned and played ({time.time() - start:.0f} s)")
    # the oracle: per draw, the agent best on a noise replicate with the draw's truth and start temperature
    options = {"truth": np.array(draws["truth"]), "initial_temperature": np.array(draws["start_temperature"])}
    names = list(agents)
    replicates = np.zeros((REPLICATES, len(names), len(held)))
    feedback_paths = [played[name]["fields"] for name in names if agents[name][0] == "feedback"]
    for r in range(REPLICATES):  # the decision time is noisy: the choice averages several replicates
        replicate = [common.REPLICATE_OFFSET + 1000 * int(seed) + r for seed in held]
        for a, name in enumerate(names):
            result = play(agents[name][1], replicate, options)
            replicates[r, a] = result["time_s"]
            if agents[name][0] == "feedback":
                feedback_paths.append(result["fields"])
    held_times = np.array([played[name]["time_s"] for name in names])
    # the bound's check: the greedy rule that reads the truth (the bound holds for it too), on the same runs
    clairvoyant = ClairvoyantSeparation(env, lambda: env.truth, margin=min(MARGINS))
    clairvoyant_runs = [play(clairvoyant, held)]
    clairvoyant_runs += [play(clairvoyant, [common.REPLICATE_OFFSET + 1000 * int(seed) + r for seed in held], options)
                         for r in range(REPLICATES)]
    feedback_paths += [run["fields"] for run in clairvoyant_runs]
    choice = np.argmin(replicates.sum(axis=0), axis=0)
    oracle = held_times[choice, np.arange(len(held))]
    log(f"[discriminate] oracle replicates played ({time.time() - start:.0f} s)")
    bound = information_floor(env, draws, np.concatenate(feedback_paths))
    clairvoyant_value, clairvoyant_ci = bootstrap(mean, n_boot, clairvoyant_runs[0]["time_s"])
    floor = np.asarray(bound["per_draw"])
    log(f"[discriminate] information bound searched ({time.time() - start:.0f} s)")
    picks = {"open_loop": min((n for n in names if agents[n][0] == "open_loop"), key=tuned.get),
             "feedback": min((n for n in names if agents[n][0] == "feedback"), key=tuned.get)}
    rows = {"replay_recording": ("open_loop", "replay_recording"), "tuned_open_loop": ("open_loop", picks["open_loop"]),
            "greedy_separation": ("feedback", picks["feedback"])}
    # every agent's per-draw mean over the held-out run and the replicates (same truth and start temperature): the
    # expectation over the noise that the bound bounds, per draw
    names = names + [clairvoyant.name]
    runs = np.concatenate([np.concatenate([held_times[None], replicates]),
                           np.array([run["time_s"] for run in clairvoyant_runs])[:, None, :]], axis=1)
    per_draw_means = runs.mean(axis=0)  # (agents and the clairvoyant rule, draws)
    table = {}
    for label, (kind, name) in rows.items():
        times = played[name]["time_s"]
        value, ci = bootstrap(mean, n_boot, times)
        table[label] = {"mean_s": value, "ci": ci, "kind": kind, "agent": name,
                        "decided": int(played[name]["decided"].sum()),
                        "overheated": int(played[name]["overheated"].sum()),
                        "draws_below_oracle": int(np.sum(times < oracle)), "per_draw": times.tolist()}
    floor_value, floor_ci = bootstrap(mean, n_boot, floor)
    oracle_value, oracle_ci = bootstrap(mean, n_boot, oracle)
    reference = min((n for n, a in table.items() if a["kind"] == "open_loop"), key=lambda n: table[n]["mean_s"])
    headroom = bootstrap(mean, n_boot, np.asarray(table[reference]["per_draw"]), floor,
                         combine=lambda r, f: r / f - 1.0)
    best = min(table, key=lambda n: table[n]["mean_s"])
    ratios = per_draw_means / floor[None, :]
    worst = np.unravel_index(int(np.argmin(ratios)), ratios.shape)
    check = {"runs_per_draw": int(runs.shape[0]),
             "tightest_per_draw_ratio": float(ratios[worst]),
             "tightest_per_draw": {"agent": names[worst[0]], "draw": int(worst[1])},
             "draws_with_a_mean_below": int(np.sum(np.any(ratios < 1.0, axis=0))),
             "tightest_mean_ratio": float(np.min(runs.mean(axis=(0, 2)) / floor_value)),
             "tightest_mean_agent": names[int(np.argmin(runs.mean(axis=(0, 2))))],
             "single_runs_below": int(np.sum(runs < floor[None, None, :])), "single_runs": int(runs.size)}
    # settle the tightest draw: its agent on SETTLE_REPLICATES more noise replicates of that draw
    settle_agent = clairvoyant if worst[0] == len(names) - 1 else agents[names[worst[0]]][1]
    settle = [common.REPLICATE_OFFSET + 1000 * int(held[worst[1]]) + REPLICATES + r for r in range(SETTLE_REPLICATES)]
    settle_options = {key: np.full(SETTLE_REPLICATES, value[worst[1]]) for key, value in options.items()}
    settled = play(settle_agent, settle, settle_options)["time_s"]
    check["tightest_settled"] = {"replicates": SETTLE_REPLICATES, "mean_s": float(settled.mean()),
                                 "standard_error_s": float(settled.std(ddof=1) / np.sqrt(SETTLE_REPLICATES)),
                                 "over_bound": float(settled.mean() / floor[worst[1]])}
    env_candidates = env.candidates
    return {"task": TASK, "statistic": "mean", "unit": "s", "heldout_draws": heldout, "tuning_draws": tuning,
            "candidates": {"a": list(env_candidates.a), "k": list(env_candidates.k),
                           "chi_r": list(env_candidates.chi_r),
                           "recording_distance": list(env_candidates.recording_distance)},
            "floor": {"kind": "search_bound", "proven": False, "mean_s": floor_value, "ci": floor_ci,
                      "per_draw": floor.tolist(), "how": bound["how"], "routes": bound["routes"],
                      "envelope_check": bound["check"], "adversarial_check": check,
                      "best_agent_over_floor": table[best]["mean_s"] / floor_value, "best_agent": best},
            "clairvoyant": {"agent": clairvoyant.name, "mean_s": clairvoyant_value, "ci": clairvoyant_ci,
                            "over_floor": clairvoyant_value / floor_value,
                            "how": "the greedy rule weighing the truth's pairs by the alternatives' posteriors; reads "
                                   "the truth (a check of the bound, which holds for it too; no benchmark agent)"},
            "oracle": {"kind": "oracle", "mean_s": oracle_value, "ci": oracle_ci, "per_draw": oracle.tolist(),
                       "choice": [names[i] for i in choice],
                       "how": f"per draw, the family's agent best on {REPLICATES} noise replicates of the draw "
                              "(same truth and start temperature), scored on the draw",
                       "beaten_on_average_by": [n for n, a in table.items() if a["mean_s"] < oracle_value]},
            "agents": table, "reference": reference, "tuning": tuned, "draws": draws,
            "headroom": {"value": headroom[0], "ci": headroom[1], "target": common.HEADROOM_TARGET},
            # a floor enters the suite as kind `bound` only when proven; the searched envelope is not
            "headroom_above_target": bool(headroom[1][0] > common.HEADROOM_TARGET),
            "in_suite": False, "wall_s": round(time.time() - start, 1)}


def information_floor(env, draws: dict, played_paths: np.ndarray) -> dict:
    """The information bound per held-out draw (s) at that draw's start temperature and truth: the searched
    separation envelope (:func:`separation_envelope`; first without the feedback agents' ``played_paths``, which
    check it, then with them) in :func:`information_bound`."""
    config = env.config
    per_draw, tail, wald, survival, excess = [], [], [], [], []
    exceeding = 0
    for d, (truth, temperature) in enumerate(zip(draws["truth"], draws["start_temperature"])):
        searched = separation_envelope(env, temperature, seed=d)
        # the check: the paths the feedback agents played (every draw's, at this start temperature) against it
        gathered = gathered_information(env, played_paths, temperature)
        above = gathered.max(axis=0) - np.concatenate([searched["pairs"], searched["mixtures"]])
        exceeding += int(np.any(above > 1e-9))
        excess.append(float(np.max(above)))
        envelope = {"pairs": np.maximum(searched["pairs"], gathered[:, :3].max(axis=0)),
                    "mixtures": np.maximum(searched["mixtures"], gathered[:, 3:].max(axis=0))}
        bound = information_bound(envelope, int(truth), config.episode_steps)
        per_draw.append(bound.steps * config.dt)
        tail.append(bound.tail_steps * config.dt)
        wald.append(bound.wald_steps * config.dt)
        survival.append(bound.survival_steps * config.dt)
    return {"per_draw": per_draw,
            "routes": {"tail_mean_s": float(np.mean(tail)), "wald_mean_s": float(np.mean(wald)),
                       "survival_mean_s": float(np.mean(survival)),
                       "survival_draws": int(np.sum(np.array(survival) >= np.maximum(tail, wald)))},
            "check": {"played_paths": int(played_paths.shape[0]), "draws_exceeded": exceeding,
                      "largest_excess_nats": float(np.max(excess))},
            "how": "the information bound (docs/envs/discriminate.md) at the largest relative entropy between the "
                   f"candidates that a search of {RANDOM_PATHS} random paths, the open-loop family, the pair-greedy "
                   f"paths and a hill climb (horizons {', '.join(map(str, CLIMB_HORIZONS))} steps) found per draw's "
                   "start temperature; proven given that envelope, which is a search's, not a proof's"}


def markdown(data: dict) -> str:
    floor, oracle, head, cand = data["floor"], data["oracle"], data["headroom"], data["candidates"]
    check, envelope, seer = floor["adversarial_check"], floor["envelope_check"], data["clairvoyant"]
    settled = check["tightest_settled"]
    lines = [f"## Discriminate measured: `{data['task']}`", "",
             f"Time to the decision (the truth's posterior at 0.99), s, mean over {data['heldout_draws']} held-out "
             f"draws (10 s when undecided or overheated; 95 % bootstrap CI). Rerun: `{data['command']}`.", "",
             "| agent (kind) | mean s [CI] | decided | overheated | draws below the oracle |", "|---|---|---|---|---|"]
    for name, entry in data["agents"].items():
        lines.append(f"| {name} ({entry['kind']}; {entry['agent']}) | {entry['mean_s']:.2f} [{entry['ci'][0]:.2f}, "
                     f"{entry['ci'][1]:.2f}] | {entry['decided']} | {entry['overheated']} | "
                     f"{entry['draws_below_oracle']} |")
    lines.append(f"| oracle: {oracle['how']} | {oracle['mean_s']:.2f} [{oracle['ci'][0]:.2f}, "
                 f"{oracle['ci'][1]:.2f}] | | | |")
    lines.append(f"| floor (information bound, searched envelope) | {floor['mean_s']:.2f} [{floor['ci'][0]:.2f}, "
                 f"{floor['ci'][1]:.2f}] | | | |")
    beaten = oracle["beaten_on_average_by"]
    lines += ["", "The oracle is beaten on average by " + (", ".join(beaten) if beaten else "no agent") + "."]
    routes = floor["routes"]
    lines += ["", f"Floor: {floor['how']}. Means of its routes: tail sum {routes['tail_mean_s']:.2f} s, Wald "
                  f"{routes['wald_mean_s']:.2f} s, survival {routes['survival_mean_s']:.2f} s (the largest per draw; "
                  f"the survival route on {routes['survival_draws']} draws). The "
                  f"{envelope['played_paths']} paths the feedback agents played exceed the searched envelope on "
                  f"{envelope['draws_exceeded']} of {data['heldout_draws']} draws (at most "
                  f"{envelope['largest_excess_nats']:.1e} nats; the floor uses the larger). Adversarial check, per "
                  f"draw the mean of {check['runs_per_draw']} runs (held-out "
                  f"and replicates) of every agent over the bound: tightest {check['tightest_per_draw_ratio']:.2f} "
                  f"({check['tightest_per_draw']['agent']}, draw {check['tightest_per_draw']['draw']}; on "
                  f"{settled['replicates']} more replicates of that draw {settled['over_bound']:.2f}, its mean "
                  f"{settled['mean_s']:.2f} +- {settled['standard_error_s']:.2f} s), draws with a "
                  f"mean below it {check['draws_with_a_mean_below']}; the tightest agent mean over the floor's mean "
                  f"{check['tightest_mean_ratio']:.2f} ({check['tightest_mean_agent']}); single runs below their "
                  f"draw's bound {check['single_runs_below']} of {check['single_runs']} (the bound is on the "
                  f"expectation over the noise). Best agent over the floor: {floor['best_agent_over_floor']:.2f} "
                  f"({floor['best_agent']}); {seer['agent']}, {seer['how']}: {seer['mean_s']:.2f} s "
                  f"[{seer['ci'][0]:.2f}, {seer['ci'][1]:.2f}], {seer['over_floor']:.2f} times the floor."]
    lines += ["", f"Reference (best open-loop agent): {data['reference']}; headroom over the floor "
                  f"{100 * head['value']:.0f} % [{100 * head['ci'][0]:.0f}, {100 * head['ci'][1]:.0f}] "
                  f"({'above' if data['headroom_above_target'] else 'not above'} 25 %). In the suite: "
                  f"{'yes' if data['in_suite'] else 'no'} (the floor's envelope is searched, not proven: not a "
                  "floor of kind `bound`).", "",
              f"Candidates at 20 C: small_loop chi_r = {cand['chi_r'][0]:g}; pinning k = {cand['k'][1]:.1f} A/m "
              f"(RMS distance to small_loop on the recording {cand['recording_distance'][1]:.2e} of Ms); "
              f"anhysteretic_width a = {cand['a'][2]:.1f} A/m ({cand['recording_distance'][2]:.2e}).", ""]
    return "\n".join(lines)

# ---------------------------------------------------------------- the information bound and its separation envelope

#: the pairs of candidates (columns of the posterior) whose noise-free outputs the envelope separates
PAIRS = ((0, 1), (0, 2), (1, 2))
#: the adversarial search of the separation envelope: random paths, hill-climbing generations and offspring, and
#: the horizons (steps) at which the hill climb pushes the cumulative separation
RANDOM_PATHS = 1024
CLIMB_GENERATIONS = 30
CLIMB_OFFSPRING = 48
CLIMB_HORIZONS = (2, 4, 6, 8, 10, 12, 16, 20, 24, 28, 32, 40, 48, 64, 96)
#: noise replicates that settle the check's tightest draw (its agent's mean over the five runs is noisy)
SETTLE_REPLICATES = 100


def simulate_paths(env, fields: np.ndarray, start_temperature: float):
    """The candidates' noise-free M/Ms ((R, N, 3)) and whether the coil is still within its limit after each step
    ((R, N)) along admissible field paths ``fields`` ((R, N), A/m) from field 0, M = 0 and ``start_temperature``
    (K), with the env's own step (slew-clipped paths; the coil cools towards its start temperature)."""
    from hyst_gym.envs.discriminate import advance_candidates, candidate_a
    from hyst_gym.physics.thermal import mean_square_linear, temperature_step

    config, rows = env.config, fields.shape[0]
    thermal = config.thermal
    decay = np.exp(-config.dt / thermal.time_constant)
    gain = thermal.thermal_resistance * thermal.power_per_square_field
    m = np.zeros((rows, 3))
    temperature = np.full(rows, float(start_temperature))
    before = np.zeros(rows)
    out, cool = np.empty((rows, fields.shape[1], 3)), np.empty((rows, fields.shape[1]), dtype=bool)
    alive = np.ones(rows, dtype=bool)
    for s in range(fields.shape[1]):
        a = candidate_a(env.models, temperature, thermal)
        after = np.ascontiguousarray(fields[:, s])
        advance_candidates(m, before, after, a, env.models)
        temperature = temperature_step(temperature, start_temperature, start_temperature,
                                       gain * mean_square_linear(before, after), decay)
        alive &= temperature <= config.temperature_limit
        out[:, s], cool[:, s], before = m / config.hysteresis.Ms, alive, after
    return out, cool


def slewed_paths(config, targets: np.ndarray) -> np.ndarray:
    """Target fields ((R, N), A/m) through the slew and field limits from field 0: admissible paths."""
    change, limit = config.max_field_change, config.field_limit
    field, paths = np.zeros(targets.shape[0]), np.empty_like(targets)
    for s in range(targets.shape[1]):
        field = np.clip(np.clip(targets[:, s], field - change, field + change), -limit, limit)
        paths[:, s] = field
    return paths


def random_paths(config, rng, count: int) -> np.ndarray:
    """``count`` admissible paths: piecewise-linear targets with knots every 1..32 steps (uniform over the field
    range, or a random walk of slew-limit moves), through the limits."""
    steps = config.episode_steps
    targets = np.empty((count, steps))
    for r in range(count):
        every = int(rng.choice([1, 2, 4, 8, 16, 32]))
        knots = np.arange(0, steps + every, every)
        if r % 2:
            values = rng.uniform(-1.0, 1.0, knots.shape[0]) * config.field_limit * rng.uniform(0.1, 1.0)
        else:
            values = np.cumsum(rng.choice([-1.0, 0.0, 1.0], knots.shape[0])) * config.max_field_change * every
        targets[r] = np.interp(np.arange(1, steps + 1), knots, values)
    return slewed_paths(config, targets)


def cumulative_separation(m: np.ndarray, cool: np.ndarray, noise: float) -> np.ndarray:
    """Per path and pair of :data:`PAIRS`: the relative entropy gathered by each step 0..N, ``sum_s d_s^2/(2
    sigma^2)`` over the steps with the coil within its limit (the overheating step counted too, which can only
    raise it): (R, 3, N + 1)."""
    counted = np.concatenate([np.ones_like(cool[:, :1]), cool[:, :-1]], axis=1)
    terms = np.stack([(m[:, :, i] - m[:, :, j]) ** 2 for i, j in PAIRS], axis=1) * counted[:, None, :]
    return np.concatenate([np.zeros(terms.shape[:2] + (1,)), np.cumsum(terms, axis=2)], axis=2) / (2 * noise ** 2)


def pair_greedy_paths(env, start_temperature: float) -> np.ndarray:
    """Per pair of :data:`PAIRS`, per truth (its two pairs) and for all three pairs: the noise-free greedy path
    that each step takes the slew move (of :data:`baselines.discriminate_agents.MOVES`) that most separates those
    pairs (the sum of their squared gaps), with no heat guard (an overheat ends the path's counting): (7, N)
    A/m."""
    from baselines.discriminate_agents import MOVES
    from hyst_gym.envs.discriminate import advance_candidates, candidate_a
    from hyst_gym.physics.thermal import mean_square_linear, temperature_step

    config = env.config
    thermal = config.thermal
    decay = np.exp(-config.dt / thermal.time_constant)
    gain = thermal.thermal_resistance * thermal.power_per_square_field
    weights = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1], [0, 1, 1], [1, 1, 1]],
                       dtype=np.float64)
    rows = weights.shape[0]
    m, field, direction = np.zeros((rows, 3)), np.zeros(rows), np.ones(rows)
    temperature = np.full(rows, float(start_temperature))
    paths = np.empty((rows, config.episode_steps))
    for s in range(config.episode_steps):
        a = candidate_a(env.models, temperature, thermal)
        best, best_field = np.full(rows, -np.inf), field.copy()
        for move in MOVES:
            target = np.clip(field + direction * move * config.max_field_change, -config.field_limit,
                             config.field_limit)
            trial = m.copy()
            advance_candidates(trial, field, target, a, env.models)
            gaps = np.stack([(trial[:, i] - trial[:, j]) ** 2 for i, j in PAIRS], axis=1)
            score = np.sum(weights * gaps, axis=1)
            better = score > best + 1e-30
            best, best_field = np.where(better, score, best), np.where(better, target, best_field)
        advance_candidates(m, field, best_field, a, env.models)
        temperature = temperature_step(temperature, start_temperature, start_temperature,
                                       gain * mean_square_linear(field, best_field), decay)
        moved = best_field - field
        direction = np.where(moved != 0, np.sign(moved), direction)
        field = best_field
        paths[:, s] = field
    return paths


def gathered_information(env, paths: np.ndarray, start_temperature: float) -> np.ndarray:
    """The relative entropy each admissible path gathers by each step 0..N: per pair of :data:`PAIRS`, then per
    truth the mean over its two alternatives ((R, 6, N + 1), nats)."""
    m, cool = simulate_paths(env, paths, start_temperature)
    pair = cumulative_separation(m, cool, env.config.output_noise)
    mix = np.stack([0.5 * (pair[:, 0] + pair[:, 1]), 0.5 * (pair[:, 0] + pair[:, 2]),
                    0.5 * (pair[:, 1] + pair[:, 2])], axis=1)  # truth 0: pairs 01, 02; 1: 01, 12; 2: 02, 12
    return np.concatenate([pair, mix], axis=1)


def separation_envelope(env, start_temperature: float, seed: int) -> dict:
    """The adversarial search's envelope of the relative entropy any admissible path gathers, at one start
    temperature: per pair of :data:`PAIRS`, the most over the searched paths by each step 0..N ((3, N + 1), nats),
    and per truth the most of the mean over its two alternatives ((3, N + 1)). The search: the open-loop
    family, :data:`RANDOM_PATHS` random paths, the pair-greedy paths, then a (1 + :data:`CLIMB_OFFSPRING`) hill
    climb from the best path per column and horizon of :data:`CLIMB_HORIZONS`. A lower estimate of the true
    envelope (the supremum over every admissible path)."""
    config = env.config
    rng = np.random.default_rng(seed)
    agents = family(env)
    open_loop = [agent._field * config.field_limit for kind, agent in agents.values() if kind == "open_loop"]
    pool = np.concatenate([slewed_paths(config, np.array(open_loop)), random_paths(config, rng, RANDOM_PATHS),
                           pair_greedy_paths(env, start_temperature)])

    def gathered(paths):
        return gathered_information(env, paths, start_temperature)

    values = gathered(pool)
    envelope = values.max(axis=0)
    scale = config.max_field_change
    for column in range(values.shape[1]):
        for horizon in CLIMB_HORIZONS:
            parent = pool[int(np.argmax(values[:, column, horizon]))][:horizon]
            best = float(values[:, column, horizon].max())
            for _ in range(CLIMB_GENERATIONS):
                kicks = rng.normal(0.0, 1.0, (CLIMB_OFFSPRING, horizon)) * scale * rng.choice([0.1, 0.3, 1.0],
                                                                                             (CLIMB_OFFSPRING, 1))
                children = slewed_paths(config, parent[None, :] + kicks)
                child_values = gathered(children)
                envelope[:, :horizon + 1] = np.maximum(envelope[:, :horizon + 1], child_values.max(axis=0))
                winner = int(np.argmax(child_values[:, column, horizon]))
                if child_values[winner, column, horizon] > best:
                    best, parent = float(child_values[winner, column, horizon]), children[winner]
    envelope = np.maximum.accumulate(envelope, axis=1)
    return {"pairs": envelope[:3], "mixtures": envelope[3:]}


def information_bound(envelope: dict, truth: int, total_steps: int):
    """:func:`hyst_gym.envs.discriminate.decision_time_bound` for ``truth`` at a :func:`separation_envelope`: the
    two alternatives' pair envelopes (each at odds :data:`DECISION_ODDS`) and the mixture's (at half the
    odds)."""
    from hyst_gym.envs.discriminate import DECISION_ODDS, decision_time_bound

    pairs = [p for p, (i, j) in enumerate(PAIRS) if truth in (i, j)]
    envelopes = [(DECISION_ODDS, envelope["pairs"][pairs[0]]), (DECISION_ODDS, envelope["pairs"][pairs[1]]),
                 (DECISION_ODDS / 2, envelope["mixtures"][truth])]
    return decision_time_bound(envelopes, total_steps)


def main(argv=None) -> int:
    return common.measurement_main("discriminate", __doc__, measure, markdown, argv, heldout=48)


if __name__ == "__main__":
    sys.exit(main())
