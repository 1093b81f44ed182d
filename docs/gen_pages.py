"""Pages the documentation site generates from the code at build time (mkdocs-gen-files).

* ``envs/<id>.md``: one page per registered id, in Gymnasium's layout. The spaces, the
  observation table (index, name, meaning with unit and scale, low, high) and the
  ``gymnasium.make`` call come from the env itself; the description is the env class's
  docstring (and, for a suite task, its preset's story and settings); the version history
  is every line of ``CHANGELOG.md`` that names the id. One source, no drift.
* ``api/<package>.md``: one ``:::`` directive per name in the package's ``__all__``, so the
  API reference covers every public name of ``hyst_gym``.

An observation entry without a line in :data:`hyst_gym.envs.core.OBSERVATION_DOCS`, or a
public name that does not resolve, fails the build.
"""

from __future__ import annotations

import importlib
import inspect
import pathlib

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
    lines = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8").splitlines()
    history, version = [], None
    for line in lines:
        if line.startswith("## "):
            version = line[3:].strip()
        elif f"`{env_id}`" in line:
            history.append(f"- {version}: {line.lstrip('- ').strip()}")
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
        rows.append(f"| {i} | `{name}` | {OBSERVATION_DOCS[name]} | {low[i]:g} | {high[i]:g} |")
    return rows


def task_preset(env_id: str):
    """(description, EnvConfig overrides) of a suite task, or None for a base env."""
    for module_name, table in (("hyst_gym.envs.suite", "SUITE_V1"), ("hyst_gym.envs.suite_v2", "TASKS_V2")):
        try:
            tasks = getattr(importlib.import_module(module_name), table)
        except (ImportError, AttributeError):
            continue
        if env_id in tasks:
            return tasks[env_id]["description"], tasks[env_id]["config"]
    return None


def env_page(env_id: str) -> str:
    env = gymnasium.make(env_id)
    unwrapped = env.unwrapped
    out = [f"# `{env_id}`", "", "| | |", "|---|---|",
           f"| Action Space | `{env.action_space}` |", f"| Observation Space | `{env.observation_space}` |",
           f"| import | `gymnasium.make(\"{env_id}\")` (after `import hyst_gym`) |",
           f"| vector env | `gymnasium.make_vec(\"{env_id}\", num_envs=n, vectorization_mode=\"vector_entry_point\")` |",
           f"| class | `{type(unwrapped).__module__}.{type(unwrapped).__name__}` |", ""]
    preset = task_preset(env_id)
    if preset is not None:
        description, config = preset
        out += ["## Story", "", description + ".", "", "## Arguments (the task's `EnvConfig` settings)", "",
                "| field | value |", "|---|---|"]
        out += [f"| `{key}` | `{value!r}` |" for key, value in config.items()]
        out += ["", "Any other `EnvConfig` field keeps its default; keywords of `gymnasium.make` override them.", ""]
    out += ["## Observation Space", ""] + observation_table(env) + [""]
    doc = inspect.getdoc(type(unwrapped)) or ""
    out += ["## Description (the class docstring)", "", "```text", doc, "```", ""]
    out += ["## Version History", ""] + version_history(env_id) + [""]
    env.close()
    return "\n".join(out)


def api_page(package: str, title: str) -> str:
    module = importlib.import_module(f"hyst_gym.{package}")
    out = [f"# {title}: `hyst_gym.{package}`", "", f"::: hyst_gym.{package}", "    options:",
           "      members: false", "      show_root_heading: false", ""]
    lazy = getattr(module, "_EXPORTS", {})  # hyst_gym.envs imports its names on first use
    for name in sorted(module.__all__):
        getattr(module, name)  # a name in __all__ that does not resolve fails the build
        where = f"hyst_gym.{package}.{lazy[name]}" if name in lazy else f"hyst_gym.{package}"
        out += [f"::: {where}.{name}", ""]
    return "\n".join(out)


def generated_pages() -> list[str]:
    """Paths (relative to ``docs/``) of the pages :func:`main` writes; the link test reads them."""
    ids = [env_id for env_id in ENV_IDS if env_id in gymnasium.registry]
    return ["envs/pages.md", *(f"envs/{slug(env_id)}.md" for env_id in ids),
            *(f"api/{package}.md" for package in API_PACKAGES)]


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
    for package, title in API_PACKAGES.items():
        with mkdocs_gen_files.open(f"api/{package}.md", "w") as page:
            page.write(api_page(package, title))


if __name__ in ("__main__", "<run_path>"):  # mkdocs-gen-files runs this file with runpy.run_path
    main()
