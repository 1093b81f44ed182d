"""Rayleigh-type extensions tried against the MnZn ferrite's 8 A/m miss (docs/results/real-loops.md).

The selection rule of ``experiments/real_loops.py`` (fit on the largest loop, choose by the second largest)
chooses ``ising + small_loop`` on the MnZn ferrite, which predicts its 8 A/m loop at 9.0 %. This script
fits two extensions with a low-field (Rayleigh) mechanism, each to the largest loop only, exactly as the
study's candidates, and reads them as the rule would (validation loop, then the smaller loops). They
are not candidates of the study: they were built after every loop of the shipped sets had been seen, so
they are reported here as what was tried, not chosen by anything.

1. ``reversal_pinning``: (6) with the small-loop extension and the physics layer's reversal-dependent
   pinning (``hysteresis.REVERSAL_PINNING``): right after a reversal only the reversible susceptibility
   acts and the irreversible term builds up linearly with |H - H_rev| (Rayleigh's law), over
   ``rayleigh_field``, fitted with the other six parameters (starts: the study's fit, rayleigh_field 0.1,
   0.3, 1 and 3 times its k).
2. ``rayleigh_population``: the HEM with the normal interaction density, the saturating reversible part and
   the anhysteretic population, plus relays of low coercivity with a uniform coercive density on
   [0, h_R] (eight nodes, the interaction density of the lognormal relays): a Preisach density that is
   finite at the origin, which is what gives the Rayleigh law at low amplitude. One linear (its
   magnetization) and one nonlinear parameter (h_R); starts: the study's fit with h_R 0.02 ... 0.5 of the
   peak field, and the best 10 of 300 random points of the box (seeded).

Besides, for each loop, the relative permeability right after the field reversal (slope of B/mu0 over the first
10 % of the field range after the minimum), measured and predicted by the chosen candidate and by the HEM
with the population: the reversible permeability the small loops start from. And the chosen fit's limit for
loops of vanishing amplitude, 1 + ``hysteresis.initial_susceptibility``, with the gain by which the mean field
amplifies its reversible part there.

    .venv/bin/python -m experiments.real_loops_extensions   # writes real_loops_extensions.json and the page section
"""

from __future__ import annotations

import json
import os
import time

import numpy as np
from scipy.optimize import least_squares

from experiments import real_loops as rl
from hyst_gym.diagnose.report import physical_params
from hyst_gym.diagnose.model import noise_level
from hyst_gym.physics.anhysteretic import anhysteretic_magnetization
from hyst_gym.physics.hem import HEMBatch, simulate_hem_batch
from hyst_gym.physics.hysteresis import HysteresisBatch, HysteresisParams, initial_susceptibility, simulate_batch

JSON = rl.RESULTS / "real_loops_extensions.json"
AREA = "real-loops-extensions"
#: Starts of rayleigh_field, in units of the fitted k.
RAYLEIGH_FIELD_STARTS = (0.1, 0.3, 1.0, 3.0)
#: Nodes of the uniform low-coercivity density and the starts of its width h_R (units of the peak field).
UNIFORM_NODES = 8
UNIFORM_WIDTH_STARTS = (0.02, 0.05, 0.1, 0.2, 0.5)
UNIFORM_WIDTH_BOUNDS = (1e-3, 2.0)
RANDOM_POINTS, RANDOM_REFINED, SEED = 300, 10, 0
CHOSEN, HEM = "ising + small_loop", "hem normal + saturating reversible + anhysteretic population"


def largest_loop(stem):
    loops = rl.load_loops(stem)
    order = np.argsort([-np.max(np.abs(h)) for h, _ in loops])
    rec = rl.loop_recording([loops[order[0]]], f"{stem} largest loop")
    mask = np.zeros(rec.size, bool)
    mask[loops[order[0]][0].size:] = True
    return loops, order, rec, mask


def loop_nrmse(loops, order, magnetization_of):
    """``{"<peak> A/m": NRMSE of B}`` of every loop (largest first), ``magnetization_of(field)`` the model's M
    along the played field (warm-up and scored cycle, started demagnetized at H = 0)."""
    out = {}
    for j in order:
        H, B = loops[j]
        rec = rl.loop_recording([(H, B)], "loop")
        out[f"{np.max(np.abs(H)):.3g} A/m"] = rl.nrmse_of_b(rec, magnetization_of(rec.field), H.size, 2 * H.size)
    return out


