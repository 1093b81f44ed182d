"""The knee family of the anhysteretic curve, ``m = sign(x)*tanh(|x|^p)^(1/p)``: the Ising curve (2) at p = 1, unit
slope at 0 for every p, odd, monotone, saturating, a harder knee as p grows; its slope, near 0 too; and the
hysteresis model (6) stepped with it."""

import math
from decimal import Decimal, localcontext

import numpy as np
import pytest
from numba import njit

from hyst_gym.physics import anhysteretic_magnetization
from hyst_gym.physics.anhysteretic import ISING, KNEE_SERIES_SWITCH, KneeCurve, anhysteretic_unit, knee_unit
from hyst_gym.physics.hysteresis import advance_one

EXPONENTS = (0.5, 0.8, 1.0, 1.7, 2.5, 4.0)


@njit(cache=True)
def _knee_array(x, exponent):
    out = np.empty((x.size, 2))
    for i in range(x.size):
        out[i, 0], out[i, 1] = knee_unit(x[i], exponent)
    return out


@njit(cache=True)
def _ising_array(x):
    out = np.empty((x.size, 2))
    for i in range(x.size):
        out[i, 0], out[i, 1] = anhysteretic_unit(x[i], ISING)
    return out


def _reference(x: float, p: float):
    """m and dm/dx in (at least) 50-digit decimal arithmetic from the closed forms (u = |x|^p, t = tanh u):
    ``t^(1/p)`` and ``t^(1/p - 1)*(1 - t^2)*|x|^(p - 1)``."""
    with localcontext() as context:
        # tanh as (e^2u - 1)/(e^2u + 1) cancels one digit per decade of u below 1
        context.prec = 50 + int(max(0.0, -p * math.log10(abs(x))))
        size, pd = Decimal(abs(x)), Decimal(p)
        u = (pd * size.ln()).exp()
        e2 = (2 * u).exp()
        t = (e2 - 1) / (e2 + 1)
        value = ((t.ln()) / pd).exp()
        slope = ((1 / pd - 1) * t.ln()).exp() * (1 - t * t) * ((pd - 1) * size.ln()).exp()
        return math.copysign(float(value), x), float(slope)


def _grid():
    magnitudes = np.concatenate([np.logspace(-12, 1.5, 300), np.linspace(0.05, 6.0, 300)])
    return np.concatenate([-magnitudes, magnitudes])


@pytest.mark.parametrize("p", EXPONENTS)
def test_value_and_slope_match_a_high_precision_reference(p):
    x = _grid()[::7]
    ours = _knee_array(x, p)
    for xi, (value, slope) in zip(x, ours):
        ref_value, ref_slope = _reference(float(xi), p)
        assert value == pytest.approx(ref_value, rel=1e-14, abs=0.0), (xi, p)
        # the slope's tail: 1 - t^2 loses relative accuracy where t -> 1 (as the Ising slope does)
        assert slope == pytest.approx(ref_slope, rel=1e-12, abs=1e-15), (xi, p)


@pytest.mark.parametrize("p", EXPONENTS)
def test_slope_is_the_derivative_of_the_value(p):
    """Central differences (step 1e-6, error ~1e-10) on both sides of the series switch and of the knee."""
    x = np.concatenate([np.linspace(-4.0, 4.0, 801) + 1e-3, KNEE_SERIES_SWITCH ** (1.0 / p) * np.array([0.9, 1.1])])
    h = 1e-6
    difference = (_knee_array(x + h, p)[:, 0] - _knee_array(x - h, p)[:, 0]) / (2 * h)
    np.testing.assert_allclose(_knee_array(x, p)[:, 1], difference, rtol=1e-7, atol=1e-9)


def test_p_one_is_the_ising_curve():
    """To the last bit above the series switch and for the slope everywhere; within 1e-15 below it."""
    x = _grid()
    knee, ising = _knee_array(x, 1.0), _ising_array(x)
    np.testing.assert_array_equal(knee[:, 1], ising[:, 1])
    above = np.abs(x) >= KNEE_SERIES_SWITCH
    np.testing.assert_array_equal(knee[above, 0], ising[above, 0])
    np.testing.assert_allclose(knee[:, 0], np.tanh(x), rtol=1e-15, atol=0.0)
    np.testing.assert_array_equal(anhysteretic_magnetization(x, 3.0, 2.0, knee_exponent=1.0)[0],
                                  anhysteretic_magnetization(x, 3.0, 2.0)[0])


