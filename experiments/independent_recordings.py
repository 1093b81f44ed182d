"""An independent generator of synthetic recordings for the mismatch tool's concealed-effect study.

The mismatch tool (:mod:`hyst_gym.diagnose`) names the physics effect a recording shows that the
base model (hysteresis eq. (6) of Nealis & Smith + lumped transducer (13)) leaves out. Its own
generator (``hyst_gym.diagnose.make_recording``) shares the simulation kernels with the fitter,
so a study that draws its recordings there partly tests the kernels against themselves. This
module writes the same physics again from the equations, with numpy and scipy only, and shares
no code with the fitter: it imports nothing from ``hyst_gym.physics``, ``hyst_gym.estimation``
or the diagnose kernels/model/fit/core/make_recording. ``hyst_gym.diagnose.recording`` (the
:class:`Recording` dataclass and the CSV writer) is imported lazily, only to hand results over
in the tool's input format, so :func:`simulate` runs without loading ``hyst_gym`` at all.

Numerics (different from the project's explicit midpoint rule in the field with substeps):

* hysteresis (6) is integrated in *time*, ``dM/dt = (dM/dH)(H(t), M, sign dH/dt) * dH/dt``, by
  an adaptive Dormand-Prince 5(4) Runge-Kutta scheme written out here (local error <=
  ``TOLERANCE*Ms`` per step); the applied field is a C2 cubic spline through a grid
  ``OVERSAMPLE`` times finer than the recording, and each grid interval is split at its field
  reversals (where sign(dH/dt) switches the irreversible term);
* eddy currents make the effective field a stiff relaxation ``k_e*chi*dHe/dt = H - He``: it
  takes exponential-midpoint steps (exact for a frozen chi, so stable in saturation) with
  step-doubling error control;
* the record starts on the initial magnetization curve at the first field value (LSODA in
  the field from the demagnetized state M = 0 at H = 0);
* linear mechanics (13), the rod's second mode and the sensor lags are exact first-order-hold
  discretizations (``scipy.signal.cont2discrete``) run by ``scipy.signal.lfilter`` on the
  fine grid, started settled; the Delta-E mechanics (stiffness varying with M) by RK4.

Every draw comes from :func:`numpy.random.default_rng` seeded by ``SeedSequence([seed,
crc32(label)...])``: the material, mechanics, conditions and excitation depend on the seed only
(so ``generate(effect, s)`` and ``generate("none", s)`` differ by the effect alone), the effect's
parameters on (seed, effect), the noise on (seed, effect, channels).

Effect sizes are drawn in physical ranges and then checked against the noise: if the effect's
mean-removed RMS change of the noise-free recorded outputs (compared with ``none``) is below
:data:`MIN_VISIBILITY` noise standard deviations, its size parameter is enlarged (up to a
physical cap) and the recording simulated again; the truth records the factor
(``size_boost``) and the final visibility.

Command line::

    python -m experiments.independent_recordings --effect eddy_current --seed 3 \\
        --channels both --out rec.csv [--truth truth.json] [--samples N]

writes ``rec.csv`` and the sidecar ``rec.json`` (material and a note; nothing names the
effect) and, with ``--truth``, the truth dict as JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

# ---------------------------------------------------------------------------- constants

#: Paper values (Nealis & Smith): lumped mechanics (13).
PAPER_CHAT = 7.8899e3      # 1/s
PAPER_KHAT = 6.4251e7      # 1/s^2
PAPER_ZETAHAT = 1.3724e-2  # m/s^2 per A/m
#: Ambient (coil) temperature, K.
T_AMBIENT = 293.15
#: The simulation grid is this many times finer than the recording.
OVERSAMPLE = 4
#: The linear dynamics (mechanics, rod mode, sensor lags) run on a grid this many times finer
#: than the simulation grid, their input refined by its cubic spline.
LINEAR_REFINE = 4
#: Local error allowed per integration step of the magnetization, as a fraction of Ms
#: (Dormand-Prince; the second-order eddy-current scheme gets EDDY_TOLERANCE).
TOLERANCE = 1e-9
EDDY_TOLERANCE = 1e-6
#: The eddy-current scheme moves the effective field by at most this fraction of min(k, a) per step.
FIELD_RESOLUTION = 0.5
#: Least visibility of an effect: mean-removed RMS change of a recorded noise-free output
#: against ``none``, in units of that channel's noise standard deviation.
MIN_VISIBILITY = 4.0
#: Largest number of enlargements of an effect that is not visible enough.
MAX_BOOSTS = 4

CHANNEL_SETS = ("magnetization", "displacement", "both")
FAMILIES = ("sines", "triangles", "prbs", "chirp", "milling")


@dataclass(frozen=True)
class EffectSpec:
    """One effect the generator can conceal.

    ``in_vocabulary``: whether the mismatch tool can name it (``hyst_gym.diagnose.model.EFFECTS``);
    flip it when the tool's vocabulary changes (``delta_e`` joined it with the tool's Delta-E model).
    ``displacement_only``: it changes the displacement channel only (needs a displacement column).
    ``changes_magnetization``: the true M differs from ``none`` (the M solve must be redone).
    """

    name: str
    in_vocabulary: bool
    displacement_only: bool
    changes_magnetization: bool
    description: str


EFFECT_SPECS = {spec.name: spec for spec in (
    EffectSpec("none", True, False, False, "the base model: Ising hysteresis (6) + lumped mechanics (13)"),
    EffectSpec("thermal_drift", True, False, True,
               "coil heating ~ H^2 with time constant tau_th; a ~ T, Ms drops by beta_Ms per K; "
               "no temperature column"),
    EffectSpec("eddy_current", True, False, True, "H_eff = H - k_e dM/dt"),
    EffectSpec("quadratic_magnetostriction", True, True, False,
               "displacement forced by M^2 about a bias M_b instead of linearly in M"),
    EffectSpec("rod_dynamics", True, True, False, "a second longitudinal rod mode (kHz) in parallel"),
    EffectSpec("sensor_lag", True, False, False, "first-order lag on each output sensor"),
    EffectSpec("field_bias", True, False, True, "unrecorded DC field offset H0"),
    EffectSpec("anhysteretic_shape", True, False, True, "Langevin instead of Ising anhysteretic curve"),
    EffectSpec("delta_e", True, True, False, "Delta-E effect: khat*(1 + beta*(M/Ms)^2)"),
    EffectSpec("small_loop", True, False, True,
               "Rayleigh region: reversible wall bowing adds chi_rev*(1 - (M/Ms)^2) to dM/dH"),
    # named by the tool's flexible families (sensor_map, input_map)
    EffectSpec("sensor_nonlinearity", True, False, False, "cubic sensor gain on each output sensor"),
    EffectSpec("amplifier_saturation", True, False, True,
               "current amplifier soft-saturates; the recorded field is the commanded one"),
    EffectSpec("input_lag", True, False, True,
               "the field in the rod lags the recorded one (a coil's L/R): a first-order lag and a delay"),
    EffectSpec("two_phase_rod", False, False, True,
               "inhomogeneous rod: volume fraction w of a second hysteresis material"),
)}
#: Effects the tool names by a family of another name (its flexible families): the cubic
#: sensor gain is one of its sensor static maps, the amplifier's saturation one of its input maps.
TOOL_NAMES = {"sensor_nonlinearity": "sensor_map", "amplifier_saturation": "input_map"}
#: The tool's additive sensor terms that this generator does not conceal (experiments/other_forms.py does).
NOT_CONCEALED = ("sensor_drift", "sensor_gain_drift", "mains_pickup")
EFFECTS_IN_VOCABULARY = tuple(n for n, s in EFFECT_SPECS.items() if s.in_vocabulary)
EFFECTS_OUTSIDE = tuple(n for n, s in EFFECT_SPECS.items() if not s.in_vocabulary)
ALL_EFFECTS = tuple(EFFECT_SPECS)


# ---------------------------------------------------------------------------- parameter draws

@dataclass(frozen=True)
class Material:
    """Hysteresis parameters of eq. (6).

    a : A/m, anhysteretic shape;  k : A/m, pinning;  alpha : 1, mean-field coupling
    (He = H + alpha*M);  Ms : A/m, saturation magnetization;  c : 1, reversibility;
    curve : "ising" (Man = Ms tanh(He/a)) or "langevin" (Man = Ms (coth(He/a) - a/He));
    chi_rev : 1, reversible low-field (Rayleigh) susceptibility of bowing walls, which has
    nothing left to bow at saturation: dM/dH gains chi_rev*(1 - (M/Ms)^2) (0: plain (6)).
    """

    a: float
    k: float
    alpha: float
    Ms: float
    c: float
    curve: str = "ising"
    chi_rev: float = 0.0

    @property
    def slope_factor(self) -> float:
        """Man'(0)*a/Ms: 1 for Ising, 1/3 for Langevin."""
        return 1.0 if self.curve == "ising" else 1.0 / 3.0

    @property
    def rho(self) -> float:
        """Dimensionless mean-field gain alpha*Man'(0)."""
        return self.alpha * self.Ms * self.slope_factor / self.a

    @property
    def knee_field(self) -> float:
        """Field (A/m) at which the Ising anhysteretic curve reaches tanh(1) = 76 % of Ms:
        He = a, i.e. H = a - alpha*0.76*Ms = a*(1 - 0.76*rho)."""
        return self.a * (1.0 - math.tanh(1.0) * self.rho)

    def problems(self) -> list[str]:
        """Why this draw is numerically unsafe (empty if it is safe).

        Denominators of (6): ``1 - alpha*c*Man'`` must stay positive for every He (for
        alpha > 0 its minimum is ``1 - c*rho``), and the irreversible denominator
        ``(1-c)*k - alpha*delta*(Man - M)`` for every |Man - M| <= 2*Ms; rho < 1 keeps the
        anhysteretic fixed point M = Man(H + alpha*M) unique.
        """
        out = []
        if not (self.a > 0 and self.k > 0 and self.Ms > 0 and 0 <= self.c <= 1):
            out.append("a, k, Ms must be positive and 0 <= c <= 1")
        if self.curve not in ("ising", "langevin"):
            out.append(f"unknown curve {self.curve!r}")
        if self.rho >= 0.8:
            out.append(f"rho = {self.rho:.3g} >= 0.8")
        if 1.0 - self.c * max(self.rho, 0.0) <= 0.2:
            out.append("1 - alpha*c*Man' may approach 0")
        pinning = (1 - self.c) * self.k
        if self.alpha > 0 and self.c < 1 and pinning - 2 * self.Ms * self.alpha <= 0.2 * pinning:
            out.append("irreversible denominator (1-c)k - alpha*(Man-M) may approach 0")
        return out

    def as_dict(self) -> dict:
        return dict(a=self.a, k=self.k, alpha=self.alpha, Ms=self.Ms, c=self.c, curve=self.curve, rho=self.rho,
                    chi_rev=self.chi_rev)


