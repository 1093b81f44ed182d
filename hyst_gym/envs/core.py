"""The batched simulator behind every hyst-gym environment.

The physics is written once over a batch axis of ``n`` independent sub-environments:
the single env is the batch of one, and the native vector env runs the same code (and
the same compiled kernels) for all its sub-envs at once. One control step of length
``dt`` (s) does, for every sub-env::

    H1 = clip(command, H0 - slew*dt, H0 + slew*dt) within [-field_limit, field_limit]
    M  : domain-wall model (6) from H0 to H1 with a = a(T0)   (physics.advance_each)
    z  : transducer, exact first-order hold on the drive M or M**2   (physics)
    T  : lumped thermal model, Joule heating R*mean((H/n)**2) + linear ambient drift, exact
    y  : measured outputs = output(z) (+ velocity) + Gaussian noise
    estimator.update(H1, y, dt) (Excitation mode) / agent's estimate (other modes)

Random streams. Each sub-env owns two generators spawned (``Generator.spawn``, i.e.
``SeedSequence`` children) from that sub-env's seeded generator: one for episode draws
(initial temperature, ambient drift rate, PRBS bits), one for measurement noise. Noise
is drawn per sub-env in blocks of :data:`NOISE_BLOCK` steps, so a sub-env's numbers do
not depend on how many sub-envs run beside it. The global ``np.random`` is never used.
"""

from __future__ import annotations

import math

import numpy as np

from ..estimation import as_kernel_tuples
from ..estimation.bank import ModelBank
from ..estimation.config import EstimatorConfig
from ..estimation.config import LumpedPlant
from ..estimation.estimators import ESTIMATORS, Law, make_estimator
from ..physics import FirstOrderPlant, LumpedLinear, LumpedNonlinear
from .config import MECHANICAL_ESTIMATOR_GAMMA, EnvConfig
from .kernels import (EnvParams, EstimateView, ObservationLayout, PlantParams, PlantState, ScoreParams, StepBuffers,
                      announce_compilation, clip_actions, excitation_step, fill_info, fill_observation, finish_step,
                      identification_commands, identification_plants, identification_step, plant_step)
from .threads import SPLIT_MIN_NODES, WorkerThreads, block_edges, step_threads

EXCITATION = "excitation"
ESTIMATION = "estimation"
IDENTIFICATION = "identification"
MODES = (EXCITATION, ESTIMATION, IDENTIFICATION)

#: the plant parameters that are per sub-env (:class:`~.kernels.PlantParams`; the others are shared by all)
PER_ROW_PARAMS = ("k", "alpha", "Ms", "c")
#: noise samples drawn per sub-env per refill (amortizes the per-generator call cost)
NOISE_BLOCK = 128
#: |normalized action| may exceed 1 by this much (float32 rounding) before it is an error
ACTION_TOLERANCE = 1e-6
#: the symmetric-log map of the tuning error saturates at 10**TUNING_DECADES dead-zone widths
TUNING_DECADES = 6.0
#: observation bounds of the measured outputs, in units of their normalization scale
OUTPUT_BOUND = 2.0
#: observation bound of the temperature sensor, in units of TEMPERATURE_SCALE from T_ref
TEMPERATURE_BOUND = 5.0
TEMPERATURE_SCALE = 10.0  # K

#: the options ``reset`` accepts (see :meth:`BatchSimulator._checked_options`); ``pinning_k`` only where the
#: simulator draws k from a prior
RESET_OPTIONS = ("initial_temperature", "ambient_drift_rate", "a_true", "a_estimate")
PINNING_OPTION = "pinning_k"

INFO_KEYS = ("a_true", "a_estimate", "estimation_error", "temperature", "field", "magnetization", "output",
             "time", "pe_integrand", "curvature_sign", "stroke_margin", "temperature_margin", "penalty")


def estimator_plant(config: EnvConfig):
    """The plant model the built-in estimator (and the PE diagnostics) assume.

    First-order plant: the same ``y' = -lambda*y + nu*M``. Mechanical transducers: the
    linearized lumped model (13) -- exactly the simulated one for :class:`LumpedLinear`;
    for the nonlinear lumped model (12) and the FEM rod, (13) linearized about the
    default bias (a deliberate model mismatch, as on a real transducer).
    """
    transducer = config.transducer
    if isinstance(transducer, FirstOrderPlant):
        return transducer  # the estimator assumes the true plant (one FirstOrderPlant class)
    if isinstance(transducer, LumpedLinear):
        lumped = transducer
    elif isinstance(transducer, LumpedNonlinear):
        lumped = transducer.linearized()
    else:
        lumped = LumpedNonlinear.from_rod(transducer.rod).linearized()
    return LumpedPlant.from_coefficients(khat=lumped.stiffness, chat=lumped.damping, zetahat=lumped.coupling)


def estimator_config(config: EnvConfig) -> EstimatorConfig:
    """The :class:`EstimatorConfig` of the built-in estimator and of the PE bank.

    ``config.estimator_gamma = None`` means the estimation layer's default gain for the
    first-order plant, and :data:`~.config.MECHANICAL_ESTIMATOR_GAMMA` for the vector
    estimator of the mechanical transducers (see there why not the paper's 5e10).
    """
    gamma = config.estimator_gamma
    if gamma is None and config.is_mechanical:
        gamma = MECHANICAL_ESTIMATOR_GAMMA
    return EstimatorConfig(theta_min=config.theta_min, theta_max=config.theta_max,
                           initial_estimate=config.initial_estimate, grid_size=config.estimator_grid_size,
                           eps=config.estimator_eps, gamma=gamma, plant=estimator_plant(config),
                           hysteresis=config.hysteresis, max_field_step=config.max_field_step)


