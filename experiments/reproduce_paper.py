"""``hyst-gym reproduce --out DIR``: the paper's numerical examples (§4.1, §4.2, Figs. 8-11).

Writes to DIR:

* ``fig8_integrand_magnetization.png`` -- (a) the integrand of (22) at the fixed
  thetahat = 6990 A/m (a = 7012 A/m), (b) M(H(t); thetahat);
* ``fig9_scalar_estimate.png`` -- (a) thetahat and a, (b) ytilde, scalar case §4.1;
* ``fig10_vector_estimate.png`` -- thetahat and a, vector case §4.2;
* ``fig11_vector_tracking.png`` -- ytilde1 (m) and ytilde2 (m/s), vector case;
* ``fig_gradient_failure.png`` -- gradient vs min-max adaptation at a high gain;
* ``fig_gradient_drift.png`` -- continuous-time drift of the gradient law on a
  non-monotone f (the mechanism of §1), min-max beside it;
* ``summary.json`` -- final estimates, settle times, settings, the gradient case.

The true plant is :mod:`hyst_gym.physics.transducers` (first-order plant and the
lumped model (13)) driven by the hysteresis model (6) at a = 7012 A/m; the estimators
are :mod:`hyst_gym.estimation`. A settle time is the first time after which
|thetahat - a| stays within ``settle_band`` (0.1 % of a) to the end; null if never.
"""

from __future__ import annotations

import json
import pathlib

import numpy as np
from tqdm import tqdm

from hyst_gym.estimation import EstimatorConfig, ModelBank, PEMonitor, make_estimator
from hyst_gym.physics import HysteresisParams, simulate_magnetization
from hyst_gym.physics.transducers import FirstOrderPlant as TruePlant
from hyst_gym.physics.transducers import LumpedLinear

A_TRUE = 7012.0  # A/m, §4
THETA0 = 6990.0  # A/m, §4
RAMP_PEAK = 1e5  # A/m reached at the end of the 6 s ramp
DURATION = 6.0  # s
#: gradient-failure case: same ramp and plant, a high adaptation gain at a 1 ms step
FAILURE_GAMMA = 1e5
FAILURE_FINE_DT = 2.5e-4
#: continuous-time drift case (§1): the visibly hysteretic parameter set (shared reference
#: data ``ja_golden_params.json`` -> "hysteretic"), a wide Theta, a 10 ms saturating pulse,
#: then the field held at DRIFT_HOLD_FIELD on the descending branch, where M(H; a) has an
#: interior maximum in a (near a = 6000 A/m) between thetahat(0) and a.
DRIFT_HYSTERESIS = HysteresisParams(a=A_TRUE, k=4000.0, alpha=-0.01, Ms=7.65e5, c=0.18)
DRIFT_THETA = (3000.0, 12000.0)  # A/m
DRIFT_GRID = 128
DRIFT_GAMMA = 100.0
DRIFT_THETA0 = 5500.0  # A/m, left of the maximum of f(., t) in a; a is right of it
DRIFT_PULSE_S = 0.01  # s for each of the ramps 0 -> RAMP_PEAK -> DRIFT_HOLD_FIELD
DRIFT_HOLD_FIELD = -1100.0  # A/m
DRIFT_HOLD_S = 10.0


def configure_parser(parser):
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    parser.add_argument("--grid-size", type=int, default=64, help="bank grid size G (16..128, default 64)")
    parser.add_argument("--dt", type=float, default=1e-3, help="control step in s (default 1e-3)")


def settle_time(time, estimates, a_true, band):
    """First time after which |estimate - a| <= band to the end; None if never."""
    outside = np.flatnonzero(np.abs(estimates - a_true) > band)
    if outside.size == 0:
        return float(time[0])
    if outside[-1] == estimates.size - 1:
        return None
    return float(time[outside[-1] + 1])


def plant_outputs(magnetization, dt, vector):
    model = (LumpedLinear() if vector else TruePlant()).discretize(dt)
    state = model.initial_state(1)
    out = np.empty((magnetization.size, 2 if vector else 1))
    out[0] = 0.0
    for i in range(1, magnetization.size):
        state = model.advance(state, magnetization[i - 1:i], magnetization[i:i + 1])
        out[i, 0] = model.output(state)[0]
        if vector:
            out[i, 1] = model.velocity(state)[0]
    return out


