"""The discriminate task's information bound on the expected decision time: the posterior's threshold, the
binary relative entropy and its inverse, the closed form at a constant separation, a Monte Carlo of the
sequential probability ratio test (the fastest test at a constant separation) above the bound. The bound
below an agent's measured decision time: tests/baselines/test_discriminate_agents.py."""

import math

import numpy as np
import pytest

from hyst_gym.envs.discriminate import (DECIDED, DECISION_ODDS, concave_majorant, decided_kl,
                                        decided_probability_bound, decision_time_bound)

STEPS = 200


def test_the_odds_are_the_posterior_threshold():
    """With a uniform prior the truth's posterior is 1/(1 + sum_j exp(-LLR_j)): at sum_j exp(-LLR_j) equal to the
    odds it is exactly DECIDED."""
    assert 1.0 / (1.0 + DECISION_ODDS) == pytest.approx(DECIDED, rel=1e-12)


@pytest.mark.parametrize("ratio", [DECISION_ODDS, DECISION_ODDS / 2])
def test_the_binary_relative_entropy_is_convex_increasing_and_inverted(ratio):
    p = np.linspace(0.0, 1.0, 2001)
    g = decided_kl(p, ratio)
    assert g[0] == 0.0 and g[-1] == pytest.approx(math.log(1.0 / ratio))
    assert np.all(np.diff(g) > 0) and np.all(np.diff(g, 2) > -1e-12)  # the tangents lie below it
    inverse = decided_probability_bound(g[:-1], ratio)
    assert np.all(inverse >= p[:-1] - 1e-12) and np.allclose(inverse, p[:-1], atol=1e-9)  # rounded up
    assert decided_probability_bound(math.log(1.0 / ratio), ratio) == 1.0


def test_the_concave_majorant_is_concave_and_above():
    values = np.array([0.0, 0.1, 0.5, 2.0, 2.1, 2.2, 4.0])
    hull = concave_majorant(values)
    assert np.all(hull >= values - 1e-12) and np.all(np.diff(hull, 2) <= 1e-12)
    assert hull[0] == values[0] and hull[-1] == values[-1]


@pytest.mark.parametrize("per_step", [1.0, 0.2])
def test_a_constant_separation_gives_the_threshold_over_the_information_per_step(per_step):
    """At a constant separation, d^2/(2 sigma^2) = c nats a step, the bound is log(99)/c steps against one
    alternative and log(198)/c against two at the same separation, less the correction of the 200-step episode
    (an agent that gives up is charged 200 steps only)."""
    k = per_step * np.arange(STEPS + 1)
    one = decision_time_bound([(DECISION_ODDS, k)], STEPS)
    two = decision_time_bound([(DECISION_ODDS, k), (DECISION_ODDS, k), (DECISION_ODDS / 2, k)], STEPS)
    for bound, threshold in ((one, math.log(99.0)), (two, math.log(198.0))):
        assert bound.steps <= threshold / per_step + 1e-6
        assert bound.steps >= threshold / per_step - (1e-3 if per_step == 1.0 else 0.2)
        assert bound.steps == max(bound.tail_steps, bound.wald_steps, bound.survival_steps)


@pytest.mark.parametrize("per_step", [1.0, 0.2, 0.05])
def test_the_sequential_probability_ratio_test_takes_longer_than_the_bound(per_step):
    """The truth's log-likelihood ratio against one alternative at a constant separation (a random walk of drift
    c and variance 2c a step), stopped at log(99) as the task's posterior does, 200 steps at most: its mean
    score (Monte Carlo) lies above the bound, and within 35 % of it (the overshoot and the truncation)."""
    rng = np.random.default_rng(0)
    runs = 4000
    llr, score, alive = np.zeros(runs), np.full(runs, float(STEPS)), np.ones(runs, dtype=bool)
    for t in range(1, STEPS + 1):
        llr += per_step + math.sqrt(2.0 * per_step) * rng.standard_normal(runs)
        decided = alive & (llr >= math.log(1.0 / DECISION_ODDS))
        score[decided], alive = t, alive & ~decided
    bound = decision_time_bound([(DECISION_ODDS, per_step * np.arange(STEPS + 1))], STEPS).steps
    assert bound < score.mean() < 1.35 * bound

