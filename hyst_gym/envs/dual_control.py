"""Dual control (identify while working): the milling actuator tracks a displacement reference through an
inverse-compensation controller that uses the current estimate of a; the agent adds a probe to the field.

Each control step of a sub-env (the plant, the heating and the noise are the calibration tasks', the
:class:`~.core.BatchSimulator` in ``Identification`` mode):

1. the task's estimator (the grid posterior over the start temperature,
   :class:`~.posterior.GridPosterior`) takes in the last measured output and reports its estimate
   ``a_hat`` of a;
2. the controller asks model (6) with ``a_hat`` (its own copy of the magnetization, driven by the applied
   field) for the field that brings M to the reference's magnetization at the end of the step
   (:func:`inverse_fields`: Newton steps on the model's dM/dH, within the slew and field limits);
3. the agent's action, a probe of ``action*field_limit`` A/m, is added to that command (the sum clipped to
   the field limit); the simulator applies it through the slew limit, heats the coil and measures;
4. the score of the step is the tracking error of the *noise-free* output against the reference, in
   percent of the output at M = Ms.

The reference is a slow milling stroke (:class:`MillingReference`); the first-order plant
``y' = -lambda*y + nu*M`` is inverted exactly for it (``M_ref/Ms = r + r'/lambda``, r the normalized
reference), so with ``a_hat = a`` the error left is the controller's own (one step of Newton on a
discretized model, the slew limit). A wrong ``a_hat`` biases the field the controller asks for; a probe
teaches the estimator faster but moves the output off the reference: probing costs tracking error.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from gymnasium.vector import AutoresetMode

from ..physics import FirstOrderPlant
from ..physics.background_compile import background_kernel
from ..physics.hysteresis import advance_one, magnetization_slope
from .core import IDENTIFICATION, INFO_KEYS, BatchSimulator
from .posterior import GridPosterior
from .vector_single import SingleOfVector, TaskVectorEnv
from .vector import seed_sub_envs

#: Newton steps of the inverse controller per control step (two leave < 1e-6 Ms of model error at full slew)
NEWTON_STEPS = 3
#: the tracking error's unit: percent of the output at M = Ms
PERCENT = 100.0
#: the tracking error charged for every scored step left after an overheat (percent of the output at Ms)
OVERHEAT_ERROR = 100.0
#: where the controller's estimate comes from: the task's estimator, the truth (the oracle controller), or the
#: preset's ``initial_estimate`` throughout (no learning: what identifying a is worth to the tracking)
CONTROLLER_ESTIMATES = ("posterior", "true", "nominal")
#: the extra info keys of a dual-control step
DUAL_INFO_KEYS = ("tracking_error", "reference", "controller_estimate")


@dataclass(frozen=True)
class MillingReference:
    """The displacement reference of the milling job, normalized by the output at M = Ms: a smooth ramp
    (``ramp_s`` seconds, a cosine blend) from 0 to ``bias``, then ``bias + amplitude*sin(2 pi t/period_s)``
    (the tool's feed oscillation) blended in over the same ramp. ``bias``, ``amplitude``: dimensionless
    (fractions of the output at Ms); ``period_s``, ``ramp_s``: s."""

    bias: float = 0.4
    amplitude: float = 0.15
    period_s: float = 2.0
    ramp_s: float = 2.0

    def __post_init__(self):
        for name in ("bias", "amplitude", "period_s", "ramp_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise ValueError(f"MillingReference: {name} must be a finite number >= 0, got {value!r}")
        if self.period_s <= 0 or self.ramp_s <= 0:
            raise ValueError("MillingReference: period_s and ramp_s must be > 0")
        if self.bias + self.amplitude >= 1.0 or self.bias - self.amplitude < 0.0:
            raise ValueError("MillingReference: the reference must stay in [0, 1) (bias +- amplitude), got "
                             f"bias={self.bias!r}, amplitude={self.amplitude!r}")

    def _blend(self, t):
        """(w, dw/dt) of the cosine ramp: 0 at t = 0, 1 from ``ramp_s`` on."""
        s = np.clip(np.asarray(t, dtype=np.float64) / self.ramp_s, 0.0, 1.0)
        inside = (s > 0.0) & (s < 1.0)
        w = 0.5 - 0.5 * np.cos(np.pi * s)
        dw = np.where(inside, 0.5 * np.pi * np.sin(np.pi * s) / self.ramp_s, 0.0)
        return w, dw

    def output(self, t) -> np.ndarray:
        """The normalized reference at times ``t`` (s)."""
        w, _ = self._blend(t)
        omega = 2.0 * np.pi / self.period_s
        return w * (self.bias + self.amplitude * np.sin(omega * np.asarray(t, dtype=np.float64)))

    def slope(self, t) -> np.ndarray:
        """d(output)/dt at times ``t`` (1/s)."""
        t = np.asarray(t, dtype=np.float64)
        w, dw = self._blend(t)
        omega = 2.0 * np.pi / self.period_s
        return dw * (self.bias + self.amplitude * np.sin(omega * t)) + w * self.amplitude * omega * np.cos(omega * t)

    def magnetization(self, t, decay_rate: float) -> np.ndarray:
        """M_ref/Ms that makes the first-order plant ``y' = -lambda*y + nu*M`` (``decay_rate`` = lambda, 1/s)
        follow the reference exactly: ``r + r'/lambda`` (y normalized by its static value at Ms, nu Ms/lambda)."""
        return self.output(t) + self.slope(t) / decay_rate


class ControllerModel(NamedTuple):
    """The constants of the controller's own copy of model (6) (named state for the compiled controller):
    ``alpha`` (dimensionless), ``Ms`` (A/m), ``c`` (dimensionless), ``kind`` (the anhysteretic curve's code),
    ``max_field_step`` (A/m, the model's substep)."""

    alpha: float
    Ms: float
    c: float
    kind: int
    max_field_step: float


@background_kernel(error_model="numpy")
def inverse_fields(field, model_m, target_m, a_hat, k, model, max_change, field_limit, out):
    """The inverse-compensation controller: per sub-env b, the field (A/m) that moves model (6) with
    ``a_hat[b]`` from (``field[b]``, ``model_m[b]``) to ``target_m[b]`` (A/m), by :data:`NEWTON_STEPS` Newton
    steps on the model's own M(H) (each evaluated by the model's substeps), kept within the slew
    (``max_change``) and the field limit. Writes ``out``."""
    for b in range(field.shape[0]):
        start = field[b]
        low = max(start - max_change, -field_limit)
        high = min(start + max_change, field_limit)
        trial = start
        for _ in range(NEWTON_STEPS):
            m_trial, _ = advance_one(model_m[b], start, trial, a_hat[b], k[b], model.alpha, model.Ms, model.c,
                                     model.kind, model.max_field_step)
            gap = target_m[b] - m_trial
            if gap == 0.0:
                break
            direction = 1.0 if trial > start else (-1.0 if trial < start else (1.0 if gap > 0.0 else -1.0))
            slope = magnetization_slope(trial, m_trial, direction, a_hat[b], k[b], model.alpha, model.Ms, model.c,
                                        model.kind)
            if not slope > 0.0:
                break
            trial = min(max(trial + gap / slope, low), high)
        out[b] = trial


@background_kernel(error_model="numpy")
def advance_models(model_m, field_from, field_to, a_hat, k, model):
    """The controller's model (6) with ``a_hat`` moved along the applied field, in place."""
    for b in range(model_m.shape[0]):
        model_m[b], _ = advance_one(model_m[b], field_from[b], field_to[b], a_hat[b], k[b], model.alpha, model.Ms,
                                    model.c, model.kind, model.max_field_step)


#: the milling job's reference of ``hyst_gym/DualControl-v0``
MILLING_REFERENCE = MillingReference()


class DualControlVectorEnv(TaskVectorEnv):
    """Native vector env of ``hyst_gym/DualControl-v0`` (see :class:`DualControlEnv`, whose page this is
    too). Autoreset ``NEXT_STEP`` (default) or ``DISABLED``; ``SAME_STEP`` is refused (a ValueError)."""

    def __init__(self, num_envs: int = 1, task: str = "hyst_gym/DualControl-v0",
                 controller_estimate: str = "posterior", posterior_nodes: int | None = None,
                 autoreset_mode=AutoresetMode.NEXT_STEP, **overrides):
        if controller_estimate not in CONTROLLER_ESTIMATES:
            raise ValueError(f"controller_estimate must be one of {CONTROLLER_ESTIMATES}, got {controller_estimate!r}")
        config = self._setup(num_envs, task, "dual_control", autoreset_mode, overrides)
        if not isinstance(config.transducer, FirstOrderPlant):
            raise ValueError(f"{task!r}: the dual-control task inverts the first-order plant; transducer "
                             f"{config.transducer_name!r} is not supported")
        self.reference = MILLING_REFERENCE
        self.controller_estimate = controller_estimate
        n = self.num_envs
        self.sim = BatchSimulator(config, IDENTIFICATION, n, **self.spec_.simulator_priors())
        self.posterior = GridPosterior(config, [0], n, None, posterior_nodes)
        hyst = config.hysteresis
        self._controller_model = ControllerModel(float(hyst.alpha), float(hyst.Ms), float(hyst.c), int(hyst.kind),
                                                 float(config.max_field_step))
        self._model_m = np.zeros(n)
        self._command_field = np.zeros(n)
        self._field_before = np.zeros(n)
        self._controller_a = np.full(n, config.initial_estimate)
        self._measured = np.zeros((n, 1))
        self._fresh = np.ones(n, dtype=bool)
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._tracking = np.zeros(n)
        self._reference_now = np.zeros(n)
        self._spaces(["output", "field", "elapsed", "a_estimate", "estimate_spread", "reference_next"],
                     [-2.0, -1.0, 0.0, -1.0, 0.0, 0.0], [2.0, 1.0, 1.0, 1.0, 1.0, 1.0])

    # ---------------------------------------------------------------- episodes

    def reset(self, *, seed=None, options=None):
        """Reset every sub-env (``seed`` as the native vector envs: an int gives sub-env i ``seed + i``)."""
        seed_sub_envs(self, seed)
        self._restart(self._all, options)
        self._autoreset[:] = False
        return self._observation(), self._infos()

    def _restart(self, rows, options=None) -> None:
        self.sim.reset(rows, options)
        self.posterior.restart(rows)
        self._fresh[rows] = True
        self._model_m[rows] = 0.0
        self._elapsed[rows] = 0
        self._tracking[rows] = 0.0
        self._reference_now[rows] = 0.0
        self._controller_a[rows] = self.config.initial_estimate
        self._measured[rows, 0] = self.sim.measured[rows, 0] / self.sim.scales[0]

    # ---------------------------------------------------------------- stepping

    def _reference_next(self) -> np.ndarray:
        return self.reference.output((self.sim.steps + 1) * self.config.dt)

    def _controller(self, skip) -> np.ndarray:
        """The estimator's update with the last output, then the controller's estimate (A/m) per sub-env."""
        going = ~self._fresh & ~skip
        self.posterior.advance(self._measured, np.flatnonzero(going), None)
        self._fresh[:] = False
        if self.controller_estimate == "true":
            return self.sim.a_true.copy()
        if self.controller_estimate == "nominal":
            return np.full(self.num_envs, self.config.initial_estimate)
        return self.posterior.estimate()

    def step(self, actions):
        config, sim = self.config, self.sim
        actions, resetting = self._begin_step(actions, "the probe / field_limit")
        a_hat = self._controller(resetting)
        self._controller_a[:] = a_hat
        t_next = (sim.steps + 1) * config.dt
        target = self.reference.magnetization(t_next, config.transducer.decay_rate) * config.hysteresis.Ms
        pinning = sim.pinning
        inverse_fields(sim.field, self._model_m, target, a_hat, pinning, self._controller_model,
                       config.max_field_change, config.field_limit, self._command_field)
        probe = actions[:, 0] * config.field_limit
        command = np.clip((self._command_field + probe) / config.field_limit, -1.0, 1.0)
        command[resetting] = 0.0
        self.posterior.advance(None, np.zeros(0, dtype=np.int64), command)
        full = np.empty((self.num_envs, 2))
        full[:, 0] = command
        full[:, 1] = np.clip(2.0 * (a_hat - config.theta_min) / config.theta_width - 1.0, -1.0, 1.0)
        self._field_before[:] = sim.field
        _, terminated, truncated = sim.step_views(full, active=~resetting if resetting.any() else None)
        terminated, truncated = terminated.copy(), truncated.copy()
        advance_models(self._model_m, self._field_before, sim.field, a_hat, pinning, self._controller_model)
        self._measured[:, 0] = sim.measured[:, 0] / sim.scales[0]
        self._reference_now[:] = self.reference.output(sim.steps * config.dt)
        true_output = (sim.state[:, sim.model.output_index] + sim.model.output_offset) / sim.scales[0]
        self._tracking[:] = PERCENT * np.abs(true_output - self._reference_now)
        reward = self._reward(terminated)
        self._end_step(reward, terminated, truncated, resetting)
        return self._observation(), reward, terminated, truncated, self._infos()

    def _reward(self, terminated) -> np.ndarray:
        """Minus the squared tracking error (percent of the output at Ms) over the episode's steps, and at an
        overheat :data:`OVERHEAT_ERROR` squared for every step left: the episode's return is minus the mean
        square tracking error, the task's per-draw score."""
        total = self.config.episode_steps
        self._elapsed += 1
        reward = -self._tracking ** 2
        reward = reward - np.where(terminated, (total - self._elapsed) * OVERHEAT_ERROR ** 2, 0.0)
        return reward / total

    # ---------------------------------------------------------------- what the agent sees

    def _observation(self) -> np.ndarray:
        config = self.config
        full = self.sim.observation()  # output, field, elapsed, previous_estimate (the controller's a_hat)
        spread = np.minimum(self.posterior.spread() / config.theta_width, 1.0)
        reference = np.clip(self._reference_next(), 0.0, 1.0)
        return np.concatenate([full[:, :4], spread[:, None], reference[:, None]], axis=1).astype(np.float32)

    def _infos(self) -> dict:
        values = self.sim.info_array.copy()
        infos = {}
        for key, row in zip(INFO_KEYS, values):
            infos[key] = row
            infos["_" + key] = np.ones(self.num_envs, dtype=bool)
        for key, value in zip(DUAL_INFO_KEYS, (self._tracking, self._reference_now, self._controller_a)):
            infos[key] = value.copy()
            infos["_" + key] = np.ones(self.num_envs, dtype=bool)
        return infos


class DualControlEnv(SingleOfVector):
    """``hyst_gym/DualControl-v0``: identify while working; probing costs tracking error.

    ## Description
    The paper's milling application as a dual-control problem. The hot coil of the calibration tasks
    (C_th 5 J/K, R_th 4 K/W, start temperature from a raised-cosine prior over 5..45 C, no ambient drift,
    overheat at 60 C) drives the first-order plant ``y' = -100 y + M``; the output must follow a milling
    stroke reference (:class:`MillingReference`: ramp to 0.4 of the output at Ms, then 0.4 +- 0.15 at
    0.5 Hz). An inverse-compensation controller computes the field from model (6) with the current estimate
    of a (the grid posterior over the start temperature, the calibration tasks' estimator); the agent adds a
    probe field. A wrong estimate biases the tracking; a probe informs the estimator but moves the output off
    the reference. The floor is an oracle: the same controller fed the true a, no probe.

    ## Action Space
    ``Box(-1, 1, (1,))``: the probe / field_limit (1e5 A/m), added to the controller's command (the sum
    clipped to the field limit; the slew limit 2500 A/m per step applies to the sum).

    ## Observation Space
    ``Box(float32)``:

    | index | name | min | max | meaning (unit) |
    |---|---|---|---|---|
    | 0 | output | -2 | 2 | measured y / y(Ms), with sensor noise |
    | 1 | field | -1 | 1 | H / 1e5 A/m |
    | 2 | elapsed | 0 | 1 | step / 200 |
    | 3 | a_estimate | -1 | 1 | the controller's estimate of a (the posterior's), mapped from Theta |
    | 4 | estimate_spread | 0 | 1 | posterior standard deviation of a / width(Theta) |
    | 5 | reference_next | 0 | 1 | the reference at the end of the coming step, y / y(Ms) |

    ## Rewards
    ``-(e/1 %)**2/200`` per step, e the tracking error ``|y - r|`` of the noise-free output in percent of
    y(Ms); at an overheat also ``-100**2/200`` for every step left. The episode's return is minus the mean
    square tracking error (%^2), the per-draw score; the suite's metric is its RMS over draws (% of y(Ms)).

    ## Starting State
    Field 0, M = 0 (the controller's model too), coil at ``T0 = 278.15 + 40*Q(u)`` K (raised-cosine quantile),
    a = 7012*T0/293.15 A/m; the estimator starts from its prior.

    ## Episode End
    ``terminated``: the coil passes 333.15 K. ``truncated``: 200 steps (10 s at dt = 0.05 s).

    ## Arguments
    ``gymnasium.make(id, controller_estimate="posterior", posterior_nodes=None, **overrides)``:
    ``controller_estimate="true"`` feeds the controller the true a (the oracle); ``posterior_nodes``: T0 nodes of
    the estimator (default 64); EnvConfig fields on top of the preset. Reset options as
    :class:`~hyst_gym.envs.single.HystEnv`. ``info`` adds ``tracking_error`` (%), ``reference`` (y/y(Ms)) and
    ``controller_estimate`` (A/m).

    ## Version History
    * v0: first version (suite v2).
    """

    vector_class = DualControlVectorEnv

    def __init__(self, task: str = "hyst_gym/DualControl-v0", render_mode=None, **overrides):
        super().__init__(task, render_mode, **overrides)

    @property
    def sim(self):
        return self.vector.sim


__all__ = ["CONTROLLER_ESTIMATES", "ControllerModel", "DualControlEnv", "DualControlVectorEnv", "MillingReference",
           "inverse_fields"]
