"""The next experiment: a drive that separates the hypotheses one record left standing.

When a diagnosis cannot decide (a tie, a low confidence, a direction the record leaves open), a lab can run
one more test. :func:`design_next_drive` designs its drive: the field H(t) that maximizes the smallest
predicted separation between the hypotheses still standing, each with its parameters as fitted, within
what the recorded drives already did (:class:`DriveLimits`).

Which hypotheses stand (:func:`standing_hypotheses`):

* the tied candidates of an ``ambiguous`` verdict;
* the best candidate and its runner-up, when the confidence is below ``CONFIDENT``;
* the base model (``none``) against the best effect, when the verdict is ``none`` or a direction of the base
  model is unidentified.

A confident single name (confidence >= ``CONFIDENT``, no open direction) leaves nothing to design.

The drive is parametrized so that every admissible limit holds by construction (:meth:`DriveLimits.project`):
``SEGMENTS`` equal segments, each a sine at its own rate, amplitude and offset (rates separate an input lag
from a sensor lag; amplitudes and offsets separate static maps), clipped to the largest recorded |field|,
opened by a frame pulse to the largest recorded |field| and back (the static input map's frame is a
record's largest |field|), then passed through a slew-rate limiter at the largest recorded slew, then the part
after the pulse scaled down (if needed) so that the mean square field over any window of
``HEATING_WINDOW_SHARE`` of the record stays at or below the largest such value of the records. Scaling down
keeps the first two limits.

The separation of two hypotheses on a drive is the mean square of the difference of their predicted outputs,
each channel divided by its noise level (the first record's), channels concatenated: in units of the noise
power. The decision's tie rule (:func:`.decide.tied_with`) calls two predictions materially different when
that mean square reaches ``MATERIAL_SHARE`` on one of ``TIE_BLOCKS`` blocks of the held-out block; the
design reports, per pair, the whole-drive separation and that held-out block maximum, and says when no drive
it found reaches the bar. The predictions keep each hypothesis's fitted parameters: a refit on the new
record can absorb part of a predicted difference, so a separation above the bar is necessary, not sufficient.

The search is a scrambled Sobol design of ``DESIGN_POINTS`` drives plus a bounded Powell refinement of the
best (``REFINE_EVALUATIONS`` evaluations at most), with a fixed seed: the same report and seed give the
same drive. Neither stops on the clock, so the result does not depend on the machine's load.
"""

from __future__ import annotations

import csv
import itertools
import time as _time
from dataclasses import dataclass, field as dataclass_field
from pathlib import Path

import numpy as np
import scipy.optimize
from numba import njit
from scipy.stats import qmc
from threadpoolctl import threadpool_limits

from .decide import MATERIAL_SHARE, TIE_BLOCKS
from .model import Model, channel_range
from .recording import Recording

#: Confidence at or above which a single name needs no next experiment.
CONFIDENT = 0.8
#: Window of the heating limit, as a share of the first record's length: the mean square field over any
#: window this long stays within the records' largest. A coil's thermal time is seconds to minutes, longer
#: than most records, so a window of a tenth of the record is a conservative stand-in for it.
HEATING_WINDOW_SHARE = 0.1
#: Segments of the designed drive, each with its own rate, amplitude and offset.
SEGMENTS = 4
#: Sobol points of the global search, and the most evaluations of the local refinement. At 20,000 samples
#: and two hypotheses one evaluation takes about 40 ms on a loaded 2-core machine: about 5 s in all.
DESIGN_POINTS = 64
REFINE_EVALUATIONS = 80
#: Fastest and slowest segment rates, in cycles per segment and as a share of the sample rate.
MIN_CYCLES = 1.0
MAX_RATE_SHARE = 0.1


