"""``hyst-gym make-recording``: synthetic recordings with one concealed effect.

``make_recording(effect, seed, strength=1.0, output="both", n_samples=8000)`` draws from the
seed: the base hysteresis parameters, the transducer coefficients, the excitation (a recorded
DC bias, sines at several frequencies under a slowly varying envelope that makes minor
loops, a ramp and a few fast transitions) and the sensor noise; then it adds the effect.
Nothing in the columns or in the sidecar names the effect (for ``thermal_drift`` there is no
temperature column).

Realism versus independence from the fitter: the generator integrates on a time grid 4x
finer than the recording, with a 4x finer field substep, and decimates, so the fitted model
never reproduces the generator's numbers exactly. The recording lasts a fraction of a
second (40-60 kHz sampling, so that the transducer's kHz dynamics are resolved)
the
thermal time constant is compressed to the record length (a tens-of-ms heating time is
not realistic for a Terfenol-D rod -- it stands for minutes-long records of a real coil).

Effects at ``strength = 1`` (the default; strength scales the effect's size):

* ``thermal_drift``: coil temperature rises ~25 K over the record (a ~ T, eq. (4); Ms drops 0.1 %/K);
* ``eddy_current``: ``H_eff = H - k_e dM/dt`` with k_e*|dM/dt| reaching ~5 % of the field amplitude;
* ``quadratic_magnetostriction``: displacement forced by M^2 (12) instead of the linearized M (13);
* ``rod_dynamics``: the finite-element rod (10) instead of the lumped mass: a light tip mass
  (0.02-0.05 kg at strength 1; ``ML / strength``) and a low Kelvin-Voigt damping
  (cD 1.5e4-6e4 Pa s, i.e. a loss factor of a few % at the second mode instead of the
  default 3e6 Pa s of RodParams, which makes every mode above the first overdamped), so that the second
  longitudinal mode (9.5-11 kHz, below the 20-30 kHz Nyquist frequency) responds to the
  broadband drive these recordings use (a repeated 3-12 kHz chirp on top of the usual
  excitation, as a rig that characterizes rod modes would apply
  ``broadband=True`` gives
  any effect, ``none`` included, the same drive). The lumped model with any chat/khat
  cannot reproduce the second resonance.
* ``sensor_lag``: a first-order lag of 2-4 samples on every output sensor;
* ``field_bias``: an unrecorded DC field of 10-20 % of the drive amplitude (a permanent magnet);
* ``anhysteretic_shape``: Langevin (3) instead of Ising (2) (strength does not apply);
* ``delta_e``: the stiffness follows the magnetization, ``khat*(1 + delta_e*((M/Ms)^2 - (M0/Ms)^2))``
  with delta_e 0.3-0.8;
* ``input_lag``: the field in the rod lags the recorded one by 2-5 samples and is delayed by 0-1.5 (a coil's
  L/R or an amplifier's bandwidth);
* ``input_map``: a saturating amplifier, the field in the rod ``h_s*tanh(H/h_s)`` of the recorded one
  (h_s 0.4-0.8 times the peak field; strength blends it with the identity);
* ``sensor_map``: each output sensor reads ``y + s*(q2*v^2 + q3*v^3)`` (v: the output over its range, s
  its half-span) with a compressive q3 of -0.05 to -0.15 and q2 within +-0.08;
* ``sensor_drift``: each sensor's offset settles exponentially by 3-8 % of its span (time constant
  0.3-1 record lengths) from zero at the start;
* ``sensor_gain_drift``: each sensor's gain settles exponentially by 3-8 % (either sign; time constant 0.3-1
  record lengths) from its calibration at the start;
* ``mains_pickup``: 50 or 60 Hz pickup of 1-3 % of each channel's span, with a third harmonic of
  20-40 % of that, at random phases.

The flexible families (the last five) hold these laws, so the concealed study draws only the
textbook ones (:data:`GENERATOR_EFFECTS`); every effect the tool names can be written
(:data:`WRITABLE_EFFECTS`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ..physics.fem import FEMRod
from ..physics.transducers import RodParams
from .kernels import (AMBIENT_TEMPERATURE, MAGNETIC_COLUMNS, lti_response, second_order_system, simulate_members,
                      varying_stiffness_response)
from ..physics.constants import PAPER_COUPLING
from .effects import EFFECTS, MECHANICAL_EFFECTS
from .model import PAPER_CHAT, PAPER_KHAT
from .recording import Recording, write_recording

#: Effects whose laws are flexible families of the tool (their generators above draw one member each).
FAMILY_GENERATED = ("input_map", "sensor_map", "sensor_drift", "sensor_gain_drift", "mains_pickup")
#: The effects the concealed study draws here: the vocabulary's textbook laws. The flexible families are
#: judged on recordings from independent generators (``experiments/independent_recordings.py``,
#: ``experiments/other_forms.py``), whose forms the tool's families do not hold exactly.
GENERATOR_EFFECTS = tuple(e for e in EFFECTS if e not in FAMILY_GENERATED) + ("none",)
#: Every effect this generator can write (``--effect``): the whole vocabulary and ``none``.
WRITABLE_EFFECTS = EFFECTS + ("none",)
OVERSAMPLE = 4
PAPER_ZETAHAT = PAPER_COUPLING  # m/s^2 per A/m, eq. (13)

#: Rod data (paper §2.2) used for rod_dynamics, each drawn within +-5 %; the tip mass and the
#: Kelvin-Voigt damping cD are drawn separately (see :func:`_rod_state_space`).
ROD = dict(Y=3.0e10, rho=9250.0, L=0.115, A=1.2668e-4, kL=2e6, cL=1e3)
#: Range of the Kelvin-Voigt damping for rod_dynamics, Pa s (log-uniform draw).
ROD_KELVIN_VOIGT = (1.5e4, 6e4)
#: Range of the tip mass for rod_dynamics at strength 1, kg (divided by the strength).
ROD_TIP_MASS = (0.02, 0.05)


def _excitation(rng, time):
    duration = time[-1] - time[0] + (time[1] - time[0])
    amplitude = rng.uniform(4e4, 1e5)                       # A/m
    bias = rng.uniform(0.0, 0.4) * amplitude                # recorded DC bias, A/m
    n_sines = int(rng.integers(2, 4))
    freqs = np.sort(rng.uniform(20.0, 120.0, n_sines))        # Hz
    weights = rng.dirichlet(np.ones(n_sines))
    phases = rng.uniform(0, 2 * np.pi, n_sines)
    carrier = sum(w * np.sin(2 * np.pi * f * time + p) for w, f, p in zip(weights, freqs, phases))
    carrier /= max(np.max(np.abs(carrier)), 1e-12)
    env_f = rng.uniform(1.0, 3.0) / duration                 # slow envelope -> minor loops
    envelope = 0.55 + 0.45 * np.cos(2 * np.pi * env_f * time + rng.uniform(0, 2 * np.pi))
    field = bias + amplitude * envelope * carrier
    # a ramp segment and a few fast transitions (rise 0.05-0.2 ms) that excite kHz dynamics
    t_ramp = rng.uniform(0.1, 0.6) * duration
    field += 0.15 * amplitude * np.clip((time - t_ramp) / (0.2 * duration), 0.0, 1.0) * rng.choice([-1, 1])
    for _ in range(int(rng.integers(3, 6))):
        t0 = rng.uniform(0.05, 0.95) * duration
        rise = rng.uniform(5e-5, 2e-4)
        size = rng.uniform(0.05, 0.15) * amplitude * rng.choice([-1, 1])
        field += size * 0.5 * (1 + np.tanh((time - t0) / (0.3 * rise)))
    return field, amplitude, bias


def _broadband_drive(rng, time, amplitude):
    """A repeated linear chirp (A/m) sweeping 3 kHz -> 12 kHz every 2-4 ms over the whole
    record, with 10-20 % of the drive amplitude: the drive a rig uses to see the rod's
    longitudinal modes (it spans the second mode at every draw of the rod data)."""
    period = rng.uniform(2e-3, 4e-3)
    f_lo, f_hi = 3e3, 12e3
    local = np.mod(time - rng.uniform(0.0, period), period)
    phase = 2 * np.pi * (f_lo * local + 0.5 * (f_hi - f_lo) / period * local ** 2)
    return rng.uniform(0.1, 0.2) * amplitude * np.sin(phase)


def _rod_state_space(rng, n_elements=12, strength=1.0):
    """FEM rod (10) from :mod:`hyst_gym.physics.fem` with rod data drawn within +-5 % of the
    defaults, a light tip mass and a low Kelvin-Voigt damping drawn from ``rng``
    returns
    (A, B, C, static tip compliance in m/N)."""
    tip_mass = rng.uniform(*ROD_TIP_MASS) / max(strength, 1e-3)
    kelvin_voigt = float(np.exp(rng.uniform(*np.log(ROD_KELVIN_VOIGT))))
    rod = RodParams(**{k: v * rng.uniform(0.95, 1.05) for k, v in ROD.items()}, ML=tip_mass, cD=kelvin_voigt)
    fem = FEMRod(rod=rod, n_elements=n_elements)
    A, b = fem.state_matrices()
    C = np.zeros(2 * n_elements)
    C[n_elements - 1] = 1.0
    static = float(np.linalg.solve(fem.stiffness_matrix(), fem.forcing_vector())[-1])
    return A, b, C, static


def make_recording(effect: str = "none", seed: int = 0, strength: float = 1.0, output: str = "both",
                   n_samples: int = 5000, broadband: bool | None = None) -> tuple[Recording, dict]:
    """Draw a synthetic recording with ``effect`` concealed in it; returns (recording, sidecar).

    ``broadband`` adds a repeated 3-12 kHz chirp to the drive (see :func:`_broadband_drive`);
    ``None`` means: only for ``rod_dynamics``, whose rod modes show only under such a drive.
    """
    recording, sidecar, _ = make_recording_with_truth(effect, seed, strength, output, n_samples, broadband)
    return recording, sidecar


def _check_arguments(effect, seed, strength, output, n_samples):
    """One-line errors naming the argument (the Python name; :func:`main` words them as CLI flags)."""
    if effect not in WRITABLE_EFFECTS:
        raise ValueError(f"effect must be one of {', '.join(WRITABLE_EFFECTS)}, got {effect!r}")
    if output not in ("magnetization", "displacement", "both"):
        raise ValueError(f"output must be magnetization, displacement or both, got {output!r}")
    if isinstance(strength, bool) or not isinstance(strength, (int, float)) or not (np.isfinite(strength)
                                                                                    and strength >= 0):
        raise ValueError(f"strength must be a finite number >= 0, got {strength!r}")
    if output == "magnetization" and effect in MECHANICAL_EFFECTS:
        raise ValueError(f"effect {effect} acts on the displacement only; record the displacement too "
                         "(output displacement or both)")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)) or n_samples < 400:
        raise ValueError(f"n_samples must be an integer >= 400, got {n_samples!r}")


def _magnetic_row(effect, strength, effect_rng, material, field, fine_time, amplitude):
    """The member row (:data:`MAGNETIC_COLUMNS`) of the true material with the magnetic effect."""
    row = dict(material, H0=0.0, k_e=0.0, heating=0.0, tau_th=1.0, beta_Ms=0.0, chi_r=0.0, heating_exponent=2.0)
    kind = 1 if material["curve"] == "langevin" else 0
    del row["curve"]
    duration = fine_time[-1]
    if effect == "field_bias":
        row["H0"] = strength * effect_rng.uniform(0.1, 0.2) * amplitude * effect_rng.choice([-1, 1])
    if effect == "small_loop":
        # a reversible low-field susceptibility of 40-80 % of the anhysteretic's initial slope Ms/a:
        # the span of the fits to the measured ferrite loops (experiments/real_loops.py); much less
        # is absorbed by the base model's own reversible term c*Man'
        row["chi_r"] = strength * effect_rng.uniform(0.4, 0.8) * row["Ms"] / row["a"]
    if effect == "eddy_current":
        plain = simulate_members(fine_time, field, np.array([[row[c_] for c_ in MAGNETIC_COLUMNS]]), kind, 25.0,
                                 AMBIENT_TEMPERATURE)[:, 0]
        rate = np.abs(np.diff(plain)) / np.diff(fine_time)
        row["k_e"] = strength * 0.05 * amplitude / float(np.percentile(rate, 99))
    if effect == "thermal_drift":
        tau = effect_rng.uniform(0.5, 2.0) * duration
        rise = 25.0 * strength
        row["tau_th"] = tau
        row["heating"] = rise / (float(np.mean(field ** 2)) * tau * (1 - np.exp(-duration / tau)))
        row["beta_Ms"] = 1e-3
    return row, kind


def _displacement(effect, strength, effect_rng, fine_time, magnetization, M0, Ms, mechanics):
    """Tip displacement (m) of the lumped transducer (13), or of the effect's mechanics."""
    chat, khat, zetahat = mechanics
    if effect == "rod_dynamics":
        A, B, C, static = _rod_state_space(effect_rng, strength=strength)
        # same static gain as the lumped model it replaces: zetahat/khat per unit (M - M0)
        gain = zetahat / khat / static
        return lti_response(fine_time, gain * (magnetization - M0), A, B, C, start="steady")
    if effect == "quadratic_magnetostriction":
        ref = max(abs(M0), 0.3 * Ms)
        linear = 2 * ref * (magnetization - M0)
        forcing = zetahat / (2 * ref) * ((1 - strength) * linear + strength * (magnetization ** 2 - M0 ** 2))
    else:
        forcing = zetahat * (magnetization - M0)
    if effect == "delta_e":
        delta_e = strength * effect_rng.uniform(0.3, 0.8)
        relative = delta_e * ((magnetization / Ms) ** 2 - (M0 / Ms) ** 2)
        return varying_stiffness_response(fine_time, forcing, relative, khat, chat)
    A, B, C = second_order_system(khat, chat, 1.0)
    return lti_response(fine_time, forcing, A, B, C, start="steady")


