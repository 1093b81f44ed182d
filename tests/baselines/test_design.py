import numpy as np
import pytest

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


def test_knot_schedule_interpolates_its_knots_and_obeys_the_common_limits():
    from baselines.direct_design import KnotSchedule

    schedule = KnotSchedule((0.0, np.arctanh(0.5), -20.0), episode_s=2.0, field_max=1.2e5)
    np.testing.assert_allclose(schedule.field(np.array([0.0, 0.5, 1.0, 2.0, 3.0])),
                               [0.0, 3.0e4, 6.0e4, -1.2e5, -1.2e5], rtol=1e-9, atol=1e-6)
    field = schedule.sampled(150, LIMITS)
    assert np.all(np.abs(field) <= LIMITS.field_max + 1e-9)
    assert np.all(np.abs(np.diff(np.r_[0.0, field])) <= LIMITS.max_field_change * (1 + 1e-12))
    for bad, message in (({"knots": (1.0,)}, "at least 2"), ({"episode_s": 0.0}, "episode_s"),
                         ({"knots": (0.0, np.nan)}, "finite")):
        with pytest.raises(ValueError, match=message):
            KnotSchedule(**{"knots": (0.0, 1.0), **bad})


def test_direct_search_finds_a_known_profile_reproducibly():
    """A score with a known minimizer (a target knot profile): CMA-ES gets close, from zero."""
    from baselines.direct_design import search_direct_design

    target = np.array([0.2, 0.8, -0.5, 0.4, 0.0])
    times = np.linspace(0.0, 4.0, 5)

    def score(schedule):
        return float(np.sum((schedule.field(times) / LIMITS.field_max - target) ** 2))

    result = search_direct_design(score, LIMITS, episode_s=4.0, n_knots=5, max_evaluations=1500, seed=2)
    np.testing.assert_allclose(result.schedule.field(times) / LIMITS.field_max, target, atol=1e-3)
    assert result.score == score(result.schedule) and list(result.history) == sorted(result.history, reverse=True)
    again = search_direct_design(score, LIMITS, episode_s=4.0, n_knots=5, max_evaluations=1500, seed=2)
    assert again.schedule == result.schedule
    with pytest.raises(ValueError, match="n_knots"):
        search_direct_design(score, LIMITS, episode_s=4.0, n_knots=1)