@dataclass(frozen=True)
class Mechanics:
    """Lumped transducer (13): x'' + chat*x' + khat*x = zetahat*M.

    chat : 1/s;  khat : 1/s^2;  zetahat : m/s^2 per A/m.
    """

    chat: float
    khat: float
    zetahat: float

    def as_dict(self) -> dict:
        return dict(chat=self.chat, khat=self.khat, zetahat=self.zetahat)


@dataclass(frozen=True)
class Thermal:
    """Coil heating: ``tau*theta' = gain*H^2 - theta`` (theta in K), ``a(T) = a*T/T_amb``,
    ``Ms(T) = Ms*(1 - beta_Ms*theta)``. gain : K per (A/m)^2;  tau : s;  beta_Ms : 1/K."""

    gain: float
    tau: float
    beta_Ms: float


@dataclass(frozen=True)
class Conditions:
    """Recording conditions the fitter is not told.

    sample_rate : Hz;  n_samples : 1;  noise_rel : 1, white Gaussian sensor noise standard
    deviation as a fraction of each output's peak-to-peak;  family : excitation family;
    amplitude : A/m, field amplitude;  bias : A/m, recorded DC field;  coil_cutoff : Hz,
    -3 dB frequency of the coil's second-order Butterworth low-pass.
    """

    sample_rate: float
    n_samples: int
    noise_rel: float
    family: str
    amplitude: float
    bias: float
    coil_cutoff: float

    @property
    def duration(self) -> float:
        """Record length, s."""
        return self.n_samples / self.sample_rate

    def as_dict(self) -> dict:
        return dict(sample_rate=self.sample_rate, n_samples=self.n_samples, noise_rel=self.noise_rel,
                    family=self.family, amplitude=self.amplitude, bias=self.bias, coil_cutoff=self.coil_cutoff,
                    duration=self.duration)


@dataclass(frozen=True)
class EffectDraw:
    """An effect's drawn parameters (SI units, see :func:`_draw_effect`).

    ``knob`` names the parameter that sets the effect's size (None: the effect has no size);
    :meth:`boosted` enlarges it by a factor, up to ``knob_max``.
    """

    name: str
    values: tuple = ()
    knob: str | None = None
    knob_max: float = math.inf

    def __getitem__(self, key):
        return dict(self.values)[key]

    def boosted(self, factor: float) -> EffectDraw:
        values = dict(self.values)
        values[self.knob] = float(min(values[self.knob] * factor, self.knob_max))
        return replace(self, values=tuple(values.items()))

    @property
    def saturated(self) -> bool:
        return self.knob is None or self[self.knob] >= self.knob_max


NO_EFFECT = EffectDraw("none")


@dataclass(frozen=True)
class BaseDraw:
    """Everything drawn from the seed alone (shared by all effects and channel sets)."""

    seed: int
    material: Material
    mechanics: Mechanics
    conditions: Conditions


def _stream(seed: int, *labels: str) -> np.random.Generator:
    """A random stream for ``seed`` and text labels; stable across runs and platforms
    (crc32 of the labels, not Python's salted ``hash``)."""
    words = [int(seed)] + [zlib.crc32(label.encode("utf-8")) for label in labels]
    return np.random.default_rng(np.random.SeedSequence(words))


def _log_uniform(rng, low, high) -> float:
    return float(np.exp(rng.uniform(math.log(low), math.log(high))))


def draw_material(rng) -> Material:
    """Ising material drawn over ranges wider than the project's defaults (paper: a = 7012 A/m,
    k = 400 A/m, alpha = -0.1 (rho = -10.9), Ms = 7.65e5 A/m, c = 0.18): a 2.5e3-1.5e4 A/m and
    k 150-6000 A/m log-uniform, Ms 5e5-1e6 A/m, c 0.05-0.6, rho = alpha*Ms/a either negative
    (75 %, -rho log-uniform 0.05-12) or 0-0.6; unsafe draws (:meth:`Material.problems`) redrawn."""
    for _ in range(1000):
        a = _log_uniform(rng, 2.5e3, 1.5e4)
        k = _log_uniform(rng, 150.0, 6000.0)
        Ms = rng.uniform(5e5, 1e6)
        c = rng.uniform(0.05, 0.6)
        rho = -_log_uniform(rng, 0.05, 12.0) if rng.uniform() < 0.75 else rng.uniform(0.0, 0.6)
        material = Material(a=a, k=k, alpha=rho * a / Ms, Ms=Ms, c=c)
        if not material.problems():
            return material
    raise RuntimeError("no numerically safe material draw in 1000 tries")  # pragma: no cover


def draw_base(seed: int, n_samples: int | None = None) -> BaseDraw:
    """Material, mechanics (paper values +-15 %) and conditions for ``seed``: sample rate
    10-60 kHz, 5000-20000 samples, noise 0.1-1 % of each output's peak-to-peak (log-uniform),
    the excitation family, field amplitude 0.8-3x the material's knee field (log-uniform,
    clipped to 1.5e4-3e5 A/m), recorded DC bias -0.3..0.6 x amplitude, coil cutoff 6-20 % of
    the sample rate.

    ``n_samples`` overrides the drawn record length (5000-20000) without changing other draws.
    """
    rng = _stream(seed, "conditions")
    fs = rng.uniform(10e3, 60e3)
    drawn_n = int(rng.integers(5000, 20001))
    noise_rel = _log_uniform(rng, 1e-3, 1e-2)
    family = FAMILIES[int(rng.integers(len(FAMILIES)))]
    material = draw_material(_stream(seed, "material"))
    mrng = _stream(seed, "mechanics")
    mechanics = Mechanics(chat=PAPER_CHAT * mrng.uniform(0.85, 1.15), khat=PAPER_KHAT * mrng.uniform(0.85, 1.15),
                          zetahat=PAPER_ZETAHAT * mrng.uniform(0.85, 1.15))
    erng = _stream(seed, "excitation")
    # relative to the material's knee, so that every draw reaches the bend of the curve (below
    # it a strongly negative alpha makes M ~ linear in H, and most effects unobservable)
    amplitude = float(np.clip(material.knee_field * _log_uniform(erng, 0.8, 3.0), 1.5e4, 3e5))
    bias = erng.uniform(-0.3, 0.6) * amplitude
    coil_cutoff = erng.uniform(0.06, 0.2) * fs
    n = drawn_n if n_samples is None else int(n_samples)
    conditions = Conditions(sample_rate=fs, n_samples=n, noise_rel=noise_rel, family=family,
                            amplitude=amplitude, bias=bias, coil_cutoff=coil_cutoff)
    return BaseDraw(seed=int(seed), material=material, mechanics=mechanics, conditions=conditions)


# ---------------------------------------------------------------------------- excitation

