"""Excitation schedules: the field H(t) (A/m) as pure functions of time (s).

Every schedule is a frozen dataclass whose :meth:`field` maps an array of times to an
array of fields, with no hidden state, so the same ``(schedule, t)`` always gives the
same H. All of them are then passed through :func:`apply_limits`, the one place where
the common field limit ``|H| <= field_max`` and slew limit ``|dH/dt| <= slew_max`` are
enforced for every agent of the benchmark (schedules, optimal design, greedy, RL).

Schedules:

* :class:`Ramp` -- the paper's input (§4.1): a linear ramp in H that drives M towards
  saturation, ``H = peak * min(t/duration, 1)``; the paper uses about 1e5 A/m over 6 s.
* :class:`Sine`, :class:`Chirp` (linear frequency sweep), :class:`MultilevelPRBS`
  (a seeded random sequence of levels held for ``bit_period`` s),
* :class:`SchroederMultisine` -- equal-amplitude harmonics with Schroeder phases
  ``phi_k = -pi*k*(k-1)/n`` (M. R. Schroeder, IEEE Trans. Inf. Theory 16, 1970), the
  classical low-crest-factor multisine of system identification,
* :class:`RandomField` -- uniformly random levels redrawn every control step (white
  before the slew limit, which then makes it a random walk at the slew rate).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ExcitationLimits:
    """Limits shared by every agent.

    Attributes
    ----------
    field_max : float
        Largest |H| the coil can produce, A/m.
    slew_max : float
        Largest |dH/dt|, A/m/s (the coil cannot jump).
    dt : float
        Control period, s.
    """

    field_max: float = 1.0e5
    slew_max: float = 5.0e4
    dt: float = 0.01

    def __post_init__(self):
        for name in ("field_max", "slew_max", "dt"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"ExcitationLimits: {name} must be a finite number > 0, got {value!r}")
            object.__setattr__(self, name, float(value))

    @property
    def max_field_change(self) -> float:
        """Largest field change in one control period, A/m."""
        return self.slew_max * self.dt


def apply_limits(field, limits: ExcitationLimits, field_start: float = 0.0) -> np.ndarray:
    """Clip a sampled field (A/m, at times ``k*dt``, k = 0, 1, ...) to the common limits.

    The first sample is reached from ``field_start`` within one slew step. Each later
    sample moves at most ``slew_max*dt`` from the previous *limited* sample, then is
    clipped to ``+-field_max``; this is exactly what a slew-limited coil driver does.
    """
    field = np.asarray(field, dtype=np.float64)
    out = np.empty_like(field)
    step = limits.max_field_change
    previous = float(field_start)
    for i, target in enumerate(field):
        value = min(max(target, previous - step), previous + step)
        value = min(max(value, -limits.field_max), limits.field_max)
        out[i] = previous = value
    return out


def limit_step(target, previous, limits: ExcitationLimits):
    """One step of :func:`apply_limits` for arrays of systems (A/m)."""
    step = limits.max_field_change
    value = np.clip(target, previous - step, previous + step)
    return np.clip(value, -limits.field_max, limits.field_max)


class Schedule:
    """Base class: ``field(t)`` (A/m) for an array of times ``t`` (s)."""

    name = "schedule"

    def field(self, time) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def sampled(self, n_steps: int, limits: ExcitationLimits) -> np.ndarray:
        """The limited field at the control instants ``dt, 2*dt, ..., n_steps*dt``."""
        time = limits.dt * np.arange(1, int(n_steps) + 1)
        return apply_limits(self.field(time), limits)

    def replace(self, **changes):
        return dataclasses.replace(self, **changes)

    def describe(self) -> dict:
        return {"name": self.name, **dataclasses.asdict(self)}


@dataclass(frozen=True)
class Ramp(Schedule):
    """The paper's ramp (§4.1): ``H = peak*min(t/duration, 1)``; peak in A/m, duration in s."""

    peak: float = 1.0e5
    duration: float = 6.0
    name = "ramp"

    def field(self, time):
        time = np.asarray(time, dtype=np.float64)
        return self.peak * np.minimum(time / self.duration, 1.0)


@dataclass(frozen=True)
class Sine(Schedule):
    """``H = offset + amplitude*sin(2*pi*frequency*t)``; A/m, Hz."""

    amplitude: float = 1.0e5
    frequency: float = 0.5
    offset: float = 0.0
    name = "sine"

    def field(self, time):
        time = np.asarray(time, dtype=np.float64)
        return self.offset + self.amplitude * np.sin(2 * np.pi * self.frequency * time)


@dataclass(frozen=True)
class Chirp(Schedule):
    """Linear chirp from ``f0`` to ``f1`` Hz over ``duration`` s, then repeating; amplitude A/m."""

    amplitude: float = 1.0e5
    f0: float = 0.1
    f1: float = 2.0
    duration: float = 6.0
    name = "chirp"

    def field(self, time):
        time = np.mod(np.asarray(time, dtype=np.float64), self.duration)
        phase = 2 * np.pi * (self.f0 * time + 0.5 * (self.f1 - self.f0) / self.duration * time ** 2)
        return self.amplitude * np.sin(phase)


