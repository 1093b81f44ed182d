"""Reading physical values back from the environments' normalized observations.

Uses the envs layer's own layout (:func:`hyst_gym.envs.core.observation_names`) and
scales, so the agents decode exactly what the environment encoded.
"""

from __future__ import annotations

import numpy as np


def observation_index(scenario, name: str, mode: str = "excitation") -> int:
    from hyst_gym.envs.core import observation_names

    names = observation_names(scenario.env_config, mode)
    if name not in names:
        raise ValueError(f"observation of {mode} mode has no {name!r} (it has {names})")
    return names.index(name)


def estimate_reader(scenario):
    """Function: Excitation-v0 observations (n, d) -> the built-in estimator's a_estimate (A/m)."""
    config = scenario.env_config
    index = observation_index(scenario, "a_estimate")
    lo, width = config.theta_min, config.theta_width

    def read(observations):
        return lo + 0.5 * (np.asarray(observations, dtype=np.float64)[:, index] + 1.0) * width

    return read


__all__ = ["observation_index", "estimate_reader"]