def run(name, config, field, outputs, dt, label):
    """Drive one estimator (E = 1) along the record; returns per-sample arrays."""
    estimator = make_estimator(name, config, 1)
    monitor = PEMonitor(1, config.pe_window)
    n = field.size
    estimates = np.empty(n)
    tracking = np.empty((n, outputs.shape[1]))
    estimates[0] = estimator.a_estimate[0]
    tracking[0] = 0.0
    integrand = np.zeros(n)
    for i in tqdm(range(1, n), desc=label, leave=False, disable=None):
        measured = outputs[i][None, :] if config.is_vector else outputs[i]
        estimates[i] = estimator.update(field[i:i + 1], measured, dt)[0]
        tracking[i] = estimator.tracking_error
        integrand[i] = estimator.pe_integrand(A_TRUE)[0]
        monitor.update(integrand[i:i + 1], estimator.curvature_sign, dt)
    pe = {key: value[0] for key, value in monitor.summary().items()}
    return {"estimate": estimates, "tracking": tracking, "integrand": integrand, "pe": pe}


def drift_field(dt, hold_s=DRIFT_HOLD_S):
    """Saturating pulse (0 -> RAMP_PEAK -> DRIFT_HOLD_FIELD, DRIFT_PULSE_S each), then held."""
    steps = int(round(DRIFT_PULSE_S / dt))
    return np.concatenate([np.linspace(0.0, RAMP_PEAK, steps + 1),
                           np.linspace(RAMP_PEAK, DRIFT_HOLD_FIELD, steps + 1)[1:],
                           np.full(int(round(hold_s / dt)), DRIFT_HOLD_FIELD)])


def drift_case(dt, hold_s=DRIFT_HOLD_S):
    """Gradient and min-max on the drift case at step ``dt`` (s).

    Returns the sample times, both estimate records and f(theta) over the bank grid at the
    end (the held field, where f(u, .) is not monotone in theta).
    """
    config = EstimatorConfig.paper_scalar(hysteresis=DRIFT_HYSTERESIS, theta_min=DRIFT_THETA[0],
                                          theta_max=DRIFT_THETA[1], grid_size=DRIFT_GRID, gamma=DRIFT_GAMMA,
                                          initial_estimate=DRIFT_THETA0)
    field = drift_field(dt, hold_s)
    params = dict(DRIFT_HYSTERESIS.__dict__)
    outputs = plant_outputs(simulate_magnetization(field, **params), dt, vector=False)
    estimates = {name: run(name, config, field, outputs, dt, f"drift {name}")["estimate"]
                 for name in ("gradient", "minmax")}
    bank = ModelBank(config, 1)
    for value in field[1:]:
        bank.advance(np.array([value]))
    return {"time": np.arange(field.size) * dt, "estimates": estimates, "grid": config.theta_grid,
            "landscape": bank.magnetization[0].copy(), "config": config}


def spurious_point(grid, landscape, a_true, start):
    """The theta on ``start``'s side of the maximum of f(u, .) at which f(theta) = f(a)
    (the false equilibrium of the gradient law on a held input), or None if none."""
    f_true = np.interp(a_true, grid, landscape)
    peak = grid[np.argmax(landscape)]
    side = np.linspace(grid[0], peak, 20001) if start < peak else np.linspace(peak, grid[-1], 20001)
    values = np.interp(side, grid, landscape) - f_true
    change = np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))
    if change.size == 0:
        return None
    i = change[-1] if start < peak else change[0]
    return float(side[i] - values[i] * (side[i + 1] - side[i]) / (values[i + 1] - values[i]))


def fixed_estimate_integrand(config, field):
    """Fig. 8a: beta*nu*(f(thetahat) - f(a)) with thetahat held at 6990 A/m."""
    bank = ModelBank(config, 2)
    points = np.array([THETA0, A_TRUE])
    integrand = np.zeros(field.size)
    magnetization = np.zeros(field.size)
    beta = np.ones(field.size)
    for i in range(1, field.size):
        bank.advance(np.full(2, field[i]))
        value, _, curvature = bank.evaluate(points)
        beta[i] = 1.0 if curvature[0] >= 0 else -1.0
        integrand[i] = beta[i] * config.plant.gain * (value[0] - value[1])
        magnetization[i] = value[0]
    return integrand, magnetization, beta


