"""The mismatch tool's vocabulary: one frozen :class:`Effect` per effect, in one registry.

Every stage reads what it needs about an effect from here: the model its parameters (ranges and
starts), the hypothesize stage its fit strategy, starts and rescue, the decision its main parameter
and plausibility checks, the identifiability tables its rate dependence and confusable partners, the
report its slot and words. What is *not* here is the effect's forward term (the kernel, in
:mod:`.model`, which reads parameters by name) and its generator (:mod:`.make_recording`). A new
effect touches this registry, the kernel, the generator and a test (``docs/architecture.md``).

Each field is required unless it says otherwise, so a forgotten entry fails when the module is
imported, not later as a check that silently does not run. The registry's order is the order in
which the candidates are tried and reported.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field as dataclass_field
from types import MappingProxyType

import numpy as np

from ..physics.constants import PAPER_STIFFNESS, ROOM_TEMPERATURE
from .kernels import lagged_rise_trace
from .parameter import Parameter, slope_factor

#: Saturation magnetization (A/m) assumed where a record has no magnetization channel.
PAPER_MS = 7.65e5
#: The channel sets a recording can have (:func:`.identifiability.channel_set`).
CHANNEL_SETS = ("magnetization", "displacement", "both")
#: Parameter names of the per-channel families (one set per output channel).
SENSOR_MAP_NAMES = {"magnetization": ("sensor_quadratic_m", "sensor_cubic_m"),
                    "displacement": ("sensor_quadratic_x", "sensor_cubic_x")}
#: The sensor offset drift's coefficients per channel: the offset d1*f + d2*f^2 + d3*(1 - exp(-f/tau_drift)) in units
#: of the channel's half-span (f: the record's time mapped to [0, 1]), the settling term's basis the gain drift's
#: (:func:`.model.settling`).
DRIFT_NAMES = {"magnetization": ("drift_linear_m", "drift_quadratic_m", "drift_settling_m"),
               "displacement": ("drift_linear_x", "drift_quadratic_x", "drift_settling_x")}
#: The sensor gain drift's coefficients per channel, in the order :func:`.model.gain_drift_factor` takes them:
#: the relative gain change g1*f + g2*(1 - exp(-f/tau_gain)) (f: the record's time mapped to [0, 1]).
GAIN_DRIFT_NAMES = {"magnetization": ("gain_drift_linear_m", "gain_drift_settling_m"),
                    "displacement": ("gain_drift_linear_x", "gain_drift_settling_x")}
MAINS_NAMES = {ch: tuple(f"{term}_{ch[0]}" for term in ("mains_cos", "mains_sin", "mains3_cos", "mains3_sin"))
               for ch in ("magnetization", "displacement")}
#: The magnetostriction law's even terms beyond the M^2 one (:func:`.model.even_law_forcing`): name -> power n of
#: the term zeta_n*Ms*((M/Ms)^n - (M0/Ms)^n) (zeta_n in the gain's units). With zeta_q's (M - M0)^2 and the linear
#: term they make the law a quartic in M/Ms: one that saturates (lambda flattens toward Ms) or rises faster than
#: M^2; 0 is the M^2 law. Why not a sixth power too: on a slow record a stiffness that follows M (delta_e, a
#: quartic in M/Ms) bends the displacement as a law of M does, and a law one degree more flexible than the
#: stiffness fitted a Delta-E dip better than the stiffness's own family (the other-forms study's sech dip named
#: a magnetostriction law, a right verdict turned wrong); at equal degree the two tie there, as they should. The
#: stiffness has a cubic term besides (delta_e_cubic), which the even law cannot have: it fits laws about a centre
#: away from M = 0 that are not parabolas there, and on the other-forms study it changed no verdict on a
#: magnetostriction-law or sensor-map record (it turned two such stand-in names on Delta-E records into ties).
EVEN_LAW_POWERS = MappingProxyType({"zeta_4": 4})
EVEN_LAW_NAMES = tuple(EVEN_LAW_POWERS)
#: The input map's coefficients in the order :func:`.model.mapped_field` takes them.
INPUT_MAP_NAMES = ("input_quadratic", "input_cubic", "input_saturation", "input_saturation_negative")
#: The input dynamics' lag and delay (s), in the order :func:`.model.input_dynamics` takes them. Its pair of poles
#: (tau2_in) is not fitted: with it the input_lag fit ran for minutes on some records of the other-forms study.
INPUT_DYNAMICS_NAMES = ("tau_in", "delay_in")
#: The Delta-E family's coefficients (:func:`.model.relative_stiffness_change`).
DELTA_E_NAMES = ("delta_e", "delta_e_linear", "delta_e_cubic", "delta_e_quartic")
#: The sensor dynamics' time constants per channel (s): 1/(1 + tau*s + tau2^2*s^2) (:func:`.model.sensor_dynamics`).
SENSOR_DYNAMICS_NAMES = {"magnetization": ("tau_m", "tau2_m"), "displacement": ("tau_x", "tau2_x")}
#: Mains pickup needs this many cycles in the record (a sinusoid of known frequency is fixed by a few)
#: and its third harmonic below the Nyquist frequency.
MAINS_MIN_CYCLES = 3


# ---------------------------------------------------------------------------- which parameter identifies it


def sample_interval(recording) -> float:
    """s: the record's median sample interval, below which a time constant does nothing the record can see."""
    return float(np.median(np.diff(recording.time)))


@dataclass(frozen=True)
class FirstFiltering:
    """A per-channel filter is identified by the time constant ``tau`` of the first channel of ``channels`` that
    is free and filters: where the channel's ``tau`` and ``tau2`` (:data:`SENSOR_DYNAMICS_NAMES`) are both below
    one sample interval it reads true, and its tau, near 0 wherever the record is cut, would pass the block check
    for nothing. Else the first free one (else the last's)."""

    channels: tuple

    def choose(self, fit, effect) -> str:
        parameters, values = fit.model.parameters, fit.values
        free = [SENSOR_DYNAMICS_NAMES[ch] for ch in self.channels if SENSOR_DYNAMICS_NAMES[ch][0] in parameters
                and parameters[SENSOR_DYNAMICS_NAMES[ch][0]].free]
        dt = sample_interval(fit.model.recording)
        filtering = [tau for tau, tau2 in free if max(values[tau], values.get(tau2, 0.0)) >= dt]
        return (filtering or [tau for tau, _ in free] or [SENSOR_DYNAMICS_NAMES[self.channels[-1]][0]])[0]


@dataclass(frozen=True)
class BestDetermined:
    """A family whose shape is spread over several coefficients: the block check refits the one the
    record determines best (largest |value|/sigma), which a real map or drift shares across the blocks
    while a family bent to mimic something else is pulled to different values by each block's
    excitation. ``among``: only these (a shape parameter such as a time constant, which means nothing
    where the coefficients vanish, is left out); None: all of the effect's parameters."""

    among: tuple | None = None

    def choose(self, fit, effect) -> str | None:
        names = effect.parameter_names if self.among is None else self.among
        scored = [(abs(fit.values[n]) / (fit.uncertainties.get(n) or np.inf), n) for n in names
                  if n in fit.model.parameters and fit.model.parameters[n].free]
        scored = [(z if np.isfinite(z) else 0.0, n) for z, n in scored]
        return max(scored)[1] if scored else None


