"""Speed of the mismatch tool, one recording at a time (target: at most 20 s per 20,000-sample
recording on a 2-core machine, :mod:`experiments.targets`).

The concealed study (:mod:`experiments.diagnose_concealed`) times every recording, but with its
worker processes sharing the cores, so its times mix the tool's cost with the load. This script
takes, per generator and channel set, the ``--slowest`` effects of largest median study time (every seed of
each; :func:`slowest_rows`) in the study's raw rows, regenerates each recording from its generator
and seed, and diagnoses it again in this process alone, with the 1-min load average before and
after. Results go to ``experiments/results/diagnose/speed_<samples>.{json,md}``. With ``--samples 20000`` the
own generator's recordings are regenerated at the issue's record length (same effect and seed).

    .venv/bin/python -m experiments.diagnose_speed --slowest 1 --samples 20000 [--workers N] [--page docs/speed.md]

``--workers`` is the tool's thread count (default: the tool's default, the cores up to 4); with
``--page`` the table also goes into the page's ``diagnose-speed`` section.

Each row also has the process's CPU time over the diagnosis (all its threads): the wall time depends on
what else runs on the machine (the 1-min load beside it), the CPU time much less; CPU time divided by the
threads is the wall time the diagnosis would take with its cores to itself and its threads always busy.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from experiments.diagnose_concealed import RESULTS, RUNS, load_rows, make
from hyst_gym.diagnose import diagnose
from hyst_gym.diagnose.pipeline import DEFAULT_WORKERS


def slowest_rows(rows, count):
    """Per generator and channel set, every study row (all its seeds, in seed order) of the ``count`` effects whose
    median study time is largest. Why per generator: ``--samples`` regenerates only the own generator's recordings
    at another length, so ranked together by their study time the own recordings (short in the study, long when
    timed) were left out. Why per channel set and effect, with every seed: a row's study time carries the load of
    the study's other workers, so the slowest single rows of a generator changed from one study to the next and
    left out seeds of its slowest case; an effect's median over its seeds is steadier, and its seeds differ by
    the recording alone."""
    chosen = []
    groups = {}
    for r in rows:
        groups.setdefault((r.get("generator"), r.get("channels")), {}).setdefault(r.get("effect"), []).append(r)
    for effects in groups.values():
        ranked = sorted(effects.items(), key=lambda item: -float(np.median([float(r["seconds"]) for r in item[1]])))
        for _, of_effect in ranked[:count]:
            chosen += sorted(of_effect, key=lambda r: int(r["seed"]))
    return chosen


def time_one(row, samples, workers):
    recording, _ = make(row["generator"], row["channels"], row["effect"], int(row["seed"]), samples)
    load_before = os.getloadavg()[0]
    started, cpu_started = time.perf_counter(), time.process_time()
    report = diagnose(recording, progress=False, workers=workers)
    seconds, cpu_seconds = time.perf_counter() - started, time.process_time() - cpu_started
    return {"generator": row["generator"], "channels": row["channels"], "effect": row["effect"],
            "seed": int(row["seed"]), "samples": recording.size, "seconds_alone": seconds, "cpu_seconds": cpu_seconds,
            "workers": workers,
            "seconds_in_study": float(row["seconds"]), "study_load_average": float(row["load_average"]),
            "load_average_before": load_before, "load_average_after": os.getloadavg()[0],
            "verdict": report.verdict, "verdict_in_study": row["verdict"]}


def _cpu(row):
    """A row's CPU seconds; rows measured before the script recorded them say so."""
    return f"{row['cpu_seconds']:.1f}" if "cpu_seconds" in row else "not recorded"


def _cpu_sentence(results):
    timed = [r for r in results if "cpu_seconds" in r]
    if not timed:
        return ""
    most = max(timed, key=lambda r: r["cpu_seconds"])
    return (" CPU s: the process's CPU time over the diagnosis, all threads, which depends on the load far less "
            f"than the wall time; the largest, {most['cpu_seconds']:.1f} s over {most['workers']} threads, is "
            f"{most['cpu_seconds'] / most['workers']:.1f} s per thread (the wall time with the cores free and the "
            "threads always busy).")


def markdown(results, cores=None):
    """The table of :func:`main`'s results; ``cores`` defaults to this machine's."""
    from experiments.targets import BY_KEY

    target = BY_KEY["diagnose_20000"]
    slowest = max(results, key=lambda r: r["seconds_alone"])
    met = "met" if target.met(slowest["seconds_alone"]) else "not met"
    lines = [f"Written by `python -m experiments.diagnose_speed --samples {results[0]['samples']}` "
             f"({cores or os.cpu_count()} cores; per generator and channel set, every seed of the effect with the "
             "largest median time in the concealed study; each recording diagnosed alone, in one process, with the "
             f"tool's threads). Target: at most {target.bound:g} s per 20,000-sample recording, **{met}** "
             f"(largest time alone {slowest['seconds_alone']:.1f} s)." + _cpu_sentence(results), "",
             "| generator / channels | effect | seed | samples | threads | s alone | CPU s | 1-min load before / after "
             "| s in the study (load) | verdict (study) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| {r['generator']}/{r['channels']} | {r['effect']} | {r['seed']} | {r['samples']:,} | "
                     f"{r['workers']} | {r['seconds_alone']:.1f} | {_cpu(r)} | "
                     f"{r['load_average_before']:.1f} / "
                     f"{r['load_average_after']:.1f} | "
                     f"{r['seconds_in_study']:.1f} ({r['study_load_average']:.1f}) | "
                     f"{r['verdict']} ({r['verdict_in_study']}) |")
    lines.append("")
    lines.append(f"Largest time alone: {slowest['seconds_alone']:.1f} s ({slowest['samples']:,} samples, "
                 f"1-min load {slowest['load_average_before']:.1f}).")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--slowest", type=int, default=1,
                        help="how many effects per generator and channel set, those of largest median study time, "
                        "each at every seed of the study (default 1)")
    parser.add_argument("--samples", type=int, default=4000,
                        help="samples per own-generator recording (default 4000, as in the study; 20000 times "
                        "the study's slowest own-generator cases at the issue's record length)")
    parser.add_argument("--workers", type=int, default=DEFAULT_WORKERS,
                        help=f"the tool's threads (default {DEFAULT_WORKERS}: the cores, at most 4)")
    parser.add_argument("--page", type=Path, help="also write the table into this page's diagnose-speed section")
    args = parser.parse_args(argv)
    if args.slowest < 1:
        parser.error("--slowest must be >= 1")
    if args.workers < 1:
        parser.error("--workers must be >= 1")
    if args.page is not None and not args.page.is_file():
        parser.error(f"--page {args.page}: no such file")
    rows = load_rows(RUNS)
    if not rows:
        parser.error(f"no study rows in {RUNS}: run experiments.diagnose_concealed first")
    results = [time_one(row, args.samples, args.workers) for row in slowest_rows(rows, args.slowest)]
    RESULTS.mkdir(parents=True, exist_ok=True)
    stem = f"speed_{args.samples}"
    (RESULTS / f"{stem}.json").write_text(json.dumps(results, indent=2, default=float) + "\n")
    text = markdown(results)
    (RESULTS / f"{stem}.md").write_text(text)
    if args.page is not None:
        from experiments.report_markdown import update_readme

        update_readme(args.page, text, area="diagnose-speed")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
