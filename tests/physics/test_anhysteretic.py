"""Anhysteretic curves (2), (3): values, slopes, the Langevin series switch-over, overflow."""

import math
import warnings
from decimal import Decimal, localcontext

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyst_gym.physics import anhysteretic_magnetization
from hyst_gym.physics.anhysteretic import (LANGEVIN_SERIES, LANGEVIN_SERIES_SWITCH, LANGEVIN_SLOPE_SERIES_SWITCH,
                                           langevin, langevin_slope, tanh_expm1)

A, MS = 7012.0, 7.65e5


def langevin_reference(x: float):
    """L(x) = coth x - 1/x and L'(x) = 1/x^2 - 1/sinh^2 x in (at least) 60-digit decimal arithmetic."""
    with localcontext() as context:
        context.prec = 60 + 3 * max(0, int(-math.log10(abs(x))))  # the slope cancels ~3 digits per decade
        xd = Decimal(x)
        e2 = (2 * xd).exp()
        coth = (e2 + 1) / (e2 - 1)
        inv_sinh2 = 4 * e2 / (e2 - 1) ** 2
        return float(coth - 1 / xd), float(1 / (xd * xd) - inv_sinh2)


@pytest.mark.parametrize("switch", [LANGEVIN_SERIES_SWITCH, LANGEVIN_SLOPE_SERIES_SWITCH])
def test_langevin_switch_over_is_continuous_and_accurate(switch):
    # Points just inside and just outside the switch-over use different formulas.
    for x in (switch * (1 - 1e-12), switch * (1 + 1e-12), -switch * (1 - 1e-12), -switch * (1 + 1e-12)):
        value, slope = langevin_reference(x)
        assert abs(langevin(x) - value) <= 1e-14 * abs(value)
        assert abs(langevin_slope(x) - slope) <= 1e-14 * slope
    # No visible step where the formula changes: the jump is below the curves' own change.
    below, above = switch * (1 - 1e-15), switch * (1 + 1e-15)
    change = abs(langevin(above) - langevin(below)) - langevin_slope(switch) * (above - below)
    assert change < 4e-15 * langevin(switch)
    assert abs(langevin_slope(above) - langevin_slope(below)) < 4e-15 * langevin_slope(switch)


@given(st.floats(min_value=-40.0, max_value=40.0, allow_nan=False).filter(lambda x: x != 0.0))
@settings(max_examples=300, deadline=None)
def test_langevin_matches_high_precision_reference(x):
    value, slope = langevin_reference(x)
    assert langevin(x) == pytest.approx(value, rel=1e-14)
    # Far from 0 the slope 1/x^2 - 1/sinh^2 x is a difference of O(1/x^2) terms.
    assert langevin_slope(x) == pytest.approx(slope, rel=1e-13)


def test_langevin_at_zero():
    assert langevin(0.0) == 0.0 and langevin_slope(0.0) == 1.0 / 3.0


@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_slope_is_derivative_of_value(curve):
    field = np.linspace(-8 * A, 8 * A, 161) + 3.7  # avoid exactly 0 for the FD stencil symmetry
    step = 1e-3 * A
    plus, _ = anhysteretic_magnetization(field + step, A, MS, curve)
    minus, _ = anhysteretic_magnetization(field - step, A, MS, curve)
    _, slope = anhysteretic_magnetization(field, A, MS, curve)
    difference = (plus - minus) / (2 * step)
    assert np.all(slope > 0), "dMan/dHe must be positive (a published code has the sign wrong)"
    np.testing.assert_allclose(slope, difference, rtol=1e-5, atol=1e-9 * MS / A)


@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_no_overflow_at_large_argument(curve):
    field = np.array([-1e308, -1e200, -1e8 * A, -800 * A, -40 * A, 40 * A, 800 * A, 1e8 * A, 1e200, 1e308])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with np.errstate(all="raise"):
            value, slope = anhysteretic_magnetization(field, A, MS, curve)
    assert np.all(np.isfinite(value)) and np.all(np.isfinite(slope))
    assert np.all(np.abs(value) <= MS) and np.all(slope >= 0)
    # Saturation: Ising approaches Ms exponentially, Langevin as Ms*(1 - 1/x).
    expected = MS * np.sign(field) * (1.0 if curve == "ising" else 1.0 - A / np.abs(field))
    np.testing.assert_allclose(value, expected, rtol=1e-12)


@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_curves_are_odd_and_have_the_right_initial_slope(curve):
    field = np.linspace(0, 10 * A, 101)
    up, slope_up = anhysteretic_magnetization(field, A, MS, curve)
    down, slope_down = anhysteretic_magnetization(-field, A, MS, curve)
    np.testing.assert_array_equal(up, -down)
    np.testing.assert_array_equal(slope_up, slope_down)
    assert slope_up[0] == pytest.approx(MS / A / (1.0 if curve == "ising" else 3.0), rel=1e-15)


def test_bad_curve_and_parameters_are_rejected():
    with pytest.raises(ValueError, match="anhysteretic must be one of"):
        anhysteretic_magnetization(0.0, A, MS, "brillouin")
    with pytest.raises(ValueError, match="a and Ms must be > 0"):
        anhysteretic_magnetization(0.0, -1.0, MS)


def test_langevin_series_coefficients_are_the_bernoulli_ones():
    # c_n = 2^(2n) B_2n / (2n)!, with B_2 = 1/6, B_4 = -1/30, B_6 = 1/42, B_8 = -1/30, B_10 = 5/66
    bernoulli = [1 / 6, -1 / 30, 1 / 42, -1 / 30, 5 / 66]
    for n, b in enumerate(bernoulli, start=1):
        assert LANGEVIN_SERIES[n - 1] == pytest.approx(2 ** (2 * n) * b / math.factorial(2 * n), rel=1e-15)


def test_inlined_tanh_matches_libm_everywhere():
    x = np.concatenate([np.linspace(-25, 25, 400001), np.geomspace(1e-300, 30, 20001), [0.0, 20.0, 1e300]])
    x = np.concatenate([x, -x])
    ours = np.array([tanh_expm1(v) for v in x[::7]])
    reference = np.tanh(x[::7])
    tiny = np.finfo(float).tiny
    assert np.max(np.abs(ours - reference) / np.maximum(np.abs(reference), tiny)) < 2e-15
    assert np.all(np.abs(ours) <= 1.0)
    assert tanh_expm1(0.0) == 0.0 and tanh_expm1(1e300) == 1.0 and tanh_expm1(-1e300) == -1.0


@given(st.floats(-50.0, 50.0, allow_nan=False))
@settings(max_examples=300, deadline=None)
def test_inlined_tanh_is_accurate_and_odd(x):
    assert tanh_expm1(x) == pytest.approx(math.tanh(x), rel=2e-15, abs=1e-300)
    assert tanh_expm1(-x) == -tanh_expm1(x)
