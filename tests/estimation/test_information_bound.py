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


# ---------------------------------------------------------------------------- the floor with the heat budget

def _thermal(**changes):
    from hyst_gym.estimation.information_bound import ThermalBudget

    values = dict(dt=0.05, thermal_resistance=4.0, heat_capacity=5.0, power_per_square_field=1e-8,
                  temperature_limit=333.15, start_low=278.15, start_high=318.15, a_reference=7012.0,
                  reference_temperature=293.15)
    return ThermalBudget(**{**values, **changes})


def test_thermal_rise_matches_the_heat_equation():
    """The per-step recursion against an ODE solver of C dT/dt = P - (T - T0)/R_th with P held over each step
    at kappa times the mean square of the field moving linearly within it (the env's heating)."""
    from scipy.integrate import solve_ivp

    from hyst_gym.estimation.information_bound import random_admissible_fields

    thermal = _thermal()
    field = random_admissible_fields(8, 40, 2500.0, 1e5, seed=3)
    field = field[:, np.argmax(np.abs(field).max(axis=0))]
    knots = np.concatenate([[0.0], field])
    mean_square = (knots[:-1] ** 2 + knots[:-1] * knots[1:] + knots[1:] ** 2) / 3

    def rate(time, rise):
        power = thermal.power_per_square_field * mean_square[min(int(time / thermal.dt + 1e-9), field.size - 1)]
        return [(power - rise[0] / thermal.thermal_resistance) / thermal.heat_capacity]

    times = thermal.dt * np.arange(1, field.size + 1)
    solved = solve_ivp(rate, (0.0, times[-1]), [0.0], t_eval=times, rtol=1e-10, atol=1e-12, max_step=thermal.dt / 20)
    assert solved.y[0, -1] > 0.1
    assert np.allclose(thermal.rise(field), solved.y[0], rtol=1e-6, atol=1e-9)
    with pytest.raises(ValueError, match="start_high"):
        _thermal(start_high=340.0)


def test_prior_pieces_split_the_raised_cosine_exactly():
    """The pieces' weights sum to 1 and rebuild the prior (a partition of unity); an inner piece, where the
    prior is nearly flat, has the Fisher information of a raised cosine of its own width, pi^2/d_a^2."""
    from hyst_gym.estimation.information_bound import _prior_pieces

    thermal = _thermal()
    centres, weights, coolest, fisher = _prior_pieces(thermal, 1.0)
    assert weights.sum() == pytest.approx(1.0, abs=1e-6)
    assert coolest[0] == thermal.start_low and np.all(np.diff(coolest) >= 0)
    x = np.linspace(thermal.start_low, thermal.start_high, 997)[1:-1]
    width = thermal.start_high - thermal.start_low
    prior = (1 - np.cos(2 * np.pi * (x - thermal.start_low) / width)) / width
    bumps = np.clip(1 - np.abs(x[:, None] - centres[None, :]), 0, None)  # |x - c| < 1 K: inside a bump
    rebuilt = (prior[:, None] * 0.5 * (1 - np.cos(np.pi * (x[:, None] - centres[None, :] + 1.0))) * (bumps > 0)).sum(1)
    assert np.allclose(rebuilt, prior, rtol=1e-9, atol=1e-12)
    middle = np.argmin(np.abs(centres - 0.5 * (thermal.start_low + thermal.start_high)))
    assert fisher[middle] == pytest.approx(np.pi ** 2 / thermal.a_per_kelvin ** 2, rel=0.01)
    with pytest.raises(ValueError, match="divide"):
        _prior_pieces(thermal, 3.0)


def _linear_programme(reward, heat, reach, decay, horizon, budget):
    """The exact optimum of the grid relaxation as a linear programme over path flows (independent of the
    dual): flows x[j, f, g] >= 0 from f_0 = 0, rises D_j = decay*D_{j-1} + sum heat*x <= budget for j < horizon."""
    import scipy.sparse as sparse
    from scipy.optimize import linprog

    n = reward.size
    edges = [(f, g) for f in range(n) for g in range(max(0, f - reach), min(n, f + reach + 1))]
    ef, eg = np.array(edges).T
    ne, nx = len(edges), horizon * len(edges)
    rows, cols, vals, rhs = [], [], [], []

    def add(row_cols, row_vals, value):
        rows.extend([len(rhs)] * len(row_cols))
        cols.extend(row_cols)
        vals.extend(row_vals)
        rhs.append(value)

    add(list(np.flatnonzero(ef == 0)), [1.0] * int(np.sum(ef == 0)), 1.0)
    for j in range(horizon - 1):
        for f in range(n):
            inflow, outflow = np.flatnonzero(eg == f), np.flatnonzero(ef == f)
            add(list(j * ne + inflow) + list((j + 1) * ne + outflow), [1.0] * inflow.size + [-1.0] * outflow.size, 0.0)
    for j in range(horizon):
        add(list(j * ne + np.arange(ne)) + [nx + j] + ([nx + j - 1] if j else []),
            list(heat[ef, eg]) + [-1.0] + ([decay] if j else []), 0.0)
    matrix = sparse.csr_matrix((vals, (rows, cols)), shape=(len(rhs), nx + horizon))
    upper = np.full(nx + horizon, np.inf)
    upper[:ne][ef != 0] = 0.0
    upper[nx:nx + horizon - 1] = budget
    cost = np.concatenate([-np.tile(reward[eg], horizon), np.zeros(horizon)])
    result = linprog(cost, A_eq=matrix, b_eq=np.array(rhs), bounds=np.column_stack([np.zeros(nx + horizon), upper]),
                     method="highs")
    assert result.status == 0
    return -result.fun


