"""Synthetic recordings whose physics takes OTHER FORMS than the mismatch tool's equations.

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
``sensor_resonance``     a sensor (or its amplifier) with a second-order resonance at 1-3    {sensor_lag}
                         kHz, damping ratio 0.05-0.4, on one channel or both (not a lag)
``pinning_temperature``  coil heating (two-time-constant network) that makes the pinning    {thermal_drift}
                         k collapse toward a near Curie point (power law or exponential),
                         Ms(T) Bloch-like with the same Tc
``other_anhysteretic``   a Brillouin curve (J 2-20), a mixture of two Langevin curves or a   {anhysteretic_shape}
                         sharper knee x/(1+|x|^p)^(1/p), blended with the material's curve
                         at the same slope at 0
``rod_on_mount``         the rod standing on a compliant mass-spring-damper mount (two      {rod_dynamics}
                         modes, the same static gain); the sensor referenced to the ground
                         or to the mount
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
from scipy import linalg, signal
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
    CaseSpec("sensor_resonance", frozenset({"sensor_lag"}), CHANNEL_SETS, ("resonant_sensor",),
             "a sensor (or its amplifier) with a second-order resonance at 1-3 kHz"),
    CaseSpec("pinning_temperature", frozenset({"thermal_drift"}), CHANNEL_SETS, ("power_law_k", "exponential_k"),
             "coil heating that moves the pinning k (collapsing toward Tc) and Ms (Bloch law, same Tc)"),
    CaseSpec("other_anhysteretic", frozenset({"anhysteretic_shape"}), CHANNEL_SETS,
             ("brillouin", "two_langevin", "sharp_knee"), "an anhysteretic curve of another shape, same slope at 0"),
    CaseSpec("rod_on_mount", frozenset({"rod_dynamics"}), ("displacement", "both"),
             ("ground_referenced", "mount_referenced"), "the rod on a compliant mount (a mass-spring-damper base)"),
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


def brillouin(x: float, j: float) -> tuple[float, float]:
    """Brillouin function B_J(x) and its slope: B_J = p coth(p x) - q coth(q x), p = (2J+1)/(2J),
    q = 1/(2J); written as p L(p x) - q L(q x) with L(u) = coth(u) - 1/u (the 1/x terms cancel),
    which stays accurate near 0 and far out. J = 1/2 is tanh, J -> infinity the Langevin function."""
    p, q = (2.0 * j + 1.0) / (2.0 * j), 1.0 / (2.0 * j)
    lp, lp_slope = ir.anhysteretic(p * x, "langevin")
    lq, lq_slope = ir.anhysteretic(q * x, "langevin")
    # far out both slopes are 1/x^2 (to rounding) and cancel: the true slope, ~exp(-x/J), is >= 0
    return p * lp - q * lq, max(p * p * lp_slope - q * q * lq_slope, 0.0)


@dataclass(frozen=True)
class AnhystereticCurve:
    """Man/Ms as a function of x = He/a, another shape than the material's ``base`` curve ("ising":
    tanh, slope 1 at 0; "langevin": slope 1/3), blended with it: (1 - blend)*base + blend*other.
    The other shape is rescaled in x to the base's slope at 0, so the blend keeps the initial
    susceptibility, rho and the safety margins of the draw (each shape is steepest at 0):

    brillouin   B_J(x) with J = ``shape`` (2-20): between tanh (J = 1/2) and Langevin;
    two_langevin  ``shape``-weighted mixture of two Langevin curves, widths 1 and ``width_ratio``;
    sharp_knee  x/(1 + |x|^p)^(1/p), p = ``shape`` (3-6): linear, then a sharper knee than tanh.
    """

    base: str
    form: str
    blend: float
    shape: float
    width_ratio: float = 1.0

    def other(self, x: float) -> tuple[float, float]:
        """(Man/Ms, slope in x) of the other shape, rescaled to the base's slope at 0."""
        s0 = 1.0 if self.base == "ising" else 1.0 / 3.0
        if self.form == "brillouin":
            g = s0 * 3.0 * self.shape / (self.shape + 1.0)  # B_J'(0) = (J+1)/(3J)
            value, slope = brillouin(g * x, self.shape)
        elif self.form == "two_langevin":
            w, r = self.shape, self.width_ratio
            g = s0 * 3.0 / (w + (1.0 - w) / r)  # L'(0) = 1/3
            v1, d1 = ir.anhysteretic(g * x, "langevin")
            v2, d2 = ir.anhysteretic(g * x / r, "langevin")
            value, slope = w * v1 + (1.0 - w) * v2, w * d1 + (1.0 - w) * d2 / r
        elif self.form == "sharp_knee":
            u = abs(s0 * x) ** self.shape
            g, value = s0, s0 * x * (1.0 + u) ** (-1.0 / self.shape)
            slope = (1.0 + u) ** (-1.0 - 1.0 / self.shape)
            return value, g * slope
        else:
            raise ValueError(f"unknown anhysteretic form {self.form!r}")
        return value, g * slope

    def __call__(self, x: float) -> tuple[float, float]:
        base_value, base_slope = ir.anhysteretic(x, self.base)
        value, slope = self.other(x)
        b = self.blend
        return (1.0 - b) * base_value + b * value, (1.0 - b) * base_slope + b * slope

    def slope(self, H: float, M: float, delta: float, a: float, k: float, alpha: float, Ms: float, c: float,
              curve: str = "", chi_rev: float = 0.0) -> float:
        """dM/dH of eq. (6) with this anhysteretic curve (``curve`` is ignored; ``chi_rev`` must be 0):
        the reversible part c*Man' and the irreversible part (Man - M)/(delta*k - alphahat*(Man - M)),
        the latter only while M lags Man in the direction of travel, all over 1 - alpha*c*Man'."""
        if chi_rev:
            raise ValueError("AnhystereticCurve.slope has no reversible bowing (chi_rev must be 0)")
        value, shape_slope = self(x=(H + alpha * M) / a)
        lag = Ms * value - M
        reversible = c * Ms * shape_slope / a
        wall = (1.0 - c) * k * delta - alpha * lag  # (1 - c) times the pinning denominator
        pinned = (1.0 - c) * lag / wall if lag * delta > 0.0 and wall * delta > 0.0 else 0.0
        return (pinned + reversible) / (1.0 - alpha * reversible)


