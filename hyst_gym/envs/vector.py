"""The native batched vector environments (Gymnasium ``vector_entry_point``).

``gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=n,
vectorization_mode="vector_entry_point")`` returns an :class:`ExcitationVectorEnv`: one
:class:`~.core.BatchSimulator` of ``n`` sub-envs, stepped by the same compiled kernels
in one call. Sub-env ``i`` behaves exactly like a single env: ``reset(seed=s)`` seeds it
with ``s + i`` (as ``SyncVectorEnv`` does), and each sub-env has its own random
streams, so ``step`` returns what a ``SyncVectorEnv`` of single envs returns, autoreset
included (``NEXT_STEP`` by default; ``SAME_STEP`` and ``DISABLED`` are supported).
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .config import EnvConfig, make_config
from .core import ESTIMATION, EXCITATION, IDENTIFICATION, INFO_KEYS, BatchSimulator
from .single import RENDER_MODES


def sub_env_seeds(env: VectorEnv, seed) -> list:
    """The seeds of the sub-envs of ``env`` (a vector env with ``num_envs``) for a reset with ``seed``: None
    (None each: a sub-env keeps its generator), an int (sub-env i gets ``seed + i``, and ``env``'s own generator
    ``seed``, as ``SyncVectorEnv``) or a list of ``num_envs`` ints/None."""
    if seed is None:
        return [None] * env.num_envs
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        VectorEnv.reset(env, seed=int(seed))
        return [int(seed) + i for i in range(env.num_envs)]
    seeds = list(seed)
    if len(seeds) != env.num_envs:
        raise ValueError(f"reset: seed list has {len(seeds)} entries for {env.num_envs} sub-envs")
    return seeds


def seed_sub_envs(env: VectorEnv, seed) -> None:
    """Give the sub-envs of ``env`` (a vector env with a :class:`~.core.BatchSimulator` ``sim``) their generators
    for a reset with ``seed`` (:func:`sub_env_seeds`; a sub-env without one gets a fresh one)."""
    seeds = sub_env_seeds(env, seed)
    for i, sub_seed in enumerate(seeds):
        if sub_seed is not None or env.sim.episode_rngs[i] is None:
            env.sim.set_generator(i, seeding.np_random(sub_seed)[0])


class HystVectorEnv(VectorEnv):
    """``num_envs`` transducers stepped together (base of the three modes).

    Parameters
    ----------
    num_envs : int
    config : EnvConfig, optional
    max_episode_steps : int, optional
        An extra time limit in steps (none is registered, so only an explicit
        ``make_vec(..., max_episode_steps=n)`` passes one); the episode is truncated at
        ``min(max_episode_steps, config.episode_steps)``, exactly like a single env made
        with the same ``max_episode_steps`` (Gymnasium's ``TimeLimit`` on an env that
        truncates itself at ``episode_steps``).
    autoreset_mode : AutoresetMode or str
        ``NEXT_STEP`` (default, as ``SyncVectorEnv``), ``SAME_STEP`` or ``DISABLED``.
    render_mode : {None, "rgb_array"}
        ``"rgb_array"``: ``render()`` returns a tuple with one frame per sub-env.
    temperature_prior, pinning_prior
        The episode draws of :class:`~.core.BatchSimulator` (as the single env).
    **overrides
        Fields of :class:`EnvConfig`.
    """

    mode = EXCITATION

    def __init__(self, num_envs: int = 1, config: EnvConfig | None = None, max_episode_steps: int | None = None,
                 autoreset_mode=AutoresetMode.NEXT_STEP, render_mode: str | None = None,
                 temperature_prior: str = "uniform", pinning_prior=None, **overrides):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        self.config = make_config(config, **overrides)
        if max_episode_steps is not None and (isinstance(max_episode_steps, bool) or
                                              not isinstance(max_episode_steps, (int, np.integer))
                                              or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be an integer >= 1 or None, got {max_episode_steps!r}")
        limit = self.config.episode_steps if max_episode_steps is None else min(int(max_episode_steps),
                                                                                self.config.episode_steps)
        if render_mode is not None and render_mode != "rgb_array":
            raise ValueError(f"render_mode of the vector env must be None or 'rgb_array', got {render_mode!r}")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.metadata = {"render_modes": ["rgb_array"], "render_fps": 30, "autoreset_mode": self.autoreset_mode}
        self.render_mode = render_mode
        self.num_envs = int(num_envs)
        self.sim = BatchSimulator(self.config, self.mode, self.num_envs, truncation_steps=limit,
                                  record=render_mode is not None, temperature_prior=temperature_prior,
                                  pinning_prior=pinning_prior)
        self.single_observation_space = spaces.Box(self.sim.obs_low, self.sim.obs_high, dtype=np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, (self.sim.action_size,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._all = np.arange(self.num_envs)

    @property
    def observation_names(self) -> list[str]:
        return list(self.sim.obs_names)

    def reset(self, *, seed=None, options: dict | None = None):
        """Reset every sub-env. ``seed``: None, an int (sub-env i gets ``seed + i``) or a
        list of ``num_envs`` ints/None."""
        seed_sub_envs(self, seed)
        self.sim.reset(self._all, options)
        self._autoreset[:] = False
        return self.sim.observation(), self._infos()

    def step(self, actions):
        actions = self.sim.as_actions(actions)  # exactly (num_envs, action size), or a ValueError
        resetting = self._autoreset if self.autoreset_mode == AutoresetMode.NEXT_STEP else None
        any_resetting = resetting is not None and bool(resetting.any())
        if any_resetting:
            # The action of a sub-env that is being reset is ignored (SyncVectorEnv semantics).
            actions = actions.copy()
            actions[resetting] = 0.0
        elif self.autoreset_mode == AutoresetMode.DISABLED and self._autoreset.any():
            raise RuntimeError("step: some sub-envs are done and autoreset_mode is DISABLED; reset them first")
        rewards, terminations, truncations = self.sim.step(actions, active=~resetting if any_resetting else None)
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            if any_resetting:
                rows = np.flatnonzero(resetting)
                self.sim.reset(rows)
                rewards[rows] = 0.0
                terminations[rows] = False
                truncations[rows] = False
            self._autoreset = terminations | truncations
            return self.sim.observation(), rewards, terminations, truncations, self._infos()
        if self.autoreset_mode == AutoresetMode.DISABLED:
            self._autoreset = terminations | truncations
            return self.sim.observation(), rewards, terminations, truncations, self._infos()
        # SAME_STEP: report the final observation/info, then reset at once.
        done = terminations | truncations
        observations = self.sim.observation()
        infos = self._infos()
        if done.any():
            rows = np.flatnonzero(done)
            final_obs = np.full(self.num_envs, None, dtype=object)
            for row in rows:
                final_obs[row] = observations[row].copy()
            # as SyncVectorEnv: entries of sub-envs that did not finish are 0 / masked out
            final_info = {}
            for key in INFO_KEYS:
                final_info[key] = np.where(done, infos[key], 0.0)
                final_info["_" + key] = done.copy()
            self.sim.reset(rows)
            observations = self.sim.observation()
            infos = self._infos()
            infos["final_obs"] = final_obs
            infos["_final_obs"] = done.copy()
            infos["final_info"] = final_info
            infos["_final_info"] = done.copy()
        return observations, rewards, terminations, truncations, infos

    def _infos(self) -> dict:
        # one copy and one mask block, handed out row by row (rows do not share memory)
        values = self.sim.info_array.copy()
        masks = np.ones(values.shape, dtype=bool)
        infos = {}
        for key, row, mask in zip(INFO_KEYS, values, masks):
            infos[key] = row
            infos["_" + key] = mask
        return infos

    def render(self):
        if self.render_mode is None:
            return None
        from .rendering import draw_figure, figure_to_array
        return tuple(figure_to_array(draw_figure(history, self.config, title=f"{type(self).__name__}[{i}]"))
                     for i, history in enumerate(self.sim.history))

    def close_extras(self, **kwargs):
        pass


class ExcitationVectorEnv(HystVectorEnv):
    """Native vector env of ``hyst_gym/Excitation-v0``."""

    mode = EXCITATION


class EstimationVectorEnv(HystVectorEnv):
    """Native vector env of ``hyst_gym/Estimation-v0``."""

    mode = ESTIMATION


class IdentificationVectorEnv(HystVectorEnv):
    """Native vector env of ``hyst_gym/Identification-v0``."""

    mode = IDENTIFICATION


__all__ = ["EstimationVectorEnv", "ExcitationVectorEnv", "HystVectorEnv", "IdentificationVectorEnv",
           "RENDER_MODES", "seed_sub_envs", "sub_env_seeds"]
