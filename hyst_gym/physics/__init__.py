"""Pure, batched, compiled physics kernels: hysteresis, transducers, temperature.

This layer imports nothing else from hyst_gym.
"""

from .anhysteretic import (ANHYSTERETIC_KINDS, ISING, LANGEVIN, anhysteretic_kind,
                           anhysteretic_magnetization)
from .hysteresis import (DEFAULT_MAX_FIELD_STEP, HysteresisBatch, HysteresisParams, advance_each,
                         advance_shared, simulate_batch, simulate_magnetization, simulate_shared)

__all__ = [
    "ANHYSTERETIC_KINDS", "ISING", "LANGEVIN", "anhysteretic_kind", "anhysteretic_magnetization",
    "DEFAULT_MAX_FIELD_STEP", "HysteresisBatch", "HysteresisParams", "advance_each", "advance_shared",
    "simulate_batch", "simulate_magnetization", "simulate_shared",
]
