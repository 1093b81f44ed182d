"""Agents of the benchmark suite v1 (``hyst_gym.envs.suite_v1``): inputs, a thermostat, an oracle.

Every agent here is a :class:`DesignBank`: one *design* per sub-environment, so the
same object plays one design on many draws (the held-out evaluation) or many designs on
one draw (the oracle's per-draw search). A design is

* an open-loop field sequence ``H_t`` (A/m, already slew- and field-limited by
  :func:`~baselines.schedules.apply_limits`), and
* an optional thermostat: while the coil temperature it reads is above
  ``temperature_limit - margin`` (K) the command is 0 (the coil cools), else ``H_t``; or,
  with ``span`` (K) set, a proportional rule: the command is ``H_t`` scaled by
  ``clip((temperature_limit - margin - T)/span, 0, 1)``, so the input grows with the
  thermal budget it reads (full at ``span`` K below the switch-off point);
* an optional identification gate (``gate`` set): the command is scaled by ``tail`` while
  the design judges a identified. The feedback rule reads the estimator's tuning error from
  the observation (identified while its normalized magnitude is at most ``gate``, i.e. the
  min-max law has nothing left to adapt: excite until the estimator is tuned, then idle); the
  clairvoyant version reads the true error (identified while |a_estimate - a_true| <= ``gate``
  A/m).
  The temperature is read either from the estimate (``a`` is proportional to T, eq. (4):
  ``T_hat = T_ref*a_hat/a_ref``, a feedback rule that needs no sensor) or, for the
  clairvoyant oracle only, from the true temperature in ``info`` (``reads_truth``).

The thermostat's timing follows its own episode step count, like a
:class:`~baselines.agents.ScheduleAgent`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .agents import Agent
from .schedules import ExcitationLimits, Ramp, Schedule, apply_limits


@dataclass(frozen=True)
class Design:
    """One input: ``schedule`` (a :class:`~baselines.schedules.Schedule`), and a thermostat
    margin in K (``None``: open loop), reading the estimate or (``truth``) the true temperature;
    ``span`` (K) makes the thermostat proportional (see the module doc)."""

    name: str
    schedule: Schedule
    margin: float | None = None
    truth: bool = False
    span: float | None = None
    gate: float | None = None
    tail: float = 0.1

    @property
    def kind(self) -> str:
        if self.margin is None and self.gate is None:
            return "open_loop"
        return "oracle" if self.truth else "feedback"


@dataclass(frozen=True)
class RampDither(Schedule):
    """A ramp to ``peak`` A/m in ``duration`` s, then a dither ``dither*sin(2 pi f (t - duration))``
    about it (A/m, Hz): go to a sensitive field once, then keep the material moving on minor loops."""

    peak: float = 5.0e4
    duration: float = 1.5
    dither: float = 1.0e4
    frequency: float = 0.5
    name = "ramp_dither"

    def field(self, time):
        time = np.asarray(time, dtype=np.float64)
        after = np.maximum(time - self.duration, 0.0)
        return Ramp(self.peak, self.duration).field(time) + self.dither * np.sin(2 * np.pi * self.frequency * after)


class DesignBank(Agent):
    """Plays ``designs[i]`` in sub-environment ``i`` (or one design everywhere when given one).

    ``config`` is the task's :class:`~hyst_gym.envs.config.EnvConfig` (limits, Theta, the
    a(T) law and the temperature limit); ``estimate_index`` is where the observation holds
    the normalized a_estimate.
    """

    name = "design_bank"

    def __init__(self, designs, config, estimate_index: int, horizon_steps: int | None = None):
        super().__init__()
        self.designs = tuple(designs)
        self.config = config
        self.estimate_index = int(estimate_index)
        steps = horizon_steps or config.episode_steps
        limits = ExcitationLimits(config.field_limit, config.slew_rate_limit, config.dt)
        time = config.dt * np.arange(1, steps + 1)
        self._commands = np.array([apply_limits(d.schedule.field(time), limits) for d in self.designs])
        self._margin = np.array([np.inf if d.margin is None else d.margin for d in self.designs])
        self._truth = np.array([d.truth for d in self.designs])
        self._span = np.array([0.0 if d.span is None else d.span for d in self.designs])
        self._gate = np.array([np.nan if d.gate is None else d.gate for d in self.designs])
        self._tail = np.array([d.tail for d in self.designs])
        from hyst_gym.envs.core import EXCITATION, observation_names

        self.tuning_index = observation_names(config, EXCITATION).index("tuning_error")
        self.reads_truth = bool(self._truth.any())
        self._steps = np.zeros(0, dtype=np.int64)
        self._temperature = None
        self._error = None
        if len(self.designs) == 1:
            self.name = self.designs[0].name

    def reset(self, seed=None):
        super().reset(seed)
        self._steps = np.zeros(0, dtype=np.int64)
        self._temperature = None
        self._error = None

    def observe(self, infos) -> None:
        """The clairvoyant designs read the true temperature and estimation error of the last step."""
        self._temperature = np.asarray(infos["temperature"], dtype=np.float64)
        self._error = np.abs(np.asarray(infos["a_estimate"], dtype=np.float64) -
                             np.asarray(infos["a_true"], dtype=np.float64))

    def _rows(self, n):
        if len(self.designs) == 1:
            return np.zeros(n, dtype=np.int64)
        if len(self.designs) != n:
            raise ValueError(f"DesignBank has {len(self.designs)} designs for {n} sub-environments")
        return np.arange(n)

    def act_batch(self, observations, episode_start):
        config = self.config
        n = observations.shape[0]
        if self._steps.shape[0] != n:
            self._steps = np.zeros(n, dtype=np.int64)
        self._steps[episode_start] = 0
        rows = self._rows(n)
        index = np.minimum(self._steps, self._commands.shape[1] - 1)
        command = self._commands[rows, index]
        self._steps += 1
        gated = np.isfinite(self._margin[rows])
        if gated.any():
            estimate = config.theta_min + 0.5 * (observations[:, self.estimate_index] + 1.0) * config.theta_width
            temperature = config.thermal.reference_temperature * estimate / config.thermal.a_reference
            if self._truth[rows].any():
                if self._temperature is None:
                    raise ValueError("a clairvoyant design needs observe(infos) before each action")
                temperature = np.where(self._truth[rows], self._temperature, temperature)
            budget = config.temperature_limit - self._margin[rows] - temperature
            span = self._span[rows]
            scale = np.where(span > 0, np.clip(budget / np.where(span > 0, span, 1.0), 0.0, 1.0),
                             (budget >= 0).astype(np.float64))
            command = np.where(gated, command * scale, command)
        gate = self._gate[rows]
        identifying = np.isfinite(gate)
        if identifying.any():
            tuned = np.abs(observations[:, self.tuning_index]) <= np.nan_to_num(gate)
            truth = self._truth[rows] & identifying
            if truth.any():
                if self._error is None:
                    raise ValueError("a clairvoyant design needs observe(infos) before each action")
                tuned = np.where(truth, self._error <= np.nan_to_num(gate), tuned)
            command = np.where(identifying & tuned, command * self._tail[rows], command)
        return (command / config.field_limit).reshape(n, 1).astype(np.float32)


__all__ = ["Design", "DesignBank", "RampDither"]
