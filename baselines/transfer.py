"""Playing a policy in an environment whose observation layout differs from its training one.

The generalization experiments evaluate policies trained on
the first-order plant (observation ``output, field, elapsed, a_estimate, ...``) on the
FEM rod, whose observation starts with the tip ``displacement, velocity``. Both outputs
are normalized the same way by the environment (by their static value at M = Ms,
:func:`hyst_gym.envs.core.output_scales`), so the rod's tip displacement takes the place
of the first-order plant's ``y`` and the velocity, which the policy never saw, is dropped.
Every other entry (the estimator's state, the field, the elapsed time) keeps its meaning
across plants and is matched by name.
"""

from __future__ import annotations

import numpy as np

from .agents import Agent

#: entry of the training layout -> entries of another layout that may stand in for it
OBSERVATION_ALIASES = {"output": ("displacement",)}


def observation_map(trained_names, target_names) -> np.ndarray:
    """Indices into the target observation that rebuild the trained layout, in order.

    Raises ``ValueError`` naming the first trained entry the target has no match for.
    """
    target = list(target_names)
    index = []
    for name in trained_names:
        candidates = (name,) + OBSERVATION_ALIASES.get(name, ())
        match = next((c for c in candidates if c in target), None)
        if match is None:
            raise ValueError(f"the policy observes {name!r}, which the target environment does not provide "
                             f"(its observation has {target})")
        index.append(target.index(match))
    return np.asarray(index, dtype=np.int64)


class ObservationAdapter(Agent):
    """``agent`` fed with ``observations[:, index]`` (see :func:`observation_map`)."""

    def __init__(self, agent: Agent, index):
        super().__init__()
        self.agent = agent
        self.index = np.asarray(index, dtype=np.int64)
        self.name = getattr(agent, "name", "agent")

    def reset(self, seed=None):
        super().reset(seed)
        self.agent.reset(seed)

    def act_batch(self, observations, episode_start):
        return self.agent.act_batch(np.asarray(observations)[:, self.index], episode_start)


def adapt_agent(agent: Agent, trained_scenario, target_scenario, mode: str = "excitation") -> Agent:
    """``agent`` (trained in ``trained_scenario``) made to play in ``target_scenario``:
    unchanged when the two observation layouts agree, else an :class:`ObservationAdapter`."""
    from hyst_gym.envs.core import observation_names

    trained = observation_names(trained_scenario.env_config, mode)
    target = observation_names(target_scenario.env_config, mode)
    if trained == target:
        return agent
    return ObservationAdapter(agent, observation_map(trained, target))


__all__ = ["OBSERVATION_ALIASES", "observation_map", "ObservationAdapter", "adapt_agent"]
