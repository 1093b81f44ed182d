"""The Van Trees floor of suite v2 (hyst_gym.estimation.information_bound), cross-checked."""

import numpy as np
import pytest
from scipy.integrate import quad

from hyst_gym.estimation.information_bound import (BoundSetting, SensitivityTable, information_ceiling,
                                                   magnetization_sensitivity, random_admissible_fields,
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


def test_ceiling_holds_for_admissible_inputs_computed_independently():
    """The Fisher information of the first-order plant under several admissible inputs, computed by
    baselines.information (finite difference and the plant filter), stays below the ceiling."""
    from baselines.information import fisher_information
    from hyst_gym.envs.suite_v2 import bound_setting, task_config_v2
    from hyst_gym.estimation.information_bound import sensitivity_table

    config = task_config_v2("hyst_gym/HotCalibrate-v0")
    setting = bound_setting(config)
    table = sensitivity_table(config.hysteresis, (setting.a_lo, 7900.0), config.field_limit, config.max_field_change,
                              config.max_field_step, n_paths=32, steps=config.episode_steps)
    ceiling = information_ceiling(setting, table)
    scale = config.transducer.gain * config.hysteresis.Ms / config.transducer.decay_rate
    ramp = np.minimum(config.max_field_change * np.arange(1, 201), 8.1e4)
    inputs = [ramp] + list(random_admissible_fields(6, 200, config.max_field_change, 1e5, seed=7).T)
    for field in inputs:
        for a in (6700.0, 7300.0):
            info = fisher_information(field, config.dt, [a], config.hysteresis.replace(a=a), config.transducer,
                                      noise_std=setting.sigma * scale)[0]
            assert info <= ceiling[-1]
    # the slew ramp to the peak field comes within a factor 2 of the ceiling (the relaxation is not vacuous)
    best = fisher_information(ramp, config.dt, [7012.0], config.hysteresis, config.transducer,
                              noise_std=setting.sigma * scale)[0]
    assert best > 0.5 * ceiling[-1]
