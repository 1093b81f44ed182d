"""The linearized convergence bound: closed form, pointwise optimality, and the nonlinear estimator."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyst_gym.estimation import EstimatorConfig, FirstOrderPlant, MinMaxEstimator
from hyst_gym.estimation.convergence import error_bound, first_passage, sensitivity_curve, sensitivity_envelope
from hyst_gym.physics.hysteresis import simulate_magnetization

from estimation_helpers import run_estimator, true_magnetization, true_outputs

PLANT = FirstOrderPlant(100.0, 1.0)
SLEW, LIMIT = 5.0e4, 1.0e5


@pytest.fixture(scope="module")
def paper_curve():
    config = EstimatorConfig.paper_scalar(grid_size=32, max_field_step=250.0)
    fields, sensitivity = sensitivity_curve(config, 7012.0, LIMIT)
    return config, fields, sensitivity


def test_constant_sensitivity_matches_closed_form():
    # e'' + lam*e' + gamma*phi^2*e = 0, e(0) = e0, e'(0) = 0 (ytilde(0) = 0)
    phi, gamma, e0 = 9.0, 1.0, 22.0
    roots = np.roots([1.0, PLANT.decay_rate, gamma * phi ** 2])
    slow, fast = np.sort(roots)[::-1]
    time = np.linspace(0.0, 3.0, 301)
    closed = e0 * (fast * np.exp(slow * time) - slow * np.exp(fast * time)) / (fast - slow)
    bound = error_bound(time, np.full_like(time, phi), e0, PLANT, gamma)
    np.testing.assert_allclose(bound, closed, rtol=1e-10)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.floats(0.05, 3.0))
def test_largest_sensitivity_gives_smallest_error_pointwise(seed, shape):
    # the claim the bound rests on: no admissible sensitivity profile below the envelope
    # gets the error lower at any instant
    rng = np.random.default_rng(seed)
    time = np.linspace(0.0, 3.0, 151)
    envelope = np.minimum(6.0 * time, 9.9)
    profile = envelope * rng.uniform(0.0, 1.0, time.size) ** shape
    best = error_bound(time, envelope, 22.0, PLANT, 1.0)
    other = error_bound(time, profile, 22.0, PLANT, 1.0)
    assert np.all(other >= best - 1e-9)


def test_sensitivity_curve_matches_finite_difference_of_the_physics(paper_curve):
    # the bank's Hermite slope against a central difference of two independent simulations
    config, fields, sensitivity = paper_curve
    path = np.concatenate([[0.0], fields])
    delta = 1.0
    upper = simulate_magnetization(path, a=7012.0 + delta, max_field_step=250.0)[1:]
    lower = simulate_magnetization(path, a=7012.0 - delta, max_field_step=250.0)[1:]
    difference = np.abs(upper - lower) / (2 * delta)
    np.testing.assert_allclose(sensitivity, difference, rtol=2e-2, atol=2e-2)
    # the paper's parameters: sensitivity peaks below the field limit, near 81 kA/m
    assert 7.0e4 < fields[np.argmax(sensitivity)] < 9.0e4


def test_envelope_is_the_reachable_running_maximum(paper_curve):
    _, fields, sensitivity = paper_curve
    time = np.linspace(0.0, 4.0, 401)
    envelope = sensitivity_envelope(time, fields, sensitivity, SLEW, LIMIT)
    assert envelope[0] == 0.0
    assert np.all(np.diff(envelope) >= 0)
    np.testing.assert_allclose(envelope[time >= LIMIT / SLEW], sensitivity.max())
    at_one_second = sensitivity[fields <= SLEW * 1.0].max()
    assert envelope[100] == pytest.approx(at_one_second)


def test_nonlinear_estimator_does_not_beat_the_bound(paper_curve):
    # independent computation: the full min-max estimator (bank, covers, dead zone) under
    # the input the bound calls optimal, the slew-limited ramp to the peak-sensitivity field
    config, fields, sensitivity = paper_curve
    dt = 1e-3
    time = np.arange(0.0, 4.0 + dt / 2, dt)
    peak = fields[np.argmax(sensitivity)]
    field = np.minimum(SLEW * time, peak)
    outputs = true_outputs(true_magnetization(field, 7012.0), dt)
    estimates, _ = run_estimator(MinMaxEstimator(config), field, outputs, dt)
    error = np.abs(estimates - 7012.0)
    bound = error_bound(time, sensitivity_envelope(time, fields, sensitivity, SLEW, LIMIT), 22.0,
                        config.plant, config.gamma)[1:]
    band = 7.012
    assert np.all(error >= bound - 0.1)  # 0.1 A/m: the linearization, 1.4 % of the band
    settle_bound = first_passage(time, error_bound(time, sensitivity_envelope(time, fields, sensitivity, SLEW, LIMIT),
                                                   22.0, config.plant, config.gamma), band)
    settle_estimator = first_passage(time[1:], error, band)
    assert settle_estimator == pytest.approx(settle_bound, abs=0.02)
    assert 2.0 < settle_bound < 2.5


def test_bad_arguments_are_one_line_errors():
    time = np.linspace(0.0, 1.0, 11)
    with pytest.raises(ValueError, match="not overdamped"):
        error_bound(time, np.full_like(time, 60.0), 22.0, PLANT, 1.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        error_bound(time[::-1], np.ones_like(time), 22.0, PLANT, 1.0)
    with pytest.raises(ValueError, match="one length"):
        error_bound(time, np.ones(3), 22.0, PLANT, 1.0)
    with pytest.raises(ValueError, match="outside Theta"):
        sensitivity_curve(EstimatorConfig.paper_scalar(), 9000.0, LIMIT)
    with pytest.raises(ValueError, match="field_limit"):
        sensitivity_curve(EstimatorConfig.paper_scalar(), 7012.0, -1.0)
    assert np.isnan(first_passage(time, np.full_like(time, 10.0), 1.0))
