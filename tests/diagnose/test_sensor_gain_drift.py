"""The sensor gain drift (``sensor_gain_drift``): a sensor's gain moves slowly over the record. Its kernel
against an independent product, and its verdicts: named (or tied, never a confident wrong name), while a
record without it stays ``none`` and a heating record stays ``thermal_drift``."""

import numpy as np
import pytest

from hyst_gym.diagnose import diagnose, make_recording
from hyst_gym.diagnose.identifiability import separating_measurement
from hyst_gym.diagnose.model import Model, Structure, base_parameters, extension_parameters, gain_drift_factor


def _model(recording, transducer):
    structure = Structure(transducer, "ising", "sensor_gain_drift")
    base = base_parameters(recording, structure)
    values = {n: p.value for n, p in base.items()}
    return Model(recording, structure, {**base, **extension_parameters(recording, structure, values)}, 200.0)


def test_the_reading_is_the_true_output_times_the_drifting_gain():
    """Each channel's prediction is the plain prediction times 1 + g1*f + g2*(1 - exp(-f/tau)), f the time
    mapped to [0, 1], written out here from its definition; each channel has its own coefficients."""
    recording = make_recording("none", 3, output="both", n_samples=600)[0]
    model = _model(recording, "lumped")
    plain_values = model.values()
    values = dict(plain_values, gain_drift_linear_m=0.04, gain_drift_settling_m=-0.07, gain_drift_linear_x=-0.02,
                  gain_drift_settling_x=0.05, tau_gain=0.3)
    plain, drifted = model.predict(plain_values), model.predict(values)
    f = (recording.time - recording.time[0]) / (recording.time[-1] - recording.time[0])
    for channel, (g1, g2) in (("magnetization", (0.04, -0.07)), ("displacement", (-0.02, 0.05))):
        expected = plain[channel] * (1.0 + g1 * f + g2 * (1.0 - np.exp(-f / 0.3)))
        np.testing.assert_allclose(drifted[channel], expected, rtol=1e-12, atol=1e-12 * np.ptp(expected))
        assert drifted[channel][0] == pytest.approx(plain[channel][0])  # calibrated at the start
    # a long settling time turns the settling term into a linear one: the family holds a linear creep
    np.testing.assert_allclose(gain_drift_factor(f, 0.0, 0.1 * 1e3, 1e3), 1.0 + 0.1 * f, rtol=0, atol=1e-4)


def test_the_generator_scales_the_recorded_output():
    """make_recording's gain drift multiplies the output: the record's ratio to the same seed's record without
    it moves away from 1 by 3-8 % over the record, from ~1 at the start (the noise is the same stream)."""
    drifted = make_recording("sensor_gain_drift", 4, output="magnetization", n_samples=2000)[0].magnetization
    plain = make_recording("none", 4, output="magnetization", n_samples=2000)[0].magnetization
    large = np.abs(plain) > 0.3 * np.max(np.abs(plain))
    ratio = drifted[large] / plain[large]
    change = np.median(ratio[-100:]) - np.median(ratio[:100])
    assert 0.01 < abs(change) < 0.09


def test_with_magnetization_alone_the_tie_with_heating_names_the_separating_measurements():
    """Where the record cannot tell a gain drift from an Ms(t) drift, the tie says what would: the
    displacement beside the magnetization, or another temperature."""
    advice = separating_measurement(("magnetization",), ["thermal_drift", "sensor_gain_drift"])
    assert "displacement" in advice and "temperature" in advice
    assert "drive off" in separating_measurement(("magnetization",), ["sensor_drift", "sensor_gain_drift"])


def _assert_named_or_tied(report, partner=None):
    tied = {c.effect for c in report.tied}
    assert report.verdict == "sensor_gain_drift" or (report.verdict == "ambiguous" and "sensor_gain_drift" in tied), \
        (report.verdict, tied)
    if report.verdict == "ambiguous" and partner in tied:
        assert "displacement" in report.advice or "temperature" in report.advice


@pytest.mark.parametrize("output", ["magnetization", "displacement", "both"])
@pytest.mark.parametrize("seed", [1, 2])
def test_a_gain_drift_is_named_or_tied_never_called_heating(output, seed):
    recording = make_recording("sensor_gain_drift", seed, output=output, n_samples=2000)[0]
    report = diagnose(recording, progress=False)
    _assert_named_or_tied(report, "thermal_drift")
    assert report.chosen.heldout_rmse < 0.4 * report.baseline_heldout  # >= 60 % lower held-out RMSE


@pytest.mark.parametrize("output", ["magnetization", "both"])
def test_a_heating_record_is_not_named_a_gain_drift(output):
    report = diagnose(make_recording("thermal_drift", 2, output=output, n_samples=2000)[0], progress=False)
    assert report.verdict != "sensor_gain_drift"
    if report.verdict == "ambiguous":
        assert "thermal_drift" in {c.effect for c in report.tied}


@pytest.mark.parametrize("output", ["magnetization", "displacement", "both"])
def test_a_record_without_an_effect_stays_none(output):
    report = diagnose(make_recording("none", 2, output=output, n_samples=2000)[0], progress=False)
    assert report.verdict == "none", (report.verdict, report.notes)
