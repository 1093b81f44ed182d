"""The Van Trees floor of suite v2 (hyst_gym.estimation.information_bound), cross-checked."""

import numpy as np
import pytest
from scipy.integrate import quad

from hyst_gym.estimation.information_bound import (BoundSetting, SensitivityTable, magnetization_sensitivity,
                                                   raised_cosine_fisher, raised_cosine_quantile, van_trees_mse)
from hyst_gym.physics import HysteresisParams


def test_quantile_inverts_the_cdf_and_the_fisher_information_matches_quadrature():
    u = np.linspace(0, 1, 101)
    x = raised_cosine_quantile(u)
    assert np.allclose(x - np.sin(2 * np.pi * x) / (2 * np.pi), u, atol=1e-12)
    width = 957.0
    density = lambda a: (1 - np.cos(2 * np.pi * a / width)) / width  # noqa: E731
    slope = lambda a: (2 * np.pi / width) * np.sin(2 * np.pi * a / width) / width  # noqa: E731
    numeric = quad(lambda a: slope(a) ** 2 / density(a), 1e-9, width - 1e-9, limit=200)[0]
    assert numeric == pytest.approx(raised_cosine_fisher(width), rel=1e-6)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        raised_cosine_quantile([1.5])


def test_finite_difference_sensitivity_matches_the_estimator_bank():
    """Two independent computations of |dM/da| on the initial curve: central difference of two
    hysteresis models here, the interpolated slope of the estimator's 32-node bank there."""
    from hyst_gym.estimation.config import EstimatorConfig
    from hyst_gym.estimation.convergence import sensitivity_along

    field = np.linspace(500.0, 1.0e5, 200)
    here = magnetization_sensitivity(field, [7012.0], HysteresisParams(), 250.0)[:, 0]
    bank = sensitivity_along(EstimatorConfig(), field, 7012.0)
    assert np.max(np.abs(here - bank)) < 0.02 * here.max()


def test_van_trees_against_monte_carlo_of_the_posterior_mean():
    """Linear case y_t = G*s*a + noise: I_t = t*(G s/sigma)^2 exactly, so the bound must sit below the
    Monte-Carlo MSE of the posterior mean (the Bayes estimator) and approach it as data accumulate."""
    setting = BoundSetting(dt=0.05, steps=40, field_limit=1.0, max_change=1.0, sigma=1e-3, gain=1 / 7.65e5,
                           a_lo=6600.0, a_hi=7560.0)
    s = 3.0
    table = SensitivityTable(np.array([0.5, 1.0]), np.array([s, s]), 1.0, 1.0)
    bound = van_trees_mse(setting, table)
    rng = np.random.default_rng(0)
    grid = np.linspace(setting.a_lo, setting.a_hi, 4001)
    log_prior = np.log(np.maximum(1 - np.cos(2 * np.pi * (grid - setting.a_lo) / (setting.a_hi - setting.a_lo)),
                                  1e-300))
    draws = 3000
    a = setting.a_lo + (setting.a_hi - setting.a_lo) * raised_cosine_quantile(rng.random(draws))
    slope = setting.gain * s
    y = slope * a[:, None] + setting.sigma * rng.standard_normal((draws, setting.steps))
    squared = np.zeros(setting.steps)
    for t in (0, 4, 39):
        sse = ((y[:, :t + 1, None] - slope * grid[None, None, :]) ** 2).sum(axis=1)
        log_post = log_prior[None, :] - sse / (2 * setting.sigma ** 2)
        weights = np.exp(log_post - log_post.max(axis=1, keepdims=True))
        estimate = (weights * grid).sum(axis=1) / weights.sum(axis=1)
        squared[t] = np.mean((estimate - a) ** 2)
    for t in (0, 4, 39):
        assert squared[t] >= 0.95 * bound[t]          # MC error of the mean: a few %
    assert squared[39] / bound[39] < 1.1              # efficient when the data dominate the prior
