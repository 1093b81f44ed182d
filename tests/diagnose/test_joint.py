"""Several records, one diagnosis: one record in gives today's report; a joint fit shares its parameters and
decides a tie that a separating second record resolves; one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hyst_gym import cli
from hyst_gym.diagnose import diagnose, make_recording, write_recording
from hyst_gym.diagnose.fit import Split
from hyst_gym.diagnose.joint import joint_fit, record_models
from hyst_gym.diagnose.next_drive import design_next_drive
from hyst_gym.diagnose.recording import Recording
from hyst_gym.diagnose.report import _jsonable

LAGS = ["input_lag", "sensor_lag", "eddy_current"]


def _comparable(report) -> str:
    data = _jsonable(report.to_json())
    data.pop("seconds")
    return json.dumps(data, sort_keys=True)


@pytest.mark.parametrize("effect, seed, effects", [("input_lag", 8, LAGS),
                                                   ("small_loop", 1, ["small_loop", "field_bias"])])
def test_one_record_in_a_list_gives_todays_report(effect, seed, effects):
    recording = make_recording(effect, seed, output="magnetization", n_samples=1500)[0]
    alone = diagnose(recording, effects=effects, progress=False, workers=1)
    listed = diagnose([recording], effects=effects, progress=False, workers=1)
    assert _comparable(alone) == _comparable(listed)
    assert all(a.fit.values == b.fit.values for a, b in zip(alone.candidates, listed.candidates))
    assert "records" not in listed.to_json()


@pytest.fixture(scope="module")
def tie_and_follow_up():
    """A tie (input lag vs sensor lag) and a second record of the input-lag hypothesis under the designed drive:
    the second record is that fitted model's prediction plus white noise at the first record's level."""
    first = make_recording("input_lag", 8, output="magnetization", n_samples=2000)[0]
    report = diagnose(first, effects=LAGS, progress=False, workers=1)
    assert report.verdict == "ambiguous"
    design = design_next_drive(report, design_points=16, refine_evaluations=20)
    truth = next(c for c in report.tied if c.effect == "input_lag").fit
    shell = Recording(time=design.time, field=design.field, magnetization=first.magnetization)
    clean = record_models(truth.model, [Split.of(shell, 0.3)])[0].predict(truth.values)["magnetization"]
    noise = np.random.default_rng(5).standard_normal(clean.size) * report.noise["magnetization"]
    second = Recording(time=design.time, field=design.field, magnetization=clean + noise, source="follow-up")
    return first, second, report


def test_a_separating_second_record_decides_the_tie(tie_and_follow_up):
    first, second, single = tie_and_follow_up
    joint = diagnose([first, second], effects=LAGS, progress=False, workers=1)
    assert joint.verdict == "input_lag"
    records = joint.to_json()["records"]
    assert [r["source"] for r in records] == [first.source, "follow-up"]
    by_record = [r["candidates"] for r in records]
    # on the follow-up the sensor lag misses where the input lag explains it to within noise
    assert by_record[1]["input_lag"] < 1.3 < by_record[1]["sensor_lag"]
    assert joint.recordings == [first, second]


def test_the_joint_fit_lowers_the_stacked_residual_with_one_shared_parameter_set(tie_and_follow_up):
    first, second, single = tie_and_follow_up
    splits = [Split.of(first, 0.3), Split.of(second, 0.3)]
    start = next(c for c in single.candidates if c.effect == "sensor_lag").fit
    fit = joint_fit(start, splits)

    def stacked_sse(values):  # computed here: each record's fitting block over its own noise level
        total = 0.0
        for model, split in zip(record_models(start.model, splits), splits):
            predicted = model.predict(values)["magnetization"]
            r = (predicted - split.recording.magnetization)[split.fit_mask] / split.noise["magnetization"]
            total += float(r @ r)
        return total

    assert fit.sse == pytest.approx(stacked_sse(fit.values), rel=1e-9)
    assert fit.sse <= stacked_sse(start.values)
    assert fit.n_residuals == int(splits[0].fit_mask.sum() + splits[1].fit_mask.sum())


def test_bad_record_lists_give_one_line_errors(tmp_path, capsys):
    with pytest.raises(ValueError, match="empty list"):
        diagnose([], progress=False)
    magnetic = make_recording("none", 1, output="magnetization", n_samples=1000)[0]
    both = make_recording("none", 1, output="both", n_samples=1000)[0]
    with pytest.raises(ValueError, match="the same channels"):
        diagnose([magnetic, both], progress=False)
    a = write_recording(tmp_path / "a.csv", magnetic)
    b = write_recording(tmp_path / "b.csv", both)
    assert cli.main(["diagnose", str(a), str(b), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the same channels" in err[0]
