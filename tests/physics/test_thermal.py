"""Thermal model and a(T), eq. (4)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyst_gym.physics import ThermalParams, a_of_temperature, advance_temperature, temperature_of_a

P = ThermalParams()


def _run(params, field_of_time, duration, dt, temperature=None):
    temperature = params.ambient_temperature if temperature is None else temperature
    times = np.arange(int(round(duration / dt)) + 1) * dt
    out = [temperature]
    for t0 in times[:-1]:
        temperature = advance_temperature(temperature, field_of_time(t0), field_of_time(t0 + dt), dt, params, time=t0)
        out.append(temperature)
    return times, np.array(out)


def test_steady_temperature_is_ambient_plus_rth_times_power():
    field = 6e4  # A/m, constant: I = 6 A, P = 36 W
    power = P.coil_resistance * (field / P.turns_per_meter) ** 2
    assert power == pytest.approx(36.0)
    _, temperature = _run(P, lambda t: field, 20 * P.time_constant, 5.0)
    assert temperature[-1] == pytest.approx(P.ambient_temperature + P.thermal_resistance * power, abs=1e-6)
    assert temperature[-1] == pytest.approx(P.steady_temperature(power))


@pytest.mark.parametrize("dt", [0.1, 7.0, 60.0])
def test_time_constant_is_rth_times_cth(dt):
    field = 1e5
    rise = P.thermal_resistance * P.coil_resistance * (field / P.turns_per_meter) ** 2
    times, temperature = _run(P, lambda t: field, 4 * P.time_constant, dt)
    fraction = (temperature - P.ambient_temperature) / rise
    # exact at every step, whatever the step: 1 - exp(-t/tau)
    np.testing.assert_allclose(fraction, 1 - np.exp(-times / (P.thermal_resistance * P.heat_capacity)),
                               rtol=1e-12, atol=1e-13)
    # the fitted decay rate of the remaining gap is 1/(R_th*C_th)
    gap = 1 - fraction
    keep = gap > 1e-3
    rate = -np.polyfit(times[keep], np.log(gap[keep]), 1)[0]
    assert rate == pytest.approx(1 / P.time_constant, rel=1e-9)


@given(st.floats(1e-3, 50.0), st.floats(-2e5, 2e5), st.floats(-2e5, 2e5), st.floats(250.0, 350.0),
       st.floats(-0.05, 0.05))
@settings(max_examples=100, deadline=None)
def test_two_half_steps_equal_one_step_under_constant_power_and_linear_ambient(dt, field, _unused, start,
                                                                               drift):
    params = P.replace(ambient_drift_rate=drift)
    one = advance_temperature(start, field, field, dt, params, time=3.0)
    half = advance_temperature(start, field, field, dt / 2, params, time=3.0)
    two = advance_temperature(half, field, field, dt / 2, params, time=3.0 + dt / 2)
    assert one == pytest.approx(two, rel=1e-13, abs=1e-10)


def test_ambient_drift_is_followed_with_lag_drift_times_tau():
    drift = 0.01  # K/s
    params = P.replace(ambient_drift_rate=drift)
    times, temperature = _run(params, lambda t: 0.0, 15 * P.time_constant, 10.0)
    lag = params.ambient_at(times[-1]) - temperature[-1]
    assert lag == pytest.approx(drift * P.time_constant, rel=1e-6)


def test_explicit_ambient_override_and_batch():
    temperatures = np.array([290.0, 300.0, 310.0])
    fields = np.array([0.0, 5e4, 1e5])
    ambient = np.array([280.0, 290.0, 300.0])
    out = advance_temperature(temperatures, fields, fields, 30.0, P, ambient=ambient)
    assert out.shape == (3,)
    for i in range(3):
        single = advance_temperature(temperatures[i], fields[i], fields[i], 30.0, P, ambient=ambient[i])
        assert out[i] == pytest.approx(single, rel=1e-15)


def test_joule_power_of_a_linear_field_step_is_its_mean():
    # Holding the step's mean power R*mean(I^2) (I linear) equals the exact integral
    # when tau >> dt; check the mean-square formula against quadrature.
    start, end = -3e4, 9e4
    fine = np.linspace(start, end, 200001)
    mean_square = np.mean(fine ** 2)
    dt = 1e-3
    heat = P.heat_capacity * (advance_temperature(P.ambient_temperature, start, end, dt, P) - P.ambient_temperature)
    assert heat / dt == pytest.approx(P.coil_resistance * mean_square / P.turns_per_meter ** 2, rel=1e-4)


def test_a_is_proportional_to_absolute_temperature():
    assert a_of_temperature(P.reference_temperature) == pytest.approx(7012.0, rel=1e-15)
    assert a_of_temperature(2 * P.reference_temperature) == pytest.approx(2 * 7012.0, rel=1e-15)
    temperatures = np.array([263.0, 293.15, 305.0])
    np.testing.assert_allclose(temperature_of_a(a_of_temperature(temperatures)), temperatures, rtol=1e-15)
    # the paper's bounds [6300, 7300] A/m are about -10 % / +4 % of a(T_ref)
    assert temperature_of_a(6300.0) == pytest.approx(263.4, abs=0.1)
    assert temperature_of_a(7300.0) == pytest.approx(305.2, abs=0.1)


def test_defaults_drift_a_by_a_few_percent_over_minutes_of_heavy_driving():
    # a 1e5 A/m sine (10 A peak in the coil) for 5 minutes, sampled at 100 Hz
    times, temperature = _run(P, lambda t: 1e5 * np.sin(2 * np.pi * 13.1 * t), 300.0, 0.01)
    drift = a_of_temperature(temperature) / P.a_reference - 1
    after_2_minutes = drift[np.searchsorted(times, 120.0)]
    assert 0.015 < after_2_minutes < 0.03
    assert 0.025 < drift[-1] < 0.05
    # below the steady temperature of the mean power (50 W -> +10 K)
    assert np.all(temperature < P.ambient_temperature + P.thermal_resistance * 50.0 + 0.01)


@pytest.mark.parametrize("change, message", [
    ({"coil_resistance": 0.0}, "coil_resistance"), ({"turns_per_meter": -1.0}, "turns_per_meter"),
    ({"thermal_resistance": float("inf")}, "thermal_resistance"), ({"heat_capacity": 0.0}, "heat_capacity"),
    ({"reference_temperature": 0.0}, "reference_temperature"), ({"a_reference": -7012.0}, "a_reference"),
    ({"ambient_drift_rate": float("nan")}, "ambient_drift_rate"),
])
def test_bad_thermal_parameters_are_rejected(change, message):
    with pytest.raises(ValueError, match=message):
        ThermalParams(**change)


def test_bad_temperature_inputs_are_rejected():
    with pytest.raises(ValueError, match="temperature must be finite and > 0 K"):
        a_of_temperature(-3.0)
    with pytest.raises(ValueError, match="dt must be a finite number > 0"):
        advance_temperature(300.0, 0.0, 0.0, 0.0)
