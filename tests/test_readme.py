"""The README works as written.

* Every ```python block of README.md (and of every page of the site, docs/**/*.md) runs, each in a fresh interpreter
  whose working directory is an empty temporary folder, so a snippet that leans on a
  name, a file or an import from elsewhere fails here.
* Every ```bash block is parsed into its commands without running them: ``hyst-gym``
  commands must be accepted by the CLI's own argument parser (subcommand, flags, choices,
  required arguments), ``python -m MODULE --flag`` must name a module whose ``--help``
  lists the flag, scripts must exist, ``pip install`` lines must name this package's
  extras. An unknown command fails the test, so new blocks are checked too.
* The speed paragraphs (docs/speed.md) are the ones ``hyst-gym bench`` writes from docs/bench.md,
  the README's leaderboard is the one ``experiments/readme_sections.py`` writes, the README is a
  front door of at most 250 lines, relative links resolve, and nothing points outside the repository.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
DOCS = sorted((REPO / "docs").rglob("*.md"))
#: the README is a front door; everything else is a page of the site (issue 24)
README_MAX_LINES = 250
FENCE = re.compile(r"^```([\w-]*)[^\n]*\n(.*?)^```[ \t]*$", re.M | re.S)
#: languages of fenced blocks and what the test does with them
RUN, CHECK, SHOW = "python", "bash", ("text", "json", "")
SNIPPET_TIMEOUT = 600  # s; generous: the first run after an install compiles numba kernels


def fenced_blocks(path: Path):
    """[(language, code, first line number of the code)] of the fenced blocks in ``path``."""
    text = path.read_text(encoding="utf-8")
    return [(m.group(1), m.group(2), text.count("\n", 0, m.start()) + 2) for m in FENCE.finditer(text)]


def _blocks(language, paths):
    return [pytest.param(path, code, id=f"{path.relative_to(REPO)}:{line}")
            for path in paths for lang, code, line in fenced_blocks(path) if lang == language]


def _env():
    env = dict(os.environ)
    env.update(MPLBACKEND="Agg", OMP_NUM_THREADS="1", PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTHONPATH", None)  # the snippets must work from an installed package
    return env


def test_readme_has_blocks_of_known_languages_only():
    blocks = fenced_blocks(README)
    assert sum(lang == RUN for lang, _, _ in blocks) >= 3   # an env with SB3, a suite task, a diagnosis
    assert sum(lang == CHECK for lang, _, _ in blocks) >= 2
    for path in [README, *DOCS]:
        for lang, _, line in fenced_blocks(path):
            assert lang in (RUN, CHECK, *SHOW), \
                f"{path.relative_to(REPO)}:{line}: block of language {lang!r} is not checked"
    for lang, _, line in blocks:
        assert lang in (RUN, CHECK), f"README.md:{line}: every README block must be python or bash"


@pytest.mark.parametrize("path, code", _blocks(RUN, [README, *DOCS]))
def test_python_block_runs(path, code, tmp_path):
    script = tmp_path / "snippet.py"
    script.write_text(code, encoding="utf-8")
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=_env(), capture_output=True,
                          text=True, timeout=SNIPPET_TIMEOUT)
    assert done.returncode == 0, f"snippet failed:\n{code}\n--- stderr ---\n{done.stderr[-3000:]}"


# ---------------------------------------------------------------- bash blocks


def shell_commands(code: str):
    """Simple commands of a bash block: comments dropped, lines joined at backslashes, split
    at ``&&``, ``||``, ``;`` and ``|``."""
    code = code.replace("\\\n", " ")
    commands = []
    for line in code.splitlines():
        lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
        lexer.whitespace_split = True
        lexer.commenters = "#"
        current = []
        for token in lexer:
            if token in ("&&", "||", ";", "|", "&"):
                if current:
                    commands.append(current)
                current = []
            else:
                current.append(token)
        if current:
            commands.append(current)
    return commands


def _pyproject():
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        tomllib = pytest.importorskip("tomli")
    return tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))


def _check_pip(args, problems, where):
    from packaging.requirements import Requirement

    project = _pyproject()["project"]
    extras = set(project.get("optional-dependencies", {}))
    skip_next = False
    for arg in args:
        if skip_next:
            skip_next = False
            continue
        if arg in ("--index-url", "--extra-index-url", "-i", "-r", "-c"):
            skip_next = True
            continue
        if arg.startswith("-") or arg == "install":
            continue
        requirement = Requirement(arg)
        if requirement.name == project["name"]:
            if not set(requirement.extras) <= extras:
                problems.append(f"{where}: pip extra(s) {sorted(set(requirement.extras) - extras)} not in pyproject")
            if requirement.url and not requirement.url.startswith("git+https://github.com/hyst-gym/hyst-gym"):
                problems.append(f"{where}: unexpected URL {requirement.url}")
        elif requirement.name == "torch":
            rl = " ".join(project["optional-dependencies"].get("rl", []))
            if "torch" not in rl:
                problems.append(f"{where}: torch is installed separately but is not in the rl extra")
        else:
            problems.append(f"{where}: pip installs {arg!r}, which the README does not explain")


def _module_file(module: str) -> Path | None:
    base = REPO.joinpath(*module.split("."))
    for candidate in (base.with_suffix(".py"), base / "__main__.py"):
        if candidate.exists():
            return candidate
    return None


def _check_python_entry(target: Path | None, label: str, args, help_argv, problems, where):
    if target is None:
        problems.append(f"{where}: {label} does not exist in the repository")
        return
    flags = [a.split("=", 1)[0] for a in args if a.startswith("--")]
    if not flags:
        return
    if "add_argument" not in target.read_text(encoding="utf-8"):
        problems.append(f"{where}: {label} takes flags {flags} but has no argument parser to check them")
        return
    shown = subprocess.run([sys.executable, *help_argv, "--help"], cwd=REPO, env=_env(), capture_output=True,
                           text=True, timeout=300)
    if shown.returncode != 0:
        problems.append(f"{where}: {label} --help failed: {shown.stderr[-500:]}")
        return
    for flag in flags:
        if not re.search(rf"(?<![\w-]){re.escape(flag)}(?![\w-])", shown.stdout):
            problems.append(f"{where}: {label} does not accept {flag}")


def _check_installed_tool(name, argv, problems, where):
    """``mkdocs serve|build`` (the docs extra) and ``tensorboard --logdir`` (the rl extra)."""
    import importlib.util

    if name == "mkdocs":
        if argv[1:2] not in (["serve"], ["build"]):
            problems.append(f"{where}: mkdocs {argv[1:2]}: expected serve or build")
        if importlib.util.find_spec("mkdocs") is None:
            problems.append(f"{where}: mkdocs is not installed (the docs extra)")
    else:
        if "--logdir" not in argv:
            problems.append(f"{where}: tensorboard without --logdir")
        if importlib.util.find_spec("tensorboard") is None:
            problems.append(f"{where}: tensorboard is not installed by the rl extra")


def _check_python(argv, problems, where):
    """``python -m pip ...``, ``python -m MODULE --flags`` (pytest: any) and ``python SCRIPT --flags``."""
    if argv[1:3] == ["-m", "pip"]:
        _check_pip(argv[3:], problems, where)
    elif argv[1] == "-m":
        module = argv[2]
        if module != "pytest":
            _check_python_entry(_module_file(module), f"python -m {module}", argv[3:], ["-m", module], problems,
                                where)
    else:
        script = REPO / argv[1]
        _check_python_entry(script if script.exists() else None, argv[1], argv[2:], [argv[1]], problems, where)


def check_command(argv, problems, hyst_gym_calls, where):
    while argv and (argv[0] == "time" or re.match(r"^[A-Za-z_]\w*=", argv[0])):
        argv = argv[1:]
    name = Path(argv[0]).name
    if name == "cd" or argv[:2] == ["git", "clone"]:
        return
    if name == "bash":
        script = REPO / argv[1]
        if not script.exists():
            problems.append(f"{where}: {argv[1]} does not exist")
        elif subprocess.run(["bash", "-n", str(script)], capture_output=True).returncode != 0:
            problems.append(f"{where}: {argv[1]} is not valid bash")
    elif name in ("pip", "pip3"):
        _check_pip(argv[1:], problems, where)
    elif name == "hyst-gym":
        hyst_gym_calls.append((where, argv[1:]))
    elif name in ("mkdocs", "tensorboard"):
        _check_installed_tool(name, argv, problems, where)
    elif name.startswith("python"):
        _check_python(argv, problems, where)
    else:
        problems.append(f"{where}: command {argv[0]!r} is not checked by tests/test_readme.py")


_CLI_CHECK = r"""
import argparse, contextlib, importlib, io, json, os, sys
sys.path.insert(0, os.getcwd())  # the benchmark's subcommands live in the clone's baselines/, experiments/
from hyst_gym.cli import SUBCOMMANDS
problems = []
for where, argv in json.loads(sys.stdin.read()):
    if not argv or argv[0] not in SUBCOMMANDS:
        problems.append(f"{where}: unknown hyst-gym subcommand in {argv}")
        continue
    entry = SUBCOMMANDS[argv[0]]
    module = importlib.import_module(getattr(entry, "module", None) or entry[0])
    parser = argparse.ArgumentParser(prog=f"hyst-gym {argv[0]}")
    module.configure_parser(parser)  # the contract of every subcommand module (hyst_gym/cli.py)
    errors = io.StringIO()
    try:
        with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
            parser.parse_args(argv[1:])
    except SystemExit as error:
        if error.code not in (0, None):
            problems.append(f"{where}: hyst-gym {' '.join(argv)}: {errors.getvalue().strip().splitlines()[-1]}")
