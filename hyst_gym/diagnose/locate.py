"""Stage 2: locate the mismatch in the base model's residual.

Every statistic works on the normalized residual (residual / channel noise level) of the
whole recording. Significance levels assume independent samples; a residual that is
not white makes them optimistic, which is why they only rank places, never decide the
verdict on their own (the decision is by held-out error, :mod:`hyst_gym.diagnose.decide`).
:func:`locate_mismatch` gathers them for the base fit.

The structured share that decides materiality (:func:`residual_structure`) is an effect size, not a
significance level. Where a channel's noise is white it is read at lags 1-3 (:func:`structured_power`);
where the noise is coloured (:func:`noise_colour`) it is read between moments of the same drive state at
least ``NOISE_HORIZON`` samples apart (:func:`partner_products`), on the assumption that the sensor noise
decorrelates within that horizon while a model error follows the drive (:mod:`.decide`, "Coloured noise").
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import stats
from scipy.spatial import cKDTree

from .decide import MATERIAL_SHARE
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


#: Lags (samples) whose mean autocovariance measures the structured part of a residual under white noise
#: (:func:`structured_power`).
STRUCTURE_LAGS = (1, 2, 3)
#: Moving-block bootstrap draws behind the interval of :func:`structured_power` (fixed seed).
STRUCTURE_BOOTSTRAP = 200
#: Samples within which the sensor noise, white or coloured, is taken to decorrelate: the assumption that
#: separates noise from a model error in :func:`partner_products` (module docstring of :mod:`.decide`).
NOISE_HORIZON = 32
#: Partners of each sample in :func:`partner_products`: its nearest drive states at least
#: ``NOISE_HORIZON`` samples away.
STATE_PARTNERS = 4
#: A channel's noise is coloured when, on the fitting block, the white-noise measure (lags 1..3) reads at least
#: this much more structure, as a share of the noise power, than the drive-paired one: correlation within a few
#: samples that does not follow the drive, half as large as a material structure (:func:`noise_colour`).
COLOURED_EXCESS = 0.5 * MATERIAL_SHARE


def _share_interval(structured_terms, power_terms, bootstrap, seed):
    """share = mean(structured)/(mean(power) - mean(structured)) and its 95 % moving-block bootstrap
    interval (blocks of ``max(50, n/40)`` samples, so the slow structure stays inside a block)."""
    def share_of(lagged, total):
        # a residual that is nearly all structure has almost no noise left to measure: the noise power is
        # floored at 1 % of the total, so the share reads about 100 at most
        noise = max(total - lagged, 0.01 * total, 1e-300)
        return lagged / noise, lagged, noise

    s = np.asarray(structured_terms, dtype=float)
    q = np.asarray(power_terms, dtype=float)
    share, structured, noise = share_of(float(s.mean()), float(q.mean()))
    n = s.size
    block = max(50, n // 40)
    out = {"share": share, "ci95": [float("nan"), float("nan")], "structured_power": structured,
           "noise_power": noise, "block_samples": block}
    if n < 2 * block or bootstrap < 1:
        return out
    rng = np.random.default_rng(seed)
    starts = rng.integers(0, n - block + 1, size=(bootstrap, n // block))
    picks = (starts[:, :, None] + np.arange(block)).reshape(bootstrap, -1)
    shares = [share_of(float(s[row].mean()), float(q[row].mean()))[0] for row in picks]
    lo, hi = np.percentile(shares, [2.5, 97.5])
    out["ci95"] = [float(lo), float(hi)]
    return out


def structured_power(residual, bootstrap: int = STRUCTURE_BOOTSTRAP, seed: int = 0) -> dict:
    """The predictable part of a residual as a share of its unpredictable (noise) part, *assuming white
    noise*: an effect size, not a significance level.

    For a residual r = s + e with e white and s varying slower than a few samples, the
    autocovariance at lags 1..3 (about zero, so an offset counts) is the power of s, whatever the
    power of e: ``structured = mean_k mean_t r_t r_{t+k}``, ``noise = mean r^2 - structured``,
    ``share = structured/noise`` (about 100 at most: the noise power is floored at 1 % of the total).
    Coloured noise is correlated over those lags too and reads as structure: a diagnosis uses
    :func:`partner_products`, which does not assume white noise; this measure stays for a residual
    without its drive. The interval is a 95 % moving-block bootstrap."""
    r = np.asarray(residual, dtype=float)
    return _share_interval(short_lag_terms(r), r * r, bootstrap, seed)


def short_lag_terms(r) -> np.ndarray:
    """Per sample t, the mean over :data:`STRUCTURE_LAGS` of the lagged products r_t r_{t+k}, each lag scaled by
    n/(n - k) (the last k samples have none), so that their mean is the mean autocovariance at those lags."""
    n = r.size
    lagged = np.zeros(n)
    for k in STRUCTURE_LAGS:
        lagged[:n - k] += r[:n - k] * r[k:] * n / (n - k) / len(STRUCTURE_LAGS)
    return lagged


def drive_state(field, time) -> np.ndarray:
    """The drive's state at each sample, (H, dH/dt), each in units of its standard deviation over the record."""
    field = np.asarray(field, dtype=float)
    rate = np.gradient(field, time)
    return np.column_stack([field / (np.std(field) or 1.0), rate / (np.std(rate) or 1.0)])