def _sensed(effect, strength, effect_rng, noise_rng, fine_time, fs, outputs, output, noise_rel):
    """The recorded channels: the sensor's effect (if concealed), decimation to the sample rate, noise."""
    if effect == "sensor_lag":
        tau = strength * effect_rng.uniform(2.0, 4.0) / fs
        if tau > 0:
            outputs = {ch: lti_response(fine_time, sig, [[-1 / tau]], [1 / tau], [1.0], start="steady")
                       for ch, sig in outputs.items()}
    if effect in SENSOR_GENERATORS:
        outputs = {ch: SENSOR_GENERATORS[effect](sig, strength, effect_rng, fine_time)
                   for ch, sig in sorted(outputs.items())}
    keep = slice(None, None, OVERSAMPLE)
    channels = ("magnetization", "displacement") if output == "both" else (output,)
    recorded = {}
    for ch in channels:
        clean = outputs[ch][keep]
        recorded[ch] = clean + noise_rel * float(np.ptp(clean)) * noise_rng.standard_normal(clean.size)
    return recorded


def _sensor_map(signal, strength, effect_rng, fine_time):
    """A static sensor nonlinearity ``y + s*(q2*v^2 + q3*v^3)`` over the output's range (compressive q3)."""
    lo, hi = float(np.min(signal)), float(np.max(signal))
    centre, half = 0.5 * (lo + hi), (0.5 * (hi - lo) or 1.0)
    q2 = strength * effect_rng.uniform(-0.08, 0.08)
    q3 = -strength * effect_rng.uniform(0.05, 0.15)
    v = (signal - centre) / half
    return signal + half * (q2 * v ** 2 + q3 * v ** 3)