def excitation(base: BaseDraw) -> tuple[np.ndarray, np.ndarray, dict]:
    """The recorded field on the fine grid: (time s, field A/m, description).

    ``bias + amplitude*u(t)`` with ``u`` of the drawn family (max |u| = 1) plus a few
    switching steps (3-10 % of the amplitude, they excite the kHz mechanics), smoothed by the
    coil's second-order Butterworth low-pass at ``coil_cutoff`` (started settled).
    """
    cond = base.conditions
    fine_rate = OVERSAMPLE * cond.sample_rate
    time = np.arange(cond.n_samples * OVERSAMPLE) / fine_rate
    duration = cond.duration
    rng = _stream(base.seed, "excitation", cond.family)
    u, info = _FAMILY_FUNCTIONS[cond.family](rng, time, duration, cond.sample_rate)
    u = u / max(float(np.max(np.abs(u))), 1e-12)
    n_steps = int(rng.integers(2, 6))
    step_times = rng.uniform(0.05, 0.95, n_steps) * duration
    step_sizes = rng.uniform(0.03, 0.1, n_steps) * rng.choice([-1.0, 1.0], n_steps)
    for t0, size in zip(step_times, step_sizes):
        u = u + size * (time >= t0)
    raw = cond.bias + cond.amplitude * u
    sos = signal.butter(2, cond.coil_cutoff, fs=fine_rate, output="sos")
    field, _ = signal.sosfilt(sos, raw, zi=signal.sosfilt_zi(sos) * raw[0])
    info = dict(info, family=cond.family, amplitude=cond.amplitude, bias=cond.bias, coil_cutoff=cond.coil_cutoff,
                steps=[[float(t), float(s * cond.amplitude)] for t, s in zip(step_times, step_sizes)])
    return time, field, info


def _sines(rng, time, duration, fs):
    """2-4 sines under a slowly varying envelope (minor loops); fundamental 4-25 cycles/record."""
    n = int(rng.integers(2, 5))
    f1 = rng.uniform(4.0, 25.0) / duration
    freqs = f1 * np.concatenate([[1.0], rng.uniform(1.3, 4.0, n - 1)])
    weights = rng.dirichlet(np.ones(n))
    phases = rng.uniform(0, 2 * np.pi, n)
    carrier = sum(w * np.sin(2 * np.pi * f * time + p) for w, f, p in zip(weights, freqs, phases))
    f_env = rng.uniform(0.7, 2.5) / duration
    envelope = 0.15 + 0.85 * (0.5 + 0.5 * np.cos(2 * np.pi * f_env * time + rng.uniform(0, 2 * np.pi)))
    return envelope * carrier, dict(frequencies=freqs.tolist(), envelope_frequency=f_env)


def _triangles(rng, time, duration, fs):
    """Ramps between 4-16 turning points of alternating sign and random height (asymmetric
    triangles; smaller turns give minor loops)."""
    n = int(rng.integers(4, 17))
    knots = np.concatenate([[0.0], np.sort(rng.uniform(0, duration, n - 1)), [duration]])
    signs = np.where(np.arange(n + 1) % 2 == 0, 1.0, -1.0) * rng.choice([-1.0, 1.0])
    levels = signs * rng.uniform(0.2, 1.0, n + 1)
    return np.interp(time, knots, levels), dict(turning_points=n + 1)


def _prbs(rng, time, duration, fs):
    """Pseudo-random binary sequence of 20-200 bits under a slow envelope; the coil filter
    smooths it to the coil bandwidth."""
    n_bits = int(rng.integers(20, 201))
    bits = rng.choice([-1.0, 1.0], n_bits)
    index = np.minimum((time / duration * n_bits).astype(int), n_bits - 1)
    f_env = rng.uniform(0.5, 2.0) / duration
    envelope = 0.4 + 0.6 * (0.5 + 0.5 * np.cos(2 * np.pi * f_env * time + rng.uniform(0, 2 * np.pi)))
    return envelope * bits[index], dict(bits=n_bits, bit_time=duration / n_bits)


def _chirp(rng, time, duration, fs):
    """Linear or logarithmic chirp from 1-4 cycles/record up to 1-5 % of the sample rate,
    under a tapering envelope."""
    f0 = rng.uniform(1.0, 4.0) / duration
    f1 = max(rng.uniform(0.01, 0.05) * fs, 4 * f0)
    method = ("linear", "logarithmic")[int(rng.integers(2))]
    sweep = signal.chirp(time, f0=f0, t1=duration, f1=f1, method=method, phi=rng.uniform(0, 360))
    taper = rng.uniform(0.3, 1.0)
    envelope = 1.0 - (1.0 - taper) * time / duration
    return envelope * sweep, dict(f0=f0, f1=f1, method=method)


def _milling(rng, time, duration, fs):
    """Milling-like periodic load: 2-4 teeth, each cut a chip-thickness ramp over 25-60 % of
    the tooth period ending in an abrupt exit, +-15 % runout per tooth, the tool entering and
    leaving the cut inside the record."""
    teeth = int(rng.integers(2, 5))
    f_spindle = rng.uniform(2.0, 12.0) / duration
    f_tooth = teeth * f_spindle
    engagement = rng.uniform(0.25, 0.6)
    runout = 1.0 + rng.uniform(-0.15, 0.15, teeth)
    cycles = time * f_tooth
    phase = cycles - np.floor(cycles)
    tooth = np.floor(cycles).astype(int) % teeth
    load = np.where(phase < engagement, np.sin(0.5 * np.pi * phase / engagement), 0.0) * runout[tooth]
    t_in, t_out = rng.uniform(0.02, 0.25) * duration, rng.uniform(0.75, 0.98) * duration
    edge = 1.0 / f_tooth
    in_cut = 0.5 * (np.tanh((time - t_in) / edge) - np.tanh((time - t_out) / edge))
    u = load * in_cut
    return 2.0 * u / max(float(np.max(u)), 1e-12) - 1.0, dict(teeth=teeth, tooth_frequency=f_tooth,
                                                              engagement=engagement, cut=[t_in, t_out])


_FAMILY_FUNCTIONS = {"sines": _sines, "triangles": _triangles, "prbs": _prbs, "chirp": _chirp,
                     "milling": _milling}


# ---------------------------------------------------------------------------- hysteresis (6)

def anhysteretic(x: float, curve: str) -> tuple[float, float]:
    """Normalized anhysteretic curve and slope at ``x = He/a``: (Man/Ms, dMan/dHe * a/Ms)."""
    if curve == "ising":
        t = math.tanh(x)
        if abs(x) > 20.0:  # 1 - t*t cancels to 0 long before sech^2 underflows
            return t, 4.0 * math.exp(-2.0 * abs(x))
        return t, 1.0 - t * t
    ax = abs(x)
    if ax < 1e-3:  # series of coth(x) - 1/x: the two terms cancel
        x2 = x * x
        return x * (1.0 / 3.0 - x2 / 45.0 + 2.0 * x2 * x2 / 945.0), 1.0 / 3.0 - x2 / 15.0 + 2.0 * x2 * x2 / 189.0
    if ax > 30.0:  # coth = +-1 in double precision; sinh would overflow further out
        return math.copysign(1.0, x) - 1.0 / x, 1.0 / (x * x)
    s = math.sinh(x)
    return math.cosh(x) / s - 1.0 / x, 1.0 / (x * x) - 1.0 / (s * s)


def hysteresis_slope(H: float, M: float, delta: float, a: float, k: float, alpha: float, Ms: float, c: float,
                     curve: str = "ising", chi_rev: float = 0.0) -> float:
    """dM/dH (1) of eq. (6) at applied field ``H`` (A/m), magnetization ``M`` (A/m) and
    direction ``delta`` (+1 rising, -1 falling field)::

        dM/dH = [dhat*(Man - M)/(k*delta - alphahat*(Man - M)) + c*Man'] / (1 - alpha*c*Man')

    with ``He = H + alpha*M`` and ``alphahat = alpha/(1 - c)``. The irreversible term is
    written as ``(1-c)*(Man-M)/((1-c)*k*delta - alpha*(Man-M))`` (the same for c < 1, and 0
    at c = 1); it is switched off (dhat = 0) unless M lags Man in the direction of travel and
    its denominator has delta's sign. ``chi_rev`` (Material) adds the Rayleigh-region bowing
    ``chi_rev*(1 - (M/Ms)^2)``, floored at 0 beyond saturation.
    """
    x = (H + alpha * M) / a
    if curve == "ising" and -20.0 <= x <= 20.0:  # the common case, inlined (this is the hot loop)
        L = math.tanh(x)
        Lp = 1.0 - L * L
    else:
        L, Lp = anhysteretic(x, curve)
    man = Ms * L
    man_slope = Ms / a * Lp
    gap = man - M
    irreversible = 0.0
    if gap * delta > 0.0:
        denominator = (1.0 - c) * k * delta - alpha * gap
        if denominator * delta > 0.0:
            irreversible = (1.0 - c) * gap / denominator
    total = (irreversible + c * man_slope) / (1.0 - alpha * c * man_slope)
    if chi_rev != 0.0:
        bowing = 1.0 - (M / Ms) * (M / Ms)
        total += chi_rev * bowing if bowing > 0.0 else 0.0
    return total


