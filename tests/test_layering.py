"""The layers import one way only.

* inside ``hyst_gym``: physics <- estimation <- envs; diagnose on physics/estimation; the
  top-level modules (CLI, bench) may use every layer;
* the repository's packages: hyst_gym <- baselines <- experiments (``hyst_gym`` never imports
  the other two, ``baselines`` never imports ``experiments``);
* the tests of a ``hyst_gym`` layer import neither ``baselines`` nor ``experiments``;
* no two modules of one package import each other, directly or around a longer cycle.

Checked statically with ``ast``: every ``import``/``from`` node anywhere in a file counts, so a
lazy import inside a function (the usual way a cycle is hidden) counts too.
"""

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "hyst_gym"

ALLOWED = {
    "physics": set(),
    "estimation": {"physics"},
    "envs": {"physics", "estimation"},
    "diagnose": {"physics", "estimation"},
}
#: what each of the repository's top-level packages may import of the others
PROJECT_ALLOWED = {
    "hyst_gym": set(),
    "baselines": {"hyst_gym"},
    "experiments": {"hyst_gym", "baselines"},
}
#: packages checked for import cycles among their own modules
CYCLE_CHECKED = [PACKAGE / layer for layer in sorted(ALLOWED)] + [ROOT / "baselines", ROOT / "experiments"]


def module_name(path: pathlib.Path, root: pathlib.Path = ROOT) -> str:
    """Dotted module name of ``path`` below ``root`` (a package's ``__init__`` is the package)."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_modules(path: pathlib.Path, root: pathlib.Path = ROOT) -> set[str]:
    """Absolute dotted names of everything ``path`` imports, anywhere in the file.

    ``from X import y`` yields both ``X`` and ``X.y``, since ``y`` may be a submodule;
    callers keep the names that are modules they know."""
    name = module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base_parts = package.split(".")
                base_parts = base_parts[:len(base_parts) - (node.level - 1)]
                base = ".".join(base_parts + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names if alias.name != "*")
    return found


def imported_layers(path: pathlib.Path, layer: str) -> set[str]:
    """hyst_gym sub-packages and top-level project packages that ``path`` (in ``layer``) imports."""
    found = set()
    for name in imported_modules(path, _root_of(path)):
        parts = name.split(".")
        if parts[0] in ("baselines", "experiments"):
            found.add(parts[0])
        elif parts[0] == "hyst_gym":
            found.add(parts[1] if len(parts) > 1 else "hyst_gym")
    return found - {layer}


def _root_of(path: pathlib.Path) -> pathlib.Path:
    """The folder a module's dotted name is counted from: above the first package folder."""
    path = path.resolve()
    root = path.parent
    while (root / "__init__.py").is_file():
        root = root.parent
    return root


def import_cycles(package_dir: pathlib.Path) -> list[list[str]]:
    """Cycles among the modules of one package (strongly connected components of the import graph)."""
    root = _root_of(package_dir / "__init__.py")
    modules = {module_name(f, root): f for f in sorted(package_dir.rglob("*.py"))}
    package = module_name(package_dir / "__init__.py", root)
    graph = {}
    for name, path in modules.items():
        # importing a submodule runs its package's __init__, which is not a cycle of its own
        graph[name] = sorted(m for m in imported_modules(path, root)
                             if m in modules and m != name and m != package)
    # Tarjan's algorithm, iterative order is irrelevant: the components are what is asserted
    index, low, on_stack, stack, cycles, counter = {}, {}, set(), [], [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return cycles


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_layer_imports_only_what_it_may_use(layer):
    files = sorted((PACKAGE / layer).rglob("*.py"))
    assert files, f"no modules found for layer {layer}"
    violations = {str(f.relative_to(PACKAGE)): sorted(imported_layers(f, layer) - ALLOWED[layer])
                  for f in files}
    violations = {f: v for f, v in violations.items() if v}
    assert not violations, f"{layer} imports layers it may not use: {violations}"


def test_top_level_modules_import_no_checkout_package():
    """The CLI and the bench ship in the wheel: they may use every layer of hyst_gym but must not
    import baselines/ or experiments/ (the CLI loads those by name, for checkout-only commands)."""
    files = sorted(PACKAGE.glob("*.py"))
    assert {f.name for f in files} >= {"cli.py", "layer_speed.py", "__init__.py"}
    violations = {f.name: sorted(imported_layers(f, "hyst_gym") & {"baselines", "experiments"}) for f in files}
    violations = {f: v for f, v in violations.items() if v}
    assert not violations, f"hyst_gym's top-level modules import checkout packages: {violations}"


def test_cli_loads_checkout_packages_only_for_checkout_commands():
    from hyst_gym.cli import CHECKOUT_PACKAGES, SUBCOMMANDS
    for name, subcommand in SUBCOMMANDS.items():
        in_checkout = subcommand.module.split(".")[0] in CHECKOUT_PACKAGES
        assert in_checkout == subcommand.checkout_only, name


@pytest.mark.parametrize("project_package", sorted(PROJECT_ALLOWED))
def test_project_packages_import_one_way(project_package):
    files = sorted((ROOT / project_package).rglob("*.py"))
    assert files
    forbidden = set(PROJECT_ALLOWED) - PROJECT_ALLOWED[project_package] - {project_package}
    violations = {}
    for f in files:
        used = {m.split(".")[0] for m in imported_modules(f)} & forbidden
        if used:
            violations[str(f.relative_to(ROOT))] = sorted(used)
    assert not violations, f"{project_package} imports packages above it: {violations}"


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_layer_tests_import_no_checkout_package(layer):
    """A hyst_gym layer's tests must run on the wheel alone, so they cannot lean on
    baselines/ or experiments/ (a shared fixture belongs in the layer or in the test helpers)."""
    files = sorted((ROOT / "tests" / layer).rglob("*.py"))
    violations = {}
    for f in files:
        used = {m.split(".")[0] for m in imported_modules(f)} & {"baselines", "experiments"}
        if used:
            violations[str(f.relative_to(ROOT))] = sorted(used)
    assert not violations, f"tests/{layer} imports checkout packages: {violations}"


@pytest.mark.parametrize("package_dir", CYCLE_CHECKED, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_import_cycle_within_a_package(package_dir):
    assert not import_cycles(package_dir), f"import cycles in {package_dir.relative_to(ROOT)}"


def test_checker_sees_a_violation(tmp_path):
    offending = tmp_path / "bad.py"
    offending.write_text("def f():\n    from ..envs import core\n    import baselines.agents\n")
    package = tmp_path / "hyst_gym" / "physics"
    package.mkdir(parents=True)
    for folder in (package.parent, package):
        (folder / "__init__.py").write_text("")
    (package / "bad.py").write_text(offending.read_text())
    assert imported_layers(package / "bad.py", "physics") == {"envs", "baselines"}


def test_checker_sees_a_cycle_hidden_in_a_function(tmp_path):
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from .b import g\n\ndef f():\n    return g()\n")
    (package / "b.py").write_text("def g():\n    from .a import f\n    return f\n")
    (package / "c.py").write_text("from . import a\n")
    assert import_cycles(package) == [["pkg.a", "pkg.b"]]
    (package / "b.py").write_text("def g():\n    return 1\n")
    assert import_cycles(package) == []
