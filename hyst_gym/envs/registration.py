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

#: id -> (single env class, vector env class), "module:Class" strings (lazy import)
ENV_IDS = {
    "hyst_gym/Excitation-v0": ("hyst_gym.envs.single:ExcitationEnv", "hyst_gym.envs.vector:ExcitationVectorEnv"),
    "hyst_gym/Estimation-v0": ("hyst_gym.envs.single:EstimationEnv", "hyst_gym.envs.vector:EstimationVectorEnv"),
    "hyst_gym/Identification-v0": ("hyst_gym.envs.single:IdentificationEnv",
                                   "hyst_gym.envs.vector:IdentificationVectorEnv"),
}
#: the benchmark suite's task ids (presets of Excitation-v0 in :mod:`hyst_gym.envs.suite`, which
#: is imported only when one is made, so registering stays cheap); each is made with ``task=id``
SUITE_IDS = ("hyst_gym/HotCoil-v1", "hyst_gym/HotCoilNoisy-v1", "hyst_gym/HotCoilWideStart-v1",
             "hyst_gym/CoolantFailure-v1", "hyst_gym/WarmCoil-v1", "hyst_gym/HotCoilLumped-v1")
ENV_IDS.update({env_id: ("hyst_gym.envs.suite:make_env", "hyst_gym.envs.suite:make_vector_env")
                for env_id in SUITE_IDS})
#: suite v2's task ids (:mod:`hyst_gym.envs.suite_v2`: envs of their own, made with ``task=id``)
SUITE_V2_IDS = ("hyst_gym/HotCalibrate-v0", "hyst_gym/HotCalibrateNoisy-v0", "hyst_gym/DisplacementOnly-v0",
                "hyst_gym/HotCalibrateUnknownK-v0", "hyst_gym/DriftJump-v0")
ENV_IDS.update({env_id: ("hyst_gym.envs.suite_v2:make_env", "hyst_gym.envs.suite_v2:make_vector_env")
                for env_id in SUITE_V2_IDS})


def register_envs() -> None:
    """Register the ids of :data:`ENV_IDS` (idempotent)."""
    for env_id, (entry_point, vector_entry_point) in ENV_IDS.items():
        if env_id in gymnasium.registry:
            continue
        kwargs = {"task": env_id} if env_id in SUITE_IDS + SUITE_V2_IDS else {}
        gymnasium.register(id=env_id, entry_point=entry_point, vector_entry_point=vector_entry_point,
                           kwargs=kwargs)


register_envs()

__all__ = ["ENV_IDS", "SUITE_IDS", "SUITE_V2_IDS", "register_envs"]
