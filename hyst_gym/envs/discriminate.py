"""Discriminate (active diagnosis): which of three explanations of a recording is the material's?

A recording of the transducer (the magnetization channel, M/Ms, driven by a ramp up to
:data:`RECORDING_PEAK` and back in 10 s, :func:`recording_drive`) is explained about equally well by three
candidates, each a model of :mod:`hyst_gym.physics`: the mismatch tool's ``small_loop`` effect, and the base
model with one parameter refitted (the explanation without an effect, which the tool weighs effects
against):

* ``small_loop``: model (6) with the small-loop extension, a reversible low-field susceptibility
  ``chi_r`` (:data:`~hyst_gym.physics.hysteresis.SMALL_LOOP_EXTENSION`);
* ``pinning``: model (6) with a different pinning constant k;
* ``anhysteretic_width``: model (6) with a different a (the anhysteretic curve's width, as a temperature
  shift would give).

The small-loop candidate's ``chi_r`` is set (:data:`SMALL_LOOP_CHI_R`); the others' k and a are fitted to it on
the recording drive (least squares, :func:`discriminate_candidates`), so on that drive all three are close.
Each episode draws the true candidate (uniform) and the coil's start temperature (raised cosine over
5..45 C, measured: a follows it by eq. (4) in every candidate, and Joule heating raises it, the
calibration tasks' hot coil). The agent designs the field under the field, slew and heat limits; the task's
estimator is the exact Bayes posterior over the three candidates (each candidate's noise-free M driven by
the applied field, a Gaussian likelihood of the measured M/Ms). The episode ends when the truth's posterior
probability reaches :data:`DECIDED` (terminated, decided), at an overheat (terminated), or at 200 steps; the
score is the time to the decision (s, the deciding step included; the whole 10 s when undecided or overheated,
an overheat on the deciding step too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode

from ..physics.background_compile import background_kernel
from ..physics.hysteresis import advance_shared_small_loop
from ..physics.thermal import a_law, mean_square_linear, temperature_step
from .core import TEMPERATURE_BOUND, TEMPERATURE_SCALE
from .vector_single import SingleOfVector, TaskVectorEnv

#: the names of the candidates, in the order of the posterior's columns
CANDIDATES = ("small_loop", "pinning", "anhysteretic_width")
#: the small-loop candidate's reversible low-field susceptibility (dimensionless, dM/dH units)
SMALL_LOOP_CHI_R = 1.0
#: the posterior probability of the truth at which it is decided
DECIDED = 0.99
#: the peak field (A/m) of the recording that the candidates explain: a ramp up to it in 5 s and back down
RECORDING_PEAK = 6.0e4


def recording_drive(steps: int, peak: float = RECORDING_PEAK) -> np.ndarray:
    """The recording's field (A/m) at the end of each of ``steps`` steps: a triangle from 0 up to ``peak`` and
    back to 0."""
    half = steps / 2.0
    k = np.arange(1, steps + 1)
    return peak * np.where(k <= half, k / half, (steps - k) / half)


@dataclass(frozen=True)
class Candidates:
    """The three candidates' parameters of model (6), per column of :data:`CANDIDATES`, at the reference
    temperature: ``a`` (A/m; a follows T by eq. (4)), ``k`` (A/m), ``chi_r`` (dimensionless), and the fit's
    RMS distance of each to the small-loop candidate on the recording drive (M/Ms)."""

    a: tuple
    k: tuple
    chi_r: tuple
    recording_distance: tuple


class CandidateModels(NamedTuple):
    """The constants of the candidates' models (6) with the small-loop extension, one column per candidate
    (named state for the compiled kernels): ``a_reference`` (A/m, a at the reference temperature; a follows T
    by eq. (4)), ``k`` (A/m), ``alpha`` (dimensionless), ``Ms`` (A/m), ``c`` (dimensionless), ``chi_r``
    (dimensionless, dM/dH units), each a float64 array; ``kind`` (the anhysteretic curve's code),
    ``max_field_step`` (A/m, the models' substep)."""

    a_reference: np.ndarray
    k: np.ndarray
    alpha: np.ndarray
    Ms: np.ndarray
    c: np.ndarray
    chi_r: np.ndarray
    kind: int
    max_field_step: float


def candidate_models(config, a_reference, k, chi_r) -> CandidateModels:
    """:class:`CandidateModels` of ``config``'s hysteresis with the columns' ``a_reference``, ``k``, ``chi_r``."""
    hyst = config.hysteresis
    a_reference, k, chi_r = (np.array(v, dtype=np.float64, ndmin=1) for v in (a_reference, k, chi_r))
    count = a_reference.shape[0]
    return CandidateModels(a_reference, k, np.full(count, float(hyst.alpha)), np.full(count, float(hyst.Ms)),
                           np.full(count, float(hyst.c)), chi_r, int(hyst.kind), float(config.max_field_step))


@background_kernel(error_model="numpy")
def _trajectory_kernel(field, models, out):
    """M/Ms of one candidate (``models`` of one column, a at ``a_reference``) at the end of each step of
    ``field`` (A/m), from M = 0 and field 0; writes ``out``."""
    m = np.zeros(1)
    previous = 0.0
    for i in range(field.shape[0]):
        advance_shared_small_loop(m, previous, field[i], models.a_reference, models.k, models.alpha, models.Ms,
                                  models.c, models.chi_r, models.kind, models.max_field_step)
        out[i] = m[0] / models.Ms[0]
        previous = field[i]


def _trajectory(config, a, k, chi_r, field):
    out = np.empty(field.shape[0])
    _trajectory_kernel(np.asarray(field, dtype=np.float64), candidate_models(config, a, k, chi_r), out)
    return out


def _golden(objective, low, high, iterations: int = 40) -> float:
    """The minimizer of a unimodal ``objective`` over [low, high] (golden-section search)."""
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = high - ratio * (high - low), low + ratio * (high - low)
    f1, f2 = objective(x1), objective(x2)
    for _ in range(iterations):
        if f1 < f2:
            high, x2, f2 = x2, x1, f1
            x1 = high - ratio * (high - low)
            f1 = objective(x1)
        else:
            low, x1, f1 = x1, x2, f2
            x2 = low + ratio * (high - low)
            f2 = objective(x2)
    return 0.5 * (low + high)


def discriminate_candidates(config, chi_r: float = SMALL_LOOP_CHI_R) -> Candidates:
    """The candidates of a config: small-loop with ``chi_r``; k and a of the others fitted (least squares of
    M/Ms) to it on :func:`recording_drive`, at the reference temperature."""
    hyst = config.hysteresis
    field = recording_drive(config.episode_steps)
    target = _trajectory(config, hyst.a, hyst.k, chi_r, field)

    def distance(trace):
        return float(np.sqrt(np.mean((trace - target) ** 2)))

    k_fit = _golden(lambda k: distance(_trajectory(config, hyst.a, k, 0.0, field)), 0.3 * hyst.k, 3.0 * hyst.k)
    a_fit = _golden(lambda a: distance(_trajectory(config, a, hyst.k, 0.0, field)), 0.5 * hyst.a, 1.5 * hyst.a)
    return Candidates((hyst.a, hyst.a, a_fit), (hyst.k, k_fit, hyst.k), (chi_r, 0.0, 0.0),
                      (0.0, distance(_trajectory(config, hyst.a, k_fit, 0.0, field)),
                       distance(_trajectory(config, a_fit, hyst.k, 0.0, field))))


@background_kernel(error_model="numpy")
def advance_candidates(model_m, field_from, field_to, a, models):
    """Every sub-env's candidate models (rows of ``model_m``, (n, 3), A/m; ``a`` (n, 3) A/m at the sub-env's
    temperature, in place of ``models.a_reference``) moved along its applied field (A/m), in place."""
    for i in range(model_m.shape[0]):
        advance_shared_small_loop(model_m[i], field_from[i], field_to[i], a[i], models.k, models.alpha, models.Ms,
                                  models.c, models.chi_r, models.kind, models.max_field_step)


#: EnvConfig settings the discriminate task does not use (the coil cools towards its start temperature, the
#: candidates' M/Ms is measured directly, the temperature always): (name, its value in a config)
UNUSED_SETTINGS = (("ambient_drift_rate_range", lambda config: config.ambient_drift_rate_range),
                   ("thermal.ambient_temperature", lambda config: config.thermal.ambient_temperature),
                   ("transducer", lambda config: config.transducer),
                   ("temperature_sensor", lambda config: config.temperature_sensor))


def _reject_unused(task: str, config, preset) -> None:
    """A one-line ValueError naming the first setting of :data:`UNUSED_SETTINGS` that ``config`` changes from the
    task's ``preset`` (the task would ignore it)."""
    for name, value in UNUSED_SETTINGS:
        if value(config) != value(preset):
            raise ValueError(f"{task!r}: the discriminate task does not use {name}; got {value(config)!r}, expected "
                             f"the preset's {value(preset)!r}")


def candidate_a(models: CandidateModels, temperature, thermal) -> np.ndarray:
    """a (A/m) of every candidate (columns) at each sub-env's ``temperature`` (K), eq. (4): (n, 3)."""
    return a_law(models.a_reference[None, :], np.asarray(temperature)[:, None], thermal.reference_temperature)


class DiscriminateVectorEnv(TaskVectorEnv):
    """Native vector env of ``hyst_gym/Discriminate-v0`` (see :class:`DiscriminateEnv`, whose page this is too).
    Autoreset ``NEXT_STEP`` (default) or ``DISABLED``; ``SAME_STEP`` is refused (a ValueError)."""

    def __init__(self, num_envs: int = 1, task: str = "hyst_gym/Discriminate-v0",
                 autoreset_mode=AutoresetMode.NEXT_STEP, **overrides):
        from ..estimation.information_bound import raised_cosine_quantile

        config = self._setup(num_envs, task, "discriminate", autoreset_mode, overrides)
        if not config.output_noise > 0:
            raise ValueError(f"{task!r}: output_noise must be > 0 (the posterior's likelihood), got "
                             f"{config.output_noise!r}")
        _reject_unused(task, config, self.spec_.env_config())
        n = self.num_envs
        self._quantile = raised_cosine_quantile
        self.candidates = discriminate_candidates(config)
        count = len(CANDIDATES)
        #: the candidates' models (public: the task publishes them; agents read them, never the truth)
        self.models = candidate_models(config, self.candidates.a, self.candidates.k, self.candidates.chi_r)
        thermal = config.thermal
        self._decay = math.exp(-config.dt / thermal.time_constant)
        self._heat_gain = thermal.thermal_resistance * thermal.power_per_square_field
        self.field = np.zeros(n)
        self.temperature = np.zeros(n)
        self.start_temperature = np.zeros(n)
        self.truth = np.zeros(n, dtype=np.int64)
        self.model_m = np.zeros((n, count))
        self.log_post = np.zeros((n, count))
        self.measured = np.zeros(n)
        self.steps = np.zeros(n, dtype=np.int64)
        self._episode_rngs: list = [None] * n
        self._noise_rngs: list = [None] * n
        self._spaces(["output", "field", "elapsed", "temperature", *(f"p_{name}" for name in CANDIDATES)],
                     [-2.0, -1.0, 0.0, -TEMPERATURE_BOUND] + [0.0] * count,
                     [2.0, 1.0, 1.0, TEMPERATURE_BOUND] + [1.0] * count)

    def posterior(self) -> np.ndarray:
        """The posterior probabilities of the candidates per sub-env, (n, 3)."""
        weights = np.exp(self.log_post - self.log_post.max(axis=1, keepdims=True))
        return weights / weights.sum(axis=1, keepdims=True)

    # ---------------------------------------------------------------- episodes

    def reset(self, *, seed=None, options=None):
        """Reset every sub-env (``seed`` as the native vector envs). Options: ``truth`` (a candidate's name or
        index), ``initial_temperature`` (K)."""
        from .vector import sub_env_seeds

        for i, sub_seed in enumerate(sub_env_seeds(self, seed)):
            if sub_seed is not None or self._episode_rngs[i] is None:
                self._episode_rngs[i], self._noise_rngs[i] = seeding.np_random(sub_seed)[0].spawn(2)
        self._restart(self._all, self._checked(options))
        self._autoreset[:] = False
        return self._observation(), self._infos()

    def _checked(self, options) -> dict:
        """The reset options as arrays of one value per sub-env (a single value is broadcast); a ValueError naming
        a bad one."""
        options = dict(options or {})
        unknown = set(options) - {"truth", "initial_temperature"}
        if unknown:
            raise ValueError(f"reset: unknown option(s) {sorted(unknown)}; expected truth, initial_temperature")
        checked = {}
        if "truth" in options:
            values = np.atleast_1d(np.asarray(options["truth"], dtype=object))
            indices = [CANDIDATES.index(v) if isinstance(v, str) and v in CANDIDATES else v for v in values]
            if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and 0 <= v < len(CANDIDATES)
                       for v in indices):
                raise ValueError(f"reset option truth must be one of {CANDIDATES} or 0..2 (or one per sub-env), got "
                                 f"{options['truth']!r}")
            checked["truth"] = self._per_sub_env("truth", np.array(indices, dtype=np.int64))
        if "initial_temperature" in options:
            values = np.atleast_1d(np.asarray(options["initial_temperature"]))
            if values.dtype.kind not in "iuf" or not np.all((values > 0) & (values < self.config.temperature_limit)):
                raise ValueError(f"reset option initial_temperature must be numbers in (0, "
                                 f"{self.config.temperature_limit:g}) K, got {options['initial_temperature']!r}")
            checked["initial_temperature"] = self._per_sub_env("initial_temperature", values.astype(np.float64))
        return checked

    def _per_sub_env(self, name: str, values: np.ndarray) -> np.ndarray:
        """``values`` (one, or one per sub-env) as one per sub-env; a one-line ValueError naming ``name`` else."""
        if values.shape[0] not in (1, self.num_envs):
            raise ValueError(f"reset option {name} must be one value or {self.num_envs} (one per sub-env), got "
                             f"{values.shape[0]}")
        return np.broadcast_to(values, (self.num_envs,))

    def _restart(self, rows, options=None) -> None:
        options = options or {}
        low, high = self.config.initial_temperature_range
        for row in rows:
            draws = self._episode_rngs[row].random(2)
            self.truth[row] = min(int(draws[0] * len(CANDIDATES)), len(CANDIDATES) - 1)
            self.start_temperature[row] = low + (high - low) * float(self._quantile(draws[1]))
        if "truth" in options:
            self.truth[rows] = options["truth"][rows]
        if "initial_temperature" in options:
            self.start_temperature[rows] = options["initial_temperature"][rows]
        self.temperature[rows] = self.start_temperature[rows]
        self.field[rows] = 0.0
        self.model_m[rows] = 0.0
        self.log_post[rows] = 0.0
        self.measured[rows] = self._noise(rows)
        self.steps[rows] = 0

    def _noise(self, rows) -> np.ndarray:
        return np.array([self.config.output_noise * self._noise_rngs[row].standard_normal() for row in rows])

    # ---------------------------------------------------------------- stepping

    def step(self, actions):
        config = self.config
        actions, resetting = self._begin_step(actions, "field / field_limit")
        before = self.field.copy()
        command = actions[:, 0] * config.field_limit
        change = config.max_field_change
        self.field[:] = np.clip(np.clip(command, before - change, before + change), -config.field_limit,
                                config.field_limit)
        # a of every candidate at the step's start temperature (eq. (4)), as the simulator's plant
        a = candidate_a(self.models, self.temperature, config.thermal)
        advance_candidates(self.model_m, before, self.field, a, self.models)
        offset = self._heat_gain * mean_square_linear(before, self.field)
        ambient = self.start_temperature  # the coil cools towards its start temperature (no drift)
        self.temperature[:] = temperature_step(self.temperature, ambient, ambient, offset, self._decay)
        self.steps += 1
        rows = self._all
        true_m = self.model_m[rows, self.truth] / config.hysteresis.Ms
        self.measured[:] = true_m + self._noise(rows)
        residual = self.measured[:, None] - self.model_m / config.hysteresis.Ms
        self.log_post -= 0.5 * residual ** 2 / config.output_noise ** 2
        decided = self.posterior()[rows, self.truth] >= DECIDED
        overheated = self.temperature > config.temperature_limit
        terminated = decided | overheated
        truncated = ~terminated & (self.steps >= config.episode_steps)
        total = config.episode_steps
        # the score: every step up to and including the deciding one, and at an overheat (which takes precedence
        # over a decision on the same step) every step left too (the metric's whole episode)
        reward = -1.0 - np.where(overheated, total - self.steps, 0)
        reward = reward / total
        self._end_step(reward, terminated, truncated, resetting)
        # after the autoreset: the resetting rows' infos describe their new episode, as their observation does
        return self._observation(), reward, terminated, truncated, self._infos(decided & ~resetting,
                                                                               overheated & ~resetting)

    # ---------------------------------------------------------------- what the agent sees

    def _observation(self) -> np.ndarray:
        config = self.config
        temperature = np.clip((self.temperature - config.thermal.reference_temperature) / TEMPERATURE_SCALE,
                              -TEMPERATURE_BOUND, TEMPERATURE_BOUND)
        return np.column_stack([np.clip(self.measured, -2.0, 2.0), self.field / config.field_limit,
                                self.steps / config.episode_steps, temperature, self.posterior()]).astype(np.float32)

    def _infos(self, decided=None, overheated=None) -> dict:
        n = self.num_envs
        infos = {"truth": self.truth.copy(), "temperature": self.temperature.copy(), "field": self.field.copy(),
                 "posterior_truth": self.posterior()[self._all, self.truth],
                 "decided": np.zeros(n, dtype=bool) if decided is None else decided.copy(),
                 "overheated": np.zeros(n, dtype=bool) if overheated is None else overheated.copy(),
                 "start_temperature": self.start_temperature.copy()}
        for key in list(infos):
            infos["_" + key] = np.ones(n, dtype=bool)
        return infos


class DiscriminateEnv(SingleOfVector):
    """``hyst_gym/Discriminate-v0``: design the excitation that tells three explanations of a recording apart.

    ## Description
    Active diagnosis. A recording (the magnetization channel driven by a ramp up to 60 kA/m and back) is
    explained about equally well by three candidates of :mod:`hyst_gym.physics`: ``small_loop`` (model (6)
    with a reversible low-field susceptibility chi_r = 1), ``pinning`` (model (6) with k fitted to that
    recording) and ``anhysteretic_width`` (model (6) with a fitted). Each episode draws the truth and the
    coil's start temperature (raised cosine over 5..45 C, measured; a follows it, eq. (4), in every
    candidate); the hot coil of the calibration tasks heats at about 13 K/s at 81 kA/m and overheats at
    60 C. The task's estimator is the exact Bayes posterior over the three (uniform prior, Gaussian noise of
    3e-3 on M/Ms); the agent designs the field.

    ## Action Space
    ``Box(-1, 1, (1,))``: field command / field_limit (1e5 A/m); slew limit 2500 A/m per step.

    ## Observation Space
    ``Box(float32)``:

    | index | name | min | max | meaning (unit) |
    |---|---|---|---|---|
    | 0 | output | -2 | 2 | measured M / Ms, with noise |
    | 1 | field | -1 | 1 | H / 1e5 A/m |
    | 2 | elapsed | 0 | 1 | step / 200 |
    | 3 | temperature | -5 | 5 | measured coil temperature (T - 293.15 K) / 10 K |
    | 4..6 | p_small_loop, p_pinning, p_anhysteretic_width | 0 | 1 | the posterior probabilities |

    ## Rewards
    ``-1/200`` for every step up to and including the one that ends with the truth's posterior at 0.99, and at
    an overheat ``-1/200`` for every step left too (an overheat on the deciding step counts as an overheat). The
    return times 10 s is minus the time to the decision (s), the per-draw score; the metric is its mean over
    draws (10 s when undecided or overheated).

    ## Starting State
    Field 0, M = 0 in every candidate, the posterior uniform; truth and start temperature drawn from the
    env's seeded generator.

    ## Episode End
    ``terminated``: the truth's posterior reaches 0.99 (``info["decided"]``) or the coil passes 333.15 K
    (``info["overheated"]``). ``truncated``: 200 steps (10 s at dt = 0.05 s).

    ## Arguments
    ``gymnasium.make(id, **overrides)``: EnvConfig fields on top of the preset. Reset options: ``truth`` (a
    candidate's name or index) and ``initial_temperature`` (K), each one value or (vector env) one per sub-env.

    ## Version History
    * v0: first version (suite v2).
    """

    vector_class = DiscriminateVectorEnv

    def __init__(self, task: str = "hyst_gym/Discriminate-v0", render_mode=None, **overrides):
        super().__init__(task, render_mode, **overrides)


__all__ = ["CANDIDATES", "CandidateModels", "Candidates", "DiscriminateEnv", "DiscriminateVectorEnv",
           "advance_candidates", "candidate_a", "candidate_models", "discriminate_candidates", "recording_drive"]
