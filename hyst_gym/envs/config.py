"""The frozen configuration of the hyst-gym environments.

One :class:`EnvConfig` describes everything the three environments simulate. Names of
nested objects are those of the physics and estimation layers:

* ``hysteresis``: :class:`~hyst_gym.physics.HysteresisParams` (its ``a`` is *not* used:
  the true ``a`` follows the temperature, ``a(T) = a_reference*T/T_ref``, eq. (4));
* ``transducer``: one of :class:`~hyst_gym.physics.FirstOrderPlant`,
  :class:`~hyst_gym.physics.LumpedLinear` (13), :class:`~hyst_gym.physics.LumpedNonlinear`
  (12), :class:`~hyst_gym.physics.FEMRod` (10); or the short names ``"first_order"``,
  ``"lumped"``, ``"lumped_nonlinear"``, ``"fem"`` for their defaults;
* ``thermal``: :class:`~hyst_gym.physics.ThermalParams` (coil, heat path and a(T); its
  ``ambient_temperature`` and ``ambient_drift_rate`` are replaced by per-episode draws).

Defaults (chosen so the default ``Excitation-v0`` is the paper's §4.1 case and fast):
first-order plant ``y' = -100*y + M``, control period 10 ms, 1000 steps (10 s), field
limit 1e5 A/m (the paper's ramp end), slew limit 5e4 A/m/s (500 A/m per step; the
paper's ramp, 1.67e4 A/m/s, fits), Theta = [6300, 7300] A/m, min-max estimator with 32
bank nodes, hysteresis substeps of at most 250 A/m (a full-slew step costs 2 substeps
per model; on the paper's ramp the midpoint rule is then within 6e-5 Ms = 46 A/m of the
converged answer, i.e. about 5 A/m of ``a``; plant and bank share this discretization),
ambient 5..25 C drifting by at most +-0.05 K/s.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..physics import (FEMRod, FirstOrderPlant, HysteresisParams, LumpedLinear, LumpedNonlinear,
                       ThermalParams, temperature_of_a)
from ..estimation.estimators import ESTIMATORS
from ..physics.thermal import a_law

TRANSDUCER_NAMES = {
    "first_order": FirstOrderPlant,
    "lumped": LumpedLinear,
    "lumped_nonlinear": LumpedNonlinear,
    "fem": FEMRod,
}
TEMPERATURE_MODES = ("drifting", "fixed")
SCHEDULES = ("ramp", "sine", "chirp", "prbs")
ESTIMATOR_NAMES = tuple(ESTIMATORS)  # the registry of the estimation layer, in its order

#: Default adaptation gain gamma of the vector estimator (24)-(25) in the envs (mechanical
#: transducers), units of y_eps^-1 s^-1 per (A/m per A/m). The paper's 5e10 (§4.2) is a
#: continuous-time, noise-free gain, and it fails at the env's defaults for two reasons
#: (measured on the paper's ramp, a = 7012, thetahat(0) = 6990; the lumped scenario):
#:
#: * sampled-data instability: with y_eps = B^T P ytilde the adaptation rate is about
#:   gamma*B^T P (-A^-1 B)*phi**2 = gamma*2.28e-10*phi**2, up to 1.2e3 1/s on the ramp
#:   (|phi| <= 10). Its explicit Euler step needs rate*dt < 2: at dt = 1 ms (the paper's
#:   reproduction) rate*dt = 1.1 and it settles in 0.39 s; at the env's 10 ms it is 12,
#:   and the estimate slams between the ends of Theta even without noise;
#: * noise: the vector law (24) has no dead zone on thetahat, and 1e-4 output noise on
#:   (displacement, velocity) gives B^T P noise of 2.5e-8 per sample, which gamma = 5e10
#:   turns into a 30 A/m random walk even at dt = 1 ms (band: 7 A/m).
#:
#: 1e8 is the gain, on a 1-2-3 grid from 3e7 to 5e10, with the shortest settle time into
#: the 0.1 % band at dt = 10 ms and output_noise = 1e-4 (about 3.5 s, like the scalar
#: estimator's 4.4 s on the same ramp); 2e8 already leaves the band again from noise.
#: Set ``estimator_gamma`` to change it (e.g. 5e10 with dt = 1e-3 and no noise).
MECHANICAL_ESTIMATOR_GAMMA = 1.0e8


def _number(owner, name, value, *, positive=False, nonnegative=False):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{owner}: {name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{owner}: {name} must be finite, got {value!r}")
    if positive and not value > 0:
        raise ValueError(f"{owner}: {name} must be > 0, got {value!r}")
    if nonnegative and not value >= 0:
        raise ValueError(f"{owner}: {name} must be >= 0, got {value!r}")
    return value


def _range(owner, name, value, *, positive=False):
    try:
        lo, hi = value
    except (TypeError, ValueError):
        raise ValueError(f"{owner}: {name} must be a pair (low, high), got {value!r}") from None
    lo = _number(owner, f"{name}[0]", lo, positive=positive)
    hi = _number(owner, f"{name}[1]", hi, positive=positive)
    if hi < lo:
        raise ValueError(f"{owner}: {name} = ({lo!r}, {hi!r}) has high < low")
    return (lo, hi)


def _integer(owner, name, value, minimum):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{owner}: {name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class EnvConfig:
    """Everything the hyst-gym environments simulate. Frozen and validated; SI units.

    Attributes
    ----------
    hysteresis : HysteresisParams
        Domain-wall model (6); ``a`` is ignored (it follows the temperature, eq. (4)).
    transducer : FirstOrderPlant | LumpedLinear | LumpedNonlinear | FEMRod | str
        Output dynamics driven by M. Measured outputs: ``y`` (first-order plant), or tip
        displacement (m) and velocity (m/s) (the mechanical models).
    thermal : ThermalParams
        Coil and heat path; ``a(T) = thermal.a_reference*T/thermal.reference_temperature``.
    temperature_mode : str
        ``"drifting"``: Joule heating ``R*(H/n)**2`` plus a linearly drifting ambient;
        ``"fixed"``: the temperature keeps its initial value for the whole episode.
    initial_temperature_range : (float, float)
        K. The initial temperature (and the initial ambient) is drawn uniformly from it
        at every reset with the env's seeded generator. Default 278.15..298.15 K (5..25 C),
        so ``a`` starts in 6653..7132 A/m.
    ambient_drift_rate_range : (float, float)
        K/s. The ambient drift rate, drawn uniformly at every reset. Default +-0.05 K/s.
    a_true : float or None
        A/m. If set, the initial temperature is the one that gives this ``a`` (the draw
        from ``initial_temperature_range`` still happens, so random streams do not shift).
        Use with ``temperature_mode="fixed"`` for the paper's constant-a case (7012).
    dt : float
        Control period, s. Default 0.01.
    episode_steps : int
        Control steps per episode (the time limit). Default 1000 (10 s).
    field_limit : float
        |H| <= field_limit, A/m. Actions are normalized to it. Default 1e5.
    slew_rate_limit : float
        |dH/dt| <= slew_rate_limit, A/m/s: the coil cannot jump. Default 5e4.
    theta_min, theta_max : float
        Theta = [theta_min, theta_max], A/m: the parameter box of the estimator and the
        range the estimate action is normalized to. Paper: [6300, 7300].
    initial_estimate : float
        thetahat(0) of the built-in estimator, A/m. Paper: 6990.
    estimator : str
        Built-in estimator of Excitation-v0: ``"minmax"`` (default), ``"gradient"`` or
        ``"multiple_model"`` (see :mod:`hyst_gym.estimation.estimators`).
    estimator_grid_size : int
        Bank nodes over Theta (16..128). Default 32.
    estimator_eps, estimator_gamma : float or None
        Dead-zone width and adaptation gain; ``None``: the estimation layer's defaults for
        the plant the estimator assumes, except gamma of the vector estimator (mechanical
        transducers): :data:`MECHANICAL_ESTIMATOR_GAMMA` = 1e8, not the paper's 5e10,
        which is unstable at this control period and amplifies the output noise.
    max_field_step : float
        Largest hysteresis substep, A/m, for the true plant and for the bank. Default 250
        (second-order error, 6e-5 Ms on the paper's ramp; 25 A/m gives 6e-7 Ms at 10x cost).
    output_noise : float
        Standard deviation of the additive Gaussian noise on each measured output, as a
        fraction of that output's normalization scale (the output at M = Ms). Default 1e-4.
    stroke_limit : float or None
        |output| above this terminates the episode (m for the mechanical models, units of
        y for the first-order plant). ``None``: no stroke constraint (default; y of the
        first-order plant is not a stroke).
    temperature_limit : float
        K. A temperature above this terminates the episode. Default 333.15 (60 C).
    stroke_penalty_band : float
        Fraction of ``stroke_limit`` below it where the stroke penalty starts. Default 0.1.
    temperature_penalty_band : float
        K below ``temperature_limit`` where the temperature penalty starts. Default 5.
    penalty_weight : float
        Weight of the quadratic constraint penalties (dimensionless). Default 1.
    temperature_sensor : bool
        If True, the measured temperature enters the observation. Default False.
    temperature_sensor_noise : float
        K, standard deviation of the temperature sensor's noise. Default 0.05.
    schedule : str
        Excitation of Estimation-v0: ``"ramp"`` (paper), ``"sine"``, ``"chirp"``, ``"prbs"``.
    schedule_amplitude : float
        Fraction of ``field_limit``. Default 1.0.
    schedule_offset : float
        Fraction of ``field_limit`` added to sine/chirp/PRBS. Default 0.
    schedule_period : float
        s. Ramp: time to reach the amplitude (paper: 6 s); sine: period; chirp: initial
        period; PRBS: bit length. Default 6.
    chirp_final_period : float
        s, the chirp's period at the end of the episode. Default 1.
    """

    hysteresis: HysteresisParams = field(default_factory=HysteresisParams)
    transducer: object = field(default_factory=FirstOrderPlant)
    thermal: ThermalParams = field(default_factory=ThermalParams)
    temperature_mode: str = "drifting"
    initial_temperature_range: tuple = (278.15, 298.15)
    ambient_drift_rate_range: tuple = (-0.05, 0.05)
    a_true: float | None = None
    dt: float = 0.01
    episode_steps: int = 1000
    field_limit: float = 1.0e5
    slew_rate_limit: float = 5.0e4
    theta_min: float = 6300.0
    theta_max: float = 7300.0
    initial_estimate: float = 6990.0
    estimator: str = "minmax"
    estimator_grid_size: int = 32
    estimator_eps: float | None = None
    estimator_gamma: float | None = None
    max_field_step: float = 250.0
    output_noise: float = 1.0e-4
    stroke_limit: float | None = None
    temperature_limit: float = 333.15
    stroke_penalty_band: float = 0.1
    temperature_penalty_band: float = 5.0
    penalty_weight: float = 1.0
    temperature_sensor: bool = False
    temperature_sensor_noise: float = 0.05
    schedule: str = "ramp"
    schedule_amplitude: float = 1.0
    schedule_offset: float = 0.0
    schedule_period: float = 6.0
    chirp_final_period: float = 1.0

    def __post_init__(self):
        self._check_models()
        self._check_numbers()
        self._check_choices()
        self._check_consistency()

    def _set(self, name, value) -> None:
        object.__setattr__(self, name, value)

    def _check_models(self) -> None:
        """The physics objects: hysteresis, transducer (a name becomes its object), thermal model."""
        owner = "EnvConfig"
        setattr_ = self._set
        if not isinstance(self.hysteresis, HysteresisParams):
            raise ValueError(f"{owner}: hysteresis must be a HysteresisParams, got {self.hysteresis!r}")
        transducer = self.transducer
        if isinstance(transducer, str):
            if transducer not in TRANSDUCER_NAMES:
                raise ValueError(f"{owner}: transducer {transducer!r} is unknown; expected one of "
                                 f"{sorted(TRANSDUCER_NAMES)} or a physics transducer object")
            transducer = TRANSDUCER_NAMES[transducer]()
        if not isinstance(transducer, tuple(TRANSDUCER_NAMES.values())):
            raise ValueError(f"{owner}: transducer must be FirstOrderPlant, LumpedLinear, LumpedNonlinear or "
                             f"FEMRod, got {transducer!r}")
        setattr_("transducer", transducer)
        if not isinstance(self.thermal, ThermalParams):
            raise ValueError(f"{owner}: thermal must be a ThermalParams, got {self.thermal!r}")

    def _check_numbers(self) -> None:
        """Every number: ranges, positive and non-negative fields, integers, Theta and the initial estimate."""
        owner = "EnvConfig"
        setattr_ = self._set
        if self.temperature_mode not in TEMPERATURE_MODES:
            raise ValueError(f"{owner}: temperature_mode must be one of {TEMPERATURE_MODES}, "
                             f"got {self.temperature_mode!r}")
        setattr_("initial_temperature_range",
                 _range(owner, "initial_temperature_range", self.initial_temperature_range, positive=True))
        setattr_("ambient_drift_rate_range", _range(owner, "ambient_drift_rate_range", self.ambient_drift_rate_range))
        if self.a_true is not None:
            setattr_("a_true", _number(owner, "a_true", self.a_true, positive=True))
        for name in ("dt", "field_limit", "slew_rate_limit", "max_field_step", "temperature_limit",
                     "stroke_penalty_band", "temperature_penalty_band", "schedule_period", "chirp_final_period"):
            setattr_(name, _number(owner, name, getattr(self, name), positive=True))
        for name in ("output_noise", "penalty_weight", "temperature_sensor_noise", "schedule_amplitude"):
            setattr_(name, _number(owner, name, getattr(self, name), nonnegative=True))
        setattr_("schedule_offset", _number(owner, "schedule_offset", self.schedule_offset))
        setattr_("episode_steps", _integer(owner, "episode_steps", self.episode_steps, 1))
        setattr_("estimator_grid_size", _integer(owner, "estimator_grid_size", self.estimator_grid_size, 16))
        lo = _number(owner, "theta_min", self.theta_min, positive=True)
        hi = _number(owner, "theta_max", self.theta_max, positive=True)
        if not hi > lo:
            raise ValueError(f"{owner}: Theta = [theta_min, theta_max] = [{lo!r}, {hi!r}] is empty")
        setattr_("theta_min", lo)
        setattr_("theta_max", hi)
        estimate = _number(owner, "initial_estimate", self.initial_estimate)
        if not lo <= estimate <= hi:
            raise ValueError(f"{owner}: initial_estimate = {estimate!r} lies outside Theta = [{lo!r}, {hi!r}]")
        setattr_("initial_estimate", estimate)
        if self.stroke_limit is not None:
            setattr_("stroke_limit", _number(owner, "stroke_limit", self.stroke_limit, positive=True))

    def _check_choices(self) -> None:
        """The named choices: estimator (and its optional numbers), temperature sensor, schedule."""
        owner = "EnvConfig"
        setattr_ = self._set
        if self.estimator not in ESTIMATOR_NAMES:
            raise ValueError(f"{owner}: estimator {self.estimator!r} is unknown; expected one of {ESTIMATOR_NAMES}")
        for name in ("estimator_eps", "estimator_gamma"):
            if getattr(self, name) is not None:
                setattr_(name, _number(owner, name, getattr(self, name), positive=True))
        if not isinstance(self.temperature_sensor, (bool, np.bool_)):
            raise ValueError(f"{owner}: temperature_sensor must be True or False, got {self.temperature_sensor!r}")
        if self.schedule not in SCHEDULES:
            raise ValueError(f"{owner}: schedule must be one of {SCHEDULES}, got {self.schedule!r}")

    def _check_consistency(self) -> None:
        owner = "EnvConfig"
        # Physical consistency: the hysteresis model must be valid for every a the
        # episode can produce (validation raises naming the parameter), and the
        # temperature limit must lie above the initial temperatures.
        for temperature in self.initial_temperature_range:
            self.hysteresis.replace(a=self.a_of(temperature))
        if self.a_true is not None:
            self.hysteresis.replace(a=self.a_true)
        if self.temperature_limit <= self.initial_temperature_range[1] and self.temperature_mode == "drifting":
            raise ValueError(f"{owner}: temperature_limit = {self.temperature_limit!r} K is not above the "
                             f"initial temperatures {self.initial_temperature_range} K")

    # ------------------------------------------------------------------ helpers

    @property
    def theta_width(self) -> float:
        """width(Theta), A/m."""
        return self.theta_max - self.theta_min

    @property
    def episode_duration(self) -> float:
        """Simulated seconds per episode."""
        return self.dt * self.episode_steps

    @property
    def max_field_change(self) -> float:
        """Largest field change in one control step, A/m (slew limit times dt)."""
        return self.slew_rate_limit * self.dt

    @property
    def is_mechanical(self) -> bool:
        """True when the outputs are (tip displacement m, tip velocity m/s)."""
        return not isinstance(self.transducer, FirstOrderPlant)

    @property
    def transducer_name(self) -> str:
        return next(name for name, cls in TRANSDUCER_NAMES.items() if type(self.transducer) is cls)

    def a_of(self, temperature):
        """a(T) = a_reference*T/T_ref, A/m (eq. 4), for T in K."""
        return a_law(self.thermal.a_reference, np.asarray(temperature, dtype=np.float64),
                     self.thermal.reference_temperature)

    def temperature_for_a(self, a):
        """The temperature (K) at which the material has ``a`` (A/m)."""
        return temperature_of_a(a, self.thermal)

    def replace(self, **changes) -> "EnvConfig":
        """A validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    def summary(self) -> str:
        """A one-line human summary of the main settings (benchmarks print it)."""
        return (f"transducer={self.transducer_name} dt={self.dt:g}s episode_steps={self.episode_steps} "
                f"field_limit={self.field_limit:g}A/m slew_rate_limit={self.slew_rate_limit:g}A/m/s "
                f"Theta=[{self.theta_min:g},{self.theta_max:g}]A/m estimator={self.estimator}"
                f"(G={self.estimator_grid_size}) max_field_step={self.max_field_step:g}A/m "
                f"temperature={self.temperature_mode} output_noise={self.output_noise:g}")


def make_config(config: EnvConfig | None = None, **overrides) -> EnvConfig:
    """``config`` (default :class:`EnvConfig`) with ``overrides`` applied; unknown names raise."""
    if config is None:
        config = EnvConfig()
    elif not isinstance(config, EnvConfig):
        raise ValueError(f"config must be an EnvConfig, got {type(config).__name__}")
    if overrides:
        names = {f.name for f in dataclasses.fields(EnvConfig)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise ValueError(f"unknown EnvConfig field(s) {unknown}; see hyst_gym.envs.EnvConfig")
        config = config.replace(**overrides)
    return config


__all__ = ["ESTIMATOR_NAMES", "EnvConfig", "MECHANICAL_ESTIMATOR_GAMMA", "SCHEDULES", "TEMPERATURE_MODES",
           "TRANSDUCER_NAMES", "make_config"]
