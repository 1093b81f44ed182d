"""Adapter from the native Gymnasium vector env to a Stable-Baselines3 ``VecEnv``.

Stable-Baselines3 does not accept a Gymnasium ``VectorEnv``. :class:`SB3VecEnvAdapter`
wraps a native :class:`~.vector.HystVectorEnv` (run in ``SAME_STEP`` autoreset mode, which
is SB3's convention) so that PPO/SAC train on the batched simulator with no
subprocesses::

    from stable_baselines3 import PPO
    from hyst_gym.envs import make_sb3_vec_env

    venv = make_sb3_vec_env("hyst_gym/Excitation-v0", num_envs=64, seed=0)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=256).learn(100_000)

SB3 conventions it follows: ``step_wait`` returns ``(obs, rewards, dones, infos)`` with
``dones = terminated | truncated``; a done sub-env is reset at once, its last
observation is in ``infos[i]["terminal_observation"]`` and
``infos[i]["TimeLimit.truncated"]`` tells truncation (bootstrap) from termination.
``seed(s)`` seeds sub-env ``i`` with ``s + i`` at the next ``reset()``. By default the
per-step infos carry only those keys (building 1024 dicts of truth every step would
dominate the step time); pass ``info_keys`` to copy some of
:data:`~.core.INFO_KEYS` (e.g. ``("a_true", "a_estimate")``) into every info dict.
"""

from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv

from .core import INFO_KEYS
from .vector import HystVectorEnv


class SB3VecEnvAdapter(VecEnv):
    """A Stable-Baselines3 ``VecEnv`` view of a native hyst-gym vector env.

    Parameters
    ----------
    venv : HystVectorEnv
        Must use ``AutoresetMode.SAME_STEP`` (:func:`make_sb3_vec_env` builds one).
    info_keys : sequence of str
        Keys of the native infos copied into every per-step info dict.
    """

    def __init__(self, venv: HystVectorEnv, info_keys=()):
        base = getattr(venv, "unwrapped", venv)
        if not isinstance(base, HystVectorEnv):
            raise ValueError(f"SB3VecEnvAdapter needs a hyst-gym native vector env, got {type(venv).__name__}")
        if base.autoreset_mode != AutoresetMode.SAME_STEP:
            raise ValueError("SB3VecEnvAdapter needs autoreset_mode=SAME_STEP (SB3 resets done envs in the same "
                             "step); build it with make_sb3_vec_env or pass vector_kwargs")
        unknown = sorted(set(info_keys) - set(INFO_KEYS))
        if unknown:
            raise ValueError(f"SB3VecEnvAdapter: unknown info key(s) {unknown}; expected some of {INFO_KEYS}")
        self.venv = venv
        self.info_keys = tuple(info_keys)
        super().__init__(base.num_envs, base.single_observation_space, base.single_action_space)
        self.render_mode = base.render_mode
        self._actions = None

    def reset(self):
        seeds = self._seeds
        options = self._options[0] if self._options and self._options[0] else None
        if all(s is None for s in seeds):
            obs, infos = self.venv.reset(options=options)
        else:
            obs, infos = self.venv.reset(seed=list(seeds), options=options)
        self.reset_infos = self._info_dicts(infos)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = terminated | truncated
        dicts = self._info_dicts(infos)
        for i in np.flatnonzero(dones):
            dicts[i]["terminal_observation"] = infos["final_obs"][i]
            dicts[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            for key in self.info_keys:  # the truth at the end of the finished episode
                dicts[i][key] = float(infos["final_info"][key][i])
        return obs, rewards.astype(np.float32), dones, dicts

    def _info_dicts(self, infos) -> list[dict]:
        if not self.info_keys:
            return [{} for _ in range(self.num_envs)]
        columns = [(key, infos[key].tolist()) for key in self.info_keys]
        return [{key: values[i] for key, values in columns} for i in range(self.num_envs)]

    def close(self) -> None:
        self.venv.close()

    def get_images(self):
        frames = self.venv.render()
        return list(frames) if frames is not None else [None] * self.num_envs

    # The attribute interface: all sub-envs share one simulator, so attributes are the
    # vector env's own (the same value for every index).
    def get_attr(self, attr_name: str, indices=None) -> list:
        value = getattr(self.venv.unwrapped, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        raise AttributeError(f"SB3VecEnvAdapter: set_attr({attr_name!r}) is not supported; the sub-envs share one "
                             f"batched simulator (build a new env with a changed EnvConfig)")

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        result = getattr(self.venv.unwrapped, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]


def make_sb3_vec_env(env_id: str = "hyst_gym/Excitation-v0", num_envs: int = 8, seed: int | None = None,
                     info_keys=(), **kwargs) -> SB3VecEnvAdapter:
    """Build the native vector env of ``env_id`` (SAME_STEP autoreset) wrapped for SB3.

    ``kwargs`` go to the env (config fields, ``config=EnvConfig(...)``). ``seed`` seeds
    sub-env ``i`` with ``seed + i`` at the first ``reset()``.
    """
    venv = gymnasium.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                              autoreset_mode=AutoresetMode.SAME_STEP, **kwargs)
    adapter = SB3VecEnvAdapter(venv, info_keys=info_keys)
    if seed is not None:
        adapter.seed(seed)
    return adapter


__all__ = ["SB3VecEnvAdapter", "make_sb3_vec_env"]
