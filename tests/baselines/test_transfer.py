"""Playing a first-order-plant policy on the FEM rod (baselines/transfer.py)."""

import numpy as np
import pytest

from baselines.agents import Agent
from baselines.evaluation import run_episodes
from baselines.scenarios import SCENARIOS
from baselines.transfer import ObservationAdapter, adapt_agent, observation_map
from hyst_gym.envs.core import observation_names


class _Recorder(Agent):
    """Holds a fixed field command and records what it was shown."""

    def __init__(self):
        super().__init__()
        self.seen = []

    def act_batch(self, observations, episode_start):
        self.seen.append(np.array(observations))
        return np.full((observations.shape[0], 1), 0.5, dtype=np.float32)


def test_map_matches_by_name_and_puts_the_tip_displacement_in_place_of_y():
    trained = ["output", "field", "elapsed", "a_estimate"]
    target = ["displacement", "velocity", "field", "elapsed", "a_estimate"]
    assert observation_map(trained, target).tolist() == [0, 2, 3, 4]
    assert observation_map(target[2:], target[2:]).tolist() == [0, 1, 2]
    with pytest.raises(ValueError, match="'temperature'"):
        observation_map(["field", "temperature"], target)


def test_same_layout_is_left_alone():
    agent = _Recorder()
    assert adapt_agent(agent, SCENARIOS["paper"], SCENARIOS["drift"]) is agent


def test_policy_of_the_first_order_plant_sees_its_own_layout_on_the_fem_rod():
    paper, fem = SCENARIOS["paper"], SCENARIOS["paper_fem"]
    trained = observation_names(paper.env_config, "excitation")
    target = observation_names(fem.env_config, "excitation")
    assert len(target) == len(trained) + 1  # the rod also reports the tip velocity

    direct, inner = _Recorder(), _Recorder()
    adapted = adapt_agent(inner, paper, fem)
    assert isinstance(adapted, ObservationAdapter)
    seeds = [5, 6]
    records_direct, _ = run_episodes(direct, fem.spec(), seeds)
    records_adapted, _ = run_episodes(adapted, fem.spec(), seeds)
    # the adapter only changes what the agent sees: same actions, same episodes
    assert records_direct == records_adapted
    for full, shown in zip(direct.seen, inner.seen):
        assert shown.shape == (2, len(trained))
        assert np.array_equal(shown[:, 0], full[:, target.index("displacement")])
        for name in trained[1:]:
            assert np.array_equal(shown[:, trained.index(name)], full[:, target.index(name)])