def main(args) -> int:
    if not (np.isfinite(args.dt) and 0 < args.dt <= 0.01):
        raise ValueError(f"--dt must be in (0, 0.01] s, got {args.dt!r}")
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    dt = float(args.dt)
    time = np.arange(0.0, DURATION + dt / 2, dt)
    field = RAMP_PEAK * time / DURATION
    scalar_config = EstimatorConfig.paper_scalar(grid_size=args.grid_size)
    vector_config = EstimatorConfig.paper_vector(grid_size=args.grid_size)
    results, scalar_out = _paper_runs(scalar_config, vector_config, field, dt)
    failure_config = scalar_config.replace(gamma=FAILURE_GAMMA)
    failure, fine, fine_time = _failure_runs(failure_config, field, scalar_out, dt)
    integrand8, magnetization8, beta8 = fixed_estimate_integrand(scalar_config, field)
    _figures(out, time, field, integrand8, magnetization8, beta8, results, failure)
    drift = drift_case(dt)
    drift_fine = drift_case(dt / 4)
    _drift_figure(out, drift)

    summary = {
        "a_true": A_TRUE,
        "settle_band": SETTLE_BAND,
        "settings": _settings(dt, args.grid_size, scalar_config, vector_config),
        "scalar": _case(results["scalar"], time),
        "vector": _case(results["vector"], time),
        "baselines": {key: _case(results[key], time)
                      for key in ("scalar_gradient", "scalar_multiple_model", "vector_gradient")},
        "figure8": {"thetahat": THETA0, "integrand_max": float(np.max(integrand8)),
                    "integrand_min": float(np.min(integrand8)),
                    "beta_changes_sign": bool(np.any(beta8 > 0) and np.any(beta8 < 0))},
        "gradient_failure": _failure_summary(failure, failure_config, fine, fine_time, time, dt,
                                             _drift_summary(drift, drift_fine, dt)),
    }
    for key in ("scalar", "vector"):
        for field_name in ("final_a_estimate", "settle_time_s"):
            summary[f"{key}.{field_name}"] = summary[key][field_name]
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    print(f"scalar: final a_estimate {summary['scalar']['final_a_estimate']:.2f} A/m, "
          f"settle {summary['scalar']['settle_time_s']} s; vector: final {summary['vector']['final_a_estimate']:.2f} "
          f"A/m, settle {summary['vector']['settle_time_s']} s; wrote {out}/summary.json and 6 figures")
    return 0


#: the settle band of the summary: 0.1 % of the true a
SETTLE_BAND = 1e-3 * A_TRUE


def _paper_runs(scalar_config, vector_config, field, dt):
    """The paper's cases on the ramp (§4.1 scalar, §4.2 vector) and the baselines on the same
    outputs: ``(results by key, the scalar plant's outputs)``."""
    magnetization = simulate_magnetization(field, a=A_TRUE)
    scalar_out = plant_outputs(magnetization, dt, vector=False)
    vector_out = plant_outputs(magnetization, dt, vector=True)
    results = {}
    for key, name, config, outputs in (
        ("scalar", "minmax", scalar_config, scalar_out),
        ("scalar_gradient", "gradient", scalar_config, scalar_out),
        ("scalar_multiple_model", "multiple_model", scalar_config, scalar_out),
        ("vector", "minmax", vector_config, vector_out),
        ("vector_gradient", "gradient", vector_config, vector_out),
    ):
        results[key] = run(name, config, field, outputs, dt, key)
    return results, scalar_out


def _failure_runs(failure_config, field, scalar_out, dt):
    """Min-max and gradient at gamma = FAILURE_GAMMA on the ramp, at ``dt`` and at the fine
    step: ``(at dt, at the fine step, the fine time axis)``."""
    failure = {name: run(name, failure_config, field, scalar_out, dt, f"gamma=1e5 {name}")
               for name in ("minmax", "gradient")}
    fine_time = np.arange(0.0, DURATION + FAILURE_FINE_DT / 2, FAILURE_FINE_DT)
    fine_field = RAMP_PEAK * fine_time / DURATION
    fine_out = plant_outputs(simulate_magnetization(fine_field, a=A_TRUE), FAILURE_FINE_DT, vector=False)
    fine = {name: run(name, failure_config, fine_field, fine_out, FAILURE_FINE_DT, f"fine {name}")
            for name in ("minmax", "gradient")}
    return failure, fine, fine_time


