"""The closed-form min-max (envelopes) against an independent LP brute force of (15)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyst_gym.estimation import envelopes, minmax_solution
from hyst_gym.estimation.reference import minmax_brute_force, minmax_objective
from hyst_gym.physics import HysteresisBatch, HysteresisParams, simulate_batch


def _check_against_brute_force(grid, g, theta_hat, sign, gradient):
    nu, phi = minmax_solution(grid, g, theta_hat, sign, gradient)
    nu_lp, _ = minmax_brute_force(grid, g, theta_hat, sign)
    scale = 1.0 + np.max(np.abs(g))
    assert nu >= 0.0
    assert abs(nu - nu_lp) <= 1e-7 * scale
    # the closed-form slope is a minimizer: it attains the min-max value
    assert minmax_objective(grid, g, theta_hat, sign, phi) <= nu_lp + 1e-7 * scale


@settings(max_examples=150, deadline=None)
@given(values=st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=40),
       position=st.floats(0.0, 1.0), sign=st.sampled_from([-1.0, 1.0]),
       gradient=st.floats(-50.0, 50.0), on_node=st.booleans())
def test_closed_form_matches_brute_force_on_random_g(values, position, sign, gradient, on_node):
    grid = np.linspace(6300.0, 7300.0, len(values))
    theta_hat = grid[int(round(position * (len(values) - 1)))] if on_node else 6300.0 + 1000.0 * position
    g = np.asarray(values)
    g[grid == theta_hat] = 0.0  # g(thetahat) = 0 by definition
    _check_against_brute_force(grid, g, theta_hat, sign, gradient)


@settings(max_examples=60, deadline=None)
@given(sample=st.integers(0, 399), position=st.floats(0.0, 1.0), sign=st.sampled_from([-1.0, 1.0]),
       hysteretic=st.booleans())
def test_closed_form_matches_brute_force_on_hysteresis_g(bank_history, sample, position, sign, hysteretic):
    grid, history = bank_history[hysteretic]
    values = history[sample]
    theta_hat = 6300.0 + 1000.0 * position
    f_hat = np.interp(theta_hat, grid, values)
    gradient = np.interp(theta_hat, grid[1:], np.diff(values) / np.diff(grid))
    _check_against_brute_force(grid, values - f_hat, theta_hat, sign, gradient)


def test_convex_g_gives_gradient_and_zero_gap():
    grid = np.linspace(-1.0, 1.0, 21)
    theta_hat = 0.35  # mid-interval: the kink slopes are 0.65 and 0.75
    g = grid ** 2 - theta_hat ** 2
    nu, phi = minmax_solution(grid, g, theta_hat, 1.0, 2 * theta_hat)
    assert nu == 0.0 and phi == 2 * theta_hat  # the gradient 0.7 lies in the subdifferential
    # sign -1: the concave cover of a convex g is the chord between the ends of Theta
    nu, phi = minmax_solution(grid, g, theta_hat, -1.0, 2 * theta_hat)
    assert np.isclose(nu, 1.0 - theta_hat ** 2) and np.isclose(phi, 0.0, atol=1e-12)


def test_envelopes_bound_the_points():
    rng = np.random.default_rng(3)
    grid = np.linspace(0.0, 1.0, 30)
    g = rng.normal(size=30)
    x, lower, upper = envelopes(grid, g, 0.37)
    values = np.interp(x, np.append(grid, 0.37)[np.argsort(np.append(grid, 0.37))],
                       np.append(g, 0.0)[np.argsort(np.append(grid, 0.37))])
    assert np.all(lower <= values + 1e-12) and np.all(upper >= values - 1e-12)
    assert np.all(np.diff(np.diff(lower) / np.diff(x)) >= -1e-9)  # convex
    assert np.all(np.diff(np.diff(upper) / np.diff(x)) <= 1e-9)  # concave


def _bank_history():
    grid = np.linspace(6300.0, 7300.0, 33)
    time = np.linspace(0.0, 2.0, 400)
    field = 6e4 * np.sin(2 * np.pi * time) * np.minimum(1.0, time)
    out = {}
    for hysteretic, params in ((False, HysteresisParams()), (True, HysteresisParams(k=4000.0, alpha=-0.01))):
        out[hysteretic] = (grid, simulate_batch(field, HysteresisBatch.grid(params, grid)))
    return out



@pytest.fixture(scope="module")
def bank_history():
    return _bank_history()
