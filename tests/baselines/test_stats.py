import numpy as np
import pytest

from baselines.stats import (iqm, probability_of_improvement, probability_of_improvement_ci,
                               stratified_bootstrap_ci, summarize)
from baselines.survival import censor, kaplan_meier, settle_time


def test_iqm_is_mean_of_middle_half():
    scores = np.arange(1.0, 9.0)  # 1..8: middle half is 3, 4, 5, 6
    assert iqm(scores) == pytest.approx(4.5)
    # robust to the tails
    assert iqm(np.r_[scores[:-1], 1e9]) == pytest.approx(4.5)


def test_bootstrap_interval_covers_true_mean_at_nominal_rate():
    rng = np.random.default_rng(1)
    hits, widths = 0, []
    for trial in range(60):
        scores = rng.normal(0.0, 1.0, size=(1, 60))
        low, high = stratified_bootstrap_ci(scores, statistic=lambda s: float(np.mean(s)), n_boot=400, seed=trial)
        hits += low <= 0.0 <= high
        widths.append(high - low)
    assert hits / 60 >= 0.85
    # not trivially wide: the normal-theory 95 % interval of a mean of 60 unit normals is 2*1.96/sqrt(60) wide
    assert np.mean(widths) == pytest.approx(2 * 1.96 / np.sqrt(60), rel=0.1)


def test_bootstrap_interval_widens_with_seed_spread():
    rng = np.random.default_rng(2)
    draws = rng.normal(size=50)
    tight = np.tile(draws, (5, 1))
    spread = tight + rng.normal(0, 3.0, size=(5, 1))  # one offset per training seed

    def width(s):
        return np.diff(stratified_bootstrap_ci(s, n_boot=500))[0]

    assert width(spread) > 1.5 * width(tight)


def test_probability_of_improvement_complementary_and_bounds():
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=(5, 50)), rng.normal(size=(1, 50))
    assert probability_of_improvement(x, y) + probability_of_improvement(y, x) == pytest.approx(1.0)
    assert probability_of_improvement(x, x + 10) == 1.0
    assert probability_of_improvement(x, x) == pytest.approx(0.5)
    point = probability_of_improvement(x, x + 0.5)
    low, high = probability_of_improvement_ci(x, x + 0.5, n_boot=200)
    assert 0.5 < low < point < high and high - low < 0.3


def test_summary_schema_and_bad_input():
    s = summarize(np.ones((2, 10)), n_boot=50)
    assert s == {"iqm": 1.0, "ci95": [1.0, 1.0], "n": 20}
    with pytest.raises(ValueError, match="finite"):
        summarize([1.0, np.nan])


def test_settle_time_definition():
    time = np.arange(10) * 0.1
    a = 7000.0
    estimate = np.array([6000, 6990, 7000, 7100, 7003, 7001, 7000, 7000, 7000, 7000.0])
    assert settle_time(time, estimate, a) == pytest.approx(0.4)  # 7003 is within 7 A/m
    assert np.isnan(settle_time(time, np.r_[estimate[:-1], 6000.0], a))
    assert settle_time(time, np.full(10, a), a) == 0.0


def test_kaplan_meier_matches_empirical_without_censoring_and_handles_censoring():
    rng = np.random.default_rng(4)
    times = rng.exponential(1.0, 200)
    t, s = kaplan_meier(times, np.ones(200, bool))
    for probe in (0.5, 1.0, 2.0):
        km = s[np.searchsorted(t, probe, side="right") - 1]
        assert km == pytest.approx(np.mean(times > probe), abs=1e-12)
    settled = np.array([1.0, 2.0, np.nan, np.nan])
    times, observed = censor(settled, 5.0)
    assert list(times) == [1.0, 2.0, 5.0, 5.0] and list(observed) == [True, True, False, False]
    t, s = kaplan_meier(times, observed)
    assert s[-1] == pytest.approx(0.5)  # censored runs never count as settled