@dataclass(frozen=True)
class DriveLimits:
    """What the recorded drives already did: the largest |field| (``peak``, A/m), the largest slew
    (``slew``, A/m/s), the largest mean square field over ``window`` samples (``heating``, (A/m)^2)."""

    peak: float
    slew: float
    heating: float
    window: int

    @classmethod
    def of(cls, recordings, window: int) -> "DriveLimits":
        """The limits over ``recordings`` (each a :class:`Recording`), the heating over ``window`` samples."""
        peak = max(float(np.max(np.abs(r.field))) for r in recordings)
        slew = max(float(np.max(np.abs(np.diff(r.field)) / np.diff(r.time))) for r in recordings)
        heating = max(float(np.max(windowed_mean_square(r.field, window))) for r in recordings)
        return cls(peak, slew, heating, int(window))

    def project(self, raw: np.ndarray, time: np.ndarray, sign: float = 1.0) -> np.ndarray:
        """``raw`` (A/m) made admissible: clipped to ``peak``, slew-limited at ``slew``, scaled into ``heating``.

        The drive opens with a frame pulse: a ramp at the largest slew from 0 to ``sign*peak`` and back to 0,
        so that it reaches the records' largest |field| whatever the scaling of the rest. Why: the static input
        map's frame is the record's largest |field| (:func:`.effects.mapped_field`), so one map's coefficients
        mean the same map only on drives with the same peak. The rest (after the pulse) is scaled down, if
        needed, until every window's mean square is within ``heating``; when the pulse alone breaks it, there
        is no pulse and the whole drive is scaled (:meth:`keeps_frame` is then false)."""
        raw = np.clip(np.asarray(raw, dtype=np.float64), -self.peak, self.peak)
        max_steps = np.ascontiguousarray(np.diff(time)) * self.slew
        ramp = int(np.ceil(self.peak / max(float(np.min(max_steps)), 1e-300)))
        length = 2 * ramp + 3
        if length < raw.size // 2:
            framed = raw.copy()
            framed[0] = 0.0
            framed[1:ramp + 2] = np.sign(sign or 1.0) * self.peak
            framed[ramp + 2:length] = 0.0
            limited = _slew_limited(framed, max_steps)
            pulse, rest = limited[:length], limited[length:]
            if float(np.max(windowed_mean_square(np.concatenate([pulse, 0.0 * rest]), self.window))) <= self.heating:
                return np.concatenate([pulse, rest * self._largest_scale(pulse, rest)])
        limited = _slew_limited(raw, max_steps)
        return limited * self._largest_scale(limited[:0], limited)

    def _largest_scale(self, fixed: np.ndarray, scaled: np.ndarray) -> float:
        """The largest factor in [0, 1] on ``scaled`` (after ``fixed``) that keeps every window's mean square
        within ``heating``: 1 if it already does, else by bisection (the mean square grows with the factor).
        A factor below 1 keeps |field| <= peak and the slew, as ``fixed`` ends at 0 where it joins."""
        def worst(factor):
            return float(np.max(windowed_mean_square(np.concatenate([fixed, factor * scaled]), self.window)))

        if worst(1.0) <= self.heating:
            return 1.0
        low, high = 0.0, 1.0
        for _ in range(40):
            middle = 0.5 * (low + high)
            low, high = (middle, high) if worst(middle) <= self.heating else (low, middle)
        return low

    def keeps_frame(self, field: np.ndarray) -> bool:
        """Whether ``field`` reaches the records' largest |field| (the static input map's frame)."""
        return bool(np.max(np.abs(field)) >= self.peak * (1 - 1e-9))

    def violations(self, field: np.ndarray, time: np.ndarray) -> list:
        """Which limits ``field`` (A/m, sampled at ``time``) breaks, in words (empty: admissible)."""
        out = []
        tolerance = 1e-9
        if np.max(np.abs(field)) > self.peak * (1 + tolerance):
            out.append(f"|field| reaches {np.max(np.abs(field)):.6g} A/m, above {self.peak:.6g}")
        # a step is the difference of two values of up to |peak|: rounding alone can move it by a few ulp(peak)
        rounding = 8 * np.finfo(np.float64).eps * max(self.peak, float(np.max(np.abs(field))))
        slew = float(np.max((np.abs(np.diff(field)) - rounding) / np.diff(time)))
        if slew > self.slew * (1 + tolerance):
            out.append(f"slew reaches {slew:.6g} A/m/s, above {self.slew:.6g}")
        heating = float(np.max(windowed_mean_square(field, self.window)))
        if heating > self.heating * (1 + tolerance):
            out.append(f"windowed mean square field reaches {heating:.6g} (A/m)^2, above {self.heating:.6g}")
        return out

    def to_json(self) -> dict:
        return {"peak_field_A_per_m": self.peak, "slew_A_per_m_per_s": self.slew,
                "heating_mean_square_A2_per_m2": self.heating, "heating_window_samples": self.window}


