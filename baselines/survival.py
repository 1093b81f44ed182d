"""Settle times with censoring, and Kaplan-Meier survival curves.

A settle time is the first time after which ``|a_estimate - a_true|`` stays within the
band (0.1 % of a_true) until the end of the episode. A run that is outside the
band at its last step never settled: it is *censored* at the episode length, not dropped
(dropping would make a bad agent look good). Survival here is the probability of *not
yet* having settled at time t.
"""

from __future__ import annotations

import numpy as np


def settle_time(time, a_estimate, a_true, band_fraction: float = 1e-3) -> float:
    """First time (s) after which the estimate stays in the band to the end; ``nan`` if never.

    ``time``, ``a_estimate`` and ``a_true`` are 1-D arrays over the episode (``a_true`` may
    be a scalar). The band is ``band_fraction*|a_true|`` at each sample.
    """
    time = np.asarray(time, dtype=np.float64)
    error = np.abs(np.asarray(a_estimate, dtype=np.float64) - a_true)
    band = band_fraction * np.abs(np.broadcast_to(np.asarray(a_true, dtype=np.float64), error.shape))
    if time.shape != error.shape or time.ndim != 1 or time.size == 0:
        raise ValueError(f"time and a_estimate must be equal-length 1-D arrays, got {time.shape} and {error.shape}")
    outside = np.flatnonzero(error > band)
    if outside.size == 0:
        return float(time[0])
    last = outside[-1]
    if last == time.size - 1:
        return float("nan")
    return float(time[last + 1])


def censor(settle_times, episode_length: float) -> tuple[np.ndarray, np.ndarray]:
    """Replace never-settled (nan) times by ``episode_length``; return (times, observed)."""
    settle_times = np.asarray(settle_times, dtype=np.float64)
    observed = np.isfinite(settle_times)
    return np.where(observed, settle_times, float(episode_length)), observed


def kaplan_meier(times, observed) -> tuple[np.ndarray, np.ndarray]:
    """Kaplan-Meier estimate of P(not settled by t).

    Returns the step function as ``(t, survival)`` arrays starting at ``(0, 1)``; survival
    drops only at observed settle times and is carried flat past censored runs.
    """
    times = np.asarray(times, dtype=np.float64).ravel()
    observed = np.asarray(observed, dtype=bool).ravel()
    if times.shape != observed.shape:
        raise ValueError("times and observed must have the same length")
    event_times = np.unique(times[observed])
    survival, t_out, s_out = 1.0, [0.0], [1.0]
    for t in event_times:
        at_risk = np.count_nonzero(times >= t)
        events = np.count_nonzero((times == t) & observed)
        survival *= 1.0 - events / at_risk
        t_out.append(float(t))
        s_out.append(survival)
    return np.array(t_out), np.array(s_out)


__all__ = ["settle_time", "censor", "kaplan_meier"]
