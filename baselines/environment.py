"""How the benchmark creates environments and reads their ``info``.

An :class:`EpisodeSpec` names a registered environment and the keyword arguments it is
made with; it is all the benchmark needs to rebuild the same environment in another
process (the experiment runner's workers, a Ray task, ``hyst-gym evaluate``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: info key used by the benchmark -> keys the environments may use for it, in order.
INFO_KEYS = {
    "time": ("time", "elapsed_time", "t"),
    "field": ("field", "applied_field"),
    "a_estimate": ("a_estimate",),
    "a_true": ("a_true",),
    "pe_integrand": ("pe_integrand",),
    "curvature_sign": ("curvature_sign",),
}


@dataclass(frozen=True)
class EpisodeSpec:
    """An environment id, its keyword arguments, and the control period ``dt`` (s)."""

    env_id: str
    env_kwargs: dict = field(default_factory=dict)
    dt: float = 0.01

    @property
    def max_episode_steps(self):
        return self.env_kwargs.get("episode_steps")

    def make(self, **overrides):
        import gymnasium

        _register()
        return gymnasium.make(self.env_id, max_episode_steps=self.max_episode_steps,
                              **{**self.env_kwargs, **overrides})


def _register():
    import hyst_gym  # noqa: F401  (registers the environments)
    import hyst_gym.envs.registration  # noqa: F401


def make_vector_env(spec: EpisodeSpec, n: int):
    """The native vector env for ``spec`` (falls back to Gymnasium's ``SyncVectorEnv``)."""
    import gymnasium

    _register()
    return gymnasium.make_vec(spec.env_id, num_envs=int(n), vectorization_mode="vector_entry_point",
                              max_episode_steps=spec.max_episode_steps, **spec.env_kwargs)


def reset_vector_env(env, seeds):
    return env.reset(seed=[int(s) for s in seeds])


def step_info(infos, n: int) -> dict:
    """Per-sub-env arrays of the benchmark's info fields (``nan`` where absent)."""
    out = {}
    for key, candidates in INFO_KEYS.items():
        value = np.full(n, np.nan)
        for candidate in candidates:
            if candidate in infos:
                raw = np.asarray(infos[candidate], dtype=np.float64).reshape(n, -1)[:, 0]
                mask = np.asarray(infos.get("_" + candidate, np.ones(n, dtype=bool)), dtype=bool)
                value = np.where(mask, raw, np.nan)
                break
        out[key] = value
    return out


def make_sb3_vec_env(spec: EpisodeSpec, n_envs: int, seed: int, n_stack: int = 1, reward: str = "dense"):
    """An SB3 ``VecEnv`` for training: the envs layer's adapter over the native vector env
    when it provides one, else ``DummyVecEnv``; the reward replaced by ``reward`` (one of
    :data:`baselines.rewards.REWARDS`; ``"dense"`` keeps the env's own) under the monitor,
    so that the logged returns are the rewards trained on; frame-stacked when ``n_stack > 1``."""
    from stable_baselines3.common.vec_env import DummyVecEnv, VecFrameStack, VecMonitor

    from .rewards import reward_wrapper

    wrapper = reward_wrapper(reward)  # checks the name before anything is built
    adapter = None
    try:
        from hyst_gym.envs import sb3 as envs_sb3  # the envs layer's adapter, when present
        adapter = getattr(envs_sb3, "make_sb3_vec_env", None)
    except ImportError:
        adapter = None
    if adapter is not None:
        venv = adapter(spec.env_id, num_envs=n_envs, seed=seed, max_episode_steps=spec.max_episode_steps,
                       **spec.env_kwargs)
    else:
        venv = DummyVecEnv([lambda: spec.make() for _ in range(n_envs)])
        venv.seed(seed)
    if wrapper is not None:
        venv = wrapper(venv)
    venv = VecMonitor(venv)
    if n_stack > 1:
        venv = VecFrameStack(venv, n_stack)
    return venv


__all__ = ["INFO_KEYS", "EpisodeSpec", "make_vector_env", "reset_vector_env", "step_info", "make_sb3_vec_env"]
