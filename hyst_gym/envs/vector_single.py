"""Tasks whose native env is a vector env of their own (:class:`TaskVectorEnv`: the checks and the spaces they
share) and their single env (:class:`SingleOfVector`: a vector env of one sub-env, autoreset disabled, so a
single env and sub-env 0 of a vector env seeded alike give the same numbers)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

#: |normalized action| may exceed 1 by this much (float32 rounding) before it is an error
ACTION_TOLERANCE = 1e-6


class TaskVectorEnv(VectorEnv):
    """Base of a task's own vector env: one action in [-1, 1] per sub-env, autoreset ``NEXT_STEP`` (default) or
    ``DISABLED`` (``SAME_STEP`` is refused)."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def _setup(self, num_envs, task: str, kind: str, autoreset_mode, overrides: dict):
        """Check and keep ``num_envs``, the task (of ``kind``) and the autoreset mode; returns the task's config."""
        from .tasks import task_spec

        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        spec = task_spec(task)
        if spec.kind != kind:
            raise ValueError(f"{task!r} is not a {kind.replace('_', '-')} task (kind {spec.kind!r})")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        if self.autoreset_mode == AutoresetMode.SAME_STEP:
            raise ValueError(f"{type(self).__name__}: autoreset_mode SAME_STEP is not supported; use NEXT_STEP or "
                             "DISABLED")
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        self.task = task
        self.num_envs = int(num_envs)
        self.render_mode = None
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._all = np.arange(self.num_envs)
        self.spec_ = spec
        self.config = spec.env_config(**overrides)
        return self.config

    def _spaces(self, names, low, high) -> None:
        self.obs_names = list(names)
        self.single_observation_space = spaces.Box(np.asarray(low, dtype=np.float32),
                                                   np.asarray(high, dtype=np.float32), dtype=np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    @property
    def observation_names(self) -> list[str]:
        return list(self.obs_names)

    def _begin_step(self, actions, meaning: str):
        """(actions as (n, 1) float64 within [-1, 1], the sub-envs this step resets (NEXT_STEP)); a ValueError
        naming a bad action (``meaning``: what the action is), a RuntimeError stepping done sub-envs (DISABLED)."""
        from .core import action_array

        actions = action_array(actions, (self.num_envs, 1), "actions")
        outside = ~np.isfinite(actions) | (np.abs(actions) > 1.0 + ACTION_TOLERANCE)
        if outside.any():
            raise ValueError(f"action value {float(actions[outside][0])!r} must be a finite number in [-1, 1] "
                             f"({meaning})")
        if self.autoreset_mode == AutoresetMode.DISABLED and self._autoreset.any():
            raise RuntimeError("step: some sub-envs are done and autoreset_mode is DISABLED; reset them first")
        resetting = self._autoreset.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP else \
            np.zeros(self.num_envs, dtype=bool)
        return np.clip(actions, -1.0, 1.0), resetting

    def _end_step(self, reward, terminated, truncated, resetting) -> None:
        """NEXT_STEP: the sub-envs ``resetting`` start new episodes (``_restart``), their step pays nothing and ends
        nothing (as ``SyncVectorEnv``); then who is done now (in place on the arrays)."""
        if resetting.any():
            rows = np.flatnonzero(resetting)
            self._restart(rows)
            reward[rows] = 0.0
            terminated[rows] = False
            truncated[rows] = False
        self._autoreset = terminated | truncated


class SingleOfVector(gym.Env):
    """``gym.Env`` over ``vector_class(1, task, autoreset_mode=DISABLED, **overrides)``: ``reset`` seeds the one
    sub-env with ``seed``; ``info`` holds the vector env's entries as Python numbers."""

    metadata = {"render_modes": []}
    vector_class = None

    def __init__(self, task: str, render_mode=None, **overrides):
        if render_mode is not None:
            raise ValueError(f"render_mode of {task!r} must be None, got {render_mode!r}")
        self.vector = self.vector_class(1, task, autoreset_mode=AutoresetMode.DISABLED, **overrides)
        self.task = task
        self.config = self.vector.config
        self.observation_space = self.vector.single_observation_space
        self.action_space = self.vector.single_action_space

    @property
    def observation_names(self) -> list[str]:
        return self.vector.observation_names

    @staticmethod
    def _one(info: dict) -> dict:
        return {key: value[0].item() for key, value in info.items() if not key.startswith("_")}

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        observation, info = self.vector.reset(seed=[seed], options=options)
        return observation[0], self._one(info)

    def step(self, action):
        from .core import action_array

        action = action_array(action, self.action_space.shape)
        observation, reward, terminated, truncated, info = self.vector.step(action[None, :])
        return observation[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), self._one(info)


__all__ = ["SingleOfVector", "TaskVectorEnv"]
