"""How fast can any input make the scalar min-max estimator converge? A linearized bound.

Near the truth (|thetahat - a| small against the curvature of f in theta) the cost
``g(theta) = f(u, theta) - f(u, thetahat)`` of (15) is locally linear, so the min-max
gives ``nu_star = 0`` and ``phi_star = df/da`` (eq. (15)), and the scalar estimator (14)
on the plant ``y' = -lam*y + nu*M`` reduces to the linear comparison system

    e'      = -gamma*nu*phi(t)*ytilde          e = thetahat - a      (A/m)
    ytilde' = -lam*ytilde + nu*phi(t)*e        ytilde = yhat - y     (units of y)

with ``e(0) = e0`` and ``ytilde(0) = 0``. The input enters only through the sensitivity
``phi(t) = df/da`` (A/m of M per A/m of a) along the field history. A field that starts
at 0 under a slew limit cannot exceed ``|H| <= min(slew*t, field_limit)``, so ``|phi(t)|``
cannot exceed the *sensitivity envelope* ``Phi(t)``: the largest sensitivity at any field
reachable by time t. Driving the comparison system with ``Phi(t)`` gives the smallest
error any admissible ``phi`` can give at every instant while the system is overdamped
(``gamma*(nu*Phi)**2 < lam**2/4``; :func:`error_bound` checks this, and the tests check
the pointwise claim on random admissible profiles). Its first passage into the settle band
is then a lower bound on the settle time of any input, up to the linearization, the
dead zone (which only slows convergence) and the measurement noise (which can carry an
estimate into the band early by chance).

The sensitivity is taken from the estimator's own bank (:class:`ModelBank`) along the
initial magnetization curve from the demagnetized state; for the paper's nearly
anhysteretic parameters other histories reach about the same sensitivity at the same
``|H|`` (``experiments/settle_floor.py`` checks this on every agent's field trace).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from .bank import ModelBank
from .config import EstimatorConfig, FirstOrderPlant


def sensitivity_curve(config: EstimatorConfig, a: float, field_limit: float, field_step: float = 100.0):
    """``|df/da|`` at ``a`` along the initial magnetization curve, H = 0 -> ``field_limit``.

    Parameters
    ----------
    config : EstimatorConfig
        The estimator whose bank gives ``f`` and ``df/dtheta`` (its grid must contain ``a``).
    a : float
        The true parameter, A/m.
    field_limit : float
        Largest field, A/m (> 0).
    field_step : float
        Spacing of the returned fields, A/m (> 0).

    Returns
    -------
    field : ndarray (n,)
        Fields ``field_step, 2*field_step, ..., <= field_limit``, A/m.
    sensitivity : ndarray (n,)
        ``|dM/da|`` at each field, A/m of M per A/m of a (dimensionless).
    """
    if not (np.isfinite(field_limit) and field_limit > 0):
        raise ValueError(f"sensitivity_curve: field_limit must be a positive number of A/m, got {field_limit!r}")
    if not (np.isfinite(field_step) and 0 < field_step <= field_limit):
        raise ValueError(f"sensitivity_curve: field_step must be in (0, field_limit] A/m, got {field_step!r}")
    if not config.theta_min <= a <= config.theta_max:
        raise ValueError(f"sensitivity_curve: a = {a!r} lies outside Theta = "
                         f"[{config.theta_min!r}, {config.theta_max!r}]")
    fields = np.arange(1, int(np.floor(field_limit / field_step + 1e-9)) + 1) * field_step
    return fields, sensitivity_along(config, fields, a)


def sensitivity_along(config: EstimatorConfig, field, a: float) -> np.ndarray:
    """``|df/da|`` at ``a`` (dimensionless) after each sample of a field path (A/m) that starts
    demagnetized at H = 0, from the estimator's own bank."""
    bank = ModelBank(config, n_systems=1)
    theta = np.array([float(a)])
    sensitivity = np.empty(len(field))
    for index, value in enumerate(np.asarray(field, dtype=np.float64)):
        bank.advance(np.array([value]))
        sensitivity[index] = abs(bank.evaluate(theta)[1][0])
    return sensitivity


