"""Every benchmark task, by id: the one list (:data:`TASKS`) the registration, the entry points and the
benchmark scripts read.

A task is a :class:`~hyst_gym.envs.task_spec.TaskSpec`; its ``kind`` picks the env classes from
:data:`~hyst_gym.envs.task_spec.KINDS`. The presets live beside their envs: suite v1's in
:mod:`hyst_gym.envs.suite_v1`, suite v2's in :mod:`hyst_gym.envs.suite_v2`. A new task of an existing
kind is one more ``TaskSpec`` in its suite's tuple.
"""

from __future__ import annotations

from importlib import import_module

from .suite_v1 import TASKS_V1
from .suite_v2 import TASKS_V2
from .task_spec import KINDS, TaskSpec

#: id -> TaskSpec of every registered task (suite v1, then v2)
TASKS: dict[str, TaskSpec] = {spec.id: spec for spec in (*TASKS_V1, *TASKS_V2)}


def task_spec(task: str) -> TaskSpec:
    """The :class:`TaskSpec` of ``task``; a ValueError naming the known ids otherwise."""
    if task not in TASKS:
        raise ValueError(f"unknown suite task {task!r}; expected one of {sorted(TASKS)}")
    return TASKS[task]


def suite_ids(suite: str) -> tuple:
    """The ids of suite ``suite`` ("v1" or "v2"), in the order of :data:`TASKS`."""
    return tuple(task for task, spec in TASKS.items() if spec.suite == suite)


def env_classes(kind: str) -> tuple:
    """(single env class, vector env class) of a task kind (:data:`~hyst_gym.envs.task_spec.KINDS`)."""
    def load(path):
        module, name = path.split(":")
        return getattr(import_module(module), name)

    return tuple(load(path) for path in KINDS[kind])


def make_env(task: str, **overrides):
    """Gymnasium entry point of every task id: the kind's single env (``overrides``: EnvConfig fields on top of
    the preset, and ``render_mode``)."""
    single, _ = env_classes(task_spec(task).kind)
    return single(task, **overrides)


def make_vector_env(task: str, num_envs: int = 1, **overrides):
    """Vector entry point of every task id: the kind's native vector env."""
    _, vector = env_classes(task_spec(task).kind)
    return vector(num_envs, task, **overrides)


__all__ = ["TASKS", "env_classes", "make_env", "make_vector_env", "suite_ids", "task_spec"]
