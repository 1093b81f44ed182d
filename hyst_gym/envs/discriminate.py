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

:func:`decision_time_bound` bounds the expected score of any agent from below, given upper envelopes of the
relative entropy between the truth's and the alternatives' noise-free outputs that admissible fields can gather
(the data-processing inequality at the posterior's threshold, :data:`DECISION_ODDS`; derived on
docs/envs/discriminate.md).
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


# ---------------------------------------------------------------- the information bound on the decision time

#: the decision's odds: the truth's posterior reaches :data:`DECIDED` exactly when the alternatives' likelihood
#: ratios to the truth sum to at most this, ``sum_j exp(-LLR_j) <= (1 - DECIDED)/DECIDED`` (uniform prior)
DECISION_ODDS = (1.0 - DECIDED) / DECIDED


def decided_kl(probability, ratio: float):
    """``kl(p || ratio*p)``: the binary relative entropy (nats) between deciding with probability ``p`` under the
    truth and with at most ``ratio*p`` under the alternative; increasing in p for ``ratio < 1/e``, from 0 to
    ``log(1/ratio)`` at p = 1."""
    p = np.asarray(probability, dtype=np.float64)
    q = ratio * p
    with np.errstate(divide="ignore", invalid="ignore"):
        tail = np.where(p < 1.0, (1.0 - p) * np.log((1.0 - p) / (1.0 - q)), 0.0)
        head = np.where(p > 0.0, p * math.log(1.0 / ratio), 0.0)
    return head + tail


def decided_probability_bound(kl_bound, ratio: float, iterations: int = 60):
    """The largest p with :func:`decided_kl` (p, ``ratio``) <= ``kl_bound`` (1 where the bound reaches
    ``log(1/ratio)``): the most the truth can be decided with when the observations carry at most ``kl_bound``
    nats against the alternative (bisection, rounded up)."""
    kl_bound = np.asarray(kl_bound, dtype=np.float64)
    low, high = np.zeros_like(kl_bound), np.ones_like(kl_bound)
    for _ in range(iterations):
        middle = 0.5 * (low + high)
        below = decided_kl(middle, ratio) <= kl_bound
        low, high = np.where(below, middle, low), np.where(below, high, middle)
    return np.where(kl_bound >= math.log(1.0 / ratio), 1.0, high)


def concave_majorant(values) -> np.ndarray:
    """The least concave majorant of ``values`` at 0, 1, ..., len - 1 (the upper hull, interpolated)."""
    values = np.asarray(values, dtype=np.float64)
    hull: list = []
    for t, v in enumerate(values):
        while len(hull) >= 2:
            (t1, v1), (t2, v2) = hull[-2], hull[-1]
            if (v2 - v1) * (t - t1) <= (v - v1) * (t2 - t1):
                hull.pop()
            else:
                break
        hull.append((t, v))
    ts, vs = zip(*hull)
    return np.interp(np.arange(values.shape[0]), ts, vs)


