"""Fuzz: 0 tracebacks and 0 internal numeric errors on 200 random valid recordings (slow tier): random
effects, strengths, rates, drive amplitudes up to 2e5 A/m and waveforms, on real (fast to quasi-static) or
synthetic time axes."""

import json

import numpy as np
import pytest

from hyst_gym.diagnose import Recording, diagnose, make_recording
from hyst_gym.diagnose.effects import EFFECTS, MECHANICAL_EFFECTS
from hyst_gym.diagnose.report import _jsonable
from hyst_gym.physics import simulate_magnetization

VERDICTS_OTHER_THAN_EFFECTS = {"none", "unexplained", "ambiguous"}
FUZZ_RECORDINGS = 200


# ---------------------------------------------------------------------------- random valid recordings


def _drive(rng, n):
    """A field (A/m) of random waveform and amplitude (1e2 to 2e5 A/m, log-uniform) with a random bias."""
    amplitude = float(np.exp(rng.uniform(np.log(1e2), np.log(2e5))))
    phase = np.linspace(0.0, rng.uniform(1.0, 6.0) * 2 * np.pi, n)
    form = rng.integers(3)
    if form == 0:
        shape = np.sin(phase) * (0.5 + 0.5 * np.cos(phase / rng.uniform(3.0, 8.0)))
    elif form == 1:
        shape = 2.0 / np.pi * np.arcsin(np.sin(phase))
    else:
        walk = np.cumsum(rng.standard_normal(n))
        shape = (walk - walk.mean()) / (np.max(np.abs(walk - walk.mean())) or 1.0)
    return amplitude * (shape + rng.uniform(-0.3, 0.3))


def _from_physics(rng, n):
    """The paper's hysteresis (6) with random parameters under a random drive; a displacement that is a
    random linear map of M, each with noise of 0.05-1 % of its span."""
    field = _drive(rng, n)
    h_max = float(np.max(np.abs(field)))
    Ms = float(rng.uniform(1e5, 1.5e6))
    a, k = h_max * rng.uniform(0.02, 0.5), h_max * rng.uniform(0.005, 0.2)
    m = simulate_magnetization(np.concatenate([[0.0], field]), max_field_step=max(h_max / 200, 1e-6), a=a, k=k,
                               alpha=0.0, Ms=Ms, c=float(rng.uniform(0.05, 0.5)))[1:]
    channels = {"magnetization": m, "displacement": 1e-11 * (m - np.mean(m))}
    chosen = [("magnetization",), ("displacement",), ("magnetization", "displacement")][rng.integers(3)]
    return field, {c: channels[c] + rng.uniform(5e-4, 1e-2) * np.ptp(channels[c]) * rng.standard_normal(n)
                   for c in chosen}


def _from_generator(rng, seed, n):
    """The tool's own generator: a random effect of the vocabulary at a random strength (0-2)."""
    effect = str(rng.choice(EFFECTS + ("none",)))
    output = "displacement" if effect in MECHANICAL_EFFECTS else str(rng.choice(["magnetization", "both"]))
    recording = make_recording(effect, seed, strength=float(rng.uniform(0.0, 2.0)), output=output, n_samples=n)[0]
    return recording.field, {c: recording.output(c) for c in recording.channels}


def fuzz_recording(seed: int) -> tuple[Recording, str]:
    """(recording, description) number ``seed``: deterministic."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 31]))
    source = "generator" if rng.random() < 0.5 else "physics"
    # short records (the generator needs 400 samples): the point is robustness, not the verdicts
    n = int(rng.integers(400, 481)) if source == "generator" else int(rng.integers(250, 401))
    field, outputs = _from_generator(rng, seed, n) if source == "generator" else _from_physics(rng, n)
    axis = ["fast", "quasi-static", "synthetic"][rng.integers(3)]
    if axis == "synthetic":
        time, metadata = np.arange(n, dtype=float), {"time_axis": "synthetic"}
    else:
        # a sample rate from 50 kHz (fast) down to 1 Hz (a quasi-static loop of minutes)
        rate = float(np.exp(rng.uniform(np.log(1e4), np.log(5e4)))) if axis == "fast" else float(
            np.exp(rng.uniform(0.0, np.log(100.0))))
        time, metadata = np.arange(n) / rate, {}
    return (Recording(time=time, field=field, metadata=metadata, source=f"fuzz {seed}", **outputs),
            f"seed {seed}: {source}, {axis} axis, {n} samples, channels {tuple(outputs)}")


@pytest.mark.slow
def test_two_hundred_random_valid_recordings_give_a_verdict_and_finite_numbers():
    """Random effects and strengths, drive amplitudes from 1e2 to 2e5 A/m, sample rates from 50 kHz to
    1 Hz and synthetic time axes, 250-480 samples: every recording gives a report (no exception, no
    failed base fit), with a finite confidence in [0, 1], a finite base held-out RMSE, and a JSON report
    without NaN or infinity."""
    problems = []
    for seed in range(FUZZ_RECORDINGS):
        recording, what = fuzz_recording(seed)
        try:
            report = diagnose(recording, progress=False)
        except Exception as error:  # noqa: BLE001 -- the point: any exception on a valid recording is a failure
            problems.append(f"{what}: {type(error).__name__}: {error}")
            continue
        if report.verdict not in VERDICTS_OTHER_THAN_EFFECTS | set(EFFECTS):
            problems.append(f"{what}: verdict {report.verdict!r}")
        if not (np.isfinite(report.confidence) and 0.0 <= report.confidence <= 1.0):
            problems.append(f"{what}: confidence {report.confidence!r}")
        if not np.isfinite(report.baseline_heldout):
            problems.append(f"{what}: base held-out RMSE {report.baseline_heldout!r}")
        json.dumps(_jsonable(report.to_json()), allow_nan=False)
    assert not problems, "\n".join(problems)
