"""Sameness of the mismatch tool's answers across a change that should not move them (a speed change).

Diagnoses a fixed set of recordings and writes, per recording, the verdict, its slot, the tied candidates,
the confidence, the held-out reduction of the verdict and every candidate's held-out RMSE to a JSON file, so
that two states of the tool can be compared with ``--compare``:

    .venv/bin/python -m experiments.diagnose_sameness --out before.json [--samples 2000] [--long]
    .venv/bin/python -m experiments.diagnose_sameness --compare before.json after.json

The set: every effect ``make_recording`` can write (and ``none``), seeds 0 and 1, on the magnetization and on
both channels, ``--samples`` samples each; with ``--long``, also the three own-generator recordings that
:mod:`experiments.diagnose_speed` times at 20,000 samples (rod_dynamics on both channels, seeds 100-102).
``--compare`` prints every recording whose verdict, tie or confidence differs, and the largest relative
change of a held-out RMSE; it exits 1 when a verdict or a tie differs.

Committed: ``experiments/results/diagnose/sameness_before.json`` (the tool at 29ec4da, before the speed work)
and ``sameness_after.json`` (at 635a46e, after it), both with ``--long``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

SEEDS = (0, 1)
CHANNEL_SETS = ("magnetization", "both")
#: The speed study's slowest own-generator recordings (experiments/results/diagnose/speed_20000.json).
LONG = [("rod_dynamics", "both", seed, 20000) for seed in (100, 101, 102)]


def jobs(samples, long):
    from hyst_gym.diagnose.make_recording import WRITABLE_EFFECTS

    chosen = [(effect, channels, seed, samples) for effect in WRITABLE_EFFECTS for channels in CHANNEL_SETS
              for seed in SEEDS]
    return chosen + (LONG if long else [])


def run_one(job):
    from hyst_gym.diagnose import diagnose
    from hyst_gym.diagnose.make_recording import make_recording_with_truth

    effect, channels, seed, samples = job
    try:
        recording, _, _ = make_recording_with_truth(effect, seed, output=channels, n_samples=samples)
    except ValueError:  # an effect this channel set cannot show (the displacement's, on the magnetization)
        return None
    started = time.perf_counter()
    report = diagnose(recording, progress=False, workers=1)
    return {"effect": effect, "channels": channels, "seed": seed, "samples": samples,
            "verdict": report.verdict, "slot": report.slot or "",
            "tied": sorted(c.effect for c in report.tied) if report.verdict == "ambiguous" else [],
            "confidence": float(report.confidence), "improvement": float(report.improvement),
            "baseline_heldout": float(report.baseline_heldout),
            "candidates": {c.effect: float(c.heldout_rmse) for c in report.candidates},
            "seconds": time.perf_counter() - started}


def key(row):
    return f"{row['effect']}/{row['channels']}/seed {row['seed']}/{row['samples']}"


def compare(before_path, after_path):
    before = {key(r): r for r in json.loads(Path(before_path).read_text())}
    after = {key(r): r for r in json.loads(Path(after_path).read_text())}
    changed, largest, seconds = 0, (0.0, ""), [0.0, 0.0]
    for name in before:
        if name not in after:
            print(f"{name}: missing after")
            continue
        b, a = before[name], after[name]
        seconds[0] += b["seconds"]
        seconds[1] += a["seconds"]
        if (b["verdict"], b["tied"]) != (a["verdict"], a["tied"]):
            changed += 1
            print(f"{name}: VERDICT {b['verdict']} {b['tied']} ({b['confidence']:.3f}) -> {a['verdict']} {a['tied']} "
                  f"({a['confidence']:.3f})")
        elif abs(b["confidence"] - a["confidence"]) > 1e-6 or abs(b["improvement"] - a["improvement"]) > 1e-6:
            print(f"{name}: {b['verdict']} confidence {b['confidence']:.4f} -> {a['confidence']:.4f}, held-out "
                  f"reduction {b['improvement']:.4f} -> {a['improvement']:.4f}")
        for effect, rmse in [("baseline", b["baseline_heldout"])] + list(b["candidates"].items()):
            other = a["baseline_heldout"] if effect == "baseline" else a["candidates"].get(effect, float("nan"))
            if rmse == other:
                continue
            relative = abs(other - rmse) / max(abs(rmse), 1e-300)
            if not relative <= largest[0]:
                largest = (relative, f"{name} {effect}: {rmse:.6g} -> {other:.6g}")
    print(f"{len(before)} recordings: {changed} verdicts or ties changed; largest relative change of a held-out "
          f"RMSE {largest[0]:.3g} ({largest[1] or 'none'}); seconds {seconds[0]:.0f} -> {seconds[1]:.0f}")
    return 1 if changed else 0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write the rows to this JSON file")
    parser.add_argument("--samples", type=int, default=2000, help="samples per recording of the quick set")
    parser.add_argument("--long", action="store_true", help="also the three 20,000-sample speed recordings")
    parser.add_argument("--processes", type=int, default=2, help="recordings diagnosed at once (default 2)")
    parser.add_argument("--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"),
                        help="compare two files written with --out")
    args = parser.parse_args(argv)
    if args.compare:
        return compare(*args.compare)
    if args.out is None:
        parser.error("give --out FILE (or --compare BEFORE AFTER)")
    if args.samples < 500 or args.processes < 1:
        parser.error("--samples must be >= 500 and --processes >= 1")
    todo = jobs(args.samples, args.long)
    load = os.getloadavg()[0]
    with ProcessPoolExecutor(max_workers=args.processes) as pool:
        rows = []
        for row in pool.map(run_one, todo):
            if row is None:
                continue
            rows.append(row)
            print(f"{key(row)}: {row['verdict']} {row['tied']} {row['confidence']:.3f} ({row['seconds']:.1f} s)",
                  file=sys.stderr)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(rows, indent=1) + "\n")
    print(f"{len(rows)} recordings, 1-min load {load:.1f} at the start -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