def _initial_magnetization(H0: float, mat: ir.Material, slope) -> float:
    """M (A/m) on the initial curve from the demagnetized state (M = 0 at H = 0) to ``H0``, for ``slope``."""
    if H0 == 0.0:
        return 0.0
    delta = 1.0 if H0 > 0 else -1.0
    sol = solve_ivp(lambda h, y: [slope(h, y[0], delta, mat.a, mat.k, mat.alpha, mat.Ms, mat.c)], (0.0, H0), [0.0],
                    method="LSODA", rtol=RTOL, atol=ATOL * mat.Ms, max_step=min(abs(H0), mat.k, mat.a) / 20)
    return float(sol.y[0, -1])


def magnetization(time, field, material: ir.Material, *, a_scale=None, ms_scale=None, k_scale=None,
                  curve: AnhystereticCurve | None = None, method: str = "LSODA") -> np.ndarray:
    """M (A/m) at the samples of ``field`` (A/m), linearly interpolated between them: eq. (6)
    integrated in the field, one ``solve_ivp`` per monotone run, from the initial curve at
    ``field[0]``. ``a_scale``/``ms_scale``/``k_scale`` (arrays on ``time``): a(t)/a, Ms(t)/Ms and
    k(t)/k, read at the time of the run's linear interpolant where the field passes H;
    ``curve``: another anhysteretic curve than the material's (its own slope function)."""
    field = np.asarray(field, dtype=float)
    mat = material
    out = np.empty(field.size)
    slope = ir.hysteresis_slope if curve is None else curve.slope
    out[0] = ir.initial_magnetization(float(field[0]), mat) if curve is None else \
        _initial_magnetization(float(field[0]), mat, slope)
    index = np.arange(field.size, dtype=float)
    if a_scale is not None or k_scale is not None:
        ones = np.ones(field.size)
        a_scale = ones if a_scale is None else a_scale
        ms_scale = ones if ms_scale is None else ms_scale
    # the pinning sets the field scale of the loop's bends: the step follows its smallest value
    least_k = mat.k * (1.0 if k_scale is None else float(np.min(k_scale)))
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
                k = mat.k if k_scale is None else mat.k * float(np.interp(s, index, k_scale))
                return [slope(h, y[0], delta, a, k, mat.alpha, Ms, mat.c, mat.curve, mat.chi_rev)]

        # evaluation points: the run's distinct field values (a flat stretch shares one)
        values, inverse = np.unique(H, return_inverse=True)
        t_eval = values if delta > 0 else values[::-1]
        sol = solve_ivp(rhs, (float(H[0]), float(H[-1])), [out[first]], method=method, t_eval=t_eval,
                        rtol=RTOL, atol=ATOL * mat.Ms, max_step=max(min(least_k, mat.a) / 4, 1e-9))
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