def windowed_mean_square(field: np.ndarray, window: int) -> np.ndarray:
    """Mean of field^2 over every window of ``window`` consecutive samples (all samples if fewer)."""
    squares = np.asarray(field, dtype=np.float64) ** 2
    window = max(1, min(int(window), squares.size))
    cumulative = np.concatenate([[0.0], np.cumsum(squares)])
    return (cumulative[window:] - cumulative[:-window]) / window


@njit(cache=True, nogil=True)
def _slew_limited(target, max_steps):
    """Follow ``target`` with steps no larger than ``max_steps`` (A/m per sample step); stays within the
    target's range, since each step moves toward the target."""
    out = np.empty_like(target)
    out[0] = target[0]
    for i in range(1, target.size):
        step = target[i] - out[i - 1]
        bound = max_steps[i - 1]
        if step > bound:
            step = bound
        elif step < -bound:
            step = -bound
        out[i] = out[i - 1] + step
    return out


@dataclass(frozen=True)
class Hypothesis:
    """One hypothesis still standing: a name (an effect, or ``none`` for the base model) and its fit."""

    name: str
    model: Model
    values: dict

    def predict(self, recording: Recording) -> dict:
        """Its predicted output channels on ``recording`` (another drive), with its parameters as fitted."""
        model = Model(recording, self.model.structure, self.model.parameters, self.model.max_field_step)
        with np.errstate(over="ignore", invalid="ignore"):
            return model.predict(self.values)


def standing_hypotheses(report) -> list:
    """The hypotheses a report leaves standing (module docstring); empty for a confident single name."""
    ranked = sorted([c for c in report.candidates if c.failure is None], key=lambda c: -c.improvement)
    base = Hypothesis("none", report.baseline.model, report.baseline.values)
    chosen = []
    if report.verdict == "ambiguous":
        chosen = list(report.tied)
    elif report.chosen is not None and report.confidence < CONFIDENT:
        runner = [c for c in ranked if c is not report.chosen][:1]
        chosen = [report.chosen] + runner
    elif report.verdict == "unexplained":
        chosen = ranked[:2]
    out = [Hypothesis(c.effect, c.fit.model, c.fit.values) for c in chosen]
    open_direction = bool((report.identifiability or {}).get("unidentified"))
    if (report.verdict == "none" or open_direction) and ranked:
        best = report.chosen if report.chosen is not None else ranked[0]
        if all(h.name != best.effect for h in out):
            out.insert(0, Hypothesis(best.effect, best.fit.model, best.fit.values))
        out.append(base)
    return out if len(out) >= 2 else []


