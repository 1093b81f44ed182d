import numpy as np

from baselines.greedy import GreedyInformationAgent
from baselines.information import fisher_information
from baselines.optimal_design import MultisineDesign, design_input
from baselines.schedules import ExcitationLimits, Ramp, apply_limits

LIMITS = ExcitationLimits(field_max=1.2e5, slew_max=2.0e5, dt=0.02)


def _log_info(field, a=(7012.0,)):
    return float(np.mean(np.log(fisher_information(field, LIMITS.dt, a))))


def test_cma_design_beats_its_start_and_the_ramp_and_obeys_limits():
    result = design_input(LIMITS, period=3.0, n_harmonics=3, max_evaluations=120, seed=1)
    field = result.design.sampled(150, LIMITS)
    start = MultisineDesign((0.0, 0.5, 0.5, 0.5, 0.0, 0.0, 0.0), 3.0, LIMITS.field_max).sampled(150, LIMITS)
    assert abs(result.log_information - _log_info(field)) < 1e-9  # the criterion is what it reports
    assert result.log_information > _log_info(start)
    assert result.log_information > _log_info(Ramp(duration=3.0).sampled(150, LIMITS))
    assert np.all(np.abs(field) <= LIMITS.field_max + 1e-9)
    assert np.all(np.abs(np.diff(np.r_[0.0, field])) <= LIMITS.max_field_change * (1 + 1e-12))
    # reproducible
    again = design_input(LIMITS, period=3.0, n_harmonics=3, max_evaluations=120, seed=1)
    assert again.design.coefficients == result.design.coefficients


def test_greedy_collects_more_information_than_the_ramp_within_limits():
    agent = GreedyInformationAgent(LIMITS, horizon=3)
    obs = np.zeros((2, 1))
    commands = np.array([agent.predict(obs)[0][:, 0] for _ in range(150)])
    field = commands[:, 0].astype(np.float64) * LIMITS.field_max
    np.testing.assert_array_equal(commands[:, 0], commands[:, 1])  # independent, identical envs
    assert np.all(np.abs(np.diff(np.r_[0.0, field])) <= LIMITS.max_field_change * (1 + 1e-5))
    ramp = apply_limits(Ramp(duration=3.0).field(LIMITS.dt * np.arange(1, 151)), LIMITS)
    assert _log_info(field) > _log_info(ramp)
