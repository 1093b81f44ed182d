"""Synthetic recordings whose physics takes OTHER FORMS than the mismatch tool's equations (issue 22).

The mismatch tool (:mod:`hyst_gym.diagnose`) names the slot of its model chain that a recording's
concealed physics fills. Its study generators write that physics in the tool's own forms (or the
same forms with other numerics, :mod:`experiments.independent_recordings`). This module writes
each effect in forms the tool does not use, so that the tool can be measured on forms it never
wrote. It imports nothing from ``hyst_gym.physics``, ``hyst_gym.estimation`` or the diagnose
kernels/model/fit/core; from :mod:`experiments.independent_recordings` (itself independent of the
fitter) it reuses the random streams, the parameter draws (:func:`draw_base`), the excitation
families, the material class and the hysteresis slope (1) of eq. (6). ``hyst_gym.diagnose.recording``
is imported lazily, only to hand results over in the tool's CSV format.

Cases (truth -> forms -> verdicts that count as right):

=======================  ============================================================  ==========================
``none_other_numerics``  no effect; other numerics (see below), hold of the mechanics'      {none}
                         input drawn: linear or zero-order hold on a fine substep grid
``delta_e_shifted``      Delta-E stiffness k(M) = khat*(1 + beta*g(M)) / (1 + beta*g(Mref)),  {delta_e}
                         g one of ((M-Mb)/Ms)^2, |(M-Mb)/Ms|^p (p 1.3-3),
                         -sech^2((M-Mb)/(w*Ms)) (a softening dip), Mb != 0
``saturating_amplifier`` true field = S(recorded field): Hs*tanh(H/Hs), Hs*(2/pi)*atan(     {input_map}
                         pi/2*H/Hs), Hs*erf(sqrt(pi)/2*H/Hs), or tanh with other Hs for
                         H < 0 (asymmetric)
``sensor_nonlinearity``  displacement sensor x_rec = c + s*f(g*v)/g, v = (x - c)/s:          {sensor_map}
                         f = atan, tanh or exp(.) - 1 (not a polynomial)
``heating_other_law``    coil heating ~ |H| or H^2 through a two-time-constant network      {thermal_drift}
                         (series coil -> rod, or two parallel paths); a(T) linear with
                         another slope or exponential; Ms(T) Bloch-like
                         (1 - (T/Tc)^1.5) or linear or constant
``sensor_offset_drift``  slow additive offset on a sensor: low-passed random walk,          {sensor_drift}
                         exponential settling, logarithmic creep, linear (integrator)
``sensor_gain_drift``    slow drift of a sensor's gain (a multiplicative factor): a       {sensor_gain_drift}
                         two-stage warm-up (two time constants), a low-passed random
                         walk, square-root creep (not the tool's one-settling family)
``mains_pickup``         additive 50 or 60 Hz (+-0.2 %) with a 3rd and a 5th harmonic       {mains_pickup}
``magnetostriction_law`` an even law lambda(M/Ms), lambda(0) = 0, not a polynomial:      {quadratic_
                         tanh((m/w)^2), 1 - exp(-(m/w)^2) (saturating) or |m|^p (p          magnetostriction}
                         2.5-3.5), blended with the linear M (share 0.5-1)
``continuum_rod``        fixed-free rod with a tip mass, 6 longitudinal modes from           {rod_dynamics}
                         beta*L*tan(beta*L) = rod mass / tip mass, constant or Rayleigh
                         damping; driven by a log chirp reaching 1.5-3x the first resonance
``input_dynamics``       true field = a filtered copy of the recorded one (an amplifier's    {input_lag}
                         bandwidth, a coil's L/R): a second-order low-pass (damping
                         0.4-1), a first-order lag with a delay, or a pure delay
``two_phase_rod``        two magnetic phases in parallel (different a, Ms, k, c): the       {unexplained, ambiguous}
                         mixture drives both channels, or only phase 1 is magnetostrictive
=======================  ============================================================  ==========================

Numerics (other than the fitter's and other than independent_recordings'): the recorded field is
linearly interpolated between samples (no spline; the magnetization is rate independent, so
its samples do not depend on the hold); the hysteresis ODE is integrated *in the field*, one
``scipy.integrate.solve_ivp`` call (LSODA or DOP853, drawn for ``none_other_numerics``) per
monotone run of the field, starting on the initial curve; a time-varying a(t), Ms(t) is read at
the time t(H) of the run's linear interpolant. The mechanics (lumped, Delta-E and the rod's
modes) are integrated by the Newmark average-acceleration rule on 6-16 substeps per sample with
the input linear or zero-order held.

Effect sizes are drawn in physical ranges; if the effect's mean-removed RMS change of the
noise-free recorded channels it acts on (against the same case at zero size) is below
:data:`MIN_VISIBILITY` noise standard deviations, its size is enlarged, up to a physical cap.
Channel sets: ``magnetization`` is skipped for effects that show only in the displacement
(``delta_e_shifted``, ``sensor_nonlinearity``, ``continuum_rod``): :data:`CASES` lists each
case's channel sets. Every draw comes from ``default_rng(SeedSequence([seed, crc32(labels)]))``.

Command line::

    python -m experiments.other_forms --case delta_e_shifted --seed 3 --channels both \\
        --out rec.csv [--truth truth.json] [--samples N]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.special import erf

from experiments import independent_recordings as ir

CHANNEL_SETS = ir.CHANNEL_SETS
BOTH = ("magnetization", "displacement")
#: Default record length (samples): one diagnosis ~10-30 s.
DEFAULT_SAMPLES = 4000
#: Least visibility: mean-removed RMS change in noise standard deviations.
MIN_VISIBILITY = 3.0
MAX_BOOSTS = 6
#: Longitudinal modes of the continuum rod.
ROD_MODES = 6
#: Relative / absolute (fraction of Ms) tolerance of the field-domain magnetization solve.
RTOL = 1e-9
ATOL = 1e-9


@dataclass(frozen=True)
class CaseSpec:
    name: str
    expected: frozenset
    channel_sets: tuple
    forms: tuple
    description: str


CASES = {c.name: c for c in (
    CaseSpec("none_other_numerics", frozenset({"none"}), CHANNEL_SETS, ("lsoda_linear", "dop853_linear",
             "lsoda_zoh", "dop853_zoh"), "no effect; other numerics (field-domain ODE solver, input hold)"),
    CaseSpec("delta_e_shifted", frozenset({"delta_e"}), ("displacement", "both"),
             ("quadratic_shifted", "power_shifted", "sech_dip"), "stiffness following M about Mb != 0"),
    CaseSpec("saturating_amplifier", frozenset({"input_map"}), CHANNEL_SETS,
             ("tanh", "arctan", "erf", "asymmetric_tanh"), "true field a saturating function of the recorded one"),
    CaseSpec("sensor_nonlinearity", frozenset({"sensor_map"}), ("displacement", "both"),
             ("arctan", "tanh", "exponential"), "static non-polynomial map of the displacement sensor"),
    CaseSpec("heating_other_law", frozenset({"thermal_drift"}), CHANNEL_SETS,
             ("two_time_constant",), "coil heating with another drive, network, a(T) and Ms(T) law"),
    CaseSpec("sensor_offset_drift", frozenset({"sensor_drift"}), CHANNEL_SETS,
             ("random_walk", "exponential", "logarithmic", "linear"), "slow additive drift of a sensor offset"),
    CaseSpec("sensor_gain_drift", frozenset({"sensor_gain_drift"}), CHANNEL_SETS,
             ("two_stage", "random_walk", "sqrt_creep"), "slow drift of a sensor's gain"),
    CaseSpec("mains_pickup", frozenset({"mains_pickup"}), CHANNEL_SETS, ("50Hz", "60Hz"),
             "additive mains pickup with 3rd and 5th harmonics"),
    CaseSpec("magnetostriction_law", frozenset({"quadratic_magnetostriction"}), ("displacement", "both"),
             ("tanh_saturating", "gaussian_saturating", "power"), "an even, non-polynomial magnetostriction law"),
    CaseSpec("continuum_rod", frozenset({"rod_dynamics"}), ("displacement", "both"),
             ("modal_constant_damping", "modal_rayleigh_damping"), "fixed-free rod with a tip mass, 6 modes"),
    CaseSpec("input_dynamics", frozenset({"input_lag"}), CHANNEL_SETS,
             ("second_order", "first_order_delay", "pure_delay"),
             "true field a filtered or delayed copy of the recorded one (amplifier bandwidth, coil L/R)"),
    CaseSpec("two_phase_rod", frozenset({"unexplained", "ambiguous"}), CHANNEL_SETS, ("mixture", "split_roles"),
             "two magnetic phases in parallel (fits no slot)"),
)}
ALL_CASES = tuple(CASES)


# ---------------------------------------------------------------------------- numerics

def monotone_runs(field) -> list[tuple[int, int, float]]:
    """(first, last, direction) of each monotone run of the sampled field (inclusive indices);
    samples where the field does not move belong to the run they sit in."""
    steps = np.sign(np.diff(field))
    runs, start, direction = [], 0, 0.0
    for i, s in enumerate(steps):
        if s == 0.0:
            continue
        if direction == 0.0:
            direction = s
        elif s != direction:
            runs.append((start, i, direction))
            start, direction = i, s
    runs.append((start, len(field) - 1, direction or 1.0))
    return runs


def magnetization(time, field, material: ir.Material, *, a_scale=None, ms_scale=None,
                  method: str = "LSODA") -> np.ndarray:
    """M (A/m) at the samples of ``field`` (A/m), linearly interpolated between them: eq. (6)
    integrated in the field, one ``solve_ivp`` per monotone run, from the initial curve at
    ``field[0]``. ``a_scale``/``ms_scale`` (arrays on ``time``): a(t)/a and Ms(t)/Ms, read at the
    time of the run's linear interpolant where the field passes H."""
    field = np.asarray(field, dtype=float)
    mat = material
    out = np.empty(field.size)
    out[0] = ir.initial_magnetization(float(field[0]), mat)
    slope = ir.hysteresis_slope
    index = np.arange(field.size, dtype=float)
    for first, last, delta in monotone_runs(field):
        H = field[first:last + 1]
        if last == first or H[-1] == H[0]:
            out[first:last + 1] = out[first]
            continue
        order = slice(None) if delta > 0 else slice(None, None, -1)
        H_sorted, at = H[order], index[first:last + 1][order]

        if a_scale is None:
            def rhs(h, y, delta=delta):
                return [slope(h, y[0], delta, mat.a, mat.k, mat.alpha, mat.Ms, mat.c, mat.curve, mat.chi_rev)]
        else:
            def rhs(h, y, delta=delta, H_sorted=H_sorted, at=at):
                s = np.interp(h, H_sorted, at)  # fractional sample index where the field is h
                a = mat.a * float(np.interp(s, index, a_scale))
                Ms = mat.Ms * float(np.interp(s, index, ms_scale))
                return [slope(h, y[0], delta, a, mat.k, mat.alpha, Ms, mat.c, mat.curve, mat.chi_rev)]

        # evaluation points: the run's distinct field values (a flat stretch shares one)
        values, inverse = np.unique(H, return_inverse=True)
        t_eval = values if delta > 0 else values[::-1]
        sol = solve_ivp(rhs, (float(H[0]), float(H[-1])), [out[first]], method=method, t_eval=t_eval,
                        rtol=RTOL, atol=ATOL * mat.Ms, max_step=max(min(mat.k, mat.a) / 4, 1e-9))
        if not sol.success:  # pragma: no cover
            raise RuntimeError(f"magnetization solve failed: {sol.message}")
        y = sol.y[0] if delta > 0 else sol.y[0][::-1]
        out[first + 1:last + 1] = y[np.asarray(inverse).reshape(-1)][1:]
    return out