def amplifier(field, form: str, overdrive: float, asymmetry: float = 1.0, peak: float | None = None) -> np.ndarray:
    """The saturating amplifier's true field for the recorded ``field``: unit small-signal gain,
    Hs = ``peak``/overdrive, ``peak`` (A/m) the first record's max|field| (default this field's;
    overdrive 0: the identity)."""
    field = np.asarray(field, dtype=float)
    if overdrive == 0.0:
        return field.copy()
    hs = (float(np.max(np.abs(field))) if peak is None else peak) / overdrive
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


def sensor_map(y, form: str, gain: float, offset: float, frame=None) -> np.ndarray:
    """A non-polynomial static sensor map about c = mid-range + offset*s (s the half range of ``frame``,
    default y): ``c + s*f(gain*v)/gain``, v = (y - c)/s, unit slope at c (gain 0: the identity)."""
    y = np.asarray(y, dtype=float)
    if gain == 0.0:
        return y.copy()
    ranged = y if frame is None else np.asarray(frame, dtype=float)
    half = 0.5 * float(np.ptp(ranged)) or 1.0
    centre = 0.5 * (float(np.max(ranged)) + float(np.min(ranged))) + offset * half
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


def thermal_rise(time, field, law: dict, rise: float, frame_field=None) -> np.ndarray:
    """Rod temperature rise (K) through a two-time-constant network driven by ``|H|`` or ``H^2``
    (``law["drive"]``), exact for a drive linear between samples; scaled so that the record's
    mean drive would heat the rod by ``rise`` K in the steady state (the mean of ``frame_field``'s drive,
    default this field's: the first record's fixes the coil's heating gain in a replay).

    series: tau1*th1' = P - th1 (coil), tau2*th2' = th1 - th2 (rod sees th2);
    parallel: th = w*th_fast + (1-w)*th_slow, each tau_i*th_i' = P - th_i."""
    def power(h):
        h = np.asarray(h, dtype=float)
        return np.abs(h) if law["drive"] == "abs" else h ** 2

    drive = power(field)
    drive = rise * drive / (float(np.mean(drive if frame_field is None else power(frame_field))) or 1.0)
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


def resonant_sensor(time, values, frequency: float, damping: float) -> np.ndarray:
    """A sensor (or its amplifier) with a second-order resonance: y'' + 2*damping*w0*y' + w0^2*y = w0^2*u,
    w0 = 2*pi*``frequency`` (Hz): unit static gain, a resonant peak 1/(2*damping*sqrt(1 - damping^2)) at
    w0*sqrt(1 - 2*damping^2) when damping < 1/sqrt(2); started settled. Numerics as the mechanics': the
    input is held ``linear`` on 16 Newmark substeps per sample."""
    dt = float(time[1] - time[0])
    w0 = 2.0 * math.pi * frequency
    return newmark(np.asarray(values, dtype=float), dt, w0 * w0, 2.0 * damping * w0, w0 * w0, 1.0, substeps=16)


