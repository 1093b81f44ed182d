"""Materiality under coloured sensor noise (hyst_gym.diagnose.locate.residual_structure).

The noise here is drawn in forms of its own, not the studies' generator: white noise plus a share passed
through a 4th-order Butterworth low-pass (an amplifier whose bandwidth is below the sample rate), or plus
1/f noise. The drive is a sum of two sines; a model error is a function of the drive's state."""

import numpy as np
import pytest
from scipy import signal

from hyst_gym.diagnose.decide import MATERIAL_SHARE, decide
from hyst_gym.diagnose.locate import (NOISE_HORIZON, colour_note, residual_structure, structured_power,
                                      drive_state)

N = 40000
CUT = 28000
TIME = np.arange(N) * 1e-4
FIELD = 3000.0 * (np.sin(2 * np.pi * TIME / 0.07) + 0.4 * np.sin(2 * np.pi * TIME / 0.023 + 1.0))
STATE = drive_state(FIELD, TIME)


def _lowpass_noise(rng, coloured_share=0.6, cutoff=0.03):
    """Unit-variance noise: ``coloured_share`` of the variance low-passed at ``cutoff`` of the sample rate
    (correlated over about 1/(2 pi cutoff) ~ 5 samples and beyond), the rest white."""
    b, a = signal.butter(4, 2 * cutoff)
    part = signal.lfilter(b, a, rng.standard_normal(N + 500))[500:]
    part /= np.std(part)
    return np.sqrt(1 - coloured_share) * rng.standard_normal(N) + np.sqrt(coloured_share) * part


def _flicker_noise(rng, coloured_share=0.5, exponent=1.2, longest=150):
    """Unit-variance noise: ``coloured_share`` of 1/f^exponent noise flat below a ``longest``-sample period."""
    spectrum = np.fft.rfft(rng.standard_normal(N))
    spectrum *= np.maximum(np.arange(spectrum.size, dtype=float), N / longest) ** (-exponent / 2)
    spectrum[0] = 0.0
    part = np.fft.irfft(spectrum, N)
    part /= np.std(part)
    return np.sqrt(1 - coloured_share) * rng.standard_normal(N) + np.sqrt(coloured_share) * part


def _model_error(rms):
    """A model error that follows the drive: a saturating function of the field, of the given RMS."""
    error = np.tanh(2.0 * STATE[:, 0]) + 0.3 * STATE[:, 0] ** 2
    error -= error.mean()
    return rms * error / np.std(error)


def _structure(residual):
    """residual_structure of one channel, the first CUT samples as the fitting block."""
    return residual_structure({"magnetization": residual[CUT:]}, {"magnetization": residual[:CUT]},
                              STATE[CUT:], STATE[:CUT])


@pytest.mark.parametrize("noise", [_lowpass_noise, _flicker_noise])
def test_coloured_noise_alone_is_not_material(noise):
    """Coloured noise and nothing else: the short-lag measure (which assumes white noise) reads it as a material
    structure -- the false alarm -- while the channel is found coloured and the drive-paired measure reads
    less than half the material share."""
    for seed in range(3):
        residual = noise(np.random.default_rng(seed))
        assert structured_power(residual[CUT:], bootstrap=0)["share"] >= MATERIAL_SHARE
        measured = _structure(residual)
        assert measured["coloured_channels"] == ["magnetization"], measured["noise_colour"]
        assert measured["method"] == "drive-paired"
        assert measured["share"] < 0.5 * MATERIAL_SHARE, (seed, measured["share"])
        assert measured["short_lag_share"] >= MATERIAL_SHARE


@pytest.mark.parametrize("noise", [_lowpass_noise, _flicker_noise])
def test_a_slow_model_error_in_coloured_noise_is_measured(noise):
    """A model error of half the noise RMS (power 0.25 of the noise power, the material bar) is read at about
    that share (within 0.06 on a 12,000-sample held-out block, over three noise draws), one of 0.7 the noise RMS
    (0.49) is material, and the colour is still found under it."""
    half = []
    for seed in range(3):
        noise_draw = noise(np.random.default_rng(10 + seed))
        measured = _structure(noise_draw + _model_error(0.5))
        assert measured["method"] == "drive-paired"
        half.append(measured["share"])
        larger = _structure(noise_draw + _model_error(0.7))
        assert larger["share"] >= MATERIAL_SHARE, (seed, larger["share"])
    assert abs(np.mean(half) - 0.25) < 0.06, half