def partner_products(residual, state, horizon: int = NOISE_HORIZON, partners: int = STATE_PARTNERS):
    """Per sample t, the mean of r_t r_u over its ``partners`` nearest samples u in drive state (Euclidean in
    ``state``) with |t - u| >= ``horizon``; and the horizon used (at most an eighth of the record).
    :func:`partner_means` gives the mean of those r_u. The mean of these products is the structured power of
    the residual for white *or coloured* noise (:func:`residual_structure` reads a coloured channel with it).

    Assumption: the sensor noise does not depend on the drive and decorrelates within ``horizon`` samples,
    while a model error follows the drive: two moments at which the drive is in the same state (field and
    field rate, :func:`drive_state`) carry the same error however far apart they are. So the power of the
    error is the mean product of the residual at pairs of moments with (nearly) the same drive state that are
    at least ``horizon`` samples apart (each sample paired with its ``STATE_PARTNERS`` nearest such states):
    the noise of the two moments is independent and drops out, whatever its colour.
    ``noise = mean r^2 - structured``, ``share = structured/noise``, as :func:`structured_power`. On a slow drive
    the partners are the samples just beyond the horizon, and this is the autocovariance at that lag; on a fast
    or repeating drive they are revisits of the same state, so a model error that changes within a few samples
    still counts. What it cannot see: an error that differs between visits of the same drive state (a slow
    drift of the sensor, a temperature) further apart than the drive takes to return; the candidates name those."""
    means, horizon = partner_means(residual, state, horizon, partners)
    return np.asarray(residual, dtype=float) * means, horizon