def mount_transfer(mech: ir.Mechanics, p: dict, form: str) -> tuple[np.ndarray, np.ndarray]:
    """(numerator, denominator) of the displacement over zetahat*M, s-polynomials, for the rod (stiffness
    khat, damping chat per unit tip mass) standing on a compliant mount of mass ``mass_ratio`` tip masses,
    stiffness ``compliance``^-1 * khat and damping ratio ``mount_damping``; the magnetostrictive force acts
    between the mount and the tip, so the static response is the lumped one, 1/khat.

    tip:   x_t'' = -khat*(x_t - x_b) - chat*(x_t' - x_b') + zetahat*M
    mount: mu*x_b'' = khat*(x_t - x_b) + chat*(x_t' - x_b') - zetahat*M - km*x_b - cm*x_b'
    With A = s^2 + chat*s + khat, B = chat*s + khat, D = mu*s^2 + (chat + cm)*s + khat + km and
    Delta = A*D - B^2: x_t/(zetahat*M) = (D - B)/Delta (``ground_referenced``, a sensor fixed to the
    ground), (x_t - x_b)/(zetahat*M) = (A + D - 2B)/Delta (``mount_referenced``, a sensor on the mount)."""
    mu = p["mass_ratio"]
    km = mech.khat / p["compliance"]
    cm = 2.0 * p["mount_damping"] * math.sqrt(km * mu)
    A = np.array([1.0, mech.chat, mech.khat])
    B = np.array([0.0, mech.chat, mech.khat])
    D = np.array([mu, mech.chat + cm, mech.khat + km])
    den = np.polysub(np.polymul(A, D), np.polymul(B, B))
    num = D - B if form == "ground_referenced" else A + D - 2.0 * B
    return np.trim_zeros(num, "f"), np.trim_zeros(den, "f")


def mount_modes(mech: ir.Mechanics, p: dict) -> np.ndarray:
    """Undamped natural frequencies (Hz) of the rod on its mount, ascending."""
    mu, km = p["mass_ratio"], mech.khat / p["compliance"]
    stiffness = np.array([[mech.khat, -mech.khat], [-mech.khat, mech.khat + km]])
    w2 = linalg.eigh(stiffness, np.diag([1.0, mu]), eigvals_only=True)
    return np.sqrt(w2) / (2.0 * math.pi)


def pinning_scales(theta, p: dict, form: str, mat: ir.Material) -> tuple[np.ndarray, np.ndarray, dict]:
    """(k(T)/k, Ms(T)/Ms, notes) at the temperature rise ``theta`` (K) above T_amb, for a ferromagnet whose
    Curie point ``curie`` (K) is near: Ms(T) ~ (1 - (T/Tc)^1.5) (Bloch), the pinning collapsing toward Tc,
    k ~ ((Tc - T)/(Tc - T_amb))^``k_power`` (``power_law_k``) or exp(-(T - T_amb)/``k_temperature``)
    (``exponential_k``). The pinning is floored where eq. (6)'s irreversible denominator would approach
    0 (alpha > 0); ``notes`` says whether that floor was reached."""
    T0, tc = ir.T_AMBIENT, p["curie"]
    T = np.minimum(T0 + theta, tc - 5.0)
    ms_scale = np.maximum((1.0 - (T / tc) ** 1.5) / (1.0 - (T0 / tc) ** 1.5), 0.05)
    if form == "power_law_k":
        k_scale = ((tc - T) / (tc - T0)) ** p["k_power"]
    else:
        k_scale = np.exp(-(T - T0) / p["k_temperature"])
    # (1 - c)*k - 2*alpha*Ms(T) > 0.2*(1 - c)*k keeps the pinning term's denominator away from 0
    floor = 0.05 if mat.alpha <= 0 else 2.5 * mat.alpha * mat.Ms * ms_scale / ((1.0 - mat.c) * mat.k)
    floored = bool(np.any(k_scale < floor))
    notes = {"temperature_capped": bool(np.any(T0 + theta > tc - 5.0)), "k_floored": floored,
             "k_scale_min": float(np.min(np.maximum(k_scale, floor))), "ms_scale_min": float(np.min(ms_scale))}
    return np.maximum(k_scale, floor), ms_scale, notes


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
    #: A replay's frame (:func:`replay`): the first record's "field", "M" (the mechanics' drive) and "true"
    #: outputs, which fix the static maps' frames, the heating gain and the stiffness reference (None: its own).
    frame: dict | None = None

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
    elif case in _DRAWS:
        p, knob, knob_max = _DRAWS[case](rng, form, duration)
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


