"""Shared helpers: the true plant driven by the hysteresis model (6), possibly with drifting a."""

import numpy as np

from hyst_gym.physics.hysteresis import HysteresisBatch, HysteresisParams, advance_shared, simulate_magnetization
from hyst_gym.physics.transducers import FirstOrderPlant as TruePlant
from hyst_gym.physics.transducers import LumpedLinear


def true_magnetization(field, a, params=None):
    """M (A/m) of the true material; ``a`` scalar or one value per sample (drift)."""
    params = HysteresisParams() if params is None else params
    a = np.broadcast_to(np.asarray(a, dtype=np.float64), field.shape)
    if np.all(a == a[0]):
        return simulate_magnetization(field, **{**params.__dict__, "a": float(a[0])})
    batch = HysteresisBatch.from_params(params, 1)
    state = np.zeros(1)
    out = np.zeros_like(field)
    for i in range(1, field.size):
        advance_shared(state, field[i - 1], field[i], a[i:i + 1], batch.k, batch.alpha, batch.Ms, batch.c,
                       batch.kind, 50.0)
        out[i] = state[0]
    return out


def true_outputs(magnetization, dt, vector=False):
    """Sampled plant output after each step: (T-1,) for the scalar plant, (T-1, 2) for (13)."""
    model = (LumpedLinear() if vector else TruePlant()).discretize(dt)
    state = model.initial_state(1)
    outputs = []
    for i in range(1, magnetization.size):
        state = model.advance(state, magnetization[i - 1:i], magnetization[i:i + 1])
        if vector:
            outputs.append(np.array([model.output(state)[0], model.velocity(state)[0]]))
        else:
            outputs.append(model.output(state)[0])
    return np.array(outputs)


def run_estimator(estimator, field, outputs, dt, a_true=None):
    """Drive an E=1 estimator; returns (a_estimate per step, V per step or None)."""
    estimates = np.empty(field.size - 1)
    lyapunov = None if a_true is None else np.empty(field.size)
    if a_true is not None:
        lyapunov[0] = estimator.lyapunov_function(a_true)[0]
    for i in range(1, field.size):
        measured = outputs[i - 1][None] if np.ndim(outputs[i - 1]) else np.array([outputs[i - 1]])
        estimates[i - 1] = estimator.update(field[i:i + 1], measured, dt)[0]
        if a_true is not None:
            lyapunov[i] = estimator.lyapunov_function(a_true)[0]
    return estimates, lyapunov
