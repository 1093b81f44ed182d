"""Blind study of the mismatch tool on concealed-effect recordings, per channel set and generator.

Two generators write the recordings:

* ``own`` -- :func:`hyst_gym.diagnose.make_recording`, which shares the fitter's kernels;
* ``independent`` -- :mod:`experiments.independent_recordings`, written separately: its own
  integrators (an adaptive Dormand-Prince 5(4) in time on the hysteresis ODE, its own mechanics), its own excitation
  families (sines with minor loops, triangles, PRBS, chirps, a milling-like load), sampling
  rates of 10-60 kHz, noise of 0.1-1 % of peak-to-peak, record lengths and wider parameter
  ranges, none of which the fitter is told. It also conceals effects the tool does not model.

For every generator, channel set (``magnetization``, ``displacement``, ``both``), effect the
channel set can show, and seed, one recording is diagnosed blind. Per-recording rows go to
``experiments/results/diagnose/concealed_study.csv`` (reruns skip rows already there). The
summary (``concealed.md``, ``concealed_summary.json``, figures in ``docs/figures/diagnose/``)
reports, per generator and channel set: exact verdicts, verdicts that are right or ambiguous
with the truth listed, wrong single names, wrong names on effects outside the vocabulary,
false alarms on ``none``, the held-out reduction of the true effect's model, seconds per
recording, and a reliability table (confidence bins against how often the verdict was right).

What counts as right: for a vocabulary effect or ``none``, its own name; for an effect outside
the vocabulary, ``unexplained`` or ``ambiguous`` (the tool must not give it a vocabulary name).

    .venv/bin/python -m experiments.diagnose_concealed --seeds 5 --jobs 2

A subset (some effects, channel sets, seeds) goes to its own folder with ``--out``, compared with an earlier
subset's rows by ``--before`` (e.g. the same subset run on an earlier commit)::

    .venv/bin/python -m experiments.diagnose_concealed --generators own --effects thermal_drift none \
        --seeds 3 --jobs 2 --out experiments/results/diagnose/some_change --before earlier/concealed_study.csv
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

from hyst_gym.diagnose import EFFECTS, GENERATOR_EFFECTS, diagnose
from hyst_gym.diagnose.effects import CHANNEL_SETS, MECHANICAL_EFFECTS
from hyst_gym.diagnose.make_recording import make_recording_with_truth

ROOT = Path(__file__).resolve().parent
RESULTS = ROOT / "results" / "diagnose"
FIGURES = ROOT.parent / "docs" / "figures" / "diagnose"
RUNS = RESULTS / "concealed_study.csv"
GENERATORS = ("own", "independent")
FIELDS = ["generator", "channels", "effect", "in_vocabulary", "seed", "verdict", "slot", "tied", "confidence",
          "outcome",
          "structured_share", "prior_binds", "unidentified",
          "baseline_heldout", "verdict_heldout", "true_effect_improvement", "seconds", "samples", "sample_rate_hz",
          "noise_relative", "excitation", "load_average", "fits"]
#: Confidence bins of the reliability table.
BINS = (0.0, 0.2, 0.5, 0.8, 0.9, 1.0001)


def expected_name(effect: str) -> str:
    """The verdict that names ``effect``: its own name, or the tool family that holds it
    (:data:`experiments.independent_recordings.TOOL_NAMES`)."""
    from experiments.independent_recordings import TOOL_NAMES

    return TOOL_NAMES.get(effect, effect)


def independent_effects():
    """(inside, outside) the tool's vocabulary, judged by the tool's own EFFECTS list."""
    from experiments.independent_recordings import ALL_EFFECTS

    inside = tuple(e for e in ALL_EFFECTS if expected_name(e) in EFFECTS or e == "none")
    return inside, tuple(e for e in ALL_EFFECTS if e not in inside)


def cases(generators, channel_sets, seeds, first_seed, effects=None):
    """Every (generator, channels, effect, seed) the channel set can show (only ``effects``, where given)."""
    out = []
    for generator in generators:
        if generator == "own":
            shown = [(e, True) for e in GENERATOR_EFFECTS]
        else:
            inside, outside = independent_effects()
            shown = [(e, True) for e in inside] + [(e, False) for e in outside]
        if effects is not None:
            shown = [(e, v) for e, v in shown if e in effects]
        for channels in channel_sets:
            for effect, in_vocabulary in shown:
                if channels == "magnetization" and (effect in MECHANICAL_EFFECTS
                                                    or _displacement_only(generator, effect)):
                    continue
                for seed in range(first_seed, first_seed + seeds):
                    out.append((generator, channels, effect, in_vocabulary, seed))
    return out


def _displacement_only(generator, effect):
    if generator == "own":
        return False
    from experiments.independent_recordings import EFFECT_SPECS

    return EFFECT_SPECS[effect].displacement_only


def make(generator, channels, effect, seed, samples):
    """(recording, conditions) from the chosen generator."""
    if generator == "own":
        recording, _, truth = make_recording_with_truth(effect, seed, output=channels, n_samples=samples)
        return recording, {"sample_rate_hz": truth["sample_rate"], "noise_relative": truth["noise_rel"],
                           "excitation": "own"}
    from experiments.independent_recordings import generate

    recording, truth = generate(effect, seed, channels)
    return recording, {"sample_rate_hz": truth.get("sample_rate_hz", truth.get("sample_rate", "")),
                       "noise_relative": truth.get("noise_relative", truth.get("noise_rel", "")),
                       "excitation": truth.get("excitation_family", "")}


def outcome(effect, in_vocabulary, verdict, tied):
    """right / ambiguous_with_truth / wrong_name / ambiguous_without_truth / unexplained / missed."""
    if not in_vocabulary:
        if verdict in ("unexplained", "ambiguous"):
            return "right"
        return "missed" if verdict == "none" else "wrong_name"
    if verdict == expected_name(effect):
        return "right"
    if verdict == "ambiguous":
        return "ambiguous_with_truth" if expected_name(effect) in tied else "ambiguous_without_truth"
    if verdict == "unexplained":
        return "unexplained"
    return "missed" if verdict == "none" else "wrong_name"


def run_one(job):
    generator, channels, effect, in_vocabulary, seed, samples = job
    recording, conditions = make(generator, channels, effect, seed, samples)
    started = time.perf_counter()
    report = diagnose(recording, progress=False)
    seconds = time.perf_counter() - started
    tied = [c.effect for c in report.tied] if report.verdict == "ambiguous" else []
    true = next((c for c in report.candidates if c.effect == expected_name(effect)), None)
    return {"generator": generator, "channels": channels, "effect": effect, "in_vocabulary": in_vocabulary,
            "seed": seed, "verdict": report.verdict, "slot": report.slot or "", "tied": ";".join(tied),
            "confidence": report.confidence, "structured_share": report.material_structure.get("share", ""),
            "prior_binds": report.identifiability["priors"].get("binds", ""),
            "unidentified": ";".join("+".join(d["components"]) for d in report.identifiability["unidentified"]),
            "outcome": outcome(effect, in_vocabulary, report.verdict, tied),
            "baseline_heldout": report.baseline_heldout,
            "verdict_heldout": report.chosen.heldout_rmse if report.chosen else report.baseline_heldout,
            "true_effect_improvement": true.improvement if true else "", "seconds": seconds,
            "samples": recording.size, **conditions, "load_average": os.getloadavg()[0],
            "fits": json.dumps(fit_summaries(report))}


def fit_summaries(report):
    """What the decision rule reads, per candidate (so a rule can be re-examined without refitting)."""
    base = report.baseline
    return {"baseline_fit_rmse": round(float(np.sqrt(base.sse / base.n_residuals)), 4),
            "candidates": [{"effect": c.effect, "heldout_rmse": round(c.heldout_rmse, 4),
                            "fit_rmse": round(float(np.sqrt(c.fit.sse / c.fit.n_residuals)), 4),
                            "delta_bic": round(c.bic - base.bic, 1), "improvement": round(c.improvement, 4),
                            "accepted": c.accepted, "plausible": c.plausibility.plausible}
                           for c in report.candidates]}


def load_rows(path):
    if not path.exists():
        return []
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _share(rows, predicate):
    return sum(1 for r in rows if predicate(r)) / len(rows) if rows else None


def summarize_group(rows):
    """The issue's targets for one (generator, channel set)."""
    inside = [r for r in rows if r["in_vocabulary"] == "True"]
    outside = [r for r in rows if r["in_vocabulary"] != "True"]
    none_rows = [r for r in inside if r["effect"] == "none"]
    per_effect = {}
    for effect in sorted({r["effect"] for r in rows}):
        group = [r for r in rows if r["effect"] == effect]
        improvements = [float(r["true_effect_improvement"]) for r in group if r["true_effect_improvement"]]
        per_effect[effect] = {
            "n": len(group), "right": _share(group, lambda r: r["outcome"] == "right"),
            "right_or_ambiguous_with_truth": _share(group, lambda r: r["outcome"] in ("right", "ambiguous_with_truth")),
            "verdicts": {v: sum(r["verdict"] == v for r in group) for v in sorted({r["verdict"] for r in group})},
            "true_effect_improvement_median": float(np.median(improvements)) if improvements else None,
            "true_effect_improvement_min": float(np.min(improvements)) if improvements else None}
    return {
        "recordings": len(rows), "in_vocabulary": len(inside), "outside_vocabulary": len(outside),
        "right": _share(inside, lambda r: r["outcome"] == "right"),
        "right_or_ambiguous_with_truth": _share(inside, lambda r: r["outcome"] in ("right", "ambiguous_with_truth")),
        "wrong_single_names": _share(inside, lambda r: r["outcome"] == "wrong_name"),
        "outside_right": _share(outside, lambda r: r["outcome"] == "right"),
        "outside_wrong_names_confidence_ge_0.5": sum(r["outcome"] == "wrong_name" and float(r["confidence"]) >= 0.5
                                                     for r in outside),
        "false_alarms_on_none": _share(none_rows, lambda r: r["verdict"] != "none"),
        "seconds_per_recording": {"median": float(np.median([float(r["seconds"]) for r in rows])),
                                  "max": float(np.max([float(r["seconds"]) for r in rows]))},
        "samples": [int(min(int(r["samples"]) for r in rows)), int(max(int(r["samples"]) for r in rows))],
        "per_effect": per_effect}


