"""Registration of the hyst-gym ids with Gymnasium, at ``import hyst_gym``.

Gymnasium 1.x has no entry-point plugins, so ``hyst_gym/__init__.py`` imports this
module; ``gymnasium.make("hyst_gym:hyst_gym/Excitation-v0")`` imports ``hyst_gym`` and
so registers the ids from any project.

No ``max_episode_steps`` is registered: the environments truncate themselves at their
``episode_steps`` (a config field, default 1000), so ``gymnasium.make(id,
episode_steps=2000)`` runs 2000 steps. A registered limit would add Gymnasium's
``TimeLimit`` at 1000 and cut such episodes short without a word.
``gymnasium.make(id, max_episode_steps=n)`` still adds a shorter limit on request.
"""

from __future__ import annotations

import gymnasium

from .tasks import TASKS, suite_ids

#: id -> (single env class, vector env class), "module:Class" strings (lazy import)
ENV_IDS = {
    "hyst_gym/Excitation-v0": ("hyst_gym.envs.single:ExcitationEnv", "hyst_gym.envs.vector:ExcitationVectorEnv"),
    "hyst_gym/Estimation-v0": ("hyst_gym.envs.single:EstimationEnv", "hyst_gym.envs.vector:EstimationVectorEnv"),
    "hyst_gym/Identification-v0": ("hyst_gym.envs.single:IdentificationEnv",
                                   "hyst_gym.envs.vector:IdentificationVectorEnv"),
}
#: the benchmark suites' task ids (:data:`hyst_gym.envs.tasks.TASKS`, the one list): every one is made by
#: :func:`hyst_gym.envs.tasks.make_env` with ``task=id``, which picks the env classes of the task's kind
SUITE_IDS = suite_ids("v1")
SUITE_V2_IDS = suite_ids("v2")
ENV_IDS.update({env_id: ("hyst_gym.envs.tasks:make_env", "hyst_gym.envs.tasks:make_vector_env")
                for env_id in TASKS})


def register_envs() -> None:
    """Register the ids of :data:`ENV_IDS` (idempotent)."""
    for env_id, (entry_point, vector_entry_point) in ENV_IDS.items():
        if env_id in gymnasium.registry:
            continue
        kwargs = {"task": env_id} if env_id in TASKS else {}
        gymnasium.register(id=env_id, entry_point=entry_point, vector_entry_point=vector_entry_point,
                           kwargs=kwargs)


register_envs()

__all__ = ["ENV_IDS", "SUITE_IDS", "SUITE_V2_IDS", "register_envs"]