@dataclass(frozen=True)
class WhenPresent:
    """The effect is identified by ``name`` where its value is not zero (a term the fit switched on); where it is
    zero the family's member is a law with no parameter of its own, and ``why`` says so (nothing to refit)."""

    name: str
    why: str

    def choose(self, fit, effect) -> str | None:
        return self.name if fit.values.get(self.name, 0.0) != 0.0 else None


@dataclass(frozen=True)
class NoParameter:
    """The effect swaps a law and adds no parameter: nothing to refit per block. ``why`` says so."""

    why: str

    def choose(self, fit, effect) -> None:
        return None


# ---------------------------------------------------------------------------- the record's scales


@dataclass(frozen=True)
class Frame:
    """The scales of a record that set the parameters' ranges: peak field (A/m), duration (s),
    median step (s) and the absolute field rate per step (A/m/s)."""

    h_max: float
    duration: float
    dt: float
    rate: np.ndarray

    @classmethod
    def of(cls, recording) -> "Frame":
        field, time = recording.field, recording.time
        return cls(h_max=float(np.max(np.abs(field))) or 1.0, duration=float(time[-1] - time[0]),
                   dt=sample_interval(recording), rate=np.abs(np.diff(field)) / np.diff(time))


def _output_free(recording, structure, channel) -> bool:
    """Whether a per-channel parameter of ``channel`` is fitted: the channel is recorded and explained."""
    return channel in recording.channels and (channel == "magnetization" or structure.transducer != "none")


def _has_displacement(recording, structure) -> bool:
    return "displacement" in recording.channels and structure.transducer != "none"


# ---------------------------------------------------------------------------- parameters, per effect
# Each builder: (recording, structure, base values) -> {name: Parameter}, in the order they are fitted.


def _field_bias_parameters(recording, structure, base_values):
    h_max = Frame.of(recording).h_max
    return {"H0": Parameter("H0", 0.0, -h_max, h_max, "A/m", scale=0.01 * h_max)}


def _eddy_parameters(recording, structure, base_values):
    frame = Frame.of(recording)
    ms = base_values.get("Ms", PAPER_MS)
    dm_dt = ms * float(np.percentile(frame.rate, 95)) / frame.h_max + 1e-30
    upper = 2.0 * frame.h_max / dm_dt
    return {"k_e": Parameter("k_e", 1e-3 * upper, 0.0, upper, "s", scale=1e-2 * upper)}


#: 1/K: thermal_drift's coefficients beta_Ms and beta_k start in [-THERMAL_BETA_RANGE, THERMAL_BETA_RANGE]
#: (beta_c in 0.4 of it). A search range, not a physical wall: the second fitting stage widens it to
#: RELATIVE_CHANGE_LIMIT at the first stage's rise. It admits the measured gadolinium near its Curie point
#: (data/real/gd-temperature, Tc 18.3 C: the major loop's largest M falls 3.4 %/K from +5 to +15 C, its coercive
#: field 2.3 %/K); 0.01/K did not.
THERMAL_BETA_RANGE = 0.05
#: The largest relative change of Ms, k or c over the record that thermal_drift may name: |X(T)/X - 1| at most
#: 0.95 at the record's largest fitted temperature rise, the same for every record. Why 0.95, not 0.9: a pinning
#: collapsing toward a Curie point falls by ~90 % (the fit of tests/diagnose/test_time_variation.py's seed 2
#: record: 91 %); a fit that needs more is mimicking something else. Symmetric, as the per-kelvin search ranges are.
RELATIVE_CHANGE_LIMIT = 0.95
#: thermal_drift's coefficients and the parameter each moves.
THERMAL_COEFFICIENTS = (("beta_Ms", "Ms"), ("beta_k", "k"), ("beta_c", "c"))


def thermal_relative_changes(recording, values) -> dict:
    """{coefficient: relative change of its parameter at the record's largest fitted temperature rise},
    ``-beta*max(theta)`` (X(T) = X*(1 - beta*theta), before the kernel's floors), keyed by the coefficient's
    name (beta_Ms, beta_k, beta_c), the parameter a plausibility check names."""
    peak = float(np.max(temperature_rise_trace(recording, values)))
    return {name: -values.get(name, 0.0) * peak for name, _ in THERMAL_COEFFICIENTS}


def _thermal_parameters(recording, structure, base_values):
    frame = Frame.of(recording)
    mean_sq = float(np.mean(recording.field ** 2)) or 1.0
    upper = 300.0 / (mean_sq * frame.duration)  # at most ~300 K of heating over the record
    return {
        "heating": Parameter("heating", 0.01 * upper, 0.0, upper, "K/s per (A/m)^2", scale=0.01 * upper),
        "tau_th": Parameter("tau_th", frame.duration, 5 * frame.dt, 1e3 * frame.duration, "s", log=True),
        # Ms, the pinning k and the reversibility c move with the temperature too (the measured gadolinium loops:
        # k collapses toward the Curie point), linear in the rise, the plain heating law at 0. Their ranges per
        # kelvin are search ranges only (registered as such): the rise is inferred through a ~ T (4), so a record
        # where a barely moves while k moves much infers a small rise and a large coefficient per kelvin. The
        # physical wall is on what the record determines, the relative change over the record
        # (RELATIVE_CHANGE_LIMIT, checked by thermal_relative_changes in the plausibility checks)
        "beta_Ms": Parameter("beta_Ms", 0.0, -THERMAL_BETA_RANGE, THERMAL_BETA_RANGE, "1/K", scale=1e-3),
        "beta_k": Parameter("beta_k", 0.0, -THERMAL_BETA_RANGE, THERMAL_BETA_RANGE, "1/K", scale=1e-3),
        "beta_c": Parameter("beta_c", 0.0, -0.4 * THERMAL_BETA_RANGE, 0.4 * THERMAL_BETA_RANGE, "1/K", scale=1e-3),
        # the family's heating law: drive ~ |H|^p (Joule heating of a current-driven coil: p = 2;
        # core or hysteresis loss: p between 1 and 3)
        "heating_exponent": Parameter("heating_exponent", 2.0, 0.5, 4.0, "1", scale=0.5),
        # the network's second stage (kernels.THERMAL_LAG_COLUMNS): the rod lagging the coil by tau_th2, seeing the
        # share thermal_share of the coil's rise directly; share 1 is the one-stage law (the value a first fit holds)
        "tau_th2": Parameter("tau_th2", 0.3 * frame.duration, frame.dt, 1e3 * frame.duration, "s", log=True),
        "thermal_share": Parameter("thermal_share", 1.0, 0.0, 1.0, "1", scale=0.5),
    }


