"""The discriminate task measured (``hyst_gym/Discriminate-v0``): how fast can an input tell the three
explanations of a recording apart?

    python -m experiments.suite.discriminate [--heldout N] [--tuning N] [--bootstrap N] [--out DIR]

Agents (:mod:`baselines.discriminate_agents`): ``replay_recording`` (the recording's own drive, open loop),
``tuned_open_loop`` (the best on the tuning draws of a family of triangles: amplitudes
:data:`AMPLITUDES` x periods :data:`PERIODS` x biases :data:`BIASES` of the field limit, through the slew limit),
``greedy_separation`` (feedback, model-based: the field move whose predicted candidate outputs differ most,
weighted by the posterior, under a braking heat guard; its margin tuned from :data:`MARGINS`). Floor: an
**oracle**: per held-out draw, the agent of that family (greedy rules included) best on :data:`REPLICATES`
noise replicates of the draw (same truth and start temperature, other noise), scored on the draw itself;
the JSON counts the draws on which an agent beats it, and says whether an agent beats it on average.
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
    and the draw (truth, start temperature)."""
    from hyst_gym.envs.discriminate import DiscriminateVectorEnv

    seeds = [int(s) for s in seeds]
    n = len(seeds)
    env = DiscriminateVectorEnv(n, TASK)
    agent.reset(seeds[0])
    observations, _ = env.reset(seed=seeds, options=options)
    draws = {"truth": env.truth.tolist(), "start_temperature": env.start_temperature.tolist()}
    total, alive, start = np.zeros(n), np.ones(n, dtype=bool), np.ones(n, dtype=bool)
    decided, overheated = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    for _ in range(env.config.episode_steps):
        actions, _ = agent.predict(observations, episode_start=start, deterministic=True)
        observations, reward, terminated, truncated, info = env.step(np.asarray(actions, dtype=np.float32))
        start[:] = False
        total += np.where(alive, reward, 0.0)
        decided |= alive & info["decided"]
        overheated |= alive & info["overheated"]
        alive &= ~(terminated | truncated)
    return {"time_s": -total * env.config.episode_duration, "decided": decided, "overheated": overheated,
            "draws": draws}


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
    replicate_times = np.zeros((len(names), len(held)))
    for r in range(REPLICATES):  # the decision time is noisy: the choice averages several replicates
        replicate = [common.REPLICATE_OFFSET + 1000 * int(seed) + r for seed in held]
        replicate_times += np.array([play(agents[name][1], replicate, options)["time_s"] for name in names])
    held_times = np.array([played[name]["time_s"] for name in names])
    choice = np.argmin(replicate_times, axis=0)
    floor = held_times[choice, np.arange(len(held))]
    picks = {"open_loop": min((n for n in names if agents[n][0] == "open_loop"), key=tuned.get),
             "feedback": min((n for n in names if agents[n][0] == "feedback"), key=tuned.get)}
    rows = {"replay_recording": ("open_loop", "replay_recording"), "tuned_open_loop": ("open_loop", picks["open_loop"]),
            "greedy_separation": ("feedback", picks["feedback"])}
    table = {}
    for label, (kind, name) in rows.items():
        times = played[name]["time_s"]
        value, ci = bootstrap(mean, n_boot, times)
        table[label] = {"mean_s": value, "ci": ci, "kind": kind, "agent": name,
                        "decided": int(played[name]["decided"].sum()),
                        "overheated": int(played[name]["overheated"].sum()),
                        "draws_beating_floor": int(np.sum(times < floor)), "per_draw": times.tolist()}
    floor_value, floor_ci = bootstrap(mean, n_boot, floor)
    reference = min((n for n, a in table.items() if a["kind"] == "open_loop"), key=lambda n: table[n]["mean_s"])
    headroom = bootstrap(mean, n_boot, np.asarray(table[reference]["per_draw"]), floor,
                         combine=lambda r, f: r / f - 1.0)
    env_candidates = env.candidates
    return {"task": TASK, "statistic": "mean", "unit": "s", "heldout_draws": heldout, "tuning_draws": tuning,
            "candidates": {"a": list(env_candidates.a), "k": list(env_candidates.k),
                           "chi_r": list(env_candidates.chi_r),
                           "recording_distance": list(env_candidates.recording_distance)},
            "floor": {"kind": "oracle", "mean_s": floor_value, "ci": floor_ci, "per_draw": floor.tolist(),
                      "choice": [names[i] for i in choice],
                      "how": f"per draw, the family's agent best on {REPLICATES} noise replicates of the draw "
                             "(same truth and start temperature), scored on the draw",
                      "beaten_on_average_by": [n for n, a in table.items() if a["mean_s"] < floor_value]},
            "agents": table, "reference": reference, "tuning": tuned, "draws": draws,
            "headroom": {"value": headroom[0], "ci": headroom[1], "target": common.HEADROOM_TARGET},
            "in_suite": bool(headroom[1][0] > common.HEADROOM_TARGET), "wall_s": round(time.time() - start, 1)}


def markdown(data: dict) -> str:
    floor, head, cand = data["floor"], data["headroom"], data["candidates"]
    lines = [f"## Discriminate measured: `{data['task']}`", "",
             f"Time to the decision (the truth's posterior at 0.99), s, mean over {data['heldout_draws']} held-out "
             f"draws (10 s when undecided or overheated; 95 % bootstrap CI). Rerun: `{data['command']}`.", "",
             "| agent (kind) | mean s [CI] | decided | overheated | draws below the floor |", "|---|---|---|---|---|"]
    for name, entry in data["agents"].items():
        lines.append(f"| {name} ({entry['kind']}; {entry['agent']}) | {entry['mean_s']:.2f} [{entry['ci'][0]:.2f}, "
                     f"{entry['ci'][1]:.2f}] | {entry['decided']} | {entry['overheated']} | "
                     f"{entry['draws_beating_floor']} |")
    lines.append(f"| floor (oracle): {floor['how']} | {floor['mean_s']:.2f} [{floor['ci'][0]:.2f}, "
                 f"{floor['ci'][1]:.2f}] | | | |")
    beaten = floor["beaten_on_average_by"]
    lines += ["", "The oracle is beaten on average by " + (", ".join(beaten) if beaten else "no agent") + "."]
    lines += ["", f"Reference (best open-loop agent): {data['reference']}; headroom over the oracle "
                  f"{100 * head['value']:.0f} % [{100 * head['ci'][0]:.0f}, {100 * head['ci'][1]:.0f}] "
                  f"({'above' if data['in_suite'] else 'not above'} 25 %).", "",
              f"Candidates at 20 C: small_loop chi_r = {cand['chi_r'][0]:g}; pinning k = {cand['k'][1]:.1f} A/m "
              f"(RMS distance to small_loop on the recording {cand['recording_distance'][1]:.2e} of Ms); "
              f"anhysteretic_width a = {cand['a'][2]:.1f} A/m ({cand['recording_distance'][2]:.2e}).", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    return common.measurement_main("discriminate", __doc__, measure, markdown, argv, heldout=48)


if __name__ == "__main__":
    sys.exit(main())
