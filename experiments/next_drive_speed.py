"""Speed of the next-drive design on 20,000-sample recordings (target: at most 30 s on this 2-core machine).

The cases are fixed before the run: the own generator's cases of the next-drive study
(:data:`experiments.diagnose_next_drive.DEFAULT_CASES`, magnetization, seeds 1-3 in the study's order),
regenerated at 20,000 samples. Each is diagnosed (timed, for information), and where the verdict leaves
hypotheses standing its next drive is designed as ``hyst-gym diagnose --next-drive`` designs it
(``report.next_drive()``, default seed and search sizes), timed alone. The run stops after ``--designs``
designs; a confident single name gets no design and is listed as such.

    .venv/bin/python -m experiments.next_drive_speed [--designs 3] [--samples 20000]

Writes ``experiments/results/diagnose/next_drive_speed.json`` (every case, with the 1-min load average
before and after each design), read by :mod:`experiments.targets`.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from hyst_gym.diagnose import diagnose, make_recording

ROOT = Path(__file__).resolve().parents[1]
RESULT = ROOT / "experiments" / "results" / "diagnose" / "next_drive_speed.json"
TARGET_SECONDS = 30.0


def own_cases():
    """The own generator's cases of the next-drive study, in its order."""
    from experiments.diagnose_next_drive import DEFAULT_CASES

    return [c for c in DEFAULT_CASES if c.generator == "own"]


def time_case(case, samples: int) -> dict:
    recording = make_recording(case.effect, case.seed, output=case.channels, n_samples=samples)[0]
    started = time.perf_counter()
    report = diagnose(recording, progress=False)
    diagnosed = time.perf_counter() - started
    row = {"effect": case.effect, "seed": case.seed, "channels": case.channels, "samples": samples,
           "verdict": report.verdict, "confidence": report.confidence, "diagnose_seconds": diagnosed}
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    design = report.next_drive()
    row.update(design_seconds=time.perf_counter() - started if design is not None else None,
               load_average_before=load_before, load_average_after=os.getloadavg()[0],
               hypotheses=design.hypotheses if design is not None else [],
               evaluations=design.evaluations if design is not None else 0,
               smallest_separation=design.smallest_separation if design is not None else None)
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--designs", type=int, default=3, help="stop after this many designs (default 3)")
    parser.add_argument("--samples", type=int, default=20_000, help="samples per recording (default 20000)")
    args = parser.parse_args(argv)
    if args.designs < 1 or args.samples < 100:
        parser.error("--designs must be >= 1 and --samples >= 100")
    rows = []
    for case in own_cases():
        row = time_case(case, args.samples)
        rows.append(row)
        timing = "no design (a confident single name)" if row["design_seconds"] is None else \
            f"design {row['design_seconds']:.1f} s ({', '.join(row['hypotheses'])}; {row['evaluations']} evaluations)"
        print(f"{case.effect} seed {case.seed}: {row['verdict']} ({row['confidence']:.2f}), diagnose "
              f"{row['diagnose_seconds']:.1f} s, {timing}, load {row['load_average_before']:.1f}", flush=True)
        if sum(r["design_seconds"] is not None for r in rows) >= args.designs:
            break
    designed = [r["design_seconds"] for r in rows if r["design_seconds"] is not None]
    payload = {"samples": args.samples, "cores": os.cpu_count(), "target_seconds": TARGET_SECONDS,
               "slowest_design_seconds": max(designed) if designed else None, "rows": rows,
               "command": "python -m experiments.next_drive_speed"}
    RESULT.parent.mkdir(parents=True, exist_ok=True)
    RESULT.write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
    print(f"slowest design: {payload['slowest_design_seconds']} s (target {TARGET_SECONDS:g} s); {RESULT}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
