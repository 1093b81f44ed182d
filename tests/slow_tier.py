"""The slow tier's list, tests/slow_tests.txt: reading it and matching node ids against it (see conftest.py)."""

from __future__ import annotations

import pathlib

SLOW_LIST = pathlib.Path(__file__).with_name("slow_tests.txt")


def read_slow_entries(path: pathlib.Path = SLOW_LIST) -> list[str]:
    """The entries of the slow list: one per line, ``#`` starts a comment, blank lines skipped."""
    entries = []
    for line in path.read_text(encoding="utf-8").splitlines():
        entry = line.split("#", 1)[0].strip()
        if entry:
            entries.append(entry)
    return entries


def is_listed(nodeid: str, entries: frozenset[str]) -> bool:
    """Whether ``nodeid`` is an entry, or lies under one (module, class, or parametrized function)."""
    if nodeid in entries:
        return True
    base = nodeid.split("[", 1)[0]   # a parametrization of a listed function
    if base in entries:
        return True
    parts = base.split("::")
    return any("::".join(parts[:i]) in entries for i in range(1, len(parts)))
