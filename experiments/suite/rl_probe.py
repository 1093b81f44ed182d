"""A small RL probe of a calibration task with the estimator in the loop: PPO (the suite's training settings,
:func:`experiments.suite.v2.train_one`) at a budget and at three times that budget, a few seeds, scored on
held-out draws, next to the task's references (``ramp_hold``, ``bang_hold``: tuned on the tuning draws,
played on the same held-out draws). A reduced measurement: it says whether PPO, which designs the field only
and sees the estimator's estimate and spread and the coil's heat state, comes near the references at these
budgets, not what a flattened RL configuration reaches. The same PPO without the heat state
(``heat_state=False``) is the ablation: what that observation entry is worth.

    python -m experiments.suite.rl_probe [--task ID] [--steps N] [--seeds S,S] [--heldout N]
                                         [--out experiments/results/suite_v2_rl_probe.json]

Models go to ``experiments/results/raw/suite_v2/probe/`` (ignored by git, like the suite's reduced models).
Bad arguments: one line, exit status 2.
"""

from __future__ import annotations

import json
import pathlib
import sys
import time

import numpy as np

from experiments.suite import common
from experiments.suite.common import OneLineParser
from experiments.suite.kinds import task_kind

OUT = common.RESULTS / "suite_v2_rl_probe.json"
RAW = common.RESULTS / "raw" / "suite_v2" / "probe"


def _budgets(task, steps: int, seeds, draws, raw: pathlib.Path, log, env_kwargs: dict) -> dict:
    """PPO at ``steps`` and ``3*steps`` for each seed, scored on ``draws``: per budget each seed's statistic,
    per-draw scores and overheated draws, and the statistic over every seed's draws."""
    from baselines.rl import PolicyAgent
    from experiments.suite import v2

    stat = task.statistic_name
    rows = {}
    for budget in (steps, 3 * steps):
        per_seed = {}
        for seed in seeds:
            start = time.time()
            v2.train_one(task.id, "ppo", seed, budget, raw, log, env_kwargs)
            folder = v2.model_dir(task.id, "ppo", seed, budget, raw)
            scores, _, traces = common.play(PolicyAgent.load(folder), task, draws, overrides=env_kwargs,
                                            keep_trace=True)
            # the trace holds the overheating step's temperature (past the limit), then nan
            overheated = int(np.sum(np.nanmax(traces["temperature"], axis=0) > task.config.temperature_limit))
            per_seed[str(seed)] = {stat: task.statistic(scores[None, :]), "per_draw": scores.tolist(),
                                   "overheated_draws": overheated, "wall_s": round(time.time() - start, 1)}
            log(f"[rl probe] {task.id} {env_kwargs or ''}: ppo seed {seed} x {budget:,} steps: {stat} "
                f"{per_seed[str(seed)][stat]:.2f} A/m, {overheated} of {len(draws)} draws overheated")
        matrix = np.array([entry["per_draw"] for entry in per_seed.values()])
        rows[str(budget)] = {"env_steps": budget, stat: task.statistic(matrix), "seeds": per_seed}
    return rows


def probe(task_id: str, steps: int, seeds, heldout: int, raw: pathlib.Path = RAW, log=print) -> dict:
    """PPO on ``task_id`` at ``steps`` and ``3*steps`` env steps (each of ``seeds``), each model scored on held-out
    draws; the same without the heat state in the observation (``heat_state=False``, the ablation); the
    references played on the same draws."""
    from baselines.scenarios import HELDOUT_SEEDS, TUNING_SEEDS

    task = task_kind(task_id)
    draws = HELDOUT_SEEDS[:heldout]
    stat = task.statistic_name
    rows = _budgets(task, steps, seeds, draws, raw, log, {})
    ablation = _budgets(task, steps, seeds, draws, raw / "without_heat_state", log, {"heat_state": False})
    references, tuned = task.reference_agents(TUNING_SEEDS[:10], draws, log)
    refs = {name: {"kind": kind, "tuned": tuned[name], stat: task.statistic(np.asarray(scores)[None, :]),
                   "per_draw": np.asarray(scores).tolist()} for name, (kind, scores) in references.items()}
    return {"algo": "ppo", "seeds": list(seeds), "statistic": stat, "budgets": rows,
            "without_heat_state": {"env_kwargs": {"heat_state": False}, "budgets": ablation}, "references": refs}


def main(argv=None) -> int:
    import gymnasium

    import hyst_gym  # noqa: F401
    from hyst_gym.envs.tasks import TASKS

    parser = OneLineParser(prog="python -m experiments.suite.rl_probe", description=__doc__.split("\n")[0])
    parser.add_argument("--task", default="hyst_gym/HotCalibrate-v0")
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--heldout", type=int, default=16)
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args(argv)
    try:
        seeds = [int(seed) for seed in args.seeds.split(",")]
    except ValueError:
        seeds = []
    if args.task not in TASKS or not TASKS[args.task].calibrates or args.steps < 1 or args.heldout < 1 or not seeds:
        print(f"rl_probe: error: --task must be a calibration task (got {args.task!r}), --steps, --heldout >= 1 and "
              f"--seeds integers separated by commas (got {args.seeds!r})", file=sys.stderr)
        return 2
    start = time.time()
    data = {"command": "python -m experiments.suite.rl_probe " + " ".join(sys.argv[1:] if argv is None else argv),
            "track": "estimator in the loop", "observation": gymnasium.make(args.task).unwrapped.observation_names,
            "heldout_draws": args.heldout, "task": args.task, **probe(args.task, args.steps, seeds, args.heldout)}
    data["wall_s"] = round(time.time() - start, 1)
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=1, default=lambda x: float(x) if isinstance(x, np.floating) else x))
    print(f"[rl probe] wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
