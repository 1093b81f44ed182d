"""Bad configurations and bad calls fail with clear one-line ValueErrors."""

import numpy as np
import pytest

from hyst_gym.estimation import EstimatorConfig, FirstOrderPlant, LumpedPlant, MinMaxEstimator, PEMonitor


@pytest.mark.parametrize("changes, message", [
    (dict(theta_min=7300.0, theta_max=6300.0), "is empty"),
    (dict(theta_min=7000.0, theta_max=7000.0), "is empty"),
    (dict(initial_estimate=6000.0), "outside"),
    (dict(initial_estimate=7400.0), "outside"),
    (dict(eps=0.0), "eps must be > 0"),
    (dict(eps=-1e-3), "eps must be > 0"),
    (dict(gamma=0.0), "gamma must be > 0"),
    (dict(grid_size=8), "grid_size"),
    (dict(grid_size=129), "grid_size"),
    (dict(grid_size=32.5), "grid_size"),
    (dict(max_field_step=0.0), "max_field_step"),
    (dict(theta_min=float("nan")), "finite"),
    (dict(pe_window=1), "pe_window"),
])
def test_bad_config_names_the_problem(changes, message):
    with pytest.raises(ValueError, match=message) as error:
        EstimatorConfig(**changes)
    assert "\n" not in str(error.value)


def test_non_hurwitz_lumped_plant_is_rejected():
    with pytest.raises(ValueError, match="Hurwitz"):
        LumpedPlant.from_coefficients(khat=6.4e7, chat=-10.0)
    with pytest.raises(ValueError, match="Hurwitz"):
        LumpedPlant(A=((0.0, 1.0), (1.0, -1.0)))


def test_bad_plant_and_weight_are_rejected():
    with pytest.raises(ValueError, match="decay_rate must be a finite number > 0"):
        FirstOrderPlant(decay_rate=-100.0)
    with pytest.raises(ValueError, match="gain nu must be > 0"):
        EstimatorConfig(plant=FirstOrderPlant(gain=-1.0))
    with pytest.raises(ValueError, match="positive definite"):
        LumpedPlant(Q=((1.0, 0.0), (0.0, -1.0)))
    with pytest.raises(ValueError, match="shape"):
        LumpedPlant(B=(0.0, 1.0, 2.0))


def test_bad_calls_fail_clearly():
    estimator = MinMaxEstimator(EstimatorConfig.paper_scalar(grid_size=16), n_systems=2)
    with pytest.raises(ValueError, match="outside"):
        estimator.reset(a_estimate=[7000.0, 8000.0])
    with pytest.raises(ValueError, match="dt must be"):
        estimator.update([0.0, 0.0], [0.0, 0.0], 0.0)
    with pytest.raises(ValueError, match="measured_output must have shape"):
        estimator.update([1.0, 1.0], np.zeros((2, 2)), 1e-3)
    with pytest.raises(ValueError, match="field must be"):
        estimator.update([1.0, 1.0, 1.0], [0.0, 0.0], 1e-3)
    with pytest.raises(ValueError, match="indices"):
        estimator.reset(indices=[2])
    vector = MinMaxEstimator(EstimatorConfig.paper_vector(grid_size=16), n_systems=2)
    with pytest.raises(ValueError, match="displacement, velocity"):
        vector.update([1.0, 1.0], [0.0, 0.0], 1e-3)
    with pytest.raises(ValueError, match="window"):
        PEMonitor(2, 1)


def test_defaults_are_the_papers():
    scalar = EstimatorConfig.paper_scalar()
    assert (scalar.theta_min, scalar.theta_max, scalar.initial_estimate, scalar.gamma) == (6300, 7300, 6990, 1.0)
    vector = EstimatorConfig.paper_vector()
    assert vector.gamma == 5e10 and vector.plant.Q == ((1e10, 0.0), (0.0, 1e-8))
    assert vector.plant.A == ((0.0, 1.0), (-6.4251e7, -7.8899e3)) and vector.plant.B == (0.0, 1.3724e-2)
