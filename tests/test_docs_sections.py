"""Every generated section of a documentation page is what its script writes from the committed results.

A section sits between ``<!-- section:AREA -->`` and ``<!-- /section:AREA -->``; the scripts
rewrite only that text. Each test rebuilds one section from the committed JSON or CSV, with the
script's own function, and compares: a result file that changed without its page being rewritten
(or a page edited by hand inside its markers) fails here.
"""

from __future__ import annotations

import json
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
DIAGNOSE_RESULTS = ROOT / "experiments" / "results" / "diagnose"


def section(page: pathlib.Path, area: str) -> str:
    text = page.read_text(encoding="utf-8")
    start, end = f"<!-- section:{area} -->", f"<!-- /section:{area} -->"
    assert text.count(start) == 1 and text.count(end) == 1, f"{page}: one {start} ... {end} pair expected"
    return text.split(start, 1)[1].split(end, 1)[0].strip()


def test_targets_table_is_current():
    from experiments.targets import AREA, PAGE, markdown_table

    assert section(PAGE, AREA) == markdown_table().strip(), "rerun: python -m experiments.targets"


def test_targets_table_says_met_or_not_met_for_every_measured_target():
    from experiments.targets import TARGETS, measurement

    for target in TARGETS:
        found = measurement(target.key)
        if found is None:
            continue
        value, _ = found
        assert target.met(value) == (value >= target.bound if target.sense == "at_least" else value <= target.bound)


def test_concealed_study_section_is_current():
    from experiments.diagnose_concealed import RUNS, load_rows, page_section, summarize

    stored = json.loads((DIAGNOSE_RESULTS / "concealed_summary.json").read_text(encoding="utf-8"))
    fresh = json.loads(json.dumps(summarize(load_rows(RUNS))))
    assert {k: v for k, v in stored.items() if k != "before_after"} == fresh, \
        "concealed_summary.json is stale against concealed_study.csv: rerun python -m experiments.diagnose_concealed"
    assert section(DOCS / "results" / "diagnose.md", "concealed-study") == page_section(stored).strip()


def test_other_forms_section_is_current():
    from experiments.diagnose_other_forms import RESULTS, page_section, study_text

    payload = json.loads((RESULTS / "other_forms.json").read_text(encoding="utf-8"))
    text = study_text(payload, RESULTS / "other_forms_before.json")
    assert (RESULTS / "other_forms.md").read_text(encoding="utf-8") == text
    assert section(DOCS / "results" / "diagnose.md", "other-forms") == page_section(text).strip(), \
        "rerun: python -m experiments.diagnose_other_forms --summarize " \
        "experiments/results/diagnose/other_forms.json --page docs/results/diagnose.md"


def test_diagnose_speed_section_is_current():
    from experiments.diagnose_speed import markdown

    rows = json.loads((DIAGNOSE_RESULTS / "speed_20000.json").read_text(encoding="utf-8"))
    page = section(DOCS / "speed.md", "diagnose-speed")
    cores = int(re.search(r"\((\d+) cores;", page).group(1))   # the machine it ran on, not this one
    assert page == markdown(rows, cores=cores).strip()


def test_first_step_section_is_current():
    from experiments.first_step_time import RESULT, markdown

    if not RESULT.exists():
        pytest.fail(f"{RESULT} is missing: run python -m experiments.first_step_time")
    result = json.loads(RESULT.read_text(encoding="utf-8"))
    assert section(DOCS / "speed.md", "first-step") == markdown(result).strip()


def test_bench_sections_are_current():
    from hyst_gym.layer_speed import readme_sections

    text = (DOCS / "bench.md").read_text(encoding="utf-8")
    results = json.loads(text.split("<!-- bench-json -->", 1)[1].split("```json", 1)[1].split("```", 1)[0])
    for layer, body in readme_sections(results).items():
        assert section(DOCS / "speed.md", f"bench-{layer}") == body.strip(), layer


def test_stated_speed_targets_are_the_targets_module():
    """The modules the installed package cannot import the targets from state the same numbers."""
    from experiments.targets import BY_KEY
    from hyst_gym.envs.step_speed import SUITE_TARGETS

    assert SUITE_TARGETS == {"single": BY_KEY["suite_single"].bound, "1024": BY_KEY["suite_vector_1024"].bound}
    for path in ("experiments/results/suite_v1.json",):
        recorded = json.loads((ROOT / path).read_text(encoding="utf-8"))["speed_targets_steps_per_s"]
        assert recorded == {"single": BY_KEY["suite_single"].bound, "1024": BY_KEY["suite_vector_1024"].bound}
    envs = section(DOCS / "speed.md", "bench-envs")
    assert f"| ≥ {BY_KEY['env_single'].bound:,.0f} |" in envs
    assert f"| ≥ {BY_KEY['env_vector_1024'].bound:,.0f} |" in envs


def test_mismatch_tool_targets_take_the_worst_channel_set_and_count_false_alarms_on_none_only():
    """The accuracy rows read per channel set and report the worst: a false alarm is a `none` recording named
    anything else, and an effect recording's right share ignores the `none` recordings."""
    from experiments.targets import _per_channel_set, _worst

    rows = [{"case": c, "channels": ch, "verdict": v, "outcome": o} for c, ch, v, o in (
        ("none_other_numerics", "both", "none", "right"), ("none_other_numerics", "both", "unexplained", "other"),
        ("none_other_numerics", "magnetization", "none", "right"),
        ("mains_pickup", "both", "mains_pickup", "right"),
        ("mains_pickup", "magnetization", "sensor_lag", "wrong_name"),
        ("sensor_gain_drift", "magnetization", "sensor_gain_drift", "right"))]
    nones = _per_channel_set(rows, lambda r: r["case"] == "none_other_numerics", lambda r: r["verdict"] != "none")
    assert nones == {"both": (1, 2), "magnetization": (0, 1)}
    assert _worst(nones, "at_most") == (50.0, "worst both; both 1/2, magnetization 0/1")
    right = _per_channel_set(rows, lambda r: r["case"] != "none_other_numerics", lambda r: r["outcome"] == "right")
    assert right == {"both": (1, 1), "magnetization": (1, 2)}
    assert _worst(right, "at_least")[0] == 50.0