@dataclass(frozen=True)
class MultilevelPRBS(Schedule):
    """Seeded multilevel pseudo-random sequence: one of ``levels`` evenly spaced values in
    ``[-amplitude, amplitude]`` held for ``bit_period`` s. Pure in t: bit i is drawn from
    ``default_rng([seed, i])``-equivalent streams, precomputed per call."""

    amplitude: float = 1.0e5
    bit_period: float = 0.5
    levels: int = 5
    seed: int = 0
    name = "prbs"

    def field(self, time):
        time = np.asarray(time, dtype=np.float64)
        bits = np.floor(time / self.bit_period).astype(np.int64)
        n = int(bits.max()) + 1 if bits.size else 0
        rng = np.random.default_rng(np.random.SeedSequence([int(self.seed), 5]))
        symbols = rng.integers(0, self.levels, size=max(n, 1))
        values = np.linspace(-self.amplitude, self.amplitude, self.levels)
        return values[symbols[np.clip(bits, 0, None)]]


@dataclass(frozen=True)
class SchroederMultisine(Schedule):
    """Sum of ``n_harmonics`` harmonics of ``base_frequency`` Hz with Schroeder phases
    ``phi_k = -pi*k*(k-1)/n``, scaled so that the peak over one period is ``amplitude`` A/m."""

    amplitude: float = 1.0e5
    base_frequency: float = 0.25
    n_harmonics: int = 5
    name = "multisine"

    def _raw(self, time):
        k = np.arange(1, self.n_harmonics + 1)
        phases = -np.pi * k * (k - 1) / self.n_harmonics
        return np.sin(2 * np.pi * self.base_frequency * np.multiply.outer(time, k) + phases).sum(axis=-1)

    def field(self, time):
        time = np.asarray(time, dtype=np.float64)
        period = np.linspace(0.0, 1.0 / self.base_frequency, 4097)
        peak = np.max(np.abs(self._raw(period)))
        return self.amplitude * self._raw(time) / peak


@dataclass(frozen=True)
class RandomField(Schedule):
    """Uniform random targets in ``[-amplitude, amplitude]`` redrawn every ``hold`` s (seeded)."""

    amplitude: float = 1.0e5
    hold: float = 0.01
    seed: int = 0
    name = "random"

    def field(self, time):
        time = np.asarray(time, dtype=np.float64)
        index = np.floor(time / self.hold + 1e-9).astype(np.int64)
        n = int(index.max()) + 1 if index.size else 1
        rng = np.random.default_rng(np.random.SeedSequence([int(self.seed), 7]))
        return rng.uniform(-self.amplitude, self.amplitude, size=max(n, 1))[np.clip(index, 0, None)]


#: name -> schedule class
SCHEDULES = {cls.name: cls for cls in (Ramp, Sine, Chirp, MultilevelPRBS, SchroederMultisine, RandomField)}

#: The documented tuning grids (each schedule is tuned by a small documented grid search).
#: Amplitudes are in A/m, frequencies in Hz, periods in s. The ramp is the
#: paper's input and is reported untuned (its grid is the single paper setting) and tuned.
#: Frequencies are low because of the common slew limit (5e4 A/m/s by default): a full
#: 1e5 A/m sine above 0.08 Hz is already slew-limited into a triangle. The ramp's grid
#: holds the slew limit's own ramp, 8e4 A/m in 1.6 s, then held: 8e4 A/m is near the
#: field of largest |dM/da| (81 kA/m for the paper's parameters), the input that the
#: convergence bound of ``experiments/settle_floor.py`` calls the fastest possible.
TUNING_GRIDS = {
    "ramp": {"peak": [1.0e5], "duration": [6.0]},
    "ramp_tuned": {"peak": [5.0e4, 8.0e4, 1.0e5], "duration": [1.6, 2.0, 4.0, 6.0]},
    "sine": {"amplitude": [5.0e4, 1.0e5], "frequency": [0.05, 0.1, 0.25]},
    "chirp": {"amplitude": [5.0e4, 1.0e5], "f0": [0.02], "f1": [0.1, 0.3]},
    "prbs": {"amplitude": [5.0e4, 1.0e5], "bit_period": [0.5, 2.0, 4.0]},
    "multisine": {"amplitude": [5.0e4, 1.0e5], "base_frequency": [0.02, 0.05]},
    "random": {"amplitude": [5.0e4, 1.0e5], "hold": [0.01, 1.0]},
}


def grid_points(grid: dict) -> list[dict]:
    """All combinations of a tuning grid, as keyword dicts, in a fixed order."""
    points = [{}]
    for key in sorted(grid):
        points = [dict(p, **{key: v}) for p in points for v in grid[key]]
    return points


def make_schedule(name: str, **params) -> Schedule:
    """Build a schedule by name (``ramp_tuned`` builds a :class:`Ramp`)."""
    base = name[:-6] if name.endswith("_tuned") else name
    if base not in SCHEDULES:
        raise ValueError(f"unknown schedule {name!r}; expected one of {sorted(SCHEDULES)}")
    try:
        return SCHEDULES[base](**params)
    except TypeError as error:
        raise ValueError(f"schedule {name!r}: {error}") from None


__all__ = ["ExcitationLimits", "apply_limits", "limit_step", "Schedule", "Ramp", "Sine", "Chirp",
           "MultilevelPRBS", "SchroederMultisine", "RandomField", "SCHEDULES", "TUNING_GRIDS",
           "grid_points", "make_schedule"]