@dataclass
class NextDrive:
    """A designed drive (``time`` s, ``field`` A/m), the hypotheses it separates and each pair's predicted
    separation (noise power units, module docstring)."""

    time: np.ndarray
    field: np.ndarray
    hypotheses: list
    pairs: list
    limits: DriveLimits
    seconds: float
    evaluations: int
    notes: list = dataclass_field(default_factory=list)

    @property
    def smallest_separation(self) -> float:
        return min(p["separation"] for p in self.pairs)

    def write_csv(self, path) -> Path:
        """The drive as CSV ``time,field`` (s, A/m), 17 significant digits."""
        path = Path(path)
        with open(path, "w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(["time", "field"])
            writer.writerows((f"{t:.17g}", f"{h:.17g}") for t, h in zip(self.time, self.field))
        return path

    def to_json(self) -> dict:
        return {"hypotheses": self.hypotheses, "pairs": self.pairs, "limits": self.limits.to_json(),
                "samples": int(self.time.size), "seconds": self.seconds, "evaluations": self.evaluations,
                "separation_units": "mean square of the difference of two hypotheses' predicted outputs, each "
                                    "channel over its noise level (1 = the noise power)",
                "material_share": MATERIAL_SHARE, "notes": self.notes}

    def words(self) -> str:
        """One paragraph: which hypotheses, each pair's separation and whether it reaches the bar."""
        parts = []
        for p in self.pairs:
            verdict = "separable" if p["material"] else "NOT separable by any drive the design found"
            parts.append(f"{p['pair'][0]} vs {p['pair'][1]}: {p['separation']:.3g} of the noise power over the "
                         f"drive, up to {p['heldout_block_max']:.3g} on a held-out block (bar {MATERIAL_SHARE}; "
                         f"the first drive gives {p['first_drive']:.3g}) -- {verdict}")
        return "Next drive separates " + ", ".join(self.hypotheses) + ": " + "; ".join(parts) + "." + (
            " " + " ".join(self.notes) if self.notes else "")


class _Designer:
    """Maps a point of the unit cube to an admissible drive and scores it against the hypotheses."""

    def __init__(self, hypotheses, first: Recording, limits: DriveLimits, noise: dict, holdout_from: int):
        self.hypotheses = hypotheses
        self.first = first
        self.limits = limits
        self.noise = noise
        self.time = first.time
        self.holdout_from = holdout_from
        self.channels = hypotheses[0].model.channels
        self.evaluations = 0
        # the frame pulse goes to the side where the first record reaches its largest |field|
        self.sign = float(np.sign(first.field[np.argmax(np.abs(first.field))]))
        n = self.time.size
        self.edges = np.linspace(0, n, SEGMENTS + 1).astype(int)
        dt = float(np.median(np.diff(self.time)))
        segment_seconds = (n / SEGMENTS) * dt
        self.rate_range = (MIN_CYCLES / segment_seconds, MAX_RATE_SHARE / dt)
        # the outputs of a prediction record are placeholders: they carry the first record's channel range,
        # the frame of the sensor-map coefficients (model.channel_range), and are never compared with anything
        self.placeholders = {ch: np.linspace(*_range(first.output(ch)), n) for ch in first.channels}

    def drive(self, point: np.ndarray) -> np.ndarray:
        lo, hi = np.log(self.rate_range[0]), np.log(self.rate_range[1])
        raw = np.empty(self.time.size)
        for k in range(SEGMENTS):
            rate_unit, amplitude_unit, offset_unit = point[3 * k: 3 * k + 3]
            a, b = self.edges[k], self.edges[k + 1]
            t = self.time[a:b] - self.time[a]
            rate = np.exp(lo + rate_unit * (hi - lo))
            amplitude = self.limits.peak * (0.1 + 0.9 * amplitude_unit)
            offset = self.limits.peak * 0.8 * (2.0 * offset_unit - 1.0)
            raw[a:b] = offset + amplitude * np.sin(2 * np.pi * rate * t)
        return self.limits.project(raw, self.time, self.sign)

    def record(self, field: np.ndarray) -> Recording:
        return Recording(time=self.time[:field.size], field=field, metadata=dict(self.first.metadata),
                         source="designed drive", **{ch: v[:field.size] for ch, v in self.placeholders.items()})

    def separations(self, field: np.ndarray) -> list:
        """Per pair: (whole-drive mean square difference, largest held-out block mean square), noise units."""
        self.evaluations += 1
        recording = self.record(field)
        predictions = [h.predict(recording) for h in self.hypotheses]
        out = []
        for i, j in itertools.combinations(range(len(self.hypotheses)), 2):
            difference = np.concatenate([(predictions[i][ch] - predictions[j][ch]) / self.noise[ch]
                                         for ch in self.channels])
            squares = np.nan_to_num(difference ** 2, nan=np.inf)
            held = np.concatenate([squares[c * field.size:(c + 1) * field.size][self.holdout_from:]
                                   for c in range(len(self.channels))])
            blocks = [b.mean() for b in np.array_split(held, TIE_BLOCKS) if b.size]
            out.append((float(np.mean(squares)), float(max(blocks))))
        return out

    def loss(self, point) -> float:
        point = np.clip(point, 0.0, 1.0)
        smallest = min(s for s, _ in self.separations(self.drive(point)))
        return -float(np.log(max(smallest, 1e-300))) if np.isfinite(smallest) else 1e3


def _range(signal):
    centre, half = channel_range(signal)
    return centre - half, centre + half


def design_next_drive(report, records=None, seed: int = 0, design_points: int = DESIGN_POINTS,
                      refine_evaluations: int = REFINE_EVALUATIONS) -> NextDrive | None:
    """The drive that best separates the hypotheses ``report`` leaves standing, or None when the verdict is a
    confident single name (module docstring). ``records``: every recording diagnosed so far (default: the
    report's own); the limits are their largest, the drive has the first one's time axis."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    for name, value, least in (("design_points", design_points, 1), ("refine_evaluations", refine_evaluations, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
    # small matrix exponentials run far slower with BLAS threads than without (as in .pipeline.diagnose)
    with threadpool_limits(limits=1, user_api="blas"):
        return _design(report, records, int(seed), int(design_points), int(refine_evaluations))


def _design(report, records, seed, design_points, refine_evaluations):
    started = _time.perf_counter()
    hypotheses = standing_hypotheses(report)
    if not hypotheses:
        return None
    first = report.baseline.model.recording
    records = [first] if records is None else list(records)
    limits = DriveLimits.of(records, max(1, int(round(HEATING_WINDOW_SHARE * first.size))))
    designer = _Designer(hypotheses, first, limits, report.noise, report.split_index)
    unit = qmc.Sobol(d=3 * SEGMENTS, scramble=True, seed=int(seed)).random(int(design_points))
    scored = sorted(((designer.loss(p), i) for i, p in enumerate(unit)))
    best = unit[scored[0][1]]
    best_loss = scored[0][0]
    if refine_evaluations > 0:
        result = scipy.optimize.minimize(designer.loss, best, method="Powell", bounds=[(0.0, 1.0)] * best.size,
                                         options={"maxfev": int(refine_evaluations), "xtol": 1e-3, "ftol": 1e-4})
        if result.fun < best_loss:
            best = np.clip(result.x, 0.0, 1.0)
    field = designer.drive(best)
    first_drive = designer.separations(np.clip(first.field, -limits.peak, limits.peak))
    pairs = []
    notes = []
    if not limits.keeps_frame(field):
        notes.append(f"The drive does not reach the records' largest |field| ({limits.peak:.4g} A/m) within the "
                     "heating limit: a static input map's coefficients are in another frame on it.")
    names = [h.name for h in hypotheses]
    for (i, j), (whole, block), (first_whole, _) in zip(itertools.combinations(range(len(names)), 2),
                                                         designer.separations(field), first_drive):
        material = bool(block >= MATERIAL_SHARE)
        pairs.append({"pair": [names[i], names[j]], "separation": whole, "heldout_block_max": block,
                      "first_drive": first_whole, "material": material})
        if not material:
            notes.append(f"No admissible drive the design found separates {names[i]} from {names[j]} by the "
                         f"material bar ({MATERIAL_SHARE} of the noise power on a held-out block): with their "
                         "parameters as fitted, they are equivalent for the experiments this rig can run.")
    return NextDrive(first.time.copy(), field, names, pairs, limits, _time.perf_counter() - started,
                     designer.evaluations, notes)