def _sensor_resonance_draw(rng, form: str, duration: float) -> tuple[dict, str, float]:
    """A resonance at 1-3 kHz with damping ratio 0.05-0.4 on each sensor (drawn apart), on one channel or
    both; ``scale`` (default 1, up to 4) divides the resonant frequencies (a slower sensor)."""
    return ({"frequency_magnetization": rng.uniform(1e3, 3e3), "frequency_displacement": rng.uniform(1e3, 3e3),
             "damping_magnetization": rng.uniform(0.05, 0.4), "damping_displacement": rng.uniform(0.05, 0.4),
             "channel": _choice(rng, ("magnetization", "displacement", "both")), "scale": 1.0}, "scale", 4.0)


def _pinning_temperature_draw(rng, form: str, duration: float) -> tuple[dict, str, float]:
    """Heating as in ``heating_other_law`` (a two-time-constant network, |H| or H^2), a Curie point
    60-200 K above T_amb, the pinning's exponent 1-3 or its temperature scale 15-60 K; ``rise`` (K,
    15-40, up to 120) sets the size."""
    network = _choice(rng, ("series", "parallel"))
    return ({"rise": rng.uniform(15.0, 40.0), "drive": _choice(rng, ("abs", "square")), "network": network,
             "tau1": rng.uniform(0.05, 0.3) * duration, "tau2": rng.uniform(0.5, 3.0) * duration,
             "fast_share": rng.uniform(0.3, 0.7), "curie": ir.T_AMBIENT + rng.uniform(60.0, 200.0),
             "k_power": rng.uniform(1.0, 3.0), "k_temperature": rng.uniform(15.0, 60.0)}, "rise", 120.0)


def _other_anhysteretic_draw(rng, form: str, duration: float) -> tuple[dict, str, float]:
    """The other curve's shape (Brillouin J 2-20 log-uniform, a Langevin mixture with share 0.3-0.7 and width ratio
    3-8, or a knee exponent 3-6) and its ``blend`` with the material's curve (0.4-0.8, up to 1)."""
    shape = {"brillouin": ir._log_uniform(rng, 2.0, 20.0), "two_langevin": rng.uniform(0.3, 0.7),
             "sharp_knee": rng.uniform(3.0, 6.0)}[form]
    return {"blend": rng.uniform(0.4, 0.8), "shape": shape, "width_ratio": rng.uniform(3.0, 8.0)}, "blend", 1.0


def _rod_on_mount_draw(rng, form: str, duration: float) -> tuple[dict, str, float]:
    """A mount of 0.5-5 tip masses whose compliance is 0.3-3 times the rod's (``compliance``, up to 10)
    with damping ratio 0.02-0.15."""
    return ({"mass_ratio": rng.uniform(0.5, 5.0), "compliance": ir._log_uniform(rng, 0.3, 3.0),
             "mount_damping": rng.uniform(0.02, 0.15)}, "compliance", 10.0)


#: Draws (rng, form, duration) -> (parameters, size knob, its cap) of the cases drawn by a helper.
_DRAWS = {"magnetostriction_law": lambda rng, form, duration: _mechanics_draw(rng, "magnetostriction_law"),
          "continuum_rod": lambda rng, form, duration: _mechanics_draw(rng, "continuum_rod"),
          "sensor_resonance": _sensor_resonance_draw, "pinning_temperature": _pinning_temperature_draw,
          "other_anhysteretic": _other_anhysteretic_draw, "rod_on_mount": _rod_on_mount_draw}


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
    if st.frame is None:
        law = law * (float(np.ptp(M)) / (float(np.ptp(law)) or 1.0))
    else:
        framed = magnetostriction(st.frame["M"], st.base.material.Ms, st.form, p["width"], p["power"])
        law = law * (float(np.ptp(st.frame["M"])) / (float(np.ptp(framed)) or 1.0))
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

    def law(m):
        if st.form == "sech_dip":
            return -1.0 / np.cosh((m - Mb) / (p["width"] * Ms)) ** 2
        return np.abs((m - Mb) / Ms) ** p["power"]

    g = law(M)
    ref = M if st.frame is None else np.asarray(st.frame["M"])  # the reference stiffness: the first record's
    g_ref = float(np.interp(np.median(ref), np.sort(ref), law(ref)[np.argsort(ref)]))
    return (1.0 + p["beta"] * g) / (1.0 + p["beta"] * g_ref)