def _case(result, samples):
    """Final estimate, settle time into the band and the largest error over the second half."""
    estimate = result["estimate"]
    return {"final_a_estimate": float(estimate[-1]),
            "settle_time_s": settle_time(samples, estimate, A_TRUE, SETTLE_BAND),
            "max_abs_error_after_half_time": float(np.max(np.abs(estimate[samples >= DURATION / 2] - A_TRUE))),
            "pe": result["pe"]}


def _bounds_share(result, config):
    """Share of the samples at which the estimate sits on a bound of Theta."""
    estimate = result["estimate"]
    return float(np.mean((estimate <= config.theta_min + 1e-6) | (estimate >= config.theta_max - 1e-6)))


def _settings(dt, grid_size, scalar_config, vector_config):
    return {
        "dt_s": dt, "duration_s": DURATION, "ramp_peak_field": RAMP_PEAK, "grid_size": grid_size,
        "theta_bounds": [scalar_config.theta_min, scalar_config.theta_max], "initial_estimate": THETA0,
        "scalar": {"lambda": scalar_config.plant.decay_rate, "nu": scalar_config.plant.gain, "eps": scalar_config.eps,
                   "gamma": scalar_config.gamma},
        "vector": {"A": vector_config.plant.A, "B": vector_config.plant.B, "Q": vector_config.plant.Q,
                   "P": vector_config.plant.lyapunov_matrix.tolist(), "eps": vector_config.eps,
                   "gamma": vector_config.gamma},
        "hysteresis": {k: v for k, v in HysteresisParams().__dict__.items() if k != "a"},
        "max_field_step": scalar_config.max_field_step,
    }


def _failure_summary(failure, failure_config, fine, fine_time, time, dt, continuous_time):
    return {
        "description": ("same ramp, plant and eps; adaptation gain gamma = 1e5 at the 1 ms control step. "
                        "Gradient adaptation overshoots and hits the bounds of Theta; min-max stays near a. "
                        "The same gain at dt = 2.5e-4 s is stable for both: this is a sampled-data "
                        "instability of the gradient law, not the continuous-time drift of the paper's §1"),
        "gamma": FAILURE_GAMMA,
        "dt_s": dt,
        "minmax": {**_case(failure["minmax"], time),
                   "share_of_time_at_bounds": _bounds_share(failure["minmax"], failure_config)},
        "gradient": {**_case(failure["gradient"], time),
                     "share_of_time_at_bounds": _bounds_share(failure["gradient"], failure_config)},
        "fine_dt_s": FAILURE_FINE_DT,
        "fine_minmax_max_abs_error_after_half_time":
            _case(fine["minmax"], fine_time)["max_abs_error_after_half_time"],
        "fine_gradient_max_abs_error_after_half_time":
            _case(fine["gradient"], fine_time)["max_abs_error_after_half_time"],
        "continuous_time": continuous_time,
    }


def _drift_summary(drift, drift_fine, dt):
    def errors(result):
        return {name: {"initial_abs_error": float(abs(est[0] - A_TRUE)), "final_a_estimate": float(est[-1]),
                       "final_abs_error": float(abs(est[-1] - A_TRUE)),
                       "max_abs_error": float(np.max(np.abs(est - A_TRUE)))}
                for name, est in result["estimates"].items()}
    return {
        "description": ("continuous-time drift of the gradient law (paper §1): 'hysteretic' parameters, a 10 ms "
                        "pulse to 1e5 A/m and back to the held field, on the descending branch where M(H; a) has "
                        "a maximum in a between thetahat(0) and a. Gradient adaptation walks AWAY from a to the "
                        "false equilibrium f(thetahat) = f(a) on the far side of the maximum; min-max never "
                        "increases |thetahat - a|. The held input carries no information that separates a from "
                        "that point, so min-max does not converge to a either (it stops in between)."),
        "hysteresis": dict(DRIFT_HYSTERESIS.__dict__), "theta_bounds": list(DRIFT_THETA),
        "grid_size": DRIFT_GRID, "gamma": DRIFT_GAMMA, "initial_estimate": DRIFT_THETA0,
        "pulse_s": DRIFT_PULSE_S, "hold_field": DRIFT_HOLD_FIELD, "hold_s": DRIFT_HOLD_S,
        "eps": drift["config"].eps, "dt_s": dt, "fine_dt_s": dt / 4,
        "f_maximum_at_theta": float(drift["grid"][np.argmax(drift["landscape"])]),
        "false_equilibrium_theta": spurious_point(drift["grid"], drift["landscape"], A_TRUE, DRIFT_THETA0),
        "at_dt": errors(drift), "at_fine_dt": errors(drift_fine),
    }