def _smallest_reaching(hull: np.ndarray, needed: np.ndarray) -> np.ndarray:
    """The smallest x (steps) at which the piecewise-linear nondecreasing ``hull`` reaches each ``needed``
    (inf where it never does)."""
    index = np.searchsorted(hull, needed, side="left")
    inside = index < hull.shape[0]
    i = np.clip(index, 1, hull.shape[0] - 1)
    rise = hull[i] - hull[i - 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(rise > 0, i - 1 + (needed - hull[i - 1]) / rise, i)
    return np.where(inside, np.where(index == 0, 0.0, x), np.inf)


def _decided_kl_slope(probability, ratio: float):
    """d/dp of :func:`decided_kl` (p, ``ratio``), for p < 1."""
    p = np.asarray(probability, dtype=np.float64)
    return (math.log(1.0 / ratio) - 1.0 + np.log((1.0 - ratio * p) / (1.0 - p))
            + ratio * (1.0 - p) / (1.0 - ratio * p))


#: the points at which the survival route's linear program takes tangents of :func:`decided_kl` (convex in p, so
#: each tangent lies below it: a relaxation), denser towards p = 1 where it steepens
TANGENT_POINTS = np.concatenate([np.linspace(0.0, 0.9, 46), 1.0 - np.logspace(-1.0, -8.0, 36)])


def _survival_steps(envelopes, total_steps: int) -> float:
    """Route 3 of :func:`decision_time_bound`: the least ``sum_t (1 - a_t)`` over every sequence a_t (the
    probability of a decision by step t) that meets, per envelope, ``kl(a_t || ratio a_t) <= sum_{s<=t} (k(s) -
    k(s-1)) (1 - a_{s-1})`` (the information gathered while the episode runs) with kl replaced by its tangents: a
    linear program, its optimum a lower bound on the expected score (steps)."""
    from scipy.optimize import linprog
    from scipy.sparse import coo_matrix

    steps = int(total_steps)
    count = steps - 1  # a_1..a_{N-1}; a_0 = 0 and a_N does not enter the score
    rows, cols, vals, b_eq, ub_rows, ub_cols, ub_vals, b_ub = [], [], [], [], [], [], [], []
    for e, (ratio, k) in enumerate(envelopes):
        k = np.maximum.accumulate(np.asarray(k, dtype=np.float64)[: steps + 1])
        gain = np.diff(k)  # gain[t - 1] = k(t) - k(t - 1) >= 0
        budget = count * (1 + e)  # the column of B_{e,1}; B_{e,t} at budget + t - 1
        for t in range(1, steps):
            row = len(b_eq)
            rows += [row]
            cols += [budget + t - 1]
            vals += [1.0]
            if t > 1:  # B_t - B_{t-1} + gain_t a_{t-1} = gain_t
                rows += [row, row]
                cols += [budget + t - 2, t - 2]
                vals += [-1.0, gain[t - 1]]
            b_eq.append(gain[t - 1])
        slopes = _decided_kl_slope(TANGENT_POINTS, ratio)
        offsets = slopes * TANGENT_POINTS - decided_kl(TANGENT_POINTS, ratio)
        for t in range(1, steps):
            for slope, offset in zip(slopes, offsets):  # slope a_t - B_t <= slope p* - kl(p*)
                row = len(b_ub)
                ub_rows += [row, row]
                ub_cols += [t - 1, budget + t - 1]
                ub_vals += [slope, -1.0]
                b_ub.append(offset)
    width = count * (1 + len(envelopes))
    objective = np.concatenate([-np.ones(count), np.zeros(width - count)])
    bounds = [(0.0, 1.0)] * count + [(None, None)] * (width - count)
    result = linprog(objective, A_ub=coo_matrix((ub_vals, (ub_rows, ub_cols)), shape=(len(b_ub), width)).tocsr(),
                     b_ub=np.array(b_ub), A_eq=coo_matrix((vals, (rows, cols)), shape=(len(b_eq), width)).tocsr(),
                     b_eq=np.array(b_eq), bounds=bounds, method="highs")
    if not result.success:
        raise RuntimeError(f"decision_time_bound: the survival program failed: {result.message}")
    return steps + float(result.fun) - 1e-6  # the solver's tolerance, on the safe side


class DecisionTimeBound(NamedTuple):
    """:func:`decision_time_bound`: ``steps`` (the bound on the expected score, steps, the largest of its
    routes): ``tail_steps`` (the tail sum), ``wald_steps`` (the stopped likelihood ratio), ``survival_steps``
    (the information gathered while the episode runs, a linear program); ``decided_by`` (the tail route's bound
    on the probability of a decision by each step 0..N)."""

    steps: float
    tail_steps: float
    wald_steps: float
    survival_steps: float
    decided_by: np.ndarray


def decision_time_bound(envelopes, total_steps: int) -> DecisionTimeBound:
    """A lower bound on the expected score (steps; a step per step to the decision, ``total_steps`` when
    undecided or overheated) of any agent, given upper envelopes of the information the agent can gather.

    ``envelopes``: ``(ratio, k)`` pairs, k an array over steps 0..N (k[0] = 0, nondecreasing): for ``ratio`` =
    :data:`DECISION_ODDS`, the most relative entropy ``sum_s d_s^2/(2 sigma^2)`` (d_s the noise-free difference
    of the truth's and one alternative's M/Ms at step s) that any admissible field path gathers by step t; for
    ``ratio`` = DECISION_ODDS/2, the most of the two alternatives' mean. The derivation (docs/envs/
    discriminate.md): a decision by step t is an event A with P_alt(A) <= ratio * P_truth(A) (the posterior's
    threshold), so by the data-processing inequality kl(P(A) || ratio P(A)) <= the relative entropy of the
    observations up to min(end, t), whose expectation is E[sum of d_s^2/(2 sigma^2)] (optional stopping) <=
    E[k(min(end, t))] = sum_{s<=t} (k(s) - k(s-1)) P(end >= s) <= k(t). Route 1 (tail sum): E[score] = sum_t
    (1 - P(decided by t)), P(decided by t) bounded through k(t) by the least of the envelopes. Route 2 (Wald),
    per envelope: with p = P(decided at all) and tau the end, kl(p || ratio p) <= E[k(tau)] <= k_hat(E[tau])
    (k_hat the concave majorant, Jensen) and E[score] >= max(E[tau], N (1 - p)), minimized over p; the largest
    over the envelopes. Route 3 (survival): P(end >= s) <= 1 - P(decided by s - 1), every envelope at once
    (:func:`_survival_steps`). Returns the largest route."""
    total_steps = int(total_steps)
    decided_by = np.ones(total_steps + 1)
    wald = 0.0
    probabilities = np.linspace(0.0, 1.0, 4001)
    for ratio, k in envelopes:
        k = np.maximum.accumulate(np.asarray(k, dtype=np.float64)[: total_steps + 1])
        decided_by = np.minimum(decided_by, decided_probability_bound(k, ratio))
        # route 2: the smallest E[tau] whose concave envelope reaches kl(p || ratio p), per p, against N (1 - p)
        hull = concave_majorant(k)
        stopping = _smallest_reaching(hull, decided_kl(probabilities, ratio))
        # on [p_i, p_i+1] the larger term is at least max(stopping(p_i), N (1 - p_i+1)): a bound over every p
        wald = max(wald, float(np.min(np.maximum(stopping[:-1], total_steps * (1.0 - probabilities[1:])))))
    decided_by[0] = 0.0
    tail = float(np.sum(1.0 - decided_by[:total_steps]))
    survival = _survival_steps(envelopes, total_steps)
    return DecisionTimeBound(max(tail, wald, survival), tail, wald, survival, decided_by)


__all__ = ["CANDIDATES", "DECISION_ODDS", "CandidateModels", "Candidates", "DecisionTimeBound", "DiscriminateEnv",
           "DiscriminateVectorEnv", "advance_candidates", "candidate_a", "candidate_models", "concave_majorant",
           "decided_kl", "decided_probability_bound", "decision_time_bound", "discriminate_candidates",
           "recording_drive"]