def _sensor_lag_parameters(recording, structure, base_values):
    # per channel the filter 1/(1 + tau*s + tau2^2*s^2): tau2 = 0 a first-order lag, tau2 > 0 a resonance at
    # 1/(2*pi*tau2) Hz with damping ratio tau/(2*tau2) (a probe or an amplifier that rings); tau2 <= duration/(40*pi)
    # keeps at least 20 cycles of the resonance in the record, and no lower bound is set (tau2 -> 0 is the lag)
    frame = Frame.of(recording)
    out = {}
    for channel, (tau, _) in SENSOR_DYNAMICS_NAMES.items():
        free = _output_free(recording, structure, channel)
        out[tau] = Parameter(tau, frame.dt if free else 0.0, 0.0, 0.05 * frame.duration, "s", scale=frame.dt,
                             free=free)
    for channel, (_, tau2) in SENSOR_DYNAMICS_NAMES.items():
        free = _output_free(recording, structure, channel)
        out[tau2] = Parameter(tau2, 0.0, 0.0, frame.duration / (40 * np.pi), "s", scale=frame.dt, free=free)
    return out


def _quadratic_parameters(recording, structure, base_values):
    m_span = base_values.get("Ms", PAPER_MS)
    gain = abs(next((base_values[g] for g in ("zetahat", "nu", "zeta_fem") if g in base_values), 1.0)) or 1.0
    out = {"zeta_q": Parameter("zeta_q", 0.0, -1e3 * gain / m_span, 1e3 * gain / m_span,
                               "gain units per A/m", scale=0.1 * gain / m_span)}
    # the even terms' coefficients multiply Ms*(M/Ms)^n: the same range as zeta_q's over M = Ms
    out.update({name: Parameter(name, 0.0, -1e3 * gain, 1e3 * gain, "gain units", scale=0.1 * gain)
                for name in EVEN_LAW_NAMES})
    return out


def _delta_e_parameters(recording, structure, base_values):
    return {"delta_e": Parameter("delta_e", 0.0, -0.5, 3.0, "1 (relative stiffness change, M = 0 to Ms)", scale=0.1),
            "delta_e_linear": Parameter("delta_e_linear", 0.0, -3.0, 3.0,
                                        "1 (relative stiffness change per unit M/Ms)", scale=0.1),
            # a cubic term: a law about a centre Mb away from M = 0 that is not a parabola there (|M - Mb|^p with
            # p 1.3-3 expanded about M = 0 has every power); without it the other-forms study's power_shifted
            # records (large stiffness changes) were left at 2.7-4.8 noise units, where the magnetostriction law
            # or the sensor map, standing in, reached 1.2 and were named
            "delta_e_cubic": Parameter("delta_e_cubic", 0.0, -3.0, 3.0,
                                       "1 (relative stiffness change, (M/Ms)^3 from 0 to 1)", scale=0.1),
            # a quartic term: a Delta-E dip narrower than a parabola, flattening toward saturation, and as
            # flexible a static law of M as the magnetostriction law's even terms, which on a slow record bend
            # the displacement alike (without it a better fit there named the family, not the slot)
            "delta_e_quartic": Parameter("delta_e_quartic", 0.0, -3.0, 3.0,
                                         "1 (relative stiffness change, (M/Ms)^4 from 0 to 1)", scale=0.1)}


def _input_map_parameters(recording, structure, base_values):
    # monotone on |u| <= 1 needs 1 + 2*q*u + 3*c*u^2 > 0: c >= -1/3 at q = 0 (a tanh's cubic term);
    # gain at the peak field down to 1/sqrt(1 + 30) = 0.18 of the small-signal gain
    return {
        "input_quadratic": Parameter("input_quadratic", 0.0, -0.5, 0.5, "1 (per unit H/max|H|)", scale=0.05),
        "input_cubic": Parameter("input_cubic", 0.0, -0.33, 1.0, "1 (per unit (H/max|H|)^2)", scale=0.05),
        "input_saturation_negative": Parameter("input_saturation_negative", 0.0, 0.0, 30.0,
                                               "1 (per unit (H/max|H|)^2, where H < 0)", scale=0.5),
        "input_saturation": Parameter("input_saturation", 0.0, 0.0, 30.0, "1 (per unit (H/max|H|)^2, where H >= 0)",
                                      scale=0.5),
    }


def _input_dynamics_parameters(recording, structure, base_values):
    # a coil's L/R or an amplifier's bandwidth: a lag and a transport delay of up to a few % of the record
    frame = Frame.of(recording)
    return {"tau_in": Parameter("tau_in", frame.dt, 0.0, 0.05 * frame.duration, "s", scale=frame.dt),
            "delay_in": Parameter("delay_in", 0.0, 0.0, 0.02 * frame.duration, "s", scale=frame.dt)}


def _per_channel_terms(names_by_channel, lower, upper, scale, unit="1 (of the channel's half-span)"):
    """Builder of a per-output-channel additive or map family with coefficients in ``unit`` (by default
    the channel's half-span), free where the channel is recorded and explained."""
    def build(recording, structure, base_values):
        out = {}
        for channel, names in names_by_channel.items():
            free = _output_free(recording, structure, channel)
            for name in names:
                out[name] = Parameter(name, 0.0, lower, upper, unit, scale=scale, free=free)
        return out
    return build


def _offset_drift_parameters(recording, structure, base_values):
    # the settling time is shared by the channels (one warm-up of the rig), as the gain drift's
    out = {"tau_drift": Parameter("tau_drift", 0.5, 0.03, 10.0, "1 (of the record's length)", log=True)}
    out.update(_per_channel_terms(DRIFT_NAMES, -1.0, 1.0, 0.01)(recording, structure, base_values))
    return out


def _gain_drift_parameters(recording, structure, base_values):
    # the coefficients are relative gain changes (a sensor's gain drifting by up to +-50 % is broken, not
    # drifting); the settling time is shared by the channels (one warm-up of the rig)
    out = {"tau_gain": Parameter("tau_gain", 0.5, 0.03, 10.0, "1 (of the record's length)", log=True)}
    out.update(_per_channel_terms(GAIN_DRIFT_NAMES, -0.5, 0.5, 0.01, "1 (relative gain change)")(
        recording, structure, base_values))
    return out


def _mains_parameters(recording, structure, base_values):
    out = {"mains_hz": Parameter("mains_hz", 50.0, 45.0, 65.0, "Hz", free=False)}
    out.update(_per_channel_terms(MAINS_NAMES, -1.0, 1.0, 0.01)(recording, structure, base_values))
    return out


#: The knee exponent p of the family's Ising phase, tanh(|x|^p)^(1/p) (:func:`hyst_gym.physics.anhysteretic.knee_unit`):
#: its physical range, from a knee softer than the Langevin curve's to one close to min(|x|, 1).
KNEE_EXPONENT_RANGE = (0.5, 4.0)


def _curve_mixture_parameters(recording, structure, base_values):
    # r starts where the second phase has the first one's initial slope Ms*slope_factor/a
    equal_slope = slope_factor(structure.anhysteretic) / slope_factor(structure.curve)
    low, high = KNEE_EXPONENT_RANGE
    return {"mix_weight": Parameter("mix_weight", 0.0, 0.0, 1.0, "1 (share of the base curve's phase)", scale=0.1),
            "mix_a_ratio": Parameter("mix_a_ratio", equal_slope, 0.02 * equal_slope, 50.0 * equal_slope,
                                     "1 (its a over the first phase's a)", log=True),
            # ln p, fitted linearly: 0 (p = 1, today's curves) is inside the range, not at a wall
            "knee_log_p": Parameter("knee_log_p", 0.0, float(np.log(low)), float(np.log(high)),
                                    "1 (ln of the Ising phase's knee exponent p)", scale=0.1)}