def reliability(rows):
    """Confidence bins against the share of verdicts exactly right (``exact``) and right or
    ambiguous with the truth listed (``right``)."""
    table = []
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        group = [r for r in rows if lo <= float(r["confidence"]) < hi]
        table.append({"confidence": [lo, min(hi, 1.0)], "n": len(group),
                      "exact": _share(group, lambda r: r["outcome"] == "right"),
                      "right": _share(group, lambda r: r["outcome"] in ("right", "ambiguous_with_truth"))})
    return table


def summarize(rows):
    groups = {}
    for generator in GENERATORS:
        for channels in CHANNEL_SETS:
            group = [r for r in rows if r["generator"] == generator and r["channels"] == channels]
            if group:
                groups[f"{generator}/{channels}"] = summarize_group(group)
    return {"groups": groups, "reliability": reliability(rows),
            "reliability_by_generator": {g: reliability([r for r in rows if r["generator"] == g]) for g in GENERATORS},
            "mean_load_average": float(np.mean([float(r["load_average"]) for r in rows])) if rows else None}


#: The study's rows before issue 22 (materiality, identifiability, families), for the before/after table.
BEFORE = RESULTS / "concealed_study_before_issue22.csv"


def before_after(before, rows):
    """Per (generator, channel set), on the recordings present in both row sets (same generator, channel
    set, effect and seed, hence the same recording): right, wrong single names, false alarms on ``none``
    and verdicts changed, with the earlier verdicts scored by today's :func:`outcome` (one yardstick:
    an effect that a family now names counts as right only when named)."""
    from experiments.independent_recordings import EFFECT_SPECS

    def key(r):
        return r["generator"], r["channels"], r["effect"], r["seed"]

    earlier = {key(r): r for r in before}
    table = []
    for generator in GENERATORS:
        for channels in CHANNEL_SETS:
            pairs = [(earlier[key(r)], r) for r in rows if r["generator"] == generator and r["channels"] == channels
                     and key(r) in earlier]
            if not pairs:
                continue

            def scored(r):
                inside = r["generator"] == "own" or EFFECT_SPECS[r["effect"]].in_vocabulary
                return outcome(r["effect"], inside, r["verdict"], r["tied"].split(";") if r["tied"] else [])

            nones = [(b, a) for b, a in pairs if b["effect"] == "none"]
            table.append({"group": f"{generator}/{channels}", "n": len(pairs),
                          "right": [sum(scored(b) == "right" for b, _ in pairs),
                                    sum(scored(a) == "right" for _, a in pairs)],
                          "wrong_names": [sum(scored(b) == "wrong_name" for b, _ in pairs),
                                          sum(scored(a) == "wrong_name" for _, a in pairs)],
                          "none_flagged": [sum(b["verdict"] != "none" for b, _ in nones),
                                           sum(a["verdict"] != "none" for _, a in nones)],
                          "none_n": len(nones), "changed": sum(b["verdict"] != a["verdict"] for b, a in pairs)})
    return table