def _sensor_drift(signal, strength, effect_rng, fine_time):
    """An offset that settles exponentially from zero at the start, by 3-8 % of the output's span."""
    size = strength * effect_rng.uniform(0.03, 0.08) * effect_rng.choice([-1.0, 1.0]) * float(np.ptp(signal))
    tau = effect_rng.uniform(0.3, 1.0) * float(fine_time[-1] - fine_time[0])
    return signal + size * (1.0 - np.exp(-(fine_time - fine_time[0]) / tau))


def _sensor_gain_drift(signal, strength, effect_rng, fine_time):
    """A gain that settles exponentially from its calibration at the start, by 3-8 % (either sign; time
    constant 0.3-1 record lengths): the reading is the true output times it."""
    size = strength * effect_rng.uniform(0.03, 0.08) * effect_rng.choice([-1.0, 1.0])
    tau = effect_rng.uniform(0.3, 1.0) * float(fine_time[-1] - fine_time[0])
    return signal * (1.0 + size * -np.expm1(-(fine_time - fine_time[0]) / tau))


def _mains_pickup(signal, strength, effect_rng, fine_time):
    """Mains pickup at 50 or 60 Hz, 1-3 % of the output's span, with a third harmonic of 20-40 % of it."""
    hz = float(effect_rng.choice([50.0, 60.0]))
    size = strength * effect_rng.uniform(0.01, 0.03) * float(np.ptp(signal))
    third = effect_rng.uniform(0.2, 0.4)
    phases = effect_rng.uniform(0.0, 2 * np.pi, 2)
    phase = 2 * np.pi * hz * fine_time
    return signal + size * (np.sin(phase + phases[0]) + third * np.sin(3 * phase + phases[1]))


