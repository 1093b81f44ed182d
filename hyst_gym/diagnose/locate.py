"""Stage 2: locate the mismatch in the base model's residual.

Every statistic works on the normalized residual (residual / channel noise level) of the
whole recording. Significance levels assume independent samples; a residual that is
not white makes them optimistic, which is why they only rank places, never decide the
verdict on their own (the decision is by held-out error, :mod:`hyst_gym.diagnose.decide`).
:func:`locate_mismatch` gathers them for the base fit.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import stats

from .fit import FitResult, local_fit
from .model import Model

N_BINS = 10


def whiteness(residual, lags: int = 20) -> dict:
    """Ljung-Box test of the residual's autocorrelation up to ``lags`` samples."""
    r = residual - residual.mean()
    n = r.size
    denom = float(r @ r) or 1.0
    acf = np.array([float(r[:-k] @ r[k:]) / denom for k in range(1, lags + 1)])
    q = n * (n + 2) * float(np.sum(acf ** 2 / (n - np.arange(1, lags + 1))))
    return {"lag1_autocorrelation": float(acf[0]), "ljung_box_q": q, "lags": lags,
            "p_value": float(stats.chi2.sf(q, lags)), "white": bool(stats.chi2.sf(q, lags) > 1e-3)}


def input_cross_correlation(residual, field, max_lag: int = 20) -> dict:
    """Largest |correlation| between the residual and the input field over +-max_lag samples."""
    r = (residual - residual.mean()) / (residual.std() or 1.0)
    h = (field - field.mean()) / (field.std() or 1.0)
    n = r.size
    best_lag, best = 0, 0.0
    for lag in range(-max_lag, max_lag + 1):
        if lag >= 0:
            value = float(r[lag:] @ h[:n - lag]) / n
        else:
            value = float(r[:lag] @ h[-lag:]) / n
        if abs(value) > abs(best):
            best_lag, best = lag, value
    bound = 1.96 / np.sqrt(n)
    return {"max_correlation": best, "at_lag_samples": best_lag, "bound_95": float(bound),
            "significant": bool(abs(best) > 2 * bound)}


def time_since_reversal(time, field):
    rate = np.diff(field)
    direction = np.sign(rate)
    out = np.zeros_like(time)
    last = time[0]
    previous = 0.0
    for i in range(1, time.size):
        d = direction[i - 1]
        if d != 0 and previous != 0 and d != previous:
            last = time[i - 1]
        if d != 0:
            previous = d
        out[i] = time[i] - last
    return out


def binned_dependence(residual, feature, name) -> dict:
    """Fraction of residual variance explained by the bin means of ``feature`` (eta^2), F-test."""
    edges = np.unique(np.quantile(feature, np.linspace(0, 1, N_BINS + 1)))
    if edges.size < 3:
        return {"feature": name, "explained_fraction": 0.0, "p_value": 1.0, "worst_bin": None}
    idx = np.clip(np.searchsorted(edges, feature, side="right") - 1, 0, edges.size - 2)
    groups = [residual[idx == b] for b in range(edges.size - 1) if np.any(idx == b)]
    means = np.array([g.mean() for g in groups])
    sizes = np.array([g.size for g in groups])
    total = float(np.sum((residual - residual.mean()) ** 2)) or 1.0
    between = float(np.sum(sizes * (means - residual.mean()) ** 2))
    k, n = len(groups), residual.size
    f = (between / max(k - 1, 1)) / (max(total - between, 1e-300) / max(n - k, 1))
    worst = int(np.argmax(np.abs(means)))
    lo, hi = edges[worst], edges[min(worst + 1, edges.size - 1)]
    return {"feature": name, "explained_fraction": between / total, "p_value": float(stats.f.sf(f, k - 1, n - k)),
            "worst_bin": [float(lo), float(hi)], "worst_bin_mean": float(means[worst])}


def frequency_bands(residual, time, n_bands: int = 8) -> list[dict]:
    """Residual power per octave band relative to the median band density (white -> ~1)."""
    dt = float(np.median(np.diff(time)))
    spectrum = np.abs(np.fft.rfft(residual - residual.mean())) ** 2
    freqs = np.fft.rfftfreq(residual.size, dt)
    nyquist = freqs[-1]
    edges = nyquist / 2.0 ** np.arange(n_bands, -1, -1)
    edges[0] = freqs[1]
    densities = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (freqs >= lo) & (freqs < hi)
        densities.append(float(spectrum[sel].mean()) if sel.any() else 0.0)
    reference = float(np.median(densities)) or 1.0
    return [{"band_hz": [float(lo), float(hi)], "relative_density": d / reference}
            for lo, hi, d in zip(edges[:-1], edges[1:], densities)]


def summarize_features(features: list[dict]) -> str:
    ranked = sorted(features, key=lambda f: -f["explained_fraction"])
    top = ranked[0]
    if top["explained_fraction"] < 0.02:
        return "no variable explains more than 2 % of the residual variance"
    lo, hi = top["worst_bin"]
    return (f"the residual depends most on {top['feature']} ({100 * top['explained_fraction']:.0f} % of its "
            f"variance; largest where {top['feature']} is in [{lo:.4g}, {hi:.4g}])")


#: Lags (samples) whose mean autocovariance measures the structured part of a residual.
STRUCTURE_LAGS = (1, 2, 3)
#: Moving-block bootstrap draws behind the interval of :func:`structured_power` (fixed seed).
STRUCTURE_BOOTSTRAP = 200