print(json.dumps(problems))
"""


def test_bash_blocks_name_real_commands_and_flags():
    problems, hyst_gym_calls = [], []
    for path in [README, *DOCS]:
        for lang, code, line in fenced_blocks(path):
            if lang != CHECK:
                continue
            for argv in shell_commands(code):
                check_command(argv, problems, hyst_gym_calls, f"{path.relative_to(REPO)}:{line}")
    assert hyst_gym_calls, "expected hyst-gym commands in the README"
    # the benchmark's subcommands (demo, train, ...) live in the repository: parse from its root
    done = subprocess.run([sys.executable, "-c", _CLI_CHECK], input=json.dumps(hyst_gym_calls), cwd=REPO,
                          env=_env(), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    problems += json.loads(done.stdout.strip().splitlines()[-1])
    assert not problems, "\n".join(problems)


def test_shell_command_splitting():
    code = "bash scripts/setup.sh && .venv/bin/hyst-gym demo --out demo_out   # comment\n" \
           "hyst-gym make-recording --effect x \\\n  --seed 3 | tee log; time hyst-gym diagnose r.csv\n"
    assert shell_commands(code) == [["bash", "scripts/setup.sh"], [".venv/bin/hyst-gym", "demo", "--out", "demo_out"],
                                    ["hyst-gym", "make-recording", "--effect", "x", "--seed", "3"], ["tee", "log"],
                                    ["time", "hyst-gym", "diagnose", "r.csv"]]


def test_cli_check_rejects_a_bad_flag():
    calls = [["here", ["diagnose", "rec.csv", "--no-such-flag"]], ["there", ["bench", "--only", "physics"]]]
    done = subprocess.run([sys.executable, "-c", _CLI_CHECK], input=json.dumps(calls), cwd=REPO, env=_env(),
                          capture_output=True, text=True, timeout=300)
    problems = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(problems) == 1 and problems[0].startswith("here:") and "--no-such-flag" in problems[0]


# ---------------------------------------------------------------- content


def test_quick_start_commands():
    text = README.read_text(encoding="utf-8")
    assert "bash scripts/setup.sh && .venv/bin/hyst-gym demo --out demo_out" in text
    assert "bash scripts/setup.sh && .venv/bin/python -m pytest -q" in text


def _generated_pages() -> set:
    """The pages docs/gen_pages.py writes at build time (they are not files in docs/)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("gen_pages", REPO / "docs" / "gen_pages.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return {(REPO / "docs" / page).resolve() for page in module.generated_pages()}


def test_readme_points_only_inside_the_repository():
    generated = _generated_pages()
    for path in [README, *DOCS]:
        text = path.read_text(encoding="utf-8")
        # no path that climbs out of the repository (a sibling checkout a user's clone does not have)
        for climbing in re.findall(r"(?:\.\./)+[\w./-]*\w", text):
            resolved = (path.parent / climbing).resolve()
            assert REPO in resolved.parents and resolved.exists(), \
                f"{path.name}: {climbing} points outside the repository or at nothing"
        assert "GUIDE" not in text, f"{path.name} cites the GUIDE, which is not shipped"
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"^[a-z]+:", target) or target.startswith("#"):
                continue
            resolved = (path.parent / target.split("#", 1)[0]).resolve()
            assert resolved.exists() or resolved in generated, f"{path.name}: broken link {target}"
            assert REPO in resolved.parents or resolved == REPO, f"{path.name}: link {target} leaves the repository"


