"""The next drive: the hypotheses left standing, the recorded limits kept by construction, determinism, a
separation the first record could not show, and one-line errors."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from hyst_gym import cli
from hyst_gym.diagnose import diagnose, make_recording, write_recording
from hyst_gym.diagnose.decide import MATERIAL_SHARE
from hyst_gym.diagnose.model import Model
from hyst_gym.diagnose.next_drive import (DriveLimits, design_next_drive, standing_hypotheses,
                                          windowed_mean_square)
from hyst_gym.diagnose.recording import Recording, read_recording

LAGS = ["input_lag", "sensor_lag", "eddy_current"]


@pytest.fixture(scope="module")
def tied():
    """An input lag that one magnetization record cannot tell from a sensor lag (seed 8: ambiguous)."""
    recording = make_recording("input_lag", 8, output="magnetization", n_samples=2000)[0]
    report = diagnose(recording, effects=LAGS, progress=False, workers=1)
    assert report.verdict == "ambiguous" and {c.effect for c in report.tied} == {"input_lag", "sensor_lag"}
    return recording, report


@pytest.fixture(scope="module")
def design(tied):
    return design_next_drive(tied[1], design_points=16, refine_evaluations=20)


def _independent_limits(field, time, recording, window):
    """The limits computed here without the module: peak, slew and the largest windowed mean square."""
    peak = np.max(np.abs(recording.field))
    slew = np.max(np.abs(np.diff(recording.field)) / np.diff(recording.time))
    heating = max(np.mean(recording.field[i:i + window] ** 2) for i in range(recording.size - window + 1))
    return (np.max(np.abs(field)) <= peak * (1 + 1e-9),
            np.max(np.abs(np.diff(field)) / np.diff(time)) <= slew * (1 + 1e-9),
            max(np.mean(field[i:i + window] ** 2) for i in range(field.size - window + 1)) <= heating * (1 + 1e-9))


def test_designed_drive_keeps_every_recorded_limit(tied, design):
    recording, _ = tied
    assert design.time.size <= recording.size
    assert np.allclose(np.diff(design.time), np.diff(recording.time)[: design.time.size - 1])
    assert all(_independent_limits(design.field, design.time, recording, design.limits.window))
    assert design.limits.violations(design.field, design.time) == []
    # it reaches the record's largest |field| (the input map's frame) on the record's side
    extreme = recording.field[np.argmax(np.abs(recording.field))]
    assert design.field[np.argmax(np.abs(design.field))] == pytest.approx(extreme, rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(raw=arrays(np.float64, st.integers(50, 400), elements=st.floats(-1e6, 1e6)),
       peak=st.floats(1.0, 1e5), slew=st.floats(1.0, 1e8), heating_share=st.floats(0.01, 1.5),
       window=st.integers(1, 60))
def test_projection_keeps_the_limits_for_any_raw_drive(raw, peak, slew, heating_share, window):
    time = np.arange(raw.size) * 1e-4
    limits = DriveLimits(peak, slew, heating_share * peak ** 2, window)
    field = limits.project(raw, time)
    assert np.max(np.abs(field)) <= peak * (1 + 1e-12)
    rounding = 8 * np.finfo(np.float64).eps * peak  # a step is a difference of values up to peak
    assert np.max(np.abs(np.diff(field))) <= slew * 1e-4 * (1 + 1e-9) + rounding
    assert np.max(windowed_mean_square(field, window)) <= limits.heating * (1 + 1e-9)
    assert limits.violations(field, time) == []
    # no window's mean square can exceed peak^2: then the frame pulse always fits, if the drive is long enough
    if limits.heating >= peak ** 2 and 2 * np.ceil(peak / (slew * 1e-4)) + 5 < raw.size // 2:
        assert limits.keeps_frame(field)


def test_the_design_is_deterministic(tied, design):
    again = design_next_drive(tied[1], design_points=16, refine_evaluations=20)
    assert np.array_equal(design.field, again.field)
    assert design.pairs == again.pairs


def test_designed_drive_separates_a_tie_the_first_drive_could_not(tied, design):
    """The tie's pair is predicted apart by more than the material bar; the number is checked against the two
    fitted models simulated here on the designed drive, and it beats the first drive's."""
    recording, report = tied
    assert design.hypotheses == [c.effect for c in report.tied]
    (pair,) = design.pairs
    assert pair["material"] and pair["heldout_block_max"] >= MATERIAL_SHARE
    assert pair["separation"] > 10 * pair["first_drive"]
    placeholder = Recording(time=design.time, field=design.field, magnetization=recording.magnetization)
    a, b = (Model(placeholder, c.fit.model.structure, c.fit.model.parameters, c.fit.model.max_field_step)
            .predict(c.fit.values)["magnetization"] for c in report.tied)
    independent = float(np.mean(((a - b) / report.noise["magnetization"]) ** 2))
    assert independent == pytest.approx(pair["separation"], rel=1e-9)


