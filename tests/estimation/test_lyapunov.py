"""P of the vector estimator, and V along scalar runs (Theorems in §3.1, §3.2)."""

import numpy as np
import pytest

from hyst_gym.estimation import EstimatorConfig, LumpedPlant, MinMaxEstimator

from estimation_helpers import run_estimator, true_magnetization, true_outputs


def test_p_solves_the_lyapunov_equation_and_is_positive_definite():
    plant = LumpedPlant.from_coefficients()
    A, Q, P = plant.state_matrix, np.array(plant.Q), plant.lyapunov_matrix
    residual = A.T @ P + P @ A + Q
    assert np.max(np.abs(residual)) <= 1e-9 * np.max(np.abs(Q))
    assert np.allclose(P, P.T) and np.all(np.linalg.eigvalsh(P) > 0)
    # independent closed form for A = [[0, 1], [-k, -c]], Q = diag(q1, q2)
    k, c = 6.4251e7, 7.8899e3
    q1, q2 = Q[0, 0], Q[1, 1]
    p2 = q1 / (2 * k)
    p3 = (q1 / k + q2) / (2 * c)
    p1 = c * p2 + k * p3
    assert np.allclose(P, [[p1, p2], [p2, p3]], rtol=1e-9)


@pytest.mark.parametrize("theta0, gamma", [(6300.0, 1.0), (7300.0, 30.0)])
def test_scalar_lyapunov_function_does_not_increase(paper_ramp, theta0, gamma):
    """V = y_eps^2 + theta_tilde^2/gamma along a run with a on a bank node (so the
    min-max covers the truth exactly); increases only at round-off level."""
    time, field, dt = paper_ramp
    config = EstimatorConfig.paper_scalar(grid_size=21, initial_estimate=theta0, gamma=gamma)
    a_true = config.theta_grid[14]  # 7000 A/m
    outputs = true_outputs(true_magnetization(field, a_true), dt)
    estimator = MinMaxEstimator(config)
    _, lyapunov = run_estimator(estimator, field, outputs, dt, a_true)
    increase = np.diff(lyapunov)
    assert lyapunov[-1] < 0.5 * lyapunov[0]  # it does decrease
    assert np.max(increase) <= 1e-9 * lyapunov[0]
