"""The README's generated sections: the brief leaderboard and the size of a clone.

    python -m experiments.readme_sections                 # rewrite both sections of README.md
    python -m experiments.readme_sections --print         # print them only
    python -m experiments.readme_sections --skip-clone    # the leaderboard only (no git clone)

**Leaderboard.**
Reads ``experiments/results/suite_v1.json`` and, where it exists, ``suite_v2.json`` (the full
profiles, written by ``hyst-gym benchmark --suite v1|v2``; while v2's full profile has not been
run, its reduced profile ``suite_v2_reduced.json``, labelled as such), and lists for every task in the
suite its floor (value and kind), the best input without feedback (the reference) and the
best agent of each kind, with the normalized score (1 = the floor, 0 = the reference). The
full tables are on the site's results pages. ``tests/test_readme.py`` checks that the
README's section is exactly what this script writes.

**Clone size.** Clones the repository's committed ``HEAD`` (``git clone --no-local`` into a
temporary folder, so the pack is what a user downloads), and states the packed size and the
share of it held by trained models (``*.zip`` blobs in the history).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results"
README = ROOT / "README.md"
AREA = "leaderboard"
CLONE_AREA = "clone-size"
#: result files per suite, first found wins (v2's reduced profile stands in until its full profile is run)
SUITES = (("suite_v2", "suite_v2_reduced"), ("suite_v1",))
#: agent kinds the brief table shows one best agent of (the full tables list every agent)
KINDS = ("feedback", "rl")


def _best(agents: dict, kinds) -> tuple[str, dict] | None:
    chosen = [(name, a) for name, a in agents.items() if a.get("kind") in kinds]
    return min(chosen, key=lambda item: item[1]["iqm"]) if chosen else None


def _cell(name: str, agent: dict) -> str:
    normalized = agent.get("normalized", {})
    normalized = normalized.get("iqm", normalized.get("value"))  # v1 writes "iqm", v2 "value"
    score = f"; score {normalized:.2f}" if normalized is not None else ""
    return f"{name} {agent['iqm']:.3g}{score}"


def rows(result: dict) -> list[str]:
    """Markdown rows, one per task in the suite, of one suite's result file."""
    out = []
    for task_id, task in result["tasks"].items():
        if not task.get("in_suite"):
            continue
        floor = task["floor"]
        agents = task["agents"]
        reference = task.get("reference")
        cells = [_cell(reference, agents[reference]) if reference in agents else "–"]
        for kinds in (("feedback",), ("rl",)):
            best = _best(agents, kinds)
            cells.append(_cell(*best) if best else "–")
        out.append(f"| `{task_id}` | {floor['value']:.3g} ({floor['kind']}) | " + " | ".join(cells) + " |")
    return out


def section() -> str:
    lines = ["Written by `python -m experiments.readme_sections` from the committed result files; "
             "metric per task (lower is better): IQM over held-out draws, or the RMS over them where the floor is "
             "a Van Trees bound (a bound on a mean square); score = (reference − agent) / "
             "(reference − floor): 1 reaches the floor, 0 is the best input without feedback, and above 1 beats an "
             "oracle floor (the best of a fixed family of designs, not a bound). Terms: [glossary](docs/glossary.md); "
             "full tables: "
             "[docs/results/suite.md](docs/results/suite.md).", "",
             "| task | floor (kind) | reference: best without feedback | best feedback rule | best RL |",
             "|---|---|---|---|---|"]
    found = []
    for stems in SUITES:
        path = next((RESULTS / f"{stem}.json" for stem in stems if (RESULTS / f"{stem}.json").exists()), None)
        if path is not None:
            result = json.loads(path.read_text(encoding="utf-8"))
            lines += rows(result)
            note = "" if result.get("profile") == "full" else f": {result.get('profile_note', '')}"
            found.append(f"{result.get('suite', path.stem)} ({result.get('profile', '?')} profile{note})")
    if not found:
        raise FileNotFoundError(f"no suite result file in {RESULTS}")
    lines += ["", "Suites: " + ", ".join(found) + "."]
    return "\n".join(lines)


def _git(*args, cwd=ROOT) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True, text=True).stdout


def clone_size() -> str:
    """A paragraph stating the packed size of a fresh clone of HEAD and the models' share."""
    head = _git("rev-parse", "--short", "HEAD").strip()
    with tempfile.TemporaryDirectory() as folder:
        clone = pathlib.Path(folder) / "clone"
        _git("clone", "--quiet", "--no-local", str(ROOT), str(clone))
        packs = sum(p.stat().st_size for p in (clone / ".git" / "objects" / "pack").glob("*.pack"))
        listing = _git("rev-list", "--objects", "--all", cwd=clone)
        zips = "\n".join(line.split(" ", 1)[0] for line in listing.splitlines() if line.endswith(".zip"))
        sizes = subprocess.run(["git", "cat-file", "--batch-check=%(objectsize:disk)"], cwd=clone,
                               input=zips + "\n", check=True, capture_output=True, text=True).stdout
        models = sum(int(s) for s in sizes.split() if s.isdigit())
        tracked = len([p for p in _git("ls-files", "*.zip", cwd=clone).splitlines() if p])
    return (f"Written by `python -m experiments.readme_sections` at commit `{head}`: a fresh clone downloads "
            f"**{packs / 2**20:.0f} MiB** (packed), of which {models / 2**20:.0f} MiB are trained models "
            f"(`model.zip` files; {tracked} in the tree, each loaded by a results table or the demo). New "
            f"training runs write their models under `experiments/results/raw/`, which `.gitignore` keeps out "
            f"of the history; commit a model only when a table or the demo loads it.")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.readme_leaderboard",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--print", action="store_true", help="print the sections; leave README.md alone")
    parser.add_argument("--skip-clone", action="store_true", help="only the leaderboard (no git clone)")
    args = parser.parse_args(argv)
    try:
        sections = {AREA: section()}
        if not args.skip_clone:
            sections[CLONE_AREA] = clone_size()
    except (OSError, KeyError, ValueError, subprocess.CalledProcessError) as error:
        print(f"readme_sections: error: {error}", file=sys.stderr)
        return 2
    from experiments.report_markdown import update_readme

    for area, text in sections.items():
        if args.print:
            print(text, end="\n\n")
        else:
            update_readme(README, text, area=area)
            print(f"rewrote the {area} section of {README.name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