def sensitivity_envelope(time, fields, sensitivity, slew_rate: float, field_limit: float) -> np.ndarray:
    """``Phi(t)``: the largest sensitivity at any field reachable by time t, ``|H| <= min(slew*t, limit)``.

    ``fields``/``sensitivity`` are a curve from :func:`sensitivity_curve` (the curve is
    taken as 0 at H = 0); ``time`` in s, ``slew_rate`` in A/m/s, ``field_limit`` in A/m.
    """
    time = np.asarray(time, dtype=np.float64)
    if slew_rate <= 0 or field_limit <= 0:
        raise ValueError(f"sensitivity_envelope: slew_rate and field_limit must be > 0, got {slew_rate!r}, "
                         f"{field_limit!r}")
    reachable = np.minimum(slew_rate * np.maximum(time, 0.0), field_limit)
    best_so_far = np.maximum.accumulate(np.concatenate([[0.0], np.asarray(sensitivity, dtype=np.float64)]))
    return np.interp(reachable, np.concatenate([[0.0], np.asarray(fields, dtype=np.float64)]), best_so_far)


def error_bound(time, sensitivity, initial_error: float, plant: FirstOrderPlant, gamma: float) -> np.ndarray:
    """``|e(t)|`` of the linearized comparison system driven by ``sensitivity`` (module docstring).

    Parameters
    ----------
    time : ndarray (n,)
        Increasing instants, s; ``time[0]`` is the start (``e = initial_error`` there).
    sensitivity : ndarray (n,)
        ``|df/da|`` on ``time``. Over each interval it is held at the larger of its two
        end values, so for a nondecreasing envelope the result stays a lower bound.
    initial_error : float
        ``|thetahat(0) - a|``, A/m.
    plant : FirstOrderPlant
        ``decay_rate`` lambda (1/s) and ``gain`` nu of the scalar plant.
    gamma : float
        Adaptation gain of the estimator.

    Returns
    -------
    ndarray (n,)
        ``|e(t)|``, A/m.
    """
    time = np.asarray(time, dtype=np.float64)
    sensitivity = np.asarray(sensitivity, dtype=np.float64)
    if time.ndim != 1 or time.shape != sensitivity.shape or time.size < 1:
        raise ValueError(f"error_bound: time and sensitivity must be 1-D of one length, got shapes "
                         f"{time.shape} and {sensitivity.shape}")
    if np.any(np.diff(time) <= 0):
        raise ValueError("error_bound: time must be strictly increasing")
    coupling = plant.gain * np.abs(sensitivity)
    coupling = np.maximum(coupling[:-1], coupling[1:]) if time.size > 1 else coupling
    if np.any(gamma * coupling ** 2 >= plant.decay_rate ** 2 / 4):
        raise ValueError(f"error_bound: gamma*(nu*phi)**2 reaches lam**2/4 = {plant.decay_rate ** 2 / 4:g}: the "
                         f"comparison system is not overdamped there, and the pointwise bound does not hold")
    state = np.array([abs(float(initial_error)), 0.0])
    error = np.empty_like(time)
    error[0] = state[0]
    # exact on each interval (phi frozen), so the bound does not depend on a step size
    for index in range(1, time.size):
        rate = coupling[index - 1]  # the interval (time[index-1], time[index])
        generator = np.array([[0.0, -gamma * rate], [rate, -plant.decay_rate]])
        state = expm(generator * (time[index] - time[index - 1])) @ state
        error[index] = abs(state[0])
    return error


def first_passage(time, error, band: float) -> float:
    """First instant at which ``error <= band`` (s), ``nan`` if never."""
    below = np.flatnonzero(np.asarray(error) <= band)
    return float(np.asarray(time)[below[0]]) if below.size else float("nan")


__all__ = ["sensitivity_curve", "sensitivity_along", "sensitivity_envelope", "error_bound", "first_passage"]
