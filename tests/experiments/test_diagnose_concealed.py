"""The concealed study's scoring: outcomes per verdict and the reliability table's two shares."""

import pytest

from experiments.diagnose_concealed import BINS, cases, outcome, reliability


@pytest.mark.parametrize("effect, in_vocabulary, verdict, tied, expected", [
    ("field_bias", True, "field_bias", [], "right"),
    ("field_bias", True, "ambiguous", ["field_bias", "small_loop"], "ambiguous_with_truth"),
    ("field_bias", True, "ambiguous", ["sensor_lag", "small_loop"], "ambiguous_without_truth"),
    ("field_bias", True, "small_loop", [], "wrong_name"),
    ("field_bias", True, "none", [], "missed"),
    ("none", True, "none", [], "right"),
    ("none", True, "small_loop", [], "wrong_name"),          # a false alarm
    ("two_phase_rod", False, "unexplained", [], "right"),     # outside the vocabulary
    ("two_phase_rod", False, "small_loop", [], "wrong_name"),
])
def test_outcome(effect, in_vocabulary, verdict, tied, expected):
    assert outcome(effect, in_vocabulary, verdict, tied) == expected


def test_reliability_counts_exact_and_ambiguous_with_truth_separately():
    rows = [{"confidence": str(c), "outcome": o} for c, o in
            [(0.95, "right"), (0.97, "ambiguous_with_truth"), (0.91, "unexplained"), (0.99, "right"),
             (0.1, "missed"), (1.0, "right")]]
    table = {tuple(r["confidence"]): r for r in reliability(rows)}
    top = table[(0.9, 1.0)]  # confidence 1.0 falls in the last bin, whose upper edge is just above 1
    assert top["n"] == 5 and top["exact"] == pytest.approx(3 / 5) and top["right"] == pytest.approx(4 / 5)
    assert table[(0.0, 0.2)]["n"] == 1 and table[(0.0, 0.2)]["exact"] == 0.0
    assert sum(r["n"] for r in table.values()) == len(rows) and len(table) == len(BINS) - 1


def test_every_vocabulary_effect_is_concealed_by_both_generators():
    """The independent generator conceals every effect the tool can name (the flexible families
    under the names of the effects they hold); the own generator every textbook law."""
    from experiments.diagnose_concealed import expected_name
    from experiments.independent_recordings import NOT_CONCEALED
    from hyst_gym.diagnose import EFFECTS, GENERATOR_EFFECTS

    todo = cases(("own", "independent"), ("both",), 1, 100)
    independent = {expected_name(e) for g, _, e, inside, _ in todo if g == "independent" and inside}
    assert independent >= (set(EFFECTS) - set(NOT_CONCEALED)) | {"none"}
    assert {e for g, _, e, inside, _ in todo if g == "own" and inside} == set(GENERATOR_EFFECTS)


def test_speed_script_times_the_slowest_rows_alone():
    """The speed check picks, per generator and channel set, every seed of the effect of largest median study
    time (not the single slowest rows, whose times carry the study's load), and its summary names the slowest time
    alone with its record length and load."""
    from experiments.diagnose_speed import markdown, slowest_rows

    def row(ident, generator, channels, effect, seed, seconds):
        return {"id": ident, "generator": generator, "channels": channels, "effect": effect, "seed": str(seed),
                "seconds": str(seconds)}

    rows = [row("a", "own", "both", "rod", 101, 9.0), row("b", "own", "both", "rod", 100, 8.0),
            row("c", "own", "both", "rod", 102, 2.0),
            # one loaded row is the slowest single row, but its effect's median is lower
            row("d", "own", "both", "gain", 100, 30.0), row("e", "own", "both", "gain", 101, 1.0),
            row("f", "own", "both", "gain", 102, 1.0),
            row("g", "own", "magnetization", "heat", 100, 3.0), row("h", "own", "magnetization", "lag", 100, 2.0),
            row("i", "independent", "both", "lag", 100, 20.0), row("j", "independent", "both", "eddy", 100, 25.0)]
    # every seed of the slowest effect, in seed order, for each generator and channel set
    assert [r["id"] for r in slowest_rows(rows, 1)] == ["b", "a", "c", "g", "j"]
    assert {r["id"] for r in slowest_rows(rows, 2)} == set("abcdefghij")
    common = {"generator": "own", "channels": "both", "effect": "rod_dynamics", "seed": 100,
              "seconds_in_study": 30.0, "study_load_average": 5.0, "load_average_before": 1.0,
              "load_average_after": 1.2, "verdict": "rod_dynamics", "verdict_in_study": "rod_dynamics",
              "workers": 2}
    text = markdown([dict(common, samples=4000, seconds_alone=10.0), dict(common, samples=20000, seconds_alone=30.0)])
    assert text.rstrip().endswith("Largest time alone: 30.0 s (20,000 samples, 1-min load 1.0).")
    assert "| own/both | rod_dynamics | 100 | 20,000 | 2 | 30.0 |" in text


def test_before_after_pairs_the_same_recordings_and_rescores_with_one_yardstick():
    """Only recordings in both row sets are compared; an earlier `unexplained` on an effect that a family
    now names is not right under today's yardstick; `none` recordings flagged are counted."""
    from experiments.diagnose_concealed import before_after

    def row(effect, seed, verdict, generator="independent", channels="both"):
        return {"generator": generator, "channels": channels, "effect": effect, "seed": str(seed),
                "verdict": verdict, "tied": ""}

    before = [row("amplifier_saturation", 1, "unexplained"), row("none", 1, "unexplained"), row("none", 2, "none"),
              row("eddy_current", 1, "eddy_current"), row("eddy_current", 9, "none")]
    after = [row("amplifier_saturation", 1, "input_map"), row("none", 1, "none"), row("none", 2, "none"),
             row("eddy_current", 1, "sensor_lag")]
    (table,) = before_after(before, after)
    assert table["group"] == "independent/both" and table["n"] == 4
    assert table["right"] == [2, 3]            # before: none 2, eddy; after: input_map, none 1, none 2
    assert table["wrong_names"] == [0, 1]      # sensor_lag for eddy currents
    assert table["none_flagged"] == [1, 0] and table["none_n"] == 2 and table["changed"] == 3


def test_a_subset_of_effects_and_its_before_after_heading(tmp_path):
    """``--effects`` keeps only those effects' cases; a before/after table against rows other than the study's own
    earlier file names that file, not issue 22."""
    from experiments.diagnose_concealed import BEFORE, before_after_markdown

    todo = cases(("own",), ("magnetization", "both"), 3, 100, effects=("thermal_drift", "none"))
    assert {e for _, _, e, _, _ in todo} == {"thermal_drift", "none"} and len(todo) == 2 * 2 * 3
    table = [{"group": "own/both", "n": 1, "right": [1, 1], "wrong_names": [0, 0], "none_flagged": [0, 0],
              "none_n": 0, "changed": 0}]
    assert "issue 22" in before_after_markdown(table, BEFORE)[1]
    other = before_after_markdown(table, tmp_path / "concealed_study.csv")
    assert "issue 22" not in "\n".join(other) and f"`{tmp_path / 'concealed_study.csv'}`" in other[3]