def _small_loop_parameters(recording, structure, base_values):
    # a reversible susceptibility up to three times the anhysteretic's initial slope
    # Ms*slope_factor/a (fits to measured ferrite loops give 0.4-0.8 times it)
    h_max = Frame.of(recording).h_max
    initial_slope = (base_values.get("Ms", PAPER_MS) * slope_factor(structure.curve)
                     / base_values.get("a", h_max / 5))
    return {"chi_r": Parameter("chi_r", 0.0, 0.0, 3.0 * initial_slope, "1 (reversible low-field susceptibility)",
                               scale=0.1 * initial_slope)}


#: The second mode's frequency range starts this far below the lumped mode: the other mode of a rod standing
#: on a compliant mount (or fixture) lies below the rod's own (the mount's mass swings against its spring), and
#: the lumped mode's stiffness is held near its nominal value by the prior, so it cannot move down to it.
SECOND_MODE_BELOW = 0.1
#: Starts of the second mode, in units of the lumped mode's frequency: one below it (a mount's mode) and the
#: three above it that a rod's higher modes need (:func:`_rod_starts`); the one below is fitted where the base
#: residual asks for a mode there (:func:`.hypothesize._second_mode_starts`).
SECOND_MODE_START_BELOW = 0.5
SECOND_MODE_START_ABOVE = 1.8


def _rod_parameters(recording, structure, base_values):
    dt = Frame.of(recording).dt
    f1 = np.sqrt(base_values.get("khat", PAPER_STIFFNESS)) / (2 * np.pi)
    nyquist = 0.5 / dt
    return {"f2": Parameter("f2", min(5 * f1, 0.6 * nyquist), SECOND_MODE_BELOW * f1, 0.98 * nyquist, "Hz",
                            log=True),
            "damping2": Parameter("damping2", 0.05, 1e-3, 2.0, "1", log=True),
            "g2": Parameter("g2", 0.0, -1.0, 1.0, "1 (static gain relative to mode 1)", scale=0.01)}


def _no_parameters(recording, structure, base_values):
    return {}


# ---------------------------------------------------------------------------- starts, per effect
# Each: (model, start = base values with the effect's parameters at their initial values) -> starts.


def lumped_mode_hz(model) -> float:
    """Hz: the lumped mode's frequency that ``model``'s second-mode range was built from (its bottom is
    ``SECOND_MODE_BELOW`` times it, :func:`_rod_parameters`)."""
    return model.parameters["f2"].lower / SECOND_MODE_BELOW


def _rod_starts(model, start):
    f1 = lumped_mode_hz(model)
    above = np.geomspace(SECOND_MODE_START_ABOVE * f1, model.parameters["f2"].upper * 0.9, 3)
    return [dict(start, f2=f, g2=0.02) for f in (SECOND_MODE_START_BELOW * f1, *above)]


def _quadratic_starts(model, start):
    gain = next((start[g] for g in ("zetahat", "nu", "zeta_fem") if g in start), 1.0)
    scale = gain / (2 * max(abs(start.get("M0", 0.0)), 0.3 * start.get("Ms", 1.0)))
    return [dict(start, zeta_q=s * scale) for s in (1.0, -1.0)]


def _field_bias_starts(model, start):
    h = model.parameters["H0"].upper
    return [dict(start, H0=s * 0.05 * h) for s in (-1, 1)]


def _eddy_starts(model, start):
    return [dict(start, k_e=model.parameters["k_e"].upper * 1e-2)]


def _thermal_starts(model, start):
    p = model.parameters
    return [dict(start, heating=p["heating"].upper * 0.05, tau_th=p["tau_th"].value)]


def _small_loop_starts(model, start):
    return [dict(start, chi_r=model.parameters["chi_r"].upper * f) for f in (0.02, 0.2)]


def _input_map_starts(model, start):
    # from the identity and from a moderate saturation (gain at the peak field 0.7 of the small-signal one)
    return [start, dict(start, input_saturation=1.0, input_saturation_negative=1.0)]


def _input_dynamics_starts(model, start):
    # from a lag of one step and from a delay of two (a delay and a lag bend the loop alike at low rates)
    dt = model.parameters["tau_in"].scale
    return [start, dict(start, tau_in=0.1 * dt, delay_in=2.0 * dt)]


def _curve_mixture_starts(model, start):
    # halfway between the two curves at equal initial slope, and with a sharper second phase (a sharper knee)
    equal_slope = model.parameters["mix_a_ratio"].value
    return [dict(start, mix_weight=0.5, mix_a_ratio=equal_slope), dict(start, mix_weight=0.5,
                                                                       mix_a_ratio=0.3 * equal_slope)]


def knee_alone(model, start) -> dict:
    """``start`` moved to the knee curve alone at the base curve's initial slope (``anhysteretic_shape``), at its
    p = 1 member (ln p = 0): the base curve itself under an Ising base, the plain swap under a Langevin one. The
    family's Ising phase is its second one (w = 1) under an Ising base and its first one (w = 0) under a Langevin
    base. Whether a knee is fitted from there is the hypothesize stage's probe (:func:`.hypothesize.knee_starts`)."""
    return dict(start, mix_weight=1.0 if model.structure.anhysteretic == "ising" else 0.0,
                mix_a_ratio=model.parameters["mix_a_ratio"].value, knee_log_p=0.0)


def _from_initial(model, start):
    return [start]


# ---------------------------------------------------------------------------- shapes the checks and report read


def mapped_field(field, quadratic, cubic, saturation, saturation_negative):
    """The ``input_map`` family: the true field (A/m) for the recorded ``field`` (A/m),
    ``H*(1 + quadratic*u + cubic*u^2)/sqrt(1 + s*u^2)`` with u = H/max|H| and s = ``saturation``
    where u >= 0, ``saturation_negative`` where u < 0: a polynomial and an algebraic sigmoid (close to
    tanh) in one family, the identity when all four vanish.

    Why two saturations: an amplifier's rails are often unequal, so it saturates at another field on
    each side; the two sides join with equal value and slope at u = 0 (s*u^2 has zero slope there),
    and each side is monotone for any s >= 0 (slope (1 + s*u^2)**-1.5 at q = c = 0), where a
    polynomial asymmetry (q) large enough to mimic unequal rails would fold back."""
    if quadratic == 0.0 and cubic == 0.0 and saturation == 0.0 and saturation_negative == 0.0:
        return field
    u = field / (float(np.max(np.abs(field))) or 1.0)
    s = np.where(u >= 0.0, saturation, saturation_negative)
    return np.ascontiguousarray(field * (1.0 + quadratic * u + cubic * u ** 2) / np.sqrt(1.0 + s * u ** 2))


def _input_map_slopes(values, channels, u):
    q, c, s_pos, s_neg = (values[n] for n in INPUT_MAP_NAMES)
    s = np.where(u >= 0.0, s_pos, s_neg)
    root = np.sqrt(1.0 + s * u ** 2)
    # d/du [u*(1 + q*u + c*u^2)/sqrt(1 + s*u^2)], s constant on each side (mapped_field)
    slope = (1.0 + 2 * q * u + 3 * c * u ** 2) / root - s * u ** 2 * (1.0 + q * u + c * u ** 2) / root ** 3
    return [("input map", slope)]