def before_after_markdown(table, before=BEFORE) -> list:
    """The before/after table's section; its heading names issue 22 only for the study's own :data:`BEFORE`."""
    if not table:
        return []
    if Path(before).resolve() == BEFORE.resolve():
        head = ["", "## Before and after issue 22 (the same recordings)", "",
                "Rows of `concealed_study_before_issue22.csv` (the tool before materiality, identifiability and the "
                "families) against this run, on the recordings both contain, both scored by today's yardstick."]
    else:
        head = ["", "## Before and after (the same recordings)", "",
                f"Rows of `{before}` (an earlier run) against this run, on the recordings both contain, "
                "both scored by today's yardstick."]
    lines = head + ["",
             "| generator / channels | recordings | right before → after | wrong single names before → after | "
             "`none` recordings flagged before → after | verdicts changed |", "|---|---|---|---|---|---|"]
    for row in table:
        lines.append(f"| {row['group']} | {row['n']} | {row['right'][0]} → {row['right'][1]} | "
                     f"{row['wrong_names'][0]} → {row['wrong_names'][1]} | "
                     f"{row['none_flagged'][0]} → {row['none_flagged'][1]} of {row['none_n']} | {row['changed']} |")
    return lines


def _pct(value):
    return "–" if value is None else f"{100 * value:.0f} %"


