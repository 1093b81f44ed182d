"""Temperature laws of the domain-wall model (6) on measured gadolinium B-H loops.

Data: ``data/real/gd-temperature/gd_loops.npz`` (README there): eight temperatures,
-38 ... +15 C (Curie point 18.3 C), three drive amplitudes each (major ~55 kA/m, mid
~10 kA/m, minor ~400 A/m). Each record runs from H ~ 0 up the initial curve to +Hmax,
down to -Hmax and back up to +Hmax. M = B/mu0 - H.

Method
------
* Field cleaning: the record is cut at its two reversals (first maximum, minimum) into
  three runs. Within each run the measured H is made monotone (mean of the running
  maximum and the reversed running minimum, a cheap isotonic fit), which removes
  the sampling noise that would otherwise act as spurious reversals (the minor loops have
  ~10 A/m of noise on 400 A/m). The runs are then subsampled every ``stride`` samples,
  always keeping the reversal samples. The model is rate independent, so this loses
  nothing but resolution.
* Model: eq. (6), Langevin anhysteretic, alpha = 0 (as in the source's fit), started at
  the measured M of the start of the record (the median of B/mu0 - H while |H| stays below 5 %
  of the first peak: one sample alone carries a few mT of noise, which on a 400 A/m loop would
  act as a remanent state). Field substep min(50 A/m, Hpeak/200).
* Laws (global parameters, one set for all temperatures; T in K; Tc = 291.45 K fixed):
    - ``eq4``: the paper's law, a = a_ref T/T_ref (eq. 4), Ms, k, c constant (4 params);
    - ``eq4_critical_ms``: a by eq. (4); Ms = Ms0 (1 - T/Tc)^beta; k = k0 (Ms/Ms0)^n_k;
      c constant (6 params);
    - ``critical``: Ms = Ms0 (1 - T/Tc)^beta; a = a0 (Ms/Ms0)^n_a; k = k0 (Ms/Ms0)^n_k;
      c constant (7 params);
    - ``smooth``: Ms = Ms0 (1 - T/Tc)^beta; log a and log k quadratic in (T - T_ref)/10 K;
      c constant (9 params);
    - ``smooth_small_loop``: ``smooth`` plus the small-loop extension, chi_r following Ms (11);
    - ``smooth_reversal``: ``smooth`` with the reversal-dependent pinning of the physics layer
      (``hysteresis.REVERSAL_PINNING``: the irreversible term builds up over rayleigh_field after
      each reversal), rayleigh_field = kappa k(T), kappa fitted (10 params);
    - ``smooth_pinning``: the same with kappa = 1, rayleigh_field = k(T), the pinning field itself
      (9 params, no parameter of its own).
    - ``hem_critical``: the homogenized energy model (``hyst_gym.physics.hem``, normal interaction
      density, 16 coercive nodes) with critical scaling near the Curie point: relay (spontaneous)
      magnetization M_R = M0 (1 - T/Tc)^beta, the pinning -- coercive median and interaction scale --
      following it as (M_R/M0)^n_c and (M_R/M0)^n_b, the reversible susceptibility diverging as
      chi0 (1 - T/Tc)^-gamma, spread of ln Hc constant (9 params);
    - ``hem_smooth``: the HEM with M_R = M0 (1 - T/Tc)^beta and log chi, log Hc, log b quadratic in
      (T - T_ref)/10 K (12 params).
    - ``hem_smooth_saturating``: ``hem_smooth`` with the saturating reversible part of the physics
      layer (``hem.SATURATING_REVERSIBLE``), its field scale h_s = hs0 (M_R/M0)^n_hs (14 params; added
      after the other laws had been run, so the shipped temperatures do not judge it blind).
    Each HEM record starts from a state of uniform play outputs whose M is the measured M0.
  A per-temperature fit (five constant parameters at one temperature, all amplitudes) gives
  the floor that no temperature law can beat.
* Fit: ``scipy.optimize.least_squares`` (trf) in log coordinates for positive parameters
  (linear for exponents), with bounds, on all three amplitudes of the fitted temperatures.
  Residual per loop = (B_model - B_meas) / ptp(B_meas) / sqrt(n), so each loop weighs by
  its NRMSE. The Jacobian is a forward difference computed as one batched simulation
  (``simulate_batch``, ``simulate_hem_batch``) per record. The laws are evaluated once per parameter
  set for all temperatures, the HEM start states of all records are solved together
  (``hem.states_with_magnetization``), and BLAS runs on one thread during
  the fit (the solver's SVD of the tall Jacobian is 20 times slower on two threads of a loaded 2-core machine).
* Score: NRMSE of B = RMS(B_model - B_meas) / ptp(B_meas) over the LOOP PART of the
  record (from the first positive peak to the end; the initial curve is simulated but not
  scored), on the subsampled points.
* Protocol: a fit on all temperatures (role ``fitted``), then leave-one-out over each
  interior temperature (-30 ... +5 C) and the warmest (+15 C, 3.3 K below Tc: an extrapolation
  towards the Curie point): fit the other seven, predict the held-out temperature at every
  amplitude (role ``predicted``).
* SELECTION RULE (interior hold-out), fixed and written here before it was run: the law with the lowest
  mean held-out NRMSE over the INTERIOR temperatures of the shared range (every temperature but the
  coldest and the warmest, each left out in turn and predicted by a fit on all the others) and every
  amplitude is chosen. The warmest temperature is left out and predicted too, an extrapolation towards
  the Curie point, and reported beside it, but the choice does not read it: a law is chosen for the
  temperatures it interpolates. The chosen law's fit on all shipped temperatures predicts any other file
  (``--predict FILE``, e.g. held-back temperatures), which the choice never reads.
* Near Tc: the warmest interior temperature (+5 C, 13 K below Tc, where the loops change fastest with
  temperature inside the range) is the near-Tc test: each law's fold there (fit on the other seven) is
  reported per amplitude, and the summary says in words at which amplitude no law predicts within
  NEAR_TC_TARGET.
* Protocol check (``record_protocol``): every raw record's length, samples per drive period, peak field,
  deviation of the drive from a sine, start field and start magnetization (relative to the loop's own
  half-range), closure of the loop and asymmetry, with the records that differ from the others flagged.

    .venv/bin/python -m experiments.gd_temperature [--data FILE] [--predict FILE] [--json FILE] [--quick]
        [--model {domain_wall,hem,auto}]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import theilslopes
from threadpoolctl import threadpool_limits

from hyst_gym.physics.hem import HEMBatch, simulate_hem_batch, states_with_magnetization
from hyst_gym.physics.hysteresis import HysteresisBatch, simulate_batch
from hyst_gym.physics.temperature_laws import (
    GD_CURIE_K, HEM_PARAMETER_NAMES, PARAMETER_NAMES, Constant, CriticalPowerLaw, FollowsMs, HEMTemperatureLaws,
    LinearInT, LogPolynomial, TemperatureLaws, celsius_to_kelvin,
)

MU0 = 4e-7 * np.pi
ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT / "data" / "real" / "gd-temperature" / "gd_loops.npz"
RESULTS_DIR = ROOT / "experiments" / "results" / "gd_temperature"
FIGURES_DIR = ROOT / "docs" / "figures" / "gd_temperature"
PAGE = ROOT / "docs" / "results" / "real-loops.md"  # its gd-summary section is page_section(results.json)
AMPLITUDES = ("major", "mid", "minor")
T_REF_K = celsius_to_kelvin(-10.0).item()  # reference temperature of eq. (4), K
ANHYSTERETIC = "langevin"
HEM_NODES = 16  # coercive nodes of the HEM families
FD_STEP = 1e-4  # forward-difference step in fit coordinates (log or linear)


def tag_for(temperature_C: float) -> str:
    """Key tag of a temperature: -38 -> 'm38C', 5 -> 'p05C', 0 -> 'p00C'."""
    t = int(round(float(temperature_C)))
    return f"{'m' if t < 0 else 'p'}{abs(t):02d}C"


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Record:
    """One measured record, cleaned and subsampled (H in A/m, B in T)."""

    temperature_C: float
    amplitude: str
    field: np.ndarray
    B: np.ndarray
    loop_start: int  # index of the first positive peak in the subsampled record
    M0: float  # measured M at the start of the record (median over the start, see clean_record), A/m
    peak_field: float
    max_field_step: float
    asymmetry: float = 0.0  # (B(+Hmax) + B(-Hmax)) / 2 / ptp(B) on the loop; 0 for a symmetric loop

    @property
    def temperature_K(self) -> float:
        return float(celsius_to_kelvin(self.temperature_C))


def reversal_indices(H: np.ndarray) -> Tuple[int, int]:
    """(first maximum, minimum) of a record that runs 0 -> +Hmax -> -Hmax -> +Hmax."""
    i_min = int(np.argmin(H))
    if i_min < 2 or i_min > H.size - 3:
        raise ValueError("record does not run 0 -> +Hmax -> -Hmax -> +Hmax")
    i_max = int(np.argmax(H[:i_min]))
    if i_max < 1:
        raise ValueError("record has no initial curve before its first maximum")
    return i_max, i_min


def _monotone(h: np.ndarray, increasing: bool) -> np.ndarray:
    if not increasing:
        return -_monotone(-h, True)
    return 0.5 * (np.maximum.accumulate(h) + np.minimum.accumulate(h[::-1])[::-1])


def clean_record(H, B, temperature_C, amplitude, stride=8) -> Record:
    """Monotone runs between the reversals, subsampled every ``stride`` samples."""
    H = np.asarray(H, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    if H.ndim != 1 or H.shape != B.shape or H.size < 20 or not (np.all(np.isfinite(H)) and np.all(np.isfinite(B))):
        raise ValueError(f"{tag_for(temperature_C)}_{amplitude}: H and B must be finite 1-D arrays of equal length")
    i_max, i_min = reversal_indices(H)
    bounds = [0, i_max, i_min, H.size - 1]
    clean = H.copy()
    keep = []
    for s, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
        clean[lo:hi + 1] = _monotone(H[lo:hi + 1], increasing=(s != 1))
        keep.append(np.arange(lo, hi, max(1, int(stride))))
    keep.append(np.array(bounds))
    idx = np.unique(np.concatenate(keep))
    loop_start = int(np.searchsorted(idx, i_max))
    peak = float(np.max(np.abs(H)))
    near = lambda i: float(np.mean(B[max(i - 10, 0):i + 11]))  # noqa: E731 - B at a reversal, averaged
    span = float(np.ptp(B[i_max:]))
    asymmetry = (near(i_max) + near(i_min)) / 2.0 / span if span > 0 else 0.0
    return Record(float(temperature_C), amplitude, np.ascontiguousarray(clean[idx]), B[idx].copy(), loop_start,
                  start_magnetization(H, B, i_max, clean), peak, min(50.0, peak / 200.0), asymmetry)


#: Share of the peak field below which the start of a record counts as its initial state.
START_FIELD_SHARE = 0.05


def start_magnetization(H, B, i_max, clean=None) -> float:
    """The measured M = B/mu0 - H (A/m) the record starts from: the straight line M = M0 + chi*H
    fitted (Theil-Sen, robust to outliers) to the record's first samples, while the field stays below
    START_FIELD_SHARE of its first maximum (the foot of the initial curve, linear there by Rayleigh's
    law), taken at the first sample. ``clean`` (default ``H``) is the de-noised field the model sees:
    it sets that window and is the abscissa of the line. One sample alone carries the sampling noise
    (a spike of a few mT at the start of a 400 A/m record would act as a remanent state the model
    then carries through the whole loop)."""
    clean = H if clean is None else clean
    low = np.abs(clean[:i_max]) <= START_FIELD_SHARE * abs(clean[i_max])
    n = int(np.argmin(low)) if not low.all() else low.size
    M = B / MU0 - H
    if n < 3 or np.ptp(clean[:n]) == 0:
        return float(np.median(M[:max(n, 1)]))
    slope, intercept = theilslopes(M[:n], clean[:n])[:2]  # median-based: a spike does not tilt the line
    return float(intercept + slope * clean[0])


def load_records(path, stride=8, temperatures: Optional[Sequence[float]] = None) -> List[Record]:
    """Records of an npz laid out like ``gd_loops.npz``; raises ValueError on a bad file."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no such file: {path}")
    try:
        data = np.load(path, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - any unreadable file is a bad argument
        raise ValueError(f"cannot read {path} as npz: {exc}") from None
    with data:
        if "temperatures_C" not in data.files:
            raise ValueError(f"{path}: missing key 'temperatures_C'")
        temps = np.atleast_1d(np.asarray(data["temperatures_C"], dtype=np.float64))
        if temps.size == 0 or not np.all(np.isfinite(temps)):
            raise ValueError(f"{path}: 'temperatures_C' must be non-empty and finite")
        records = []
        for T in temps:
            if temperatures is not None and not np.any(np.isclose(T, temperatures)):
                continue
            for amp in AMPLITUDES:
                key = f"{tag_for(T)}_{amp}"
                if f"{key}_H" not in data.files or f"{key}_B" not in data.files:
                    raise ValueError(f"{path}: missing keys {key}_H / {key}_B")
                records.append(clean_record(data[f"{key}_H"], data[f"{key}_B"], T, amp, stride))
                if not np.ptp(records[-1].B[records[-1].loop_start:]) > 0:
                    raise ValueError(f"{path}: {key}_B is constant over the loop")
    return records


# --------------------------------------------------------------------------- protocol check

#: A record differs from the others of its amplitude when its value lies this far outside their range (peak
#: field: relative; start magnetization: share of the loop's half-range; closure and asymmetry: share of ptp B;
#: the drive's deviation from a sine: share of the peak field, and only above the others' range).
PROTOCOL_TOLERANCE = {"peak_field": 0.005, "start_share": 0.05, "closure": 0.02, "asymmetry": 0.02,
                      "sine_deviation": 0.01}


def record_protocol(path) -> List[dict]:
    """How each raw record of an npz laid out like ``gd_loops.npz`` was taken: its length, samples per drive
    period (twice the samples between the two reversals), peak field, the drive's RMS deviation from a sine
    of that period over the loop (share of the peak field), the start field, the start magnetization
    (:func:`start_magnetization`) as a share of the loop's own half-range of M, the loop's closure
    (B at the end minus B at the first maximum, share of ptp B) and its asymmetry."""
    rows = []
    with np.load(path, allow_pickle=False) as data:
        for T in np.atleast_1d(np.asarray(data["temperatures_C"], dtype=np.float64)):
            for amp in AMPLITUDES:
                H = np.asarray(data[f"{tag_for(T)}_{amp}_H"], dtype=np.float64)
                B = np.asarray(data[f"{tag_for(T)}_{amp}_B"], dtype=np.float64)
                i_max, i_min = reversal_indices(H)
                period = 2 * (i_min - i_max)
                loop = np.arange(i_max, H.size)
                design = np.column_stack([np.cos(2 * np.pi * (loop - i_max) / period),
                                          np.sin(2 * np.pi * (loop - i_max) / period)])
                coefficients = np.linalg.lstsq(design, H[loop], rcond=None)[0]
                peak = float(np.max(np.abs(H)))
                M = B / MU0 - H
                half_range = float(np.ptp(M[i_max:])) / 2.0
                record = clean_record(H, B, T, amp, stride=1)
                rows.append({"temperature_C": float(T), "amplitude": amp, "samples": int(H.size),
                             "samples_per_period": int(period), "peak_field": peak,
                             "sine_deviation": float(np.sqrt(np.mean((design @ coefficients - H[loop]) ** 2)) / peak),
                             "start_field": float(H[0]),
                             "start_share": start_magnetization(H, B, i_max) / half_range,
                             "closure": float((B[-1] - B[i_max]) / np.ptp(B[i_max:])),
                             "asymmetry": record.asymmetry})
    return rows


def protocol_differences(rows: Sequence[dict]) -> List[str]:
    """What differs, record by record, from the other records of the same amplitude (PROTOCOL_TOLERANCE), and
    records whose length differs from the most common one."""
    lengths = [r["samples"] for r in rows]
    common = max(set(lengths), key=lengths.count)
    notes = [f"{r['temperature_C']:+g} °C {r['amplitude']}: {r['samples']} samples ({r['samples_per_period']} per "
             f"drive period), the others {common}" for r in rows if r["samples"] != common]
    for r in rows:
        others = [o for o in rows if o["amplitude"] == r["amplitude"] and o is not r]
        for key, tolerance in PROTOCOL_TOLERANCE.items():
            values = [o[key] for o in others]
            low, high = min(values), max(values)
            scale = abs(np.median(values)) if key == "peak_field" else 1.0
            below = key != "sine_deviation" and r[key] < low - tolerance * scale
            if below or r[key] > high + tolerance * scale:
                notes.append(f"{r['temperature_C']:+g} °C {r['amplitude']}: {key} {r[key]:.4g}, the others "
                             f"{low:.4g} to {high:.4g}")
    return notes


def sampling_check(study: dict, data, stride: int, law: str) -> Dict[str, float]:
    """Whether the sampling density matters: the largest change, per amplitude, of the NRMSE of B of ``law``'s fit
    on all temperatures when the records of the common length (``study["protocol"]``) are played at half their
    samples per drive period (stride doubled), as the shorter records were taken. The model is rate
    independent, so only the field cleaning and the scoring points change."""
    lengths = [r["samples"] for r in study["protocol"]]
    common = {r["temperature_C"] for r in study["protocol"] if r["samples"] == max(set(lengths), key=lengths.count)}
    fit = next(f for f in study["fits"] if f["family"] == law and f["protocol"] == "all")
    family = FAMILIES[law]
    z = family.to_z([fit["params"][n] for n in family.names])
    scores = []
    for s in (stride, 2 * stride):
        records = load_records(data, s)
        scores.append({(r.temperature_C, r.amplitude): nrmse(r, b[:, 0])
                       for r, b in zip(records, simulate_records(records, family, z[None, :])) if b is not None})
    return {amp: max(abs(scores[1][key] - value) for key, value in scores[0].items()
                     if key[1] == amp and key[0] in common) for amp in AMPLITUDES}


def protocol_table(rows: Sequence[dict]) -> str:
    lines = ["| T (°C) | amplitude | samples | per drive period | peak field (A/m) | drive vs sine (% of peak) | "
             "start field (A/m) | start M (share of the loop's half-range) | loop closure (% of ptp B) | "
             "asymmetry (% of ptp B) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['temperature_C']:+g} | {r['amplitude']} | {r['samples']} | {r['samples_per_period']} | "
                     f"{r['peak_field']:.0f} | {100 * r['sine_deviation']:.2f} | {r['start_field']:.1f} | "
                     f"{r['start_share']:+.3f} | {100 * r['closure']:+.1f} | {100 * r['asymmetry']:+.1f} |")
    differences = protocol_differences(rows)
    lines += ["", "Records that differ from the others of their amplitude:", ""]
    lines += [f"- {d}" for d in differences] or ["- none"]
    return "\n".join(lines)


def sampling_words(change: Dict[str, float], law: str) -> str:
    changes = ", ".join(f"{100 * v:.2f} points ({a})" for a, v in change.items())
    return (f"Half the samples per drive period (the stride of every record of the common length doubled), {law} "
            f"fitted on all temperatures: the NRMSE of B changes by at most {changes}.")


# --------------------------------------------------------------------------- law families


@dataclass(frozen=True)
class LawFamily:
    """A parametrized set of temperature laws: fit coordinates, bounds and builder."""

    name: str
    description: str
    names: Tuple[str, ...]
    x0: Tuple[float, ...]
    lower: Tuple[float, ...]
    upper: Tuple[float, ...]
    log: Tuple[bool, ...]
    build: Callable[[Dict[str, float]], TemperatureLaws]
    #: the reversal-dependent pinning (``hysteresis.REVERSAL_PINNING``), rayleigh_field = kappa*k(T):
    #: kappa fixed (a number), fitted (the name of its parameter), or None for model (6)'s pinning
    rayleigh_ratio: Optional[object] = None
    #: the hysteresis model: "domain_wall" (6) (``build`` gives TemperatureLaws) or the homogenized energy
    #: model of ``hyst_gym.physics.hem`` with this interaction density (``build`` gives HEMTemperatureLaws)
    model: str = "domain_wall"

    def to_z(self, values) -> np.ndarray:
        v = np.asarray(values, dtype=np.float64)
        return np.where(self.log, np.log(np.where(self.log, v, 1.0)), v)

    def from_z(self, z) -> Dict[str, float]:
        z = np.asarray(z, dtype=np.float64)
        v = np.where(self.log, np.exp(z), z)
        return dict(zip(self.names, map(float, v)))

    def bounds_z(self):
        return self.to_z(self.lower), self.to_z(self.upper)


def _eq4(p):
    return TemperatureLaws(a=LinearInT(p["a_ref"], T_REF_K), k=Constant(p["k"]), c=Constant(p["c"]),
                           Ms=Constant(p["Ms"]), alpha=Constant(0.0))


def _eq4_critical_ms(p):
    return TemperatureLaws(a=LinearInT(p["a_ref"], T_REF_K), k=FollowsMs(p["k0"], p["n_k"]), c=Constant(p["c"]),
                           Ms=CriticalPowerLaw(p["Ms0"], GD_CURIE_K, p["beta"]), alpha=Constant(0.0))


def _critical(p):
    return TemperatureLaws(a=FollowsMs(p["a0"], p["n_a"]), k=FollowsMs(p["k0"], p["n_k"]), c=Constant(p["c"]),
                           Ms=CriticalPowerLaw(p["Ms0"], GD_CURIE_K, p["beta"]), alpha=Constant(0.0))


def _smooth(p):
    return TemperatureLaws(a=LogPolynomial((p["la0"], p["la1"], p["la2"]), T_REF_K, 10.0),
                           k=LogPolynomial((p["lk0"], p["lk1"], p["lk2"]), T_REF_K, 10.0), c=Constant(p["c"]),
                           Ms=CriticalPowerLaw(p["Ms0"], GD_CURIE_K, p["beta"]), alpha=Constant(0.0))


def _smooth_small_loop(p):
    return replace(_smooth(p), chi_r=FollowsMs(p["chi0"], p["n_chi"]))


FAMILIES = {
    "eq4": LawFamily(
        "eq4", "paper eq. (4): a = a_ref T/T_ref; Ms, k, c constant",
        ("a_ref", "k", "c", "Ms"), (4000.0, 500.0, 0.3, 1.0e6),
        (50.0, 5.0, 1e-3, 1e5), (1e5, 2e4, 0.99, 5e6), (True, True, True, True), _eq4),
    "eq4_critical_ms": LawFamily(
        "eq4_critical_ms", "a by eq. (4); Ms = Ms0 (1-T/Tc)^beta; k = k0 (Ms/Ms0)^n_k; c constant",
        ("a_ref", "k0", "n_k", "c", "Ms0", "beta"), (4000.0, 500.0, 0.0, 0.3, 2.0e6, 0.3),
        (50.0, 5.0, -4.0, 1e-3, 1e5, 0.05), (1e5, 2e4, 4.0, 0.99, 2e7, 1.5),
        (True, True, False, True, True, False), _eq4_critical_ms),
    "critical": LawFamily(
        "critical", "Ms = Ms0 (1-T/Tc)^beta; a = a0 (Ms/Ms0)^n_a; k = k0 (Ms/Ms0)^n_k; c constant",
        ("a0", "n_a", "k0", "n_k", "c", "Ms0", "beta"), (4000.0, 0.0, 500.0, 0.0, 0.3, 2.0e6, 0.3),
        (50.0, -4.0, 5.0, -4.0, 1e-3, 1e5, 0.05), (1e5, 4.0, 2e4, 4.0, 0.99, 2e7, 1.5),
        (True, False, True, False, True, True, False), _critical),
    "smooth": LawFamily(
        "smooth", "Ms = Ms0 (1-T/Tc)^beta; log a and log k quadratic in (T - T_ref)/10 K; c constant",
        ("la0", "la1", "la2", "lk0", "lk1", "lk2", "c", "Ms0", "beta"),
        (float(np.log(5000.0)), 0.0, 0.0, float(np.log(400.0)), 0.3, 0.0, 0.45, 2.3e6, 0.31),
        (float(np.log(50.0)), -3.0, -3.0, float(np.log(5.0)), -3.0, -3.0, 1e-3, 1e5, 0.05),
        (float(np.log(1e5)), 3.0, 3.0, float(np.log(2e4)), 3.0, 3.0, 0.99, 2e7, 1.5),
        (False, False, False, False, False, False, True, True, False), _smooth),
    "smooth_small_loop": LawFamily(
        "smooth_small_loop", "smooth, plus the small-loop extension: chi_r = chi0 (Ms/Ms0)^n_chi",
        ("la0", "la1", "la2", "lk0", "lk1", "lk2", "c", "Ms0", "beta", "chi0", "n_chi"),
        (float(np.log(5000.0)), 0.0, 0.0, float(np.log(400.0)), 0.3, 0.0, 0.45, 2.3e6, 0.31, 10.0, 1.0),
        (float(np.log(50.0)), -3.0, -3.0, float(np.log(5.0)), -3.0, -3.0, 1e-3, 1e5, 0.05, 1e-3, -4.0),
        (float(np.log(1e5)), 3.0, 3.0, float(np.log(2e4)), 3.0, 3.0, 0.99, 2e7, 1.5, 1e4, 4.0),
        (False, False, False, False, False, False, True, True, False, True, False), _smooth_small_loop),
    "smooth_reversal": LawFamily(
        "smooth_reversal", "smooth, plus reversal-dependent pinning: rayleigh_field = kappa k(T)",
        ("la0", "la1", "la2", "lk0", "lk1", "lk2", "c", "Ms0", "beta", "kappa"),
        (float(np.log(5000.0)), 0.0, 0.0, float(np.log(400.0)), 0.3, 0.0, 0.45, 2.3e6, 0.31, 0.5),
        (float(np.log(50.0)), -3.0, -3.0, float(np.log(5.0)), -3.0, -3.0, 1e-3, 1e5, 0.05, 1e-3),
        (float(np.log(1e5)), 3.0, 3.0, float(np.log(2e4)), 3.0, 3.0, 0.99, 2e7, 1.5, 30.0),
        (False, False, False, False, False, False, True, True, False, True), _smooth, "kappa"),
}
#: The reversal-dependent pinning with no parameter of its own: the irreversible term builds up over
#: a field change of the pinning field k(T) itself (kappa = 1).
def _hem_critical(p):
    ms = CriticalPowerLaw(p["M0"], GD_CURIE_K, p["beta"])
    return HEMTemperatureLaws(relay_magnetization=ms,
                              reversible_susceptibility=CriticalPowerLaw(p["chi0"], GD_CURIE_K, -p["gamma"]),
                              coercive_median=FollowsMs(p["Hc0"], p["n_c"]), coercive_spread=Constant(p["sigma"]),
                              interaction_scale=FollowsMs(p["b0"], p["n_b"]))


def _hem_smooth(p):
    ms = CriticalPowerLaw(p["M0"], GD_CURIE_K, p["beta"])
    return HEMTemperatureLaws(relay_magnetization=ms,
                              reversible_susceptibility=LogPolynomial((p["lx0"], p["lx1"], p["lx2"]), T_REF_K, 10.0),
                              coercive_median=LogPolynomial((p["lh0"], p["lh1"], p["lh2"]), T_REF_K, 10.0),
                              coercive_spread=Constant(p["sigma"]),
                              interaction_scale=LogPolynomial((p["lb0"], p["lb1"], p["lb2"]), T_REF_K, 10.0))


#: The homogenized energy model with critical scaling near the Curie point: the relay (spontaneous)
#: magnetization (1 - T/Tc)^beta, the pinning (coercive median and interaction scale) following it as
#: powers of the reduced magnetization, the reversible susceptibility diverging as (1 - T/Tc)^-gamma.
FAMILIES["hem_critical"] = LawFamily(
    "hem_critical", "HEM: M_R = M0 (1-T/Tc)^beta; Hc, b ~ (M_R/M0)^n; chi = chi0 (1-T/Tc)^-gamma; sigma constant",
    ("M0", "beta", "chi0", "gamma", "Hc0", "n_c", "b0", "n_b", "sigma"),
    (2.0e6, 0.3, 1.0, 1.0, 2000.0, 1.0, 5000.0, 1.0, 0.6),
    (1e5, 0.05, 1e-3, 0.0, 1.0, -4.0, 1.0, -4.0, 0.05), (2e7, 1.5, 1e3, 3.0, 1e5, 6.0, 1e5, 6.0, 3.0),
    (True, False, True, False, True, False, True, False, True), _hem_critical, model="normal")
def _hem_smooth_saturating(p):
    return replace(_hem_smooth(p), reversible_saturation=FollowsMs(p["hs0"], p["n_hs"]))


#: The same with smooth (log-quadratic in T) laws for the susceptibility and the pinning.
FAMILIES["hem_smooth"] = LawFamily(
    "hem_smooth", "HEM: M_R = M0 (1-T/Tc)^beta; log chi, log Hc, log b quadratic in (T - T_ref)/10 K; sigma constant",
    ("M0", "beta", "lx0", "lx1", "lx2", "lh0", "lh1", "lh2", "lb0", "lb1", "lb2", "sigma"),
    (2.0e6, 0.3, 0.0, 0.0, 0.0, float(np.log(1000.0)), 0.0, 0.0, float(np.log(4000.0)), 0.0, 0.0, 0.6),
    (1e5, 0.05, -8.0, -3.0, -3.0, 0.0, -3.0, -3.0, 0.0, -3.0, -3.0, 0.05),
    (2e7, 1.5, 8.0, 3.0, 3.0, float(np.log(1e5)), 3.0, 3.0, float(np.log(1e5)), 3.0, 3.0, 3.0),
    (True, False, False, False, False, False, False, False, False, False, False, True), _hem_smooth, model="normal")
#: hem_smooth with the saturating reversible part (``hem.SATURATING_REVERSIBLE``), its field scale following
#: the spontaneous magnetization, h_s = hs0 (M_R/M0)^n_hs (added after the first HEM results).
FAMILIES["hem_smooth_saturating"] = LawFamily(
    "hem_smooth_saturating", "hem_smooth + saturating reversible part, h_s = hs0 (M_R/M0)^n_hs",
    FAMILIES["hem_smooth"].names + ("hs0", "n_hs"), FAMILIES["hem_smooth"].x0 + (3.0e4, 1.0),
    FAMILIES["hem_smooth"].lower + (1e2, -4.0), FAMILIES["hem_smooth"].upper + (1e7, 6.0),
    FAMILIES["hem_smooth"].log + (True, False), _hem_smooth_saturating, model="normal")
FAMILIES["smooth_pinning"] = replace(
    FAMILIES["smooth"], name="smooth_pinning", rayleigh_ratio=1.0,
    description="smooth, plus reversal-dependent pinning over the pinning field: rayleigh_field = k(T)")


#: The law families of each ``--model``; the selection rule chooses among them.
MODEL_FAMILIES = {"domain_wall": ("eq4", "eq4_critical_ms", "critical", "smooth", "smooth_small_loop",
                                  "smooth_reversal", "smooth_pinning"),
                  "hem": ("hem_smooth", "hem_critical", "hem_smooth_saturating")}
MODEL_FAMILIES["auto"] = MODEL_FAMILIES["domain_wall"] + MODEL_FAMILIES["hem"]


# --------------------------------------------------------------------------- model and fit


def parameter_table(family: LawFamily, zs: np.ndarray, temperatures_K: np.ndarray) -> Dict[str, np.ndarray]:
    """JA parameters, each of shape (len(zs), len(temperatures_K)), for fit coordinates ``zs``."""
    out = {n: np.empty((len(zs), len(temperatures_K))) for n in ("a", "k", "c", "Ms", "alpha", "chi_r")}
    out["rayleigh_field"] = np.zeros((len(zs), len(temperatures_K)))
    for i, z in enumerate(zs):
        params = family.from_z(z)
        values = family.build(params)(temperatures_K)
        for n in PARAMETER_NAMES:
            out[n][i] = values[n]
        if family.rayleigh_ratio is not None:
            ratio = family.rayleigh_ratio
            kappa = params.get(ratio) if isinstance(ratio, str) else ratio
            out["rayleigh_field"][i] = kappa * values["k"]
    return out


def _hem_values(family: LawFamily, zs: np.ndarray, temperatures_K: np.ndarray) -> List[Optional[dict]]:
    """The HEM parameters of each row of ``zs`` at every temperature (one law call per row, vectorized over the
    temperatures); a row whose laws raise is evaluated temperature by temperature, a temperature that raises
    giving None there."""
    out = []
    for z in zs:
        law = family.build(family.from_z(z))
        try:
            values = law(temperatures_K)
            out.append([{n: v[j] for n, v in values.items()} for j in range(temperatures_K.size)])
        except ValueError:
            row = []
            for T in temperatures_K:
                try:
                    row.append({n: v[0] for n, v in law(np.array([T])).items()})
                except ValueError:
                    row.append(None)
            out.append(row)
    return out


def simulate_records_hem(records: Sequence[Record], family: LawFamily, zs: np.ndarray) -> List[Optional[np.ndarray]]:
    """:func:`simulate_records` for a HEM family: each record's bank starts at its measured M0. The laws are
    evaluated once per row of ``zs`` for all temperatures, the records of one temperature share one bank of
    parameters, and the start states of all records are solved together
    (:func:`~hyst_gym.physics.hem.states_with_magnetization`)."""
    temps = np.array(sorted({r.temperature_K for r in records}))
    values = _hem_values(family, zs, temps)
    batches: List[Optional[HEMBatch]] = []
    for j in range(temps.size):
        try:
            if any(v[j] is None for v in values):
                raise ValueError("laws undefined at this temperature")
            batches.append(HEMBatch(*(np.array([v[j][n] for v in values]) for n in HEM_PARAMETER_NAMES),
                                    family.model, HEM_NODES,
                                    np.array([v[j]["reversible_saturation"] for v in values])))
        except ValueError:
            batches.append(None)
    constants = [None if b is None else b.constants() for b in batches]
    which = [int(np.searchsorted(temps, r.temperature_K)) for r in records]
    runnable = [i for i, j in enumerate(which) if batches[j] is not None]
    states = [] if not runnable else states_with_magnetization(
        [constants[which[i]] for i in runnable], batches[which[runnable[0]]].kind,
        np.array([records[i].field[0] for i in runnable]), np.array([records[i].M0 for i in runnable]))
    out: List[Optional[np.ndarray]] = [None] * len(records)
    for i, state in zip(runnable, states):
        r = records[i]
        out[i] = MU0 * (r.field[:, None] + simulate_hem_batch(r.field, batches[which[i]], state))
    return out


def simulate_records(records: Sequence[Record], family: LawFamily, zs: np.ndarray) -> List[Optional[np.ndarray]]:
    """Model B (T) for each record and each row of ``zs``: list of arrays (n_samples, len(zs)).

    A record whose temperature gives invalid parameters (e.g. T >= Tc) yields None.
    """
    zs = np.atleast_2d(zs)
    if family.model != "domain_wall":
        return simulate_records_hem(records, family, zs)
    temps = np.array(sorted({r.temperature_K for r in records}))
    table = parameter_table(family, zs, temps)
    out = []
    for r in records:
        j = int(np.searchsorted(temps, r.temperature_K))
        try:
            batch = HysteresisBatch(*(table[n][:, j] for n in ("a", "k", "alpha", "Ms", "c")), ANHYSTERETIC,
                                    table["chi_r"][:, j], table["rayleigh_field"][:, j])
        except ValueError:
            out.append(None)
            continue
        M = simulate_batch(r.field, batch, r.M0, r.max_field_step)
        out.append(MU0 * (r.field[:, None] + M))
    return out


def nrmse(record: Record, B_model: np.ndarray) -> float:
    """RMS(B_model - B_meas)/ptp(B_meas) over the loop part (first positive peak onward)."""
    meas = record.B[record.loop_start:]
    return float(np.sqrt(np.mean((B_model[record.loop_start:] - meas) ** 2)) / np.ptp(meas))


def _scaled_residuals(records, B_models):
    parts = []
    for r, Bm in zip(records, B_models):
        meas = r.B[r.loop_start:]
        scale = np.ptp(meas) * np.sqrt(meas.size)
        parts.append((Bm[r.loop_start:] - meas[:, None]) / scale)
    return np.concatenate(parts, axis=0)


@dataclass(frozen=True)
class FitResult:
    family: str
    params: Dict[str, float]
    temperatures_C: Tuple[float, ...]
    cost: float
    nfev: int
    seconds: float  # wall clock
    success: bool
    cpu_seconds: float = float("nan")  # CPU time of this process during the fit


def fit_family(records: Sequence[Record], family: LawFamily, x0=None, max_nfev=200) -> FitResult:
    """Least-squares fit of the family's global parameters to all ``records``."""
    lo, hi = family.bounds_z()
    z0 = np.clip(family.to_z(family.x0 if x0 is None else x0), lo + 1e-9, hi - 1e-9)
    big = 1e3  # residual of a record the model cannot run (bounds should prevent it)
    n_residuals = sum(r.B.size - r.loop_start for r in records)

    def point(z):
        B = simulate_records(records, family, z[None, :])
        if any(b is None for b in B):
            return np.full(n_residuals, big)
        return _scaled_residuals(records, B)[:, 0]

    def neighbours(z):
        """The point and its forward-difference neighbours as one bank: (residuals, Jacobian or None)."""
        zs = np.repeat(z[None, :], z.size + 1, axis=0)
        steps = np.where(zs[0] + FD_STEP <= hi, FD_STEP, -FD_STEP)
        zs[1:] += np.diag(steps)
        B = simulate_records(records, family, zs)
        if any(b is None for b in B):
            return None, None
        R = _scaled_residuals(records, B)
        return R[:, 0].copy(), (R[:, 1:] - R[:, :1]) / steps

    # Domain-wall laws: the solver asks for the residuals at a trial point and, when it accepts the step
    # (nearly always), for the Jacobian there. A bank of 12 models costs about three of one in the compiled
    # kernel, so the point is simulated with its neighbours at once and the Jacobian kept for the next call.
    # Every model of a bank runs on its own: column 0 is bit for bit the point alone, so the fit takes the
    # same steps. (An HEM bank costs in proportion to its size: there a rejected step would waste it.)
    merged = family.model == "domain_wall"
    last = {}

    def fun(z):
        if not merged:
            return point(z)
        r, J = neighbours(z)
        last.update(z=z.copy(), J=J)
        return point(z) if r is None else r

    def jac(z):
        if merged and last.get("J") is not None and np.array_equal(last["z"], z):
            return last["J"]
        r, J = neighbours(z)
        return np.zeros((n_residuals, z.size)) if J is None else J

    start, cpu_start = time.perf_counter(), time.process_time()
    # BLAS on one thread: the solver's SVD of the (residuals x parameters) Jacobian is tall and thin, and with
    # two threads on a loaded 2-core machine it took 20 times longer (0.2 s instead of 9 ms per iteration)
    with threadpool_limits(limits=1, user_api="blas"):
        sol = least_squares(fun, z0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=max_nfev,
                            xtol=1e-8, ftol=1e-8)
    seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu_start
    return FitResult(family.name, family.from_z(sol.x), tuple(sorted({r.temperature_C for r in records})),
                     float(sol.cost), int(sol.nfev), seconds, bool(sol.success), cpu_seconds)


def score(records: Sequence[Record], family: LawFamily, fit: FitResult, role: str) -> List[dict]:
    z = family.to_z([fit.params[n] for n in family.names])
    B = simulate_records(records, family, z[None, :])
    rows = []
    for r, Bm in zip(records, B):
        rows.append({"law": family.name, "temperature_C": r.temperature_C, "amplitude": r.amplitude,
                     "peak_field": round(r.peak_field, 1),
                     "nrmse": None if Bm is None else round(nrmse(r, Bm[:, 0]), 5), "role": role,
                     "asymmetry": round(r.asymmetry, 4)})
    return rows


# --------------------------------------------------------------------------- study


def run_study(records: Sequence[Record], families: Sequence[str], holdouts: Sequence[float],
              predict_records: Sequence[Record] = (), max_nfev=200, floor=True, log=print) -> dict:
    """Full fit, predictions of ``predict_records`` and leave-one-out per family.

    With ``floor``, the model is also fitted at each temperature alone (five constant
    parameters, all amplitudes): the floor that no temperature law can beat.
    """
    out = {"fits": [], "rows": []}
    if floor:
        for T in sorted({r.temperature_C for r in records}):
            at_T = [r for r in records if r.temperature_C == T]
            fit = fit_family(at_T, FAMILIES["eq4"], max_nfev=max_nfev)
            out["fits"].append({**fit.__dict__, "family": "per_temperature", "protocol": f"only{T:+g}"})
            out["rows"] += [{**row, "law": "per_temperature", "protocol": "all"}
                            for row in score(at_T, FAMILIES["eq4"], fit, "fitted")]
        log("per-temperature floor fitted")
    for name in families:
        family = FAMILIES[name]
        full = fit_family(records, family, max_nfev=max_nfev)
        log(f"[{name}] fit on all {len(full.temperatures_C)} temperatures: {full.seconds:.1f} s "
            f"({full.cpu_seconds:.1f} s CPU), "
            f"nfev {full.nfev}, params " + ", ".join(f"{k}={v:.4g}" for k, v in full.params.items()))
        out["fits"].append({**full.__dict__, "protocol": "all"})
        out["rows"] += [{**row, "protocol": "all"} for row in score(records, family, full, "fitted")]
        if predict_records:
            out["rows"] += [{**row, "protocol": "predict_file"}
                            for row in score(predict_records, family, full, "predicted")]
        for T in holdouts:
            train = [r for r in records if r.temperature_C != T]
            test = [r for r in records if r.temperature_C == T]
            # from the family's own start, not from the fit that saw the left-out temperature: a fit that
            # stalls near its start would otherwise carry that temperature into its "prediction"
            fit = fit_family(train, family, max_nfev=max_nfev)
            out["fits"].append({**fit.__dict__, "protocol": f"loo{T:+g}"})
            rows = score(test, family, fit, "predicted")
            out["rows"] += [{**row, "protocol": "loo"} for row in rows]
            log(f"[{name}] leave out {T:+g} C: fit {fit.seconds:.1f} s; predicted NRMSE "
                + ", ".join(f"{r['amplitude']} {100 * r['nrmse']:.2f}%" for r in rows if r["nrmse"] is not None))
    return out


def _seconds(fit: dict) -> str:
    """Wall-clock seconds of a stored fit, its CPU seconds in parentheses where the study recorded them."""
    cpu = fit.get("cpu_seconds")
    return f"{fit['seconds']:.1f} s" + (f" ({cpu:.1f} s)" if cpu is not None and np.isfinite(cpu) else "")


def markdown_table(study: dict, families: Sequence[str]) -> str:
    rows = study["rows"]
    temps = sorted({r["temperature_C"] for r in rows if r["protocol"] in ("all", "loo")})
    lines = ["NRMSE of B (% of ptp B, loop part). `fit`: fitted on all temperatures; "
             "`LOO`: predicted with that temperature left out of the fit; `per-T floor`: the model "
             "fitted at that temperature alone (5 constant parameters, all amplitudes).", ""]
    has_floor = any(r["law"] == "per_temperature" for r in rows)
    head = ("| T (C) | amplitude | " + ("per-T floor | " if has_floor else "")
            + " | ".join(f"{f} fit | {f} LOO" for f in families) + " |")
    lines += [head, "|" + "---|" * (2 + has_floor + 2 * len(families))]

    def cell(f, T, amp, proto):
        hit = [r for r in rows if r["law"] == f and r["temperature_C"] == T and r["amplitude"] == amp
               and r["protocol"] == proto]
        return "-" if not hit or hit[0]["nrmse"] is None else f"{100 * hit[0]['nrmse']:.2f}"

    for T in temps:
        for amp in AMPLITUDES:
            lines.append(f"| {T:+g} | {amp} | " + (f"{cell('per_temperature', T, amp, 'all')} | " if has_floor else "")
                         + " | ".join(
                f"{cell(f, T, amp, 'all')} | {cell(f, T, amp, 'loo')}" for f in families) + " |")
    odd = sorted({(r["temperature_C"], r["amplitude"], r["asymmetry"]) for r in rows
                  if abs(r.get("asymmetry", 0.0)) > 0.03})
    if odd:
        lines += ["", "Measured loops that are not point-symmetric, (B(+Hmax) + B(-Hmax))/2 in % of ptp B "
                  "(the model's loops are symmetric, so this offset is a floor on their NRMSE): "
                  + ", ".join(f"{T:+g} C {amp} {100 * a:+.1f} %" for T, amp, a in odd)]
    lines += ["", "Worst leave-one-out NRMSE per amplitude (targets: major <= 2 %, mid and minor <= 8 %):", ""]
    lines += ["| law | major | mid | minor |", "|---|---|---|---|"]
    for f in families:
        worst = []
        for amp in AMPLITUDES:
            vals = [r["nrmse"] for r in rows if r["law"] == f and r["amplitude"] == amp and r["protocol"] == "loo"
                    and r["nrmse"] is not None]
            worst.append(f"{100 * max(vals):.2f}" if vals else "-")
        lines.append(f"| {f} | " + " | ".join(worst) + " |")
    floor_fits = [f for f in study["fits"] if f["family"] == "per_temperature"]
    if floor_fits:
        lines += ["", "Per-temperature floor fits: the model's own parameters at each temperature "
                  "(eq. (4) predicts a constant a/T):", "",
                  "| T (C) | a (A/m) | a/T (A/m/K) | k (A/m) | c | Ms (A/m) |", "|---|---|---|---|---|---|"]
        for f in floor_fits:
            T_C = f["temperatures_C"][0]
            a = f["params"]["a_ref"] * float(celsius_to_kelvin(T_C)) / T_REF_K
            lines.append(f"| {T_C:+g} | {a:.0f} | {a / float(celsius_to_kelvin(T_C)):.2f} | {f['params']['k']:.0f} | "
                         f"{f['params']['c']:.3f} | {f['params']['Ms']:.4g} |")
    lines += ["", f"Fits (seconds wall clock, CPU, function evaluations, parameters); whole study "
              f"{study.get('total_seconds', float('nan')):.1f} s"
              + (f" ({study['total_cpu_seconds']:.1f} s CPU)" if "total_cpu_seconds" in study else "")
              + " in one process:", ""]
    for fit in study["fits"]:
        lines.append(f"- {fit['family']} / {fit['protocol']}: {_seconds(fit)}, nfev {fit['nfev']}, "
                     + ", ".join(f"{k}={v:.4g}" for k, v in fit["params"].items()))
    return "\n".join(lines) + "\n"


#: What each law family is, in the words of the README's summary table.
FAMILY_LABELS = {
    "eq4": "eq. (4) alone, constant Ms (the paper's model)",
    "eq4_critical_ms": "eq. (4) for a, critical power-law Ms, k following Ms",
    "critical": "a and k following Ms",
    "smooth": "smooth laws for a and k, power-law Ms",
    "smooth_small_loop": "smooth laws + small-loop extension (chi_r following Ms)",
    "smooth_reversal": "smooth laws + reversal-dependent pinning (rayleigh_field = kappa k, kappa fitted)",
    "smooth_pinning": "smooth laws + reversal-dependent pinning (rayleigh_field = k, no new parameter)",
    "hem_critical": "HEM, critical scaling: M_R ~ (1-T/Tc)^beta, pinning ~ M_R^n, chi ~ (1-T/Tc)^-gamma",
    "hem_smooth": "HEM, M_R ~ (1-T/Tc)^beta, smooth laws for chi and the pinning",
    "hem_smooth_saturating": "HEM, smooth laws + saturating reversible part, h_s ~ M_R^n",
}


#: The accuracy a held-out temperature must reach at every amplitude (NRMSE of B).
NEAR_TC_TARGET = 0.08


def loo_temperatures(study: dict) -> Tuple[List[float], Optional[float]]:
    """(interior left-out temperatures, the warmest left-out one if it is the top of the range, else None)."""
    rows = study["rows"]
    shipped = sorted({r["temperature_C"] for r in rows if r["protocol"] == "all"})
    left_out = sorted({r["temperature_C"] for r in rows if r["protocol"] == "loo"})
    interior = [T for T in left_out if shipped and shipped[0] < T < shipped[-1]]
    return interior, (shipped[-1] if shipped and shipped[-1] in left_out else None)


def _loo(rows, law, temperatures, amplitude=None):
    return [r for r in rows if r["law"] == law and r["protocol"] == "loo" and r["nrmse"] is not None
            and r["temperature_C"] in temperatures and (amplitude is None or r["amplitude"] == amplitude)]


def selection_scores(study: dict, families: Sequence[str]) -> Dict[str, float]:
    """The rule's score of each law: mean held-out NRMSE over the interior temperatures and every amplitude."""
    interior, _ = loo_temperatures(study)
    scores = {f: [r["nrmse"] for r in _loo(study["rows"], f, interior)] for f in families}
    return {f: float(np.mean(v)) for f, v in scores.items() if v}


def _fold_cells(rows, law, temperature) -> str:
    values = {r["amplitude"]: r["nrmse"] for r in _loo(rows, law, [temperature])}
    return " / ".join(f"{100 * values[a]:.1f}" if a in values else "-" for a in AMPLITUDES)


def near_tc_words(study: dict, families: Sequence[str]) -> List[str]:
    """Where no law predicts within NEAR_TC_TARGET: per fold near Tc (the warmest interior temperature and the
    extrapolated warmest) and amplitude, the laws within the target or, where none is, the best one."""
    interior, warmest = loo_temperatures(study)
    lines = []
    for T, what in ((interior[-1] if interior else None, "the near-Tc test, inside the range"),
                    (warmest, "the extrapolation towards Tc, not read by the rule")):
        if T is None:
            continue
        parts = []
        for amp in AMPLITUDES:
            scored = sorted((r["nrmse"], f) for f in families for r in _loo(study["rows"], f, [T], amp))
            if not scored:
                continue
            good = [f for v, f in scored if v <= NEAR_TC_TARGET]
            if good:
                parts.append(f"{amp}: {len(good)} of {len(scored)} laws within {100 * NEAR_TC_TARGET:.0f} % "
                             f"(best {scored[0][1]}, {100 * scored[0][0]:.1f} %)")
            else:
                parts.append(f"{amp}: **no law within {100 * NEAR_TC_TARGET:.0f} %** (best {scored[0][1]}, "
                             f"{100 * scored[0][0]:.1f} %)")
        tc_distance = GD_CURIE_K - float(celsius_to_kelvin(T))
        lines.append(f"- {T:+g} °C ({tc_distance:.1f} K below Tc; {what}): " + "; ".join(parts) + ".")
    return lines


def summary_table(study: dict, families: Sequence[str]) -> str:
    """The full summary (results.md): :func:`page_section`, then each left-out temperature of the chosen law and
    the best law of the other model, the fit times' load, the protocol table of every record and the sampling
    check."""
    lines = [page_section(study, families, brief=False)]
    load = study.get("load_average", float("nan"))
    lines.append(f"\nNRMSE of B in %. Fit times: wall clock (CPU), one process on {os.cpu_count()} cores at 1-min load "
                 f"average {load:.1f}.")
    if study.get("protocol"):
        lines += ["", "How the records were taken (`record_protocol`, from the raw records):", "",
                  protocol_table(study["protocol"])]
    if study.get("sampling_check"):
        lines += ["", sampling_words(*study["sampling_check"])]
    return "\n".join(lines)


def page_section(study: dict, families: Sequence[str], brief: bool = True) -> str:
    """Results-page section: per law, the worst held-out NRMSE of B (%) over the interior temperatures per
    amplitude (with where it occurs), the rule's score (interior mean), the near-Tc fold (+5 C) and the
    extrapolated warmest fold, and the fit time on all temperatures; then the choice and the near-Tc words.
    ``brief`` (the page): then the records that differ from the others and the sampling check, the full tables
    being in results.md; else (``summary_table``) each left-out temperature of the chosen law and the best of
    the other model."""
    rows = study["rows"]
    interior, warmest = loo_temperatures(study)
    near = interior[-1] if interior else None
    peaks = {amp: np.median([r["peak_field"] for r in rows if r["amplitude"] == amp]) for amp in AMPLITUDES}
    scores = selection_scores(study, families)
    lines = ["| law | " + " | ".join(f"{amp} (≈ {peaks[amp]:.3g} A/m)" for amp in AMPLITUDES)
             + " | interior mean (the rule) | " + (f"{near:+g} °C fold, near Tc | " if near is not None else "")
             + (f"{warmest:+g} °C, extrapolated | " if warmest is not None else "") + "fit on all temperatures (CPU) |",
             "|---|" + "---|" * (len(AMPLITUDES) + 2 + (near is not None) + (warmest is not None))]
    for f in families:
        full = [fit for fit in study["fits"] if fit["family"] == f and fit["protocol"] == "all"]
        cells = []
        for amp in AMPLITUDES:
            loo = sorted((r["nrmse"], r["temperature_C"]) for r in _loo(rows, f, interior, amp))
            cells.append(f"{100 * loo[-1][0]:.2f} ({loo[-1][1]:+g} °C)" if loo else "-")
        cells.append(f"{100 * scores[f]:.2f}" if f in scores else "-")
        cells += [_fold_cells(rows, f, T) for T in (near, warmest) if T is not None]
        cells.append(_seconds(full[0]) if full else "-")
        lines.append(f"| {FAMILY_LABELS.get(f, f)} | " + " | ".join(cells) + " |")
    listed = ", ".join(f"{T:+g}" for T in interior)
    lines.append(f"\nWorst held-out NRMSE of B (%) over the interior temperatures ({listed} °C) per amplitude; the "
                 "folds near Tc give major / mid / minor.")
    if scores:
        chosen = min(scores, key=scores.get)
        lines.append(f"\nLowest mean held-out error over the interior temperatures and every amplitude (the selection "
                     f"rule): **{FAMILY_LABELS.get(chosen, chosen)}** ({100 * scores[chosen]:.2f} %).")
        lines += ["", "Where the laws predict near Tc, and where none does (target "
                  f"{100 * NEAR_TC_TARGET:.0f} % at every amplitude):", ""] + near_tc_words(study, families)
        # beside it, the best law of the other model (domain wall or HEM), for comparison
        other_model = [f for f in scores if FAMILIES[f].model != FAMILIES[chosen].model]
        compared = [chosen] + ([min(other_model, key=scores.get)] if other_model else [])
        if not brief:
            lines += ["", "Each left-out temperature, the chosen law and the best of the other model:", "",
                      per_temperature_table(study, compared)]
    if brief:
        load = study.get("load_average", float("nan"))
        lines.append(f"\nFit times: wall clock (CPU), one process at 1-min load average {load:.1f}. Every temperature "
                     "and amplitude, and how each record was taken: `experiments/results/gd_temperature/results.md`.")
        if study.get("protocol"):
            lines += ["", "Records that differ from the others of their amplitude (`record_protocol`):", ""]
            lines += [f"- {d}" for d in protocol_differences(study["protocol"])] or ["- none"]
        if study.get("sampling_check"):
            lines += ["", sampling_words(*study["sampling_check"])]
    return "\n".join(lines)


def per_temperature_table(study: dict, families: Sequence[str]) -> str:
    """Held-out NRMSE of B (%) at every left-out temperature and amplitude, one column pair per family,
    with each temperature's distance below the Curie point and the fit time of that fold."""
    rows = study["rows"]
    temps = sorted({r["temperature_C"] for r in rows if r["protocol"] == "loo"})
    head = "| left out (°C) | Tc − T (K) | " + " | ".join(
        f"{f}: {amp}" for f in families for amp in AMPLITUDES) + " | " + " | ".join(f"{f}: fit time" for f in families)
    lines = [head + " |", "|---|---|" + "---|" * (len(families) * (len(AMPLITUDES) + 1))]
    for T in temps:
        cells = []
        for f in families:
            for amp in AMPLITUDES:
                hit = [r["nrmse"] for r in rows if r["law"] == f and r["temperature_C"] == T and r["amplitude"] == amp
                       and r["protocol"] == "loo" and r["nrmse"] is not None]
                cells.append(f"{100 * hit[0]:.2f}" if hit else "-")
        times = [next((f"{x['seconds']:.1f} s" for x in study["fits"] if x["family"] == f
                       and x["protocol"] == f"loo{T:+g}"), "-") for f in families]
        lines.append(f"| {T:+g} | {GD_CURIE_K - float(celsius_to_kelvin(T)):.1f} | " + " | ".join(cells + times) + " |")
    return "\n".join(lines)


def make_figure(records, study, families, held_out_T, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(18, 4.2))
    test = [r for r in records if r.temperature_C == held_out_T]
    colors = {"eq4": "tab:red", "eq4_critical_ms": "tab:orange", "critical": "tab:blue", "smooth": "tab:green",
              "smooth_small_loop": "tab:olive", "smooth_reversal": "tab:purple", "smooth_pinning": "tab:brown",
              "hem_critical": "tab:cyan", "hem_smooth": "tab:pink", "hem_smooth_saturating": "tab:gray"}
    for ax, r in zip(axes[:3], test):
        ax.plot(r.field[r.loop_start:] / 1e3, r.B[r.loop_start:], "k-", lw=2.5, alpha=0.35, label="measured")
        for f in families:
            fit = next(x for x in study["fits"] if x["family"] == f and x["protocol"] == f"loo{held_out_T:+g}")
            family = FAMILIES[f]
            z = family.to_z([fit["params"][n] for n in family.names])
            Bm = simulate_records([r], family, z[None, :])[0]
            if Bm is not None:
                ax.plot(r.field[r.loop_start:] / 1e3, Bm[r.loop_start:, 0], "-", lw=1, color=colors.get(f),
                        label=f"{f} ({100 * nrmse(r, Bm[:, 0]):.1f} %)")
        ax.set_title(f"{held_out_T:+g} C held out, {r.amplitude}")
        ax.set_xlabel("H (kA/m)")
        ax.set_ylabel("B (T)")
        ax.legend(fontsize=7)
    ax = axes[3]
    for f in families:
        for amp, style in zip(AMPLITUDES, ("o-", "s--", "^:")):
            pts = sorted((r["temperature_C"], r["nrmse"]) for r in study["rows"]
                         if r["law"] == f and r["amplitude"] == amp and r["protocol"] == "loo"
                         and r["nrmse"] is not None)
            if pts:
                ax.plot(*zip(*[(t, 100 * v) for t, v in pts]), style, color=colors.get(f), ms=4,
                        label=f"{f} {amp}")
    ax.axhline(2, color="k", lw=0.5)
    ax.axhline(8, color="k", lw=0.5, ls="--")
    ax.set_yscale("log")
    ax.set_xlabel("held-out temperature (C)")
    ax.set_ylabel("predicted NRMSE of B (%)")
    ax.set_title("leave-one-out prediction")
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------- CLI


def build_parser():
    p = argparse.ArgumentParser(prog="python -m experiments.gd_temperature",
                                description="Fit temperature laws of the JA model to gadolinium loops.")
    p.add_argument("--data", default=str(DEFAULT_DATA), help="npz of loops to fit (default: the shipped one)")
    p.add_argument("--predict", default=None, help="npz of other temperatures to predict from the full fit")
    p.add_argument("--json", default=None, help="write the per temperature/amplitude rows here")
    p.add_argument("--quick", action="store_true", help="coarser subsampling, two laws, fewer hold-outs")
    p.add_argument("--model", choices=sorted(MODEL_FAMILIES), default="auto",
                   help="laws of the domain-wall model (6), of the homogenized energy model, or both (default)")
    p.add_argument("--from-results", default=None, metavar="JSON",
                   help="rebuild the tables from a study written before (results.json), without fitting")
    p.add_argument("--page", action="store_true",
                   help="with --from-results: rewrite the gd-summary section of docs/results/real-loops.md and the "
                   "tables beside the JSON (.md) from the stored study (its protocol and sampling checks as stored)")
    p.add_argument("--no-artifacts", action="store_true",
                   help="do not write experiments/results/gd_temperature or docs/figures/gd_temperature")
    return p


def bad_input(problem) -> None:
    """Bad input: one line on stderr, exit status 2."""
    print(f"gd_temperature: error: {problem}", file=sys.stderr)
    raise SystemExit(2)


def rebuild_tables(args, families) -> int:
    """``--from-results JSON``: the tables of a study written before, rebuilt with this version's summary (the
    selection rule, the near-Tc words, the protocol check of ``--data``), printed; nothing is fitted."""
    try:
        study = json.loads(Path(args.from_results).read_text())
        if args.page:
            from experiments.report_markdown import update_readme

            families = [f for f in families if any(r["law"] == f for r in study["rows"])]
            update_readme(PAGE, page_section(study, families), area="gd-summary")
            tables = Path(args.from_results).with_suffix(".md")
            tables.write_text(markdown_table(study, families) + "\n" + summary_table(study, families) + "\n")
            print(f"rewrote the gd-summary section of {PAGE} and {tables}")
            return 0
        study["protocol"] = record_protocol(args.data)
        stride = study.get("settings", {}).get("stride", 6)
        chosen = min(selection_scores(study, families).items(), key=lambda item: item[1])[0]
        study["sampling_check"] = (sampling_check(study, args.data, stride, chosen), chosen)
    except (OSError, ValueError, KeyError) as exc:
        bad_input(f"--from-results {args.from_results}: {exc}")
    families = [f for f in families if any(r["law"] == f for r in study["rows"])]
    print(markdown_table(study, families) + "\n" + summary_table(study, families))
    return 0


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    stride = 16 if args.quick else 6
    if args.page and not args.from_results:
        bad_input("--page rewrites the page from a stored study: give --from-results JSON")
    try:
        records = load_records(args.data, stride)
        predict_records = load_records(args.predict, stride) if args.predict else []
    except ValueError as exc:
        bad_input(exc)
    temps = sorted({r.temperature_C for r in records})
    if len(temps) < 3:
        bad_input(f"--data needs at least 3 temperatures, got {len(temps)}")
    interior = temps[1:-1]
    families = MODEL_FAMILIES[args.model]
    if args.from_results:
        return rebuild_tables(args, families)
    if args.quick:  # the paper's law and one smooth law of each model asked for
        families = tuple(f for f in ("eq4", "smooth", "hem_smooth") if f in families)[:2]
    # every interior temperature, and the warmest (nearest the Curie point: an extrapolation towards Tc)
    holdouts = interior[::2] if args.quick else interior + temps[-1:]
    start, cpu_start = time.perf_counter(), time.process_time()
    study = run_study(records, families, holdouts, predict_records, max_nfev=60 if args.quick else 200)
    study["total_seconds"] = time.perf_counter() - start
    study["total_cpu_seconds"] = time.process_time() - cpu_start
    study["load_average"] = os.getloadavg()[0]
    study["protocol"] = record_protocol(args.data)
    chosen = min(selection_scores(study, families).items(), key=lambda item: item[1])[0]
    study["sampling_check"] = (sampling_check(study, args.data, stride, chosen), chosen)
    study["settings"] = {"stride": stride, "anhysteretic": ANHYSTERETIC, "alpha": 0.0, "Tc_K": GD_CURIE_K,
                         "T_ref_K": T_REF_K, "score": "NRMSE of B over the loop part (first positive peak on)",
                         "data": str(args.data), "predict": args.predict, "quick": bool(args.quick)}
    print(f"total {study['total_seconds']:.1f} s ({study['total_cpu_seconds']:.1f} s CPU)")
    table = markdown_table(study, families) + "\n" + summary_table(study, families) + "\n"
    print(table)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(study["rows"], indent=1))
    if not args.no_artifacts:
        RESULTS_DIR.mkdir(parents=True, exist_ok=True)
        suffix = "_quick" if args.quick else ""
        (RESULTS_DIR / f"results{suffix}.json").write_text(json.dumps(study, indent=1, default=float))
        (RESULTS_DIR / f"results{suffix}.md").write_text(table)
        if (not args.quick and args.model == "auto" and Path(args.data).resolve() == DEFAULT_DATA.resolve()
                and not args.predict):
            from experiments.report_markdown import update_readme

            update_readme(PAGE, page_section(study, families), area="gd-summary")
        held = holdouts[-1] if holdouts else temps[0]  # the held-out temperature nearest Tc
        if holdouts:
            make_figure(records, study, families, held, FIGURES_DIR / f"gd_temperature{suffix}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