def _sensor_map_slopes(values, channels, u):
    out = []
    for channel in channels:
        q2, q3 = (values[n] for n in SENSOR_MAP_NAMES[channel])
        out.append((f"{channel} sensor map", 1.0 + 2 * q2 * u + 3 * q3 * u ** 2))
    return out


def temperature_rise_trace(recording, values) -> np.ndarray:
    """K per sample: the fitted thermal model's temperature rise that the material sees. The heated stage,
    dT/dt = heating*|H|^p - T/tau_th, integrated exactly over each sample interval (H held), from 0 at the first
    sample; with a second stage (``tau_th2`` > 0, :data:`.kernels.THERMAL_LAG_COLUMNS`) the share ``thermal_share``
    of it plus the rest of the stage lagging it."""
    decay = np.exp(-np.diff(recording.time) / values["tau_th"])
    exponent = values.get("heating_exponent", 2.0)
    h_ref = float(np.sqrt(np.mean(recording.field ** 2))) or 1.0
    drive = values["heating"] * values["tau_th"] * h_ref ** 2 * np.abs(recording.field[:-1] / h_ref) ** exponent
    trace = np.zeros(len(recording.time))
    for i, (factor, target) in enumerate(zip(decay, drive)):
        trace[i + 1] = target + (trace[i] - target) * factor
    tau2 = values.get("tau_th2", 0.0)
    if tau2 <= 0.0:
        return trace
    share = values.get("thermal_share", 1.0)
    lagged = lagged_rise_trace(np.ascontiguousarray(recording.time, dtype=float), trace, float(tau2))
    return share * trace + (1.0 - share) * lagged


def record_temperature_rise(recording, values) -> float:
    """K: the fitted thermal model's temperature rise from the first to the last sample. Unlike a
    steady-state rise, it stays meaningful when tau_th is much longer than the record."""
    return float(temperature_rise_trace(recording, values)[-1])


def thermal_change_words(recording, values) -> str:
    """What a thermal_drift fit determines, in words: the change of a and Ms over the record, and the
    temperature rise that the laws a ~ T (4) and Ms*(1 - beta*theta) imply.

    Why both: without a temperature channel the record determines how a and Ms changed, not the
    temperature; the rise is read off through the a(T) law, so it is only as right as that law (near a
    Curie point, say, a and Ms change far faster per kelvin than a ~ T and the implied rise is too
    large). The report says so instead of stating the rise as a measurement."""
    rise = record_temperature_rise(recording, values)
    a_change = rise / ROOM_TEMPERATURE  # a ~ T: relative change of a = rise / T_amb
    ms_change = -values.get("beta_Ms", 0.0) * rise
    pinning = "".join(f", {what} by {-100 * values[name] * rise:+.3g} %" for name, what in
                      (("beta_k", "the pinning k"), ("beta_c", "the reversibility c")) if values.get(name, 0.0))
    return (f"over the record a changes by {100 * a_change:+.3g} %{pinning} and Ms by {100 * ms_change:+.3g} %; the "
            f"temperature rise that the law a ~ T (4) implies is {rise:.3g} K, an inference through that law, "
            f"not a measurement: the record determines the changes of a and Ms, and the rise is right only where "
            f"a(T) is proportional to T (not near a Curie point); a temperature channel would measure it")


def _thermal_details(values, recording) -> str:
    network = ""
    if values.get("tau_th2", 0.0) > 0.0 and values.get("thermal_share", 1.0) < 1.0:
        network = (f"; the material lags the heated stage: a second stage of {values['tau_th2']:.3g} s, "
                   f"{100 * values['thermal_share']:.3g} % of the heated stage's rise seen directly")
    return f" ({thermal_change_words(recording, values)}{network})"


def _quadratic_details(values, recording) -> str:
    if not values.get("zeta_q") or "zetahat" not in values:
        return ""
    words = (f" (an M^2 law: zetahat/(2*zeta_q) = {values['zetahat'] / (2 * values['zeta_q']):.4g} A/m "
             f"is the bias magnetization it implies")
    even = {n: values.get(n, 0.0) for n in EVEN_LAW_NAMES}
    if any(even.values()):
        words += "; with even terms " + ", ".join(f"{n} = {v:.4g}" for n, v in even.items())
    return words + ")"


def _mains_details(values, recording) -> str:
    return f" (at {values['mains_hz']:.0f} Hz, the better fit of 50 and 60 Hz)"


# ---------------------------------------------------------------------------- applicability


def _sensor_dynamics_details(values, recording) -> str:
    """The fitted resonance of each sensor that has one, in Hz and as a damping ratio."""
    words = []
    for channel, (tau, tau2) in SENSOR_DYNAMICS_NAMES.items():
        if values.get(tau2, 0.0) > 0.0:
            words.append(f"the {channel} sensor resonates at {1.0 / (2 * np.pi * values[tau2]):.4g} Hz with a "
                         f"damping ratio of {values.get(tau, 0.0) / (2 * values[tau2]):.2g}")
        elif values.get(tau, 0.0) > 0.0:
            words.append(f"the {channel} sensor lags by {values[tau]:.3g} s (first order)")
    return f" ({'; '.join(words)})" if words else ""


def _always(recording, structure) -> bool:
    return True


def _mains_applies(recording, structure) -> bool:
    """A real time axis with ``MAINS_MIN_CYCLES`` cycles of 50 Hz and the 60 Hz third harmonic below Nyquist."""
    duration = float(recording.time[-1] - recording.time[0])
    nyquist = 0.5 / float(np.median(np.diff(recording.time)))
    rated = recording.metadata.get("time_axis") != "synthetic"
    return duration * 50.0 >= MAINS_MIN_CYCLES and nyquist > 3 * 60.0 and rated


def _magnetostriction_applies(recording, structure) -> bool:
    # the nonlinear lumped base holds the M^2 law already
    return _has_displacement(recording, structure) and structure.transducer != "lumped_nonlinear"


def _lumped_mechanics_applies(recording, structure) -> bool:
    return _has_displacement(recording, structure) and structure.transducer in ("lumped", "lumped_nonlinear")


# ---------------------------------------------------------------------------- separating measurements

_RECORD_M = "record the magnetization (a pick-up coil) beside the displacement"
_BROADBAND = "excite above the first resonance (a broadband or chirp drive up to the sensor's Nyquist frequency)"
_TEMPERATURE = "record the coil or rod temperature"
_AMPLITUDES = ("record loops at several amplitudes, down to a tenth of the largest (small loops show the low-field "
               "susceptibility)")
_SLOW = "repeat the record at a lower and a higher drive frequency (rate effects scale with frequency)"
_CALIBRATE_SENSOR = "calibrate the sensor against a reference (a static map of the sensor does not follow the drive)"
_AFTER_MECHANICS = (_BROADBAND + ": a sensor's static map acts after the mechanics, a magnetostriction or "
                    "stiffness law before them")
_FIELD_AT_ROD = ("measure the field at the rod (a Hall probe or a field coil) beside the recorded drive: an input lag "
                 "delays it, a sensor lag only the outputs (with a rate-independent loop the two are otherwise the "
                 "same record)")
_GAIN_OR_MS = ("record the displacement beside the magnetization (a drift of Ms moves both channels alike, a "
               "sensor's gain drift only its own), or a second record at another temperature")