def partner_indices(state, horizon: int = NOISE_HORIZON, partners: int = STATE_PARTNERS):
    """Per sample t, the indices of its ``partners`` nearest samples u in drive state (Euclidean in ``state``)
    with |t - u| >= ``horizon`` (an (n, partners) array), and the horizon used (at most an eighth of the
    record)."""
    state = np.asarray(state, dtype=float)
    n = state.shape[0]
    horizon = int(max(1, min(horizon, n // 8)))
    # the 2*horizon - 1 samples nearer than the horizon in time may all be nearest in state: asking for that
    # many more neighbours always leaves `partners` outside the horizon
    k = min(n, 2 * horizon - 1 + partners)
    _, idx = cKDTree(state).query(state, k=k)
    allowed = np.abs(idx - np.arange(n)[:, None]) >= horizon
    # stable sort: the allowed neighbours first, nearest first
    order = np.argsort(~allowed, axis=1, kind="stable")[:, :partners]
    return np.take_along_axis(idx, order, axis=1), horizon


def partner_means(residual, state, horizon: int = NOISE_HORIZON, partners: int = STATE_PARTNERS):
    """Per sample t, the mean of r_u over its partners (:func:`partner_indices`): the part of r_t that follows the
    drive, as far as the other visits of its state tell it; and the horizon used."""
    idx, horizon = partner_indices(state, horizon, partners)
    return np.asarray(residual, dtype=float)[idx].mean(axis=1), horizon


def noise_colour(residual, state, horizon: int = NOISE_HORIZON) -> dict:
    """Whether a channel's noise is coloured, read on the base model's residual on the fitting block (in units of
    the second-difference noise level, so never on the held-out block that the verdict judges).

    ``coloured``: the white-noise measure (:func:`structured_power`, lags 1..3) reads at least
    ``COLOURED_EXCESS`` more structure than the drive-paired one (:func:`partner_products`): the residual is
    correlated over a few samples in a way that does not follow the drive. With white noise both read the same
    structure. Also reported: ``power_ratio``, the residual's power less the part that follows the drive, in
    noise units squared (about 1 for white noise; for coloured noise, its total power over the white part that
    second differences see; it also holds any error that does not follow the drive's state, such as a sensor's
    ringing), and ``correlation_samples``, the lag at which the rest's autocovariance falls to 1/e of its value at
    lag 1 (None when it is not correlated at lag 1)."""
    r = np.asarray(residual, dtype=float)
    means, used = partner_means(r, state, horizon)
    structured = float(np.mean(r * means))
    noise = float(np.mean(r * r)) - structured
    short = structured_power(r, bootstrap=0)["share"]
    paired = structured / max(noise, 0.01 * float(np.mean(r * r)), 1e-300)
    correlation = None
    first = float(np.mean(r[:-1] * r[1:])) - structured
    if first > 0.0:
        longest = min(r.size // 4, 8 * used)
        correlation = next((k - 1 for k in range(2, longest + 1)
                            if float(np.mean(r[:-k] * r[k:])) - structured < first / np.e), longest)
    # what does not follow the drive must have decorrelated by the horizon, the assumption itself: the residual's
    # autocovariance at lags horizon..2*horizon, less the structure, RMS over the lags (a hum's changes sign), stays
    # below COLOURED_EXCESS of the noise power. A hum or a drift stays correlated there and is no sensor noise; so
    # does a model error on a drive that changes within the horizon, and the channel is then read at lags 1-3.
    beyond = float(np.sqrt(np.mean([(np.mean(r[:-k] * r[k:]) - structured) ** 2 for k in range(used, 2 * used + 1)])))
    beyond_share = beyond / max(noise, 0.01 * float(np.mean(r * r)), 1e-300)
    return {"coloured": bool(short - paired >= COLOURED_EXCESS and beyond_share < COLOURED_EXCESS),
            "short_lag_share": float(short), "drive_paired_share": float(paired), "beyond_horizon_share": beyond_share,
            "power_ratio": noise, "correlation_samples": correlation, "horizon_samples": int(used)}


def residual_structure(held, fit, held_state, fit_state, horizon: int = NOISE_HORIZON) -> dict:
    """The structured share of the base model's held-out residual (``held``: channel -> residual in noise units),
    each channel read by the measure its noise allows: lags 1..3 (:func:`structured_power`) where its noise is
    white, the drive-paired products (:func:`partner_products`) where :func:`noise_colour` finds it coloured on
    the fitting block (``fit``, same channels). The result is :func:`structured_power`'s, with ``noise_colour``
    per channel and, for the coloured channels, ``short_lag_share``: what lags 1..3 would have read on the
    held-out block."""
    colour = {ch: noise_colour(fit[ch], fit_state, horizon) for ch in held}
    terms, powers, short_terms = [], [], []
    used = horizon
    for ch, r in held.items():
        r = np.asarray(r, dtype=float)
        lagged = short_lag_terms(r)
        short_terms.append(lagged)
        if colour[ch]["coloured"]:
            products, used = partner_products(r, held_state, horizon)
            terms.append(products)
        else:
            terms.append(lagged)
        powers.append(r * r)
    out = _share_interval(np.concatenate(terms), np.concatenate(powers), STRUCTURE_BOOTSTRAP, 0)
    coloured = [ch for ch in held if colour[ch]["coloured"]]
    out.update(method="drive-paired" if coloured else "short-lag", coloured_channels=coloured,
               noise_colour=colour, horizon_samples=int(used))
    if coloured:
        out["short_lag_share"] = _share_interval(np.concatenate(short_terms), np.concatenate(powers), 0, 0)["share"]
    return out


def colour_note(structure: dict, heldout_by_channel: dict) -> str | None:
    """The report's note on coloured noise (None when every channel's noise is white): what was found and what
    the tool did with it."""
    coloured = structure.get("coloured_channels") or []
    if not coloured:
        return None
    parts = []
    for ch in coloured:
        c = structure["noise_colour"][ch]
        ratio = max(c["power_ratio"], 1.0)
        corr = c["correlation_samples"]
        parts.append(f"'{ch}' ({ratio:.1f}x the power that second differences see"
                     + (f", correlated over ~{corr} samples" if corr else "") + ")")
    total = [heldout_by_channel[ch] / np.sqrt(max(structure["noise_colour"][ch]["power_ratio"], 1.0))
             for ch in coloured if ch in heldout_by_channel]
    return (f"the noise is coloured on {', '.join(parts)}: on the fitting block the residual is correlated over a "
            "few samples in a way that does not follow the drive, which is taken for sensor noise, so there "
            f"materiality is read between moments of the same drive state at least {structure['horizon_samples']} "
            "samples apart "
            "(assumed: the noise decorrelates within them, a model error follows the drive): "
            f"{100 * structure['share']:.0f} % of the noise power, where "
            f"lags 1-3 would read {100 * structure['short_lag_share']:.0f} %; held-out errors stay in units of the "
            "white part (in units of the total noise the base model's held-out RMSE on "
            + ", ".join(f"'{ch}' is {t:.2f}" for ch, t in zip(coloured, total)) + ")")


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
