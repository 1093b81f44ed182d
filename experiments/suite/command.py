"""``hyst-gym benchmark --suite v1|v2 [options]``: the command line of both suites.

    hyst-gym benchmark [--suite v1] [--quick] [--tasks ID,ID] [--out DIR] [--figure PATH] [--no-readme]
    hyst-gym benchmark --suite v2 [--quick | --reduced] [--tasks ID,ID] [--merge] [--out DIR] [--no-docs]
    python -m experiments.suite [same options]

Suite v1 (the sanity tier): :mod:`experiments.suite.v1`; suite v2: :mod:`experiments.suite.v2`.
"""

from __future__ import annotations

import pathlib
import sys

from experiments.suite.common import DOCS_PAGE, FIGURES, RESULTS, UsageError

PROFILE_FLAG = {"full": "", "quick": " --quick", "reduced": " --reduced"}


def configure_parser(parser) -> None:
    """The ``benchmark`` subcommand's options (v1's, and v2's ``--reduced``, ``--no-docs``, ``--merge``,
    ``--speed-only``)."""
    parser.add_argument("--suite", default="v1", help="suite version: v1 (default, the sanity tier) or v2")
    parser.add_argument("--quick", action="store_true",
                        help="quick profile: 16 held-out draws, small design searches, committed RL models, no "
                             "docs edit (writes suite_v1_quick.* or suite_v2_quick.*)")
    parser.add_argument("--tasks", default="", help="comma list of task ids (default: the suite and, v1 only, "
                        "the rejected candidates; v1 quick: the suite)")
    parser.add_argument("--out", default=str(RESULTS), help="folder of the JSON and markdown results")
    parser.add_argument("--figure", default=None, help="figure path (default docs/figures/suite_vN[_PROFILE].png)")
    parser.add_argument("--no-readme", action="store_true",
                        help="v1: do not rewrite the suite-v1 section of docs/results/suite.md")
    parser.add_argument("--reduced", action="store_true", help="v2 only: the reduced-budget measurement "
                        "(24 draws, RL at small budgets, 3 seeds); writes suite_v2_reduced.*")
    parser.add_argument("--no-docs", action="store_true", help="v2 only: do not rewrite the suite-v2 section of "
                        "docs/results/suite.md (the full and reduced profiles write it)")
    parser.add_argument("--docs", action="store_true", help="v2 --quick only: write the quick profile's own "
                        "section (suite-v2-quick) of docs/results/suite.md")
    parser.add_argument("--merge", action="store_true", help="v2 only: keep the other tasks of the profile's "
                        "stored JSON (same settings) and replace or add only the --tasks of this run")
    parser.add_argument("--speed-only", action="store_true", help="v2 only: train and evaluate nothing; re-measure "
                        "the env speed of the tasks in the profile's stored JSON and rewrite its JSON, table and page "
                        "section (the speed measured beside training is low)")


def _task_ids(args, suite: str, default: list) -> list:
    from hyst_gym.envs.tasks import suite_ids

    known = suite_ids(suite)
    if not args.tasks:
        return default
    task_ids = [t.strip() for t in args.tasks.split(",") if t.strip()]
    unknown = [t for t in task_ids if t not in known]
    if unknown or not task_ids:
        raise UsageError(f"--tasks: unknown {suite} task id(s) {unknown or args.tasks!r}; expected some of "
                         f"{sorted(known)}")
    return task_ids


def _v1_options(args):
    from experiments.suite import v1
    from hyst_gym.envs.suite_v1 import TASKS, suite_tasks

    if args.reduced or args.no_docs or args.speed_only or args.merge or args.docs:
        raise UsageError("--reduced, --no-docs, --docs, --merge and --speed-only are options of --suite v2")
    profile = v1.PROFILES["quick" if args.quick else "full"]
    default = list(suite_tasks()) + ([] if args.quick else [t for t in TASKS if t not in suite_tasks()])
    task_ids = _task_ids(args, "v1", default)
    stem = "suite_v1" if profile.name == "full" else f"suite_v1_{profile.name}"
    figure_path = pathlib.Path(args.figure) if args.figure else FIGURES / f"{stem}.png"
    readme = None if (args.no_readme or args.quick) else DOCS_PAGE
    return profile, task_ids, pathlib.Path(args.out), figure_path, readme


def _v2_options(args):
    from experiments.suite import v2
    from hyst_gym.envs.tasks import suite_ids

    if args.quick and args.reduced:
        raise UsageError("--quick and --reduced exclude each other")
    profile = v2.PROFILES["quick" if args.quick else "reduced" if args.reduced else "full"]
    from hyst_gym.envs.tasks import TASKS

    task_ids = _task_ids(args, "v2", [t for t in suite_ids("v2") if not TASKS[t].rejected])
    own = [t for t in task_ids if TASKS[t].kind in ("dual_control", "discriminate")]
    if own:
        raise UsageError(f"--tasks: {', '.join(own)} is measured by its own script (python -m "
                         f"experiments.suite.{TASKS[own[0]].kind}), not by the suite's harness")
    stem = "suite_v2" if profile.name == "full" else f"suite_v2_{profile.name}"
    figure_path = pathlib.Path(args.figure) if args.figure else FIGURES / f"{stem}.png"
    if args.docs and profile.name != "quick":
        raise UsageError("--docs is an option of --suite v2 --quick (the full and reduced profiles write the page)")
    # the reduced profile writes the page while the full one has not been run; the quick one only with --docs
    docs = None if args.no_docs or (profile.name == "quick" and not args.docs) else DOCS_PAGE
    return profile, task_ids, pathlib.Path(args.out), figure_path, docs


def _run_v1(args) -> int:
    from experiments.suite import v1

    profile, task_ids, out, figure_path, readme = _v1_options(args)
    v1.run_suite(profile, task_ids, out, figure_path, readme=readme)
    return 0


def _run_v2(args) -> int:
    from experiments.suite import v2

    profile, task_ids, out, figure_path, docs = _v2_options(args)
    if args.speed_only:
        stem = "suite_v2" if profile.name == "full" else f"suite_v2_{profile.name}"
        path = out / f"{stem}.json"
        if not path.is_file():
            raise UsageError(f"--speed-only: no stored {path} (run the profile first)")
        v2.remeasure_speed(path, figure_path, docs,
                           "hyst-gym benchmark --suite v2 --speed-only" + PROFILE_FLAG[profile.name])
        return 0
    try:
        v2.run_suite(profile, task_ids, out, figure_path, docs=docs, merge=args.merge,
                     docs_area="suite-v2-quick" if profile.name == "quick" else v2.DOCS_AREA)
    except ValueError as error:
        if not str(error).startswith("merge:"):
            raise
        raise UsageError(f"--{error}") from None
    return 0


def main(args) -> int:
    runs = {"v1": _run_v1, "v2": _run_v2}
    try:
        if args.suite not in runs:
            raise UsageError(f"--suite: unknown suite version {args.suite!r}; expected 'v1' or 'v2'")
        return runs[args.suite](args)
    except UsageError as error:
        print(f"hyst-gym benchmark: error: {error}", file=sys.stderr)
        return 2
