"""The input dynamics (``input_lag``): the field in the material lags the recorded one (a coil's L/R, an
amplifier's bandwidth). Its kernel against an independent integration, and an honest name or tie."""

import numpy as np
import pytest

from hyst_gym.diagnose import diagnose, make_recording
from hyst_gym.diagnose.kernels import AMBIENT_TEMPERATURE, MAGNETIC_COLUMNS, simulate_members
from hyst_gym.diagnose.model import Model, Structure, base_parameters, extension_parameters, input_dynamics


def test_the_lag_is_a_first_order_filter_and_the_delay_a_shift():
    """A lag tau: the closed-form response of tau*y' = u - y to a field linear between samples (the
    kernel's first-order hold), started settled; a delay of three steps: the field three samples
    earlier, the first one held."""
    time = np.sort(np.concatenate([np.linspace(0.0, 0.02, 400), [0.00123, 0.0111]]))  # non-uniform steps
    field = 5e4 * np.sin(2 * np.pi * 150 * time) + 2e4 * np.sign(np.sin(2 * np.pi * 40 * time))
    tau = 3e-4
    expected = np.empty_like(field)
    expected[0] = field[0]
    for i, h in enumerate(np.diff(time)):
        slope = (field[i + 1] - field[i]) / h  # y = u - tau*slope + (y0 - u0 + tau*slope)*exp(-h/tau)
        expected[i + 1] = field[i + 1] - tau * slope + (expected[i] - field[i] + tau * slope) * np.exp(-h / tau)
    np.testing.assert_allclose(input_dynamics(time, field, tau, 0.0), expected, rtol=0, atol=1e-6 * np.ptp(field))
    uniform = np.linspace(0.0, 0.01, 201)
    drive = 5e4 * np.sin(2 * np.pi * 220 * uniform)
    delayed = input_dynamics(uniform, drive, 0.0, 3 * (uniform[1] - uniform[0]))
    np.testing.assert_allclose(delayed[3:], drive[:-3], rtol=0, atol=1e-9 * np.ptp(drive))
    assert np.all(delayed[:3] == drive[0])
    assert input_dynamics(uniform, drive, 0.0, 0.0) is drive  # the identity when both vanish


def test_the_model_simulates_the_loop_on_the_lagged_field():
    recording = make_recording("none", 2, output="magnetization", n_samples=1000)[0]
    structure = Structure("none", "ising", "input_lag")
    base = base_parameters(recording, structure)
    values = {n: p.value for n, p in base.items()}
    model = Model(recording, structure, {**base, **extension_parameters(recording, structure, values)}, 200.0)
    values = dict(model.values(), tau_in=4e-5, delay_in=1e-5)
    lagged = input_dynamics(recording.time, recording.field, 4e-5, 1e-5)
    row = np.array([model.magnetic_row(values)])
    expected = simulate_members(recording.time, lagged, row, 0, 200.0, AMBIENT_TEMPERATURE)[:, 0]
    np.testing.assert_array_equal(model.magnetization([values])[:, 0], expected)
    assert list(MAGNETIC_COLUMNS)  # the row is the kernel's, column for column


@pytest.mark.parametrize("seed", [7, 8])
def test_an_input_lag_is_named_or_tied_with_a_sensor_lag_never_named_as_one(seed):
    """From the magnetization alone an input lag and a sensor lag bend the loop alike: the verdict is
    ``input_lag``, or ``ambiguous`` with both and the measurement that separates them; never the sensor lag
    alone."""
    recording = make_recording("input_lag", seed, output="magnetization", n_samples=2000)[0]
    report = diagnose(recording, progress=False)
    tied = {c.effect for c in report.tied}
    assert report.verdict == "input_lag" or (report.verdict == "ambiguous" and {"input_lag", "sensor_lag"} <= tied)
    if report.verdict == "ambiguous":
        assert "Hall probe" in report.advice


def test_a_pure_delay_is_a_member_of_the_family_not_a_fit_at_a_wall():
    """A field delayed by three samples and not lagged: the fit's lag ends at zero, which is no lag (a member of
    the family), so the candidate is not rejected as pinned at a bound; the verdict names the input dynamics, or
    ties them with a sensor lag."""
    base = make_recording("none", 3, output="magnetization", n_samples=2000)[0]
    dt = float(base.time[1] - base.time[0])
    delayed = input_dynamics(base.time, base.field, 0.0, 3 * dt)
    row = np.array([[dict(a=6000.0, k=1500.0, alpha=-0.01, Ms=8e5, c=0.2, H0=0.0, k_e=0.0, heating=0.0, tau_th=1.0,
                          beta_Ms=0.0, chi_r=0.0, heating_exponent=2.0)[c] for c in MAGNETIC_COLUMNS]])
    clean = simulate_members(base.time, delayed, row, 0, 25.0, AMBIENT_TEMPERATURE)[:, 0]
    noisy = clean + 1e-3 * np.ptp(clean) * np.random.default_rng(0).standard_normal(clean.size)
    from hyst_gym.diagnose import Recording

    report = diagnose(Recording(time=base.time, field=base.field, magnetization=noisy), progress=False)
    lag = next(c for c in report.candidates if c.effect == "input_lag")
    assert not any("sits at the bound" in reason for reason in lag.plausibility.reasons)
    assert report.verdict == "input_lag" or (report.verdict == "ambiguous"
                                             and "input_lag" in {c.effect for c in report.tied})