def test_white_noise_keeps_the_short_lag_measure():
    """With white noise nothing changes: the channel is not found coloured, and the share is the lags 1-3
    measure's, with or without a model error."""
    rng = np.random.default_rng(5)
    for rms in (0.0, 0.5):
        residual = rng.standard_normal(N) + _model_error(rms)
        measured = _structure(residual)
        assert measured["coloured_channels"] == [] and measured["method"] == "short-lag"
        assert measured["share"] == pytest.approx(structured_power(residual[CUT:], bootstrap=0)["share"])
        assert colour_note(measured, {"magnetization": 1.0}) is None


def test_a_hum_is_not_taken_for_noise():
    """A mains hum (50 Hz at 40 kHz: 800 samples a period) of 0.32 of the noise power does not follow the drive
    but stays correlated beyond the noise horizon: it breaks the assumption that separates noise from a model
    error, so the channel is not found coloured and the hum stays material (lags 1-3). The check needs that
    correlation to reach half a material share of the noise power: a hum of 0.125 of it with a 167-sample
    period is taken for coloured noise (a limitation: the mains_pickup candidate, which fits a hum, names it)."""
    rng = np.random.default_rng(8)
    hum = _structure(rng.standard_normal(N) + 0.8 * np.sin(2 * np.pi * np.arange(N) / 800.0))
    assert hum["coloured_channels"] == []
    assert hum["share"] >= MATERIAL_SHARE
    weak = _structure(rng.standard_normal(N) + 0.5 * np.sin(2 * np.pi * np.arange(N) / 167.0))
    assert weak["coloured_channels"] == ["magnetization"]


def test_the_report_says_what_it_found_and_did():
    """The note names the coloured channel, its power over the white part and correlation, the horizon and both
    shares; a decision on the same structure says the share was read between moments of the same drive state."""
    residual = 1.3 * _lowpass_noise(np.random.default_rng(2))
    measured = _structure(residual)
    note = colour_note(measured, {"magnetization": float(np.sqrt(np.mean(residual[CUT:] ** 2)))})
    assert note is not None
    assert "coloured" in note and "'magnetization'" in note and f"{NOISE_HORIZON} samples" in note
    ratio = measured["noise_colour"]["magnetization"]["power_ratio"]
    assert ratio == pytest.approx(1.69, rel=0.1)  # 1.3^2: the whole noise, over a noise unit of 1
    assert f"{ratio:.1f}x the power that second differences see" in note
    assert f"lags 1-3 would read {100 * measured['short_lag_share']:.0f} %" in note

    material = _structure(residual + 1.3 * _model_error(0.8))
    assert material["share"] >= MATERIAL_SHARE
    assert decide([], 1.2, ("magnetization",), base_structure=material).verdict == "unexplained"
    paired = dict(material, method="drive-paired")
    assert "between moments of the same drive state" in decide([], 1.2, ("magnetization",),
                                                                base_structure=paired).notes[-1]


@pytest.mark.slow
def test_coloured_noise_alone_gives_none_with_the_note():
    """End to end: a recording of the base physics (the own generator, no effect) with a low-passed noise of
    0.8 times the white noise's RMS added to its magnetization is `none`, and the report's notes say the
    noise was found coloured and what was done."""
    from dataclasses import replace

    from hyst_gym.diagnose import diagnose
    from hyst_gym.diagnose.make_recording import make_recording_with_truth

    recording, _, truth = make_recording_with_truth("none", 3, output="magnetization", n_samples=4000)
    sigma = truth["noise_rel"] * float(np.ptp(recording.magnetization))
    b, a = signal.butter(4, 2 * 0.02)
    part = signal.lfilter(b, a, np.random.default_rng(4).standard_normal(recording.size + 500))[500:]
    coloured = replace(recording, magnetization=recording.magnetization + 0.8 * sigma * part / np.std(part))
    report = diagnose(coloured, progress=False)
    assert report.verdict == "none", report.notes
    assert report.material_structure["coloured_channels"] == ["magnetization"]
    assert any(note.startswith("the noise is coloured on 'magnetization'") for note in report.notes), report.notes
