"""Stage 5: the report -- a plain-words paragraph, a JSON file and PNG plots."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..physics.constants import ROOM_TEMPERATURE
from .effects import (EFFECT_PARAMETERS, EFFECT_WORDS, EVEN_LAW_NAMES, INPUT_MAP_NAMES, SENSOR_MAP_NAMES,
                      effect as registered, record_temperature_rise, temperature_rise_trace, thermal_change_words)
from ..physics.anhysteretic import anhysteretic_magnetization
from .fit import FitResult
from .kernels import MIN_RELATIVE_STIFFNESS
from .model import (FEM_ROD_NAMES, channel_range, even_law_forcing, mapped_field, relative_stiffness_change,
                    slope_factor)

# EFFECT_WORDS (each effect's sentence) and the thermal words are the registry's (:mod:`.effects`);
# they stay importable here.
__all__ = ["EFFECT_WORDS", "UNITS", "explain", "physical_params", "record_temperature_rise", "slot_shapes",
           "temperature_rise_trace", "thermal_change_words", "write_json", "write_plots"]
UNITS = {"H0": "A/m", "k_e": "s", "heating": "K/s per (A/m)^2", "heating_exponent": "", "tau_th": "s", "beta_Ms": "1/K",
         "tau_th2": "s", "thermal_share": "",
         "tau_m": "s", "tau_x": "s", "tau2_m": "s", "tau2_x": "s", "tau2_in": "s", "zeta_q": "m/s^2 per (A/m)^2",
         "zeta_4": "m/s^2 per A/m", "f2": "Hz", "damping2": "", "g2": "",
         "delta_e": "", "delta_e_linear": "", "delta_e_cubic": "", "delta_e_quartic": "",
         "chi_r": "", "knee_log_p": "", "a": "A/m", "k": "A/m", "Ms": "A/m", "c": "", "alpha": "",
         "Y": "Pa", "ML": "kg", "cD": "Pa s", "cL": "N s/m", "khat": "1/s^2", "chat": "1/s"}


def physical_params(fit: FitResult) -> dict:
    """Fitted values in physical units, with alpha recovered from the fitted feedback rho."""
    values = dict(fit.values)
    curve = fit.model.structure.curve
    values["alpha"] = values["rho"] * values["a"] / (values["Ms"] * slope_factor(curve))
    values["anhysteretic"] = curve
    return values


def _fmt(name, values, sigmas):
    value = values[name]
    sigma = sigmas.get(name)
    unit = UNITS.get(name, "")
    text = f"{name} = {value:.4g}"
    if sigma is not None and np.isfinite(sigma):
        text += f" +- {sigma:.2g}"
    return text + (f" {unit}" if unit else "")


def slot_shapes(fit) -> list:
    """The fitted shape of the slot an extension fills, as curves to plot:
    ``(file stem, title, x label, y label, [(label, x, y), ...])`` per plot
    empty for extensions
    whose shape is a number (a lag, a bias)."""
    values, rec = fit.values, fit.model.recording
    effect = fit.model.structure.extension
    if effect == "delta_e":
        m = np.linspace(-values["Ms"], values["Ms"], 201)
        # clipped as the simulation clips it (kernels.varying_stiffness_response): the plot shows the law that ran
        stiffness = values["khat"] * (1.0 + np.maximum(relative_stiffness_change(m, values), MIN_RELATIVE_STIFFNESS))
        return [("stiffness", "Stiffness against magnetization (Delta-E family)", "M (A/m)", "khat(M) (1/s^2)",
                 [("fitted", m, stiffness), ("without the effect", m, np.full_like(m, values["khat"]))])]
    if effect == "input_map":
        # the map's frame is max|H| of the record: evaluate it on a grid spanning exactly that range
        peak = float(np.max(np.abs(rec.field)))
        h = np.linspace(-peak, peak, 201)
        shape = [values[n] for n in INPUT_MAP_NAMES]
        return [("input_map", "Input map: true field against recorded field", "recorded H (A/m)", "true H (A/m)",
                 [("fitted", h, mapped_field(h, *shape)), ("identity", h, h)])]
    if effect == "sensor_map":
        curves = []
        for channel in fit.model.channels:
            q2, q3 = (values[n] for n in SENSOR_MAP_NAMES[channel])
            centre, half = channel_range(rec.output(channel))
            y = np.linspace(centre - half, centre + half, 201)
            v = (y - centre) / half
            curves.append((f"{channel} (fitted)", y, y + half * (q2 * v ** 2 + q3 * v ** 3)))
        return [("sensor_map", "Sensor static map: reading against true output", "true output", "reading",
                 curves)]
    if effect == "sensor_drift":
        model = fit.model
        curves = []
        for channel in model.channels:
            plain = {**values, **{n: 0.0 for n in EFFECT_PARAMETERS["sensor_drift"]}}
            curves.append((channel, rec.time, (model.predict(values)[channel] - model.predict(plain)[channel])
                           / channel_range(rec.output(channel))[1]))
        return [("sensor_drift", "Sensor offset drift", "time (s)", "offset / channel half-span", curves)]
    if effect == "thermal_drift":
        rise = temperature_rise_trace(rec, values)
        a_t = values["a"] * (ROOM_TEMPERATURE + rise) / ROOM_TEMPERATURE
        # Ms, k and c as the kernel (kernels.simulate_members) moves them, with its limits: Ms and k floored at
        # 1e-3 of their start, c kept in [0, 0.999]; a curve whose limit binds says so in its label
        ms_raw = 1.0 - values.get("beta_Ms", 0.0) * rise
        k_raw = 1.0 - values.get("beta_k", 0.0) * rise
        c_raw = values["c"] * (1.0 - values.get("beta_c", 0.0) * rise)
        ms_t, k_t, c_t = np.maximum(ms_raw, 1e-3), np.maximum(k_raw, 1e-3), np.clip(c_raw, 0.0, 0.999)

        def label(name, raw, kept):
            return name if np.array_equal(raw, kept) else f"{name} (at the kernel's limit for part of the record)"

        curves = [("a(t)", rec.time, a_t / a_t[0]), (label("Ms(t)", ms_raw, ms_t), rec.time, ms_t / ms_t[0])]
        if values.get("beta_k", 0.0):
            curves.append((label("k(t)", k_raw, k_t), rec.time, k_t / k_t[0]))
        if values.get("beta_c", 0.0) and values["c"]:
            curves.append((label("c(t)", c_raw, c_t), rec.time, c_t / c_t[0]))
        return [("material_drift", "Material parameters over the record (relative to the start)", "time (s)",
                 "value / value at t = 0", curves)]
    if effect == "anhysteretic_shape":
        return [_anhysteretic_shape(fit)]
    if effect == "quadratic_magnetostriction" and "zetahat" in values:
        # the law as the fitted forcing (gain units x A/m) over M, against the M^2 law with the same M and M^2
        # gains (the even terms 0): where they part, the even terms carry the law
        m = np.linspace(-values["Ms"], values["Ms"], 201)
        deviation = m - values["M0"]
        quadratic = values["zetahat"] * deviation + values.get("zeta_q", 0.0) * deviation ** 2
        even = even_law_forcing(m, values["Ms"], values["M0"], {n: values.get(n, 0.0) for n in EVEN_LAW_NAMES})
        return [("magnetostriction", "Magnetostriction law: fitted forcing against M", "M (A/m)",
                 "forcing (gain units x A/m)", [("fitted", m, quadratic + even), ("M^2 law alone", m, quadratic)])]
    return []


def _anhysteretic_shape(fit):
    """The fitted anhysteretic curve (the family's mixture, its Ising phase with the fitted knee exponent) against
    the two textbook curves (2), (3) at the initial slope of the phase that weighs more, over six of its widths."""
    values, structure = fit.values, fit.model.structure
    a, weight = values["a"], values.get("mix_weight", 0.0)
    knee = float(np.exp(values.get("knee_log_p", 0.0)))  # the Ising phase's knee exponent (Model.magnetic_row)

    def phase(a_phase, curve):
        return anhysteretic_magnetization(h, a_phase, 1.0, curve, knee_exponent=knee if curve == "ising" else 1.0)[0]

    # the textbook curves at the initial slope of the phase that weighs more (under an Ising base, w = 1 is the
    # knee curve alone, whose a is a*r), over six of its widths
    ratio = slope_factor(structure.anhysteretic) / slope_factor(structure.curve)
    swapped_a = a if weight <= 0.5 else a * values.get("mix_a_ratio", 1.0) / ratio
    h = np.linspace(-6.0 * swapped_a, 6.0 * swapped_a, 241)
    swapped = anhysteretic_magnetization(h, swapped_a, 1.0, structure.curve)[0]
    base = anhysteretic_magnetization(h, swapped_a * ratio, 1.0, structure.anhysteretic)[0]
    fitted = ((1.0 - weight) * phase(a, structure.curve)
              + weight * phase(a * values.get("mix_a_ratio", 1.0), structure.anhysteretic))
    return ("anhysteretic", "Anhysteretic curve: fitted family against the textbook laws", "H_eff (A/m)",
            "Man / Ms", [(f"fitted (knee exponent p = {knee:.3g})" if knee != 1.0 else "fitted", h, fitted),
                         (f"{structure.curve} (textbook)", h, swapped),
                         (f"{structure.anhysteretic} (textbook, same initial slope)", h, base)])


def explain(report) -> str:
    """One paragraph in plain words: the effect, the evidence, the added model, the errors,
    then whatever the checks of :mod:`.decide` found (rejected candidates, pinned mechanics)."""
    text = _verdict_words(report)
    if report.notes:
        text += " Notes: " + "; ".join(report.notes) + "."
    return text


def _verdict_words(report) -> str:
    base = report.baseline_heldout
    loc = report.located["summary"]
    if report.verdict == "none":
        best = max(report.candidates, key=lambda c: c.improvement, default=None)
        tail = (f" The best extension ({best.effect}) changed the held-out error by only "
                f"{100 * best.improvement:.1f} %." if best else "")
        return (f"The base model ({report.structure.transducer}, {report.structure.anhysteretic}) explains this "
                f"recording to within noise: its held-out RMSE is {base:.2f} noise units on the last "
                f"{100 * (1 - report.split_index / report.baseline.model.recording.size):.0f} % of the record, "
                f"and no extension from the vocabulary beats it beyond noise.{tail} Verdict: none.")
    if report.verdict == "ambiguous":
        listed = ", ".join(f"{c.effect} ({100 * c.improvement:.0f} % lower held-out RMSE, "
                           f"{c.heldout_rmse:.2f} noise units)" for c in report.tied)
        return (f"The base model misses (held-out RMSE {base:.2f} noise units): {loc}. Several extensions explain "
                f"the held-out block about equally well: {listed}. The channels recorded here cannot tell them "
                f"apart. To separate them: {report.advice}. Verdict: ambiguous (confidence {report.confidence:.2f}).")
    if report.verdict == "unexplained":
        ranked = sorted(report.candidates, key=lambda c: -c.improvement)
        tried = ", ".join(f"{c.effect} {100 * c.improvement:+.0f} %" for c in ranked[:3])
        return (f"The base model leaves a structured residual (held-out RMSE {base:.2f} noise units, where 1 is "
                f"noise): {loc}. No extension in the vocabulary explains it (best held-out changes: {tried}). "
                f"Verdict: unexplained.")
    chosen = report.chosen
    fit = chosen.fit
    names = EFFECT_PARAMETERS[chosen.effect] or ("a", "k", "alpha", "Ms", "c")
    continuum = getattr(report, "continuum", {}) or {}
    if continuum.get("named"):
        # another base (the FEM rod) or released mechanics: its own mechanical parameters tell the story
        names = FEM_ROD_NAMES if fit.model.structure.transducer == "fem" else names + ("khat", "chat")
    values = dict(fit.values)
    values.update(physical_params(fit))
    params = ", ".join(_fmt(n, values, fit.uncertainties) for n in names if fit.model.parameters.get(n) is None
                       or fit.model.parameters[n].free or n == "alpha")
    details = registered(chosen.effect).details
    extra = "" if details is None else details(values, fit.model.recording)
    if continuum.get("named"):
        extra = (f" (continuum mechanics, {continuum['explained_by']}; nominal lumped first resonance "
                 f"{continuum['first_resonance_hz']:.4g} Hz)")
    runner = sorted([c for c in report.candidates if c is not chosen], key=lambda c: -c.improvement)
    second = f" The runner-up, {runner[0].effect}, reached {100 * runner[0].improvement:.0f} %." if runner else ""
    how = "Modelling it" if continuum.get("named") else "Adding it to the base model"
    return (f"The recording shows {EFFECT_WORDS[chosen.effect]}. Evidence: {loc}. {how} "
            f"with fitted {params}{extra} lowers the held-out RMSE from {base:.2f} to {chosen.heldout_rmse:.2f} "
            f"noise units ({100 * chosen.improvement:.0f} % lower), and the BIC on the fitting block by "
            f"{report.baseline.bic - chosen.bic:.0f}.{second} Verdict: {chosen.effect} "
            f"(confidence {report.confidence:.2f}).")


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def write_json(report, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = _jsonable(report.to_json())
    data["split"]["heldout_from_time_s"] = float(report.baseline.model.recording.time[report.split_index])
    path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    return path


def write_plots(report, directory) -> list[Path]:
    """PNG plots: residual maps, loops and time traces, before (base) and after (verdict)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    base = report.baseline
    rec = base.model.recording
    after = report.chosen.fit if report.chosen is not None else None
    models = [("before (base)", base)] + ([(f"after ({report.chosen.effect})", after)] if after else [])
    predictions = [(label, fit.model.predict(fit.values)) for label, fit in models]
    cut_time = rec.time[report.split_index]
    paths = []
    channels = base.model.channels

    fig, axes = plt.subplots(len(channels), 2, figsize=(11, 3.6 * len(channels)), squeeze=False)
    for row, ch in enumerate(channels):
        for label, pred in predictions:
            r = (pred[ch] - rec.output(ch)) / report.noise[ch]
            axes[row, 0].plot(rec.time, r, ".", ms=1.5, alpha=0.5, label=label)
            axes[row, 1].plot(rec.field, r, ".", ms=1.5, alpha=0.5, label=label)
        axes[row, 0].axvline(cut_time, color="k", lw=0.8, ls="--")
        axes[row, 0].set_xlabel("time (s)  [held-out block right of the dashed line]")
        axes[row, 1].set_xlabel("field H (A/m)")
        for ax in axes[row]:
            ax.set_ylabel(f"{ch} residual (noise units)")
            ax.legend(markerscale=6, fontsize=8)
    fig.suptitle(f"Residual maps: {report.verdict}")
    fig.tight_layout()
    paths.append(directory / "residual_maps.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(1, len(channels), figsize=(5.5 * len(channels), 4.4), squeeze=False)
    for col, ch in enumerate(channels):
        ax = axes[0, col]
        ax.plot(rec.field, rec.output(ch), color="0.6", lw=0.6, label="recording")
        for label, pred in predictions:
            ax.plot(rec.field, pred[ch], lw=0.8, label=label)
        ax.set_xlabel("field H (A/m)")
        ax.set_ylabel(f"{ch} ({'A/m' if ch == 'magnetization' else 'm'})")
        ax.legend(fontsize=8)
    fig.suptitle("Loops, before and after")
    fig.tight_layout()
    paths.append(directory / "loops.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(len(channels), 1, figsize=(11, 3.2 * len(channels)), squeeze=False)
    for row, ch in enumerate(channels):
        ax = axes[row, 0]
        ax.plot(rec.time, rec.output(ch), color="0.6", lw=0.8, label="recording")
        for label, pred in predictions:
            ax.plot(rec.time, pred[ch], lw=0.8, label=label)
        ax.axvspan(cut_time, rec.time[-1], color="y", alpha=0.12, label="held out")
        ax.set_xlabel("time (s)")
        ax.set_ylabel(ch)
        ax.legend(fontsize=8, ncol=4)
    fig.tight_layout()
    paths.append(directory / "traces.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    for stem, title, xlabel, ylabel, curves in (slot_shapes(after) if after is not None else []):
        fig, ax = plt.subplots(figsize=(5.5, 4.2))
        for label, x, y in curves:
            ax.plot(x, y, lw=1.2, label=label, ls="--" if label in ("identity", "without the effect") else "-")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=8)
        fig.tight_layout()
        paths.append(directory / f"{stem}.png")
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    return paths