def markdown(summary, comparison=(), before=BEFORE, command="python -m experiments.diagnose_concealed"):
    lines = ["# Concealed-effect study", "",
             f"Generated by `{command}`. Right = the concealed effect's name (for an "
             "effect outside the vocabulary: `unexplained` or `ambiguous`). Default lumped base model, blind.", "",
             "| generator / channels | recordings | right | right or ambiguous with truth | wrong single name | "
             "outside vocabulary right | outside: wrong names with confidence >= 0.5 | false alarms on none | "
             "s per recording (median / max) |", "|---|---|---|---|---|---|---|---|---|"]
    for key, g in summary["groups"].items():
        lines.append(f"| {key} | {g['recordings']} | {_pct(g['right'])} | {_pct(g['right_or_ambiguous_with_truth'])} | "
                     f"{_pct(g['wrong_single_names'])} | {_pct(g['outside_right'])} | "
                     f"{g['outside_wrong_names_confidence_ge_0.5']} | {_pct(g['false_alarms_on_none'])} | "
                     f"{g['seconds_per_recording']['median']:.1f} / {g['seconds_per_recording']['max']:.1f} |")
    for key, g in summary["groups"].items():
        lines += ["", f"## {key}", "", "| effect | n | right | right or ambiguous with truth | verdicts | "
                  "held-out reduction of the true effect (median / min) |", "|---|---|---|---|---|---|"]
        for effect, e in g["per_effect"].items():
            verdicts = ", ".join(f"{v} {n}" for v, n in e["verdicts"].items())
            reduction = ("–" if e["true_effect_improvement_median"] is None else
                         f"{_pct(e['true_effect_improvement_median'])} / {_pct(e['true_effect_improvement_min'])}")
            lines.append(f"| {effect} | {e['n']} | {_pct(e['right'])} | {_pct(e['right_or_ambiguous_with_truth'])} | "
                         f"{verdicts} | {reduction} |")
    lines += ["", "## Reliability of `confidence` (all recordings)", "",
              "| confidence | n | exactly right | right or ambiguous with truth |", "|---|---|---|---|"]
    for row in summary["reliability"]:
        lines.append(f"| {row['confidence'][0]:.1f}-{row['confidence'][1]:.1f} | {row['n']} | {_pct(row['exact'])} | "
                     f"{_pct(row['right'])} |")
    lines += before_after_markdown(list(comparison), before)
    return "\n".join(lines) + "\n"


