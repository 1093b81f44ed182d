"""Pages the documentation site generates from the code at build time (mkdocs-gen-files).

* ``envs/<id>.md``: one page per registered id, in Gymnasium's layout. The spaces, the
  observation table (index, name, meaning with unit and scale, low, high) and the
  ``gymnasium.make`` call come from the env itself; the description is the env class's
  docstring (and, for a suite task, its preset's story and settings); the version history
  is every line of ``CHANGELOG.md`` that names the id. One source, no drift.
* ``api/<package>.md``: one ``:::`` directive per name in the package's ``__all__``, so the
  API reference covers every public name of ``hyst_gym``.
* ``equations.md``: each equation number of the paper that a public name's docstring cites,
  such as "(6)" or "eq. (4)", with the names that cite it.

An observation entry without a line in :data:`hyst_gym.envs.core.OBSERVATION_DOCS`, or a
public name that does not resolve, fails the build.
"""

from __future__ import annotations

import importlib
import inspect
import pathlib
import re

import gymnasium

import hyst_gym  # noqa: F401  (registers the ids)
from hyst_gym.envs.core import OBSERVATION_DOCS
from hyst_gym.envs.registration import ENV_IDS

ROOT = pathlib.Path(__file__).resolve().parents[1]
API_PACKAGES = {"physics": "Physics", "estimation": "Estimation", "envs": "Environments",
                "diagnose": "Mismatch tool"}


def slug(env_id: str) -> str:
    return env_id.split("/", 1)[1]


def version_history(env_id: str) -> list[str]:
    """Every CHANGELOG bullet (continuation lines joined) that names ``env_id``, with its version."""
    history, version, bullets = [], None, []
    for line in (ROOT / "CHANGELOG.md").read_text(encoding="utf-8").splitlines():
        if line.startswith("## "):
            version = line[3:].strip()
        elif line.startswith("- "):
            bullets.append([version, line[2:].strip()])
        elif line.startswith("  ") and bullets:
            bullets[-1][1] += " " + line.strip()
    for version, text in bullets:
        if f"`{env_id}`" in text:
            history.append(f"- **{version}**: {text}")
    if not history:
        raise ValueError(f"CHANGELOG.md names no version of {env_id}: add a line for it")
    return history


def observation_table(env) -> list[str]:
    names = env.unwrapped.observation_names
    low, high = env.observation_space.low, env.observation_space.high
    rows = ["| index | name | meaning (unit, scale) | low | high |", "|---|---|---|---|---|"]
    for i, name in enumerate(names):
        if name not in OBSERVATION_DOCS:
            raise KeyError(f"observation entry {name!r} of {env.spec.id} has no line in OBSERVATION_DOCS")
        meaning = OBSERVATION_DOCS[name].replace("|", "\\|")  # a bare | would end the table cell
        rows.append(f"| {i} | `{name}` | {meaning} | {low[i]:g} | {high[i]:g} |")
    return rows


def task_preset(env_id: str):
    """(description, EnvConfig overrides) of a suite task, or None for a base env."""
    from hyst_gym.envs.tasks import TASKS

    if env_id in TASKS:
        return TASKS[env_id].description, TASKS[env_id].config
    return None


def env_page(env_id: str) -> str:
    env = gymnasium.make(env_id)
    unwrapped = env.unwrapped
    out = [f"# `{env_id}`", "", "| | |", "|---|---|",
           f"| Action Space | `{env.action_space}` |", f"| Observation Space | `{env.observation_space}` |",
           f"| import | `gymnasium.make(\"{env_id}\")` (after `import hyst_gym`) |",
           f"| vector env | `gymnasium.make_vec(\"{env_id}\", num_envs=n, "
           f"vectorization_mode=\"vector_entry_point\")` |",
           f"| class | `{type(unwrapped).__module__}.{type(unwrapped).__name__}` |", ""]
    preset = task_preset(env_id)
    if preset is not None:
        description, config = preset
        out += ["## Story", "", description + ".", "", "## Arguments (the task's `EnvConfig` settings)", "",
                "| field | value |", "|---|---|"]
        out += [f"| `{key}` | `{value!r}` |" for key, value in config.items()]
        out += ["", "Any other `EnvConfig` field keeps its default; keywords of `gymnasium.make` override them. "
                "These settings override the defaults that the class description below names.", ""]
    out += ["## Observation Space", ""] + observation_table(env) + [""]
    doc = inspect.getdoc(type(unwrapped)) or ""
    # the docstring is the env's documentation (``help(env)`` says the same): shown as Markdown,
    # with its reST cross-reference roles reduced to code
    doc = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", doc)
    doc = re.sub(r"^(#{1,4}) ", r"\1## ", doc, flags=re.M)  # its own headings sit under this section
    out += ["## Description (the class docstring)", "", doc, ""]
    out += ["## Version History", ""] + version_history(env_id) + [""]
    env.close()
    return "\n".join(out)