#: Generators of the sensor's effects that act on each recorded output alone.
SENSOR_GENERATORS = {"sensor_map": _sensor_map, "sensor_drift": _sensor_drift, "sensor_gain_drift": _sensor_gain_drift,
                     "mains_pickup": _mains_pickup}


def _input_mapped(field, strength, effect_rng, fine_time, fs):
    """The field (A/m) a saturating amplifier delivers for the recorded (commanded) ``field``:
    ``h_s*tanh(H/h_s)``, blended with the identity by ``strength`` (0: none)."""
    h_s = effect_rng.uniform(0.4, 0.8) * float(np.max(np.abs(field)))
    return np.ascontiguousarray(field + strength * (h_s * np.tanh(field / h_s) - field))


def _input_lagged(field, strength, effect_rng, fine_time, fs):
    """The field (A/m) in the rod behind a coil's L/R: the recorded one delayed by 0-1.5 samples and lagged
    by 2-5 samples (both times ``strength``), integrated on the fine grid."""
    delay = strength * effect_rng.uniform(0.0, 1.5) / fs
    tau = strength * effect_rng.uniform(2.0, 5.0) / fs
    delayed = np.interp(fine_time - delay, fine_time, field)
    if tau <= 0.0:
        return np.ascontiguousarray(delayed)
    return np.ascontiguousarray(lti_response(fine_time, delayed, [[-1 / tau]], [1 / tau], [1.0], start="steady"))


