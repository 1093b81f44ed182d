"""Blind study of the mismatch tool on concealed-effect recordings (issue 6).

For every effect of the vocabulary and for ``none``, ``--seeds`` synthetic recordings are
drawn with ``make_recording`` (default length and strength) and diagnosed blind (the tool
sees only the recording). Raw per-recording rows go to
``experiments/results/diagnose/concealed_runs.csv`` (reruns skip rows already there); the
confusion matrix, the mean held-out improvement per effect, the false-alarm rate and the
seconds per recording go to ``concealed.md``, ``concealed_summary.json`` and
``docs/figures/diagnose/confusion.png``.

    .venv/bin/python experiments/diagnose_concealed.py --seeds 5 --jobs 2 --samples 4000

``--effects E1 E2 --rerun`` recomputes only those effects' rows (e.g. after a generator change
for them) and keeps the other effects' rows.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from hyst_gym.diagnose import GENERATOR_EFFECTS, diagnose, make_recording

ROOT = Path(__file__).resolve().parent
RESULTS = ROOT / "results" / "diagnose"
FIGURES = ROOT.parent / "docs" / "figures" / "diagnose"
FIELDS = ["effect", "seed", "verdict", "confidence", "baseline_heldout", "verdict_heldout", "true_effect_heldout",
          "true_effect_improvement", "improvement", "seconds", "samples", "load_average"]
LABELS = list(GENERATOR_EFFECTS) + ["unexplained"]


def run_one(job):
    effect, seed, samples = job
    recording, _ = make_recording(effect, seed, n_samples=samples)
    started = time.perf_counter()
    report = diagnose(recording, progress=False)
    seconds = time.perf_counter() - started
    true = next((c for c in report.candidates if c.effect == effect), None)
    return {"effect": effect, "seed": seed, "verdict": report.verdict, "confidence": report.confidence,
            "baseline_heldout": report.baseline_heldout,
            "verdict_heldout": report.chosen.heldout_rmse if report.chosen else report.baseline_heldout,
            "true_effect_heldout": true.heldout_rmse if true else "",
            "true_effect_improvement": true.improvement if true else "",
            "improvement": report.improvement, "seconds": seconds, "samples": recording.size,
            "load_average": os.getloadavg()[0]}


def load_rows(path):
    if not path.exists():
        return []
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def summarize(rows):
    index = {label: i for i, label in enumerate(LABELS)}
    matrix = np.zeros((len(GENERATOR_EFFECTS), len(LABELS)), dtype=int)
    for row in rows:
        matrix[index[row["effect"]], index[row["verdict"]]] += 1
    correct = sum(matrix[i, i] for i in range(len(GENERATOR_EFFECTS)))
    total = int(matrix.sum())
    none_rows = [r for r in rows if r["effect"] == "none"]
    false_alarms = sum(r["verdict"] != "none" for r in none_rows)
    improvement = {}
    for effect in GENERATOR_EFFECTS:
        if effect == "none":
            continue
        vals = [float(r["true_effect_improvement"]) for r in rows if r["effect"] == effect
                and r["true_effect_improvement"] not in ("", None)]
        improvement[effect] = {"mean": float(np.mean(vals)) if vals else None,
                               "min": float(np.min(vals)) if vals else None, "n": len(vals)}
    seconds = [float(r["seconds"]) for r in rows]
    return {"recordings": total, "correct": int(correct), "accuracy": correct / total if total else None,
            "none_recordings": len(none_rows), "false_alarms": int(false_alarms),
            "false_alarm_rate": false_alarms / len(none_rows) if none_rows else None,
            "mean_heldout_improvement_of_true_effect": improvement,
            "seconds_per_recording": {"mean": float(np.mean(seconds)), "max": float(np.max(seconds))},
            "samples": sorted({int(r["samples"]) for r in rows}),
            "mean_load_average": float(np.mean([float(r["load_average"]) for r in rows])),
            "confusion": {"rows_true": list(GENERATOR_EFFECTS), "columns_verdict": LABELS,
                          "counts": matrix.tolist()}}


def write_outputs(summary):
    RESULTS.mkdir(parents=True, exist_ok=True)
    FIGURES.mkdir(parents=True, exist_ok=True)
    (RESULTS / "concealed_summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    counts = np.array(summary["confusion"]["counts"])
    with open(RESULTS / "confusion.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["true \\ verdict"] + LABELS)
        for effect, row in zip(GENERATOR_EFFECTS, counts):
            writer.writerow([effect] + row.tolist())
    lines = ["# Concealed-effect study", "",
             f"{summary['recordings']} recordings ({summary['samples']} samples each), diagnosed blind with the "
             f"default lumped base model.", "",
             f"- correct verdicts: {summary['correct']}/{summary['recordings']} = {100 * summary['accuracy']:.0f} %",
             f"- false alarms on `none`: {summary['false_alarms']}/{summary['none_recordings']}",
             f"- seconds per recording: mean {summary['seconds_per_recording']['mean']:.1f}, max "
             f"{summary['seconds_per_recording']['max']:.1f} (mean 1-min load average during the run "
             f"{summary['mean_load_average']:.1f} on 2 cores)", "",
             "| true \\ verdict | " + " | ".join(LABELS) + " |", "|---" * (len(LABELS) + 1) + "|"]
    for effect, row in zip(GENERATOR_EFFECTS, counts):
        lines.append(f"| {effect} | " + " | ".join(str(v) for v in row) + " |")
    lines += ["", "Held-out RMSE reduction of the true effect's model over the base model:", "",
              "| effect | mean | min | n |", "|---|---|---|---|"]
    for effect, stats in summary["mean_heldout_improvement_of_true_effect"].items():
        if stats["mean"] is not None:
            lines.append(f"| {effect} | {100 * stats['mean']:.0f} % | {100 * stats['min']:.0f} % | {stats['n']} |")
    (RESULTS / "concealed.md").write_text("\n".join(lines) + "\n")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(9, 6))
    ax.imshow(counts, cmap="Blues")
    ax.set_xticks(range(len(LABELS)), LABELS, rotation=45, ha="right")
    ax.set_yticks(range(len(GENERATOR_EFFECTS)), GENERATOR_EFFECTS)
    for i in range(counts.shape[0]):
        for j in range(counts.shape[1]):
            if counts[i, j]:
                ax.text(j, i, str(counts[i, j]), ha="center", va="center")
    ax.set_xlabel("verdict"); ax.set_ylabel("concealed effect")
    ax.set_title(f"Blind verdicts: {100 * summary['accuracy']:.0f} % correct")
    fig.tight_layout()
    fig.savefig(FIGURES / "confusion.png", dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--first-seed", type=int, default=100)
    parser.add_argument("--samples", type=int, default=5000)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--effects", nargs="*", default=list(GENERATOR_EFFECTS), choices=GENERATOR_EFFECTS)
    parser.add_argument("--rerun", action="store_true",
                        help="drop the stored rows of --effects and recompute them (other effects' rows are kept)")
    args = parser.parse_args(argv)
    runs = RESULTS / "concealed_runs.csv"
    RESULTS.mkdir(parents=True, exist_ok=True)
    rows = load_rows(runs)
    if args.rerun and rows:
        rows = [r for r in rows if r["effect"] not in args.effects]
        with open(runs, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=FIELDS)
            writer.writeheader()
            writer.writerows(rows)
    done = {(r["effect"], int(r["seed"])) for r in rows}
    jobs = [(e, s, args.samples) for e in args.effects
            for s in range(args.first_seed, args.first_seed + args.seeds) if (e, s) not in done]
    new_file = not runs.exists()
    with open(runs, "a", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=FIELDS)
        if new_file:
            writer.writeheader()
        with ProcessPoolExecutor(max_workers=args.jobs) as pool:
            for row in tqdm(pool.map(run_one, jobs), total=len(jobs), desc="concealed study"):
                writer.writerow(row)
                handle.flush()
                rows.append({k: str(v) for k, v in row.items()})
    summary = summarize(rows)
    write_outputs(summary)
    print(json.dumps({k: summary[k] for k in ("accuracy", "false_alarm_rate", "seconds_per_recording")}))


if __name__ == "__main__":
    main()
