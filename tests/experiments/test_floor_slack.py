"""experiments/floor_slack.py on tiny settings: it replays the committed agents of the two tasks that share a
floor (reproducing the committed held-out scores), and the plant checks that make their floors equal hold: the
same output gain and noise, and a displacement transducer whose mechanics settle within one sample."""

import json

from experiments.floor_slack import PAIR, main


def test_floor_slack_tiny(tmp_path):
    out = tmp_path / "slack.json"
    assert main(["--draws", "8", "--subset", "4", "--boot", "20", "--pair-only", "--out", str(out)]) == 0
    record = json.loads(out.read_text())
    noisy, displacement = (record["plants"][task] for task in PAIR)
    assert abs(noisy["output_gain_G"] / displacement["output_gain_G"] - 1.0) < 1e-9
    assert noisy["output_noise"] == displacement["output_noise"]
    assert displacement["largest_pole_per_step"] < 1e-3
    for task in PAIR:
        entry = record["tasks"][task]
        for agent in entry["agents"].values():
            assert abs(agent["replayed_heldout_rms"] / agent["committed_rms"] - 1.0) < 1e-6
            assert agent["ci"][0] <= agent["rms"] <= agent["ci"][1]
            assert agent["subsets_of_4"]["count"] == 2
    for paired in record["paired_displacement_minus_noisy"].values():
        assert paired["same_start_temperatures"]


def test_floor_slack_bad_arguments(capsys):
    assert main(["--draws", "1"]) == 2
    assert "error:" in capsys.readouterr().err
