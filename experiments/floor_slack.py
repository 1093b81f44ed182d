"""Why the displacement-only task's best agent sat further above its floor than the others'.

The heated Van Trees floor of ``hyst_gym/DisplacementOnly-v0`` equals that of ``HotCalibrateNoisy-v0``
(``experiments/results/floors.json``), and in the committed reduced profile the same best agent (the
thermostat, with the same tuned settings) scored 1.24x that floor on the noisy task and 1.83x on the
displacement-only one. This script checks the candidate reasons:

* the plants: the output gain ``G`` the bound uses (l1 norm of the normalized output's response to M), the
  sensor noise, and how fast the lumped transducer's mechanics settle against the sample time (if they settle
  within a step, the displacement is a scaled copy of M at the sample rate and carries what the first-order
  output does);
* the agents: the committed best agent (the thermostat) and the reference (the sized ramp-and-hold), at
  their committed tuned settings (read from ``experiments/results/suite_v2_reduced.json``), replayed on the
  committed held-out draws (reproducing the committed scores) and then on many fresh draws, each seed played
  on every task (same start temperature per seed), with bootstrap intervals of the RMS, of its ratio to the
  floor and of the paired difference between the two tasks;
* the sampling: the RMS of disjoint subsets of as many draws as the reduced profile used, and how often
  such a subset puts the agent above 1.6x the floor.

Writes ``experiments/results/floor_slack.json``.

    python -m experiments.floor_slack                         # 4096 fresh draws per task (the committed JSON)
    python -m experiments.floor_slack --draws 16 --subset 4 --boot 50 --out /tmp/slack.json

Bad arguments give a one-line error and exit status 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
SUITE_RESULTS = RESULTS / "suite_v2_reduced.json"
FLOORS = RESULTS / "floors.json"
OUT = RESULTS / "floor_slack.json"
#: the two tasks that share a floor (same gain, noise and heat budget), the displacement-only one second
PAIR = ("hyst_gym/HotCalibrateNoisy-v0", "hyst_gym/DisplacementOnly-v0")
#: the other calibration tasks, for the same ratio at many draws
OTHERS = ("hyst_gym/HotCalibrate-v0", "hyst_gym/HotCalibrateUnknownK-v0")
#: fresh draws start here (the suite's held-out seeds are 100,000..., tuning 300,000...)
FRESH_SEED = 500_000
TARGET_RATIO = 1.6


def plant_checks(task_id: str) -> dict:
    """The bound's view of a task's output: G, the noise, and the largest pole of the discretized transducer
    (|eig(phi)|: what of a step's response is left one sample later)."""
    from hyst_gym.envs.suite_v2 import output_gain, task_config_v2

    config = task_config_v2(task_id)
    model = config.transducer.discretize(config.dt)
    poles = np.abs(np.linalg.eigvals(np.atleast_2d(model.phi)))
    record = {"transducer": repr(config.transducer), "dt": float(config.dt),
              "output_gain_G": float(output_gain(config)), "output_noise": float(config.output_noise),
              "largest_pole_per_step": float(poles.max())}
    stiffness = getattr(config.transducer, "stiffness", None)
    if stiffness is not None:  # the lumped mechanics x'' + damping x' + stiffness x = coupling M
        record["resonance_hz"] = float(np.sqrt(stiffness) / (2.0 * np.pi))
        record["damping_ratio"] = float(config.transducer.damping / (2.0 * np.sqrt(stiffness)))
    return record


def agents_of(task, tuned: dict) -> dict:
    """name -> agent: the committed tuned thermostat and ramp-and-hold of a task."""
    from baselines.references import ramp_hold
    from baselines.suite_agents import Design
    from experiments.suite import common

    family = {design.name: design for design in common.design_family()}
    peak = float(tuned["ramp_hold"].split("_")[-1])
    return {"thermostat": task.design_agent([family[tuned["thermostat"]]]),
            "ramp_hold": task.design_agent([Design(tuned["ramp_hold"], ramp_hold(task.config, peak))])}


def run(draws: int, subset: int, n_boot: int, tasks) -> dict:
    """Intervals: the suite's bootstrap (:func:`experiments.suite.v2.bootstrap`, draws resampled jointly across
    the two tasks for the paired difference)."""
    from experiments.suite import common
    from experiments.suite.kinds import task_kind
    from experiments.suite.v2 import bootstrap

    suite = json.loads(SUITE_RESULTS.read_text())
    floors = json.loads(FLOORS.read_text())["tasks"]
    heldout = [int(s) for s in suite["seeds"]["heldout"]]
    fresh = list(range(FRESH_SEED, FRESH_SEED + draws))
    record = {"plants": {task_id: plant_checks(task_id) for task_id in PAIR}, "tasks": {}}
    per_seed = {}
    for task_id in tasks:
        entry = suite["tasks"][task_id]
        floor = floors[task_id]["value"]
        task = task_kind(task_id)
        out = {"floor": floor, "tuned": {k: entry["tuned"][k] for k in ("thermostat", "ramp_hold")}, "agents": {}}
        for name, agent in agents_of(task, entry["tuned"]).items():
            started = time.time()
            replay, draws_held, _ = common.play(agent, task, heldout)
            scores, draws_fresh, _ = common.play(agent, task, fresh)
            per_seed[(task_id, name)] = (scores, np.asarray(draws_fresh["temperature"]))
            rms, ci = bootstrap(task.statistic, n_boot, scores)
            usable = (draws // subset) * subset
            subsets = np.sqrt(scores[:usable].reshape(-1, subset).mean(axis=1)) / floor
            out["agents"][name] = {
                "committed_rms": entry["agents"][name]["rms"], "committed_ci": entry["agents"][name]["ci"],
                "replayed_heldout_rms": float(np.sqrt(replay.mean())), "heldout_draws": len(heldout),
                "fresh_draws": draws, "rms": rms, "ci": ci, "over_floor": rms / floor,
                "over_floor_ci": [ci[0] / floor, ci[1] / floor],
                "committed_over_floor": entry["agents"][name]["rms"] / floor,
                f"subsets_of_{subset}": {"count": int(subsets.size),
                                         "over_floor_min_median_max": [float(subsets.min()), float(np.median(subsets)),
                                                                       float(subsets.max())],
                                         f"share_above_{TARGET_RATIO}": float(np.mean(subsets > TARGET_RATIO))},
                "wall_s": round(time.time() - started, 1)}
        record["tasks"][task_id] = out
    if all(task_id in tasks for task_id in PAIR):
        paired = {}
        statistic = task_kind(PAIR[0]).statistic
        for name in ("thermostat", "ramp_hold"):
            first, t_first = per_seed[(PAIR[0], name)]
            second, t_second = per_seed[(PAIR[1], name)]
            difference, difference_ci = bootstrap(statistic, n_boot, second, first, combine=lambda a, b: a - b)
            paired[name] = {"same_start_temperatures": bool(np.allclose(t_first, t_second)),
                            "rms_difference": difference, "rms_difference_ci": difference_ci,
                            "per_draw_error_correlation": float(np.corrcoef(np.sqrt(first), np.sqrt(second))[0, 1])}
        record["paired_displacement_minus_noisy"] = paired
    return record


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.floor_slack", description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=4096, help="fresh draws per task and agent (>= 2)")
    parser.add_argument("--subset", type=int, default=24, help="draws per subset (the reduced profile's 24)")
    parser.add_argument("--boot", type=int, default=2000, help="bootstrap resamples")
    parser.add_argument("--pair-only", action="store_true", help="only the two tasks that share a floor")
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args(argv)
    if args.draws < 2 or not 1 <= args.subset <= args.draws or args.boot < 10:
        print(f"error: need --draws >= 2, 1 <= --subset <= --draws and --boot >= 10, got {args.draws}, "
              f"{args.subset}, {args.boot}", file=sys.stderr)
        return 2
    started = time.time()
    tasks = PAIR if args.pair_only else PAIR + OTHERS
    record = run(args.draws, args.subset, args.boot, tasks)
    record["meta"] = {"draws": args.draws, "fresh_seeds_from": FRESH_SEED, "subset": args.subset,
                      "boot": args.boot, "wall_s": round(time.time() - started, 1)}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=1) + "\n")
    for task_id, entry in record["tasks"].items():
        for name, agent in entry["agents"].items():
            print(f"{task_id} {name}: {agent['rms']:.2f} [{agent['ci'][0]:.2f}, {agent['ci'][1]:.2f}] = "
                  f"{agent['over_floor']:.2f}x the floor (committed {agent['committed_over_floor']:.2f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