def output_scales(config: EnvConfig, model) -> np.ndarray:
    """Normalization of the measured outputs: their static value at M = Ms (and, for the
    velocity, that displacement times the first natural angular frequency)."""
    Ms = config.hysteresis.Ms
    static = abs(float(model.output(model.steady_state(Ms))[0]))
    transducer = config.transducer
    if isinstance(transducer, FirstOrderPlant):
        return np.array([static])
    if isinstance(transducer, LumpedLinear):
        omega = math.sqrt(transducer.stiffness)
    elif isinstance(transducer, LumpedNonlinear):
        omega = math.sqrt(transducer.stiffness / transducer.mass)
    else:
        omega = 2 * math.pi * float(transducer.natural_frequencies(1)[0])
    return np.array([static, static * omega])


def observation_names(config: EnvConfig, mode: str) -> list[str]:
    """Names of the observation entries, in order (see the README's layout table)."""
    names = ["displacement", "velocity"] if config.is_mechanical else ["output"]
    names += ["field", "elapsed"]
    if mode == EXCITATION:
        names += ["a_estimate", "tuning_error", "curvature_sign", "minmax_gap"]
    else:
        names += ["previous_estimate"]
    if config.temperature_sensor:
        names += ["temperature"]
    return names


#: what each observation entry is, with its unit and scale (the environment pages' observation
#: tables are built from these and from :func:`observation_bounds`; a name missing here fails
#: the documentation build)
OBSERVATION_DOCS = {
    "output": "measured plant output y / y(Ms) (first-order plant), with sensor noise",
    "displacement": "measured tip displacement x / x(Ms) (mechanical transducers), with sensor noise",
    "velocity": "measured tip velocity v / (x(Ms)·ω1), ω1 the first natural angular frequency (rad/s)",
    "field": "applied field H / field_limit (H in A/m)",
    "elapsed": "steps taken / episode_steps",
    "a_estimate": "built-in estimator's a (A/m) mapped linearly from Theta onto [-1, 1]",
    "tuning_error": "estimator tuning error y_eps as sign·log10(1 + |y_eps|/eps)/6",
    "curvature_sign": "±1: sign of the output's curvature in a at the current estimate",
    "minmax_gap": "min-max gap nu* as log1p(nu*)/log1p(2 Ms) (nu* in A/m)",
    "previous_estimate": "the agent's previous estimate of a, mapped from Theta onto [-1, 1]",
    "estimate_spread": "built-in estimator's uncertainty of a: posterior standard deviation / width(Theta), in [0, 1]",
    "temperature": "measured coil temperature (T − T_ref)/10 K (with temperature_sensor=True)",
    "heat_used": "the coil's temperature rise above its start (T − T0) / the margin of the prior's hottest start "
                 "to the limit (1: that start overheats); a function of the applied field's history alone",
    "reference_next": "the dual-control task's displacement reference at the end of the coming step, y / y(Ms)",
    "p_small_loop": "the discriminate task's posterior probability of the small-loop candidate",
    "p_pinning": "the discriminate task's posterior probability of the pinning candidate",
    "p_anhysteretic_width": "the discriminate task's posterior probability of the anhysteretic-width candidate",
}


def observation_bounds(config: EnvConfig, mode: str):
    bounds = {"displacement": (-OUTPUT_BOUND, OUTPUT_BOUND), "velocity": (-OUTPUT_BOUND, OUTPUT_BOUND),
              "output": (-OUTPUT_BOUND, OUTPUT_BOUND), "field": (-1.0, 1.0), "elapsed": (0.0, 1.0),
              "a_estimate": (-1.0, 1.0), "tuning_error": (-1.0, 1.0), "curvature_sign": (-1.0, 1.0),
              "minmax_gap": (0.0, 1.0), "previous_estimate": (-1.0, 1.0),
              "temperature": (-TEMPERATURE_BOUND, TEMPERATURE_BOUND)}
    names = observation_names(config, mode)
    low = np.array([bounds[n][0] for n in names], dtype=np.float32)
    high = np.array([bounds[n][1] for n in names], dtype=np.float32)
    return low, high


def action_size(mode: str) -> int:
    return 2 if mode == IDENTIFICATION else 1


#: dtype kinds an action array may have: signed, unsigned integers and floats (not bool,
#: complex, strings or objects, which ``np.asarray(..., dtype=float)`` would turn into nan or accept)
NUMERIC_KINDS = "iuf"


