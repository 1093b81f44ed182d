"""Shared helpers of the environment tests."""

import gymnasium
import numpy as np

import hyst_gym  # noqa: F401  (registers the ids)

ENV_IDS = ("hyst_gym/Excitation-v0", "hyst_gym/Estimation-v0", "hyst_gym/Identification-v0")

#: short episodes with a stroke limit that random actions reach at different times, so
#: episodes end both by termination and by truncation
SHORT = dict(episode_steps=40, stroke_limit=400.0)


def rollout(env, actions, seed=None):
    """Observations, rewards, flags and infos of a single env under a fixed action list."""
    obs, info = env.reset(seed=seed)
    out = [(obs, 0.0, False, False, info)]
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        out.append((obs, reward, terminated, truncated, info))
        if terminated or truncated:
            break
    return out


def random_actions(space, count, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, (count, *space.shape)).astype(np.float32)


def make(env_id, **kwargs):
    return gymnasium.make(env_id, **kwargs)
