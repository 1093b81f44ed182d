"""The dual-control task measured: does probing pay? (``hyst_gym/DualControl-v0``)

    python -m experiments.suite.dual_control [--heldout N] [--tuning N] [--bootstrap N] [--out DIR]

Agents (their probe added to the inverse-compensation controller's field; :mod:`baselines.dual_control_agents`):
``no_probe`` (certainty equivalence), ``probe_burst`` (open loop: a square-wave probe burst, its amplitude and
length tuned on the tuning draws from :data:`BURST_AMPLITUDES` x :data:`BURST_STEPS`), ``probe_while_unsure``
(feedback: probe while the posterior's spread is above a threshold, tuned likewise); for context the controller
fed the preset's ``initial_estimate`` throughout (``nominal_a``: what identifying a is worth). Floor: the oracle,
the controller fed the true a with no probe (``controller_estimate="true"``; an oracle, not a bound: a probe could
in principle correct the controller's own one-step error). Metric: RMS over the 200 steps and the draws of the
tracking error of the noise-free output, in % of y(Ms) (100 % per step after an overheat). Headroom:
``reference/floor - 1`` with the reference the best open-loop agent; 95 % bootstrap CIs over the draws.

Writes ``experiments/results/suite_v2_dual_control.json`` and ``.md``. Bad arguments: one line, exit status 2.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from experiments.suite import common

TASK = "hyst_gym/DualControl-v0"
#: probe amplitudes (fraction of the field limit; the slew limit is 0.025 of it per step) and burst lengths (steps)
BURST_AMPLITUDES = (0.0025, 0.01, 0.025)
BURST_STEPS = (4, 10, 40)
#: the feedback rule's spread thresholds (std of a / width(Theta)) and amplitudes
UNSURE_THRESHOLDS = (0.02, 0.05)
UNSURE_AMPLITUDES = (0.0025, 0.01)
OUT = common.RESULTS


def play(agent, seeds, controller_estimate: str = "posterior") -> np.ndarray:
    """Per-draw mean square tracking error (%^2) of ``agent`` on ``seeds`` (one sub-env each): minus the
    episode's return, which the env makes the per-draw score (an overheat charges the steps left)."""
    from hyst_gym.envs.dual_control import DualControlVectorEnv

    seeds = [int(s) for s in seeds]
    env = DualControlVectorEnv(len(seeds), TASK, controller_estimate=controller_estimate)
    agent.reset(seeds[0])
    observations, _ = env.reset(seed=seeds)
    total = np.zeros(len(seeds))
    alive = np.ones(len(seeds), dtype=bool)
    start = np.ones(len(seeds), dtype=bool)
    for _ in range(env.config.episode_steps):
        actions, _ = agent.predict(observations, episode_start=start, deterministic=True)
        observations, reward, terminated, _, _ = env.step(np.asarray(actions, dtype=np.float32))
        start[:] = False
        total += np.where(alive, reward, 0.0)
        alive &= ~terminated
    return -total


def working_point(config, reference, probe_field: float = 250.0) -> dict:
    """What the measurement's explanation rests on, from model (6) on its initial curve (demagnetized start,
    rising field, the task's hysteresis at a(20 C)): the field H* where M reaches the reference's bias, the
    change of M at H* for a 1 % larger a, and for ``probe_field`` A/m more field (both in % of Ms)."""
    from hyst_gym.physics.hysteresis import advance_one

    hyst = config.hysteresis
    a = float(config.a_of(293.15))
    step = 50.0

    def curve(a_value, fields):
        m, h, out = 0.0, 0.0, []
        for target in fields:
            m, _ = advance_one(m, h, target, a_value, hyst.k, hyst.alpha, hyst.Ms, hyst.c, hyst.kind,
                               config.max_field_step)
            h = target
            out.append(m)
        return np.array(out)

    fields = np.arange(step, config.field_limit + step, step)
    magnetization = curve(a, fields)
    index = int(np.searchsorted(magnetization, reference.bias * hyst.Ms))
    h_star = float(fields[index])
    at = magnetization[index]
    wider = curve(1.01 * a, fields[:index + 1])[-1]
    probed = curve(a, np.append(fields[:index + 1], h_star + probe_field))[-1]
    return {"field_A_per_m": h_star, "magnetization_percent_Ms": 100.0 * at / hyst.Ms,
            "per_percent_of_a_percent_Ms": 100.0 * abs(wider - at) / hyst.Ms,
            "probe_field_A_per_m": probe_field, "probe_percent_Ms": 100.0 * abs(probed - at) / hyst.Ms,
            "alpha_Ms_over_a": hyst.alpha * hyst.Ms / a}


def rms(scores) -> float:
    return float(np.sqrt(np.mean(scores)))


def tuned(candidates: dict, tuning) -> tuple[str, dict]:
    """The candidate with the lowest RMS on the tuning draws, and every candidate's tuning RMS."""
    scores = {name: rms(play(agent, tuning)) for name, agent in candidates.items()}
    return min(scores, key=scores.get), scores


