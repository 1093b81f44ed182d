"""Persistent-excitation diagnostics: the windowed 3.1(a)/(b) test and the integrand."""

import numpy as np

from hyst_gym.estimation import EstimatorConfig, MinMaxEstimator, PEMonitor


def test_windowed_conditions_on_known_sign_patterns():
    monitor = PEMonitor(n_systems=3, window=4)
    # system 0: integrand flips, beta fixed -> (a); system 1: beta flips, integrand fixed -> (b);
    # system 2: both flip -> neither
    integrand = [(1, 1, 1), (-1, 1, -1), (1, 1, 1), (-1, 1, -1)]
    beta = [(1, 1, 1), (1, -1, -1), (1, 1, 1), (1, -1, -1)]
    for i, b in zip(integrand, beta):
        monitor.update(np.array(i, dtype=float), np.array(b, dtype=float))
    assert monitor.condition_a.tolist() == [True, False, False]
    assert monitor.condition_b.tolist() == [False, True, False]
    # after the window slides past the flips, nothing reverses any more
    for _ in range(4):
        monitor.update(np.ones(3), np.ones(3))
    assert not monitor.condition_a.any() and not monitor.condition_b.any()
    summary = monitor.summary()
    assert summary["held"] == ["a", "b", "neither"]
    assert 0 < summary["fraction_a"][0] < 1 and summary["fraction_a"][1] == 0


def test_integrand_sign_and_curvature_from_the_bank():
    """thetahat < a on a rising field: f(thetahat) > f(a) (M falls with a), so the
    integrand's sign is beta's; it vanishes when thetahat = a."""
    config = EstimatorConfig.paper_scalar(grid_size=32)
    estimator = MinMaxEstimator(config, n_systems=2)
    estimator.reset(a_estimate=[6990.0, 7012.0])
    for field in np.linspace(0.0, 5e4, 200)[1:]:
        estimator.bank.advance(np.full(2, field))
    estimator._refresh()
    integrand = estimator.pe_integrand(7012.0)
    assert np.sign(integrand[0]) == estimator.curvature_sign[0] and integrand[0] != 0
    assert integrand[1] == 0.0