#: Generators of the input side's effects: the field in the rod for the recorded one.
INPUT_GENERATORS = {"input_map": _input_mapped, "input_lag": _input_lagged}


def make_recording_with_truth(effect: str = "none", seed: int = 0, strength: float = 1.0, output: str = "both",
                              n_samples: int = 5000, broadband: bool | None = None) -> tuple[Recording, dict, dict]:
    """As :func:`make_recording`, plus the true parameters (for tests and studies only).

    Three random streams per seed: the conditions (rate, drive, material, mechanics, noise), the
    effect's parameters, and the noise, so that an effect changes nothing else in the record."""
    _check_arguments(effect, seed, strength, output, n_samples)
    n_samples = int(n_samples)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 6]))
    fs = rng.uniform(40e3, 60e3)
    time = np.arange(n_samples) / fs
    fine_time = np.arange(n_samples * OVERSAMPLE) / (fs * OVERSAMPLE)
    field, amplitude, bias = _excitation(rng, fine_time)
    if broadband is None:
        broadband = effect == "rod_dynamics"
    if broadband:
        # a separate stream, so the rest of the recording is the same with or without the chirp
        field = field + _broadband_drive(np.random.default_rng(np.random.SeedSequence([int(seed), 6, 3])),
                                         fine_time, amplitude)
    a = rng.uniform(4000, 9000)
    k = rng.uniform(800, 3000)
    rho = rng.uniform(-0.6, 0.4)
    Ms = rng.uniform(6e5, 9e5)
    c = rng.uniform(0.1, 0.4)
    curve = "langevin" if effect == "anhysteretic_shape" else "ising"
    if curve == "langevin":
        a = a / 3.0  # same initial anhysteretic slope Ms/(3a) as the Ising curve it replaces
    alpha = rho * a / Ms * (3.0 if curve == "langevin" else 1.0)
    chat = PAPER_CHAT * rng.uniform(0.8, 1.25)
    khat = PAPER_KHAT * rng.uniform(0.8, 1.25)
    zetahat = PAPER_ZETAHAT * rng.uniform(0.8, 1.25)
    noise_rel = rng.uniform(0.5e-3, 1.5e-3)
    effect_rng = np.random.default_rng(np.random.SeedSequence([int(seed), 6, 1]))
    material = dict(a=a, k=k, alpha=alpha, Ms=Ms, c=c, curve=curve)
    row, kind = _magnetic_row(effect, strength, effect_rng, material, field, fine_time, amplitude)
    # the field in the rod: the recorded one, or what a saturating amplifier makes of it (input_map)
    applied = INPUT_GENERATORS[effect](field, strength, effect_rng, fine_time, fs) if effect in INPUT_GENERATORS \
        else field
    magnetization = simulate_members(fine_time, applied, np.array([[row[c_] for c_ in MAGNETIC_COLUMNS]]), kind,
                                     25.0, AMBIENT_TEMPERATURE)[:, 0]
    M0 = float(np.median(magnetization))
    displacement = _displacement(effect, strength, effect_rng, fine_time, magnetization, M0, Ms,
                                 (chat, khat, zetahat))
    noise_rng = np.random.default_rng(np.random.SeedSequence([int(seed), 6, 2]))
    recorded = _sensed(effect, strength, effect_rng, noise_rng, fine_time, fs,
                       {"magnetization": magnetization, "displacement": displacement}, output, noise_rel)
    recording = Recording(time=time, field=field[::OVERSAMPLE], source=f"make-recording seed {seed}", **recorded)
    sidecar = {"material": "Terfenol-D (synthetic)", "notes": f"synthetic recording from hyst-gym, seed {seed}"}
    truth = dict(row, rho=rho, curve=curve, chat=chat, khat=khat, zetahat=zetahat, M0=M0,
                 noise_rel=noise_rel, sample_rate=fs)
    return recording, sidecar, truth


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--effect", required=True, choices=WRITABLE_EFFECTS, help="concealed effect")
    parser.add_argument("--seed", type=int, required=True, help="seed for parameters, excitation and noise")
    parser.add_argument("--strength", type=float, default=1.0, help="size of the effect (default 1)")
    parser.add_argument("--output", default="both", choices=("magnetization", "displacement", "both"),
                        help="channels to record besides the field (default both)")
    parser.add_argument("--samples", type=int, default=5000, help="number of samples (default 5000)")
    parser.add_argument("--out", required=True, type=Path, help="CSV file to write (sidecar .json beside it)")


#: The CLI flag of each argument of :func:`make_recording`, for its one-line errors.
FLAGS = {"effect": "--effect", "seed": "--seed", "strength": "--strength", "output": "--output",
         "n_samples": "--samples"}


def main(args) -> int:
    try:
        recording, sidecar = make_recording(args.effect, args.seed, args.strength, args.output, args.samples)
    except ValueError as error:
        message = str(error)
        first = message.split(" ", 1)[0]
        raise ValueError(FLAGS[first] + message[len(first):] if first in FLAGS else message) from None
    write_recording(args.out, recording, sidecar)
    print(f"wrote {args.out} ({recording.size} samples, columns: time, field, {', '.join(recording.channels)})")
    return 0
