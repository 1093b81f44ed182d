"""The project's speed and accuracy targets, in one place, each checked against its committed measurement.

    python -m experiments.targets            # rewrite the table in docs/targets.md
    python -m experiments.targets --print    # print it only

Every target names the committed file that holds its measurement and the command that rewrites
that file; this module only reads them (it measures nothing). The table on the documentation
site (``docs/targets.md``, between its ``<!-- section:targets -->`` markers) is what
:func:`markdown_table` writes, and ``tests/test_docs_sections.py`` fails when the page differs
from it, so a new measurement or a changed target shows up as met or not met on the next run.

Modules that state a target read it from here (:data:`BY_KEY`); the ones the installed package
cannot import from (``hyst_gym.layer_speed``, ``hyst_gym.envs.step_speed``) are checked against it by
the same test.
"""

from __future__ import annotations

import argparse
import json
import pathlib
from dataclasses import dataclass

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results"
PAGE = ROOT / "docs" / "targets.md"
AREA = "targets"


@dataclass(frozen=True)
class Target:
    """One target: ``measured`` must be at least (``at_least``) or at most (``at_most``) ``bound``.

    ``unit`` is the unit of ``bound`` and of the measurement; ``source`` is the committed file
    (relative to the repository root) that holds the measurement, ``command`` the command that
    rewrites it."""

    key: str
    area: str
    what: str
    sense: str
    bound: float
    unit: str
    source: str
    command: str

    def met(self, measured: float) -> bool:
        return measured >= self.bound if self.sense == "at_least" else measured <= self.bound

    def stated(self) -> str:
        sign = "≥" if self.sense == "at_least" else "≤"
        return f"{sign} {_number(self.bound)} {self.unit}".rstrip()


BENCH = "docs/bench.md"
BENCH_COMMAND = "hyst-gym bench --markdown docs/bench.md --page docs/speed.md"
SUITES = ("experiments/results/suite_v1.json", "experiments/results/suite_v2_reduced.json")
SUITE_COMMAND = "hyst-gym benchmark --suite v1; hyst-gym benchmark --suite v2 --speed-only --reduced"

TARGETS = (
    Target("env_single", "speed", "`Excitation-v0`, one env (`gymnasium.make`, wrappers included)", "at_least",
           5_000, "steps/s", BENCH, BENCH_COMMAND),
    Target("env_vector_1024", "speed", "`Excitation-v0`, native vector env, n = 1024", "at_least",
           100_000, "steps/s", BENCH, BENCH_COMMAND),
    Target("suite_single", "speed", "every suite task, one env (the slowest task)", "at_least",
           20_000, "steps/s", ", ".join(SUITES), SUITE_COMMAND),
    Target("suite_vector_1024", "speed", "every suite task, native vector env, n = 1024 (the slowest task)",
           "at_least", 200_000, "steps/s", ", ".join(SUITES), SUITE_COMMAND),
    Target("first_step_install", "speed", "`import` to the first `env.step` after installing the wheel "
           "(fresh venv, empty numba cache)", "at_most", 5.0, "s",
           "experiments/results/first_step_time.json", "python -m experiments.first_step_time"),
    Target("first_step_cached", "speed", "`import` to the first `env.step`, later runs (compiled kernels cached)",
           "at_most", 1.0, "s", "experiments/results/first_step_time.json", "python -m experiments.first_step_time"),
    Target("diagnose_20000", "speed", "`hyst-gym diagnose` of one 20,000-sample recording, alone (the slowest "
           "of the study's slowest recordings)", "at_most", 20.0, "s",
           "experiments/results/diagnose/speed_20000.json",
           "python -m experiments.diagnose_speed --samples 20000 --page docs/speed.md"),
    Target("next_drive_20000", "speed", "designing the next drive (`diagnose --next-drive`) for a 20,000-sample "
           "recording (the slowest of the own generator's study cases)", "at_most", 30.0, "s",
           "experiments/results/diagnose/next_drive_speed.json", "python -m experiments.next_drive_speed"),
    Target("pe_prediction_auc", "accuracy", "the best persistent-excitation test predicts settling: AUC over all "
           "episodes", "at_least", 0.9, "", "experiments/results/pe_prediction.json",
           "python -m experiments.pe_prediction"),
    Target("paper_settle_half_ramp", "accuracy", "paper scenario: best RL settle-time IQM over the ramp's",
           "at_most", 0.5, "", "experiments/results/details.json", "python -m experiments.report"),
    Target("drift_rms_half_best_schedule", "accuracy", "drift scenario: best RL RMS-error IQM over the best "
           "schedule's", "at_most", 0.5, "", "experiments/results/details.json", "python -m experiments.report"),
)