class _Spline:
    """A C2 cubic spline through samples on a uniform grid (SciPy's ``CubicSpline``), its
    coefficients as Python lists: on interval i, at time s after its start,
    ``H = ((c0*s + c1)*s + c2)*s + c3``. The integrators evaluate it inline (a SciPy spline
    call costs ~10 us; the loops make ~10^5 evaluations)."""

    def __init__(self, time, values):
        spline = CubicSpline(time, values)
        self.dt = float(time[1] - time[0])
        self.c0, self.c1, self.c2, self.c3 = (row.tolist() for row in spline.c)


def simulate_magnetization(time, field, material: Material, *, eddy_k: float = 0.0,
                           thermal: Thermal | None = None, tol: float | None = None) -> np.ndarray:
    """Magnetization M (A/m) on the uniform ``time`` grid (s) under the applied ``field`` (A/m,
    same grid), starting on the initial curve at ``field[0]`` (:func:`initial_magnetization`).

    ``thermal``: coil heating (:func:`thermal_scales` gives a(t) and Ms(t)). ``eddy_k`` (s):
    eddy currents (:func:`_integrate_eddy`); otherwise Dormand-Prince (:func:`_integrate_dopri`).
    ``tol``: local error per step, as a fraction of Ms (default TOLERANCE, or EDDY_TOLERANCE).
    """
    time = np.asarray(time, dtype=float)
    field = np.asarray(field, dtype=float)
    spline = _Spline(time, field)
    scales = None
    if thermal is not None:
        _, a_scale, ms_scale = thermal_scales(time, field, thermal)
        scales = (a_scale.tolist(), ms_scale.tolist())
    m0 = initial_magnetization(float(field[0]), material)
    if eddy_k > 0.0:
        tol = EDDY_TOLERANCE if tol is None else tol
        return _integrate_eddy(spline, material, m0, float(field[0]), eddy_k, scales, tol * material.Ms)
    tol = TOLERANCE if tol is None else tol
    return _integrate_dopri(spline, material, m0, scales, tol * material.Ms)


def _turning_points(c0: float, c1: float, c2: float, dt: float) -> list[float]:
    """Times in (0, dt) where the interval's cubic has dH/dt = 0 (field reversals)."""
    a, b = 3.0 * c0, 2.0 * c1
    if a == 0.0:
        roots = [-c2 / b] if b != 0.0 else []
    else:
        disc = b * b - 4.0 * a * c2
        if disc < 0.0:
            return []
        q = -0.5 * (b + math.copysign(math.sqrt(disc), b))  # the stable quadratic formula
        roots = [q / a] + ([c2 / q] if q != 0.0 else [])
    return sorted(r for r in roots if 0.0 < r < dt)


# Dormand-Prince 5(4) tableau (Hairer, Norsett & Wanner, Solving ODEs I, table 5.2)
_DP_C = (0.2, 0.3, 0.8, 8.0 / 9.0, 1.0)
_DP_A = ((0.2,),
         (3.0 / 40.0, 9.0 / 40.0),
         (44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0),
         (19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0),
         (9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0))
_DP_B = (35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0)
_DP_E = (71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0)


def _integrate_dopri(spline, mat: Material, m0: float, scales, tol: float) -> np.ndarray:
    """Adaptive Dormand-Prince 5(4) in time on ``dM/dt = (dM/dH)(H(t), M, sign(dH/dt))*dH/dt``,
    landing on every grid node; local error per step <= ``tol`` (A/m).

    Each grid interval is split at its field reversals (where sign(dH/dt) switches the
    irreversible term: a kink in the right-hand side that an embedded error estimate would
    only trip over); the step size carries over from interval to interval, so that smooth
    stretches cost one step per interval and the stiff relaxation after each reversal (over
    a field change ~k) gets as many as the error needs. With ``scales`` (thermal drift) a and
    Ms take their values at the interval's middle (they change by ~1e-5 per interval).
    """
    a, k, alpha, Ms, c, curve, chi_rev = mat.a, mat.k, mat.alpha, mat.Ms, mat.c, mat.curve, mat.chi_rev
    slope = hysteresis_slope
    c0s, c1s, c2s, c3s = spline.c0, spline.c1, spline.c2, spline.c3
    dt = spline.dt
    (a21,), (a31, a32), (a41, a42, a43), (a51, a52, a53, a54), (a61, a62, a63, a64, a65) = _DP_A
    b1, _, b3, b4, b5, b6 = _DP_B
    e1, _, e3, e4, e5, e6, e7 = _DP_E
    cc2, cc3, cc4, cc5, _ = _DP_C
    out = [m0]
    m = m0
    h = dt
    for i in range(len(c0s)):
        c0, c1, c2, c3 = c0s[i], c1s[i], c2s[i], c3s[i]
        if scales is not None:
            a = mat.a * 0.5 * (scales[0][i] + scales[0][i + 1])
            Ms = mat.Ms * 0.5 * (scales[1][i] + scales[1][i + 1])
        # a reversal inside needs dH/dt to change sign there, or its extremum inside
        r_end = (3.0 * c0 * dt + 2.0 * c1) * dt + c2
        may_turn = c2 * r_end <= 0.0 or (c0 != 0.0 and 0.0 < -c1 / (3.0 * c0) < dt)
        turns = _turning_points(c0, c1, c2, dt) if may_turn else None
        edges = [0.0] + turns + [dt] if turns else (0.0, dt)
        for p in range(len(edges) - 1):
            s, stop = edges[p], edges[p + 1]
            mid = 0.5 * (s + stop)
            delta = 1.0 if (3.0 * c0 * mid + 2.0 * c1) * mid + c2 >= 0.0 else -1.0

            def f(t, y, c0=c0, c1=c1, c2=c2, c3=c3, delta=delta, a=a, Ms=Ms):  # dM/dt, t into the interval
                rate = (3.0 * c0 * t + 2.0 * c1) * t + c2
                return slope(((c0 * t + c1) * t + c2) * t + c3, y, delta, a, k, alpha, Ms, c, curve, chi_rev) * rate

            k1 = f(s, m)
            while stop - s > 1e-12 * dt:
                h = min(h, stop - s)
                if stop - s - h < 1e-3 * h:  # do not leave a sliver behind
                    h = stop - s
                k2 = f(s + cc2 * h, m + h * a21 * k1)
                k3 = f(s + cc3 * h, m + h * (a31 * k1 + a32 * k2))
                k4 = f(s + cc4 * h, m + h * (a41 * k1 + a42 * k2 + a43 * k3))
                k5 = f(s + cc5 * h, m + h * (a51 * k1 + a52 * k2 + a53 * k3 + a54 * k4))
                k6 = f(s + h, m + h * (a61 * k1 + a62 * k2 + a63 * k3 + a64 * k4 + a65 * k5))
                m_new = m + h * (b1 * k1 + b3 * k3 + b4 * k4 + b5 * k5 + b6 * k6)
                k7 = f(s + h, m_new)
                err = abs(h * (e1 * k1 + e3 * k3 + e4 * k4 + e5 * k5 + e6 * k6 + e7 * k7))
                if err <= tol:
                    s += h
                    m = m_new
                    k1 = k7  # first-same-as-last
                    h *= 5.0 if err == 0.0 else min(5.0, 0.9 * (tol / err) ** 0.2)
                else:
                    h *= max(0.2, 0.9 * (tol / err) ** 0.2)
        out.append(m)
    return np.array(out)


def _relax(he: float, h: float, tau: float, H_start: float, rate: float) -> float:
    """He after time h (s) of ``tau*dHe/dt = H - He`` with H = H_start + rate*t (A/m, A/(m s))
    and a frozen time constant tau (s): exact, so stable however small tau is."""
    if tau <= 0.0:
        return H_start + rate * h
    decay = math.exp(-h / tau)
    return H_start + rate * h - tau * rate + (he - H_start + tau * rate) * decay


