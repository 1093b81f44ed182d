"""The model bank against direct single-model runs, and its interpolation."""

import numpy as np

from hyst_gym.estimation import EstimatorConfig, ModelBank
from hyst_gym.physics import HysteresisParams, simulate_magnetization


def test_bank_node_equals_single_model_run_bit_for_bit():
    params = HysteresisParams(k=4000.0, alpha=-0.01)
    config = EstimatorConfig(grid_size=16, hysteresis=params, max_field_step=25.0)
    rng = np.random.default_rng(0)
    fields = np.cumsum(rng.normal(0.0, 3e3, size=(300, 3)), axis=0)  # three systems, own fields
    fields[0] = 0.0
    bank = ModelBank(config, n_systems=3)
    history = np.empty((300, 3, 16))
    history[0] = 0.0
    for i in range(1, 300):
        bank.advance(fields[i])
        history[i] = bank.magnetization
    for system in range(3):
        for node in (0, 7, 15):
            theta = config.theta_grid[node]
            direct = simulate_magnetization(fields[:, system], max_field_step=25.0,
                                            **{**params.__dict__, "a": theta})
            assert np.array_equal(history[:, system, node], direct)
            value, _, _ = bank.evaluate(np.full(3, theta))
            assert value[system] == history[-1, system, node]  # f(thetahat) at a node: exact


def test_interpolation_is_accurate_between_nodes():
    field = np.linspace(0.0, 6e4, 400)
    config = EstimatorConfig(grid_size=32)
    bank = ModelBank(config, 1)
    for i in range(1, field.size):
        bank.advance(field[i:i + 1])
    theta = 6300.0 + 1000.0 * np.array([0.123])
    value, slope, _ = bank.evaluate(theta)
    direct = simulate_magnetization(field, a=float(theta[0]))[-1]
    step = 1.0
    slope_direct = (simulate_magnetization(field, a=float(theta[0]) + step)[-1]
                    - simulate_magnetization(field, a=float(theta[0]) - step)[-1]) / (2 * step)
    assert abs(value[0] - direct) < 1e-4 * abs(direct - simulate_magnetization(field, a=7300.0)[-1])
    assert abs(slope[0] - slope_direct) < 1e-2 * abs(slope_direct)
