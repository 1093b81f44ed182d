"""Theorem 1's integral condition (22), 3.1(a)/(b), the truth-free version and the ROC tools,
checked against independent computations."""

import numpy as np
import pytest

from hyst_gym.estimation import EstimatorConfig, MinMaxEstimator, ModelBank, PEMonitor, error_bound, first_passage
from hyst_gym.estimation import integral_condition as ic

from estimation_helpers import true_magnetization, true_outputs

GRID = np.linspace(6300.0, 7300.0, 21)


def quadratic_bank(time, center=6800.0):
    """f(t, theta) = t*(theta - center)**2 on GRID: quadratic in theta (so the cubic Hermite
    interpolant with finite-difference slopes is exact), convex (beta = +1) for t > 0, and
    linear in t (so the trapezoid rule integrates it exactly)."""
    return time[:, None] * (GRID[None, :] - center) ** 2


def test_interpolant_is_exact_for_quadratics_and_matches_the_estimator():
    """Centred and second-order end differences are exact on quadratics, so the C1 Hermite
    interpolant reproduces f, f' and f'' of a quadratic in theta anywhere on the grid; and on a real
    bank it gives the numbers of the estimator's own evaluation."""
    config = EstimatorConfig.paper_scalar(grid_size=32)
    grid = config.theta_grid
    rng = np.random.default_rng(1)
    coeffs = rng.normal(size=(4, 3)) * [1e-3, 1.0, 1e3]
    values = np.array([c[0] * grid ** 2 + c[1] * grid + c[2] for c in coeffs])
    theta = rng.uniform(grid[0], grid[-1], (4, 5))
    rows = np.repeat(np.arange(4)[:, None], 5, axis=1)
    f, slope, curvature = ic.interpolate(grid, values, theta, rows)
    c = coeffs[rows]
    np.testing.assert_allclose(f, c[..., 0] * theta ** 2 + c[..., 1] * theta + c[..., 2], rtol=1e-10)
    np.testing.assert_allclose(slope, 2 * c[..., 0] * theta + c[..., 1], rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(curvature, 2 * c[..., 0], rtol=1e-6)
    bank = ModelBank(config, n_systems=3)
    for field in np.linspace(0.0, 8e4, 60)[1:]:
        bank.advance(np.full(3, field) * np.array([1.0, 0.5, -0.7]))
    estimate = rng.uniform(6300.0, 7300.0, 3)
    for e, g in zip(bank.evaluate(estimate), ic.interpolate(grid, bank.magnetization, estimate)):
        np.testing.assert_array_equal(g, e)


def test_frozen_integral_has_the_known_value():
    """beta = +1 and f linear in t: the integral of nu*(f(thetahat(t_s)) - f(a)) over
    [t_s, t_s + delta] is nu*((thetahat - c)^2 - (a - c)^2)*(t_s + delta/2)*delta exactly."""
    dt, delta_steps, nu, c = 0.01, 7, 2.0, 6800.0
    time = 0.5 + dt * np.arange(60)
    bank = quadratic_bank(time, c)
    theta_hat = 6900.0 + 30.0 * np.sin(time)  # frozen at each start
    a = 7012.0
    parts = ic.frozen_integrals(GRID, bank, theta_hat, np.full(time.size, a), dt, delta_steps, nu)
    starts = time.size - delta_steps
    delta = delta_steps * dt
    expected = nu * ((theta_hat[:starts] - c) ** 2 - (a - c) ** 2) * (time[:starts] + delta / 2) * delta
    np.testing.assert_allclose(parts["with_beta"], expected, rtol=1e-9)
    np.testing.assert_allclose(parts["without_beta"], expected, rtol=1e-9)
    np.testing.assert_allclose(parts["error"], np.abs(theta_hat[:starts] - a))


def test_given_reference_values_and_a_reused_frozen_estimate_change_nothing():
    dt, delta_steps = 0.01, 4
    time = 0.5 + dt * np.arange(30)
    bank = np.cos(time)[:, None] * (GRID[None, :] - 6700.0) ** 2
    theta_hat = np.linspace(6950.0, 7050.0, time.size)
    a = np.full(time.size, 7012.0)
    plain = ic.frozen_integrals(GRID, bank, theta_hat, a, dt, delta_steps)
    f_true = ic.interpolate(GRID, bank, a)[0]
    frozen = ic.frozen_estimate(GRID, bank, theta_hat, delta_steps)
    given = ic.frozen_integrals(GRID, bank, theta_hat, a, dt, delta_steps, reference_values=f_true, frozen=frozen)
    for key in plain:
        np.testing.assert_allclose(given[key], plain[key], rtol=1e-12, atol=1e-12)
    shifted = ic.frozen_integrals(GRID, bank, theta_hat, a, dt, delta_steps, reference_values=f_true + 1.0)
    # f(a) one A/m higher lowers the raw integral by nu*1*delta exactly
    np.testing.assert_allclose(shifted["without_beta"], plain["without_beta"] - delta_steps * dt, rtol=1e-12)


def test_frozen_integral_with_sign_changes_against_a_direct_trapezoid():
    """A bank whose curvature in theta changes sign in time: beta*nu*(f(thetahat(t_s)) - f(a))
    evaluated sample by sample from the formula, then numpy's trapezoid over each subinterval."""
    dt, delta_steps, nu = 0.02, 9, 1.0
    time = dt * np.arange(80)
    c = 6750.0

    def f(t, theta):
        return np.sin(3 * t) * (theta - c) ** 2 + 40.0 * np.cos(t) * theta

    bank = f(time[:, None], GRID[None, :])
    theta_hat = 6990.0 + 5.0 * time
    a = 7012.0 + 2.0 * np.cos(time)  # a drifting truth, per instant
    parts = ic.frozen_integrals(GRID, bank, theta_hat, a, dt, delta_steps, nu)
    for s in range(time.size - delta_steps):
        window = slice(s, s + delta_steps + 1)
        beta = np.where(np.sin(3 * time[window]) >= 0, 1.0, -1.0)  # d2f/dtheta2 = 2 sin(3t)
        raw = nu * (f(time[window], theta_hat[s]) - f(time[window], a[window]))
        assert parts["with_beta"][s] == pytest.approx(np.trapezoid(beta * raw, dx=dt), rel=1e-9, abs=1e-9)
        assert parts["without_beta"][s] == pytest.approx(np.trapezoid(raw, dx=dt), rel=1e-9, abs=1e-9)


def test_windowed_existence_against_brute_force():
    rng = np.random.default_rng(2)
    values = rng.normal(size=50)
    for span in (0, 1, 6):
        expected = [max(values[t:t + span + 1]) for t in range(values.size - span)]
        np.testing.assert_array_equal(ic.exists_in_window(values, span), expected)


def test_condition_22_margin_and_windows():
    """(22) holds in a window exactly when some subinterval clears 2*eps + eps0*|theta_tilde|."""
    dt, delta_steps, span = 0.01, 5, 10
    time = 0.5 + dt * np.arange(100)
    bank = quadratic_bank(time)
    theta_hat = np.full(time.size, 6990.0)
    a = 7012.0
    eps, eps0 = 0.01, 3.0
    out = ic.integral_condition(GRID, bank, theta_hat, a, dt, delta_steps, span, eps, eps0)
    parts = ic.frozen_integrals(GRID, bank, theta_hat, np.full(time.size, a), dt, delta_steps)
    margin = parts["with_beta"] - (2 * eps + eps0 * 22.0)
    np.testing.assert_allclose(out["beta"], [margin[t:t + span + 1].max() for t in range(margin.size - span)])
    # f(6990) < f(7012) here (f grows with theta - 6800 > 0), beta = +1: the signed integral is
    # negative, (22) fails everywhere; its magnitude passes
    assert np.all(out["beta"] < 0) and np.all(out["magnitude"] > 0)


def test_truth_free_equals_truth_when_the_envelope_collapses_onto_a():
    dt, delta_steps, span = 0.02, 6, 8
    time = 0.3 + dt * np.arange(70)
    bank = np.sin(2 * time)[:, None] * (GRID[None, :] - 6700.0) ** 2 + 0.1 * time[:, None] * GRID[None, :]
    theta_hat = 6900.0 + 40.0 * np.sin(time)
    a = 7012.0
    eps, eps0 = 0.01, 0.2
    truth = ic.integral_condition(GRID, bank, theta_hat, a, dt, delta_steps, span, eps, eps0)["beta"]
    starts = time.size - delta_steps
    radius = np.abs(a - theta_hat[:starts])
    side = np.sign(a - theta_hat[:starts])
    collapsed = ic.truth_free_condition(GRID, bank, theta_hat, radius, dt, delta_steps, span, eps, eps0, side=side)
    np.testing.assert_allclose(collapsed, truth, rtol=1e-12, atol=1e-12)
    # the candidate set {a} reached by the certificate over both sides: the other side leaves Theta
    low = np.full(time.size, 6400.0)
    truth_low = ic.integral_condition(GRID, bank, low, 7300.0, dt, delta_steps, span, eps, eps0)["beta"]
    both = ic.truth_free_condition(GRID, bank, low, 900.0, dt, delta_steps, span, eps, eps0)
    np.testing.assert_allclose(both, truth_low, rtol=1e-12, atol=1e-12)


def test_truth_free_two_sided_needs_both_signs():
    """With f monotone in theta and beta fixed, the two candidates give integrals of opposite
    sign: the two-sided certificate fails although the side where a lies passes."""
    dt, delta_steps, span = 0.01, 5, 5
    time = 0.5 + dt * np.arange(40)
    bank = quadratic_bank(time, center=6000.0)  # increasing and convex on Theta
    theta_hat = np.full(time.size, 6990.0)
    below, above = ic.candidate_margins(GRID, bank, theta_hat, 7.0, dt, delta_steps, 0.01, 0.0)
    assert np.all(above < 0) and np.all(below > 0)
    assert np.all(ic.truth_free_condition(GRID, bank, theta_hat, 7.0, dt, delta_steps, span, 0.01, 0.0) < 0)
    side = -np.ones(time.size - delta_steps)
    assert np.all(ic.truth_free_condition(GRID, bank, theta_hat, 7.0, dt, delta_steps, span, 0.01, 0.0,
                                          side=side) > 0)


def test_integrand_matches_the_estimator_along_a_closed_loop():
    """The bank replay plus this module's interpolant give the estimator's own pe_integrand."""
    config = EstimatorConfig.paper_scalar(grid_size=32, gamma=50.0)
    dt, a_true = 1e-3, 7012.0
    field = np.concatenate([np.linspace(0.0, 6e4, 800), np.linspace(6e4, -3e4, 700)[1:]])
    outputs = true_outputs(true_magnetization(field, a_true), dt)
    estimator = MinMaxEstimator(config, 1)
    estimates, integrands = [], []
    for i in range(1, field.size):
        estimates.append(estimator.update(field[i:i + 1], np.array([outputs[i - 1]]), dt)[0])
        integrands.append(estimator.pe_integrand(a_true)[0])
    bank = ic.bank_trace(config, field[1:])
    f_hat, _, curvature = ic.interpolate(config.theta_grid, bank, np.array(estimates))
    f_true, _, _ = ic.interpolate(config.theta_grid, bank, np.full(len(estimates), a_true))
    mine = ic.curvature_sign(curvature) * config.plant.gain * (f_hat - f_true)
    assert np.ptp(estimates) > 1.0  # the estimate moved
    np.testing.assert_allclose(mine, integrands, rtol=1e-9, atol=1e-9)


def test_sign_conditions_agree_with_the_pe_monitor_on_full_windows():
    rng = np.random.default_rng(3)
    steps, window = 300, 6
    integrand = np.repeat(rng.choice([-1.0, 1.0], steps // 3) * rng.uniform(0.5, 2.0, steps // 3), 3)
    beta = np.repeat(rng.choice([-1.0, 1.0], steps // 5, p=[0.3, 0.7]), 5)
    mine = ic.sign_conditions(integrand / beta, beta, window)  # the module takes the integrand without beta
    monitor = PEMonitor(1, window)
    flags_a, flags_b = [], []
    for i in range(steps):
        monitor.update(np.array([integrand[i]]), np.array([beta[i]]))
        flags_a.append(monitor.condition_a[0])
        flags_b.append(monitor.condition_b[0])
    np.testing.assert_array_equal(mine["a"], flags_a[window - 1:])
    np.testing.assert_array_equal(mine["b_beta"], flags_b[window - 1:])
    assert mine["a"].any() and mine["b_beta"].any()


def test_the_two_readings_of_31b():
    """beta flips while f(thetahat) - f(a) keeps its sign: 3.1(b) without beta, not with it."""
    raw = np.full(8, 3.0)
    beta = np.array([1, 1, 1, 1, -1, -1, -1, -1.0])
    out = ic.sign_conditions(raw, beta, 8)
    assert out["b_raw"].tolist() == [True] and out["b_beta"].tolist() == [False] and out["a"].tolist() == [False]
    out = ic.sign_conditions(raw * beta, beta, 8)  # beta*raw keeps its sign instead
    assert out["b_beta"].tolist() == [True] and out["b_raw"].tolist() == [False]
    assert not ic.sign_conditions(np.zeros(8), beta, 8)["b_raw"].any()  # no sign at all: no condition


def test_roc_auc_against_a_pairwise_count():
    rng = np.random.default_rng(4)
    for _ in range(20):
        n = rng.integers(5, 60)
        scores = rng.integers(0, 6, n).astype(float)  # many ties
        labels = rng.random(n) < 0.4
        if labels.all() or not labels.any():
            continue
        pos, neg = scores[labels], scores[~labels]
        wins = np.sum(pos[:, None] > neg[None, :]) + 0.5 * np.sum(pos[:, None] == neg[None, :])
        brute = wins / (pos.size * neg.size)
        assert ic.roc_auc(scores, labels) == pytest.approx(brute, abs=1e-12)
        fpr, tpr = ic.roc_curve(scores, labels)
        assert np.trapezoid(tpr, fpr) == pytest.approx(brute, abs=1e-12)  # the curve's area is the AUC
    assert np.isnan(ic.roc_auc(np.ones(3), np.ones(3, dtype=bool)))


def test_bootstrap_resamples_clusters():
    scores = np.array([0.9, 0.8, 0.95, 0.1, 0.2, 0.15])
    labels = np.array([True, True, True, False, False, False])
    clusters = np.array(["a", "a", "b", "c", "c", "d"])
    assert ic.bootstrap_auc(scores, labels, clusters, n_boot=200, seed=0) == (1.0, 1.0)
    rng = np.random.default_rng(5)
    scores = rng.normal(size=200) + np.repeat(rng.normal(size=20), 10)
    labels = np.repeat(rng.random(20) < 0.5, 10)
    clusters = np.repeat(np.arange(20), 10)
    lo, hi = ic.bootstrap_auc(scores, labels, clusters, n_boot=300, seed=1)
    assert 0.0 <= lo <= ic.roc_auc(scores, labels) <= hi <= 1.0
    assert (lo, hi) == ic.bootstrap_auc(scores, labels, clusters, n_boot=300, seed=1)  # deterministic


def test_required_eps0_settles_the_comparison_system_within_the_horizon():
    """At the sensitivity eps0/(nu*delta) the linearized estimator of convergence.py goes from the
    initial error to the band in about the horizon (quasi-static while lambda dominates)."""
    config = EstimatorConfig.paper_scalar(grid_size=32)
    lam, gain, gamma = config.plant.decay_rate, config.plant.gain, config.gamma
    initial, band, horizon, delta = 22.0, 7.012, 10.0, 0.5
    eps0 = ic.required_eps0(initial, band, horizon, delta, lam, gamma, gain)
    phi = eps0 / (gain * delta)
    time = np.linspace(0.0, 2 * horizon, 4001)
    error = error_bound(time, np.full(time.size, phi), initial, config.plant, gamma)
    assert first_passage(time, error, band) == pytest.approx(horizon, rel=0.03)
    assert ic.required_eps0(5.0, band, horizon, delta, lam, gamma, gain) == 0.0


def test_bad_arguments_raise_one_line_errors():
    bank = quadratic_bank(0.5 + 0.01 * np.arange(20))
    with pytest.raises(ValueError, match="delta_steps"):
        ic.frozen_integrals(GRID, bank, np.full(20, 7000.0), np.full(20, 7012.0), 0.01, 0, 1.0)
    with pytest.raises(ValueError, match="dt"):
        ic.frozen_integrals(GRID, bank, np.full(20, 7000.0), np.full(20, 7012.0), -1.0, 3, 1.0)
    with pytest.raises(ValueError, match="reference"):
        ic.frozen_integrals(GRID, bank, np.full(20, 7000.0), np.full(7, 7012.0), 0.01, 3, 1.0)
    with pytest.raises(ValueError, match="window"):
        ic.sign_conditions(np.ones(5), np.ones(5), 9)
    with pytest.raises(ValueError, match="radius"):
        ic.candidate_margins(GRID, bank, np.full(20, 7000.0), -1.0, 0.01, 3, 0.01, 0.0)
    with pytest.raises(ValueError, match="initial_error"):
        ic.required_eps0(float("nan"), 7.0, 10.0, 0.5, 100.0, 1.0)
