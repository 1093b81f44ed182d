"""RL excitation policies (PPO, SAC from Stable-Baselines3) behind the common agent interface.

History: hysteresis is not Markov in (H, y), so the policy sees the last ``n_stack``
observations (SB3's ``VecFrameStack``: zeros after a reset, newest frame last).
:class:`PolicyAgent` rebuilds exactly that stack from raw observations, so a trained
model is evaluated through the same interface and on the same envs as every baseline.
A recurrent policy (sb3-contrib's RecurrentPPO) is not used: sb3-contrib is not a
dependency of this project.
"""

from __future__ import annotations

import json
import pathlib

import numpy as np

from .agents import Agent

ALGORITHMS = ("ppo", "sac")


def algorithm_class(algo: str):
    from stable_baselines3 import PPO, SAC

    try:
        return {"ppo": PPO, "sac": SAC}[algo.lower()]
    except KeyError:
        raise ValueError(f"unknown algorithm {algo!r}; expected one of {ALGORITHMS}") from None


class PolicyAgent(Agent):
    """A trained SB3 model playing on raw (unstacked) observations."""

    def __init__(self, model, n_stack: int = 1, deterministic: bool = True, name: str = "policy"):
        super().__init__()
        self.model, self.n_stack, self.deterministic, self.name = model, int(n_stack), deterministic, name
        self._stack = None

    @classmethod
    def load(cls, path, name=None, device="cpu"):
        """Load ``model.zip`` (or a folder holding it) and its ``config.json`` (for ``n_stack``)."""
        path = pathlib.Path(path)
        model_path = path / "model.zip" if path.is_dir() else path
        if not model_path.exists():
            raise OSError(f"no trained model at {model_path}")
        config_path = model_path.parent / "config.json"
        config = json.loads(config_path.read_text()) if config_path.exists() else {}
        algo = config.get("algo") or ("sac" if "sac" in model_path.name.lower() else "ppo")
        model = algorithm_class(algo).load(model_path, device=device)
        return cls(model, config.get("n_stack", 1), name=name or algo)

    def reset(self, seed=None):
        super().reset(seed)
        self._stack = None

    def act_batch(self, observations, episode_start):
        observations = np.asarray(observations, dtype=np.float32)
        n, size = observations.shape
        if self._stack is None or self._stack.shape[0] != n:
            self._stack = np.zeros((n, size * self.n_stack), dtype=np.float32)
        self._stack[np.asarray(episode_start, dtype=bool)] = 0.0
        self._stack = np.roll(self._stack, -size, axis=1)
        self._stack[:, -size:] = observations
        actions, _ = self.model.predict(self._stack, deterministic=self.deterministic)
        return np.asarray(actions, dtype=np.float32).reshape(n, -1)


__all__ = ["ALGORITHMS", "algorithm_class", "PolicyAgent"]