OTHER_FORMS = "experiments/results/diagnose/other_forms.json"
OTHER_FORMS_COMMAND = "python -m experiments.diagnose_other_forms --seeds 5 --jobs 2 --page docs/results/diagnose.md"
COLOURED = "experiments/results/diagnose/other_forms_coloured_none.json"
COLOURED_COMMAND = ("python -m experiments.diagnose_other_forms --cases none_other_numerics --seeds 5 "
                    "--noise coloured --jobs 2 --out experiments/results/diagnose/other_forms_coloured_none "
                    "--page docs/results/diagnose.md")
NEXT_DRIVE = "experiments/results/diagnose/next_drive.json"
NEXT_DRIVE_COMMAND = "python -m experiments.diagnose_next_drive"

#: The mismatch tool's accuracy on recordings whose forms and numerics the project did not write (the
#: other-forms generator), per channel set: the worst channel set is the measurement.
DIAGNOSE_TARGETS = (
    Target("other_forms_right", "accuracy", "mismatch tool, physics in other forms (effect recordings): right "
           "(the effect's slot), the worst channel set", "at_least", 90, "%", OTHER_FORMS, OTHER_FORMS_COMMAND),
    Target("other_forms_right_or_tied", "accuracy", "mismatch tool, physics in other forms (effect recordings): "
           "right, or `ambiguous` containing the truth, the worst channel set", "at_least", 97, "%",
           OTHER_FORMS, OTHER_FORMS_COMMAND),
    Target("other_forms_wrong_names", "accuracy", "mismatch tool, physics in other forms (effect recordings): "
           "wrong single names, the worst channel set", "at_most", 3, "%", OTHER_FORMS, OTHER_FORMS_COMMAND),
    Target("none_false_alarms_white", "accuracy", "mismatch tool: `none` false alarms, white noise (other "
           "numerics), the worst channel set", "at_most", 5, "%", OTHER_FORMS, OTHER_FORMS_COMMAND),
    Target("none_false_alarms_coloured", "accuracy", "mismatch tool: `none` false alarms, coloured noise, the worst "
           "channel set", "at_most", 5, "%", COLOURED, COLOURED_COMMAND),
    Target("confident_exactly_right", "accuracy", "mismatch tool, physics in other forms: verdicts at confidence "
           "≥ 0.8 exactly right", "at_least", 90, "%", OTHER_FORMS, OTHER_FORMS_COMMAND),
    Target("next_drive_right", "accuracy", "mismatch tool, one designed follow-up: right, the worst channel set "
           "(three generators)", "at_least", 95, "%", NEXT_DRIVE, NEXT_DRIVE_COMMAND),
    Target("next_drive_beats_control", "accuracy", "mismatch tool: designed follow-up minus control follow-up, "
           "right verdicts, lower end of the paired 95 % interval", "at_least", 0, "", NEXT_DRIVE,
           NEXT_DRIVE_COMMAND),
)
TARGETS = TARGETS + DIAGNOSE_TARGETS

BY_KEY = {target.key: target for target in TARGETS}


def _number(value: float) -> str:
    return f"{value:,.0f}" if value >= 1000 else f"{value:g}"


def _json(relative: str) -> dict:
    return json.loads((ROOT / relative).read_text(encoding="utf-8"))


def _bench_json() -> dict:
    """The raw figures of the last ``hyst-gym bench`` run, the JSON block of ``docs/bench.md``."""
    text = (ROOT / BENCH).read_text(encoding="utf-8")
    block = text.split("<!-- bench-json -->", 1)[1].split("```json", 1)[1].split("```", 1)[0]
    return json.loads(block)