def _integrate_eddy(spline, mat: Material, m0: float, he0: float, k_e: float, scales, tol: float) -> np.ndarray:
    """Eddy currents, ``He = H - k_e*dM/dt``: from ``dM/dt = chi(He, M)*dHe/dt`` the effective
    field relaxes towards the applied one, ``k_e*chi*dHe/dt = H - He``, with dM = chi*dHe and
    the irreversible switch following the direction of He. This is stiff where chi -> 0
    (saturation), so a step is an exponential midpoint step: He advanced exactly with chi
    frozen at the start over half the step (predictor), then over the whole step with chi at
    that midpoint, and M += chi_mid*(He_new - He) (second order, stable for any chi >= 0).
    Step size control by step doubling: a step is accepted when one step and two half steps
    agree in M to ``tol`` (A/m) and He moves by at most ``FIELD_RESOLUTION*min(k, a)`` (the
    field scale over which the hysteresis bends); the two half steps are kept. Over a step,
    H is the chord of the interval's cubic."""
    a, k, alpha, Ms, c, curve, chi_rev = mat.a, mat.k, mat.alpha, mat.Ms, mat.c, mat.curve, mat.chi_rev
    slope = hysteresis_slope
    relax = _relax
    c0s, c1s, c2s, c3s = spline.c0, spline.c1, spline.c2, spline.c3
    dt = spline.dt
    max_move = FIELD_RESOLUTION * min(k, a)

    def step(m, he, H_start, H_end, h):
        rate = (H_end - H_start) / h
        gap = H_start - he
        delta = 1.0 if (gap > 0.0 or (gap == 0.0 and rate >= 0.0)) else -1.0
        chi = slope(he, m, delta, a, k, alpha, Ms, c, curve, chi_rev)
        he_half = relax(he, 0.5 * h, k_e * chi, H_start, rate)
        m_half = m + chi * (he_half - he)
        gap = H_start + 0.5 * h * rate - he_half
        delta = 1.0 if (gap > 0.0 or (gap == 0.0 and rate >= 0.0)) else -1.0
        chi = slope(he_half, m_half, delta, a, k, alpha, Ms, c, curve, chi_rev)
        he_new = relax(he, h, k_e * chi, H_start, rate)
        return m + chi * (he_new - he), he_new

    out = [m0]
    m, he = m0, he0
    h = dt
    for i in range(len(c0s)):
        c0, c1, c2, c3 = c0s[i], c1s[i], c2s[i], c3s[i]
        if scales is not None:
            a = mat.a * 0.5 * (scales[0][i] + scales[0][i + 1])
            Ms = mat.Ms * 0.5 * (scales[1][i] + scales[1][i + 1])
        s = 0.0
        H_s = c3
        while dt - s > 1e-12 * dt:
            h = min(h, dt - s)
            if dt - s - h < 1e-3 * h:
                h = dt - s
            sm, se = s + 0.5 * h, s + h
            H_m = ((c0 * sm + c1) * sm + c2) * sm + c3
            H_e = ((c0 * se + c1) * se + c2) * se + c3
            m_full, _ = step(m, he, H_s, H_e, h)
            m_1, he_1 = step(m, he, H_s, H_m, 0.5 * h)
            m_2, he_2 = step(m_1, he_1, H_m, H_e, 0.5 * h)
            # the error relative to tol, or the move relative to its limit, whichever is worse
            ratio = max(abs(m_2 - m_full) / tol, abs(he_2 - he) / max_move)
            if ratio <= 1.0:
                s, m, he, H_s = se, m_2, he_2, H_e
                h *= 4.0 if ratio == 0.0 else min(4.0, 0.9 * ratio ** (-1.0 / 3.0))
            else:
                h *= max(0.2, 0.9 * ratio ** (-1.0 / 3.0))
        out.append(m)
    return np.array(out)


def thermal_scales(time, field, thermal: Thermal) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coil temperature rise theta (K) from ``tau*theta' = gain*H^2 - theta``, theta(0) = 0,
    exact for H^2 linear between grid points; returns (theta, a/a0, Ms/Ms0)."""
    dt = float(time[1] - time[0])
    drive = thermal.gain * np.asarray(field, dtype=float) ** 2
    decay = math.exp(-dt / thermal.tau)
    weight = thermal.tau / dt * (1.0 - decay)
    b0, b1 = 1.0 - weight, weight - decay   # theta[n+1] = decay*theta[n] + b1*u[n] + b0*u[n+1]
    # lfilter's first output is b0*u[0] + zi: this zi starts the rise at theta(0) = 0
    theta, _ = signal.lfilter([b0, b1], [1.0, -decay], drive, zi=[-b0 * drive[0]])
    return theta, (T_AMBIENT + theta) / T_AMBIENT, np.maximum(1.0 - thermal.beta_Ms * theta, 1e-3)


def initial_magnetization(H0: float, material: Material) -> float:
    """M (A/m) reached from the demagnetized state (M = 0 at H = 0) along the initial curve
    up to ``H0`` (A/m): the virgin state in which every recording starts (dM/dH integrated
    in the field by LSODA)."""
    if H0 == 0.0:
        return 0.0
    delta = 1.0 if H0 > 0 else -1.0
    m = material

    def rhs(H, y):
        return [hysteresis_slope(H, y[0], delta, m.a, m.k, m.alpha, m.Ms, m.c, m.curve, m.chi_rev)]

    sol = solve_ivp(rhs, (0.0, H0), [0.0], method="LSODA", rtol=1e-10, atol=1e-8 * m.Ms,
                    max_step=min(abs(H0), m.k, m.a) / 20)
    return float(sol.y[0, -1])


def anhysteretic_magnetization(field, material: Material) -> np.ndarray:
    """Closed-form limit (c = 1): M = Man(H + alpha*M) (A/m), solved per sample by bisection
    on the monotone ``g(M) = M - Man(H + alpha*M)`` (rho < 1)."""
    out = np.empty(len(field))
    m = material
    for i, H in enumerate(np.asarray(field, dtype=float)):
        lo, hi = -1.5 * m.Ms, 1.5 * m.Ms
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid - m.Ms * anhysteretic((H + m.alpha * mid) / m.a, m.curve)[0] > 0:
                hi = mid
            else:
                lo = mid
            if hi - lo < 1e-9 * m.Ms:
                break
        out[i] = 0.5 * (lo + hi)
    return out


# ---------------------------------------------------------------------------- linear dynamics

def _refined(values, factor: int) -> np.ndarray:
    """``values`` (uniform grid) on a grid ``factor`` times finer, through their C2 cubic spline:
    the linear dynamics below then see a smooth input rather than its piecewise-linear
    interpolant (whose error, ~h^2*M''/8, would reach 1e-4 of the range for fast content)."""
    if factor == 1:
        return np.asarray(values, dtype=float)
    n = len(values)
    return CubicSpline(np.arange(n), values)(np.arange((n - 1) * factor + 1) / factor)


def lti_response(num, den, u, dt: float, refine: int = LINEAR_REFINE) -> np.ndarray:
    """Response of the continuous transfer function num(s)/den(s) to ``u`` sampled every ``dt``
    (s), started in the steady state of ``u[0]``: ``u`` is refined ``refine`` times by its cubic
    spline (:func:`_refined`), and the system is discretized exactly for an input linear
    between the refined samples (first-order hold), then run by ``lfilter``."""
    fine = _refined(u, refine)
    numd, dend, _ = signal.cont2discrete((np.atleast_1d(num), np.atleast_1d(den)), dt / refine, method="foh")
    numd = np.ravel(numd)
    zi = signal.lfilter_zi(numd, dend) * fine[0]
    y, _ = signal.lfilter(numd, dend, fine, zi=zi)
    return y[::refine]


def lumped_displacement(forcing, dt: float, chat: float, khat: float, refine: int = LINEAR_REFINE) -> np.ndarray:
    """x (m) of x'' + chat*x' + khat*x = forcing (m/s^2), settled at the start."""
    return lti_response([1.0], [1.0, chat, khat], forcing, dt, refine)


def second_mode(forcing, dt: float, f2: float, zeta2: float, static_gain: float) -> np.ndarray:
    """x2 (m) of a mode at f2 (Hz) with damping ratio zeta2 whose static response to
    ``forcing`` is ``static_gain*forcing``: x2'' + 2 zeta2 w2 x2' + w2^2 x2 = static_gain w2^2 forcing."""
    w2 = 2 * np.pi * f2
    return lti_response([static_gain * w2 ** 2], [1.0, 2 * zeta2 * w2, w2 ** 2], forcing, dt)


def sensor_lag(values, dt: float, tau: float) -> np.ndarray:
    """First-order sensor tau*y' = u - y (tau in s), settled at the start."""
    return lti_response([1.0], [tau, 1.0], values, dt)