def page_section(summary) -> str:
    """The documentation page's section: the summary table and the reliability table of
    :func:`markdown` (the per-effect tables and the before/after table stay in ``concealed.md``)."""
    sections = markdown(summary).split("\n## ")
    reliability_table = next(s for s in sections if s.startswith("Reliability of"))
    return (sections[0].split("\n", 2)[2] + "\n### " + reliability_table
            + "\nPer effect and generator, and the tool's earlier verdicts on the same recordings: "
            "`experiments/results/diagnose/concealed.md`.\n")


def write_outputs(summary, rows, out=RESULTS, before=BEFORE, command=None):
    """``concealed_summary.json`` and ``concealed.md`` in ``out`` (``command``: the one the .md names, where not
    the plain study); the figures only for the study's own folder."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "concealed_summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    text = markdown(summary, summary.get("before_after", ()), before, *([command] if command else []))
    (out / "concealed.md").write_text(text)
    if out.resolve() != RESULTS.resolve():
        return
    FIGURES.mkdir(parents=True, exist_ok=True)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(summary["groups"])
    fig, ax = plt.subplots(figsize=(8, 3.8))
    x = np.arange(len(keys))
    for offset, (name, label) in enumerate((("right", "right"),
                                            ("right_or_ambiguous_with_truth", "right or ambiguous with truth"),
                                            ("wrong_single_names", "wrong single name"))):
        ax.bar(x + 0.27 * (offset - 1), [100 * (summary["groups"][k][name] or 0) for k in keys], 0.27, label=label)
    ax.set_xticks(x, keys, rotation=20, ha="right")
    ax.set_ylabel("% of recordings (vocabulary effects)")
    ax.axhline(85, color="k", lw=0.6, ls=":")
    ax.legend(fontsize=8)
    ax.set_title("Concealed-effect study: verdicts per generator and channel set")
    fig.tight_layout()
    fig.savefig(FIGURES / "concealed_by_channel_set.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(4.5, 4))
    table = [r for r in summary["reliability"] if r["n"]]
    centers = [0.5 * sum(r["confidence"]) for r in table]
    ax.plot([0, 1], [0, 1], color="0.6", lw=0.8, ls="--")
    ax.plot(centers, [r["exact"] for r in table], "o-", label="exactly right")
    ax.plot(centers, [r["right"] for r in table], "s--", ms=4, label="or ambiguous with truth")
    ax.legend(fontsize=7, loc="lower right")
    for c, r in zip(centers, table):
        ax.annotate(str(r["n"]), (c, r["right"]), textcoords="offset points", xytext=(4, -10), fontsize=8)
    ax.set(xlabel="confidence (bin centre)", ylabel="share right", ylim=(0, 1.05), title="Reliability of confidence")
    fig.tight_layout()
    fig.savefig(FIGURES / "concealed_reliability.png", dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="recordings per case (default 5)")
    parser.add_argument("--first-seed", type=int, default=100, help="first seed (default 100)")
    parser.add_argument("--samples", type=int, default=5000,
                        help="samples per recording of the own generator (the independent one draws its own length)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument("--generators", nargs="+", default=list(GENERATORS), choices=GENERATORS,
                        help="which generators (default both)")
    parser.add_argument("--channels", nargs="+", default=list(CHANNEL_SETS), choices=CHANNEL_SETS,
                        help="which channel sets (default all three)")
    parser.add_argument("--effects", nargs="+", metavar="EFFECT",
                        help="only these concealed effects (default every effect the generators conceal)")
    parser.add_argument("--out", type=Path, default=RESULTS,
                        help="folder of the rows (concealed_study.csv) and the summary (concealed.md, "
                        "concealed_summary.json); default experiments/results/diagnose, the only folder that also "
                        "gets the figures and --readme")
    parser.add_argument("--before", type=Path, metavar="CSV", default=BEFORE,
                        help="earlier rows for the before/after table, on the recordings both contain "
                        "(default experiments/results/diagnose/concealed_study_before_issue22.csv)")
    parser.add_argument("--rerun", action="store_true", help="drop the stored rows of the selected cases first")
    parser.add_argument("--readme", type=Path, help="also write the summary and reliability tables into this "
                        "file's <!-- section:concealed-study --> block (e.g. README.md)")
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.jobs < 1 or args.samples < 400:
        parser.error("--seeds and --jobs must be >= 1 and --samples >= 400")
    default_out = args.out.resolve() == RESULTS.resolve()
    if args.readme is not None and not default_out:
        parser.error("--readme writes the study's own summary: not with --out")
    if args.effects is not None:
        known = {e for g in args.generators for _, _, e, _, _ in cases((g,), CHANNEL_SETS, 1, 0)}
        unknown = sorted(set(args.effects) - known)
        if unknown:
            parser.error(f"--effects: {', '.join(unknown)} not concealed by {', '.join(args.generators)} "
                         f"(known: {', '.join(sorted(known))})")
    todo = cases(args.generators, args.channels, args.seeds, args.first_seed, args.effects)
    runs = RUNS if default_out else args.out / RUNS.name
    rows = load_rows(runs)
    if args.rerun:
        selected = {(g, c, e, str(s)) for g, c, e, _, s in todo}
        rows = [r for r in rows if (r["generator"], r["channels"], r["effect"], r["seed"]) not in selected]
        runs.unlink(missing_ok=True)
    args.out.mkdir(parents=True, exist_ok=True)
    done = {(r["generator"], r["channels"], r["effect"], r["seed"]) for r in rows}
    jobs = [(g, c, e, v, s, args.samples) for g, c, e, v, s in todo if (g, c, e, str(s)) not in done]
    new_file = not runs.exists()
    with open(runs, "a", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=FIELDS)
        if new_file:
            writer.writeheader()
            writer.writerows(rows)
        with ProcessPoolExecutor(max_workers=args.jobs) as pool:
            for row in tqdm(pool.map(run_one, jobs), total=len(jobs), desc="concealed study"):
                writer.writerow(row)
                handle.flush()
                rows.append({k: str(v) for k, v in row.items()})
    summary = summarize(rows)
    summary["before_after"] = before_after(load_rows(args.before), rows)
    # a subset's summary names the command that wrote it; the study's own keeps the plain one of the page
    command = None if default_out else "python -m experiments.diagnose_concealed " + " ".join(
        str(a) for a in (argv if argv is not None else __import__("sys").argv[1:]))
    write_outputs(summary, rows, args.out, args.before, command)
    text = markdown(summary, summary["before_after"], args.before, *([command] if command else []))
    if args.readme is not None:
        from experiments.report_markdown import update_readme

        update_readme(args.readme, page_section(summary), area="concealed-study")
    print(text.split("\n## ")[0])


if __name__ == "__main__":
    main()