def study_nrmse(loops, order, fit):
    """:func:`loop_nrmse` of one of the study's fits (either kind), through the study's own prediction."""
    out = {}
    for j in order:
        H, B = loops[j]
        rec, m = rl.predict_loop(fit, H, B, "loop")
        out[f"{np.max(np.abs(H)):.3g} A/m"] = rl.nrmse_of_b(rec, m, H.size, 2 * H.size)
    return out


# ------------------------------------------------------------------ (6) with reversal-dependent pinning

def _wall_columns(z):
    """Physical parameters (a, k, alpha, Ms, c, chi_r, rayleigh_field) of rows of z = (ln a, ln k, logit rho,
    ln Ms, logit c, ln chi_r, ln rayleigh_field); rho = alpha*Ms/a < 1 (Ising curve)."""
    z = np.atleast_2d(z)
    a, Ms = np.exp(z[:, 0]), np.exp(z[:, 3])
    rho = 1.0 / (1.0 + np.exp(-z[:, 2]))
    return a, np.exp(z[:, 1]), rho * a / Ms, Ms, 1.0 / (1.0 + np.exp(-z[:, 4])), np.exp(z[:, 5]), np.exp(z[:, 6])


def wall_magnetization(field, z, step):
    """M (A/m) along ``field`` for rows of z (:func:`_wall_columns`), started demagnetized at H = 0."""
    batch = HysteresisBatch(*_wall_columns(z)[:5], "ising", *_wall_columns(z)[5:])
    return simulate_batch(np.concatenate([[0.0], field]), batch, 0.0, step)[1:]


def fit_reversal_pinning(rec, mask, base):
    """(6) + small-loop extension + reversal-dependent pinning fitted to ``rec`` on ``mask`` from the study's
    fit ``base`` (physical values): ``(z, sse)``, residuals weighed as the study's (noise level of M)."""
    step = float(np.ptp(rec.field)) / 2000
    weight = noise_level(rec.magnetization)
    rho = base["alpha"] * base["Ms"] / base["a"]

    def rows(zs):
        m = wall_magnetization(rec.field, zs, step)
        return ((m[mask] - rec.magnetization[mask, None]) / weight).T

    def jacobian(z):
        steps = 1e-5 * np.maximum(1.0, np.abs(z))
        r = rows(np.vstack([z, z + np.diag(steps)]))
        return ((r[1:] - r[:1]) / steps[:, None]).T

    best = (None, np.inf)
    for share in RAYLEIGH_FIELD_STARTS:
        z0 = np.array([np.log(base["a"]), np.log(base["k"]), np.log(rho / (1 - rho)), np.log(base["Ms"]),
                       np.log(base["c"] / (1 - base["c"])), np.log(base["chi_r"]), np.log(share * base["k"])])
        solution = least_squares(lambda z: rows(z)[0], z0, jac=jacobian, max_nfev=150, xtol=1e-10, ftol=1e-12)
        if 2 * solution.cost < best[1]:
            best = (solution.x, 2 * solution.cost)
    return best


# ------------------------------------------------------------------ HEM with a low-coercivity population

def _hem_names():
    return rl.hem_nonlinear_names(True, True) + ("uniform_width",)


def hem_columns(field, nonlinear):
    """The study's HEM columns (reversible part, lognormal relays, anhysteretic population) plus the uniform
    low-coercivity relays (M = 1), for rows of ``nonlinear`` (values of :func:`_hem_names`)."""
    nonlinear = np.atleast_2d(nonlinear)
    names = _hem_names()
    columns = rl._relay_columns(field, "normal", nonlinear[:, :-1], names[:-1])
    width, scale = nonlinear[:, -1], nonlinear[:, names.index("interaction_scale")]
    played = np.concatenate([[0.0], field])
    uniform = 0.0
    for i in range(UNIFORM_NODES):  # midpoints of equal cells of [0, h_R]; each node a point mass (one HEM node)
        batch = HEMBatch(np.ones(width.size), 0.0, width * (i + 0.5) / UNIFORM_NODES, 1e-9, scale, "normal", 1)
        uniform = uniform + simulate_hem_batch(played, batch)[1:] / UNIFORM_NODES
    return columns + [uniform]