def held_input(values, substeps: int, hold: str) -> np.ndarray:
    """``values`` (uniform samples) on a grid ``substeps`` times finer: linear interpolation,
    or a zero-order hold on the fine grid (each fine interval keeps its start value)."""
    n = len(values)
    fine = np.arange((n - 1) * substeps + 1) / substeps
    linear = np.interp(fine, np.arange(n), values)
    if hold == "linear":
        return linear
    held = np.empty_like(linear)
    held[0] = linear[0]
    held[1:] = linear[:-1]
    return held


def newmark(forcing, dt: float, omega2, damping, gain, output, *, stiffness_factor=None,
            substeps: int = 8, hold: str = "linear") -> np.ndarray:
    """Modal mechanics q_i'' + damping_i*q_i' + omega2_i*s(t)*q_i = gain_i*F(t), x = sum output_i*q_i,
    by the Newmark average-acceleration rule (implicit trapezoid, unconditionally stable) on
    ``substeps`` steps per sample of ``forcing`` (held by ``hold``); ``stiffness_factor`` s(t)
    (samples, default 1). Starts at the static equilibrium of the first sample."""
    omega2, damping, gain, output = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (omega2, damping, gain, output))
    F = held_input(forcing, substeps, hold)
    S = np.ones_like(F) if stiffness_factor is None else held_input(stiffness_factor, substeps, "linear")
    h = dt / substeps
    q = gain * F[0] / (omega2 * S[0])
    v = np.zeros_like(q)
    acc = np.zeros_like(q)
    out = np.empty(len(forcing))
    out[0] = float(output @ q)
    half, quarter = 0.5 * h, 0.25 * h * h
    for n in range(1, F.size):
        k = omega2 * S[n]
        acc_new = (gain * F[n] - damping * (v + half * acc) - k * (q + h * v + quarter * acc)) \
            / (1.0 + damping * half + k * quarter)
        q = q + h * v + quarter * (acc + acc_new)
        v = v + half * (acc + acc_new)
        acc = acc_new
        if n % substeps == 0:
            out[n // substeps] = float(output @ q)
    return out


def rod_modes(mass_ratio: float, n_modes: int = ROD_MODES):
    """Fixed-free rod with a tip mass in units L = EA = rho*A = 1 (so omega_n = beta_n):
    (beta_n*L, static tip compliance of each mode phi_n(L)^2/(m_n*omega_n^2)). ``mass_ratio`` mu =
    rod mass / tip mass; frequency equation beta*L*tan(beta*L) = mu (:func:`rod_frequency_roots`);
    mode shapes sin(beta_n x), modal mass int_0^1 sin^2 + sin^2(beta_n)/mu. Over all modes the
    compliances sum to the rod's L/(EA) = 1; the first few hold nearly all of it."""
    roots = rod_frequency_roots(mass_ratio, n_modes)
    modal_mass = 0.5 - np.sin(2 * roots) / (4 * roots) + np.sin(roots) ** 2 / mass_ratio
    return roots, np.sin(roots) ** 2 / (modal_mass * roots ** 2)


def rod_frequency_roots(mass_ratio: float, n_modes: int) -> np.ndarray:
    """The first ``n_modes`` roots beta*L of beta*L*tan(beta*L) = mass_ratio (one per branch
    (j*pi, j*pi + pi/2)), by brentq."""
    eps = 1e-12
    return np.array([brentq(lambda z: z * math.sin(z) - mass_ratio * math.cos(z), j * math.pi + eps,
                            j * math.pi + 0.5 * math.pi - eps, xtol=1e-14) for j in range(n_modes)])


# ---------------------------------------------------------------------------- maps (pure functions)

def amplifier(field, form: str, overdrive: float, asymmetry: float = 1.0) -> np.ndarray:
    """The saturating amplifier's true field for the recorded ``field``: unit small-signal gain,
    Hs = max|field|/overdrive (overdrive 0: the identity)."""
    field = np.asarray(field, dtype=float)
    if overdrive == 0.0:
        return field.copy()
    hs = float(np.max(np.abs(field))) / overdrive
    if form == "tanh":
        return hs * np.tanh(field / hs)
    if form == "arctan":
        return hs * (2 / np.pi) * np.arctan(0.5 * np.pi * field / hs)
    if form == "erf":
        return hs * erf(0.5 * math.sqrt(math.pi) * field / hs)
    if form == "asymmetric_tanh":
        hs_neg = hs * asymmetry
        return np.where(field >= 0, hs * np.tanh(field / hs), hs_neg * np.tanh(field / hs_neg))
    raise ValueError(f"unknown amplifier form {form!r}")


def sensor_map(y, form: str, gain: float, offset: float) -> np.ndarray:
    """A non-polynomial static sensor map about c = mid-range + offset*s (s the half range):
    ``c + s*f(gain*v)/gain``, v = (y - c)/s, unit slope at c (gain 0: the identity)."""
    y = np.asarray(y, dtype=float)
    if gain == 0.0:
        return y.copy()
    half = 0.5 * float(np.ptp(y)) or 1.0
    centre = 0.5 * (float(np.max(y)) + float(np.min(y))) + offset * half
    v = gain * (y - centre) / half
    f = {"arctan": np.arctan, "tanh": np.tanh, "exponential": np.expm1}[form]
    return centre + half * f(v) / gain


def mains(time, frequency: float, amplitude: float, harmonics, phases) -> np.ndarray:
    """Pickup ``amplitude*(sin(w t + p1) + r3 sin(3 w t + p3) + r5 sin(5 w t + p5))``."""
    w = 2 * np.pi * frequency * np.asarray(time, dtype=float)
    r3, r5 = harmonics
    p1, p3, p5 = phases
    return amplitude * (np.sin(w + p1) + r3 * np.sin(3 * w + p3) + r5 * np.sin(5 * w + p5))


def drift(time, form: str, amplitude: float, tau: float, walk=None) -> np.ndarray:
    """A slow offset drift starting at 0 (``walk``: the unit-RMS low-passed random walk)."""
    t = np.asarray(time, dtype=float) - float(time[0])
    duration = float(t[-1]) or 1.0
    if form == "random_walk":
        return amplitude * walk
    if form == "exponential":
        return amplitude * -np.expm1(-t / tau)
    if form == "logarithmic":
        return amplitude * np.log1p(t / tau) / math.log1p(duration / tau)
    if form == "linear":
        return amplitude * t / duration
    raise ValueError(f"unknown drift form {form!r}")


def magnetostriction(M, Ms: float, form: str, width: float, power: float) -> np.ndarray:
    """An even magnetostriction law lambda(m), m = M/Ms, lambda(0) = 0, in arbitrary units: tanh((m/w)^2) or
    1 - exp(-(m/w)^2) (both saturate beyond m ~ w), or |m|^p."""
    m = np.asarray(M, dtype=float) / Ms
    if form == "tanh_saturating":
        return np.tanh((m / width) ** 2)
    if form == "gaussian_saturating":
        return -np.expm1(-(m / width) ** 2)
    if form == "power":
        return np.abs(m) ** power
    raise ValueError(f"unknown magnetostriction form {form!r}")


def gain_drift(time, form: str, amplitude: float, tau: float, walk=None, share: float = 0.5) -> np.ndarray:
    """A sensor's relative gain change starting at 0 (the reading is the true output times 1 + this): a
    two-stage warm-up (a fast settling with time constant ``tau`` and share ``share``, the rest with 10 x
    ``tau``), a low-passed random walk (``walk``, unit RMS) or square-root creep."""
    t = np.asarray(time, dtype=float) - float(time[0])
    duration = float(t[-1]) or 1.0
    if form == "two_stage":
        return amplitude * (share * -np.expm1(-t / tau) + (1.0 - share) * -np.expm1(-t / (10.0 * tau)))
    if form == "random_walk":
        return amplitude * walk
    if form == "sqrt_creep":
        return amplitude * np.sqrt(t / duration)
    raise ValueError(f"unknown gain drift form {form!r}")


def thermal_rise(time, field, law: dict, rise: float) -> np.ndarray:
    """Rod temperature rise (K) through a two-time-constant network driven by ``|H|`` or ``H^2``
    (``law["drive"]``), exact for a drive linear between samples; scaled so that the record's
    mean drive would heat the rod by ``rise`` K in the steady state.

    series: tau1*th1' = P - th1 (coil), tau2*th2' = th1 - th2 (rod sees th2);
    parallel: th = w*th_fast + (1-w)*th_slow, each tau_i*th_i' = P - th_i."""
    field = np.asarray(field, dtype=float)
    drive = np.abs(field) if law["drive"] == "abs" else field ** 2
    drive = rise * drive / (float(np.mean(drive)) or 1.0)
    dt = float(time[1] - time[0])

    def stage(u, tau):
        num, den, _ = signal.cont2discrete(([1.0], [tau, 1.0]), dt, method="foh")
        num = np.ravel(num)
        y, _ = signal.lfilter(num, den, u, zi=signal.lfilter_zi(num, den) * 0.0)
        return y

    if law["network"] == "series":
        return stage(stage(drive, law["tau1"]), law["tau2"])
    w = law["fast_share"]
    return w * stage(drive, law["tau1"]) + (1 - w) * stage(drive, law["tau2"])


def material_scales(theta, law: dict) -> tuple[np.ndarray, np.ndarray]:
    """(a(T)/a, Ms(T)/Ms) at the temperature rise ``theta`` (K) above T_amb."""
    T0 = ir.T_AMBIENT
    if law["a_law"] == "linear":
        a_scale = 1.0 + law["a_slope"] * theta
    else:
        a_scale = np.exp(law["a_slope"] * theta)
    if law["ms_law"] == "bloch":
        tc = law["curie"]
        ms_scale = (1.0 - ((T0 + theta) / tc) ** 1.5) / (1.0 - (T0 / tc) ** 1.5)
    elif law["ms_law"] == "linear":
        ms_scale = 1.0 - law["ms_slope"] * theta
    else:
        ms_scale = np.ones_like(theta)
    return np.maximum(a_scale, 0.05), np.maximum(ms_scale, 0.05)


# ---------------------------------------------------------------------------- draws

@dataclass(frozen=True)
class Setup:
    """Everything of one (case, seed) but the effect's size: conditions, recorded field,
    numerics and the effect's form and parameters (``knob`` sets the size)."""

    case: str
    seed: int
    base: ir.BaseDraw
    time: np.ndarray
    field: np.ndarray
    excitation: dict
    numerics: dict
    form: str
    params: dict
    knob: str | None
    knob_max: float

    def sized(self, factor: float) -> Setup:
        """The same setup with the knob multiplied by ``factor`` (capped)."""
        if self.knob is None:
            return self
        params = dict(self.params)
        value = params[self.knob]  # a signed knob keeps its sign; the cap bounds its magnitude
        params[self.knob] = math.copysign(float(min(abs(value) * factor, abs(self.knob_max))), value)
        return replace(self, params=params)

    @property
    def saturated(self) -> bool:
        return self.knob is None or abs(self.params[self.knob]) >= abs(self.knob_max)


def _choice(rng, options):
    return options[int(rng.integers(len(options)))]


def _numerics(case, seed):
    rng = ir._stream(seed, "other_forms", "numerics", case)
    method = _choice(rng, ("LSODA", "DOP853"))
    hold = _choice(rng, ("linear", "zoh")) if case == "none_other_numerics" else "linear"
    substeps = int(rng.integers(6, 17)) if hold == "linear" else int(rng.integers(12, 17))
    return {"method": method, "hold": hold, "substeps": substeps}


def _rod_excitation(base: ir.BaseDraw, rng):
    """A log chirp from 2-6 cycles/record to 1.5-3x the first resonance, at a sample rate high
    enough for the rod's second mode; returns (base with that rate, time, field, info)."""
    f1 = math.sqrt(base.mechanics.khat) / (2 * math.pi)
    top = rng.uniform(1.5, 3.0) * f1
    fs = rng.uniform(30e3, 60e3)
    cond = replace(base.conditions, sample_rate=fs, family="chirp", coil_cutoff=fs / 2)
    base = replace(base, conditions=cond)
    time = np.arange(cond.n_samples) / fs
    duration = cond.n_samples / fs
    f0 = rng.uniform(2.0, 6.0) / duration
    sweep = signal.chirp(time, f0=f0, t1=time[-1], f1=top, method="logarithmic", phi=rng.uniform(0, 360))
    envelope = 1.0 - rng.uniform(0.0, 0.5) * time / duration
    field = cond.bias + cond.amplitude * envelope * sweep
    return base, time, field, {"family": "chirp", "f0": f0, "f1": top, "first_resonance": f1,
                               "amplitude": cond.amplitude, "bias": cond.bias}


def setup(case: str, seed: int, n_samples: int | None = None) -> Setup:
    """Conditions, field, numerics and effect draw for (case, seed)."""
    base = ir.draw_base(seed, n_samples or DEFAULT_SAMPLES)
    rng = ir._stream(seed, "other_forms", "effect", case)
    if case == "continuum_rod":
        base, time, field, info = _rod_excitation(base, rng)
    else:
        fine_time, fine_field, info = ir.excitation(base)
        time, field = fine_time[::ir.OVERSAMPLE].copy(), fine_field[::ir.OVERSAMPLE].copy()
    spec = CASES[case]
    form = _choice(rng, spec.forms)
    numerics = _numerics(case, seed)
    if case == "none_other_numerics":
        form = f"{numerics['method'].lower()}_{numerics['hold']}"
    duration = base.conditions.duration
    knob, knob_max, p = None, math.inf, {}
    if case == "delta_e_shifted":
        p = {"Mb_fraction": rng.uniform(0.2, 0.6) * rng.choice([-1.0, 1.0])}
        if form == "sech_dip":
            p.update(beta=rng.uniform(0.15, 0.45), width=rng.uniform(0.2, 0.5))
            knob, knob_max = "beta", 0.8
        else:
            p.update(beta=rng.uniform(0.3, 1.0), power=2.0 if form == "quadratic_shifted" else rng.uniform(1.3, 3.0))
            knob, knob_max = "beta", 3.0
    elif case == "saturating_amplifier":
        p = {"overdrive": rng.uniform(0.5, 1.5), "asymmetry": rng.uniform(1.3, 2.0) ** rng.choice([-1.0, 1.0])}
        knob, knob_max = "overdrive", 4.0
    elif case == "sensor_nonlinearity":
        cap = 1.5 if form == "exponential" else 3.0
        p = {"gain": rng.uniform(0.1, 0.4) if form == "exponential" else rng.uniform(0.3, 1.0),
             "offset": rng.uniform(-0.3, 0.3)}
        if form == "exponential":
            p["gain"] *= rng.choice([-1.0, 1.0])
            cap = math.copysign(cap, p["gain"])
        knob, knob_max = "gain", cap
    elif case == "heating_other_law":
        network = _choice(rng, ("series", "parallel"))
        a_law = _choice(rng, ("linear", "exponential"))
        ms_law = _choice(rng, ("bloch", "linear", "constant"))
        form = f"{network}/{a_law}_a/{ms_law}_Ms"
        p = {"rise": rng.uniform(20.0, 50.0), "drive": _choice(rng, ("abs", "square")), "network": network,
             "tau1": rng.uniform(0.05, 0.3) * duration, "tau2": rng.uniform(0.5, 3.0) * duration,
             "fast_share": rng.uniform(0.3, 0.7), "a_law": a_law,
             # not the tool's a ~ T (slope 1/T_amb = 3.4e-3/K): 1-2.5e-3/K or 5-8e-3/K
             "a_slope": _choice(rng, (rng.uniform(1e-3, 2.5e-3), rng.uniform(5e-3, 8e-3))),
             "ms_law": ms_law, "curie": rng.uniform(420.0, 700.0), "ms_slope": rng.uniform(5e-4, 2e-3)}
        knob, knob_max = "rise", 150.0
    elif case in ("sensor_offset_drift", "sensor_gain_drift"):
        p = _drift_draw(rng, case, form, duration)
        knob, knob_max = "amplitude", math.copysign(0.3, p["amplitude"])
    elif case == "mains_pickup":
        p = {"frequency": (50.0 if form == "50Hz" else 60.0) * (1 + rng.uniform(-0.002, 0.002)),
             "amplitude": rng.uniform(0.003, 0.02), "r3": rng.uniform(0.1, 0.5), "r5": rng.uniform(0.0, 0.15),
             "phases": rng.uniform(0, 2 * np.pi, 3).tolist(),
             "channel": _choice(rng, ("magnetization", "displacement", "both"))}
        knob, knob_max = "amplitude", 0.2
    elif case in ("magnetostriction_law", "continuum_rod"):
        p, knob, knob_max = _mechanics_draw(rng, case)
    elif case == "input_dynamics":
        p, knob, knob_max = _input_dynamics_draw(rng, form, base.conditions.sample_rate), "scale", 20.0
    elif case == "two_phase_rod":
        def ratio():
            return ir._log_uniform(rng, 1.5, 3.0) ** rng.choice([-1.0, 1.0])
        p = {"w": rng.uniform(0.25, 0.5), "a_ratio": ratio(), "k_ratio": ratio(),
             "c_ratio": ir._log_uniform(rng, 0.5, 2.0),
             "Ms_ratio": _choice(rng, (rng.uniform(0.6, 0.85), rng.uniform(1.15, 1.4)))}
        knob, knob_max = "w", 0.5
    return Setup(case=case, seed=int(seed), base=base, time=time, field=field, excitation=info,
                 numerics=numerics, form=form, params=p, knob=knob, knob_max=knob_max)


def _mechanics_draw(rng, case: str) -> tuple[dict, str, float]:
    """(parameters, size knob, its cap) of the even magnetostriction law or the continuum rod."""
    if case == "magnetostriction_law":
        return ({"blend": rng.uniform(0.5, 1.0), "width": rng.uniform(0.3, 0.7), "power": rng.uniform(2.5, 3.5)},
                "blend", 1.0)
    return ({"mass_ratio": rng.uniform(0.5, 3.0), "zeta1": rng.uniform(0.01, 0.05),
             "rayleigh_stiff_share": rng.uniform(0.3, 0.8)}, "mass_ratio", 8.0)


def _drift_draw(rng, case: str, form: str, duration: float) -> dict:
    """A sensor's offset drift of 1-5 % of the channel's span, or a gain drift of 3-8 % (either sign; a
    two-stage warm-up with a fast time constant of 0.05-0.2 records and 30-70 % share, a walk low-passed at
    1-3 cycles per record, or a square-root creep); on one channel or both (the displacement sensor's drift
    0.3-1.5 times the magnetization sensor's, either sign)."""
    if case == "sensor_offset_drift":
        return {"amplitude": rng.uniform(0.01, 0.05) * rng.choice([-1.0, 1.0]),
                "tau": rng.uniform(0.1, 0.8) * duration, "cutoff_cycles": rng.uniform(1.0, 4.0),
                "channel": _choice(rng, ("magnetization", "displacement", "both")),
                "walk_seed": int(rng.integers(2 ** 31))}
    return {"amplitude": rng.uniform(0.03, 0.08) * rng.choice([-1.0, 1.0]), "tau": rng.uniform(0.05, 0.2) * duration,
            "share": rng.uniform(0.3, 0.7), "cutoff_cycles": rng.uniform(1.0, 3.0),
            "channel": _choice(rng, ("magnetization", "displacement", "both")),
            "walk_seed": int(rng.integers(2 ** 31)),
            # two sensors (a pick-up coil, a displacement probe) do not share their gain's drift: the
            # displacement sensor's is this multiple of the magnetization sensor's
            "displacement_ratio": rng.uniform(0.3, 1.5) * rng.choice([-1.0, 1.0])}


def _input_dynamics_draw(rng, form: str, sample_rate: float) -> dict:
    """Times (s) of the input filter: a second-order low-pass at 1/(2*pi*(2-6 samples)) with damping 0.4-1,
    a lag of 2-6 samples after a delay of 0.5-2, or a delay of 1-4 samples; ``scale`` multiplies them."""
    dt = 1.0 / sample_rate
    if form == "second_order":
        return {"tau": rng.uniform(2.0, 6.0) * dt, "damping": rng.uniform(0.4, 1.0), "delay": 0.0, "scale": 1.0}
    if form == "first_order_delay":
        return {"tau": rng.uniform(2.0, 6.0) * dt, "delay": rng.uniform(0.5, 2.0) * dt, "scale": 1.0}
    return {"tau": 0.0, "delay": rng.uniform(1.0, 4.0) * dt, "scale": 1.0}


def input_filter(time, field, form: str, p: dict) -> np.ndarray:
    """The field (A/m) in the rod for the recorded ``field`` (uniform ``time``): delayed (linear
    interpolation, the first sample held), then low-passed (first or second order, scipy's exact
    discretization of the refined input); the recorded field at ``scale`` 0."""
    tau, delay = p["tau"] * p["scale"], p["delay"] * p["scale"]
    dt = float(time[1] - time[0])
    steps = np.arange(field.size, dtype=float)
    out = np.interp(steps - delay / dt, steps, field) if delay > 0.0 else field
    if tau <= 0.0:
        return out
    if form == "second_order":
        return ir.lti_response([1.0], [tau ** 2, 2.0 * p["damping"] * tau, 1.0], out, dt)
    return ir.lti_response([1.0], [tau, 1.0], out, dt)


def second_material(mat: ir.Material, p: dict) -> ir.Material:
    """The second phase: a, k, c, Ms scaled; k raised until numerically safe."""
    a2, Ms2 = mat.a * p["a_ratio"], mat.Ms * p["Ms_ratio"]
    second = ir.Material(a=a2, k=mat.k * p["k_ratio"], alpha=mat.rho * a2 / Ms2, Ms=Ms2,
                         c=float(min(max(mat.c * p["c_ratio"], 0.02), 0.9)))
    while second.problems():
        second = replace(second, k=second.k * 1.5)
    return second


# ---------------------------------------------------------------------------- forward model

def _lumped(st: Setup, M, stiffness_factor=None):
    mech, num = st.base.mechanics, st.numerics
    dt = float(st.time[1] - st.time[0])
    return newmark(mech.zetahat * M, dt, mech.khat, mech.chat, 1.0, 1.0, stiffness_factor=stiffness_factor,
                   substeps=num["substeps"], hold=num["hold"])


def _even_law_drive(st: Setup, M):
    """The magnetization-like drive of the lumped mechanics under the even law: (1 - blend)*M + blend*lambda(M)
    with lambda scaled to the span of M over the record (blend 0: the linearized law (13))."""
    p = st.params
    law = magnetostriction(M, st.base.material.Ms, st.form, p["width"], p["power"])
    law = law * (float(np.ptp(M)) / (float(np.ptp(law)) or 1.0))
    return (1.0 - p["blend"]) * M + p["blend"] * law


def _rod(st: Setup, M):
    """Tip displacement of the continuum rod; static gain zetahat/khat, first mode at sqrt(khat)."""
    mech, p = st.base.mechanics, st.params
    roots, compliance = rod_modes(p["mass_ratio"])
    w1 = math.sqrt(mech.khat)
    omega = w1 * roots / roots[0]
    if st.form == "modal_rayleigh_damping":
        # zeta_n = alpha/(2 w_n) + beta w_n/2 with zeta_1 given, a share of it from the stiffness term
        b = 2 * p["zeta1"] * p["rayleigh_stiff_share"] / w1
        a = 2 * p["zeta1"] * (1 - p["rayleigh_stiff_share"]) * w1
        zeta = np.minimum(a / (2 * omega) + b * omega / 2, 0.5)
    else:
        zeta = np.full(omega.size, p["zeta1"])
    # static tip response sum(compliance) normalized to zetahat/khat
    gain = omega ** 2 * compliance / compliance.sum() * mech.zetahat / mech.khat
    dt = float(st.time[1] - st.time[0])
    return newmark(M, dt, omega ** 2, 2 * zeta * omega, gain, np.ones(omega.size),
                   substeps=st.numerics["substeps"], hold=st.numerics["hold"])


def _stiffness(st: Setup, M):
    p, Ms = st.params, st.base.material.Ms
    Mb = p["Mb_fraction"] * Ms
    if st.form == "sech_dip":
        g = -1.0 / np.cosh((M - Mb) / (p["width"] * Ms)) ** 2
    else:
        g = np.abs((M - Mb) / Ms) ** p["power"]
    g_ref = float(np.interp(np.median(M), np.sort(M), g[np.argsort(M)]))
    return (1.0 + p["beta"] * g) / (1.0 + p["beta"] * g_ref)


def forward(st: Setup) -> dict:
    """Noise-free recorded channels {"magnetization", "displacement"} (A/m, m) on the sample grid."""
    case, p, mat, num = st.case, st.params, st.base.material, st.numerics
    field = st.field
    if case == "saturating_amplifier":
        field = amplifier(field, st.form, p["overdrive"], p["asymmetry"])
    if case == "input_dynamics":
        field = input_filter(st.time, field, st.form, p)
    if case == "heating_other_law":
        theta = thermal_rise(st.time, field, p, p["rise"])
        a_scale, ms_scale = material_scales(theta, p)
        M = magnetization(st.time, field, mat, a_scale=a_scale, ms_scale=ms_scale, method=num["method"])
    else:
        M = magnetization(st.time, field, mat, method=num["method"])
    M_drive = M
    if case == "two_phase_rod":
        M2 = magnetization(st.time, field, second_material(mat, p), method=num["method"])
        mixed = (1 - p["w"]) * M + p["w"] * M2
        M_drive = M if st.form == "split_roles" else mixed
        M = mixed
    if case == "delta_e_shifted":
        x = _lumped(st, M_drive, _stiffness(st, M_drive))
    elif case == "continuum_rod":
        x = _rod(st, M_drive)
    elif case == "magnetostriction_law":
        x = _lumped(st, _even_law_drive(st, M_drive))
    else:
        x = _lumped(st, M_drive)
    out = {"magnetization": M, "displacement": x}
    if case == "sensor_nonlinearity":
        out["displacement"] = sensor_map(x, st.form, p["gain"], p["offset"])
    elif case in ("sensor_offset_drift", "mains_pickup"):
        for ch in _acted_channels(st, BOTH):
            span = float(np.ptp(out[ch]))
            if case == "mains_pickup":
                out[ch] = out[ch] + mains(st.time, p["frequency"], p["amplitude"] * span, (p["r3"], p["r5"]),
                                          p["phases"])
            else:
                out[ch] = out[ch] + drift(st.time, st.form, p["amplitude"] * span, p["tau"], _walk(st, ch))
    elif case == "sensor_gain_drift":
        for ch in _acted_channels(st, BOTH):
            amplitude = p["amplitude"] * (p["displacement_ratio"] if ch == "displacement" else 1.0)
            out[ch] = out[ch] * (1.0 + gain_drift(st.time, st.form, amplitude, p["tau"], _walk(st, ch), p["share"]))
    return out


def _walk(st: Setup, channel: str) -> np.ndarray | None:
    """Unit-RMS random walk from 0, low-passed at ``cutoff_cycles`` per record."""
    if st.form != "random_walk":
        return None
    rng = ir._stream(st.params["walk_seed"], "walk", channel)
    walk = np.cumsum(rng.standard_normal(st.time.size))
    fs = st.base.conditions.sample_rate
    sos = signal.butter(2, st.params["cutoff_cycles"] / st.base.conditions.duration, fs=fs, output="sos")
    walk = signal.sosfiltfilt(sos, walk)
    walk = walk - walk[0]
    return walk / (float(np.sqrt(np.mean(walk ** 2))) or 1.0)


def _acted_channels(st: Setup, wanted) -> tuple:
    """The recorded channels the effect acts on."""
    case = st.case
    if case in ("delta_e_shifted", "sensor_nonlinearity", "continuum_rod", "magnetostriction_law"):
        acted = ("displacement",)
    elif case in ("sensor_offset_drift", "sensor_gain_drift", "mains_pickup"):
        ch = st.params["channel"]
        acted = BOTH if ch == "both" else (ch,)
    elif case == "two_phase_rod" and st.form == "split_roles":
        acted = ("magnetization",)  # the displacement follows phase 1 alone: the channels disagree
    else:
        acted = BOTH
    return tuple(c for c in acted if c in wanted)


def zero_size(st: Setup) -> Setup:
    """The same case without its effect (knob 0; the rod: the lumped model of its first mode)."""
    if st.case == "continuum_rod":
        return replace(st, case="none_other_numerics")
    if st.knob is None:
        return st
    return replace(st, params=dict(st.params, **{st.knob: 0.0}))


#: Mean-removed RMS change in noise standard deviations (noise_rel * ptp), per channel.
visibility = ir._visibility


# ---------------------------------------------------------------------------- public API

#: A noise-free recording: time, field, clean channels, truth and the zero-size reference.
Simulation = ir.Simulation


def _check(case, seed, channels, n_samples):
    if case not in CASES:
        raise ValueError(f"case must be one of {', '.join(ALL_CASES)}, got {case!r}")
    ir._check_arguments("none", seed, channels, n_samples)  # seed, channel set and length as there
    if channels not in CASES[case].channel_sets:
        raise ValueError(f"case {case} cannot show with channels {channels}; use one of "
                         f"{', '.join(CASES[case].channel_sets)}")


def simulate(case: str, seed: int, channels: str = "both", *, n_samples: int | None = None,
             size: float | None = None) -> Simulation:
    """The noise-free recording of (case, seed, channels) and its zero-size reference.

    ``size``: a factor on the drawn effect size, no visibility boost (0: no effect); default:
    the drawn size, enlarged until every channel the effect acts on shows by MIN_VISIBILITY."""
    _check(case, seed, channels, n_samples)
    wanted = BOTH if channels == "both" else (channels,)
    st = drawn = setup(case, seed, n_samples)
    if st.form == "split_roles" and channels != "both":  # shows only as a disagreement of two channels
        st = drawn = replace(st, form="mixture")
    if "channel" in st.params and channels != "both":  # an additive sensor term on the one recorded channel
        st = drawn = replace(st, params=dict(st.params, channel=channels))
    noise_rel = st.base.conditions.noise_rel
    reference = forward(zero_size(st))
    judged = _acted_channels(st, wanted) if case != "none_other_numerics" else ()
    boosts, vis = 0, {}
    if size is not None:
        st = st.sized(size) if st.knob else st
        outputs = forward(st) if size or st.knob is None else reference
        vis = visibility({c: outputs[c] for c in judged}, reference, noise_rel)
    elif case == "none_other_numerics":
        outputs = reference
    else:
        for boosts in range(MAX_BOOSTS + 1):
            outputs = forward(st)
            vis = visibility({c: outputs[c] for c in judged}, reference, noise_rel)
            weakest = min(vis.values()) if vis else 0.0
            if weakest >= MIN_VISIBILITY or st.saturated or boosts == MAX_BOOSTS:
                break
            st = st.sized(min(max(1.5 * MIN_VISIBILITY / max(weakest, 1e-3), 1.2), 10.0))
    spec = CASES[case]
    truth = dict(
        case=case, form=st.form, description=spec.description, expected_verdicts=sorted(spec.expected),
        effect_parameters=st.params, drawn_effect_parameters=drawn.params, size_knob=st.knob,
        size_boost=(st.params[st.knob] / drawn.params[drawn.knob]) if st.knob and drawn.params[drawn.knob] else 1.0,
        boosts=boosts, visibility=vis, acts_on=list(judged),
        visible=case == "none_other_numerics" or bool(vis) and min(vis.values()) >= MIN_VISIBILITY,
        numerics=st.numerics, seed=int(seed), channels=channels,
        sample_rate=st.base.conditions.sample_rate, n_samples=int(st.time.size), noise_rel=noise_rel,
        excitation_family=st.excitation.get("family"), excitation_details=st.excitation,
        material=st.base.material.as_dict(), mechanics=st.base.mechanics.as_dict(),
        generator="experiments.other_forms")
    if case == "none_other_numerics":
        truth["difference_from_independent_recordings"] = numerics_difference(st, outputs, wanted)
    if case == "continuum_rod":
        roots = rod_frequency_roots(st.params["mass_ratio"], ROD_MODES)
        f1 = math.sqrt(st.base.mechanics.khat) / (2 * math.pi)
        truth["mode_frequencies_hz"] = (f1 * roots / roots[0]).tolist()
    if case == "two_phase_rod":
        truth["second_material"] = second_material(st.base.material, st.params).as_dict()
    return Simulation(time=st.time, field=st.field, clean={c: outputs[c] for c in wanted},
                      reference={c: reference[c] for c in wanted}, truth=ir._jsonable(truth))


def numerics_difference(st: Setup, outputs: dict, wanted) -> dict:
    """RMS difference (noise standard deviations) of these numerics' ``none`` recording from
    :mod:`experiments.independent_recordings`' for the same draws (spline field, Dormand-Prince
    in time, exact first-order-hold mechanics): how far two correct simulators differ."""
    theirs = ir.simulate("none", st.seed, "both", n_samples=st.time.size)
    return {ch: float(np.sqrt(np.mean((outputs[ch] - theirs.clean[ch]) ** 2))
                      / (st.base.conditions.noise_rel * float(np.ptp(outputs[ch])))) for ch in wanted}


def generate(case: str, seed: int, channels: str = "both", *, n_samples: int | None = None):
    """A synthetic recording of ``case``: (Recording, truth dict); deterministic."""
    from hyst_gym.diagnose.recording import Recording

    sim = simulate(case, seed, channels, n_samples=n_samples)
    rng = ir._stream(seed, "other_forms", "noise", case, channels)
    noisy, sigmas = {}, {}
    for ch in BOTH:
        if ch in sim.clean:
            y = sim.clean[ch]
            sigmas[ch] = sim.truth["noise_rel"] * float(np.ptp(y))
            noisy[ch] = y + sigmas[ch] * rng.standard_normal(y.size)
    recording = Recording(time=sim.time, field=sim.field, metadata=sidecar(seed),
                          source=f"synthetic recording (other forms), seed {seed}", **noisy)
    return recording, dict(sim.truth, noise_std=sigmas)


def sidecar(seed: int) -> dict:
    """Sidecar metadata: nothing in it names or hints at the effect."""
    return {"material": "Terfenol-D (synthetic)", "notes": f"synthetic recording, seed {seed}"}


def write(case: str, seed: int, channels: str, out: Path, *, n_samples=None, truth_path: Path | None = None):
    """Write the CSV (+ sidecar) and optionally the truth JSON; returns (recording, truth)."""
    from hyst_gym.diagnose.recording import write_recording

    recording, truth = generate(case, seed, channels, n_samples=n_samples)
    write_recording(out, recording, recording.metadata)
    if truth_path is not None:
        truth_path.parent.mkdir(parents=True, exist_ok=True)
        truth_path.write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")
    return recording, truth


# ---------------------------------------------------------------------------- command line

def _csv_path(text: str) -> Path:
    path = Path(text)
    if path.suffix.lower() != ".csv":
        raise argparse.ArgumentTypeError(f"must name a .csv file, got {text!r}")
    return path


def main(argv=None) -> int:
    """Command line: write one recording (CSV + sidecar) and optionally its truth."""
    parser = argparse.ArgumentParser(prog="python -m experiments.other_forms", description=__doc__.splitlines()[0])
    options = {"--case": dict(required=True, choices=ALL_CASES),
               "--seed": dict(required=True, type=ir._seed, help="integer >= 0"),
               "--channels": dict(default="both", choices=CHANNEL_SETS),
               "--samples": dict(type=ir._samples, default=None, help=f"record length (default {DEFAULT_SAMPLES})"),
               "--out": dict(required=True, type=_csv_path, help="recording CSV; its sidecar .json goes beside it"),
               "--truth": dict(type=Path, default=None, help="where to write the truth as JSON")}
    for flag, kwargs in options.items():
        parser.add_argument(flag, **kwargs)
    args = parser.parse_args(argv)
    own = {args.out.resolve(), args.out.with_suffix(".json").resolve()}
    if args.truth is not None and args.truth.resolve() in own:
        parser.error("--truth must not be the CSV or its sidecar")
    try:
        recording, _ = write(args.case, args.seed, args.channels, args.out, n_samples=args.samples,
                             truth_path=args.truth)
    except (ValueError, OSError) as error:
        parser.error(str(error) if isinstance(error, ValueError)
                     else f"cannot write {error.filename}: {error.strerror}")
    print(f"wrote {args.out} ({recording.size} samples; columns time, field, {', '.join(recording.channels)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