def delta_e_displacement(magnetization, dt: float, mech: Mechanics, beta: float, Ms: float,
                         refine: int = 2) -> np.ndarray:
    """x (m) of x'' + chat*x' + khat*(1 + beta*(M/Ms)^2)*x = zetahat*M: the Delta-E effect makes
    the stiffness depend on M (A/m, sampled every ``dt`` s). Classical RK4 with ``refine`` steps
    per sample interval (h*sqrt(khat*(1+beta)) < 0.3: well inside RK4's stability region), M at
    the stages from its cubic spline; starts at the static equilibrium of the first sample."""
    chat, khat, zeta = mech.chat, mech.khat, mech.zetahat
    ratio = beta / (Ms * Ms)
    # M at every half step: the RK4 stages of step j sit at 2j, 2j+1, 2j+2
    forcing = (zeta * _refined(magnetization, 2 * refine)).tolist()
    stiffness = (khat * (1.0 + ratio * _refined(magnetization, 2 * refine) ** 2)).tolist()
    x = forcing[0] / stiffness[0]
    v = 0.0
    h = dt / refine
    out = [x]
    for j in range((len(forcing) - 1) // 2):
        f1, fm, f4 = forcing[2 * j], forcing[2 * j + 1], forcing[2 * j + 2]
        K1, Km, K4 = stiffness[2 * j], stiffness[2 * j + 1], stiffness[2 * j + 2]
        ax1 = f1 - chat * v - K1 * x
        x2, v2 = x + 0.5 * h * v, v + 0.5 * h * ax1
        ax2 = fm - chat * v2 - Km * x2
        x3, v3 = x + 0.5 * h * v2, v + 0.5 * h * ax2
        ax3 = fm - chat * v3 - Km * x3
        x4, v4 = x + h * v3, v + h * ax3
        ax4 = f4 - chat * v4 - K4 * x4
        x += h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
        v += h / 6.0 * (ax1 + 2.0 * ax2 + 2.0 * ax3 + ax4)
        out.append(x)
    return np.array(out[::refine])


# ---------------------------------------------------------------------------- effects

def _draw_effect(name: str, base: BaseDraw, reference: dict) -> EffectDraw:
    """Parameters of ``name`` (SI units) from the stream (seed, "effect", name).

    ``reference`` is the noise-free ``none`` simulation on the fine grid (its true
    magnetization "M"), which some sizes are scaled to. Ranges (before any boost):

    * thermal_drift: steady rise ``rise`` 20-50 K for the record's mean-square field,
      tau_th 0.3-2 record lengths, beta_Ms 1e-3-2.5e-3 1/K (knob: rise, cap 150 K);
    * eddy_current: k_e (s) such that k_e*|dM/dt| reaches 5-15 % of the field amplitude at the
      99th percentile of ``none`` (knob: k_e, cap 10x);
    * quadratic_magnetostriction: forcing ``zetahat*M + kappa*zetahat*(M - M_b)^2/(2*M_b)``
      (kappa = 1: the pure M^2 law about the bias M_b), kappa 0.4-1, |M_b| = max(|median M|,
      q*Ms) with q 0.2-0.4 (knob: kappa, cap 1);
    * rod_dynamics: f2 in [max(2 kHz, 0.08 fs), min(12 kHz, 0.35 fs)], zeta2 0.01-0.06, static
      gain g2 0.08-0.3 of the lumped mode's (knob: g2, cap 1);
    * sensor_lag: tau_m, tau_x 2-8 samples (knob: scale, a factor on both, cap 200);
    * field_bias: H0 = +-(5-20 %) of the amplitude (knob: fraction, cap 0.6);
    * anhysteretic_shape: Langevin with a/3 (same initial slope Ms/a), alpha unchanged (no knob);
    * delta_e: beta 0.3-1.0 (knob: beta, cap 3);
    * small_loop: chi_rev 40-80 % of the anhysteretic's initial slope Ms*slope_factor/a, the span
      of the fits to the measured ferrite loops (knob: chi_rev, cap 1.5x the slope);
    * sensor_nonlinearity: each sensor y -> y_r + s*(v + gamma*v^3), v = (y - y_r)/s with s the
      half range, y_r within +-30 % of the mid-range, |gamma| 0.04-0.15 (knob: scale, cap 5);
    * amplifier_saturation: H_true = H/(1 + |H/H_sat|^p)^(1/p), H_sat = max|H|/(1 + overdrive),
      overdrive 0.15-0.8, p 3-8 (knob: overdrive, cap 4);
    * input_lag: the field in the rod is the recorded one delayed by delay_in 0-2 samples and lagged by
      tau_in 2-6 samples (knob: scale, a factor on both, cap 20);
    * two_phase_rod: volume fraction w 0.2-0.5 of a second material (a and k x or / 1.5-3, c
      x 0.5-2, Ms x 0.8-1.2, same rho) (knob: w, cap 0.5).
    """
    rng = _stream(base.seed, "effect", name)
    cond, mat = base.conditions, base.material
    if name == "none":
        return NO_EFFECT
    if name == "thermal_drift":
        return EffectDraw(name, (("rise", rng.uniform(20.0, 50.0)), ("tau_th", rng.uniform(0.3, 2.0) * cond.duration),
                                 ("beta_Ms", rng.uniform(1e-3, 2.5e-3))), "rise", 150.0)
    if name == "eddy_current":
        rate = np.abs(np.gradient(reference["M"], 1.0 / (OVERSAMPLE * cond.sample_rate)))
        k_e = rng.uniform(0.05, 0.15) * cond.amplitude / max(float(np.percentile(rate, 99)), 1e-12)
        return EffectDraw(name, (("k_e", k_e),), "k_e", 10.0 * k_e)
    if name == "quadratic_magnetostriction":
        M = reference["M"]
        median = float(np.median(M))
        q = rng.uniform(0.2, 0.4)
        M_b = math.copysign(max(abs(median), q * mat.Ms), median if median != 0 else 1.0)
        return EffectDraw(name, (("kappa", rng.uniform(0.4, 1.0)), ("M_b", M_b)), "kappa", 1.0)
    if name == "rod_dynamics":
        lo, hi = max(2e3, 0.08 * cond.sample_rate), min(12e3, 0.35 * cond.sample_rate)
        return EffectDraw(name, (("f2", rng.uniform(lo, hi)), ("zeta2", rng.uniform(0.01, 0.06)),
                                 ("g2", rng.uniform(0.08, 0.3))), "g2", 1.0)
    if name == "sensor_lag":
        return EffectDraw(name, (("tau_m", rng.uniform(2, 8) / cond.sample_rate),
                                 ("tau_x", rng.uniform(2, 8) / cond.sample_rate), ("scale", 1.0)), "scale", 200.0)
    if name == "field_bias":
        return EffectDraw(name, (("fraction", rng.uniform(0.05, 0.2)), ("sign", float(rng.choice([-1.0, 1.0])))),
                          "fraction", 0.6)
    if name == "anhysteretic_shape":
        return EffectDraw(name, (("a_langevin", mat.a / 3.0),))
    if name == "input_lag":
        return EffectDraw(name, (("tau_in", rng.uniform(2, 6) / cond.sample_rate),
                                 ("delay_in", rng.uniform(0, 2) / cond.sample_rate), ("scale", 1.0)), "scale", 20.0)
    if name == "delta_e":
        return EffectDraw(name, (("beta", rng.uniform(0.3, 1.0)),), "beta", 3.0)
    if name == "small_loop":
        initial_slope = mat.Ms * mat.slope_factor / mat.a
        return EffectDraw(name, (("chi_rev", rng.uniform(0.4, 0.8) * initial_slope),), "chi_rev", 1.5 * initial_slope)
    return _draw_form_effect(name, rng)


def _draw_form_effect(name: str, rng) -> EffectDraw:
    """The effects of :func:`_draw_effect` that the tool names by a family of another form, and the one
    outside its vocabulary (same stream, drawn in the same order)."""
    if name == "sensor_nonlinearity":
        values = []
        for ch in ("m", "x"):
            values += [(f"gamma_{ch}", rng.uniform(0.04, 0.15) * rng.choice([-1.0, 1.0])),
                       (f"offset_{ch}", rng.uniform(-0.3, 0.3))]
        return EffectDraw(name, tuple(values) + (("scale", 1.0),), "scale", 5.0)
    if name == "amplifier_saturation":
        return EffectDraw(name, (("overdrive", rng.uniform(0.15, 0.8)), ("p", rng.uniform(3.0, 8.0))), "overdrive", 4.0)
    if name == "two_phase_rod":
        def ratio():  # x or / 1.5-3
            return _log_uniform(rng, 1.5, 3.0) ** rng.choice([-1.0, 1.0])

        values = (("w", rng.uniform(0.2, 0.5)), ("a_ratio", ratio()), ("k_ratio", ratio()),
                  ("c_ratio", _log_uniform(rng, 0.5, 2.0)), ("Ms_ratio", rng.uniform(0.8, 1.2)))
        return EffectDraw(name, values, "w", 0.5)
    raise ValueError(f"unknown effect {name!r}")


def _second_material(mat: Material, eff: EffectDraw) -> Material:
    """The two-phase rod's second material; its c is clipped and its k raised until safe."""
    a2, Ms2 = mat.a * eff["a_ratio"], mat.Ms * eff["Ms_ratio"]
    second = Material(a=a2, k=mat.k * eff["k_ratio"], alpha=mat.rho * a2 / Ms2, Ms=Ms2,
                      c=float(min(max(mat.c * eff["c_ratio"], 0.02), 0.9)))
    while second.problems():
        second = replace(second, k=second.k * 1.5)
    return second


def _forward(base: BaseDraw, eff: EffectDraw, time, field, reference=None, cache=None, frame=None) -> dict:
    """Noise-free outputs on the fine grid for effect ``eff``: {"M": true M (A/m),
    "magnetization": M as sensed (A/m), "displacement": x as sensed (m)}. Both channels are
    always computed (the mechanics costs little), so an effect's size never depends on which
    sensors are recorded. ``reference`` (the ``none`` result) supplies M when the effect leaves
    the magnetization unchanged; ``cache`` (a dict) keeps magnetization solves for reuse (a
    boosted two-phase fraction w needs no new solve). ``frame`` (a replay, :func:`replay`): the first
    record's fine-grid field and true outputs, which set the frames of the static maps (the amplifier's
    saturation field, the sensors' ranges) and the coil's heating gain, so that they stay the same
    hardware under another drive."""
    mat, mech = base.material, base.mechanics
    frame_field = field if frame is None else frame["field"]
    dt = float(time[1] - time[0])
    name = eff.name
    if reference is not None and not EFFECT_SPECS[name].changes_magnetization:
        M = reference["M"]
    else:
        applied = _applied_field(base, eff, field, dt, frame_field)
        materials, eddy_k, thermal = [mat], 0.0, None
        if name == "eddy_current":
            eddy_k = eff["k_e"]
        elif name == "thermal_drift":
            thermal = _thermal(eff, frame_field)
        elif name == "anhysteretic_shape":
            materials = [replace(mat, a=eff["a_langevin"], curve="langevin")]
        elif name == "two_phase_rod":
            materials = [mat, _second_material(mat, eff)]
        elif name == "small_loop":
            materials = [replace(mat, chi_rev=eff["chi_rev"])]
        cache = {} if cache is None else cache
        phases = []
        for material in materials:
            key = (material, eddy_k, thermal, applied.tobytes())
            if key not in cache:
                cache[key] = simulate_magnetization(time, applied, material, eddy_k=eddy_k, thermal=thermal)
            phases.append(cache[key])
        M = phases[0] if len(phases) == 1 else (1 - eff["w"]) * phases[0] + eff["w"] * phases[1]
    if name == "delta_e":
        x = delta_e_displacement(M, dt, mech, eff["beta"], mat.Ms)
    else:
        forcing = mech.zetahat * M
        if name == "quadratic_magnetostriction":
            forcing = forcing + eff["kappa"] * mech.zetahat * (M - eff["M_b"]) ** 2 / (2 * eff["M_b"])
        x = lumped_displacement(forcing, dt, mech.chat, mech.khat)
        if name == "rod_dynamics":
            # the second mode sees the same forcing, scaled so that its static response is g2
            # times the lumped mode's (forcing/khat)
            x = x + second_mode(forcing / mech.khat, dt, eff["f2"], eff["zeta2"], eff["g2"])
    out = {"M": M, "x": x, "magnetization": M, "displacement": x}
    if name == "sensor_lag":
        out["magnetization"] = sensor_lag(M, dt, eff["tau_m"] * eff["scale"])
        out["displacement"] = sensor_lag(x, dt, eff["tau_x"] * eff["scale"])
    elif name == "sensor_nonlinearity":
        for ch, tag in (("magnetization", "m"), ("displacement", "x")):
            out[ch] = _nonlinear_sensor(out[ch], eff["scale"] * eff[f"gamma_{tag}"], eff[f"offset_{tag}"],
                                        None if frame is None else frame["M" if tag == "m" else "x"])
    return out


def _applied_field(base: BaseDraw, eff: EffectDraw, field, dt: float, frame_field=None) -> np.ndarray:
    """The field (A/m) the rod feels, given the recorded one (sampled every ``dt`` s): plus the unrecorded
    bias H0, through the saturating amplifier ``H/(1 + |H/H_sat|^p)^(1/p)``, or delayed and lagged.
    ``frame_field``: the drive that sets H_sat (default ``field``)."""
    if eff.name == "input_lag":
        steps = np.arange(len(field), dtype=float)
        delayed = np.interp(steps - eff["delay_in"] * eff["scale"] / dt, steps, field)
        return sensor_lag(delayed, dt, eff["tau_in"] * eff["scale"])
    if eff.name == "field_bias":
        return field + _bias_field(base, eff)
    if eff.name == "amplifier_saturation":
        h_sat = _saturation_field(eff, field if frame_field is None else frame_field)
        return field / (1.0 + np.abs(field / h_sat) ** eff["p"]) ** (1.0 / eff["p"])
    return field


def _bias_field(base: BaseDraw, eff: EffectDraw) -> float:
    """field_bias's H0, A/m."""
    return eff["sign"] * eff["fraction"] * base.conditions.amplitude


def _saturation_field(eff: EffectDraw, field) -> float:
    """amplifier_saturation's H_sat, A/m: the largest recorded |H| over (1 + overdrive)."""
    return float(np.max(np.abs(field))) / (1.0 + eff["overdrive"])


def _thermal(eff: EffectDraw, field) -> Thermal:
    """thermal_drift's heating, scaled so that the record's mean-square field would heat the
    coil by ``rise`` K in the steady state."""
    return Thermal(gain=eff["rise"] / float(np.mean(field ** 2)), tau=eff["tau_th"], beta_Ms=eff["beta_Ms"])


def _nonlinear_sensor(y, gamma: float, offset: float, frame=None) -> np.ndarray:
    """A sensor with a cubic gain error about its zero point: ``y_r + s*(v + gamma*v^3)``,
    ``v = (y - y_r)/s``, s the half range of y and y_r = mid-range + offset*s (range of ``frame``, default y)."""
    ranged = y if frame is None else frame
    half = 0.5 * float(np.ptp(ranged)) or 1.0
    centre = 0.5 * (float(np.max(ranged)) + float(np.min(ranged))) + offset * half
    v = (y - centre) / half
    return centre + half * (v + gamma * v ** 3)


def _derived(base: BaseDraw, eff: EffectDraw, time, field) -> dict:
    """Physical values the truth reports besides the drawn parameters (SI units)."""
    if eff.name == "field_bias":
        return {"H0": _bias_field(base, eff)}
    if eff.name == "amplifier_saturation":
        return {"H_sat": _saturation_field(eff, field)}
    if eff.name == "thermal_drift":
        thermal = _thermal(eff, field)
        theta, _, _ = thermal_scales(time, field, thermal)
        return {"heating_gain": thermal.gain, "temperature_rise_at_end": float(theta[-1]),
                "a_at_end": base.material.a * (T_AMBIENT + float(theta[-1])) / T_AMBIENT}
    if eff.name == "sensor_lag":
        return {"tau_m_effective": eff["tau_m"] * eff["scale"], "tau_x_effective": eff["tau_x"] * eff["scale"]}
    if eff.name == "sensor_nonlinearity":
        return {"gamma_m_effective": eff["gamma_m"] * eff["scale"], "gamma_x_effective": eff["gamma_x"] * eff["scale"]}
    if eff.name == "two_phase_rod":
        return {"second_material": _second_material(base.material, eff).as_dict()}
    return {}


def _recorded(outputs: dict, channels=("magnetization", "displacement")) -> dict:
    """Fine-grid channels sampled at the recording rate."""
    return {ch: outputs[ch][::OVERSAMPLE] for ch in channels}


def _visibility(clean: dict, reference: dict, noise_rel: float) -> dict:
    """Mean-removed RMS difference from ``none`` in noise standard deviations, per channel
    (a constant offset is not observable: the tool fits offsets)."""
    out = {}
    for ch, y in clean.items():
        diff = y - reference[ch]
        sigma = noise_rel * float(np.ptp(y))
        out[ch] = float(np.sqrt(np.mean((diff - diff.mean()) ** 2)) / sigma) if sigma > 0 else 0.0
    return out


# ---------------------------------------------------------------------------- public API

@dataclass(frozen=True)
class Simulation:
    """A noise-free recording: time (s), recorded field (A/m), clean output channels (the
    requested ones, A/m and m), the truth, and the ``none`` recording of the same seed."""

    time: np.ndarray
    field: np.ndarray
    clean: dict
    truth: dict
    reference: dict


def _check_arguments(effect, seed, channels, n_samples):
    if effect not in EFFECT_SPECS:
        raise ValueError(f"effect must be one of {', '.join(ALL_EFFECTS)}, got {effect!r}")
    if channels not in CHANNEL_SETS:
        raise ValueError(f"channels must be one of {', '.join(CHANNEL_SETS)}, got {channels!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if channels == "magnetization" and EFFECT_SPECS[effect].displacement_only:
        raise ValueError(f"effect {effect} changes the displacement only; use channels displacement or both")
    if n_samples is not None and (isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer))
                                  or n_samples < 400):
        raise ValueError(f"n_samples must be an integer >= 400, got {n_samples!r}")