def _brief_repr(value, width: int = 60) -> str:
    """``repr(value)`` on one line, shortened to ``width`` characters (for error messages)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= width else text[:width - 3] + "..."


def action_array(action, shape: tuple, name: str = "action") -> np.ndarray:
    """``action`` as a float64 array of exactly ``shape``, else a one-line ``ValueError``
    that says what was given (None, something that is not numbers, another shape).

    The values themselves (finite, within [-1, 1]) are checked by the step kernels."""
    if isinstance(action, np.ndarray) and action.shape == shape and action.dtype.kind in NUMERIC_KINDS:
        return action.astype(np.float64, copy=False)
    if action is None:
        raise ValueError(f"{name} is None; expected an array of numbers of shape {shape}")
    try:
        array = np.asarray(action)
    except (TypeError, ValueError):  # ragged nested sequences
        array = None
    if array is None or array.dtype.kind not in NUMERIC_KINDS:
        raise ValueError(f"{name} must be an array of numbers of shape {shape}, got {type(action).__name__} "
                         f"{_brief_repr(action)}")
    if array.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got shape {array.shape}")
    return array.astype(np.float64, copy=False)


def uses_fused_step(mode: str, estimator: str) -> bool:
    """Whether the step is the one fused kernel (Excitation with a compiled estimator law)."""
    return mode == EXCITATION and ESTIMATORS[estimator].law != Law.HELD


def step_kernels(mode: str, estimator: str) -> tuple:
    """The compiled kernels an env of ``mode`` steps with (to tell whether they are cached)."""
    if uses_fused_step(mode, estimator):
        return (fill_observation, fill_info, excitation_step)
    if mode == IDENTIFICATION:
        return (fill_observation, fill_info, identification_step, identification_commands, identification_plants,
                finish_step)
    return (fill_observation, fill_info, clip_actions, plant_step, finish_step)


def _temperature_quantile(prior: str):
    """None (uniform start temperature) or the quantile function [0, 1] -> [0, 1] that shapes the draw."""
    if prior == "uniform":
        return None
    if prior == "raised_cosine":
        from ..estimation.information_bound import raised_cosine_quantile

        return raised_cosine_quantile
    raise ValueError(f"temperature_prior must be 'uniform' or 'raised_cosine', got {prior!r}")


def spawn_streams(generator: np.random.Generator):
    """(episode generator, noise generator) spawned from a sub-env's seeded generator."""
    episode, noise = generator.spawn(2)
    return episode, noise


def _checked_number(name: str, value, valid: tuple) -> float:
    """``value`` as a float within ``valid`` = (low, high, low inclusive, unit, why); a ValueError naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"reset option {name} must be a number, got {type(value).__name__} "
                         f"{_brief_repr(value)}")
    value = float(value)
    low, high, low_inclusive, unit, why = valid
    above_low = value >= low if low_inclusive else value > low
    if not (math.isfinite(value) and above_low and value <= high):
        bracket = "[" if low_inclusive else "("
        span = "finite" if name == "ambient_drift_rate" else f"in {bracket}{low:g}, {high:g}] {unit} ({why})"
        raise ValueError(f"reset option {name} = {value!r} {unit} is out of range: it must be {span}")
    return value


def _checked_pinning(value) -> float:
    """The reset option ``pinning_k`` (A/m, finite, > 0) as a float; a ValueError naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or \
            not np.isfinite(value) or value <= 0:
        raise ValueError(f"reset option {PINNING_OPTION} must be a finite number > 0 (A/m), got {value!r}")
    return float(value)