_GAIN_OR_MATERIAL = ("record the magnetization beside the displacement (a drift of the material moves both channels "
                     "alike, a sensor's gain drift only its own), or a second record at another temperature")
_ZERO_STRETCHES = ("record a stretch with the drive off at the start and at the end: an offset drift moves the "
                   "sensor's zero, a gain drift does not")
_MAINS_CYCLES = ("record longer (many mains cycles) or a stretch with the drive off: pickup repeats at 50/60 Hz, "
                 "a drift does not")


def _everywhere(measurement: str) -> dict:
    return {cs: measurement for cs in CHANNEL_SETS}


# ---------------------------------------------------------------------------- the registry


@dataclass(frozen=True)
class Effect:
    """One effect of the vocabulary: an extension of the base model that fills one slot of its chain.

    Attributes
    ----------
    name : its id (the verdict that names it)
    slot : the slot of the model chain it fills, in an engineer's words
    words : what it is, in a sentence of the report
    parameter_names : the parameters it adds (empty: it swaps a law)
    parameters : ``(recording, structure, base values) -> {name: Parameter}``: ranges, initial values, units
    identified_by : which parameter the block-consistency check refits (:class:`FirstFiltering`, a name,
        :class:`BestDetermined`, :class:`NoParameter` with the reason)
    applies : ``(recording, structure) -> bool``: whether the base structure and the record can show it
    rate_dependent : its signature needs a real time axis (a rate, a delay or a resonance)
    confusable : ``{partner: {channel set: measurement that separates the two}}``; each pair is listed on
        one of its two effects
    rescue : parameters searched again with the hysteresis when the local fit misses by far
        (:func:`.hypothesize.rescue`); None: no rescue (it searches globally already, or is linear)
    starts : ``(model, start) -> [starts]`` of its local fit
    strategy : how the hypothesize stage fits it (:data:`.hypothesize.STRATEGIES`; ``linear_sensor_scan``:
        its channel terms solved linearly at each point of a grid over its first ``search_ranges`` parameter)
    mechanical : it acts on the displacement path only (invisible with magnetization alone)
    swaps_curve : it swaps the anhysteretic curve (Ising <-> Langevin)
    channel_terms : per output channel, its coefficients that are linear in the recorded output
    search_ranges : its parameters whose bounds are search ranges, not physical walls
    absent_at_zero : its parameters whose lower bound 0 means "this term is absent" (a member of the
        family), not a wall; their upper bound is still one
    unfiltered_at_zero : ``{time constant: its partner}``: a time constant whose lower bound 0 is a member of the
        family (the channel does not filter) where the partner is below one sample interval too, and a wall where
        it is not (``tau`` at 0 beside a ``tau2`` the record sees: a resonance without damping)
    slopes : ``(values, channels, u) -> [(what, slope)]`` of a static map, which must be monotone
    loop_offset : the parameter that must show as a horizontal offset of the recorded loop
    details : ``(values, recording) -> str`` added to the report's sentence
    relative_changes : ``(recording, values) -> {parameter: relative change}``: changes over the record whose
        magnitude must stay below :data:`RELATIVE_CHANGE_LIMIT` (a physical wall on what the record determines,
        where the parameter's own range is a search range)
    held_first : with strategy ``staged``: its parameters held at their initial values in a first fit (the
        family's older member), then released from that fit and kept only if the fitting block asks for them
    """

    name: str
    slot: str
    words: str
    parameter_names: tuple
    parameters: Callable
    identified_by: object
    applies: Callable
    rate_dependent: bool
    confusable: Mapping
    rescue: tuple | None
    starts: Callable = _from_initial
    strategy: str = "local"
    mechanical: bool = False
    swaps_curve: bool = False
    channel_terms: Mapping = dataclass_field(default_factory=dict)
    search_ranges: tuple = ()
    absent_at_zero: tuple = ()
    unfiltered_at_zero: Mapping = dataclass_field(default_factory=dict)
    slopes: Callable | None = None
    loop_offset: str | None = None
    details: Callable | None = None
    held_first: tuple = ()
    relative_changes: Callable | None = None

    def main_parameter(self, fit) -> str | None:
        """The parameter the block-consistency check refits in ``fit`` (None: none)."""
        if isinstance(self.identified_by, str):
            return self.identified_by
        return self.identified_by.choose(fit, self)