def _drift_figure(out, drift):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    axes[0].plot(drift["grid"], drift["landscape"] / 1e3, ".-", ms=3)
    for value, color, style, label in ((A_TRUE, "k", "-", "true a"), (DRIFT_THETA0, "C2", "--", "thetahat(0)"),
                                       (drift["estimates"]["gradient"][-1], "C1", ":", "gradient, end"),
                                       (drift["estimates"]["minmax"][-1], "C0", "-.", "min-max, end")):
        axes[0].axvline(value, color=color, ls=style, lw=1, label=label)
    axes[0].set(xlabel="theta (A/m)", ylabel="f = M(H history; theta) (kA/m)",
                title=f"(a) f over Theta at the held field {DRIFT_HOLD_FIELD:g} A/m")
    axes[0].legend(fontsize=8)
    for name, label in (("gradient", "gradient"), ("minmax", "min-max")):
        axes[1].plot(drift["time"], drift["estimates"][name], label=label)
    axes[1].axhline(A_TRUE, color="k", lw=0.8, label="true value")
    axes[1].set(xlabel="Time (s)", ylabel="a (A/m)", title=f"(b) estimates, gamma = {DRIFT_GAMMA:g}")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "fig_gradient_drift.png", dpi=120)
    plt.close(fig)


def _figures(out, time, field, integrand8, magnetization8, beta8, results, failure):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    axes[0].plot(time, integrand8)
    axes[0].set(xlabel="Time (s)", ylabel="integrand of (22) (A/m)",
                title="(a) beta*nu*(f(6990) - f(7012))")
    axes[1].plot(time, magnetization8)
    axes[1].set(xlabel="Time (s)", ylabel="Magnetization (A/m)", title="(b) M(H(t); thetahat)")
    fig.tight_layout()
    fig.savefig(out / "fig8_integrand_magnetization.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for key, style, label in (("scalar", "-", "min-max"), ("scalar_gradient", ":", "gradient"),
                              ("scalar_multiple_model", "--", "multiple-model")):
        axes[0].plot(time, results[key]["estimate"], style, label=label)
    axes[0].axhline(A_TRUE, color="k", lw=0.8, label="true value")
    axes[0].set(xlabel="Time (s)", ylabel="a (A/m)", title="(a) estimate of a, scalar case", ylim=(6960, 7020))
    axes[0].legend()
    axes[1].plot(time, results["scalar"]["tracking"][:, 0])
    axes[1].set(xlabel="Time (s)", ylabel="tracking error ytilde", title="(b) ytilde, min-max")
    fig.tight_layout()
    fig.savefig(out / "fig9_scalar_estimate.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    ax.plot(time, results["vector"]["estimate"], label="min-max (24)-(25)")
    ax.plot(time, results["vector_gradient"]["estimate"], ":", label="gradient")
    ax.axhline(A_TRUE, color="k", lw=0.8, label="true value")
    ax.set(xlabel="Time (s)", ylabel="a (A/m)", title="estimate of a, vector case", ylim=(6970, 7020))
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "fig10_vector_estimate.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    axes[0].plot(time, results["vector"]["tracking"][:, 0])
    axes[0].set(xlabel="Time (s)", ylabel="ytilde1 (m)", title="(a) displacement error")
    axes[1].plot(time, results["vector"]["tracking"][:, 1])
    axes[1].set(xlabel="Time (s)", ylabel="ytilde2 (m/s)", title="(b) velocity error")
    fig.tight_layout()
    fig.savefig(out / "fig11_vector_tracking.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    ax.plot(time, failure["gradient"]["estimate"], lw=0.8, label="gradient")
    ax.plot(time, failure["minmax"]["estimate"], label="min-max")
    ax.axhline(A_TRUE, color="k", lw=0.8, label="true value")
    ax.set(xlabel="Time (s)", ylabel="a (A/m)", title=f"gamma = {FAILURE_GAMMA:g}, dt = 1 ms")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "fig_gradient_failure.png", dpi=120)
    plt.close(fig)
