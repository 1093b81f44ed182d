"""Two test tiers: ``pytest -m "not slow"`` for contributors, the full suite in CI.

A test is slow when it carries ``@pytest.mark.slow`` or when ``tests/slow_tests.txt`` lists it.
The list keeps the tier in one file (with the measured durations as comments) instead of a
decorator in every test module; an entry is a node id (``tests/x/test_y.py::test_z``, which
also covers every parametrization ``test_z[...]``), a class (``tests/x/test_y.py::TestC``) or a
whole module (``tests/x/test_y.py``). ``tests/test_tiers.py`` checks that every entry still
names a test that exists, so a renamed test cannot drop out of the slow tier unnoticed.
"""

from __future__ import annotations

import os

import pytest

from slow_tier import is_listed, read_slow_entries

# The tests compare and time the compiled kernels and start no background compile helpers: kernels
# compile on first use, as plain numba (hyst_gym/physics/background_compile.py; its own modes are
# tested in fresh interpreters by tests/envs/test_background_compile.py).
os.environ.setdefault("HYST_GYM_COMPILE", "foreground")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    entries = frozenset(read_slow_entries())
    for item in items:
        if is_listed(item.nodeid, entries):
            item.add_marker(pytest.mark.slow)
