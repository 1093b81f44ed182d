"""Fisher information about the anhysteretic parameter a carried by an input H(t).

For the first-order plant of the paper (§4.1), ``y' = -lambda*y + nu*M(H; a)``, with
additive white measurement noise of standard deviation ``sigma`` on y at every control
step, the Fisher information about a of the samples ``y_1..y_N`` is::

    I(a) = sum_k (dy_k/da)^2 / sigma^2

The sensitivity ``dM/da`` is taken by a central difference on a two-model bank
``a*(1 -+ rel_step)`` driven by the same field (the compiled kernel of
:mod:`hyst_gym.physics.hysteresis`), and ``dy/da`` follows by filtering it through the
plant, discretized exactly for a zero-order hold on M. Everything is rate independent in
M, so the cost follows the input's variation.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from hyst_gym.physics import FirstOrderPlant, HysteresisBatch, HysteresisParams, simulate_batch

#: the default models of the signatures below (frozen dataclasses: one shared instance is safe)
DEFAULT_HYSTERESIS = HysteresisParams()
DEFAULT_PLANT = FirstOrderPlant()


def zero_order_hold(plant: FirstOrderPlant, dt: float) -> tuple[float, float]:
    """``(pole, input_gain)`` of ``y' = -lambda*y + nu*M`` sampled every ``dt`` (s) with M held
    over each period: ``y[k+1] = pole*y[k] + input_gain*M[k]`` (exact for a held M)."""
    pole = np.exp(-plant.decay_rate * dt)
    return pole, plant.gain * (1.0 - pole) / plant.decay_rate


def plant_output(plant: FirstOrderPlant, magnetization, dt: float, axis: int = 0) -> np.ndarray:
    """y at the samples (y_0 = 0) for M held constant over each period dt (s)."""
    pole, input_gain = zero_order_hold(plant, dt)
    return lfilter([0.0, input_gain], [1.0, -pole], magnetization, axis=axis)


def magnetization_sensitivity(field, a_values, params: HysteresisParams = DEFAULT_HYSTERESIS,
                              rel_step: float = 1e-3) -> np.ndarray:
    """dM/da (dimensionless) along ``field`` (A/m, from M = 0 at H = 0) for each a in ``a_values``.

    Returns shape ``(len(field), len(a_values))``.
    """
    a_values = np.atleast_1d(np.asarray(a_values, dtype=np.float64))
    bank = np.concatenate([a_values * (1 - rel_step), a_values * (1 + rel_step)])
    field = np.concatenate([[0.0], np.asarray(field, dtype=np.float64)])
    magnetization = simulate_batch(field, HysteresisBatch.grid(params, bank))[1:]
    n = a_values.shape[0]
    return (magnetization[:, n:] - magnetization[:, :n]) / (2 * rel_step * a_values)


def fisher_information(field, dt: float, a_values, params: HysteresisParams = DEFAULT_HYSTERESIS,
                       plant: FirstOrderPlant = DEFAULT_PLANT, noise_std: float = 1.0) -> np.ndarray:
    """Fisher information about a (1/(A/m)^2 per unit noise variance) for each a in ``a_values``."""
    sensitivity = plant_output(plant, magnetization_sensitivity(field, a_values, params), dt, axis=0)
    return np.sum(sensitivity ** 2, axis=0) / noise_std ** 2


__all__ = ["magnetization_sensitivity", "fisher_information", "plant_output", "zero_order_hold"]
