"""hyst-gym: hysteretic magnetostrictive transducers as a benchmark for adaptive
estimation and reinforcement learning.

Importing the package registers the Gymnasium environments (``hyst_gym/...-v0``).
"""

from .physics import HysteresisParams, simulate_magnetization

__version__ = "0.1.0"
__all__ = ["HysteresisParams", "simulate_magnetization", "__version__"]

# The envs layer adds its registration import here (hyst_gym.envs.registration).
