"""The next-drive study (experiments/diagnose_next_drive.py): its own replay is the generator's
record, each generator's truth is scored by its slot, the paired interval behaves, and the page's
generated section is current. (The mismatch tool's own next-drive tests are in tests/diagnose.)"""
from __future__ import annotations

import numpy as np
import pytest

from hyst_gym.diagnose import make_recording

def test_the_own_replay_keeps_the_sensor_maps_range_and_is_the_generators_record():
    from experiments import diagnose_next_drive as study

    first = make_recording("sensor_map", 2, output="magnetization", n_samples=800)[0]
    again = study.replay("sensor_map", 2, "magnetization", 800)  # noise stream 0: the generator's own draw
    np.testing.assert_allclose(again.magnetization, first.magnetization, rtol=0,
                               atol=1e-9 * np.ptp(first.magnetization))
    # the map is the generator's: on its own range the framed map equals the generator's map of the same draws
    signal = np.linspace(-3.0, 5.0, 50) ** 3
    mapped = study._framed_sensor_map(signal, signal, np.random.default_rng(7), None)
    np.testing.assert_allclose(mapped, study.generator._sensor_map(signal, 1.0, np.random.default_rng(7), None),
                               rtol=1e-12, atol=1e-12 * np.ptp(signal))


def test_the_study_scores_each_generators_truth_by_its_slot():
    from experiments.diagnose_next_drive import StudyCase, _right, _wrong
    from hyst_gym.diagnose.effects import EFFECT_SLOTS

    class Verdict:
        def __init__(self, verdict, slot=None):
            self.verdict, self.slot = verdict, slot

    amplifier = StudyCase("independent", "amplifier_saturation", 1, "magnetization").expected
    assert amplifier == {"input_map"}
    assert StudyCase("other_forms", "sensor_resonance", 0, "both").expected == {"sensor_lag"}
    assert StudyCase("independent", "two_phase_rod", 1, "both").expected == {"unexplained", "ambiguous"}
    named = Verdict("input_map", EFFECT_SLOTS["input_map"])
    assert _right(named, amplifier) and not _wrong(named, amplifier)
    other = Verdict("sensor_map", EFFECT_SLOTS["sensor_map"])
    assert not _right(other, amplifier) and _wrong(other, amplifier)
    assert not _right(Verdict("ambiguous"), amplifier) and not _wrong(Verdict("ambiguous"), amplifier)
    assert _right(Verdict("none"), frozenset({"none"})) and not _right(Verdict("none"), amplifier)


def test_the_paired_interval_brackets_the_mean_and_excludes_zero_only_when_it_should():
    from experiments.diagnose_next_drive import paired_difference

    def rows(pattern):
        return [{"designed": {"right": d}, "control": {"right": c}} for d, c in pattern]

    tie = paired_difference(rows([(True, True)] * 20 + [(True, False), (False, True)]))
    assert tie["mean"] == 0.0 and tie["ci95"][0] < 0 < tie["ci95"][1]
    better = paired_difference(rows([(True, False)] * 12 + [(True, True)] * 8))
    assert better["mean"] == pytest.approx(0.6) and better["ci95"][0] > 0
    assert better["designed_only"] == 12 and better["control_only"] == 0


def test_the_next_drive_page_section_is_current():
    """docs/results/next-drive.md's generated section is what the script writes from the committed JSON."""
    import json
    import pathlib

    from experiments.diagnose_next_drive import OUT, PAGE, SECTION, payload_of, page_section

    stored = json.loads((OUT / "next_drive.json").read_text(encoding="utf-8"))
    fresh = payload_of(stored["rows"], stored["samples"])
    text = PAGE.read_text(encoding="utf-8")
    start, end = f"<!-- section:{SECTION} -->", f"<!-- /section:{SECTION} -->"
    assert text.count(start) == 1 and text.count(end) == 1
    assert text.split(start, 1)[1].split(end, 1)[0].strip() == page_section(fresh).strip(), \
        "rerun: python -m experiments.diagnose_next_drive --rewrite"
    assert pathlib.Path(OUT / "next_drive.md").read_text(encoding="utf-8").endswith(page_section(fresh))
