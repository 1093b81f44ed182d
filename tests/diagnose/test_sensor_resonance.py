"""Sensor dynamics with a resonance (``sensor_lag``): each output sensor a second-order low-pass
``1/(1 + tau*s + tau2^2*s^2)``, the first-order lag its member at tau2 = 0; the input dynamics (``input_lag``)
take the same filter after their delay. The kernel against an independent integration, and a ringing probe named
in its slot with the resonance it has."""

import numpy as np
import pytest
from scipy import signal as scipy_signal

from hyst_gym.diagnose import Recording, diagnose, make_recording
from hyst_gym.diagnose.kernels import AMBIENT_TEMPERATURE, MAGNETIC_COLUMNS, simulate_members
from hyst_gym.diagnose.model import INPUT_POLE_DAMPING, input_dynamics, sensor_dynamics

MATERIAL = dict(a=6000.0, k=1500.0, alpha=-0.01, Ms=8e5, c=0.2, H0=0.0, k_e=0.0, heating=0.0, tau_th=1.0,
                beta_Ms=0.0, chi_r=0.0, heating_exponent=2.0)


def _drive(samples=8001, duration=0.02):
    time = np.linspace(0.0, duration, samples)
    # a sine and a square wave: the square's edges excite a resonance, the sine does not
    return time, 5e4 * np.sin(2 * np.pi * 150 * time) + 2e4 * np.sign(np.sin(2 * np.pi * 400 * time))


def test_the_second_order_filter_matches_an_independent_integration():
    """tau2^2*y'' + tau*y' + y = u against scipy's lsim of the same transfer function (linear interpolation of
    the input, started at the settled state of the first sample)."""
    time, drive = _drive()
    tau2 = 1.0 / (2 * np.pi * 2000.0)
    tau = 2 * 0.1 * tau2  # a damping ratio of 0.1: it rings at 2 kHz after each edge
    state = scipy_signal.lti([1.0], [tau2 ** 2, tau, 1.0]).to_ss()
    settled = np.linalg.solve(-state.A, state.B.ravel() * drive[0])
    _, expected, _ = scipy_signal.lsim(state, drive, time, X0=settled)
    ours = sensor_dynamics(time, drive, tau, tau2)
    np.testing.assert_allclose(ours, expected, rtol=0, atol=1e-6 * np.ptp(drive))
    assert np.max(ours) > np.max(drive) + 0.1 * 2e4  # the resonance overshoots the edges (not a plain lag)


def test_the_first_order_lag_and_the_identity_are_members_of_the_family():
    time, drive = _drive(2001)
    tau = 3e-4
    expected = np.empty_like(drive)
    expected[0] = drive[0]
    for i, h in enumerate(np.diff(time)):  # closed form of tau*y' = u - y, u linear between samples
        slope = (drive[i + 1] - drive[i]) / h
        expected[i + 1] = drive[i + 1] - tau * slope + (expected[i] - drive[i] + tau * slope) * np.exp(-h / tau)
    np.testing.assert_allclose(sensor_dynamics(time, drive, tau, 0.0), expected, rtol=0, atol=1e-6 * np.ptp(drive))
    assert sensor_dynamics(time, drive, 0.0, 0.0) is drive
    # a very fast second pole is the first-order lag again
    np.testing.assert_allclose(sensor_dynamics(time, drive, tau, 1e-3 * tau), expected, rtol=0,
                               atol=1e-3 * np.ptp(drive))
    # the input side: the lag, then a Butterworth pair of poles (damping ratio 1/sqrt(2): no ringing)
    lagged = sensor_dynamics(time, drive, tau)
    np.testing.assert_array_equal(input_dynamics(time, drive, tau, 0.0, 2e-4),
                                  sensor_dynamics(time, lagged, 2 * INPUT_POLE_DAMPING * 2e-4, 2e-4))
    np.testing.assert_array_equal(input_dynamics(time, drive, tau, 0.0, 0.0), sensor_dynamics(time, drive, tau))


