"""A benchmark task's description (:class:`TaskSpec`), the priors a task draws per episode, and the
table of task kinds: ``{kind: (single env class, vector env class)}``.

This module imports nothing of the env classes (the table names them as ``"module:Class"`` strings),
so the preset modules (:mod:`.suite_v1`, :mod:`.suite_v2`) and :mod:`.tasks` (the one id list) can
import it without a cycle.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

#: task kind -> (single env, vector env), as "module:Class" (imported when a task is made). Every class
#: takes the task id: ``Env(task, render_mode=None, **overrides)`` and ``VectorEnv(num_envs, task, **overrides)``
#: (overrides: EnvConfig fields, and the vector env's ``max_episode_steps``, ``autoreset_mode``, ``render_mode``).
KINDS = {
    "excite": ("hyst_gym.envs.suite_v1:SuiteExcitationEnv", "hyst_gym.envs.suite_v1:SuiteExcitationVectorEnv"),
    "calibrate": ("hyst_gym.envs.suite_v2:HotCalibrateEnv", "hyst_gym.envs.suite_v2:HotCalibrateVectorEnv"),
    "calibrate_unknown_k": ("hyst_gym.envs.suite_v2:HotCalibrateUnknownKEnv",
                            "hyst_gym.envs.suite_v2:HotCalibrateUnknownKVectorEnv"),
    "jump": ("hyst_gym.envs.suite_v2:DriftJumpEnv", "hyst_gym.envs.suite_v2:DriftJumpVectorEnv"),
    "dual_control": ("hyst_gym.envs.dual_control:DualControlEnv", "hyst_gym.envs.dual_control:DualControlVectorEnv"),
    "discriminate": ("hyst_gym.envs.discriminate:DiscriminateEnv", "hyst_gym.envs.discriminate:DiscriminateVectorEnv"),
}
#: the kinds whose agent-facing job is calibration (the metric is the RMS error of a over the scored steps)
CALIBRATION_KINDS = ("calibrate", "calibrate_unknown_k")
#: the start-temperature shapes a task may draw from (the simulator's ``temperature_prior``)
TEMPERATURE_PRIORS = ("uniform", "raised_cosine")


@dataclass(frozen=True)
class PinningPrior:
    """Uniform prior of the pinning constant k of model (6) over ``[low, high]`` (A/m, ``0 < low < high``),
    drawn per episode by the simulator: ``k = low + (high - low)*u`` with u uniform from the sub-env's
    episode generator, drawn after the simulator's other draws of that sub-env."""

    low: float
    high: float

    def __post_init__(self):
        for name in ("low", "high"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
                raise ValueError(f"PinningPrior: {name} must be a finite number > 0 (A/m), got {value!r}")
        if not self.low < self.high:
            raise ValueError(f"PinningPrior: high must exceed low, got low={self.low!r}, high={self.high!r}")

    def nodes(self, count: int) -> np.ndarray:
        """``count`` midpoints of equal cells over the support (A/m)."""
        return self.low + (self.high - self.low) * (np.arange(count) + 0.5) / count

    def draw(self, u: float) -> float:
        """k (A/m) at the uniform number ``u`` in [0, 1)."""
        return self.low + (self.high - self.low) * u


@dataclass(frozen=True)
class TaskSpec:
    """One benchmark task behind a registered, versioned id.

    ``id``: the Gymnasium id; ``suite``: ``"v1"`` or ``"v2"``; ``kind``: a key of :data:`KINDS` (which
    env classes play it); ``family``: the story family; ``difficulty``: 1 = easiest (0: a rejected
    candidate, registered so its measurement can be repeated); ``config``: EnvConfig overrides (read-only);
    ``sensors_hidden``: observation entries hidden from the agent; ``k_prior``: a :class:`PinningPrior`
    (None: k fixed at the preset's); ``temperature_prior``: the start-temperature shape over
    ``initial_temperature_range`` (one of :data:`TEMPERATURE_PRIORS`); ``scored_from``: the first step
    (0-based) of the task metric; ``candidate``: True for a candidate the suite measured and rejected early.
    """

    id: str
    suite: str
    kind: str
    family: str
    description: str
    difficulty: int
    config: Mapping = field(default_factory=dict)
    sensors_hidden: tuple = ()
    k_prior: PinningPrior | None = None
    temperature_prior: str = "uniform"
    scored_from: int = 0
    rejected: bool = False

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"TaskSpec {self.id!r}: kind must be one of {sorted(KINDS)}, got {self.kind!r}")
        if (self.kind == "calibrate_unknown_k") != (self.k_prior is not None):
            raise ValueError(f"TaskSpec {self.id!r}: a k prior needs kind 'calibrate_unknown_k', and that kind "
                             "a k prior")
        if self.temperature_prior not in TEMPERATURE_PRIORS:
            raise ValueError(f"TaskSpec {self.id!r}: temperature_prior must be one of {TEMPERATURE_PRIORS}, "
                             f"got {self.temperature_prior!r}")
        object.__setattr__(self, "config", MappingProxyType(dict(self.config)))
        object.__setattr__(self, "sensors_hidden", tuple(self.sensors_hidden))

    @property
    def calibrates(self) -> bool:
        """Whether the task is a calibration (kind in :data:`CALIBRATION_KINDS`)."""
        return self.kind in CALIBRATION_KINDS

    @property
    def slug(self) -> str:
        """The id without the ``hyst_gym/`` namespace."""
        return self.id.split("/")[-1]

    def env_config(self, **overrides):
        """The task's :class:`~hyst_gym.envs.config.EnvConfig` (with ``overrides``)."""
        from .config import make_config

        return make_config(**{**self.config, **overrides})

    def simulator_priors(self) -> dict:
        """The keywords of :class:`~hyst_gym.envs.core.BatchSimulator` that draw the task's episodes."""
        return {"temperature_prior": self.temperature_prior, "pinning_prior": self.k_prior}


__all__ = ["CALIBRATION_KINDS", "KINDS", "TEMPERATURE_PRIORS", "PinningPrior", "TaskSpec"]