def _slowest_suite_task(kind: str) -> tuple[float, str]:
    speeds = {task_id: task["steps_per_s"][kind] for path in SUITES
              for task_id, task in _json(path)["tasks"].items() if task.get("steps_per_s")}
    task_id = min(speeds, key=speeds.get)
    return speeds[task_id], f"`{task_id}`, the slowest of {len(speeds)} tasks"


def _first_step(which: str):
    path = ROOT / BY_KEY["first_step_install"].source
    if not path.exists():
        return None
    result = json.loads(path.read_text(encoding="utf-8"))
    return result[which], f"1-min load {result['load_average_1min']:.1f}, {result['cores']} cores"


def _diagnose_speed():
    rows = _json(BY_KEY["diagnose_20000"].source)
    slowest = max(rows, key=lambda r: r["seconds_alone"])
    detail = (f"{slowest['generator']}/{slowest['channels']} {slowest['effect']}, {slowest['samples']:,} samples, "
              f"1-min load {slowest['load_average_before']:.1f}")
    return slowest["seconds_alone"], detail


def _next_drive_speed():
    result = _json(BY_KEY["next_drive_20000"].source)
    designed = [r for r in result["rows"] if r["design_seconds"] is not None]
    slowest = max(designed, key=lambda r: r["design_seconds"])
    detail = (f"own/{slowest['channels']} {slowest['effect']} seed {slowest['seed']}, {result['samples']:,} samples, "
              f"{len(designed)} designs, 1-min load {slowest['load_average_before']:.1f}")
    return slowest["design_seconds"], detail


def _pe_auc():
    result = _json(BY_KEY["pe_prediction_auc"].source)
    test = result["best_test"]
    evaluation = result["evaluation"]["all"]
    auc = evaluation["tests"][test]["auc"]
    return auc, f"`{test}`, {evaluation['episodes']} episodes"


def _benchmark_ratio(key: str, reference: str, name: str):
    target = _json(BY_KEY[key].source)["targets"][key]
    return (target["rl_iqm"] / target[f"{reference}_iqm"],
            f"{target['best_rl']} {target['rl_iqm']:.3g} against {target.get(name, reference)} "
            f"{target[f'{reference}_iqm']:.3g}")


def _per_channel_set(rows, case_filter, hit):
    """``{channel set: (hits, n)}`` over the rows ``case_filter`` keeps."""
    counts = {}
    for row in rows:
        if case_filter(row):
            hits, n = counts.get(row["channels"], (0, 0))
            counts[row["channels"]] = (hits + bool(hit(row)), n + 1)
    return counts


def _worst(counts, sense):
    """The worst channel set's share (%) and a detail naming it and every channel set's count."""
    shares = {ch: 100.0 * h / n for ch, (h, n) in counts.items()}
    worst = (min if sense == "at_least" else max)(shares, key=shares.get)
    every = ", ".join(f"{ch} {h}/{n}" for ch, (h, n) in sorted(counts.items()))
    return shares[worst], f"worst {worst}; {every}"


def _other_forms(key: str):
    source = ROOT / BY_KEY[key].source
    if not source.exists():
        return None
    rows = json.loads(source.read_text(encoding="utf-8"))["rows"]
    sense = BY_KEY[key].sense
    effects = lambda r: r["case"] not in ("none_other_numerics",)  # noqa: E731
    nones = lambda r: r["case"] == "none_other_numerics"  # noqa: E731
    if key == "other_forms_right":
        return _worst(_per_channel_set(rows, effects, lambda r: r["outcome"] == "right"), sense)
    if key == "other_forms_right_or_tied":
        return _worst(_per_channel_set(rows, effects, lambda r: r["outcome"] in ("right", "ambiguous_with_truth")),
                      sense)
    if key == "other_forms_wrong_names":
        return _worst(_per_channel_set(rows, effects, lambda r: r["outcome"] == "wrong_name"), sense)
    if key in ("none_false_alarms_white", "none_false_alarms_coloured"):
        return _worst(_per_channel_set(rows, nones, lambda r: r["verdict"] != "none"), sense)
    confident = [r for r in rows if r["confidence"] is not None and r["confidence"] >= 0.8]
    exact = sum(r["outcome"] == "right" for r in confident)
    singles = [r for r in confident if r["verdict"] not in ("ambiguous", "none", "unexplained")]
    ties = [r for r in confident if r["verdict"] == "ambiguous"]
    detail = (f"{exact} of {len(confident)}; single names {sum(r['outcome'] == 'right' for r in singles)} of "
              f"{len(singles)} right, ties {sum(r['outcome'] == 'ambiguous_with_truth' for r in ties)} of "
              f"{len(ties)} contain the truth")
    return (100.0 * exact / len(confident) if confident else 0.0), detail


