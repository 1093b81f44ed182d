"""The slow tier's list (tests/slow_tests.txt) names tests that exist, and the matching is exact."""

from __future__ import annotations

import ast
import pathlib

import pytest

from slow_tier import SLOW_LIST, is_listed, read_slow_entries

ROOT = pathlib.Path(__file__).resolve().parents[1]


def defined_names(module: pathlib.Path) -> set[str]:
    """``f`` for each top-level test function, ``C`` and ``C::m`` for each class and its methods."""
    names: set[str] = set()
    for node in ast.parse(module.read_text(encoding="utf-8")).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.ClassDef):
            names.add(node.name)
            names.update(f"{node.name}::{item.name}" for item in node.body
                         if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)))
    return names


@pytest.mark.parametrize("entry", read_slow_entries())
def test_every_slow_entry_names_an_existing_test(entry):
    path, _, rest = entry.partition("::")
    module = ROOT / path
    assert module.is_file() and module.name.startswith("test_"), f"{SLOW_LIST.name}: no test module {path}"
    if rest:
        assert rest in defined_names(module), f"{SLOW_LIST.name}: {path} defines no test {rest}"


def test_no_duplicate_entries():
    entries = read_slow_entries()
    assert len(entries) == len(set(entries))


def test_listing_matches_module_class_function_and_parametrizations():
    entries = frozenset({"tests/a/test_m.py", "tests/b/test_n.py::test_f", "tests/c/test_o.py::TestK"})
    assert is_listed("tests/a/test_m.py::test_anything[3]", entries)
    assert is_listed("tests/b/test_n.py::test_f", entries)
    assert is_listed("tests/b/test_n.py::test_f[seed-1-x::y]", entries)
    assert is_listed("tests/c/test_o.py::TestK::test_m[2]", entries)
    # a longer name that merely starts like an entry is not that entry
    assert not is_listed("tests/b/test_n.py::test_f_other", entries)
    assert not is_listed("tests/b/test_n.py::test_g", entries)
    assert not is_listed("tests/a/test_m2.py::test_f", entries)
    assert not is_listed("tests/c/test_o.py::TestKo::test_m", entries)


def test_comments_and_blank_lines_are_not_entries(tmp_path):
    listing = tmp_path / "slow.txt"
    listing.write_text("# header\n\ntests/a/test_m.py::test_f   # 12.3 s\n  tests/b/test_n.py\n", encoding="utf-8")
    assert read_slow_entries(listing) == ["tests/a/test_m.py::test_f", "tests/b/test_n.py"]
