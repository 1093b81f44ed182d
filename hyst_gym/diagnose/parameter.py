"""One fitted model parameter: its physical value, bounds, unit and fitted coordinate."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Parameter:
    """One model parameter: physical value, bounds, unit, whether it is fitted.

    The fitted coordinate is ``ln(value)`` for a positive scale parameter (``log``) and
    ``value/scale`` for the others."""

    name: str
    value: float
    lower: float
    upper: float
    unit: str
    log: bool = False
    free: bool = True
    scale: float = 1.0  # fitted coordinate is value/scale for linear parameters

    def to_x(self, value):
        return np.log(value) if self.log else value / self.scale

    def from_x(self, x):
        return float(np.exp(x)) if self.log else float(x * self.scale)

    @property
    def x_bounds(self):
        return self.to_x(self.lower), self.to_x(self.upper)


def slope_factor(curve: str) -> float:
    """Man'(0)*a/Ms: 1 for Ising (2), 1/3 for Langevin (3)."""
    return 1.0 if curve == "ising" else 1.0 / 3.0