_REGISTERED = (
    Effect(
        name="thermal_drift", slot="time variation of the material parameters (a(t), Ms(t), k(t), c(t))",
        words="thermal drift: the material heats up during the record and its anhysteretic parameter a "
              "moves with temperature (a ~ T, eq. 4), its Ms, pinning k and reversibility c with it",
        parameter_names=("heating", "tau_th", "beta_Ms", "heating_exponent", "beta_k", "beta_c", "tau_th2",
                         "thermal_share"),
        parameters=_thermal_parameters,
        identified_by="heating", applies=_always, rate_dependent=False, rescue=("heating",),
        starts=_thermal_starts, strategy="staged_pinning",
        search_ranges=("tau_th", "heating_exponent", "beta_Ms", "beta_k", "beta_c", "tau_th2", "thermal_share"),
        details=_thermal_details,
        relative_changes=thermal_relative_changes,
        confusable={"anhysteretic_shape": _everywhere(_TEMPERATURE),
                    "delta_e": {"displacement": _TEMPERATURE}}),
    Effect(
        name="eddy_current", slot="rate dependence",
        words="eddy-current (rate-dependent) loss: the material sees H - k_e dM/dt",
        parameter_names=("k_e",), parameters=_eddy_parameters, identified_by="k_e", applies=_always,
        rate_dependent=True, rescue=("k_e",), starts=_eddy_starts,
        confusable={"sensor_lag": {"magnetization": _SLOW + "; a sensor lag is a fixed delay, eddy loss widens the "
                                                            "loop",
                                   "displacement": _RECORD_M},
                    "rod_dynamics": {"displacement": _RECORD_M}}),
    Effect(
        name="quadratic_magnetostriction", slot="magnetostriction law",
        words="a magnetostriction law: the displacement follows an even law of M, the M^2 law (12) and an (M/Ms)^4 "
              "term (a law that saturates or rises faster; plotted in magnetostriction.png), not the linearized "
              "M (13)",
        parameter_names=("zeta_q",) + EVEN_LAW_NAMES, parameters=_quadratic_parameters, identified_by="zeta_q",
        applies=_magnetostriction_applies, rate_dependent=False, rescue=(), starts=_quadratic_starts,
        strategy="quadratic_outputs", mechanical=True, details=_quadratic_details,
        confusable={"field_bias": {"displacement": _RECORD_M},
                    "anhysteretic_shape": {"displacement": _RECORD_M},
                    # with M recorded too: on a slow record a law of M and a stiffness that follows M both make the
                    # displacement a static function of M; only the stiffness moves the resonance
                    "delta_e": {"displacement": _RECORD_M + ", and " + _BROADBAND,
                                "both": _BROADBAND + " at two bias fields (a stiffness that follows M moves the "
                                        "resonance, a magnetostriction law does not)"}}),
    Effect(
        # damping2, not zeta2: zeta2 is the M^2 gain of lumped_nonlinear (12)
        name="rod_dynamics", slot="mechanical dynamics (a second mode)",
        words="rod dynamics: a second longitudinal rod mode (10) that the lumped model lacks",
        parameter_names=("f2", "damping2", "g2"), parameters=_rod_parameters, identified_by="f2",
        applies=_lumped_mechanics_applies, rate_dependent=True, rescue=("f2",), starts=_rod_starts,
        strategy="second_mode", mechanical=True, search_ranges=("g2", "damping2"),
        confusable={"sensor_lag": {"displacement": _BROADBAND + ", or " + _RECORD_M, "both": _BROADBAND},
                    "delta_e": {"both": _BROADBAND + " at two bias fields"}}),
    Effect(
        name="sensor_lag", slot="sensor dynamics (a lag or a resonance)",
        words="sensor dynamics: the output sensor(s) filter the true output, a first-order lag or a second-order "
              "low-pass with a resonance (a probe or an amplifier that rings)",
        parameter_names=("tau_m", "tau_x", "tau2_m", "tau2_x"), parameters=_sensor_lag_parameters,
        identified_by=FirstFiltering(("displacement", "magnetization")), applies=_always, rate_dependent=True,
        rescue=(),
        strategy="sensor_dynamics_scan", details=_sensor_dynamics_details,
        # no resonance (tau2 = 0) is the first-order lag, a member of the family, not a wall; and tau = 0 with tau2
        # below a sample interval is a channel whose sensor does not filter (with both channels recorded, one probe
        # may ring while the other reads true), a member too. Read as a wall, it set aside sensor-dynamics fits
        # that brought sensor_resonance records (both channels, other-forms seeds 0, 1 and 3) within 1.0 noise
        # units, for tau_x = 3.4e-6 s or tau_m = 5.6e-7 s "at the bound" 0 beside a tau2 under the sample
        # interval. tau = 0 beside a tau2 the record sees (a resonance without damping) stays a wall
        absent_at_zero=tuple(tau2 for _, tau2 in SENSOR_DYNAMICS_NAMES.values()),
        unfiltered_at_zero=dict(SENSOR_DYNAMICS_NAMES.values()),
        confusable={}),
    Effect(
        name="input_lag", slot="input dynamics (recorded to true field): a lag and a delay",
        words="input dynamics: the field in the material lags the recorded one (a coil's L/R or an amplifier's "
              "bandwidth: a first-order lag tau_in and a delay delay_in)",
        parameter_names=INPUT_DYNAMICS_NAMES, parameters=_input_dynamics_parameters, identified_by=BestDetermined(),
        applies=_always, rate_dependent=True, rescue=("tau_in",), starts=_input_dynamics_starts,
        # no lag or no delay (0) is a member of the family (a pure delay, a pure lag), not a wall
        absent_at_zero=INPUT_DYNAMICS_NAMES,
        confusable={"sensor_lag": _everywhere(_FIELD_AT_ROD),
                    "eddy_current": _everywhere(_SLOW + "; an input lag shifts the loop in time, eddy loss "
                                                "widens it")}),
    Effect(
        name="field_bias", slot="input map (recorded to true field): an offset",
        words="an unrecorded DC bias field H0 (e.g. a permanent magnet) added to H",
        parameter_names=("H0",), parameters=_field_bias_parameters, identified_by="H0", applies=_always,
        rate_dependent=False, rescue=("H0",), starts=_field_bias_starts, loop_offset="H0",
        confusable={"anhysteretic_shape": {"magnetization": "record a loop symmetric about H = 0 at two amplitudes",
                                           "displacement": _RECORD_M},
                    "delta_e": {"displacement": _RECORD_M}}),
    Effect(
        name="anhysteretic_shape", slot="anhysteretic curve",
        words="another anhysteretic curve: the other one (Ising (2) <-> Langevin (3)), or a mixture of the two with "
              "its own shape parameter (a Brillouin-like curve), or an Ising curve with a sharper or softer knee "
              "tanh(|x|^p)^(1/p) (plotted in anhysteretic.png)",
        parameter_names=("mix_weight", "mix_a_ratio", "knee_log_p"), parameters=_curve_mixture_parameters,
        identified_by=WhenPresent("mix_weight", "the plain swap adds no parameter"), applies=_always,
        rate_dependent=False, rescue=None, strategy="other_curve", swaps_curve=True, starts=_curve_mixture_starts,
        # no second phase (0) is the plain swap, a member of the family; and neither bound of w is a wall: w = 1
        # is the base curve's phase alone, with its own a and knee (under an Ising base the knee curve itself)
        search_ranges=("mix_a_ratio", "mix_weight"), absent_at_zero=("mix_weight",),
        confusable={"delta_e": {"displacement": _RECORD_M}}),
    Effect(
        name="small_loop", slot="anhysteretic curve at low field (reversible susceptibility)",
        words="small-loop (Rayleigh) behaviour: a reversible low-field susceptibility chi_r that (6) lacks, "
              "fading at saturation",
        parameter_names=("chi_r",), parameters=_small_loop_parameters, identified_by="chi_r", applies=_always,
        rate_dependent=False, rescue=None, starts=_small_loop_starts, strategy="with_hysteresis",
        confusable={"anhysteretic_shape": {"magnetization": _AMPLITUDES,
                                           "displacement": _AMPLITUDES + ", and " + _RECORD_M,
                                           "both": _AMPLITUDES},
                    "field_bias": {"magnetization": _AMPLITUDES, "displacement": _RECORD_M},
                    "quadratic_magnetostriction": {"displacement": _RECORD_M},
                    "delta_e": {"displacement": _RECORD_M}}),
    Effect(
        name="input_map",
        slot="input map (recorded to true field): a static nonlinearity, e.g. a saturating amplifier",
        words="an input map: the field in the material is a static nonlinear function of the recorded one "
              "(e.g. a saturating amplifier; plotted in input_map.png)",
        parameter_names=INPUT_MAP_NAMES, parameters=_input_map_parameters, identified_by=BestDetermined(),
        applies=_always, rate_dependent=False,
        rescue=("input_saturation", "input_saturation_negative", "input_cubic"), starts=_input_map_starts,
        search_ranges=("input_saturation", "input_saturation_negative"), slopes=_input_map_slopes,
        confusable={"anhysteretic_shape": {"magnetization": "record the coil current and the field (a Hall probe) "
                                                            "together",
                                           "displacement": _RECORD_M},
                    "quadratic_magnetostriction": {"displacement": _RECORD_M}}),
    Effect(
        name="sensor_map", slot="sensor static map (a nonlinearity)",
        words="a sensor nonlinearity: an output sensor reads a static nonlinear function of the true output "
              "(plotted in sensor_map.png)",
        parameter_names=SENSOR_MAP_NAMES["magnetization"] + SENSOR_MAP_NAMES["displacement"],
        parameters=_per_channel_terms(SENSOR_MAP_NAMES, -0.5, 0.5, 0.05), identified_by=BestDetermined(),
        applies=_always, rate_dependent=False, rescue=(), strategy="linear_sensor", channel_terms=SENSOR_MAP_NAMES,
        slopes=_sensor_map_slopes,
        confusable={"anhysteretic_shape": {"magnetization": _CALIBRATE_SENSOR,
                                           "displacement": _RECORD_M + ", or " + _CALIBRATE_SENSOR},
                    "quadratic_magnetostriction": {"displacement": _AFTER_MECHANICS, "both": _AFTER_MECHANICS},
                    "delta_e": {"displacement": _AFTER_MECHANICS, "both": _AFTER_MECHANICS},
                    "field_bias": {"displacement": _RECORD_M},
                    "small_loop": {"displacement": _RECORD_M}}),
    Effect(
        name="sensor_drift", slot="sensor offset (a slow drift)",
        words="a slow drift of a sensor's offset over the record, d1*f + d2*f^2 + d3*(1 - exp(-f/tau_drift)) "
              "(f: the record's time mapped to [0, 1]; zeroed at the start; plotted in sensor_drift.png)",
        parameter_names=("tau_drift",) + DRIFT_NAMES["magnetization"] + DRIFT_NAMES["displacement"],
        parameters=_offset_drift_parameters,
        identified_by=BestDetermined(DRIFT_NAMES["magnetization"] + DRIFT_NAMES["displacement"]),
        applies=_always, rate_dependent=False, rescue=None, strategy="linear_sensor_scan", channel_terms=DRIFT_NAMES,
        search_ranges=("tau_drift",),
        confusable={"thermal_drift": _everywhere(_TEMPERATURE)}),
    Effect(
        # its own effect beside sensor_drift, not a widening of it: a gain scales the reading, an offset shifts
        # it, and the two separate on a record that swings about a bias (the slot says which one it is)
        name="sensor_gain_drift", slot="sensor static map (a slow drift of the gain)",
        words="a slow drift of a sensor's gain over the record: it reads the true output times "
              "1 + g1*f + g2*(1 - exp(-f/tau_gain)) (f: the record's time mapped to [0, 1]; calibrated at the start)",
        parameter_names=("tau_gain",) + GAIN_DRIFT_NAMES["magnetization"] + GAIN_DRIFT_NAMES["displacement"],
        parameters=_gain_drift_parameters,
        identified_by=BestDetermined(GAIN_DRIFT_NAMES["magnetization"] + GAIN_DRIFT_NAMES["displacement"]),
        applies=_always, rate_dependent=False, rescue=None, strategy="linear_sensor_scan",
        channel_terms=GAIN_DRIFT_NAMES, search_ranges=("tau_gain",),
        confusable={"thermal_drift": {"magnetization": _GAIN_OR_MS, "displacement": _GAIN_OR_MATERIAL,
                                      "both": _TEMPERATURE},
                    "sensor_drift": _everywhere(_ZERO_STRETCHES)}),
    Effect(
        name="mains_pickup", slot="sensor pickup (mains interference at 50/60 Hz)",
        words="mains pickup: an output sensor picks up the 50/60 Hz mains and its third harmonic",
        parameter_names=("mains_hz",) + MAINS_NAMES["magnetization"] + MAINS_NAMES["displacement"],
        parameters=_mains_parameters, identified_by=BestDetermined(), applies=_mains_applies,
        rate_dependent=False, rescue=None, strategy="mains", channel_terms=MAINS_NAMES, details=_mains_details,
        confusable={"sensor_drift": _everywhere(_MAINS_CYCLES), "thermal_drift": _everywhere(_MAINS_CYCLES)}),
    Effect(
        name="delta_e", slot="stiffness (it follows the magnetization)",
        words="the Delta-E effect: the transducer's stiffness changes with its magnetization (a quartic in "
              "M/Ms, plotted in stiffness.png)",
        parameter_names=DELTA_E_NAMES, parameters=_delta_e_parameters,
        identified_by="delta_e", applies=_lumped_mechanics_applies, rate_dependent=False,
        # the rescue's design spans the quadratic law (the cubic and quartic keep their local values): the search it
        # needs is for the hysteresis a strong Delta-E dragged off, not for the law's shape
        rescue=("delta_e", "delta_e_linear"),
        # the quadratic law first: fitted from 0 at once, the quartic led the local fit into another basin (a
        # concealed M^2-law record: 44 noise units held out where the quadratic law's fit reached 7); the cubic
        # and quartic terms are then released together
        strategy="staged", held_first=("delta_e_cubic", "delta_e_quartic"),
        mechanical=True, confusable={}),
)