def test_speed_figures_come_from_docs_bench():
    """The speed page's paragraphs are exactly what ``hyst-gym bench --from docs/bench.md
    --page docs/speed.md`` writes: no hand-typed speed figures."""
    from hyst_gym.layer_speed import load, readme_sections

    text = (REPO / "docs" / "speed.md").read_text(encoding="utf-8")
    sections = readme_sections(load(REPO / "docs" / "bench.md"))
    assert set(sections) == {"physics", "estimation", "envs"}
    for layer, body in sections.items():
        start, end = f"<!-- section:bench-{layer} -->", f"<!-- /section:bench-{layer} -->"
        assert text.count(start) == 1 and text.count(end) == 1, layer
        assert text.split(start)[1].split(end)[0].strip() == body.strip(), (
            f"docs/speed.md section '{layer}' differs from docs/bench.md; run "
            f"hyst-gym bench --from docs/bench.md --page docs/speed.md")


def test_readme_is_a_short_front_door():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines (at most {README_MAX_LINES})"


def test_readme_leaderboard_is_the_scripts():
    """The README's leaderboard is what ``python -m experiments.readme_sections`` renders from the
    committed suite results, and it names every task that entered a suite."""
    sys.path.insert(0, str(REPO))
    from experiments.readme_sections import AREA, RESULTS, section

    text = README.read_text(encoding="utf-8")
    start, end = f"<!-- section:{AREA} -->", f"<!-- /section:{AREA} -->"
    assert text.split(start)[1].split(end)[0].strip() == section().strip(), \
        "README leaderboard differs from the results; run python -m experiments.readme_sections"
    entered = [task for path in RESULTS.glob("suite_v[0-9].json")
               for task, row in json.loads(path.read_text())["tasks"].items() if row.get("in_suite")]
    assert entered and all(f"`{task}`" in section() for task in entered)