def _frame(st: Setup, *keys):
    """The replay frame's entry at ``keys`` (None when ``st`` is a first record)."""
    value = st.frame
    for key in keys:
        value = None if value is None else value[key]
    return value


def _material_response(st: Setup, field) -> np.ndarray:
    """M (A/m) of the case's material (its heating, its pinning's temperature, its anhysteretic curve)."""
    case, p, mat, method = st.case, st.params, st.base.material, st.numerics["method"]
    if case == "heating_other_law":
        theta = thermal_rise(st.time, field, p, p["rise"], _frame(st, "field"))
        a_scale, ms_scale = material_scales(theta, p)
        return magnetization(st.time, field, mat, a_scale=a_scale, ms_scale=ms_scale, method=method)
    if case == "pinning_temperature" and p["rise"] > 0.0:
        theta = thermal_rise(st.time, field, p, p["rise"], _frame(st, "field"))
        k_scale, ms_scale, _ = pinning_scales(theta, p, st.form, mat)
        return magnetization(st.time, field, mat, ms_scale=ms_scale, k_scale=k_scale, method=method)
    if case == "other_anhysteretic" and p["blend"] > 0.0:
        curve = AnhystereticCurve(base=mat.curve, form=st.form, blend=p["blend"], shape=p["shape"],
                                  width_ratio=p["width_ratio"])
        return magnetization(st.time, field, mat, curve=curve, method=method)
    return magnetization(st.time, field, mat, method=method)


def _on_mount(st: Setup, M) -> np.ndarray:
    """Displacement (m) of the rod on its mount (:func:`mount_transfer`), by scipy's ``lsim`` (the input
    linear between samples) from the steady state of the first sample."""
    num, den = mount_transfer(st.base.mechanics, st.params, st.form)
    system = signal.StateSpace(*signal.tf2ss(num, den))
    forcing = st.base.mechanics.zetahat * np.asarray(M, dtype=float)
    start = -np.linalg.solve(system.A, system.B[:, 0] * forcing[0])
    _, x, _ = signal.lsim(system, forcing, st.time - st.time[0], X0=start)
    return np.asarray(x, dtype=float)


def forward(st: Setup, trace: dict | None = None) -> dict:
    """Noise-free recorded channels {"magnetization", "displacement"} (A/m, m) on the sample grid. ``trace``
    (a dict) receives the frame a replay keeps (:attr:`Setup.frame`): the field, the mechanics' drive M and
    the true outputs ahead of the sensors."""
    case, p, mat, num = st.case, st.params, st.base.material, st.numerics
    field = st.field
    if case == "saturating_amplifier":
        peak = None if st.frame is None else float(np.max(np.abs(st.frame["field"])))
        field = amplifier(field, st.form, p["overdrive"], p["asymmetry"], peak)
    if case == "input_dynamics":
        field = input_filter(st.time, field, st.form, p)
    M = _material_response(st, field)
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
    elif case == "rod_on_mount" and p["compliance"] > 0.0:
        x = _on_mount(st, M_drive)
    else:
        x = _lumped(st, M_drive)
    if trace is not None:
        trace.update(field=st.field, M=M_drive, true={"magnetization": M, "displacement": x})
    return _sensor_terms(st, {"magnetization": M, "displacement": x})


def _sensor_terms(st: Setup, out: dict) -> dict:
    """The recorded channels: the true ``out`` through the case's sensors (maps, dynamics, drifts, pickup)."""
    case, p = st.case, st.params
    x = out["displacement"]
    if case == "sensor_nonlinearity":
        out["displacement"] = sensor_map(x, st.form, p["gain"], p["offset"], _frame(st, "true", "displacement"))
    elif case == "sensor_resonance" and p["scale"] > 0.0:
        for ch in _acted_channels(st, BOTH):
            out[ch] = resonant_sensor(st.time, out[ch], p[f"frequency_{ch}"] / p["scale"], p[f"damping_{ch}"])
    elif case in ("sensor_offset_drift", "mains_pickup"):
        for ch in _acted_channels(st, BOTH):
            span = float(np.ptp(out[ch] if st.frame is None else st.frame["true"][ch]))
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
    if case in ("delta_e_shifted", "sensor_nonlinearity", "continuum_rod", "magnetostriction_law", "rod_on_mount"):
        acted = ("displacement",)
    elif case in ("sensor_offset_drift", "sensor_gain_drift", "mains_pickup", "sensor_resonance"):
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
    if case == "rod_on_mount":
        truth["mode_frequencies_hz"] = mount_modes(st.base.mechanics, st.params).tolist()
    if case == "pinning_temperature":  # a temperature capped below Tc or a floored pinning is said here
        theta = thermal_rise(st.time, st.field, st.params, st.params["rise"])
        truth["pinning_notes"] = pinning_scales(theta, st.params, st.form, st.base.material)[2]
        truth["max_temperature_rise"] = float(np.max(theta))
    return Simulation(time=st.time, field=st.field, clean={c: outputs[c] for c in wanted},
                      reference={c: reference[c] for c in wanted}, truth=ir._jsonable(truth))


