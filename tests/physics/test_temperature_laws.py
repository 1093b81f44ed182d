"""Temperature laws of the domain-wall model: eq. (4), critical power law, Ms-following laws."""

import dataclasses

import numpy as np
import pytest

from hyst_gym.physics.hysteresis import simulate_batch, simulate_magnetization
from hyst_gym.physics.temperature_laws import (
    GD_CURIE_K, Constant, CriticalPowerLaw, FollowsMs, LinearInT, LogPolynomial, TemperatureLaws,
    celsius_to_kelvin, critical_power_law, linear_in_temperature,
)


def test_eq4_is_exactly_linear_and_equals_a_ref_at_T_ref():
    law = LinearInT(7012.0, 263.0)
    assert law(263.0) == pytest.approx(7012.0, rel=0, abs=1e-9)
    T = np.linspace(200.0, 400.0, 41)
    a = law(T)
    assert a.shape == T.shape
    # exactly proportional to T: constant ratio, zero second difference, a(2T) = 2 a(T)
    np.testing.assert_allclose(a / T, 7012.0 / 263.0, rtol=1e-14)
    np.testing.assert_allclose(np.diff(a, 2), 0.0, atol=1e-9)
    assert law(526.0) == pytest.approx(2 * 7012.0, rel=1e-14)
    assert linear_in_temperature(300.0, 10.0, 300.0) == pytest.approx(10.0)


def test_critical_power_law_vanishes_at_Tc_and_decreases_monotonically():
    Tc, beta = GD_CURIE_K, 0.281
    T = np.linspace(1.0, Tc + 20.0, 500)
    Ms = critical_power_law(T, 2.0e6, Tc, beta)
    below = T < Tc
    assert np.all(Ms[below] > 0) and np.all(Ms[~below] == 0)
    assert critical_power_law(Tc, 2.0e6, Tc, beta) == 0.0
    assert np.all(np.diff(Ms) <= 0)  # monotone non-increasing in T
    assert np.all(np.diff(Ms[below]) < 0)  # strictly below Tc
    # critical exponent: log Ms vs log(1 - T/Tc) has slope beta
    t = np.array([0.01, 0.1])
    m = critical_power_law(Tc * (1 - t), 1.0, Tc, beta)
    assert np.log(m[1] / m[0]) / np.log(t[1] / t[0]) == pytest.approx(beta, rel=1e-12)
    # a larger beta drops faster near Tc
    assert critical_power_law(0.99 * Tc, 1.0, Tc, 0.5) < critical_power_law(0.99 * Tc, 1.0, Tc, 0.281)


def test_temperature_laws_vectorize_and_follow_ms():
    laws = TemperatureLaws(a=FollowsMs(4000.0, 0.5), k=FollowsMs(300.0, -1.0), c=Constant(0.3),
                           Ms=CriticalPowerLaw(2.0e6, GD_CURIE_K, 0.3), alpha=Constant(0.0))
    T = celsius_to_kelvin(np.array([[-38.0, -10.0], [0.0, 15.0]]))
    values = laws(T)
    assert set(values) == {"a", "k", "c", "Ms", "alpha", "chi_r"}
    assert np.all(values["chi_r"] == 0.0)  # the small-loop extension is off unless a law is given
    for v in values.values():
        assert v.shape == T.shape
    reduced = values["Ms"] / 2.0e6
    np.testing.assert_allclose(values["a"], 4000.0 * reduced ** 0.5, rtol=1e-14)
    np.testing.assert_allclose(values["k"], 300.0 / reduced, rtol=1e-14)
    np.testing.assert_allclose(laws.reduced_ms(T), reduced, rtol=1e-14)
    # element-wise equal to scalar evaluation
    for idx in np.ndindex(T.shape):
        one = laws(T[idx])
        for n in values:
            assert float(one[n]) == pytest.approx(values[n][idx], rel=1e-14)
    # warmer -> smaller Ms and a, larger k (n_k < 0)
    flat = laws(np.sort(T.ravel()))
    assert np.all(np.diff(flat["Ms"]) < 0) and np.all(np.diff(flat["a"]) < 0) and np.all(np.diff(flat["k"]) > 0)


def test_default_laws_are_the_papers_model_and_build_a_batch():
    laws = TemperatureLaws()
    v = laws(263.0)
    assert (float(v["a"]), float(v["k"]), float(v["alpha"]), float(v["Ms"]), float(v["c"])) == (
        7012.0, 400.0, -0.1, 7.65e5, 0.18)
    assert float(laws.reduced_ms(300.0)) == 1.0
    T = np.array([250.0, 263.0, 290.0])
    batch = laws.batch(T, "ising")
    assert not batch.small_loop
    with_small_loops = TemperatureLaws(chi_r=FollowsMs(40.0, 2.0), Ms=CriticalPowerLaw(2.0e6, GD_CURIE_K, 0.3))
    warm, cold = with_small_loops.batch(celsius_to_kelvin(np.array([10.0, -30.0])), "langevin").chi_r
    assert 0.0 < warm < cold < 40.0  # follows Ms**2 down towards the Curie point
    np.testing.assert_allclose(batch.a, 7012.0 * T / 263.0)
    H = 1.2e5 * np.sin(np.linspace(0, 2 * np.pi, 801))
    M = simulate_batch(H, batch)
    M1 = simulate_magnetization(H, a=7012.0 * 290.0 / 263.0)
    np.testing.assert_array_equal(M[:, 2], M1)  # the batch gives the scalar model bit for bit
    # eq. (4): a warmer sample has a larger a, so a lower magnetization at the peak field
    assert M[200, 0] > M[200, 1] > M[200, 2]


def test_laws_are_frozen_and_reject_bad_temperatures():
    law = LinearInT(1.0, 300.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        law.ref_value = 2.0
    with pytest.raises(ValueError):
        law(np.array([300.0, -1.0]))
    with pytest.raises(ValueError):
        CriticalPowerLaw(1.0)(np.nan)
    with pytest.raises(ValueError):
        FollowsMs(1.0, 1.0)(300.0, None)


def test_log_polynomial_is_positive_and_smooth():
    law = LogPolynomial((np.log(500.0), -0.2, 0.05), T_ref=263.15, T_scale=10.0)
    assert law(263.15) == pytest.approx(500.0)
    T = np.linspace(230.0, 290.0, 61)
    v = law(T)
    assert np.all(v > 0)
    np.testing.assert_allclose(np.log(v), np.log(500.0) - 0.2 * (T - 263.15) / 10 + 0.05 * ((T - 263.15) / 10) ** 2)
