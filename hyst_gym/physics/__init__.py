"""Pure, batched, compiled physics kernels: hysteresis, transducers, temperature.

This layer imports nothing else from hyst_gym.
"""

from .anhysteretic import (ANHYSTERETIC_KINDS, ISING, LANGEVIN, anhysteretic_kind,
                           anhysteretic_magnetization)
from .hysteresis import (DEFAULT_MAX_FIELD_STEP, HysteresisBatch, HysteresisParams, advance_each,
                         advance_shared, simulate_batch, simulate_magnetization, simulate_shared)
from .constants import PAPER_A, PAPER_COUPLING, PAPER_DAMPING, PAPER_STIFFNESS, ROOM_TEMPERATURE
from .fem import FEMRod, analytic_frequencies
from .hem import HEMBatch, HEMParams, HEMState, simulate_hem, simulate_hem_batch
from .linear_system import DiscreteTransducer
from .thermal import ThermalParams, a_of_temperature, advance_temperature, temperature_of_a
from .transducers import (DEFAULT_BIAS_MAGNETIZATION, FirstOrderPlant, LumpedLinear, LumpedNonlinear,
                          RodParams)

__all__ = [
    "ANHYSTERETIC_KINDS", "ISING", "LANGEVIN", "anhysteretic_kind", "anhysteretic_magnetization",
    "DEFAULT_MAX_FIELD_STEP", "HysteresisBatch", "HysteresisParams", "advance_each", "advance_shared",
    "simulate_batch", "simulate_magnetization", "simulate_shared",
    "HEMBatch", "HEMParams", "HEMState", "simulate_hem", "simulate_hem_batch",
    "DEFAULT_BIAS_MAGNETIZATION", "DiscreteTransducer", "FEMRod", "FirstOrderPlant", "LumpedLinear",
    "LumpedNonlinear", "RodParams", "analytic_frequencies",
    "ThermalParams", "a_of_temperature", "advance_temperature", "temperature_of_a",
    "PAPER_A", "PAPER_COUPLING", "PAPER_DAMPING", "PAPER_STIFFNESS", "ROOM_TEMPERATURE",
]