def fit_rayleigh_population(rec, mask, base):
    """The HEM with the uniform low-coercivity relays fitted by variable projection (the study's): ``(nonlinear,
    linear, sse)``."""
    names = _hem_names()
    h_max = float(np.max(np.abs(rec.field)))
    bounds = dict(rl.HEM_BOUNDS, uniform_width=UNIFORM_WIDTH_BOUNDS)
    unit = np.array([1.0 if n == "coercive_spread" else h_max for n in names])
    lower = np.log(np.array([bounds[n][0] for n in names]) * unit)
    upper = np.log(np.array([bounds[n][1] for n in names]) * unit)

    def rows(zs):
        return rl._linear_parts(hem_columns(rec.field, np.exp(zs)), rec.magnetization, mask)[1][mask].T

    def jacobian(z):
        steps = 1e-6 * np.maximum(1.0, np.abs(z))
        r = rows(np.vstack([z, z + np.diag(steps)]))
        return ((r[1:] - r[:1]) / steps[:, None]).T

    own = np.log([getattr(base, n) for n in names[:-1]])
    starts = [np.append(own, np.log(w * h_max)) for w in UNIFORM_WIDTH_STARTS]
    points = lower + (upper - lower) * np.random.default_rng(SEED).random((RANDOM_POINTS, len(names)))
    first = np.einsum("ij,ij->i", *(2 * [rows(points)]))
    starts += list(points[np.argsort(first)[:RANDOM_REFINED]])
    best = (None, np.inf)
    for z0 in starts:
        solution = least_squares(lambda z: rows(z[None, :])[0], np.clip(z0, lower, upper), jac=jacobian,
                                 bounds=(lower, upper), max_nfev=100, xtol=1e-10, ftol=1e-12)
        if 2 * solution.cost < best[1]:
            best = (solution.x, 2 * solution.cost)
    nonlinear = np.exp(best[0])
    linear = rl._linear_parts(hem_columns(rec.field, nonlinear), rec.magnetization, mask)[0][0]
    return nonlinear, linear, best[1]


def hem_magnetization(field, nonlinear, linear):
    return sum(c * column[:, 0] for c, column in zip(linear, hem_columns(field, nonlinear)))


# ------------------------------------------------------------------ permeability after the reversal