def measure(heldout: int, tuning: int, n_boot: int, log=print) -> dict:
    from baselines.dual_control_agents import ProbeBurst, ProbeWhileUnsure
    from baselines.scenarios import HELDOUT_SEEDS, TUNING_SEEDS
    from experiments.suite.v2 import bootstrap
    from hyst_gym.envs.dual_control import DualControlVectorEnv

    start = time.time()
    tune, held = TUNING_SEEDS[:tuning], HELDOUT_SEEDS[:heldout]
    spread = DualControlVectorEnv(1, TASK).observation_names.index("estimate_spread")
    bursts = {f"probe_{a:g}x{s}": ProbeBurst(a, s) for a in BURST_AMPLITUDES for s in BURST_STEPS}
    unsure = {f"unsure_{a:g}_{t:g}": ProbeWhileUnsure(spread, t, a) for a in UNSURE_AMPLITUDES
              for t in UNSURE_THRESHOLDS}
    burst_pick, burst_tuning = tuned(bursts, tune)
    unsure_pick, unsure_tuning = tuned(unsure, tune)
    log(f"[dual control] tuned: {burst_pick} (open loop), {unsure_pick} (feedback) ({time.time() - start:.0f} s)")
    scores = {"no_probe": ("open_loop", play(ProbeBurst(0.0, 0), held)),
              "probe_burst": ("open_loop", play(bursts[burst_pick], held)),
              "probe_while_unsure": ("feedback", play(unsure[unsure_pick], held)),
              "nominal_a": ("context", play(ProbeBurst(0.0, 0), held, "nominal"))}
    floor = play(ProbeBurst(0.0, 0), held, "true")
    agents = {}
    for name, (kind, per_draw) in scores.items():
        value, ci = bootstrap(rms_of_matrix, n_boot, per_draw)
        agents[name] = {"rms": value, "ci": ci, "kind": kind, "per_draw": per_draw.tolist()}
    floor_value, floor_ci = bootstrap(rms_of_matrix, n_boot, floor)
    reference = min((n for n, a in agents.items() if a["kind"] == "open_loop"), key=lambda n: agents[n]["rms"])
    headroom = bootstrap(rms_of_matrix, n_boot, scores[reference][1], floor, combine=lambda r, f: r / f - 1.0)
    probing = ("probe_burst", "probe_while_unsure")
    verdict = {"probing_pays": bool(any(agents[n]["ci"][1] < agents["no_probe"]["ci"][0] for n in probing)),
               "probing_loses": bool(all(agents[n]["ci"][0] > agents["no_probe"]["ci"][1] for n in probing)),
               # how much of what knowing a is worth (nominal a -> true a) the estimator learns with no probe
               "passive_share": (agents["nominal_a"]["rms"] - agents["no_probe"]["rms"])
               / (agents["nominal_a"]["rms"] - floor_value)}
    env = DualControlVectorEnv(1, TASK)
    verdict["working_point"] = working_point(env.config, env.reference)
    return {"task": TASK, "statistic": "rms", "verdict": verdict, "unit": "% of y(Ms)", "heldout_draws": heldout,
            "tuning_draws": tuning,
            "floor": {"kind": "oracle", "rms": floor_value, "ci": floor_ci, "per_draw": floor.tolist(),
                      "how": "the same controller fed the true a, no probe (an oracle, not a bound)"},
            "agents": agents, "reference": reference,
            "headroom": {"value": headroom[0], "ci": headroom[1], "target": common.HEADROOM_TARGET},
            "tuning": {"probe_burst": burst_tuning, "probe_while_unsure": unsure_tuning,
                       "picked": {"probe_burst": burst_pick, "probe_while_unsure": unsure_pick}},
            "wall_s": round(time.time() - start, 1)}


def rms_of_matrix(matrix) -> float:
    return float(np.sqrt(np.mean(matrix)))


def markdown(data: dict) -> str:
    floor = data["floor"]
    lines = [f"## Dual control measured: `{data['task']}`", "",
             f"RMS tracking error over the 200 steps and {data['heldout_draws']} held-out draws, % of y(Ms) "
             f"(95 % bootstrap CI). Rerun: `{data['command']}`.", "",
             "| agent (kind) | RMS [CI] |", "|---|---|"]
    for name, entry in data["agents"].items():
        lines.append(f"| {name} ({entry['kind']}) | {entry['rms']:.4f} [{entry['ci'][0]:.4f}, {entry['ci'][1]:.4f}] |")
    lines.append(f"| floor: {floor['how']} | {floor['rms']:.4f} [{floor['ci'][0]:.4f}, {floor['ci'][1]:.4f}] |")
    head = data["headroom"]
    picked = data["tuning"]["picked"]
    verdict = data["verdict"]
    point = verdict["working_point"]
    lines += ["", f"Reference (best open-loop agent): {data['reference']}; headroom over the oracle "
                  f"{100 * head['value']:.0f} % [{100 * head['ci'][0]:.0f}, {100 * head['ci'][1]:.0f}]. "
                  f"Tuned on {data['tuning_draws']} tuning draws: probe burst {picked['probe_burst']}, "
                  f"feedback rule {picked['probe_while_unsure']}.", "",
              f"Probing pays (a probing agent's CI below no_probe's): {'yes' if verdict['probing_pays'] else 'no'}; "
              f"every probing agent's CI above no_probe's: {'yes' if verdict['probing_loses'] else 'no'}. "
              f"With no probe the estimator recovers {100 * verdict['passive_share']:.0f} % of what knowing a is "
              "worth (RMS from nominal_a down to the oracle).", "",
              f"Model (6) on its initial curve at a(20 C) (alpha*Ms/a = {point['alpha_Ms_over_a']:.1f}): M reaches "
              f"the stroke's bias ({point['magnetization_percent_Ms']:.1f} % of Ms) at "
              f"{point['field_A_per_m']:.0f} A/m; there a 1 % larger a moves M by "
              f"{point['per_percent_of_a_percent_Ms']:.3f} % of Ms, and {point['probe_field_A_per_m']:.0f} A/m "
              f"more field by {point['probe_percent_Ms']:.3f} % of Ms.", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    return common.measurement_main("dual_control", __doc__, measure, markdown, argv, heldout=24)


if __name__ == "__main__":
    sys.exit(main())