def simulate(effect: str, seed: int, channels: str = "both", *, n_samples: int | None = None) -> Simulation:
    """The noise-free recording of :func:`generate` (same draws), with its ``none`` reference.

    The effect's size is enlarged (at most :data:`MAX_BOOSTS` times, up to its cap) until
    every channel it acts on changes by at least :data:`MIN_VISIBILITY` noise deviations; the
    decision looks at both channels whatever ``channels`` asks for, so the clean arrays of a
    channel set are the same as those columns of ``"both"``. Runs without importing hyst_gym.
    """
    _check_arguments(effect, seed, channels, n_samples)
    wanted = ("magnetization", "displacement") if channels == "both" else (channels,)
    spec = EFFECT_SPECS[effect]
    judged = ("displacement",) if spec.displacement_only else ("magnetization", "displacement")
    base = draw_base(seed, n_samples)
    noise_rel = base.conditions.noise_rel
    time, field, info = excitation(base)
    cache = {}
    reference = _forward(base, NO_EFFECT, time, field, cache=cache)
    reference_rec = _recorded(reference)
    drawn = eff = _draw_effect(effect, base, reference)
    outputs, boosts = reference, 0
    visibility = {ch: 0.0 for ch in judged}
    if effect != "none":
        exponent, last = 1.0, None  # visibility ~ knob**exponent, learnt from the boosts
        for boosts in range(MAX_BOOSTS + 1):
            outputs = _forward(base, eff, time, field, reference, cache)
            visibility = _visibility(_recorded(outputs, judged), reference_rec, noise_rel)
            weakest = min(visibility.values())
            if weakest >= MIN_VISIBILITY or eff.saturated or boosts == MAX_BOOSTS:
                break
            if last is not None and weakest > last[1] > 0 and eff[eff.knob] > last[0]:
                exponent = min(max(math.log(weakest / last[1]) / math.log(eff[eff.knob] / last[0]), 0.5), 4.0)
            last = (eff[eff.knob], weakest)
            # aim at 1.5x the threshold
            eff = eff.boosted(min(max((1.5 * MIN_VISIBILITY / max(weakest, 1e-3)) ** (1.0 / exponent), 1.2), 20.0))
    truth = dict(
        effect=effect, in_vocabulary=spec.in_vocabulary, description=spec.description,
        effect_parameters=dict(eff.values, **_derived(base, eff, time, field)),
        drawn_effect_parameters=dict(drawn.values),
        size_knob=eff.knob, size_boost=(eff[eff.knob] / drawn[drawn.knob]) if eff.knob else 1.0, boosts=boosts,
        visibility={ch: visibility[ch] for ch in wanted if ch in visibility},
        visible=effect == "none" or all(visibility[ch] >= MIN_VISIBILITY for ch in wanted if ch in visibility),
        seed=int(seed), channels=channels,
        sample_rate=base.conditions.sample_rate, n_samples=base.conditions.n_samples, noise_rel=noise_rel,
        excitation_family=base.conditions.family, excitation=base.conditions.family, excitation_details=info,
        conditions=base.conditions.as_dict(),
        material=base.material.as_dict(), mechanics=base.mechanics.as_dict(),
        initial_state="initial curve from the demagnetized state (M = 0 at H = 0) to the first field",
        generator="experiments.independent_recordings",
    )
    return Simulation(time=time[::OVERSAMPLE].copy(), field=field[::OVERSAMPLE].copy(),
                      clean=_recorded(outputs, wanted), truth=_jsonable(truth),
                      reference=_recorded(reference, wanted))


