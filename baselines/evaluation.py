"""Run agents on a batch of seeded episodes and compute the benchmark's metrics.

Every agent (schedule, design, greedy, estimator, RL policy) is evaluated by the same
function on the same native vector environment, one sub-environment per evaluation
draw, so all agents see the same draws of temperature, drift and noise (the evaluation protocol in README, "Benchmark").

Per-episode metrics:

* ``settle_time_s`` -- first time after which |a_estimate - a_true| stays within
  ``band_fraction*a_true`` (0.1 %) to the end; ``nan`` if never (censored later);
* ``integrated_error`` -- the integral of |a_estimate - a_true| over the episode, A/m*s;
* ``rms_error`` -- RMS of a_estimate - a_true over the episode, A/m;
* ``tracking_rms_error`` -- RMS of a_estimate - a_true over the episode's second half,
  A/m: the tracking error once the initial acquisition is over (in the drift scenario the
  first seconds, with an initial error of up to a few hundred A/m, dominate ``rms_error``);
* ``final_error`` -- |a_estimate - a_true| at the last step, A/m;
* ``pe_a_fraction``, ``pe_b_fraction`` -- fraction of steps at which the windowed test
  of the estimation layer (:class:`hyst_gym.estimation.PEMonitor`, window
  :data:`PE_WINDOW_S`) finds 3.1(a) / 3.1(b), from the integrand of (22) and the
  curvature sign that the environment reports in ``info`` (truth known in simulation).
"""

from __future__ import annotations

import numpy as np

from .environment import EpisodeSpec, make_vector_env, step_info

#: window of the persistent-excitation test, s
PE_WINDOW_S = 1.0

METRICS = ("settle_time_s", "integrated_error", "rms_error", "tracking_rms_error", "final_error", "pe_a_fraction",
           "pe_b_fraction")


def run_episodes(agent, spec: EpisodeSpec, seeds, band_fraction: float = 1e-3, max_batch: int = 64,
                 keep_traces: int = 0):
    """Evaluate ``agent`` on one episode per seed. Returns ``(records, traces)``.

    ``records`` is a list of dicts (one per seed, in order) with the seed, the episode
    length and :data:`METRICS`; ``traces`` holds ``time``, ``field``, ``a_estimate`` and
    ``a_true`` arrays for the first ``keep_traces`` seeds (for figures).
    """
    seeds = [int(s) for s in seeds]
    records, traces = [], []
    for start in range(0, len(seeds), max_batch):
        chunk = seeds[start:start + max_batch]
        chunk_records, chunk_traces = _run_batch(agent, spec, chunk, band_fraction,
                                                 max(0, keep_traces - start))
        records += chunk_records
        traces += chunk_traces
    return records, traces


def play_batch(agent, spec: EpisodeSpec, seeds, extra=None):
    """Play ``agent`` on one episode per seed in the native vector env, deterministic actions.

    Returns ``(columns, lengths)``: the benchmark's info fields per step (``step_info``), plus
    whatever ``extra(observations, infos)`` returns per step (a dict of (n,) arrays), each an
    array (T, n) with ``nan`` after the episode ended; and each episode's length in steps.
    """
    from .environment import reset_vector_env
    n = len(seeds)
    env = make_vector_env(spec, n)
    columns, lengths = {}, np.zeros(n, dtype=np.int64)
    try:
        agent.reset(seeds[0])
        observations, infos = reset_vector_env(env, seeds)
        episode_start = np.ones(n, dtype=bool)
        active = np.ones(n, dtype=bool)
        while active.any():
            actions, _ = agent.predict(observations, episode_start=episode_start, deterministic=True)
            observations, _, terminated, truncated, infos = env.step(np.asarray(actions, dtype=np.float32))
            episode_start = np.zeros(n, dtype=bool)
            values = step_info(infos, n)
            if extra is not None:
                values.update(extra(observations, infos))
            for key, value in values.items():
                columns.setdefault(key, []).append(np.where(active, value, np.nan))
            lengths += active
            active &= ~(np.asarray(terminated) | np.asarray(truncated))
    finally:
        env.close()
    return {key: np.array(v) for key, v in columns.items()}, lengths


def _run_batch(agent, spec, seeds, band_fraction, keep_traces):
    data, lengths = play_batch(agent, spec, seeds)
    data["pe_a"], data["pe_b"] = _pe_conditions(data["pe_integrand"], data["curvature_sign"], spec.dt)
    records, traces = [], []
    for i, seed in enumerate(seeds):
        length = int(lengths[i])
        rows = slice(0, length)
        time = data["time"][rows, i]
        estimate, truth = data["a_estimate"][rows, i], data["a_true"][rows, i]
        records.append(episode_metrics(seed, time, estimate, truth, data["pe_a"][rows, i], data["pe_b"][rows, i],
                                       spec.dt, band_fraction))
        if i < keep_traces:
            traces.append({"seed": seed, "time": time, "field": data["field"][rows, i],
                           "a_estimate": estimate, "a_true": truth})
    return records, traces


def _pe_conditions(integrand, curvature, dt):
    """Per-step 3.1(a)/(b) flags (T, n) from the windowed test; nan where the data are absent."""
    from hyst_gym.estimation import PEMonitor

    steps, n = integrand.shape
    flags_a, flags_b = np.full((steps, n), np.nan), np.full((steps, n), np.nan)
    if not np.isfinite(integrand).any():
        return flags_a, flags_b
    monitor = PEMonitor(n, max(2, int(round(PE_WINDOW_S / dt))))
    for t in range(steps):
        present = np.isfinite(integrand[t])
        monitor.update(np.nan_to_num(integrand[t]), np.nan_to_num(curvature[t], nan=1.0), dt)
        flags_a[t] = np.where(present, monitor.condition_a, np.nan)
        flags_b[t] = np.where(present, monitor.condition_b, np.nan)
    return flags_a, flags_b


def episode_metrics(seed, time, a_estimate, a_true, pe_a, pe_b, dt, band_fraction=1e-3) -> dict:
    from baselines.survival import settle_time

    error = a_estimate - a_true
    return {
        "seed": int(seed),
        "steps": int(time.size),
        "episode_time_s": float(time[-1]) if time.size else 0.0,
        "settle_time_s": settle_time(time, a_estimate, a_true, band_fraction),
        "integrated_error": float(np.sum(np.abs(error)) * dt),
        "rms_error": float(np.sqrt(np.mean(error ** 2))),
        "tracking_rms_error": float(np.sqrt(np.mean(error[error.size // 2:] ** 2))),
        "final_error": float(abs(error[-1])),
        "pe_a_fraction": float(np.nanmean(pe_a)) if np.isfinite(pe_a).any() else float("nan"),
        "pe_b_fraction": float(np.nanmean(pe_b)) if np.isfinite(pe_b).any() else float("nan"),
    }


__all__ = ["METRICS", "run_episodes", "episode_metrics"]