def numerics_difference(st: Setup, outputs: dict, wanted) -> dict:
    """RMS difference (noise standard deviations) of these numerics' ``none`` recording from
    :mod:`experiments.independent_recordings`' for the same draws (spline field, Dormand-Prince
    in time, exact first-order-hold mechanics): how far two correct simulators differ."""
    theirs = ir.simulate("none", st.seed, "both", n_samples=st.time.size)
    return {ch: float(np.sqrt(np.mean((outputs[ch] - theirs.clean[ch]) ** 2))
                      / (st.base.conditions.noise_rel * float(np.ptp(outputs[ch])))) for ch in wanted}


#: Noise colours the generator can draw (``generate(noise=...)``): white Gaussian sensor noise, or a mixture of
#: white noise and a coloured part that second differences cannot see.
NOISE_COLOURS = ("white", "coloured")
#: Longest period (samples) at which the flicker noise's spectrum still rises (:func:`coloured_noise`).
FLICKER_LONGEST_PERIOD = 200.0


def coloured_noise(rng, n: int) -> tuple[np.ndarray, dict]:
    """Unit-variance sensor noise whose spectrum is not flat: a share (0.3-0.7 of the variance, uniform) of
    either AR(1) noise with a correlation time of 3-30 samples (log-uniform; an amplifier's bandwidth below the
    sample rate) or flicker noise with a 1/f^beta power spectrum, beta 0.8-1.5 (uniform; a sensor's electronics),
    the rest white; returns (noise, what was drawn).

    The flicker spectrum is flat below a period of :data:`FLICKER_LONGEST_PERIOD` samples: 1/f down to the
    record's own length would be a wander of the sensor's offset over the record, which is an effect the tool
    names (``sensor_drift``; the ``sensor_offset_drift`` case draws it as a random walk), not noise."""
    form = _choice(rng, ("ar1", "flicker"))
    share = float(rng.uniform(0.3, 0.7))
    white = rng.standard_normal(n)
    if form == "ar1":
        tau = ir._log_uniform(rng, 3.0, 30.0)
        phi = math.exp(-1.0 / tau)
        drive = rng.standard_normal(n) * math.sqrt(1.0 - phi * phi)
        drive[0] = rng.standard_normal()  # start in the stationary distribution
        part = signal.lfilter([1.0], [1.0, -phi], drive)
        drawn = {"form": form, "share": share, "correlation_samples": tau}
    else:
        beta = float(rng.uniform(0.8, 1.5))
        spectrum = np.fft.rfft(rng.standard_normal(n))
        lowest = max(1.0, n / FLICKER_LONGEST_PERIOD)  # in cycles per record
        spectrum *= np.maximum(np.arange(spectrum.size, dtype=float), lowest) ** (-beta / 2.0)
        spectrum[0] = 0.0
        part = np.fft.irfft(spectrum, n)
        drawn = {"form": form, "share": share, "exponent": beta}
    part = part / float(np.std(part))
    return math.sqrt(1.0 - share) * white + math.sqrt(share) * part, drawn


