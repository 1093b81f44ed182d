"""Is the direct design's search budget enough? Search it at a budget and at three times that budget and
compare their scores on the held-out draws (the design is flat in its budget when tripling changes its
score by less than :data:`FLAT_CHANGE`).

    python -m experiments.suite.direct_budget [--tasks ID,ID] [--evaluations N] [--tuning N] [--heldout N]
                                              [--hottest-safe] [--out experiments/results/suite_direct_budget.json]

For each calibration task: CMA-ES over a 9-knot field (:func:`experiments.suite.common.direct_design`) on the
first ``--tuning`` tuning draws at ``N`` and ``3 N`` evaluations; both designs are played on the first
``--heldout`` held-out draws with the task's estimator in the loop; the JSON holds each score (RMS, A/m),
the relative change and whether it is below 2 %. ``--hottest-safe``: the search keeps to inputs that take the
prior's hottest start no closer than 1 K to the limit. Bad arguments: one line, exit status 2.
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

#: tripling the budget must change the held-out score by less than this fraction
FLAT_CHANGE = 0.02
OUT = common.RESULTS / "suite_direct_budget.json"


def budget_check(task_id: str, evaluations: int, tuning: int, heldout: int, log=print,
                 hottest_safe: bool = False) -> dict:
    """The direct design of ``task_id`` searched at ``evaluations`` and 3x that, scored on held-out draws."""
    from baselines.scenarios import HELDOUT_SEEDS, TUNING_SEEDS
    from baselines.suite_agents import Design

    task = task_kind(task_id)
    rows = {}
    for budget in (evaluations, 3 * evaluations):
        start = time.time()
        schedule = common.direct_design(task, TUNING_SEEDS[:tuning], budget, hottest_safe=hottest_safe)
        tuned = task.statistic(common.play(task.design_agent([Design("d", schedule)]), task,
                                           TUNING_SEEDS[:tuning])[0][None, :])
        scores = common.play(task.design_agent([Design("d", schedule)]), task, HELDOUT_SEEDS[:heldout])[0]
        rows[str(budget)] = {"evaluations": budget, "tuning_score": tuned,
                             "heldout_score": task.statistic(scores[None, :]), "knots": list(schedule.knots),
                             "wall_s": round(time.time() - start, 1)}
        log(f"[direct budget] {task_id}: {budget} evaluations: held-out {rows[str(budget)]['heldout_score']:.3f} "
            f"A/m ({rows[str(budget)]['wall_s']:.0f} s)")
    low, high = rows[str(evaluations)]["heldout_score"], rows[str(3 * evaluations)]["heldout_score"]
    change = abs(high - low) / low
    return {"statistic": task.statistic_name, "budgets": rows, "relative_change": change,
            "flat": bool(change < FLAT_CHANGE)}


def main(argv=None) -> int:
    from hyst_gym.envs.tasks import TASKS

    parser = OneLineParser(prog="python -m experiments.suite.direct_budget", description=__doc__.split("\n")[0])
    parser.add_argument("--tasks", default="hyst_gym/HotCalibrate-v0")
    parser.add_argument("--evaluations", type=int, default=40)
    parser.add_argument("--tuning", type=int, default=10)
    parser.add_argument("--heldout", type=int, default=16)
    parser.add_argument("--hottest-safe", action="store_true", help="search only inputs that keep the prior's "
                        "hottest start 1 K below the limit (common.direct_design's hottest_safe)")
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args(argv)
    task_ids = [t.strip() for t in args.tasks.split(",") if t.strip()]
    bad = [t for t in task_ids if t not in TASKS or not TASKS[t].calibrates]
    if bad or not task_ids or min(args.evaluations, args.tuning, args.heldout) < 1:
        print(f"direct_budget: error: --tasks must name calibration tasks (got {bad or task_ids}) and --evaluations, "
              "--tuning, --heldout must be >= 1", file=sys.stderr)
        return 2
    start = time.time()
    data = {"command": "python -m experiments.suite.direct_budget " + " ".join(sys.argv[1:] if argv is None else argv),
            "flat_change": FLAT_CHANGE, "tuning_draws": args.tuning, "heldout_draws": args.heldout,
            "hottest_safe": args.hottest_safe,
            "tasks": {task: budget_check(task, args.evaluations, args.tuning, args.heldout,
                                         hottest_safe=args.hottest_safe) for task in task_ids}}
    data["wall_s"] = round(time.time() - start, 1)
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=1, default=lambda x: float(x) if isinstance(x, np.floating) else x))
    print(f"[direct budget] wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