def _next_drive(key: str):
    result = _json(BY_KEY[key].source)
    if key == "next_drive_beats_control":
        paired = result["paired_designed_minus_control"]
        return paired["ci95"][0], (f"mean {paired['mean']:+.2f} [{paired['ci95'][0]:+.2f}, {paired['ci95'][1]:+.2f}] "
                                   f"over {paired['cases']} recordings")
    counts = {}
    for row in result["summary"]:
        hits, n = counts.get(row["channel_set"], (0, 0))
        counts[row["channel_set"]] = (hits + row["designed"], n + row["cases"])
    return _worst(counts, "at_least")


def measurement(key: str):
    """``(value, detail)`` of a target from its committed file, or None where the file is missing."""
    if key == "env_single":
        return _bench_json()["env_single_steps_per_s"], f"bench of {_bench_json()['machine']['date']}"
    if key == "env_vector_1024":
        return _bench_json()["env_vector_steps_per_s"]["1024"], f"bench of {_bench_json()['machine']['date']}"
    if key in ("suite_single", "suite_vector_1024"):
        return _slowest_suite_task("single" if key == "suite_single" else "1024")
    if key in ("first_step_install", "first_step_cached"):
        return _first_step("first_s" if key == "first_step_install" else "cached_s")
    if key == "diagnose_20000":
        return _diagnose_speed()
    if key == "next_drive_20000":
        return _next_drive_speed()
    if key == "pe_prediction_auc":
        return _pe_auc()
    if key == "paper_settle_half_ramp":
        return _benchmark_ratio(key, "ramp", "ramp")
    if key == "drift_rms_half_best_schedule":
        return _benchmark_ratio(key, "schedule", "best_schedule")
    if key.startswith(("other_forms_", "none_false_alarms_", "confident_")):
        return _other_forms(key)
    if key.startswith("next_drive_") and key != "next_drive_20000":
        return _next_drive(key)
    raise KeyError(f"no measurement for target {key!r}")


def _files(source: str) -> str:
    return ", ".join(f"`{path}`" for path in source.split(", "))


def _measured(value: float, unit: str) -> str:
    if unit == "steps/s":
        return f"{value:,.0f} {unit}"
    if unit == "%":
        return f"{value:.0f} %"
    return f"{value:.1f} {unit}" if unit == "s" else f"{value:.2f}"


def markdown_table() -> str:
    lines = ["Written by `python -m experiments.targets` from the committed measurements.", "",
             "| area | what | target | measured | met | measurement |", "|---|---|---|---|---|---|"]
    for target in TARGETS:
        found = measurement(target.key)
        if found is None:
            lines.append(f"| {target.area} | {target.what} | {target.stated()} | not measured | – | "
                         f"no committed {_files(target.source)} |")
            continue
        value, detail = found
        verdict = "**met**" if target.met(value) else "**not met**"
        lines.append(f"| {target.area} | {target.what} | {target.stated()} | {_measured(value, target.unit)} | "
                     f"{verdict} | {detail}; {_files(target.source)} |")
    commands = {}
    for target in TARGETS:
        commands.setdefault(target.command, target.source)
    lines += ["", "Each measurement's file is rewritten by:", ""]
    lines += [f"- `{command}`: {_files(source)}" for command, source in commands.items()]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--print", action="store_true", help="print the table only; leave docs/targets.md alone")
    args = parser.parse_args(argv)
    text = markdown_table()
    print(text)
    if not args.print:
        from experiments.sections import update_readme

        update_readme(PAGE, text, area=AREA)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
