"""Per-episode metrics (baselines/evaluation.py) against hand-computed values."""

import numpy as np
import pytest

from baselines.evaluation import METRICS, episode_metrics


def test_episode_metrics_on_a_known_error_trace():
    dt = 0.1
    time = dt * np.arange(1, 11)
    a_true = np.full(10, 7000.0)
    # error 20 A/m for the first half, then 3, -4 alternating (inside the 0.1 % band = 7 A/m)
    error = np.r_[np.full(5, 20.0), [3.0, -4.0, 3.0, -4.0, 3.0]]
    flags = np.r_[np.ones(5), np.zeros(5)]
    metrics = episode_metrics(7, time, a_true + error, a_true, flags, np.full(10, np.nan), dt)
    assert set(METRICS) <= set(metrics)
    assert metrics["settle_time_s"] == pytest.approx(time[5])  # in the band from the 6th step on
    assert metrics["integrated_error"] == pytest.approx(dt * np.abs(error).sum())
    assert metrics["rms_error"] == pytest.approx(np.sqrt(np.mean(error ** 2)))
    assert metrics["tracking_rms_error"] == pytest.approx(np.sqrt((3 * 9 + 2 * 16) / 5))  # second half only
    assert metrics["final_error"] == pytest.approx(3.0)
    assert metrics["pe_a_fraction"] == pytest.approx(0.5) and np.isnan(metrics["pe_b_fraction"])
