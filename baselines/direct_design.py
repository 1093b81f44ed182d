"""Open-loop input designed by direct search on the benchmark's own metric.

The Fisher-information designs (:mod:`baselines.optimal_design`) maximize a proxy, the
information about a in one period. This design instead searches the input that makes the
*simulated* closed loop (plant, noise, min-max estimator) converge fastest: CMA-ES over a
piecewise-linear field, scored by running the episodes. It is the strongest open-loop
baseline we can build from the simulator alone, and it answers how fast any input under
the common limits can make the estimator settle -- the bar a learned policy has to clear.

Parameterization: ``n_knots`` knots at ``t_k = k*episode_s/(n_knots - 1)`` (s), with field
``H_k = field_max*tanh(x_k)`` (A/m); H(t) interpolates linearly between them and is then
passed through the common slew and field limits (:func:`~baselines.schedules.apply_limits`)
like every other agent. The score is supplied by the caller (the experiment runner uses
the same criterion as the schedule grid searches, on the tuning draws, never on the
held-out ones).
"""

from __future__ import annotations

from dataclasses import dataclass, field as dataclass_field

import numpy as np

from .cma_search import cma_minimize
from .schedules import ExcitationLimits, Schedule


@dataclass(frozen=True)
class KnotSchedule(Schedule):
    """Piecewise-linear H(t) through ``len(knots)`` equally spaced knots over ``[0, episode_s]``.

    Attributes
    ----------
    knots : tuple of float
        Unbounded coordinates ``x_k``; the knot field is ``field_max*tanh(x_k)``, A/m.
    episode_s : float
        Time of the last knot, s; the field holds the last knot's value afterwards.
    field_max : float
        Largest |H|, A/m.
    """

    knots: tuple = (0.0, 0.0)
    episode_s: float = 10.0
    field_max: float = 1.0e5
    name = "direct_design"

    def __post_init__(self):
        if len(self.knots) < 2:
            raise ValueError(f"KnotSchedule: knots needs at least 2 values, got {len(self.knots)}")
        if not (np.isfinite(self.episode_s) and self.episode_s > 0):
            raise ValueError(f"KnotSchedule: episode_s must be a finite number > 0 s, got {self.episode_s!r}")
        if not np.all(np.isfinite(self.knots)):
            raise ValueError("KnotSchedule: knots must be finite")

    def field(self, time):
        knot_times = np.linspace(0.0, self.episode_s, len(self.knots))
        knot_fields = self.field_max * np.tanh(np.asarray(self.knots, dtype=np.float64))
        return np.interp(np.asarray(time, dtype=np.float64), knot_times, knot_fields)


@dataclass(frozen=True)
class DirectDesignResult:
    schedule: KnotSchedule
    score: float
    evaluations: int
    history: tuple = dataclass_field(default=())


def search_direct_design(score, limits: ExcitationLimits, episode_s: float, n_knots: int = 16,
                         max_evaluations: int = 600, seed: int = 0) -> DirectDesignResult:
    """CMA-ES over the knots of a :class:`KnotSchedule`, minimizing ``score(schedule)``.

    ``score`` maps a schedule to a float to minimize (e.g. the censored IQM settle time, s,
    over some draws); it must be deterministic for the search to be reproducible. The
    search starts from a zero field with step size 1 in the tanh coordinates, bounded to
    [-3, 3] (so a knot reaches up to tanh(3) = 99.5 % of ``field_max``), with a fixed
    CMA-ES seed.
    """
    if n_knots < 2 or max_evaluations < 1:
        raise ValueError(f"n_knots must be >= 2 and max_evaluations >= 1, got {n_knots} and {max_evaluations}")

    def schedule_of(x):
        return KnotSchedule(tuple(float(v) for v in x), float(episode_s), limits.field_max)

    best, best_score, evaluations, history = cma_minimize(lambda x: score(schedule_of(x)), np.zeros(n_knots), 1.0,
                                                          3.0, max_evaluations, seed)
    return DirectDesignResult(schedule_of(best), best_score, evaluations, history)


__all__ = ["KnotSchedule", "DirectDesignResult", "search_direct_design"]