def reversal_permeability(H, B):
    """Slope of B/mu0 over H (relative permeability) over the first 10 % of the field range after the loop minimum."""
    n, start = H.size, int(np.argmin(H))
    after = np.arange(start, start + n // 2) % n
    after = after[H[after] - H[start] <= 0.1 * np.ptp(H)]
    return float(np.polyfit(H[after], B[after], 1)[0] / rl.MU0)


def study(stem):
    loops, order, rec, mask = largest_loop(stem)
    weights = {"magnetization": noise_level(rec.magnetization)}
    step = float(np.ptp(rec.field)) / 2000
    base_fit = rl.fit_variant(rec, "ising", None, weights, mask, step)[0]
    chosen = rl.fit_variant(rec, "ising", "small_loop", weights, mask, step, base_fit)[0]
    hem = rl.fit_hem(rec, "normal", mask, saturating=True, anhysteretic=True)
    out = {"study_fits": {CHOSEN: study_nrmse(loops, order, chosen), HEM: study_nrmse(loops, order, hem)}}

    cpu = time.process_time()
    z, sse = fit_reversal_pinning(rec, mask, physical_params(chosen))
    fitted = loops[order[0]]
    base_sse = float(np.sum(((rl.predict_loop(chosen, *fitted, "fitted")[1] - rec.magnetization)[mask]
                             / weights["magnetization"]) ** 2))
    values = dict(zip(("a", "k", "alpha", "Ms", "c", "chi_r", "rayleigh_field"),
                      (float(v[0]) for v in _wall_columns(z))))
    out["reversal_pinning"] = {"nrmse_B": loop_nrmse(loops, order, lambda f: wall_magnetization(f, z, step)[:, 0]),
                               "sse_ratio": sse / base_sse, "params": values,
                               "cpu_seconds": time.process_time() - cpu}
    cpu = time.process_time()
    nonlinear, linear, sse = fit_rayleigh_population(rec, mask, hem.params)
    values = dict(zip(_hem_names(), map(float, nonlinear)))
    values.update(zip(rl.HEM_LINEAR + ("uniform_magnetization",), map(float, linear)))
    out["rayleigh_population"] = {"nrmse_B": loop_nrmse(loops, order,
                                                        lambda f: hem_magnetization(f, nonlinear, linear)),
                                  "sse_ratio": sse / hem.sse, "params": values,
                                  "cpu_seconds": time.process_time() - cpu}
    permeability = {}
    for j in order:
        H, B = loops[j]
        entry = {"measured": reversal_permeability(H, B)}
        for name, fit in ((CHOSEN, chosen), (HEM, hem)):
            other, m = rl.predict_loop(fit, H, B, "loop")
            entry[name] = reversal_permeability(H, rl.MU0 * (H + m[H.size:]))
        permeability[f"{np.max(np.abs(H)):.3g} A/m"] = entry
    out["reversal_permeability"] = permeability
    values = physical_params(chosen)
    params = HysteresisParams(**{n: float(values[n]) for n in ("a", "k", "alpha", "Ms", "c", "chi_r")},
                              anhysteretic=values["anhysteretic"])
    chi = initial_susceptibility(params)
    man_slope = float(anhysteretic_magnetization(0.0, params.a, params.Ms, params.anhysteretic)[1])
    out["initial_susceptibility"] = {"chi": chi, "feedback_gain": (chi - params.chi_r) / (params.c * man_slope)}
    return out


EXTENSIONS = {"reversal_pinning": "(6) + small_loop + reversal-dependent pinning (Rayleigh onset)",
              "rayleigh_population": "HEM normal + saturating reversible + anhysteretic population + uniform "
                                     "low-coercivity relays"}


def _cells(scores):
    values = list(scores.values())
    return f"{100 * values[0]:.2f} % | {100 * values[1]:.2f} % | " + ", ".join(
        f"{100 * v:.1f} %" for v in values[2:])


def page_section(payload) -> str:
    """The real-loops-extensions section: each extension beside the study's fit it extends, and the reversal
    permeability of every loop."""
    lines = ["| material | model | fitted loop | validation loop | predicted (smaller loops) | fitted-loop SSE / "
             "study's fit |", "|---|---|---|---|---|---|"]
    for stem, name in rl.MATERIALS.items():
        entry = payload[stem]
        for study_name, key in ((CHOSEN, "reversal_pinning"), (HEM, "rayleigh_population")):
            lines.append(f"| {name} | {study_name} (study) | {_cells(entry['study_fits'][study_name])} | 1 |")
            lines.append(f"| {name} | {EXTENSIONS[key]} | {_cells(entry[key]['nrmse_B'])} | "
                         f"{entry[key]['sse_ratio']:.3f} |")
    lines += ["", "Relative permeability right after the reversal (slope of B/µ0 over H over the first 10 % of the "
              "field range), measured and predicted from the largest loop:", "",
              f"| material | loop | measured | {CHOSEN} | hem normal + sat. + population |", "|---|---|---|---|---|"]
    for stem, name in rl.MATERIALS.items():
        for loop, values in payload[stem]["reversal_permeability"].items():
            lines.append(f"| {name} | {loop} | {values['measured']:.0f} | {values[CHOSEN]:.0f} | {values[HEM]:.0f} |")
    limits = [(rl.MATERIALS[stem], payload[stem]["initial_susceptibility"]) for stem in rl.MATERIALS
              if "initial_susceptibility" in payload[stem]]
    lines.append("\nAt vanishing amplitude the chosen fit's relative permeability tends to 1 + its initial "
                 "susceptibility (`hysteresis.initial_susceptibility`): "
                 + ", ".join(f"{name} {1 + limit['chi']:.0f}" for name, limit in limits)
                 + "; the mean field amplifies its reversible part there "
                 + " and ".join(f"{limit['feedback_gain']:.1f}-fold" for _, limit in limits) + ".")
    run = payload["run"]
    lines.append("\nFit CPU time of the extensions: " + ", ".join(
        f"{rl.MATERIALS[stem]} {payload[stem]['reversal_pinning']['cpu_seconds']:.1f} s and "
        f"{payload[stem]['rayleigh_population']['cpu_seconds']:.1f} s" for stem in rl.MATERIALS)
        + f" (1-min load average {run['load_average']:.1f}, {run['cores']} cores).")
    return "\n".join(lines)


def main(argv=None):
    payload = {stem: study(stem) for stem in rl.MATERIALS}
    payload["run"] = {"load_average": os.getloadavg()[0], "cores": os.cpu_count()}
    JSON.write_text(json.dumps(payload, indent=2, default=float) + "\n")
    from experiments.report_markdown import update_readme

    update_readme(rl.PAGE, page_section(payload), area=AREA)
    print(page_section(payload))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