class BatchSimulator:
    """``n`` independent transducers with drifting temperature, stepped together.

    Parameters
    ----------
    config : EnvConfig
    mode : str
        ``"excitation"``, ``"estimation"`` or ``"identification"``.
    n : int
        Number of sub-environments.
    truncation_steps : int, optional
        Time limit in steps (default ``config.episode_steps``); the elapsed-time
        observation is always relative to ``config.episode_steps``.
    record : bool
        Keep per-step histories (for rendering).
    temperature_prior : {"uniform", "raised_cosine"}
        The shape of the start-temperature draw over ``config.initial_temperature_range``: uniform, or
        the raised cosine of :func:`~hyst_gym.estimation.information_bound.raised_cosine_quantile`.
    pinning_prior : optional
        An object with ``draw(u) -> k`` (A/m), e.g. :class:`~hyst_gym.envs.task_spec.PinningPrior`: each
        reset draws the sub-env's k of model (6) from it (after the sub-env's other draws); the reset option
        ``pinning_k`` (A/m) sets it instead. None: k stays at the config's.
    """

    def __init__(self, config: EnvConfig, mode: str, n: int = 1, truncation_steps: int | None = None,
                 record: bool = False, temperature_prior: str = "uniform", pinning_prior=None):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        # before the estimator is built: building it already compiles kernels
        announce_compilation(step_kernels(mode, config.estimator))
        self.config = config
        self.mode = mode
        self.n = int(n)
        self.truncation_steps = config.episode_steps if truncation_steps is None else int(truncation_steps)
        if self.truncation_steps < 1:
            raise ValueError(f"max_episode_steps must be >= 1, got {truncation_steps!r}")
        self.model = config.transducer.discretize(config.dt)
        self.scales = output_scales(config, self.model)
        self.n_outputs = self.scales.shape[0]
        self.obs_names = observation_names(config, mode)
        self.obs_low, self.obs_high = observation_bounds(config, mode)
        self.action_size = action_size(mode)
        self.record = record
        self.history: list[list[dict]] = [[] for _ in range(self.n)]
        self.temperature_quantile = _temperature_quantile(temperature_prior)
        self.temperature_prior = temperature_prior
        self.pinning_prior = pinning_prior
        self._make_estimator()
        self._allocate_plant()
        self._allocate_noise()
        self._allocate_step_outputs()
        self._plant_params = self._make_plant_params()
        self._build_kernel_args()

    def _make_estimator(self):
        """The estimator (Excitation) or the bare model bank (the agent estimates) the env runs."""
        config, n = self.config, self.n
        self.est_config = estimator_config(config)
        if self.mode == EXCITATION:
            self.estimator = make_estimator(config.estimator, self.est_config, n)
            self.bank = self.estimator.bank
            self._eps = self.est_config.eps
        else:
            self.estimator = None
            self.bank = ModelBank(self.est_config, n)
        plant = self.est_config.plant
        self._pe_gain = plant.gain if isinstance(plant, FirstOrderPlant) else 1.0

    def _allocate_plant(self):
        """The true plants' state (n sub-envs), set by :meth:`reset`."""
        config, n = self.config, self.n
        hyst = config.hysteresis
        self._k = np.full(n, hyst.k)
        self._alpha = np.full(n, hyst.alpha)
        self._Ms = np.full(n, hyst.Ms)
        self._c = np.full(n, hyst.c)
        self._kind = hyst.kind
        self.field = np.zeros(n)
        self.magnetization = np.zeros(n)
        self._magnetization_prev = np.zeros(n)
        self.state = self.model.initial_state(n)
        self._state_next = np.empty_like(self.state)
        self.temperature = np.zeros(n)
        self.ambient0 = np.zeros(n)
        self.drift_rate = np.zeros(n)
        self.steps = np.zeros(n, dtype=np.int64)
        self.a_true = np.zeros(n)
        self.a_estimate = np.full(n, config.initial_estimate)
        self.measured = np.zeros((n, self.n_outputs))
        self.measured_temperature = np.zeros(n)
        self.prbs_bits = np.zeros((n, int(math.ceil(config.episode_duration / config.schedule_period)) + 1))

    def _allocate_noise(self):
        """Per-sub-env random streams and the pre-drawn measurement noise blocks."""
        config, n = self.config, self.n
        self.episode_rngs: list = [None] * n
        self.noise_rngs: list = [None] * n
        self._noise_width = self.n_outputs + (1 if config.temperature_sensor else 0)
        self._noisy = config.output_noise > 0 or (config.temperature_sensor and config.temperature_sensor_noise > 0)
        self._noise = np.zeros((n, NOISE_BLOCK, self._noise_width))
        self._noise_pos = np.full(n, NOISE_BLOCK, dtype=np.int64)
        self._noise_sigma = np.concatenate([config.output_noise * self.scales,
                                            [config.temperature_sensor_noise] if config.temperature_sensor else []])

    def _allocate_step_outputs(self):
        """What a step writes besides the plant: rewards, terminations, observations, info, scratch."""
        config, n = self.config, self.n
        self._rows = np.arange(n)
        self._all_active = np.ones(n, dtype=bool)
        self._out = {"reward": np.zeros(n), "terminated": np.zeros(n, dtype=bool),
                     "truncated": np.zeros(n, dtype=bool), "error": np.zeros(n), "penalty": np.zeros(n),
                     "stroke": np.zeros(n)}
        self._obs = np.zeros((n, len(self.obs_names)), dtype=np.float32)
        self._pe = (np.zeros(n), np.zeros(n), np.zeros(n))
        self._gap_norm = math.log1p(2.0 * config.hysteresis.Ms)
        self.info_array = np.zeros((len(INFO_KEYS), n))
        self._theta = np.zeros(n)
        self._obs_fresh = False

    def _make_plant_params(self) -> PlantParams:
        """The fixed data of :func:`~.kernels.plant_step`: hysteresis, transducer, thermal model, noise."""
        config, transducer, thermal = self.config, self.model, self.config.thermal
        self._decay = math.exp(-config.dt / thermal.time_constant)
        self._power_per_h2 = thermal.power_per_square_field
        return PlantParams(
            k=self._k, alpha=self._alpha, Ms=self._Ms, c=self._c, kind=self._kind,
            max_field_step=config.max_field_step, field_limit=config.field_limit,
            max_change=config.max_field_change, phi=transducer.phi, gamma0=transducer.gamma0,
            gamma1=transducer.gamma1, quadratic=transducer.drive == "quadratic", drive_gain=transducer.drive_gain,
            output_index=transducer.output_index,
            velocity_index=(-1 if transducer.velocity_index is None or not config.is_mechanical
                            else transducer.velocity_index),
            drifting=config.temperature_mode == "drifting", dt=config.dt, decay=self._decay,
            power_per_h2=self._power_per_h2, thermal_resistance=thermal.thermal_resistance,
            tau=thermal.time_constant, a_reference=thermal.a_reference, t_reference=thermal.reference_temperature,
            noise_sigma=self._noise_sigma, noisy=self._noisy, temperature_sensor=config.temperature_sensor)

    def _build_kernel_args(self):
        """The named state of the compiled step kernels (live arrays, changed in place), and
        its plain-tuple form for the kernels called once per step."""
        config = self.config
        n = self.n
        estimator = self.estimator
        self._clipped = np.zeros((n, self.action_size))
        self._command = np.zeros(n)
        self._plant = PlantState(
            field=self.field, magnetization=self.magnetization, magnetization_prev=self._magnetization_prev,
            state=self.state, state_next=self._state_next, temperature=self.temperature, ambient0=self.ambient0,
            drift_rate=self.drift_rate, steps=self.steps, a_true=self.a_true, measured=self.measured,
            measured_temperature=self.measured_temperature, noise=self._noise, noise_pos=self._noise_pos)
        value, slope, second = self._pe
        if estimator is not None:
            state = estimator.kernel_state  # live arrays, updated in place by the estimator
            self._view = EstimateView(a_estimate=self.a_estimate, value_hat=state.f_hat, curvature=state.curvature,
                                      tuning=state.y_eps, gap=state.nu)
            eps = self._eps
        else:
            # no tuning features without an estimator (layout.excitation is False); the agent's
            # estimate fills f and its curvature from the bank
            self._view = EstimateView(a_estimate=self.a_estimate, value_hat=np.zeros(n), curvature=np.zeros(n),
                                      tuning=self.a_estimate, gap=self.a_estimate)
            eps = 1.0
        self._score = ScoreParams(
            truncation_steps=self.truncation_steps, theta_min=config.theta_min, theta_max=config.theta_max,
            theta_width=config.theta_width, temperature_limit=config.temperature_limit,
            temperature_band=config.temperature_penalty_band,
            stroke_limit=-1.0 if config.stroke_limit is None else config.stroke_limit,
            stroke_band=config.stroke_penalty_band, penalty_weight=config.penalty_weight,
            output_index=self.model.output_index, output_offset=self.model.output_offset, dt=config.dt,
            pe_gain=self._pe_gain, agent_estimate=estimator is None,
            estimate_column=0 if self.mode == ESTIMATION else 1)
        self._layout = ObservationLayout(
            scales=self.scales, field_limit=config.field_limit, episode_steps=config.episode_steps,
            theta_min=config.theta_min, theta_width=config.theta_width, eps=eps, gap_norm=self._gap_norm,
            decades=TUNING_DECADES, excitation=estimator is not None,
            t_reference=config.thermal.reference_temperature, temperature_scale=TEMPERATURE_SCALE,
            temperature_sensor=config.temperature_sensor, low=self.obs_low, high=self.obs_high)
        out = self._out
        self._buffers = StepBuffers(
            clipped=self._clipped, command=self._command, obs=self._obs, info=self.info_array, rows=self._rows,
            reward=out["reward"], terminated=out["terminated"], truncated=out["truncated"], error=out["error"],
            penalty=out["penalty"], stroke=out["stroke"], truth_clipped=self._theta, value_true=value,
            slope_scratch=slope, second_scratch=second)
        params = EnvParams(tolerance=ACTION_TOLERANCE, plant=self._plant_params, score=self._score,
                           layout=self._layout)
        # the plain-tuple forms (as_kernel_tuples) for plant_step, finish_step and excitation_step
        self._plant_tuples = as_kernel_tuples(self._plant, self._plant_params)
        self._finish_tuples = as_kernel_tuples(self._plant, self._view, self._buffers, self._score, self._layout,
                                               self.bank.kernel_state, self.bank.kernel_params)
        # Excitation with a compiled estimator law: the whole step is one kernel call.
        self._fused = uses_fused_step(self.mode, config.estimator)
        if self._fused:
            estimator_tuples = as_kernel_tuples(estimator.bank.kernel_state, estimator.bank.kernel_params,
                                                estimator.kernel_state, estimator.observer_params,
                                                estimator.hold_params(config.dt))
            self._fused_tuples = (*as_kernel_tuples(self._plant, self._view, self._buffers, params), estimator_tuples)
        # Identification (the agent's estimate): the whole step is one kernel call too.
        if self.mode == IDENTIFICATION:
            self._identification_tuples = as_kernel_tuples(self._plant, self._view, self._buffers, params,
                                                           self.bank.kernel_state, self.bank.kernel_params)
            self._command_tuples = as_kernel_tuples(params, self._buffers)
            self._plants_tuples = as_kernel_tuples(self._plant, self._plant_params, self.bank.kernel_state,
                                                   self.bank.kernel_params)
            self._plant_blocks = self._split_plants()
            self._threads = WorkerThreads(step_threads() - 1, "hyst-gym-simulator")

    def __getstate__(self) -> dict:
        # A copy (pickle, deepcopy) makes its own blocks and threads: a block's arrays are views of the simulator's,
        # which a copy would make arrays of their own (no longer the simulator's), and a pool does not copy.
        state = dict(self.__dict__)
        state.pop("_plant_blocks", None)
        state.pop("_threads", None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if self.mode == IDENTIFICATION:
            self._plant_blocks = self._split_plants()
            self._threads = WorkerThreads(step_threads() - 1, "hyst-gym-simulator")

    def _split_plants(self) -> list:
        """The blocks of sub-envs whose plants and model bank an Identification step moves in :func:`step_threads`
        threads at once (:func:`~.kernels.identification_plants`): (slice of sub-envs, its kernel arguments after
        the commands: views of the arrays); empty (the one kernel for all, :func:`~.kernels.identification_step`)
        with one thread or fewer than :data:`~.threads.SPLIT_MIN_NODES` bank models. The model bank is most of the
        step (G models per sub-env; the rest, :func:`~.kernels.finish_step`, runs after the blocks, for all)."""
        threads = min(step_threads(), self.n)
        bank = self.bank.kernel_state
        if threads < 2 or bank.magnetization.size < SPLIT_MIN_NODES:
            return []
        plant, params = self._plant, self._plant_params
        blocks = []
        for lo, hi in block_edges(self.n, threads):
            rows = slice(lo, hi)
            block_plant = plant._replace(**{name: getattr(plant, name)[rows] for name in plant._fields})
            block_params = params._replace(**{name: getattr(params, name)[rows] for name in PER_ROW_PARAMS})
            block_bank = bank._replace(**{name: getattr(bank, name)[rows] for name in bank._fields})
            blocks.append((rows, as_kernel_tuples(block_plant, block_params, block_bank, self.bank.kernel_params)))
        return blocks

    # ------------------------------------------------------------------ seeding and reset

    def set_pinning(self, rows, k) -> None:
        """Set the pinning constant k of model (6) (A/m, > 0) of sub-envs ``rows``: the per-row value
        the plant kernel reads, so their next steps follow (6) with it. The estimator and the
        observation scales do not depend on k."""
        k = np.asarray(k, dtype=np.float64)
        if not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise ValueError(f"set_pinning: k must be finite and > 0 (A/m), got {k!r}")
        self._k[rows] = k

    @property
    def pinning(self) -> np.ndarray:
        """The pinning constant k (A/m) of every sub-env (a copy)."""
        return self._k.copy()

    def shift_temperature(self, rows, change) -> None:
        """Step the coil and its surroundings of sub-envs ``rows`` by ``change`` (K) mid-episode (a mount
        change): temperature, ambient and a = a(T) move together; the next step starts from them."""
        self.temperature[rows] += change
        self.ambient0[rows] += change
        self.a_true[rows] = self.config.a_of(self.temperature[rows])

    def set_generator(self, row: int, generator: np.random.Generator) -> None:
        """Give sub-env ``row`` its seeded generator (its two streams are spawned from it)."""
        self.episode_rngs[row], self.noise_rngs[row] = spawn_streams(generator)
        self._noise_pos[row] = NOISE_BLOCK

    def reset(self, rows, options: dict | None = None) -> None:
        """Start new episodes in sub-envs ``rows`` (array of int), drawing from their streams.
        ``options``: :meth:`_checked_options` (``initial_temperature`` may hold one value per row)."""
        config = self.config
        rows = np.asarray(rows, dtype=np.int64)
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"reset: options must be a dict or None, got {type(options).__name__} "
                             f"{_brief_repr(options)}")
        options = self._checked_options(options or {}, rows.shape[0])
        d_lo, d_hi = config.ambient_drift_rate_range
        fractions = np.zeros(rows.shape[0])
        for i, row in enumerate(rows):
            rng = self.episode_rngs[row]
            if rng is None:
                raise RuntimeError("reset: sub-env has no generator; call set_generator first")
            draws = rng.random(2)
            fractions[i] = draws[0]
            self.drift_rate[row] = d_lo + (d_hi - d_lo) * draws[1]
            if config.schedule == "prbs" and self.mode == ESTIMATION:
                self.prbs_bits[row] = np.where(rng.random(self.prbs_bits.shape[1]) < 0.5, -1.0, 1.0)
            if self.pinning_prior is not None:  # drawn even when the option fixes k: the streams stay aligned
                self._k[row] = self.pinning_prior.draw(rng.random())
            self._noise_pos[row] = NOISE_BLOCK  # a new episode starts a new noise block
        self.temperature[rows] = self._start_temperature(fractions, options)
        if PINNING_OPTION in options:
            self._k[rows] = options[PINNING_OPTION]
        if "ambient_drift_rate" in options:
            self.drift_rate[rows] = options["ambient_drift_rate"]
        self.ambient0[rows] = self.temperature[rows]
        self.a_true[rows] = config.a_of(self.temperature[rows])
        self.field[rows] = 0.0
        self.magnetization[rows] = 0.0
        self.state[rows] = 0.0
        self.steps[rows] = 0
        a_estimate = options.get("a_estimate", config.initial_estimate)
        self._measure(rows)
        if self.estimator is not None:
            measured = self.measured[rows] if config.is_mechanical else self.measured[rows, 0]
            self.estimator.reset(a_estimate=a_estimate, field=0.0, output=measured, magnetization=0.0,
                                 indices=rows)
            self.a_estimate[rows] = self.estimator.a_estimate[rows]
        else:
            self.bank.reset(0.0, 0.0, rows)
            self.a_estimate[rows] = a_estimate
        if self.record:
            for row in rows:
                self.history[row] = []
        self._out["penalty"][rows] = 0.0
        self._fill_info(rows, self._out["penalty"])
        self._obs_fresh = False
        if self.record:
            self._record(rows)

    def _start_temperature(self, fractions: np.ndarray, options: dict) -> np.ndarray:
        """The start temperatures (K) of the reset rows: the one place they are set. In order of precedence:
        the option ``initial_temperature``, the option ``a_true``, the config's ``a_true``, the draw
        ``fractions`` (uniform in [0, 1)) shaped by the temperature prior over ``initial_temperature_range``."""
        config = self.config
        if "initial_temperature" in options:
            return np.broadcast_to(options["initial_temperature"], fractions.shape)
        if "a_true" in options:
            return np.full(fractions.shape, config.temperature_for_a(options["a_true"]))
        if config.a_true is not None:
            return np.full(fractions.shape, config.temperature_for_a(config.a_true))
        t_lo, t_hi = config.initial_temperature_range
        if self.temperature_quantile is not None:
            # one call for all the rows: elementwise arithmetic, so a row's value does not depend on the others
            # (tests/envs/test_posterior_speed.py checks it against the call per row)
            fractions = np.asarray(self.temperature_quantile(fractions), dtype=np.float64)
        return t_lo + (t_hi - t_lo) * fractions

    def _checked_options(self, options: dict, n_rows: int = 1) -> dict:
        """The reset options as floats, each checked against the range the config makes
        physical; a ``ValueError`` naming the option and its range otherwise.

        * ``initial_temperature`` (K): in (0, temperature_limit]: a start above the limit
          would end the episode on its first step;
        * ``a_true`` (A/m): in (0, a(temperature_limit)], since a(T) = a_reference*T/T_ref;
        * ``a_estimate`` (A/m): in Theta = [theta_min, theta_max], as ``initial_estimate``;
        * ``ambient_drift_rate`` (K/s): any finite number (a fast drift is a legitimate
          stress test; it ends the episode at the temperature limit);
        * ``pinning_k`` (A/m, > 0; only with a ``pinning_prior``): the episode's k, in place of the draw.

        ``initial_temperature`` may be a 1-D array with one value per reset row (``n_rows``).

        The hysteresis model must also be valid at the resulting ``a`` (checked by the
        physics layer, which names the parameter).
        """
        config = self.config
        allowed = RESET_OPTIONS + ((PINNING_OPTION,) if self.pinning_prior is not None else ())
        unknown = set(options) - set(allowed)
        if unknown:
            raise ValueError(f"reset: unknown option(s) {sorted(unknown)}; expected initial_temperature (K), "
                             f"ambient_drift_rate (K/s), a_true (A/m), a_estimate (A/m)"
                             + (f", {PINNING_OPTION} (A/m)" if self.pinning_prior is not None else ""))
        a_max = float(config.a_of(config.temperature_limit))
        ranges = {  # name -> (low, high, low inclusive, unit, why)
            "initial_temperature": (0.0, config.temperature_limit, False, "K",
                                    f"above 0 K, at most temperature_limit = {config.temperature_limit:g} K"),
            "a_true": (0.0, a_max, False, "A/m",
                       f"a = a_reference*T/T_ref for T in (0, temperature_limit = {config.temperature_limit:g} K]"),
            "a_estimate": (config.theta_min, config.theta_max, True, "A/m", "Theta = [theta_min, theta_max]"),
            "ambient_drift_rate": (-math.inf, math.inf, True, "K/s", "finite"),
        }
        checked = {}
        for name, value in options.items():
            if name == PINNING_OPTION:
                checked[name] = _checked_pinning(value)
            elif name == "initial_temperature" and isinstance(value, np.ndarray) and value.ndim == 1:
                # one start temperature per reset row (a grid of simulators started at its nodes)
                if value.shape[0] != n_rows:
                    raise ValueError(f"reset option initial_temperature has {value.shape[0]} values for {n_rows} "
                                     "rows; give one number or one per reset row")
                checked[name] = np.array([_checked_number(name, v, ranges[name]) for v in value])
            else:
                checked[name] = _checked_number(name, value, ranges[name])
        temperature = None
        if "a_true" in checked:
            temperature = config.temperature_for_a(checked["a_true"])
        if "initial_temperature" in checked:
            temperature = checked["initial_temperature"]
        if temperature is not None:  # a is monotone in T: the extremes of the rows' starts bound every one
            for value in {float(np.min(temperature)), float(np.max(temperature))}:
                config.hysteresis.replace(a=float(config.a_of(value)))  # raises naming the parameter
        return checked

    # ------------------------------------------------------------------ stepping

    def as_actions(self, actions) -> np.ndarray:
        """``actions`` as a float64 array of shape (n, action_size); a ``ValueError`` naming
        the expected and the given shape (or saying the actions are not numbers) otherwise."""
        return action_array(actions, self._clipped.shape, "actions")

    def check_actions(self, actions) -> np.ndarray:
        """Validate normalized actions (shape (n, action_size)); raise naming a bad value."""
        actions = self.as_actions(actions)
        finite = np.isfinite(actions)
        if not finite.all():
            bad = actions[~finite][0]
            raise ValueError(f"action contains {float(bad)!r}: normalized actions must be finite numbers in [-1, 1]")
        outside = np.abs(actions) > 1.0 + ACTION_TOLERANCE
        if outside.any():
            bad = actions[outside][0]
            raise ValueError(f"action value {float(bad)!r} is outside [-1, 1] (normalized; the field command is "
                             f"action*field_limit, the estimate maps [-1, 1] onto Theta)")
        return np.clip(actions, -1.0, 1.0)

    def field_command(self, actions: np.ndarray) -> np.ndarray:
        """Commanded field (A/m) before the limits, at the end of the coming step."""
        config = self.config
        if self.mode == ESTIMATION:
            return self.schedule(self.steps + 1)
        return actions[:, 0] * config.field_limit

    def schedule(self, steps) -> np.ndarray:
        """The excitation schedule of Estimation-v0 at step count ``steps`` (A/m)."""
        config = self.config
        t = np.asarray(steps, dtype=np.float64) * config.dt
        h = config.field_limit
        period = config.schedule_period
        if config.schedule == "ramp":
            return h * config.schedule_amplitude * np.minimum(t / period, 1.0)
        if config.schedule == "sine":
            return h * (config.schedule_offset + config.schedule_amplitude * np.sin(2 * np.pi * t / period))
        if config.schedule == "chirp":
            f0, f1 = 1.0 / period, 1.0 / config.chirp_final_period
            phase = 2 * np.pi * (f0 * t + 0.5 * (f1 - f0) * t * t / config.episode_duration)
            return h * (config.schedule_offset + config.schedule_amplitude * np.sin(phase))
        index = np.minimum((t / period).astype(np.int64), self.prbs_bits.shape[1] - 1)
        bits = self.prbs_bits[self._rows, index]
        return h * (config.schedule_offset + config.schedule_amplitude * bits)

    def step(self, actions, active=None):
        """Advance every sub-env one control period with normalized ``actions`` (n, k).

        Raises ``ValueError`` naming a non-finite action or one outside [-1, 1] (nothing
        changes then). Returns ``(reward, terminated, truncated)`` arrays of shape (n,);
        observations come from :meth:`observation`, per-step truth from :attr:`info`.
        ``active`` (bool mask, default all) marks the sub-envs whose step counts: the
        others are stepped along with the batch but draw no noise (their streams stay as
        they are), and the caller resets them right after.
        """
        reward, terminated, truncated = self.step_views(actions, active)
        return reward.copy(), terminated.copy(), truncated.copy()

    def step_views(self, actions, active=None):
        """:meth:`step` returning live (n,) views, overwritten by the next step."""
        config = self.config
        actions = self.as_actions(actions)
        if active is None:
            active = self._all_active
        if self._noisy and self._noise_pos.max() >= NOISE_BLOCK:
            self._refill_noise(np.flatnonzero((self._noise_pos >= NOISE_BLOCK) & active))
        if self._fused:
            status = excitation_step(actions, active, *self._fused_tuples)
            if status == 1:
                self.check_actions(actions)  # raises, naming the value
            if status == 2:
                raise ValueError("step: the simulated field or output is not finite")
        elif self.mode == IDENTIFICATION and self._plant_blocks:
            # identification_step in three parts, the middle one (the plants and the model bank) in blocks of
            # sub-envs in threads once it runs compiled (its first call, which may compile it or stand in with its
            # Python twin, and the twin itself run here, one call for all)
            if not identification_commands(actions, *self._command_tuples):
                self.check_actions(actions)  # raises, naming the value
            if getattr(identification_plants, "overloads", None):
                self._threads.run(self._step_plants, [(rows, active[rows], arguments)
                                                      for rows, arguments in self._plant_blocks])
            else:
                identification_plants(self._command, active, *self._plants_tuples)
            finish_step(*self._finish_tuples)
        elif self.mode == IDENTIFICATION:
            if identification_step(actions, active, *self._identification_tuples):
                self.check_actions(actions)  # raises, naming the value
        else:
            if not clip_actions(actions, ACTION_TOLERANCE, self._clipped):
                self.check_actions(actions)  # raises, naming the value
            command = (self.schedule(self.steps + 1) if self.mode == ESTIMATION
                       else self._clipped[:, 0] * config.field_limit)
            plant_step(command, active, *self._plant_tuples)
            if self.estimator is not None:
                self.a_estimate[:] = self.estimator.update(self.field, self.measured, config.dt)
            else:
                self.bank.advance(self.field)
            finish_step(*self._finish_tuples)
        self._obs_fresh = True
        if self.record:
            self._record(self._rows)
        out = self._out
        return out["reward"], out["terminated"], out["truncated"]

    def _step_plants(self, rows, active, arguments) -> None:
        """:func:`~.kernels.identification_plants` of one block of sub-envs (in a thread)."""
        identification_plants(self._command[rows], active, *arguments)

    def _refill_noise(self, rows):
        for row in rows:
            self._noise[row] = self.noise_rngs[row].standard_normal((NOISE_BLOCK, self._noise_width))
            self._noise_pos[row] = 0

    def _measure(self, rows):
        """Noisy measured outputs (and temperature) of ``rows`` at the current state."""
        outputs = self.model.output(self.state[rows])
        if self.config.is_mechanical:
            self.measured[rows, 0] = outputs
            self.measured[rows, 1] = self.model.velocity(self.state[rows])
        else:
            self.measured[rows, 0] = outputs
        self.measured_temperature[rows] = self.temperature[rows]
        if not self._noisy:
            return
        empty = rows[self._noise_pos[rows] >= NOISE_BLOCK]
        for row in empty:
            self._noise[row] = self.noise_rngs[row].standard_normal((NOISE_BLOCK, self._noise_width))
            self._noise_pos[row] = 0
        noise = self._noise[rows, self._noise_pos[rows]] * self._noise_sigma
        self._noise_pos[rows] += 1
        self.measured[rows] += noise[:, :self.n_outputs]
        if self.config.temperature_sensor:
            self.measured_temperature[rows] += noise[:, self.n_outputs]

    # ------------------------------------------------------------------ observations and info

    def observation(self) -> np.ndarray:
        """Normalized observations of all sub-envs, float32 of shape (n, obs_size) (a new array)."""
        if not self._obs_fresh:
            self._fill_observation()
        return self._obs.copy()

    def _fill_observation(self):
        fill_observation(self._obs, self._plant, self._view, self._layout)
        self._obs_fresh = True

    def _fill_info(self, rows, penalty):
        """Per-step truth of ``rows`` (all if None) into :attr:`info_array`; ``penalty`` is (n,)."""
        config = self.config
        rows = self._rows if rows is None else rows
        np.clip(self.a_true, config.theta_min, config.theta_max, out=self._theta)
        value, slope, second = self._pe
        if self.estimator is not None:
            view = self._view  # the estimator's f(u, thetahat) and curvature at thetahat
        else:
            self.bank.evaluate(self.a_estimate, value, slope, second)
            view = self._view._replace(value_hat=value.copy(), curvature=second.copy())
        self.bank.evaluate(self._theta, value, slope, second)
        fill_info(self.info_array, rows, self._plant, view, value, penalty, self._score)

    @property
    def info(self) -> dict:
        """Per-step truth of all sub-envs: key -> (n,) array view (copy before keeping)."""
        return dict(zip(INFO_KEYS, self.info_array))

    def info_of(self, row: int) -> dict:
        """The info dict of one sub-env, with Python floats."""
        return dict(zip(INFO_KEYS, self.info_array[:, row].tolist()))

    def _record(self, rows):
        for row in rows:
            self.history[row].append({"time": float(self.steps[row] * self.config.dt),
                                      "field": float(self.field[row]),
                                      "magnetization": float(self.magnetization[row]),
                                      "output": float(self.model.output(self.state[row:row + 1])[0]),
                                      "a_true": float(self.a_true[row]),
                                      "a_estimate": float(self.a_estimate[row]),
                                      "temperature": float(self.temperature[row])})


__all__ = ["BatchSimulator", "EXCITATION", "ESTIMATION", "IDENTIFICATION", "INFO_KEYS", "MODES",
           "NOISE_BLOCK", "RESET_OPTIONS", "action_array", "estimator_config", "estimator_plant", "observation_names",
           "output_scales", "step_kernels", "uses_fused_step"]
