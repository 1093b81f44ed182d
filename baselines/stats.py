"""Statistics for reporting RL and baseline results (Agarwal et al., NeurIPS 2021).

An rliable-equivalent implementation, written out so that it is auditable and needs no
extra dependency:

* :func:`iqm` -- the interquartile mean, the mean of the middle 50 % of all scores
  (``scipy.stats.trim_mean(x, 0.25)`` over the flattened runs x draws).
* :func:`stratified_bootstrap_ci` -- a 95 % percentile interval. Scores come as a
  matrix ``(n_runs, n_draws)``: runs are training seeds (1 for a deterministic
  baseline), draws are the shared held-out evaluation draws. Each bootstrap replicate
  resamples the draws with replacement and, within each drawn column (the strata, as
  rliable's tasks), resamples the runs with replacement. It so carries both the
  evaluation-set and the training-seed variability; with one run it is the ordinary
  bootstrap over draws.
* :func:`probability_of_improvement` -- P(X better than Y) averaged over the draws,
  with ties counting 1/2 (the Mann-Whitney U statistic per draw, as rliable).
"""

from __future__ import annotations

import numpy as np
from scipy import stats as scipy_stats


def _as_matrix(scores) -> np.ndarray:
    scores = np.asarray(scores, dtype=np.float64)
    if scores.ndim == 1:
        scores = scores[None, :]
    if scores.ndim != 2 or scores.size == 0:
        raise ValueError(f"scores must be a non-empty (runs, draws) matrix, got shape {scores.shape}")
    if not np.all(np.isfinite(scores)):
        raise ValueError("scores must be finite (censor settle times at the episode length first)")
    return scores


def iqm(scores) -> float:
    """Interquartile mean of all scores (25 % trimmed from each end)."""
    return float(scipy_stats.trim_mean(_as_matrix(scores).ravel(), 0.25))


def _bootstrap_indices(n_runs, n_draws, n_boot, rng):
    columns = rng.integers(0, n_draws, size=(n_boot, n_draws))
    rows = rng.integers(0, n_runs, size=(n_boot, n_runs, n_draws))
    return rows, columns


def stratified_bootstrap_ci(scores, statistic=iqm, n_boot: int = 2000, confidence: float = 0.95,
                            seed: int = 0) -> tuple[float, float]:
    """Percentile interval of ``statistic`` under the stratified bootstrap described above."""
    scores = _as_matrix(scores)
    n_runs, n_draws = scores.shape
    rng = np.random.default_rng(seed)
    rows, columns = _bootstrap_indices(n_runs, n_draws, n_boot, rng)
    values = np.empty(n_boot)
    for b in range(n_boot):
        values[b] = statistic(scores[rows[b], columns[b][None, :]])
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(values, [tail, 100 - tail])
    return float(low), float(high)


def probability_of_improvement(x, y, lower_is_better: bool = True) -> float:
    """P(a run of X scores better than a run of Y on the same draw), averaged over draws.

    ``x`` and ``y`` are ``(runs, draws)`` matrices over the same draws (same columns).
    """
    x, y = _as_matrix(x), _as_matrix(y)
    if x.shape[1] != y.shape[1]:
        raise ValueError(f"x and y must share the evaluation draws, got {x.shape[1]} and {y.shape[1]} columns")
    if lower_is_better:
        x, y = -x, -y
    greater = (x[:, None, :] > y[None, :, :]).mean(axis=(0, 1))
    ties = (x[:, None, :] == y[None, :, :]).mean(axis=(0, 1))
    return float(np.mean(greater + 0.5 * ties))


def probability_of_improvement_ci(x, y, lower_is_better=True, n_boot=1000, confidence=0.95, seed=0):
    """Stratified-bootstrap interval of :func:`probability_of_improvement` (shared draws)."""
    x, y = _as_matrix(x), _as_matrix(y)
    rng = np.random.default_rng(seed)
    n_draws = x.shape[1]
    values = np.empty(n_boot)
    for b in range(n_boot):
        columns = rng.integers(0, n_draws, size=n_draws)
        rx = rng.integers(0, x.shape[0], size=x.shape[0])
        ry = rng.integers(0, y.shape[0], size=y.shape[0])
        values[b] = probability_of_improvement(x[rx][:, columns], y[ry][:, columns], lower_is_better)
    tail = 100 * (1 - confidence) / 2
    return tuple(float(v) for v in np.percentile(values, [tail, 100 - tail]))


def summarize(scores, n_boot: int = 2000, seed: int = 0) -> dict:
    """``{"iqm": x, "ci95": [lo, hi], "n": n}`` as used in ``experiments/results/summary.json``."""
    scores = _as_matrix(scores)
    low, high = stratified_bootstrap_ci(scores, n_boot=n_boot, seed=seed)
    return {"iqm": iqm(scores), "ci95": [low, high], "n": int(scores.size)}


__all__ = ["iqm", "stratified_bootstrap_ci", "probability_of_improvement",
           "probability_of_improvement_ci", "summarize"]
