"""The layers import one way only: physics <- estimation <- envs; diagnose on physics/estimation.

Checked statically with ``ast`` so that a lazy import inside a function counts too.
"""

import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "hyst_gym"

ALLOWED = {
    "physics": set(),
    "estimation": {"physics"},
    "envs": {"physics", "estimation"},
    "diagnose": {"physics", "estimation"},
}


def imported_layers(path: pathlib.Path, layer: str) -> set[str]:
    """hyst_gym sub-packages and top-level project packages that ``path`` imports."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.ImportFrom):
            if node.level == 0:
                names = [node.module or ""]
            elif node.level == 1:  # from .x import y stays inside the layer (or names its own modules)
                names = [f"hyst_gym.{layer}.{node.module or ''}"]
            else:  # from ..x import y
                names = [f"hyst_gym.{node.module or ''}"] if node.module else \
                    [f"hyst_gym.{alias.name}" for alias in node.names]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] in ("baselines", "experiments"):
                found.add(parts[0])
            elif parts[0] == "hyst_gym":
                found.add(parts[1] if len(parts) > 1 and parts[1] else "hyst_gym")
    return found - {layer}


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_layer_imports_only_what_it_may_use(layer):
    files = sorted((PACKAGE / layer).rglob("*.py"))
    assert files, f"no modules found for layer {layer}"
    violations = {str(f.relative_to(PACKAGE)): sorted(imported_layers(f, layer) - ALLOWED[layer])
                  for f in files}
    violations = {f: v for f, v in violations.items() if v}
    assert not violations, f"{layer} imports layers it may not use: {violations}"


def test_checker_sees_a_violation(tmp_path):
    offending = tmp_path / "bad.py"
    offending.write_text("def f():\n    from ..envs import core\n    import baselines.agents\n")
    assert imported_layers(offending, "physics") == {"envs", "baselines"}
