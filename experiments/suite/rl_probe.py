"""A small RL probe of a calibration task with the estimator in the loop: PPO (the suite's training settings,
:func:`experiments.suite.v2.train_one`) at a budget and at three times that budget, one seed, scored on
held-out draws. A reduced measurement: it says whether PPO, which now designs the field only, comes near
the task's references at these budgets, not what a flattened RL configuration reaches.

    python -m experiments.suite.rl_probe [--task ID] [--steps N] [--seed S] [--heldout N]
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


def probe(task_id: str, steps: int, seed: int, heldout: int, raw: pathlib.Path = RAW, log=print) -> dict:
    """PPO on ``task_id`` at ``steps`` and ``3*steps`` env steps (seed ``seed``), each scored on held-out draws."""
    from baselines.rl import PolicyAgent
    from baselines.scenarios import HELDOUT_SEEDS
    from experiments.suite import v2

    task = task_kind(task_id)
    rows = {}
    for budget in (steps, 3 * steps):
        start = time.time()
        v2.train_one(task_id, "ppo", seed, budget, raw, log)
        folder = v2.model_dir(task_id, "ppo", seed, budget, raw)
        scores = common.play(PolicyAgent.load(folder), task, HELDOUT_SEEDS[:heldout])[0]
        rows[str(budget)] = {"env_steps": budget, task.statistic_name: task.statistic(scores[None, :]),
                             "per_draw": scores.tolist(), "wall_s": round(time.time() - start, 1)}
        log(f"[rl probe] {task_id}: ppo x {budget:,} steps: {task.statistic_name} "
            f"{rows[str(budget)][task.statistic_name]:.2f} A/m")
    return {"algo": "ppo", "seed": seed, "statistic": task.statistic_name, "budgets": rows}


def main(argv=None) -> int:
    from hyst_gym.envs.tasks import TASKS

    parser = OneLineParser(prog="python -m experiments.suite.rl_probe", description=__doc__.split("\n")[0])
    parser.add_argument("--task", default="hyst_gym/HotCalibrate-v0")
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--heldout", type=int, default=16)
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args(argv)
    if args.task not in TASKS or not TASKS[args.task].calibrates or args.steps < 1 or args.heldout < 1:
        print(f"rl_probe: error: --task must be a calibration task (got {args.task!r}) and --steps, --heldout >= 1",
              file=sys.stderr)
        return 2
    start = time.time()
    data = {"command": "python -m experiments.suite.rl_probe " + " ".join(sys.argv[1:] if argv is None else argv),
            "track": "estimator in the loop", "heldout_draws": args.heldout,
            "task": args.task, **probe(args.task, args.steps, args.seed, args.heldout)}
    data["wall_s"] = round(time.time() - start, 1)
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=1, default=lambda x: float(x) if isinstance(x, np.floating) else x))
    print(f"[rl probe] wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