def structured_power(residual, bootstrap: int = STRUCTURE_BOOTSTRAP, seed: int = 0) -> dict:
    """The predictable part of a residual as a share of its unpredictable (noise) part: an effect
    size, not a significance level.

    For a residual r = s + e with e white and s varying slower than a few samples, the
    autocovariance at lags 1..3 (about zero, so an offset counts) is the power of s, whatever the
    power of e: ``structured = mean_k mean_t r_t r_{t+k}``, ``noise = mean r^2 - structured``,
    ``share = structured/noise`` (about 100 at most: the noise power is floored at 1 % of the total).
    Unlike the held-out RMSE it needs no estimate of the noise
    level, and unlike a whiteness p-value it does not grow with the record: a 5 % systematic
    error stays 0.05 at any length. The interval is a 95 % moving-block bootstrap (blocks of
    ``max(50, n/40)`` samples, so the slow structure stays inside a block)."""
    r = np.asarray(residual, dtype=float)
    n = r.size

    def share_of(x):
        total = float(np.mean(x * x))
        lagged = float(np.mean([np.mean(x[:-k] * x[k:]) for k in STRUCTURE_LAGS]))
        # a residual that is nearly all structure has almost no white part left to measure: the
        # noise power is floored at 1 % of the total, so the share reads about 100 at most
        noise = max(total - lagged, 0.01 * total, 1e-300)
        return lagged / noise, lagged, noise

    share, structured, noise = share_of(r)
    block = max(50, n // 40)
    if n < 2 * block:
        return {"share": share, "ci95": [float("nan"), float("nan")], "structured_power": structured,
                "noise_power": noise, "block_samples": block}
    rng = np.random.default_rng(seed)
    starts = rng.integers(0, n - block + 1, size=(bootstrap, n // block))
    shares = [share_of(np.concatenate([r[s:s + block] for s in row]))[0] for row in starts]
    lo, hi = np.percentile(shares, [2.5, 97.5])
    return {"share": share, "ci95": [float(lo), float(hi)], "structured_power": structured, "noise_power": noise,
            "block_samples": block}


def locate_mismatch(base: FitResult, noise, windows: int = 4) -> dict:
    """Stage 2: where the base model's residual lives, and how significant it is."""
    model = base.model
    rec = model.recording
    predicted = model.predict(base.values)
    excess = {}
    residuals = {}
    for ch in model.channels:
        r = (predicted[ch] - rec.output(ch)) / noise[ch]
        residuals[ch] = r
        excess[ch] = float(np.mean(r ** 2))
    channel = max(excess, key=excess.get)
    r = residuals[channel]
    magnetization = model.magnetization([base.values])[:, 0]
    rate = np.gradient(rec.field, rec.time)
    features = [
        binned_dependence(r, rec.time, "time (s)"),
        binned_dependence(r, rec.field, "field H (A/m)"),
        binned_dependence(r, rate, "field rate dH/dt (A/m/s)"),
        binned_dependence(r, np.abs(magnetization), "|M| (A/m)"),
        binned_dependence(r, magnetization ** 2, "M^2 (A^2/m^2)"),
        binned_dependence(r, time_since_reversal(rec.time, rec.field), "time since last reversal (s)"),
    ]
    drift = window_refits(base, noise, windows)
    white = whiteness(r)
    xcorr = input_cross_correlation(r, rec.field)
    bands = frequency_bands(r, rec.time)
    worst_band = max(bands, key=lambda b: b["relative_density"])
    summary = (f"channel '{channel}' (mean squared residual {excess[channel]:.2f} noise units^2); "
               + summarize_features(features)
               + f"; residual {'is' if white['white'] else 'is not'} white (lag-1 autocorrelation "
               f"{white['lag1_autocorrelation']:.2f}); most excess power in {worst_band['band_hz'][0]:.3g}-"
               f"{worst_band['band_hz'][1]:.3g} Hz (x{worst_band['relative_density']:.1f} the median band)")
    if drift.get("significant"):
        summary += f"; a drifts across time windows ({drift['a_change_percent']:+.1f} % first to last window)"
    return {"summary": summary, "channel": channel, "mean_square_by_channel": excess, "whiteness": white,
            "input_cross_correlation": xcorr, "features": features, "frequency_bands": bands,
            "window_refits": drift}


def window_refits(base: FitResult, noise, windows: int = 4) -> dict:
    """Refit ``a`` alone on consecutive time windows (others held at the base fit): a drifting
    parameter shows as a trend; significance from the windows' 1-sigma errors."""
    model = base.model
    n = model.recording.size
    fixed = {name: (p if name == "a" else replace(p, free=False)) for name, p in model.parameters.items()}
    window_model = Model(model.recording, model.structure, fixed, model.max_field_step).with_values(base.values)
    values, sigmas, centers = [], [], []
    edges = np.linspace(0, n, windows + 1).astype(int)
    for lo, hi in zip(edges[:-1], edges[1:]):
        mask = np.zeros(n, dtype=bool)
        mask[lo:hi] = True
        result = local_fit(window_model, noise, mask, base.values, max_nfev=8)
        values.append(result.values["a"])
        sigmas.append(result.uncertainties.get("a", np.nan))
        centers.append(float(model.recording.time[(lo + hi - 1) // 2]))
    values, sigmas = np.array(values), np.array(sigmas)
    change = values[-1] - values[0]
    combined = float(np.hypot(sigmas[-1], sigmas[0]))
    return {"parameter": "a", "window_centers_s": centers, "values": values.tolist(), "sigmas": sigmas.tolist(),
            "a_change_percent": float(100 * change / values[0]),
            "significant": bool(np.isfinite(combined) and abs(change) > 5 * combined
                                and abs(change) > 0.005 * values[0])}