def api_page(package: str, title: str) -> str:
    out = [f"# {title}: `hyst_gym.{package}`", "", f"::: hyst_gym.{package}", "    options:",
           "      members: false", "      show_root_heading: false", ""]
    for owner, _, _, path in public_objects():
        if owner == package:
            out += [f"::: {path}", ""]
    return "\n".join(out)


def generated_pages() -> list[str]:
    """Paths (relative to ``docs/``) of the pages :func:`main` writes; the link test reads them."""
    ids = [env_id for env_id in ENV_IDS if env_id in gymnasium.registry]
    return ["envs/pages.md", "equations.md", *(f"envs/{slug(env_id)}.md" for env_id in ids),
            *(f"api/{package}.md" for package in API_PACKAGES)]


#: an equation reference in a docstring: "eq. (4)", "eqs. (24)-(25)", "model (6)", "(12)/(13)"
EQUATION = re.compile(r"\((\d{1,2})\)")
#: text before "(N)" that makes it an item of an enumeration ("... stages. (2) Locate"), not an equation
ENUMERATION = re.compile(r"(?:^|(?<![Ee]q)(?<![Ee]qs)[.:;]|\*\*)\s*$")


def cited_equations(doc: str) -> set[int]:
    return {int(m.group(1)) for m in EQUATION.finditer(doc)
            if 1 <= int(m.group(1)) <= 30 and not ENUMERATION.search(doc[max(0, m.start() - 6):m.start()])}


def public_objects():
    """(package, name, object, documented path) for every name in the API packages' ``__all__``;
    the path is where mkdocstrings finds it (``hyst_gym.envs`` imports its names on first use,
    so those are documented at their defining module)."""
    for package in API_PACKAGES:
        module = importlib.import_module(f"hyst_gym.{package}")
        lazy = getattr(module, "_EXPORTS", {})
        for name in sorted(module.__all__):
            obj = getattr(module, name)  # a name in __all__ that does not resolve fails the build
            where = f"hyst_gym.{package}.{lazy[name]}" if name in lazy else f"hyst_gym.{package}"
            yield package, name, obj, f"{where}.{name}"


def equations_page() -> str:
    cited = {}
    for package, name, obj, path in public_objects():
        doc = inspect.getdoc(obj) if (inspect.isclass(obj) or callable(obj)) else ""
        for number in cited_equations(doc or ""):  # the paper numbers its equations 1..30
            cited.setdefault(number, []).append(f"[`{package}.{name}`](api/{package}.md#{path})")
    rows = ["# Paper equations in the code", "",
            "Each equation number of Nealis & Smith that a public name's docstring cites, and the names "
            "that cite it (generated from the docstrings by `docs/gen_pages.py`). `grep -rn \"(6)\" hyst_gym` "
            "finds every use in the source, private functions included. The [model notes](model.md) derive "
            "them and say where the implementation departs from the print.", "",
            "| equation | cited by |", "|---|---|"]
    rows += [f"| ({number}) | {', '.join(sorted(names))} |" for number, names in sorted(cited.items())]
    return "\n".join(rows) + "\n"


def main() -> None:
    import mkdocs_gen_files

    ids = [env_id for env_id in ENV_IDS if env_id in gymnasium.registry]
    index = ["# Environment pages", "", "One page per registered id, generated from the code "
             "(`docs/gen_pages.py`).", "", "| id | class | action | observation |", "|---|---|---|---|"]
    for env_id in ids:
        with mkdocs_gen_files.open(f"envs/{slug(env_id)}.md", "w") as page:
            page.write(env_page(env_id))
        env = gymnasium.make(env_id)
        index.append(f"| [`{env_id}`]({slug(env_id)}.md) | `{type(env.unwrapped).__name__}` | "
                     f"{env.action_space.shape} | {env.observation_space.shape} |")
        env.close()
    with mkdocs_gen_files.open("envs/pages.md", "w") as page:
        page.write("\n".join(index) + "\n")
    with mkdocs_gen_files.open("equations.md", "w") as page:
        page.write(equations_page())
    for package, title in API_PACKAGES.items():
        with mkdocs_gen_files.open(f"api/{package}.md", "w") as page:
            page.write(api_page(package, title))


if __name__ in ("__main__", "<run_path>"):  # mkdocs-gen-files runs this file with runpy.run_path
    main()