def add_noise(sim: Simulation, effect: str, seed: int, channels: str) -> tuple[dict, dict]:
    """White Gaussian noise of ``noise_rel * ptp`` on each output (stream (seed, effect,
    channels)); returns (noisy channels, noise standard deviations)."""
    rng = _stream(seed, "noise", effect, channels)
    noisy, sigmas = {}, {}
    for ch in ("magnetization", "displacement"):
        if ch in sim.clean:
            y = sim.clean[ch]
            sigmas[ch] = sim.truth["noise_rel"] * float(np.ptp(y))
            noisy[ch] = y + sigmas[ch] * rng.standard_normal(y.size)
    return noisy, sigmas


def generate(effect: str, seed: int, channels: str = "both", *, n_samples: int | None = None):
    """A synthetic recording with ``effect`` concealed in it: (Recording, truth dict).

    effect : one of :data:`ALL_EFFECTS` (``"none"`` included);  seed : int >= 0;
    channels : "magnetization" (field + M), "displacement" (field + x) or "both";
    n_samples : record length override (default: drawn, 5000-20000).
    Deterministic: the same arguments give identical arrays.
    """
    # imported here so that the physics above runs (and is tested) without hyst_gym;
    # importing hyst_gym.diagnose.recording loads the package, whose code this module never calls
    from hyst_gym.diagnose.recording import Recording

    sim = simulate(effect, seed, channels, n_samples=n_samples)
    noisy, sigmas = add_noise(sim, effect, seed, channels)
    truth = dict(sim.truth, noise_std=sigmas)
    recording = Recording(time=sim.time, field=sim.field, metadata=sidecar(seed),
                          source=f"independent synthetic recording, seed {seed}", **noisy)
    return recording, truth


def check_drive(drive, n_samples: int, name: str = "drive") -> np.ndarray:
    """``drive`` as a float array of ``n_samples`` finite values (A/m), or a ValueError naming the problem."""
    values = np.asarray(drive, dtype=float)
    if values.ndim != 1 or values.size != n_samples:
        raise ValueError(f"{name} must be a 1-D array of {n_samples} samples (the record's), got shape {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return values


def replay(effect: str, seed: int, channels: str = "both", drive=None, *, noise_seed: int,
           n_samples: int | None = None):
    """The hidden system of :func:`generate` ``(effect, seed, channels, n_samples)`` under another ``drive``
    (A/m at the record's samples; None: its own recorded field): (Recording, truth dict).

    Kept from the first record: the material, mechanics and sensors, the effect's parameters at the size the
    first record's visibility check settled on, the frames of the static maps and the coil's heating gain
    (``_forward``'s ``frame``), the start state (demagnetized, then the initial curve to the drive's first
    value; the mechanics, sensors and coil temperature settled) and the absolute noise standard deviations.
    New: the drive (held between samples by its cubic spline on the fine grid, as the generator holds its
    own) and the noise draw, from the stream (seed, "replay", effect, channels, ``noise_seed``), which is
    never the first record's. Deterministic in all arguments."""
    from hyst_gym.diagnose.recording import Recording

    if isinstance(noise_seed, bool) or not isinstance(noise_seed, (int, np.integer)) or noise_seed < 0:
        raise ValueError(f"noise_seed must be an integer >= 0, got {noise_seed!r}")
    sim = simulate(effect, seed, channels, n_samples=n_samples)
    base = draw_base(seed, n_samples)
    time, field, _ = excitation(base)
    drawn = _draw_effect(effect, base, _forward(base, NO_EFFECT, time, field))
    settled = sim.truth["effect_parameters"]
    eff = replace(drawn, values=tuple((k, settled[k]) for k, _ in drawn.values))
    first = _forward(base, eff, time, field)
    record_time = time[::OVERSAMPLE]
    if drive is None:
        fine, recorded_field = field, field[::OVERSAMPLE].copy()
    else:
        recorded_field = check_drive(drive, record_time.size)
        fine = CubicSpline(record_time, recorded_field)(time)
    outputs = _recorded(_forward(base, eff, time, fine, frame={"field": field, "M": first["M"], "x": first["x"]}),
                        tuple(sim.clean))
    rng = _stream(seed, "replay", effect, channels, str(int(noise_seed)))
    sigmas = {ch: sim.truth["noise_rel"] * float(np.ptp(y)) for ch, y in sim.clean.items()}
    noisy = {ch: y + sigmas[ch] * rng.standard_normal(y.size) for ch, y in outputs.items()}
    truth = dict(sim.truth, noise_std=sigmas, replay={"noise_seed": int(noise_seed), "own_drive": drive is None})
    recording = Recording(time=record_time.copy(), field=recorded_field, metadata=sidecar(seed),
                          source=f"independent synthetic recording, seed {seed}, replay {noise_seed}", **noisy)
    return recording, truth


def sidecar(seed: int) -> dict:
    """Sidecar metadata: nothing in it names or hints at the effect."""
    return {"material": "Terfenol-D (synthetic)", "notes": f"synthetic recording (independent generator), seed {seed}"}


def _jsonable(value):
    """Plain JSON types (numpy scalars/arrays to Python floats/lists)."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value)
    return value


# ---------------------------------------------------------------------------- command line

def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def _samples(text: str) -> int:
    value = _seed(text)
    if value < 400:
        raise argparse.ArgumentTypeError(f"must be >= 400, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m experiments.independent_recordings",
                                     description="Independent synthetic recordings for the mismatch tool.")
    parser.add_argument("--effect", required=True, choices=ALL_EFFECTS, help="concealed effect")
    parser.add_argument("--seed", required=True, type=_seed, help="integer >= 0")
    parser.add_argument("--channels", default="both", choices=CHANNEL_SETS)
    parser.add_argument("--samples", type=_samples, default=None, help="record length (default: drawn)")
    parser.add_argument("--out", required=True, type=Path, help="CSV to write (sidecar .json beside it)")
    parser.add_argument("--truth", type=Path, default=None, help="JSON file for the truth (effect, parameters)")
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.out.suffix.lower() != ".csv":
        parser.error(f"--out must name a .csv file, got {str(args.out)!r}")
    if args.truth is not None and args.truth.resolve() in (args.out.resolve(), args.out.with_suffix(".json").resolve()):
        parser.error("--truth must not be the CSV or its sidecar")
    try:
        recording, truth = generate(args.effect, args.seed, args.channels, n_samples=args.samples)
    except ValueError as error:
        parser.error(str(error))
    from hyst_gym.diagnose.recording import write_recording

    try:
        write_recording(args.out, recording, recording.metadata)
        if args.truth is not None:
            args.truth.parent.mkdir(parents=True, exist_ok=True)
            args.truth.write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")
    except OSError as error:
        parser.error(f"cannot write {error.filename or args.out}: {error.strerror or error}")
    print(f"wrote {args.out} ({recording.size} samples, columns: time, field, {', '.join(recording.channels)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
