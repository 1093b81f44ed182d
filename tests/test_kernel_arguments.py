"""No compiled kernel takes more than 12 arguments (issue 15).

State and parameters travel as named structures (namedtuples of arrays, gymnax's
EnvState/EnvParams the model), so a long positional list, where swapping two arrays of one
type compiles and silently gives wrong numbers, is never the contract. Checked statically
with ``ast`` on every ``@njit`` function.

Scope: every module of ``hyst_gym``.
"""

import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "hyst_gym"
MAX_ARGUMENTS = 12


def compiled_kernels(path: pathlib.Path) -> dict[str, int]:
    """``{name: number of positional arguments}`` of the njit/jit/background_kernel-decorated functions in ``path``."""
    kernels = {}
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.FunctionDef) and any(word in ast.unparse(d) for d in node.decorator_list
                                                        for word in ("jit", "background_kernel")):
            kernels[node.name] = len(node.args.args) + len(node.args.kwonlyargs)
    return kernels


def test_kernels_take_at_most_twelve_arguments():
    files = sorted(PACKAGE.rglob("*.py"))
    counts = {f"{f.relative_to(PACKAGE)}::{name}": n for f in files for name, n in compiled_kernels(f).items()}
    assert len(counts) > 20, "expected the kernels of physics, estimation, envs and diagnose"
    too_long = {name: n for name, n in counts.items() if n > MAX_ARGUMENTS}
    assert not too_long, f"kernels with more than {MAX_ARGUMENTS} arguments: {too_long}"


@pytest.mark.parametrize("source, expected", [
    ("from numba import njit\n@njit(cache=True)\ndef f(a, b, c):\n    return a\n", {"f": 3}),
    ("import numba\n@numba.njit\ndef g(*args):\n    return 0\ndef h(a, b):\n    return a\n", {"g": 0}),
])
def test_checker_counts_arguments(tmp_path, source, expected):
    path = tmp_path / "kernels.py"
    path.write_text(source)
    assert compiled_kernels(path) == expected
