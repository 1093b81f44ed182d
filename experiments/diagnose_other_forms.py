"""Blind study of the mismatch tool on recordings whose physics takes other forms than its own.

Recordings come from :mod:`experiments.other_forms` (forms the tool does not use, other
numerics). For every case, channel set the case can show and seed, the recording is written
to a temporary CSV and diagnosed blind with ``hyst_gym.diagnose.diagnose(path, progress=False)``.
Outcome of a recording (from ``report.to_json()``):

* ``right`` -- the verdict is in the case's set of right verdicts;
* ``ambiguous_with_truth`` -- ``ambiguous`` with a right name among ``candidates_tied``;
* ``wrong_name`` -- a single effect name outside the set;
* ``missed`` -- ``none`` for a case with an effect;  ``other`` -- anything else (e.g.
  ``unexplained`` or ``ambiguous`` without the truth for a nameable effect, ``unexplained`` on
  ``none_other_numerics``, or ``error`` if the tool raised).

Writes ``experiments/results/diagnose/other_forms.json`` (per-recording rows and summaries) and
``other_forms.md`` (tables per channel set, per case, per case x channel set, per form, rows)::

    nice -n 10 .venv/bin/python -m experiments.diagnose_other_forms --seeds 2 --jobs 1
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from experiments import other_forms

ROOT = Path(__file__).resolve().parent
RESULTS = ROOT / "results" / "diagnose"
OUTCOMES = ("right", "ambiguous_with_truth", "wrong_name", "missed", "other")


def jobs_for(cases, channel_sets, seeds, first_seed, samples, noise="white"):
    """Every (case, channels, seed, samples, noise) the case can show; skipped pairs listed apart."""
    jobs, skipped = [], []
    for case in cases:
        for channels in channel_sets:
            if channels not in other_forms.CASES[case].channel_sets:
                skipped.append(f"{case}/{channels}")
                continue
            jobs += [(case, channels, seed, samples, noise) for seed in range(first_seed, first_seed + seeds)]
    return jobs, skipped


def outcome(case: str, verdict: str, tied) -> str:
    expected = other_forms.CASES[case].expected
    if verdict in expected:
        return "right"
    if verdict == "ambiguous" and expected & set(tied):
        return "ambiguous_with_truth"
    if verdict == "none":
        return "missed"
    if verdict in ("unexplained", "ambiguous", "error"):
        return "other"
    return "wrong_name"


def run_one(job) -> dict:
    """Generate, write, diagnose blind and score one recording."""
    from hyst_gym.diagnose import diagnose

    case, channels, seed, samples, noise = job
    row = {"case": case, "channels": channels, "seed": seed, "noise": noise}
    with tempfile.TemporaryDirectory(prefix="other_forms_") as folder:
        path = Path(folder) / "recording.csv"
        started = time.perf_counter()
        recording, truth = other_forms.write(case, seed, channels, path, n_samples=samples, noise=noise)
        if "noise_colour" in truth:
            row["noise_colour"] = truth["noise_colour"]
        row["generate_seconds"] = round(time.perf_counter() - started, 2)
        started = time.perf_counter()
        try:
            report = diagnose(path, progress=False).to_json()
        except Exception as error:  # the tool is being changed: record, do not stop the study
            report = {"verdict": "error", "confidence": float("nan"), "candidates_tied": [],
                      "error": f"{type(error).__name__}: {error}"[:300]}
        row["seconds"] = round(time.perf_counter() - started, 2)
    tied = list(report.get("candidates_tied") or [])
    row.update(form=truth["form"], verdict=report["verdict"], slot=report.get("slot"), tied=tied,
               confidence=report.get("confidence"), outcome=outcome(case, report["verdict"], tied),
               visibility=truth["visibility"], size_boost=round(truth["size_boost"], 3),
               samples=recording.size, sample_rate_hz=round(truth["sample_rate"], 1),
               noise_relative=truth["noise_rel"], excitation=truth["excitation_family"],
               numerics=truth["numerics"], load_average=round(os.getloadavg()[0], 2),
               improvement=report.get("improvement"),
               baseline_heldout=(report.get("baseline") or {}).get("heldout_rmse"))
    if "error" in report:
        row["error"] = report["error"]
    return row


def tally(rows) -> dict:
    n = len(rows)
    counts = {o: sum(r["outcome"] == o for r in rows) for o in OUTCOMES}
    # held-out RMSE reduction of the named verdict where it is right (the ">= 60 % per form");
    # rows of an earlier study without the field are left out
    reductions = sorted(r["improvement"] for r in rows if r["outcome"] == "right" and r.get("improvement")
                        and r["verdict"] not in ("none", "unexplained", "ambiguous"))
    return {"n": n, **counts,
            "median_reduction_when_named_right": reductions[len(reductions) // 2] if reductions else None,
            "min_reduction_when_named_right": reductions[0] if reductions else None,
            "right_share": counts["right"] / n if n else None,
            "right_or_ambiguous_share": (counts["right"] + counts["ambiguous_with_truth"]) / n if n else None,
            "verdicts": {v: sum(r["verdict"] == v for r in rows) for v in sorted({r["verdict"] for r in rows})}}


def summarize(rows) -> dict:
    def by(*keys):
        groups = {}
        for r in rows:
            groups.setdefault("/".join(str(r[k]) for k in keys), []).append(r)
        return {k: tally(v) for k, v in sorted(groups.items())}

    seconds = sorted(r["seconds"] for r in rows)
    return {"total": tally(rows), "per_channel_set": by("channels"), "per_case": by("case"),
            "per_case_and_channel_set": by("case", "channels"), "per_case_and_form": by("case", "form"),
            "seconds_per_diagnosis": {"median": seconds[len(seconds) // 2], "min": seconds[0], "max": seconds[-1]}
            if seconds else None}


def _pct(x):
    return "–" if x is None else f"{100 * x:.0f} %"


def _table(title, groups):
    lines = [f"## {title}", "", "| group | n | right | right or ambiguous with truth | wrong name | missed | other "
             "| held-out reduction when named right: median (min) | verdicts |",
             "|---|---|---|---|---|---|---|---|---|"]
    for key, t in groups.items():
        verdicts = ", ".join(f"{v} {c}" for v, c in t["verdicts"].items())
        median, least = t.get("median_reduction_when_named_right"), t.get("min_reduction_when_named_right")
        reduction = "–" if median is None else f"{_pct(median)} ({_pct(least)})"
        lines.append(f"| {key} | {t['n']} | {t['right']} ({_pct(t['right_share'])}) | "
                     f"{t['right'] + t['ambiguous_with_truth']} ({_pct(t['right_or_ambiguous_share'])}) | "
                     f"{t['wrong_name']} | {t['missed']} | {t['other']} | {reduction} | {verdicts} |")
    return lines + [""]


#: Confidence bins of the reliability table (the issue: >= 90 % of verdicts at confidence >= 0.8 exactly right).
CONFIDENCE_BINS = ((0.0, 0.2), (0.2, 0.5), (0.5, 0.8), (0.8, 0.9), (0.9, 1.0))


def reliability(rows) -> list[str]:
    """Markdown lines: per confidence bin, how many verdicts, and how often each kind of verdict holds.

    A single name holds when it is exactly right; an ``ambiguous`` verdict states that the truth is one of
    its tied effects, and its confidence is its margin over the best effect left out of the tie (see
    :mod:`hyst_gym.diagnose.decide`), so it holds when the truth is in the tie. Both are shown apart, with
    every other verdict (``none``, ``unexplained``), so that no kind hides another."""
    lines = ["## Reliability of `confidence`", "",
             "| confidence | n | exactly right (all verdicts) | single names: right / n | ties: truth in the tie / n "
             "| verdict holds |", "|---|---|---|---|---|---|"]
    scored = [r for r in rows if r["confidence"] is not None and r["confidence"] == r["confidence"]]

    def share(k, n):
        return f"{k} ({_pct(k / n)})" if n else "–"

    def row(label, lo, hi):
        group = [r for r in scored if lo <= r["confidence"] < hi or (hi == 1.0 and r["confidence"] == 1.0)]
        right = sum(r["outcome"] == "right" for r in group)
        ties = [r for r in group if r["verdict"] == "ambiguous"]
        tie_holds = sum(r["outcome"] == "ambiguous_with_truth" for r in ties)
        singles = [r for r in group if r["verdict"] not in ("ambiguous", "none", "unexplained")]
        single_right = sum(r["outcome"] == "right" for r in singles)
        return (f"| {label} | {len(group)} | {share(right, len(group))} | {single_right} / {len(singles)} | "
                f"{tie_holds} / {len(ties)} | {share(right + tie_holds, len(group))} |")

    lines += [row(f"{lo:.1f}-{hi:.1f}", lo, hi) for lo, hi in CONFIDENCE_BINS]
    return lines + [row("**0.8-1.0 (all)**", 0.8, 1.0), ""]


def markdown(summary, rows, command, skipped) -> str:
    studied = {r["case"] for r in rows}
    right_sets = ", ".join(f"`{c}`: {{{', '.join(sorted(s.expected))}}}" for c, s in other_forms.CASES.items()
                           if c in studied)
    lines = ["# Mismatch tool on physics in other forms", "",
             f"Generated by `{command}` (generator `experiments/other_forms.py`). Right verdicts per case: "
             f"{right_sets}.", ""]
    if any(r.get("noise", "white") != "white" for r in rows):
        lines += ["Sensor noise: coloured (`experiments.other_forms.coloured_noise`): per channel, 30-70 % of the "
                  "variance AR(1) with a correlation time of 3-30 samples or flicker (1/f^0.8-1.5 up to a period of "
                  f"{other_forms.FLICKER_LONGEST_PERIOD:.0f} samples), the rest white; the same standard deviation "
                  "as the white studies. The tool estimates each channel's noise from second differences, which see "
                  "mostly the white part.", ""]
    if skipped:
        lines += [f"Not run (the effect cannot show in that channel set): {', '.join(skipped)}.", ""]
    sec = summary["seconds_per_diagnosis"]
    if sec:
        lines += [f"Seconds per diagnosis: median {sec['median']:.1f}, min {sec['min']:.1f}, max {sec['max']:.1f}.", ""]
    lines += _table("Total", {"all": summary["total"]})
    lines += _table("Per channel set", summary["per_channel_set"])
    lines += _table("Per case", summary["per_case"])
    lines += _table("Per case and channel set", summary["per_case_and_channel_set"])
    lines += _table("Per case and form", summary["per_case_and_form"])
    lines += reliability(rows)
    lines += ["## Recordings", "", "| case | channels | seed | form | verdict | tied | confidence | outcome | "
              "visibility (noise sd) | s |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        vis = ", ".join(f"{k[0]} {v:.1f}" for k, v in r["visibility"].items()) or "–"
        conf = r["confidence"]
        conf = "–" if conf is None or conf != conf else f"{conf:.2f}"
        lines.append(f"| {r['case']} | {r['channels']} | {r['seed']} | {r['form']} | {r['verdict']} | "
                     f"{', '.join(r['tied']) or '–'} | {conf} | {r['outcome']} | {vis} | {r['seconds']:.1f} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2, help="recordings per case and channel set (default 2)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--samples", type=int, default=other_forms.DEFAULT_SAMPLES)
    parser.add_argument("--cases", nargs="+", default=list(other_forms.ALL_CASES), choices=other_forms.ALL_CASES)
    parser.add_argument("--channels", nargs="+", default=list(other_forms.CHANNEL_SETS),
                        choices=other_forms.CHANNEL_SETS)
    parser.add_argument("--noise", choices=other_forms.NOISE_COLOURS, default="white",
                        help="the sensor noise: white (default) or coloured (AR(1) or flicker mixed with white, "
                        "experiments.other_forms.coloured_noise); with --page, coloured writes its own section, "
                        "<!-- section:other-forms-coloured-noise -->")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1: a single process)")
    parser.add_argument("--out", type=Path, default=RESULTS / "other_forms",
                        help="stem of the .json and .md to write (default experiments/results/diagnose/other_forms)")
    parser.add_argument("--page", type=Path, help="also write the tables into this page's "
                        "<!-- section:other-forms --> block (e.g. docs/results/diagnose.md)")
    parser.add_argument("--summarize", type=Path, metavar="JSON",
                        help="diagnose nothing: rewrite the .md (and --page) from a stored study JSON")
    parser.add_argument("--before", type=Path, metavar="JSON", default=RESULTS / "other_forms_before.json",
                        help="an earlier study JSON: a before/after table on the recordings both contain "
                        "(default experiments/results/diagnose/other_forms_before.json, if present)")
    args = parser.parse_args(argv)
    if args.summarize is not None:
        if not args.summarize.is_file():
            parser.error(f"--summarize {args.summarize}: no such file")
        payload = json.loads(args.summarize.read_text())
        _write_texts(args, payload)
        return
    if args.seeds < 1 or args.jobs < 1 or args.samples < 400:
        parser.error("--seeds and --jobs must be >= 1 and --samples >= 400")
    command = "python -m experiments.diagnose_other_forms " + " ".join(argv if argv is not None else
                                                                         __import__("sys").argv[1:])
    jobs, skipped = jobs_for(args.cases, args.channels, args.seeds, args.first_seed, args.samples, args.noise)
    rows = []
    if args.jobs == 1:
        results = map(run_one, jobs)
    else:
        pool = ProcessPoolExecutor(max_workers=args.jobs)
        results = pool.map(run_one, jobs)
    for i, row in enumerate(results, 1):
        rows.append(row)
        print(f"[{i}/{len(jobs)}] {row['case']}/{row['channels']}/seed {row['seed']} ({row['form']}): "
              f"{row['verdict']} {row['confidence']} -> {row['outcome']} ({row['seconds']:.1f} s)", flush=True)
    if args.jobs != 1:
        pool.shutdown()
    summary = summarize(rows)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    payload = {"command": command, "skipped": skipped, "summary": summary, "rows": rows}
    args.out.with_suffix(".json").write_text(json.dumps(payload, indent=2, default=str) + "\n")
    _write_texts(args, payload)
    print("\n".join(_table("Per case and channel set", summary["per_case_and_channel_set"])))


def before_after(before_rows, after_rows) -> list[str]:
    """Markdown lines: per case and channel set, on the recordings (case, channels, seed) that both row sets
    contain, right and wrong names before -> after, and how many verdicts changed."""
    key = lambda r: (r["case"], r["channels"], int(r["seed"]))  # noqa: E731
    earlier = {key(r): r for r in before_rows}
    pairs = [(earlier[key(r)], r) for r in after_rows if key(r) in earlier]
    lines = ["| case / channels | recordings | right before → after | right or ambiguous with truth before → after "
             "| wrong names before → after | verdicts changed |", "|---|---|---|---|---|---|"]
    groups = sorted({f"{a['case']}/{a['channels']}" for _, a in pairs}) + ["all"]
    for case in groups:
        group = [(b, a) for b, a in pairs if case in ("all", f"{a['case']}/{a['channels']}")]
        # both scored by today's yardstick (outcome() reads the case's right verdicts now)
        scored = [(outcome(b["case"], b["verdict"], b.get("tied") or []),
                   outcome(a["case"], a["verdict"], a.get("tied") or [])) for b, a in group]

        def count(which, names, scored=scored):
            return sum(s[which] in names for s in scored)

        lines.append(f"| {case} | {len(group)} | {count(0, ('right',))} → {count(1, ('right',))} | "
                     f"{count(0, ('right', 'ambiguous_with_truth'))} → {count(1, ('right', 'ambiguous_with_truth'))} | "
                     f"{count(0, ('wrong_name',))} → {count(1, ('wrong_name',))} | "
                     f"{sum(b['verdict'] != a['verdict'] for b, a in group)} |")
    return lines


#: the study markdown's sections that the documentation page shows; the others (per case and
#: channel set, per form, every recording, before/after) stay in ``other_forms.md``
PAGE_SECTIONS = ("Total", "Per channel set", "Per case", "Reliability of `confidence`",
                 "Before and after (the same recordings)")


#: the sections a coloured-noise study shows on the page (its own block: a false-alarm check, few cases)
COLOURED_PAGE_SECTIONS = ("Per case and channel set", "Reliability of `confidence`")


def page_section(text: str, sections=PAGE_SECTIONS,
                 study_md: str = "experiments/results/diagnose/other_forms.md") -> str:
    """The page's section from the study's markdown: its preamble and ``sections``."""
    parts = text.split("\n## ")
    body = parts[0].split("\n", 2)[2]   # drop the title line and the blank line after it
    kept = [p for p in parts[1:] if p.split("\n", 1)[0].strip() in sections]
    return ("\n### ".join([body, *kept]).rstrip("\n")
            + f"\n\nPer case and channel set, per form, and every recording: `{study_md}`.\n")


def study_text(payload, before=None) -> str:
    """The study's markdown from its JSON payload, with the before/after table against the study
    JSON ``before`` where that file exists."""
    text = markdown(payload["summary"], payload["rows"], payload["command"], payload["skipped"])
    if before is not None and before.is_file():
        earlier = json.loads(before.read_text())
        text += "\n".join(["", "## Before and after (the same recordings)", "",
                           f"Rows of `{before.name}` (`{earlier['command']}`, an earlier tool) against this run, "
                           "on the recordings both contain, both scored by today's right verdicts.", ""]
                          + before_after(earlier["rows"], payload["rows"])) + "\n"
    return text


def _write_texts(args, payload):
    """The study's markdown, and with ``--page`` its tables (less the title) in the page's section."""
    text = study_text(payload, getattr(args, "before", None))
    args.out.with_suffix(".md").write_text(text)
    if args.page is not None:
        from experiments.report_markdown import update_readme

        if any(r.get("noise", "white") != "white" for r in payload["rows"]):
            section = page_section(text, COLOURED_PAGE_SECTIONS, args.out.with_suffix(".md").as_posix())
            update_readme(args.page, section, area="other-forms-coloured-noise")
        else:
            update_readme(args.page, page_section(text), area="other-forms")


if __name__ == "__main__":
    main()
