"""The dual-control agents (probe burst, probe while unsure) and the dual-control measurement script."""

import json

import numpy as np
import pytest

from baselines.dual_control_agents import ProbeBurst, ProbeWhileUnsure


def test_probe_burst_is_a_square_wave_for_its_steps_then_nothing():
    agent = ProbeBurst(0.01, 6, half_period=2)
    agent.reset(0)
    obs = np.zeros((2, 6))
    start = np.array([True, True])
    actions = []
    for _ in range(9):
        actions.append(agent.predict(obs, episode_start=start)[0][:, 0])
        start = np.array([False, False])
    actions = np.array(actions)
    assert np.allclose(actions[:, 0], [0.01, 0.01, -0.01, -0.01, 0.01, 0.01, 0.0, 0.0, 0.0])
    assert ProbeBurst(0.0, 0).name == "no_probe"
    with pytest.raises(ValueError, match="amplitude must be in"):
        ProbeBurst(2.0, 3)


def test_probe_while_unsure_stops_once_the_spread_is_small():
    agent = ProbeWhileUnsure(spread_index=4, threshold=0.05, amplitude=0.01)
    agent.reset(0)
    obs = np.zeros((2, 6))
    obs[:, 4] = [0.1, 0.01]
    action, _ = agent.predict(obs, episode_start=np.array([True, True]))
    assert action[0, 0] == pytest.approx(0.01) and action[1, 0] == 0.0


def test_the_script_measures_the_floor_below_no_probe_and_refuses_bad_arguments(tmp_path, capsys):
    from experiments.suite import dual_control

    assert dual_control.main(["--heldout", "0"]) == 2
    assert "--heldout, --tuning and --bootstrap must be >= 1" in capsys.readouterr().err
    assert dual_control.main(["--heldout", "3", "--tuning", "2", "--bootstrap", "50", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "suite_v2_dual_control.json").read_text())
    floor, agents = data["floor"], data["agents"]
    # the oracle controller (true a, no probe) tracks better than the same controller with the nominal a and
    # than the posterior with no probe, draw by draw
    assert np.all(np.array(floor["per_draw"]) <= np.array(agents["no_probe"]["per_draw"]))
    assert floor["rms"] < agents["nominal_a"]["rms"]
    point = data["verdict"]["working_point"]
    assert abs(point["magnetization_percent_Ms"] - 40.0) < 0.5
    assert 0 < point["per_percent_of_a_percent_Ms"] < point["probe_percent_Ms"]
    assert "Dual control measured" in (tmp_path / "suite_v2_dual_control.md").read_text()