@pytest.mark.parametrize("p", EXPONENTS)
def test_unit_slope_at_zero_odd_monotone_and_saturating(p):
    tiny = np.array([0.0, 5e-324, 1e-300, 1e-100, -1e-100])
    near = _knee_array(tiny, p)
    np.testing.assert_allclose(near[:, 1], 1.0, rtol=1e-15)  # no 0/0 and no 0**negative at x = 0
    np.testing.assert_allclose(near[:, 0], tiny, rtol=1e-15, atol=0.0)
    # 1 - slope and 1 - m/x vanish as u^2 = |x|^(2p) (the series of tanh(u)/u)
    small = np.array([1e-8, -1e-8])
    np.testing.assert_allclose(_knee_array(small, p)[:, 1], 1.0, rtol=2.0 * 1e-8 ** (2 * p))
    x = np.linspace(-8.0, 8.0, 40001)
    value, slope = _knee_array(x, p).T
    np.testing.assert_array_equal(_knee_array(-x, p)[:, 0], -value)
    assert np.all(np.diff(value) >= -2.3e-16)  # monotone (to a unit in the last place)
    assert np.all(slope >= 0.0)
    far = _knee_array(np.array([1e3, 1e6, 1e300, np.inf, -1e300]), p)  # u = |x|^p >= 31
    np.testing.assert_array_equal(far[:, 0], [1.0, 1.0, 1.0, 1.0, -1.0])
    np.testing.assert_array_equal(far[:, 1], 0.0)


def test_the_knee_sharpens_with_p_toward_the_hard_knee():
    """Ordered in p at every field (p < 1 softer than Ising, p > 1 sharper) and within 1 % of min(|x|, 1) at
    p = 40."""
    x = np.linspace(0.01, 5.0, 500)
    curves = [_knee_array(x, p)[:, 0] for p in (0.5, 1.0, 2.0, 4.0, 40.0)]
    for softer, sharper in zip(curves, curves[1:]):
        assert np.all(sharper >= softer)
    assert np.max(np.abs(curves[-1] - np.minimum(x, 1.0))) < 0.01
    assert np.max(np.abs(curves[2] - np.minimum(x, 1.0))) > 0.1


def test_bad_exponents_and_curves_are_rejected():
    with pytest.raises(ValueError, match="knee_exponent"):
        anhysteretic_magnetization(1.0, knee_exponent=0.0)
    with pytest.raises(ValueError, match="Ising"):
        anhysteretic_magnetization(1.0, anhysteretic="langevin", knee_exponent=2.0)


@njit(cache=True)
def _loop(field, curve):
    m = np.empty(field.size)
    value, previous = 0.0, 0.0
    for i in range(field.size):
        value, _ = advance_one(value, previous, field[i], 4000.0, 1500.0, -2e-3, 7.65e5, 0.2, curve, 50.0)
        previous = field[i]
        m[i] = value
    return m


def test_the_hysteresis_model_steps_the_knee_family():
    """(6) with the knee curve: p = 1 gives the Ising loop (to rounding), p = 2.5 a loop that saturates sooner
    beyond the knee but has the same initial slope (the same first step from the demagnetized state)."""
    field = 1.2e5 * np.sin(np.linspace(0.0, 4 * np.pi, 2001))
    ising = _loop(field, ISING)
    np.testing.assert_allclose(_loop(field, KneeCurve(1.0)), ising, rtol=0.0, atol=1e-9 * 7.65e5)
    sharp = _loop(field, KneeCurve(2.5))
    first_step = np.array([2.0])  # 2 A/m: x = He/a ~ 1e-3
    assert _loop(first_step, KneeCurve(2.5))[0] == pytest.approx(_loop(first_step, ISING)[0], rel=1e-5)
    knee = np.argmin(np.abs(field[:500] - 4000.0))
    assert sharp[knee] > ising[knee]
    assert np.max(np.abs(sharp - ising)) > 0.02 * 7.65e5
