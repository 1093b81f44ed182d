"""hyst-gym: hysteretic magnetostrictive transducers as a benchmark for adaptive
estimation and reinforcement learning.

Importing the package registers the Gymnasium environments (``hyst_gym/...-v0``).
"""

from .physics import HysteresisParams, simulate_magnetization

__version__ = "0.2.0"
__all__ = ["HysteresisParams", "simulate_magnetization", "__version__"]

from .envs import registration as _registration  # noqa: E402,F401  (registers hyst_gym/...-v0)