def _ringing_record(seed, frequency, damping, samples=3000, oversample=8, noise=2e-4):
    """A magnetization record through a probe that rings at ``frequency`` Hz: the loop simulated on a grid
    ``oversample`` times finer, filtered there by scipy's lsim (not our kernel), decimated, white noise added."""
    base = make_recording("none", seed, output="magnetization", n_samples=samples)[0]
    fine = np.linspace(base.time[0], base.time[-1], (samples - 1) * oversample + 1)
    field = np.interp(fine, base.time, base.field)
    row = np.array([[MATERIAL[c] for c in MAGNETIC_COLUMNS]])
    clean = simulate_members(fine, field, row, 0, 25.0, AMBIENT_TEMPERATURE)[:, 0]
    tau2 = 1.0 / (2 * np.pi * frequency)
    system = scipy_signal.lti([1.0], [tau2 ** 2, 2 * damping * tau2, 1.0])
    state = system.to_ss()
    _, filtered, _ = scipy_signal.lsim(state, clean, fine, X0=np.linalg.solve(-state.A, state.B.ravel() * clean[0]))
    recorded = filtered[::oversample]
    recorded = recorded + noise * np.ptp(recorded) * np.random.default_rng(seed).standard_normal(recorded.size)
    return Recording(time=base.time, field=base.field, magnetization=recorded)


@pytest.mark.parametrize("seed, share, damping", [(3, 0.03, 0.1), (4, 0.01, 0.2)])
def test_a_ringing_probe_is_named_sensor_dynamics_with_its_resonance(seed, share, damping):
    """A probe ringing at 1-3 % of the sampling rate: the verdict is the sensor-dynamics slot (not
    ``unexplained`` or a sensor map), and the fit finds the resonance within 3 % and its damping ratio within
    20 %."""
    base = make_recording("none", seed, output="magnetization", n_samples=3000)[0]
    frequency = share / float(np.median(np.diff(base.time)))
    recording = _ringing_record(seed, frequency, damping)
    report = diagnose(recording, effects=["sensor_lag", "sensor_map", "eddy_current", "input_lag"], progress=False)
    assert report.verdict == "sensor_lag", (report.verdict, report.explanation)
    values = report.chosen.fit.values
    fitted_frequency = 1.0 / (2 * np.pi * values["tau2_m"])
    assert abs(fitted_frequency / frequency - 1.0) < 0.03
    assert abs(values["tau_m"] / (2 * values["tau2_m"]) / damping - 1.0) < 0.2
    assert "resonates at" in report.explanation


def test_a_channel_whose_sensor_does_not_filter_is_no_wall():
    """tau = 0 on a channel whose tau2 is below one sample interval too is a member of the sensor-dynamics family
    (that channel's sensor reads true while the other rings), not a fit that ran into a wall; tau = 0 beside a tau2
    the record sees (a resonance without damping) is a wall, and so is a tau at the family's upper bound. The block
    check then refits the filtering channel's tau, not the near-zero one."""
    from types import SimpleNamespace

    from hyst_gym.diagnose.decide import Plausibility, _check_bounds
    from hyst_gym.diagnose.effects import effect
    from hyst_gym.diagnose.parameter import Parameter

    registered = effect("sensor_lag")
    parameters = {name: Parameter(name, 0.0, 0.0, 5e-3, "s") for name in registered.parameter_names}
    model = SimpleNamespace(parameters=parameters, recording=SimpleNamespace(time=np.arange(2000) * 1e-5))
    ringing_m = {"tau_m": 2e-4, "tau_x": 3.4e-6, "tau2_m": 1e-4, "tau2_x": 5e-7}

    def check(values):
        out = Plausibility()
        _check_bounds(out, registered, SimpleNamespace(model=model, values=values))
        return out

    assert check(ringing_m).plausible, check(ringing_m).reasons
    undamped = check(dict(ringing_m, tau2_x=1e-4))
    assert not undamped.plausible and undamped.at_bound == ["tau_x"]
    walled = check(dict(ringing_m, tau_m=5e-3))
    assert not walled.plausible and walled.at_bound == ["tau_m"]
    fit = SimpleNamespace(model=model, values=ringing_m)
    assert registered.main_parameter(fit) == "tau_m"
    assert registered.main_parameter(SimpleNamespace(model=model, values=dict(ringing_m, tau_x=5e-5))) == "tau_x"