#: name -> :class:`Effect`, in the order the candidates are tried.
REGISTRY = MappingProxyType({effect.name: effect for effect in _REGISTERED})


def effect(name: str) -> Effect:
    """The registered effect ``name``; a one-line error naming the vocabulary if there is none."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown effect {name!r}; expected one of {', '.join(REGISTRY)}") from None


def _confusable_table() -> dict:
    """``{channel set: {frozenset(pair): measurement}}`` from the registry; a pair listed twice, or with a
    partner or channel set the registry does not know, fails here."""
    table = {cs: {} for cs in CHANNEL_SETS}
    for one in _REGISTERED:
        for partner, by_channels in one.confusable.items():
            if partner not in REGISTRY or partner == one.name:
                raise ValueError(f"effect {one.name!r}: confusable partner {partner!r} is not another registered "
                                 "effect")
            for channels, measurement in by_channels.items():
                pair = frozenset({one.name, partner})
                if pair in table[channels]:
                    raise ValueError(f"confusable pair {sorted(pair)} on {channels!r} is listed twice")
                table[channels][pair] = measurement
    return table


# ---------------------------------------------------------------------------- views of the registry
EFFECTS = tuple(REGISTRY)
EFFECT_SLOTS = {e.name: e.slot for e in _REGISTERED}
EFFECT_WORDS = {e.name: e.words for e in _REGISTERED}
EFFECT_PARAMETERS = {e.name: e.parameter_names for e in _REGISTERED}
RATE_EFFECTS = tuple(e.name for e in _REGISTERED if e.rate_dependent)
MECHANICAL_EFFECTS = tuple(e.name for e in _REGISTERED if e.mechanical)
SEARCH_RANGES_ONLY = tuple(n for e in _REGISTERED for n in e.search_ranges)
CONFUSABLE = _confusable_table()


def extension_parameters(recording, structure, base_values: dict) -> dict:
    """Initial values and bounds of the parameters ``structure.extension`` adds (none without one)."""
    if structure.extension is None:
        return {}
    return effect(structure.extension).parameters(recording, structure, base_values)


def applicable_effects(recording, structure) -> list[str]:
    """Vocabulary effects that can show in this recording under this base structure, in registry order."""
    return [e.name for e in _REGISTERED if e.applies(recording, structure)]


def effect_starts(model, name: str, base_values: dict) -> list[dict]:
    """Starts of the local fit of effect ``name``: the base values with its parameters at their
    initial values, moved by the effect's own start rule."""
    start = {**base_values, **{n: model.parameters[n].value for n in effect(name).parameter_names}}
    return effect(name).starts(model, start)


def static_map_slopes(name, values, channels, points: int = 201):
    """``[(what, slope over the normalized input -1..1)]`` of a static map (an ``input_map``, relative to
    the small-signal gain, or each channel's ``sensor_map``); empty for an effect that is no static map."""
    slopes = effect(name).slopes
    return [] if slopes is None else slopes(values, channels, np.linspace(-1.0, 1.0, points))
