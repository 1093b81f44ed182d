"""The benchmark's scenarios and its fixed seed sets.

A :class:`Scenario` fixes the environment settings, the common excitation limits and the
prior of a used by the optimal design. The environment keyword arguments are built by
:func:`env_kwargs` from plain values (and frozen, picklable physics dataclasses such as a
:class:`~hyst_gym.physics.FEMRod`) so that a scenario can be shipped to another process.
Scenarios with ``trained_in`` set are evaluation-only (generalization): they play the
schedules, designs and policies of another scenario.

Seeds: every agent is evaluated on :data:`HELDOUT_SEEDS` (50 draws of temperature, drift
and noise). Learning curves use :data:`VALIDATION_SEEDS`
and schedule tuning :data:`TUNING_SEEDS`; the three sets are disjoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from hyst_gym.physics import DEFAULT_BIAS_MAGNETIZATION, FEMRod

from .environment import EpisodeSpec
from .schedules import ExcitationLimits

HELDOUT_SEEDS = tuple(range(100_000, 100_050))
VALIDATION_SEEDS = tuple(range(200_000, 200_016))
TUNING_SEEDS = tuple(range(300_000, 300_010))

EXCITATION_ID = "hyst_gym/Excitation-v0"
ESTIMATION_ID = "hyst_gym/Estimation-v0"


@dataclass(frozen=True)
class Scenario:
    """One benchmark scenario.

    Attributes
    ----------
    name : str
    description : str
    settings : dict
        Environment settings, overrides of :class:`hyst_gym.envs.EnvConfig` fields.
    limits : ExcitationLimits
        Field (A/m), slew (A/m/s) limits and control period (s) shared by every agent.
    episode_s : float
        Episode length, s of simulated time.
    theta : (float, float)
        The parameter box Theta, A/m.
    nominal_a : float
        Nominal a, A/m (the paper's 7012).
    prior_a : tuple
        Quantiles of the prior of a over the scenario's temperature range, A/m (used by
        the prior-averaged optimal design).
    trained_in : str or None
        For evaluation-only (generalization) scenarios: the scenario whose tuned
        schedules, designs and trained policies are evaluated here.
    """

    name: str
    description: str
    settings: dict = field(default_factory=dict)
    limits: ExcitationLimits = ExcitationLimits()
    episode_s: float = 6.0
    theta: tuple = (6300.0, 7300.0)
    nominal_a: float = 7012.0
    prior_a: tuple = (7012.0,)
    trained_in: str | None = None

    @property
    def source(self) -> str:
        """Name of the scenario whose artifacts (tuning, designs, policies) are used."""
        return self.trained_in or self.name

    @property
    def episode_steps(self) -> int:
        return int(round(self.episode_s / self.limits.dt))

    @cached_property
    def env_config(self):
        """The scenario's :class:`hyst_gym.envs.EnvConfig`, built and validated once: the agents,
        the observation readers and the transfer checks all read this one (``settings`` is
        not changed after construction). Imported here, so a scenario ships to another
        process without the envs layer."""
        from hyst_gym.envs.config import make_config

        return make_config(**self.settings)

    def spec(self, env_id: str = EXCITATION_ID) -> EpisodeSpec:
        return EpisodeSpec(env_id, env_kwargs(self, env_id), self.limits.dt)


def env_kwargs(scenario: Scenario, env_id: str) -> dict:
    """Keyword arguments for ``gymnasium.make(env_id, ...)`` in this scenario.

    They are overrides of :class:`hyst_gym.envs.EnvConfig` fields, in plain values.
    """
    return dict(scenario.settings)


_PAPER_LIMITS = ExcitationLimits(field_max=1.0e5, slew_max=5.0e4, dt=0.01)
_DRIFT_LIMITS = ExcitationLimits(field_max=1.0e5, slew_max=5.0e4, dt=0.05)
_PAPER = {"temperature_mode": "fixed", "a_true": 7012.0, "initial_estimate": 6990.0, "dt": 0.01,
          "episode_steps": 1000, "field_limit": 1.0e5, "slew_rate_limit": 5.0e4}
_DRIFT = {"temperature_mode": "drifting", "initial_estimate": 6990.0, "dt": 0.05, "episode_steps": 1200,
          "field_limit": 1.0e5, "slew_rate_limit": 5.0e4}
#: The temperature prior of a: a(T) over the default initial temperatures 278.15..298.15 K
#: plus heating (EnvConfig docs). The paper and lumped scenarios fix a = 7012, but their
#: prior-averaged design is still robust to this range (what one would use before knowing T).
_DRIFT_PRIOR = tuple(float(a) for a in np.linspace(6653.0, 7250.0, 5))

SCENARIOS = {
    "paper": Scenario("paper", "Paper §4.1: first-order plant, a = 7012 fixed, thetahat(0) = 6990, 10 s",
                      _PAPER, _PAPER_LIMITS, 10.0, prior_a=_DRIFT_PRIOR),
    "drift": Scenario("drift", "Joule heating and ambient drift (5..25 C start, +-0.05 K/s), 60 s episodes",
                      _DRIFT, _DRIFT_LIMITS, 60.0, prior_a=_DRIFT_PRIOR),
    "lumped": Scenario("lumped", "Lumped transducer (13), vector estimator (24)-(25), a = 7012 fixed, 10 s",
                       {**_PAPER, "transducer": "lumped"}, _PAPER_LIMITS, 10.0, prior_a=_DRIFT_PRIOR),
    # generalization (evaluation only): policies trained in "drift"
    "drift_hot": Scenario("drift_hot", "Drift, started outside the training range (27..32 C)",
                          {**_DRIFT, "initial_temperature_range": (300.15, 305.15)}, _DRIFT_LIMITS, 60.0,
                          prior_a=_DRIFT_PRIOR, trained_in="drift"),
    "drift_noisy": Scenario("drift_noisy", "Drift with 10x the output noise", {**_DRIFT, "output_noise": 1e-3},
                            _DRIFT_LIMITS, 60.0, prior_a=_DRIFT_PRIOR, trained_in="drift"),
    # generalization (evaluation only): policies trained in "paper", played on the FEM rod (10)
    # whose estimator assumes the lumped model (13) (hyst_gym.envs.core.estimator_plant)
    "paper_fem": Scenario("paper_fem", "Paper case on the 16-element FEM rod linearized about the bias; "
                          "the vector estimator assumes the lumped model (13)",
                          {**_PAPER, "transducer": FEMRod(bias_magnetization=DEFAULT_BIAS_MAGNETIZATION)},
                          _PAPER_LIMITS, 10.0, prior_a=_DRIFT_PRIOR, trained_in="paper"),
    "paper_fem_nonlinear": Scenario("paper_fem_nonlinear", "Paper case on the FEM rod with the quadratic "
                                    "force zeta*M**2 of (10) and no bias; the estimator assumes (13)",
                                    {**_PAPER, "transducer": FEMRod()}, _PAPER_LIMITS, 10.0,
                                    prior_a=_DRIFT_PRIOR, trained_in="paper"),
}
#: scenarios a policy can be trained in (the others are evaluation-only)
TRAINING_SCENARIOS = tuple(name for name, scenario in SCENARIOS.items() if scenario.trained_in is None)

__all__ = ["HELDOUT_SEEDS", "VALIDATION_SEEDS", "TUNING_SEEDS", "EXCITATION_ID", "ESTIMATION_ID", "Scenario",
           "SCENARIOS", "TRAINING_SCENARIOS", "env_kwargs", "scenario_spec"]


def scenario_spec(name: str, env_id: str = EXCITATION_ID) -> EpisodeSpec:
    try:
        return SCENARIOS[name].spec(env_id)
    except KeyError:
        raise ValueError(f"unknown scenario {name!r}; expected one of {sorted(SCENARIOS)}") from None