def test_dual_ceiling_is_above_the_exact_optimum_and_close_to_it():
    """Weak duality: the dual ceiling can never be below the linear programme's optimum of the same grid
    relaxation, and its multiplier family comes within a few per cent of it."""
    from hyst_gym.estimation.information_bound import CurrentFieldEnvelope, heated_information_ceiling

    slew, cells = 500.0, 2
    fields = np.arange(0.0, 5000.0 + 1, slew / cells)
    envelope = CurrentFieldEnvelope(fields, 1.3e-4 * fields + 0.05 * np.sqrt(fields / fields[-1]), fields, 1.0, 0, 1.0)
    thermal = _thermal(power_per_square_field=5e-6)  # 0.31 K per step at the limit: the budget binds
    horizons = [12, 30]
    ceiling = heated_information_ceiling(envelope, thermal, slew, horizons, cells)
    reward = envelope.envelope[np.minimum(np.arange(fields.size) + 1, fields.size - 1)] ** 2
    x, y = fields[:, None], fields[None, :]
    heat = thermal.rise_per_mean_square * np.where(x + y > slew, (x * x + x * y + y * y) / 3, (x * x + y * y) / 6)
    for budget in (1.5, 4.0):
        bound = ceiling.at(budget)
        for column, horizon in enumerate(horizons):
            exact = _linear_programme(reward, heat, cells, thermal.decay, horizon, budget)
            assert bound[column] >= exact * (1 - 1e-9)
            assert bound[column] <= 1.05 * exact
            assert exact < ceiling.free[column]          # the budget binds
    assert np.all(ceiling.at(1e6) == pytest.approx(ceiling.free))


def test_heated_floor_with_an_ample_budget_is_the_free_floor_and_rises_as_the_budget_shrinks():
    from hyst_gym.estimation.information_bound import CurrentFieldEnvelope, heated_floor, heated_information_ceiling

    slew, cells = 2500.0, 2
    fields = np.arange(0.0, 1e5 + 1, slew / cells)
    envelope = CurrentFieldEnvelope(fields, 1.3e-4 * fields, fields, 1.0, 0, 1.0)
    setting = BoundSetting(dt=0.05, steps=60, field_limit=1e5, max_change=slew, sigma=1e-4, gain=1 / 7.65e5,
                           a_lo=6653.0, a_hi=7610.0)
    floors = []
    for limit in (1e4, 333.15, 323.15):
        thermal = _thermal(temperature_limit=limit)
        ceiling = heated_information_ceiling(envelope, thermal, slew, np.arange(5, 61, 5), cells)
        floor = heated_floor(setting, ceiling, thermal, 30, 1600.0, 2.0)
        assert floor.overheat_margin > 1 and floor.value <= floor.hottest_start
        floors.append(floor)
    # ample budget: only the pieces' own prior information separates it from the heat-free floor
    assert floors[0].value == pytest.approx(floors[0].free, rel=0.02) and floors[0].value <= floors[0].free
    assert floors[0].value < floors[1].value < floors[2].value
    with pytest.raises(ValueError, match="first_step"):
        heated_floor(setting, ceiling, _thermal(), 60, 1600.0)


def test_current_field_envelope_covers_the_initial_curve_and_its_own_histories():
    """The envelope is non-decreasing, lies at or above |dM/da| on the initial curve at fields between its
    bins (an independent evaluation) and on the descending branch, and the later sets only raise it."""
    from hyst_gym.estimation.information_bound import current_field_envelope

    params = HysteresisParams()
    envelope = current_field_envelope([params], (6653.0, 7968.0), 1e5, 2500.0, 625.0, 1250.0, n_a=3, n_paths=16)
    assert np.all(np.diff(envelope.envelope) >= 0) and np.all(envelope.envelope >= envelope.sampled)
    assert envelope.correction_ratio >= 1 and envelope.residual_ratio >= 1
    up = np.arange(1, 33) * 2500.0 - 777.0
    path = np.concatenate([up, up[::-1][1:]])
    seen = magnetization_sensitivity(path, [6653.0, 7300.0, 7968.0], params, 625.0).max(axis=1)
    assert np.all(seen <= envelope.at(path) * 1.02)      # a between-node a may sit a little above the nodes
    assert envelope.at(2e4) > 1.1 * envelope.at(1e4)     # it follows the present field, not the largest so far
    with pytest.raises(ValueError, match="above"):
        envelope.at(2e5)
