"""The documentation reads as documentation: results pages stay short, and neither the pages nor
the docstrings the API reference renders carry issue numbers or work-history phrases (the history
lives in ``docs/changelog.md``)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS_PAGE_LIMIT = 25_000  # characters

#: Phrases that tell how the work went rather than what the code does or what was measured.
HISTORY = re.compile(
    r"\bissues? #?\d+|\bthis session\b|\b(?:second|third|fourth|fifth|sixth|seventh) run\b"
    r"|\bbefore issue\b|\bhelper-\d+",
    re.IGNORECASE,
)


def _pages() -> list[Path]:
    return sorted(p for p in (ROOT / "docs").rglob("*.md") if p.name != "changelog.md")


def _sources() -> list[Path]:
    return sorted((ROOT / "hyst_gym").rglob("*.py"))


@pytest.mark.parametrize("page", sorted((ROOT / "docs" / "results").glob("*.md")), ids=lambda p: p.name)
def test_results_page_is_short(page):
    size = len(page.read_text(encoding="utf-8"))
    assert size <= RESULTS_PAGE_LIMIT, f"{page.relative_to(ROOT)}: {size} characters > {RESULTS_PAGE_LIMIT}"


def _history_lines(paths) -> list[str]:
    found = []
    for path in paths:
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if HISTORY.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    return found


def test_pages_carry_no_work_history():
    assert _history_lines(_pages()) == []


def test_package_sources_carry_no_work_history():
    """Docstrings render in the API reference; comments are read by maintainers, who need the why."""
    assert _history_lines(_sources()) == []


def test_history_pattern_catches_what_it_should():
    """Cross-check of the pattern on text written here, so a broken pattern cannot pass vacuously."""
    assert HISTORY.search("Targets (issue 13, 2-core machine)")
    assert HISTORY.search("as this session's measurement shows")
    assert HISTORY.search("A fifth run gave")
    assert not HISTORY.search("raises an issue when the file is missing; 13 runs")
