"""Gymnasium environments and wrappers (uses physics and estimation).

Ids (registered at ``import hyst_gym``): ``hyst_gym/Excitation-v0``,
``hyst_gym/Estimation-v0``, ``hyst_gym/Identification-v0``. Classes are imported lazily
so that ``import hyst_gym`` stays cheap::

    from hyst_gym.envs import EnvConfig, ExcitationEnv, ExcitationVectorEnv, SB3VecEnvAdapter
"""

from importlib import import_module

_EXPORTS = {
    "EnvConfig": "config", "make_config": "config",
    "HystEnv": "single", "ExcitationEnv": "single", "EstimationEnv": "single", "IdentificationEnv": "single",
    "HystVectorEnv": "vector", "ExcitationVectorEnv": "vector", "EstimationVectorEnv": "vector",
    "IdentificationVectorEnv": "vector",
    "BatchSimulator": "core", "observation_names": "core",
    "SB3VecEnvAdapter": "sb3", "make_sb3_vec_env": "sb3",
    "save_episode_figure": "rendering", "record_episode": "rendering",
    "ENV_IDS": "registration", "register_envs": "registration",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