def test_standing_hypotheses_follow_the_verdict(tied):
    _, report = tied
    names = [h.name for h in standing_hypotheses(report)]
    assert names == [c.effect for c in report.tied]
    for pair in itertools.combinations(names, 2):
        assert pair[0] != pair[1]


def test_a_confident_name_writes_nothing(tmp_path):
    recording = make_recording("small_loop", 1, output="magnetization", n_samples=2000)[0]
    report = diagnose(recording, effects=["small_loop", "field_bias"], progress=False, workers=1)
    path = tmp_path / "next.csv"
    if report.confidence >= 0.8 and report.verdict == "small_loop" and not report.identifiability["unidentified"]:
        assert report.next_drive(path) is None
        assert not path.exists()
    else:
        pytest.fail(f"expected a confident small_loop, got {report.verdict} at {report.confidence:.2f}")


def test_cli_writes_a_readable_drive(tmp_path, tied, capsys):
    recording, _ = tied
    path = write_recording(tmp_path / "rec.csv", recording)
    out = tmp_path / "next.csv"
    # the full vocabulary: the drive separates what it leaves standing, whatever that is
    assert cli.main(["diagnose", str(path), "--quiet", "--next-drive", str(out)]) == 0
    text = capsys.readouterr().out
    if out.exists():
        assert out.read_text().splitlines()[0] == "time,field"
        data = np.loadtxt(out, delimiter=",", skiprows=1)
        assert data.shape[0] <= recording.size and data.shape[1] == 2
        assert all(_independent_limits(data[:, 1], data[:, 0], recording, max(1, round(0.1 * recording.size))))
        assert "Next drive separates" in text
    else:
        assert "none written" in text


def test_bad_arguments_give_one_line_errors(tmp_path, tied, capsys):
    recording, report = tied
    with pytest.raises(ValueError, match="seed must be an integer >= 0"):
        design_next_drive(report, seed=-1)
    with pytest.raises(ValueError, match="design_points must be an integer >= 1"):
        design_next_drive(report, design_points=0)
    path = write_recording(tmp_path / "rec.csv", recording)
    assert cli.main(["diagnose", str(path), "--quiet", "--next-drive", str(tmp_path / "missing" / "n.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--next-drive" in err[0] and "does not exist" in err[0]
    assert cli.main(["diagnose", str(path), "--quiet", "--next-drive", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is a folder" in err[0]
    assert read_recording(path).size == recording.size


def test_a_low_confidence_name_stands_with_its_runner_up_and_an_open_direction_with_none():
    recording = make_recording("input_lag", 7, output="magnetization", n_samples=2000)[0]
    report = diagnose(recording, effects=LAGS, progress=False, workers=1)
    assert report.verdict == "input_lag" and report.confidence < 0.8
    runner = max((c for c in report.candidates if c is not report.chosen), key=lambda c: c.improvement)
    names = [h.name for h in standing_hypotheses(report)]
    assert names[:2] == ["input_lag", runner.effect]
    assert ("none" in names) == bool(report.identifiability["unidentified"])


def test_the_frame_pulse_reaches_the_peak_when_heating_allows_and_is_dropped_when_not():
    time = np.arange(400) * 1e-4
    raw = 5.0 * np.sin(2 * np.pi * 50 * time)
    allowed = DriveLimits(peak=2.0, slew=5e3, heating=4.0, window=40)   # 0.5 A/m per step: a 4-step ramp
    field = allowed.project(raw, time, sign=-1.0)
    assert field[0] == 0.0 and field.min() == pytest.approx(-2.0, rel=1e-12) and allowed.keeps_frame(field)
    assert allowed.violations(field, time) == []
    tight = DriveLimits(peak=2.0, slew=5e3, heating=0.05, window=40)   # the pulse alone heats more than this
    field = tight.project(raw, time)
    assert not tight.keeps_frame(field) and tight.violations(field, time) == []