def generate(case: str, seed: int, channels: str = "both", *, n_samples: int | None = None, noise: str = "white"):
    """A synthetic recording of ``case``: (Recording, truth dict); deterministic.

    ``noise``: ``"white"`` (Gaussian, the studies' default) or ``"coloured"`` (:func:`coloured_noise`, drawn per
    channel from its own stream); the standard deviation is the same (``noise_rel`` of each channel's span)."""
    from hyst_gym.diagnose.recording import Recording

    if noise not in NOISE_COLOURS:
        raise ValueError(f"noise must be one of {', '.join(NOISE_COLOURS)}, got {noise!r}")
    sim = simulate(case, seed, channels, n_samples=n_samples)
    rng = ir._stream(seed, "other_forms", "noise", case, channels)
    noisy, sigmas, colours = {}, {}, {}
    for ch in BOTH:
        if ch in sim.clean:
            y = sim.clean[ch]
            sigmas[ch] = sim.truth["noise_rel"] * float(np.ptp(y))
            if noise == "white":
                unit = rng.standard_normal(y.size)
            else:
                unit, colours[ch] = coloured_noise(ir._stream(seed, "other_forms", "noise_colour", case, channels,
                                                              ch), y.size)
            noisy[ch] = y + sigmas[ch] * unit
    recording = Recording(time=sim.time, field=sim.field, metadata=sidecar(seed),
                          source=f"synthetic recording (other forms), seed {seed}", **noisy)
    truth = dict(sim.truth, noise_std=sigmas)
    if colours:
        truth["noise_colour"] = colours
    return recording, truth


def replay(case: str, seed: int, channels: str = "both", drive=None, *, noise_seed: int,
           n_samples: int | None = None):
    """The hidden system of :func:`generate` ``(case, seed, channels, n_samples)`` under another ``drive``
    (A/m at the record's samples, held linearly between them as the first record's; None: its own recorded
    field): (Recording, truth dict).

    Kept from the first record: the conditions, material, mechanics and sensors, the effect's form and its
    parameters at the size the visibility check settled on, the frame (:attr:`Setup.frame`: the static maps'
    ranges, the amplifier's saturation field, the coil's heating gain, the stiffness reference, the pickup's
    and drifts' amplitudes), the start state (demagnetized, then the initial curve to the drive's first value;
    mechanics, sensors and coil temperature settled) and the absolute noise standard deviations. New: the
    drive, and the noise draw from the stream (seed, "other_forms", "replay", case, channels, ``noise_seed``),
    never the first record's. Under its own drive the clean channels are the first record's, bit for bit."""
    from hyst_gym.diagnose.recording import Recording

    if isinstance(noise_seed, bool) or not isinstance(noise_seed, (int, np.integer)) or noise_seed < 0:
        raise ValueError(f"noise_seed must be an integer >= 0, got {noise_seed!r}")
    sim = simulate(case, seed, channels, n_samples=n_samples)
    st = replace(setup(case, seed, n_samples), form=sim.truth["form"], params=dict(sim.truth["effect_parameters"]))
    trace = {}
    forward(st, trace)
    field = st.field.copy() if drive is None else ir.check_drive(drive, st.time.size)
    outputs = forward(replace(st, field=field, frame=trace))
    rng = ir._stream(seed, "other_forms", "replay", case, channels, str(int(noise_seed)))
    sigmas = {ch: sim.truth["noise_rel"] * float(np.ptp(y)) for ch, y in sim.clean.items()}
    noisy = {ch: outputs[ch] + sigmas[ch] * rng.standard_normal(st.time.size) for ch in BOTH if ch in sim.clean}
    truth = dict(sim.truth, noise_std=sigmas, replay={"noise_seed": int(noise_seed), "own_drive": drive is None})
    recording = Recording(time=st.time.copy(), field=field, metadata=sidecar(seed),
                          source=f"synthetic recording (other forms), seed {seed}, replay {noise_seed}", **noisy)
    return recording, truth


def sidecar(seed: int) -> dict:
    """Sidecar metadata: nothing in it names or hints at the effect."""
    return {"material": "Terfenol-D (synthetic)", "notes": f"synthetic recording, seed {seed}"}


def write(case: str, seed: int, channels: str, out: Path, *, n_samples=None, truth_path: Path | None = None,
          noise: str = "white"):
    """Write the CSV (+ sidecar) and optionally the truth JSON; returns (recording, truth)."""
    from hyst_gym.diagnose.recording import write_recording

    recording, truth = generate(case, seed, channels, n_samples=n_samples, noise=noise)
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
