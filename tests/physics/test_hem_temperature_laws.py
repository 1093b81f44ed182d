"""Critical scaling of the homogenized energy model's parameters near the Curie point."""

import numpy as np
import pytest

from hyst_gym.physics.hem import simulate_hem_batch
from hyst_gym.physics.temperature_laws import (GD_CURIE_K, HEM_PARAMETER_NAMES, Constant, CriticalPowerLaw,
                                               FollowsMs, HEMTemperatureLaws)

LAWS = HEMTemperatureLaws(relay_magnetization=CriticalPowerLaw(2.0e6, GD_CURIE_K, 0.35),
                          reversible_susceptibility=CriticalPowerLaw(2.0, GD_CURIE_K, -1.3),
                          coercive_median=FollowsMs(3000.0, 2.0), coercive_spread=Constant(0.5),
                          interaction_scale=FollowsMs(6000.0, 1.0))


def _slope(T, values):
    reduced = 1.0 - np.asarray(T) / GD_CURIE_K
    return np.log(values[1] / values[0]) / np.log(reduced[1] / reduced[0])


def test_exponents_of_the_critical_laws():
    T = np.array([GD_CURIE_K - 20.0, GD_CURIE_K - 2.0])
    values = LAWS(T)
    assert _slope(T, values["relay_magnetization"]) == pytest.approx(0.35, rel=1e-12)
    assert _slope(T, values["reversible_susceptibility"]) == pytest.approx(-1.3, rel=1e-12)
    # the pinning follows the spontaneous magnetization: exponent n times beta in (1 - T/Tc)
    assert _slope(T, values["coercive_median"]) == pytest.approx(2.0 * 0.35, rel=1e-12)
    assert _slope(T, values["interaction_scale"]) == pytest.approx(0.35, rel=1e-12)
    np.testing.assert_allclose(values["coercive_spread"], 0.5)
    assert set(values) == set(HEM_PARAMETER_NAMES) | {"reversible_saturation"}
    np.testing.assert_array_equal(values["reversible_saturation"], 0.0)  # default: the linear reversible part


def test_loops_narrow_and_flatten_towards_the_curie_point():
    T = np.array([GD_CURIE_K - 50.0, GD_CURIE_K - 20.0, GD_CURIE_K - 5.0])
    batch = LAWS.batch(T)
    assert batch.size == 3
    peak = 3.0e4
    field = np.concatenate([np.linspace(0, peak, 200), np.linspace(peak, -peak, 400), np.linspace(-peak, peak, 400)])
    M = simulate_hem_batch(field, batch)
    descending = M[200:600]
    H = field[200:600]
    remanence = np.array([np.interp(0.0, H[::-1], descending[::-1, j]) for j in range(3)])
    coercivity = np.array([np.interp(0.0, descending[::-1, j], H[::-1]) for j in range(3)])
    assert np.all(np.diff(remanence) < 0) and np.all(remanence > 0)
    assert np.all(np.diff(np.abs(coercivity)) < 0)
