"""The mismatch tool on measured MnZn ferrite B-H loops (data/real/jamodel-loops, shipped with its MIT licence).

Conversion to recordings (documented quasi-static time axis): each measured loop (129
points, closed, in traversal order) is played twice -- a warm-up cycle, then the scored
cycle -- at a uniform 1 ms per sample. The model is rate independent, so the time axis
only orders the samples. Every model starts demagnetized at H = 0 and is brought
quasi-statically to the loop's first field. Magnetization M = B/mu0 - H (A/m).

Amplitude hold-out: every candidate model is fitted on the scored cycle of the largest loop, then
predicts the other amplitudes. Score: NRMSE of B = RMS(B_model - B_measured) / peak-to-peak B_measured
over the scored cycle.
Then ``diagnose`` runs blind on one recording holding all loops (largest first), fitting
on the first half and holding out the second half, and again on a re-sampled copy and with a
40 % held-out block (the verdict must not flip). Last, the gadolinium major loops
(``data/real/gd-temperature``) are played in order of temperature, -38 to +15 C, with the
temperature left out: a real record whose concealed effect (warming) is known.

    .venv/bin/python -m experiments.real_loops                       # the full study, shipped data
    .venv/bin/python -m experiments.real_loops --data DIR --json S.json   # score your own loops

Models (``--model``): ``domain_wall`` -- (6) with the Langevin or Ising curve, each alone and with the
small-loop extension (four candidates); ``hem`` -- the homogenized energy model of ``hyst_gym.physics.hem``
with a normal (the HEM's), Lorentzian or Student-t (2 degrees of freedom) interaction density, 16 coercive
nodes, the normal one with a saturating reversible part, and each density with the saturating reversible part
and an anhysteretic population (seven candidates, HEM_VARIANTS); ``auto`` -- all eleven (the default).

SELECTION RULE (validation loop), fixed and written here before it was run on anything. It chooses by
how a candidate transfers across amplitudes within the material, never by how well it fits the loop it
was fitted on:

1. Every candidate is fitted to the scored cycle of the target material's largest loop (nothing of it
   left out).
2. The loops are ordered by peak field, largest first. With three or more loops, the second is the
   VALIDATION LOOP: each candidate's validation score is its NRMSE of B on that loop, predicted from the
   fit of step 1. The candidate with the lowest validation score is chosen (an exact tie: the lower
   fitted-loop NRMSE). The remaining, smaller loops are the PREDICTION: the choice never reads them.
3. With two loops (or one), a validation loop would leave nothing to predict, so the choice falls back to
   the leave-one-material-out TRANSFER SCORE: every candidate is fitted the same way to each shipped,
   shared material other than the target (a folder holding a shared material's very loops does not
   count it) and predicts that material's smaller amplitudes; the transfer score is the mean over those
   materials of the worst predicted amplitude's NRMSE. The lowest transfer score is chosen; without any
   (no other shared material), the lowest fitted-loop NRMSE.

Every candidate's fitted-loop, validation and prediction numbers are reported beside the chosen one, so
that a reader sees what the rule gave up. The same rule applies to ``--data DIR`` (held-back sets).

Fitting: all starts of a variant (a grid that puts the low-field slope into c and k or chi_r, the
best points of a Sobol design and the loop-informed starts, and for the extension the base fit)
are fitted at once by :func:`batched_least_squares`, each iteration one bank of models in one
compiled call; the best is polished by the diagnose tool's local fit, which gives the uncertainties.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

from dataclasses import dataclass

import numpy as np
import scipy.io
from scipy.optimize import least_squares, nnls
from scipy.special import erf

from hyst_gym.diagnose import Recording, diagnose, write_json, write_plots
from hyst_gym.diagnose.hypothesize import loop_informed_starts
from hyst_gym.diagnose.fit import FitResult, Objective, global_search, local_fit
from hyst_gym.diagnose.report import physical_params
from hyst_gym.diagnose.model import Model, Structure, base_parameters, extension_parameters, noise_level
from hyst_gym.physics.hem import HEMBatch, HEMParams, simulate_hem_batch

MU0 = 4e-7 * np.pi
DATA = Path(__file__).resolve().parents[1] / "data" / "real" / "jamodel-loops"
GD_DATA = Path(__file__).resolve().parents[1] / "data" / "real" / "gd-temperature" / "gd_loops.npz"
RESULTS = Path(__file__).resolve().parent / "results" / "diagnose"
FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures" / "diagnose"
PAGE = Path(__file__).resolve().parents[1] / "docs" / "results" / "real-loops.md"  # its real-loops-table section
MATERIALS = {"MnZn_ferrite": "MnZn ferrite", "MnZn_HP_ferrite": "MnZn HP ferrite"}
DT = 1e-3  # s per sample, quasi-static


def find_materials(folder: Path) -> dict:
    """``{stem: name}`` for every ``B_<stem>.mat`` with an ``H_<stem>.mat`` beside it."""
    if not folder.is_dir():
        raise ValueError(f"--data {folder}: not a folder")
    stems = sorted(p.stem[2:] for p in folder.glob("B_*.mat") if (folder / f"H_{p.stem[2:]}.mat").exists())
    if not stems:
        raise ValueError(f"--data {folder}: no B_<name>.mat / H_<name>.mat pairs")
    return {stem: MATERIALS.get(stem, stem.replace("_", " ")) for stem in stems}


def load_loops(stem, folder=DATA):
    """The loops of one material: a list of (H in A/m, B in T), one per matrix column."""
    matrices = []
    for prefix in ("B", "H"):
        path = folder / f"{prefix}_{stem}.mat"
        try:
            content = scipy.io.loadmat(path)
        except Exception as error:  # scipy raises several types for a bad file
            raise ValueError(f"{path}: not a readable .mat file ({error})") from None
        arrays = [v for k, v in content.items() if not k.startswith("__")]
        if len(arrays) != 1 or np.ndim(arrays[0]) != 2:
            raise ValueError(f"{path}: expected one 2-D matrix (one loop per column)")
        matrices.append(np.asarray(arrays[0], dtype=float))
    B, H = matrices
    if B.shape != H.shape or not np.all(np.isfinite(B)) or not np.all(np.isfinite(H)):
        raise ValueError(f"{folder}/B_{stem}.mat and H_{stem}.mat: shapes {B.shape} and "
                         f"{H.shape} differ or hold non-finite values")
    return [(H[:, j], B[:, j]) for j in range(B.shape[1])]


def loop_recording(loops, source):
    fields, mags = [], []
    for H, B in loops:
        for _ in range(2):
            fields.append(H)
            mags.append(B / MU0 - H)
    field, mag = np.concatenate(fields), np.concatenate(mags)
    # the time axis is made up: the sidecar says so, and diagnose then tries no rate effect
    return Recording(time=np.arange(field.size) * DT, field=field, magnetization=mag, source=source,
                     metadata={"time_axis": "synthetic"})


def resampled(recording, stride=2, offset=1):
    """A re-sampled copy (every ``stride``-th sample from ``offset``): the verdict must not flip."""
    keep = slice(offset, None, stride)
    return Recording(time=recording.time[keep], field=recording.field[keep],
                     magnetization=recording.magnetization[keep], metadata=dict(recording.metadata),
                     source=recording.source + f" (every {stride}th sample from {offset})")


def gd_tag(celsius):
    """Key prefix of one temperature in gd_loops.npz: -38 C -> 'm38C', 5 C -> 'p05C'."""
    return f"{'m' if celsius < 0 else 'p'}{abs(int(round(celsius))):02d}C"


def gd_recording(path=GD_DATA, amplitude="major", stride=8):
    """The gadolinium loops of one amplitude played one after another in order of temperature,
    with the temperature left out: a real record whose concealed effect is known (the sample
    warmed from -38 to +15 C, through most of its magnetization, near its 18.3 C Curie point).
    Every ``stride``-th sample, on a synthetic uniform time axis."""
    data = np.load(path)
    temperatures = np.sort(np.asarray(data["temperatures_C"], dtype=float))
    fields, mags = [], []
    for celsius in temperatures:
        H = np.asarray(data[f"{gd_tag(celsius)}_{amplitude}_H"], float)[::stride]
        B = np.asarray(data[f"{gd_tag(celsius)}_{amplitude}_B"], float)[::stride]
        fields.append(H)
        mags.append(B / MU0 - H)
    field, mag = np.concatenate(fields), np.concatenate(mags)
    return Recording(time=np.arange(field.size) * DT, field=field, magnetization=mag,
                     source=f"gadolinium {amplitude} loops, {temperatures[0]:g} to {temperatures[-1]:g} C, "
                            "temperature column left out", metadata={"time_axis": "synthetic"})


def stability_checks(recording, **kwargs):
    """Verdicts on the recording, a re-sampled copy and with a different held-out block."""
    reports = {"as recorded": diagnose(recording, progress=False, **kwargs),
               "re-sampled (every 2nd sample)": diagnose(resampled(recording), progress=False, **kwargs),
               "held-out block 40 %": diagnose(recording, progress=False, **{**kwargs, "holdout": 0.4})}
    return {name: {"verdict": r.verdict, "confidence": r.confidence, "baseline_heldout": r.baseline_heldout,
                   "improvement": r.improvement, "located": r.located["summary"], "notes": r.notes}
            for name, r in reports.items()}, reports["as recorded"]


def loop_shape(recording, predicted_m, start, stop) -> dict:
    """Predicted over measured loop area (the loss per cycle) and peak-to-peak B over the scored cycle: where
    a prediction misses, whether the model's loop is too lossy (relays switch) or too flat."""
    H = recording.field[start:stop]
    b_meas = MU0 * (H + recording.magnetization[start:stop])
    b_model = MU0 * (H + predicted_m[start:stop])
    area = [abs(float(np.sum(0.5 * (b[1:] + b[:-1]) * np.diff(H)))) for b in (b_model, b_meas)]
    return {"area_ratio": area[0] / area[1], "ptp_ratio": float(np.ptp(b_model) / np.ptp(b_meas))}


def loop_scores(fit, loops, order, stem):
    """``(nrmse_B, shape)``: the NRMSE of B of every loop (largest first) and its :func:`loop_shape`."""
    nrmse, shape = {}, {}
    for j in order:
        H, B = loops[j]
        recording, m = predict_loop(fit, H, B, f"{stem} loop {j}")
        key = f"{np.max(np.abs(H)):.3g} A/m"
        nrmse[key] = nrmse_of_b(recording, m, H.size, 2 * H.size)
        shape[key] = loop_shape(recording, m, H.size, 2 * H.size)
    return nrmse, shape


def nrmse_of_b(recording, predicted_m, start, stop):
    H = recording.field[start:stop]
    b_meas = MU0 * (H + recording.magnetization[start:stop])
    b_model = MU0 * (H + predicted_m[start:stop])
    return float(np.sqrt(np.mean((b_model - b_meas) ** 2)) / np.ptp(b_meas))


#: Model variants fitted to the largest loop: both anhysteretic curves, each with model (6) alone
#: and with the physics layer's small-loop extension (reversible low-field susceptibility chi_r).
VARIANTS = tuple((curve, extension) for curve in ("langevin", "ising") for extension in (None, "small_loop"))
REPORTED = ("a", "k", "alpha", "Ms", "c", "chi_r")


def variant_name(curve, extension):
    return curve if extension is None else f"{curve} + {extension}"


def _predict(fit, H, B, label):
    """The fitted model driven by one measured loop (warm-up cycle, then the scored cycle)."""
    other = loop_recording([(H, B)], label)
    model = fit.model.__class__(other, fit.model.structure, fit.model.parameters, float(np.ptp(other.field)) / 2000)
    return other, model.magnetization([fit.values])[:, 0]


def holdout_study(stem, folder=DATA, materials=MATERIALS, model="auto"):
    """Fit every candidate of ``model`` (MODEL_CANDIDATES) on the scored cycle of the largest loop and
    predict the others. Returns the rows (one per candidate), the loops, their order (largest first) and
    the fits by variant name. The choice among the rows is :func:`choose_variant`'s."""
    loops = load_loops(stem, folder)
    order = np.argsort([-np.max(np.abs(h)) for h, _ in loops])
    fitted = loops[order[0]]
    rec = loop_recording([fitted], f"{stem} largest loop")
    n = fitted[0].size
    scored = np.zeros(rec.size, bool)
    scored[n:] = True
    weights = {"magnetization": noise_level(rec.magnetization)}
    step = float(np.ptp(rec.field)) / 2000
    results, fits, base_seconds, base_cpu, bases = [], {}, {}, {}, {}
    for curve, extension in (VARIANTS if model in ("domain_wall", "auto") else ()):
        started, cpu = time.perf_counter(), time.process_time()
        fit, good, starts = fit_variant(rec, curve, extension, weights, scored, step, bases.get(curve))
        own = seconds = time.perf_counter() - started
        own_cpu = cpu = time.process_time() - cpu
        if extension is None:
            bases[curve], base_seconds[curve], base_cpu[curve] = fit, seconds, cpu
        else:  # the extension's fit needs the base fit first (its bounds and a start): its time counts too
            seconds += base_seconds[curve]
            cpu += base_cpu[curve]
        name = variant_name(curve, extension)
        fits[name] = fit
        # own_fit_seconds: this candidate's fit beyond the base fit already counted in its own row
        row = {"material": materials[stem], "curve": curve, "variant": name, "fit_seconds": seconds,
               "cpu_seconds": cpu, "own_fit_seconds": own, "own_cpu_seconds": own_cpu,
               "params": {k: v for k, v in physical_params(fit).items() if k in REPORTED},
               "uncertainties": {k: v for k, v in fit.uncertainties.items() if k in REPORTED + ("rho",)},
               "at_bound": [name for name, p in fit.model.parameters.items() if p.free and
                            min(abs(fit.values[name] - p.lower), abs(p.upper - fit.values[name]))
                            < 1e-3 * (p.upper - p.lower)]}
        row["nrmse_B"], row["loop_shape"] = loop_scores(fit, loops, order, stem)
        row["prediction_spread"] = prediction_spread(good, starts, loops, order, stem)
        results.append(row)
    for variant in (HEM_VARIANTS if model in ("hem", "auto") else ()):
        row, fit = hem_row(stem, variant, rec, scored, loops, order, materials)
        results.append(row)
        fits[row["variant"]] = fit
    return results, loops, order, fits


#: Fits whose fitted-loop sum of squares is within this factor of the best count as equally good.
EQUALLY_GOOD = 1.25
#: Starts of the batched fit: the grid below, and the best points of a Sobol design over the boxes.
SOBOL_POINTS, SOBOL_KEEP = 128, 3


def variant_model(rec, curve, extension, step, base=None):
    """The model of one variant with its parameter boxes, scaled to the recording; the
    small-loop extension's box for chi_r comes from the base fit of the same curve."""
    structure = Structure("none", curve, extension)
    parameters = base_parameters(rec, structure)
    if extension is not None:
        parameters.update(extension_parameters(rec, structure, base.values))
    return Model(rec, structure, parameters, step)


def grid_starts(rec, small_loop):
    """Starts that put the low-field slope into c and k, or (with the small-loop extension)
    into chi_r: a local fit from one start can settle in the wrong basin."""
    h_max = float(np.max(np.abs(rec.field)))
    peak = float(np.max(np.abs(rec.magnetization)))
    return [dict(a=a * h_max, k=k * h_max, c=c, rho=0.0, Ms=1.2 * peak,
                 **({"chi_r": chi * peak / h_max} if small_loop else {}))
            for a in (0.1, 0.3, 1.0) for k in (0.03, 0.1) for c in (0.05, 0.4)
            for chi in ((0.3,) if small_loop else (None,))]


def fit_variant(rec, curve, extension, weights, fit_mask, step, base=None):
    """All starts of one variant fitted at once (:func:`batched_least_squares`), the best one polished
    by the diagnose tool's local fit (which also gives the uncertainties). Returns the best fit, the
    fits that are equally good on the fitted samples and the number of starts."""
    model = variant_model(rec, curve, extension, step, base)
    names = [n for n in ("a", "k", "rho", "Ms", "c", "chi_r") if n in model.parameters and model.parameters[n].free]
    starts = grid_starts(rec, extension is not None)
    starts += global_search(model, weights, fit_mask, names, n_points=SOBOL_POINTS, keep=SOBOL_KEEP,
                            extra_starts=loop_informed_starts(rec))
    if base is not None:  # the base fit, with a little of its low-field slope moved into chi_r
        starts += [dict(base.values, chi_r=share * model.parameters["chi_r"].upper) for share in (0.0, 0.1)]
    values, sse = batched_least_squares(model, weights, fit_mask, starts)
    best = local_fit(model, weights, fit_mask, values[int(np.argmin(sse))], max_nfev=10)
    good = [best] + [FitResult(model.with_values(v), v, {}, float(e), best.n_residuals, best.n_free, 0)
                     for v, e in zip(values, sse) if e <= EQUALLY_GOOD * best.sse]
    return best, good, len(starts)


#: A start of the batched fit stops when an accepted step lowers its sum of squares by less than this share:
#: the best start is polished by the local fit afterwards, and on the shipped loops 1e-6 gives the NRMSEs of
#: 1e-9 to two decimals (and the same equally good fits but one) in 80 % of the time.
CONVERGED_IMPROVEMENT = 1e-6


def batched_least_squares(model, weights, fit_mask, starts, iterations=80, prune_after=10, prune_factor=10.0):
    """Levenberg-Marquardt (Marquardt's diagonal scaling, steps clipped to the boxes) from every
    start at once: each iteration simulates the Jacobians of all starts (forward differences), then
    the trial steps of all starts, each as one bank of models in one compiled call, instead of one
    local fit after the other. A start stops when its sum of squares improves by less than
    CONVERGED_IMPROVEMENT relatively, its damping exceeds 1e8, or (after ``prune_after`` iterations) it is
    more than ``prune_factor`` times the best. Returns the values dicts and sums of squares of all starts."""
    objective = Objective(model, weights, fit_mask)
    names = model.free_names
    lower = np.array([model.parameters[n].x_bounds[0] for n in names])
    upper = np.array([model.parameters[n].x_bounds[1] for n in names])
    span = upper - lower
    x = np.array([np.clip(model.x_from_values({**model.values(), **start}), lower + 1e-9 * span,
                          upper - 1e-9 * span) for start in starts])

    def residuals(points):
        values = [model.values_from_x(p) for p in points]
        rows = objective.residuals_many(values)
        return np.array([np.nan_to_num(r, nan=1e6, posinf=1e6, neginf=-1e6) for r in rows])

    r = residuals(x)
    sse = np.einsum("ij,ij->i", r, r)
    damping = np.full(len(x), 1e-3)
    active = np.ones(len(x), bool)
    stale = np.ones(len(x), bool)  # Jacobian to be recomputed
    jacobians = np.zeros((len(x), r.shape[1], len(names)))
    for iteration in range(iterations):
        todo = np.flatnonzero(active & stale)
        if todo.size:
            steps = 1e-5 * np.maximum(1.0, np.abs(x[todo]))
            steps = np.where(x[todo] + steps > upper, -steps, steps)
            shifted = np.repeat(x[todo], len(names), axis=0) + np.concatenate([np.diag(s) for s in steps])
            moved = residuals(shifted).reshape(todo.size, len(names), -1)
            jacobians[todo] = np.transpose((moved - r[todo][:, None, :]) / steps[:, :, None], (0, 2, 1))
            stale[todo] = False
        live = np.flatnonzero(active)
        trial = np.empty((live.size, len(names)))
        for i, s in enumerate(live):
            J = jacobians[s]
            normal = J.T @ J
            scale = np.diag(normal) + 1e-12
            step = np.linalg.solve(normal + damping[s] * np.diag(scale), -J.T @ r[s])
            trial[i] = np.clip(x[s] + step, lower, upper)
        r_trial = residuals(trial)
        sse_trial = np.einsum("ij,ij->i", r_trial, r_trial)
        for i, s in enumerate(live):
            if sse_trial[i] < sse[s]:
                converged = sse[s] - sse_trial[i] < CONVERGED_IMPROVEMENT * sse[s]
                x[s], r[s], sse[s] = trial[i], r_trial[i], sse_trial[i]
                damping[s] = max(damping[s] / 3.0, 1e-9)
                stale[s] = True
                active[s] = not converged
            else:
                damping[s] *= 4.0
                active[s] = damping[s] < 1e8
        if iteration >= prune_after:
            active &= sse <= prune_factor * sse.min()
        if not active.any():
            break
    return [model.values_from_x(p) for p in x], sse


# ------------------------------------------------------------------ the homogenized energy model

#: HEM variants: the interaction density of the relay kernel (``hyst_gym.physics.hem``, 16 coercive nodes),
#: whether the reversible part saturates (``hem.SATURATING_REVERSIBLE``; added after the first three had been
#: run on the shipped sets) and whether the coercive density holds a population of zero coercivity
#: (``hem.ANHYSTERETIC_POPULATION``; the last three, added after the validation-loop rule had been fixed and
#: run; see docs/results/real-loops.md).
HEM_VARIANTS = (("normal", False, False), ("lorentzian", False, False), ("student_t2", False, False),
                ("normal", True, False), ("normal", True, True), ("lorentzian", True, True), ("student_t2", True, True))
HEM_NODES = 16
#: Bounds of the nonlinear HEM parameters: fields in units of the fitted loop's peak field, the spread of
#: ln Hc dimensionless.
HEM_BOUNDS = {"coercive_median": (1e-3, 2.0), "coercive_spread": (0.05, 3.0), "interaction_scale": (1e-3, 5.0),
              "reversible_saturation": (1e-2, 10.0), "anhysteretic_scale": (1e-3, 5.0)}
#: Starts of the HEM fit (same units); every start is simulated as one bank, the best HEM_REFINED refined.
HEM_STARTS = [dict(coercive_median=hc, coercive_spread=sigma, interaction_scale=b)
              for hc in (0.05, 0.15, 0.4) for sigma in (0.4, 1.0) for b in (0.05, 0.2, 0.6)]
#: The options' starts: the saturating reversible part and the anhysteretic population are two saturating
#: reversible parts that can trade roles (the one with the small field scale follows the knee, the other the
#: approach to saturation), so the starts hold both orders: h_s from 0.1 and b_A up to 0.6 of the peak field.
#: With h_s in (0.3, 1.0) and b_A in (0.05, 0.2) alone, two fits on the shipped ferrites stopped 2 and 6 %
#: above the lowest sum of squares of 400 random starts (tests/experiments/test_real_loops_models.py).
HEM_OPTION_STARTS = {"reversible_saturation": (0.1, 0.3, 1.0), "anhysteretic_scale": (0.05, 0.2, 0.6)}
HEM_REFINED = 3
#: The linear parts of a HEM fit: the reversible part's chi, the relays' M_R and the anhysteretic population's M_A.
HEM_LINEAR = ("reversible_susceptibility", "relay_magnetization", "anhysteretic_magnetization")


def hem_variant_name(density, saturating, anhysteretic=False):
    return (f"hem {density}" + (" + saturating reversible" if saturating else "")
            + (" + anhysteretic population" if anhysteretic else ""))


def hem_nonlinear_names(saturating, anhysteretic):
    return (("coercive_median", "coercive_spread", "interaction_scale") + (("reversible_saturation",) if saturating
                                                                          else ())
            + (("anhysteretic_scale",) if anhysteretic else ()))


@dataclass(frozen=True)
class HEMFit:
    """A fitted HEM: the parameters in physical units and the fit's sum of squares (A/m)^2."""

    params: HEMParams
    sse: float

    def magnetization(self, field):
        """M (A/m) along ``field`` (A/m), started demagnetized at H = 0 and brought to ``field[0]``."""
        return simulate_hem_batch(np.concatenate([[0.0], field]), HEMBatch.from_params(self.params))[1:, 0]


def _share(scaled, density):
    """2F - 1 of the interaction density at ``scaled`` = H/b (hem.ANHYSTERETIC_POPULATION)."""
    if density == "normal":
        return erf(scaled / np.sqrt(2.0))
    if density == "student_t2":
        return scaled / np.sqrt(2.0 + scaled * scaled)
    return (2.0 / np.pi) * np.arctan(scaled)


def _relay_columns(field, density, nonlinear, names):
    """The HEM's linear parts along ``field`` for each row of ``nonlinear`` (values of ``names``): M =
    chi*g(H) + M_R*R(H) [+ M_A*A(H)]; returns the columns g (H itself, or h_s*tanh(H/h_s)), R (the relays
    with M_R = 1) and, with the anhysteretic population, A = 2F(H; b_A) - 1, each of shape (T, rows)."""
    nonlinear = np.atleast_2d(nonlinear)
    value = dict(zip(names, nonlinear.T))
    batch = HEMBatch(1.0, 0.0, value["coercive_median"], value["coercive_spread"], value["interaction_scale"],
                     density, HEM_NODES)
    if "reversible_saturation" in value:
        saturation = value["reversible_saturation"][None, :]
        reversible = saturation * np.tanh(field[:, None] / saturation)
    else:
        reversible = np.repeat(field[:, None], nonlinear.shape[0], axis=1)
    columns = [reversible, simulate_hem_batch(np.concatenate([[0.0], field]), batch)[1:]]
    if "anhysteretic_scale" in value:
        columns.append(_share(field[:, None] / value["anhysteretic_scale"][None, :], density))
    return columns


def _linear_parts(columns, measured, mask):
    """The linear parts >= 0 (HEM_LINEAR order) by least squares on ``mask`` for each row of the columns, and
    the residuals, shape (T, rows)."""
    out = []
    for j in range(columns[0].shape[1]):
        design = np.column_stack([c[mask, j] for c in columns])
        scale = np.max(np.abs(design), axis=0) + 1e-300  # columns of A/m and of 1: equilibrated for nnls
        coefficients, _ = nnls(design / scale, measured[mask])
        out.append(coefficients / scale)
    coefficients = np.array(out)
    residuals = sum(coefficients[:, i][None, :] * c for i, c in enumerate(columns)) - measured[:, None]
    return coefficients, residuals


def fit_hem(rec, density, fit_mask, saturating=False, anhysteretic=False) -> HEMFit:
    """The HEM fitted to a recording's magnetization on ``fit_mask``: chi, M_R (and M_A), which enter linearly,
    are solved by non-negative least squares inside every evaluation (variable projection); the three
    nonlinear parameters (one more each for the saturating reversible part and the anhysteretic population)
    by ``least_squares`` in log coordinates from the best starts of HEM_STARTS, each Jacobian one bank. With
    the anhysteretic population, the fit without it (the nested model, M_A = 0) is made first and refined
    from too, so that the population can only lower the sum of squares."""
    h_max = float(np.max(np.abs(rec.field)))
    names = hem_nonlinear_names(saturating, anhysteretic)
    unit = np.array([1.0 if n == "coercive_spread" else h_max for n in names])
    lower = np.log(np.array([HEM_BOUNDS[n][0] for n in names]) * unit)
    upper = np.log(np.array([HEM_BOUNDS[n][1] for n in names]) * unit)
    field, measured = rec.field, rec.magnetization

    def residual_rows(zs):
        _, residuals = _linear_parts(_relay_columns(field, density, np.exp(zs), names), measured, fit_mask)
        return residuals[fit_mask].T

    starts = [dict(start) for start in HEM_STARTS]
    for option, values in HEM_OPTION_STARTS.items():
        if option in names:
            starts = [dict(start, **{option: v}) for start in starts for v in values]
    starts = np.log(np.array([[start[n] for n in names] for start in starts]) * unit)
    sse = np.einsum("ij,ij->i", *(2 * [residual_rows(starts)]))
    refined = starts[np.argsort(sse)[:HEM_REFINED]]
    if anhysteretic:
        nested = fit_hem(rec, density, fit_mask, saturating, False).params
        refined = np.vstack([refined] + [np.log([getattr(nested, n) for n in names[:-1]] + [b * h_max])
                                         for b in HEM_OPTION_STARTS["anhysteretic_scale"]])
    best_z, best_sse = None, np.inf
    for z0 in refined:
        def jacobian(z):
            step = 1e-6 * np.maximum(1.0, np.abs(z))
            rows = residual_rows(np.vstack([z, z + np.diag(step)]))
            return ((rows[1:] - rows[:1]) / step[:, None]).T

        solution = least_squares(lambda z: residual_rows(z[None, :])[0], np.clip(z0, lower, upper), jac=jacobian,
                                 bounds=(lower, upper), x_scale=1.0, max_nfev=60, xtol=1e-8, ftol=1e-10)
        if 2 * solution.cost < best_sse:
            best_z, best_sse = solution.x, 2 * solution.cost
    nonlinear = np.exp(best_z)
    linear = _linear_parts(_relay_columns(field, density, nonlinear, names), measured, fit_mask)[0][0]
    values = dict(zip(names, (float(v) for v in nonlinear)), **dict(zip(HEM_LINEAR, (float(v) for v in linear))))
    values["relay_magnetization"] = max(values["relay_magnetization"], 1e-9 * float(np.ptp(measured)))
    return HEMFit(HEMParams(interaction_density=density, coercive_nodes=HEM_NODES, **values), float(best_sse))


def hem_row(stem, variant, rec, fit_mask, loops, order, materials):
    """The row of one HEM variant (density, saturating, anhysteretic) in the hold-out table (the domain-wall
    rows' keys)."""
    density, saturating, anhysteretic = variant
    started, cpu = time.perf_counter(), time.process_time()
    fit = fit_hem(rec, density, fit_mask, saturating, anhysteretic)
    seconds = time.perf_counter() - started
    cpu = time.process_time() - cpu
    names = ("relay_magnetization", "reversible_susceptibility") + hem_nonlinear_names(saturating, anhysteretic) + (
        ("anhysteretic_magnetization",) if anhysteretic else ())
    params = {n: getattr(fit.params, n) for n in names}
    h_max = float(np.max(np.abs(rec.field)))
    unit = {n: 1.0 if n == "coercive_spread" else h_max for n in HEM_BOUNDS}
    at_bound = [n for n, (lo, hi) in HEM_BOUNDS.items() if n in params
                and min(abs(np.log(params[n] / (lo * unit[n]))), abs(np.log(hi * unit[n] / params[n]))) < 1e-3]
    row = {"material": materials[stem], "curve": None, "variant": hem_variant_name(*variant),
           "fit_seconds": seconds, "cpu_seconds": cpu, "own_fit_seconds": seconds, "own_cpu_seconds": cpu,
           "params": params,
           "uncertainties": {},
           "at_bound": at_bound,
           "prediction_spread": None}
    row["nrmse_B"], row["loop_shape"] = loop_scores(fit, loops, order, stem)
    return row, fit


def predict_loop(fit, H, B, label):
    """The fitted model (either kind) driven by one measured loop: (its recording, M in A/m)."""
    if isinstance(fit, HEMFit):
        other = loop_recording([(H, B)], label)
        return other, fit.magnetization(other.field)
    return _predict(fit, H, B, label)


# ------------------------------------------------------------------ the selection rule

#: Candidates of each ``--model``: the domain-wall variants, the HEM variants, or both.
MODEL_CANDIDATES = {"domain_wall": tuple(variant_name(*v) for v in VARIANTS),
                    "hem": tuple(hem_variant_name(*v) for v in HEM_VARIANTS)}
MODEL_CANDIDATES["auto"] = MODEL_CANDIDATES["domain_wall"] + MODEL_CANDIDATES["hem"]
#: The validation loop (the second largest) decides where a material has at least this many loops; with
#: fewer, the leave-one-material-out transfer score does (module docstring, the selection rule).
VALIDATION_MIN_LOOPS = 3
CHOSEN_BY = {"validation": "validation loop: lowest NRMSE on the second-largest loop, predicted from the fit to "
                           "the largest; the smaller loops are the prediction",
             "transfer": "fewer than three loops: lowest leave-one-material-out transfer score (mean over the other "
                         "shared materials of the worst predicted amplitude)",
             "fitted": "fewer than three loops and no transfer score: lowest fitted-loop NRMSE"}


def transfer_scores(shared: dict, exclude=()) -> dict:
    """``{variant: mean over the shared materials not in exclude of the worst NRMSE over that material's
    predicted (not fitted) amplitudes}``; ``shared`` maps a stem to its hold-out rows."""
    per_variant = {}
    for stem, rows in shared.items():
        if stem in exclude:
            continue
        for row in rows:
            predicted = list(row["nrmse_B"].values())[1:]
            if predicted:
                per_variant.setdefault(row["variant"], []).append(max(predicted))
    return {variant: float(np.mean(values)) for variant, values in per_variant.items()}


def needs_transfer(rows) -> bool:
    """Whether the rule falls back to the transfer score: fewer than VALIDATION_MIN_LOOPS loops."""
    return len(rows[0]["nrmse_B"]) < VALIDATION_MIN_LOOPS


def _finite(value) -> float:
    """A score that is not a number (a candidate whose model could not run) ranks last, not first."""
    return float(value) if np.isfinite(value) else np.inf


def validation_score(row) -> float:
    """NRMSE of B on the validation loop, the second largest (``nrmse_B`` is ordered largest first)."""
    return _finite(list(row["nrmse_B"].values())[1])


def fitted_score(row) -> float:
    return _finite(list(row["nrmse_B"].values())[0])


def choose_variant(rows, transfer: dict):
    """The selection rule (module docstring): ``(chosen row, how)``, ``how`` a key of CHOSEN_BY. With three or
    more loops the lowest validation-loop NRMSE (exact ties: the lower fitted-loop NRMSE); with fewer, the
    lowest leave-one-material-out transfer score, else the lowest fitted-loop NRMSE."""
    if not needs_transfer(rows):
        return min(rows, key=lambda r: (validation_score(r), fitted_score(r))), "validation"
    scored = [r for r in rows if r["variant"] in transfer]
    if scored:
        return min(scored, key=lambda r: (_finite(transfer[r["variant"]]), fitted_score(r))), "transfer"
    return min(rows, key=fitted_score), "fitted"


_SHARED_STUDIES = {}


def shared_studies(model: str) -> dict:
    """Hold-out rows of the shipped (shared) materials for ``model``, computed once per process."""
    if model not in _SHARED_STUDIES:
        _SHARED_STUDIES[model] = {stem: holdout_study(stem, DATA, MATERIALS, model) for stem in MATERIALS}
    return _SHARED_STUDIES[model]


def same_loops(first, second) -> bool:
    """Whether two materials' loop lists hold the same measurements (a shared set under another name)."""
    return len(first) == len(second) and all(
        h1.shape == h2.shape and np.array_equal(h1, h2) and np.array_equal(b1, b2)
        for (h1, b1), (h2, b2) in zip(first, second))


def held_out_materials(loops, shared: dict) -> set:
    """The shared stems that hold the target's own loops: left out of its transfer score."""
    return {stem for stem, study in shared.items() if same_loops(loops, study[1])}


def prediction_spread(good, starts, loops, order, stem):
    """The range of predicted NRMSE per loop over fits the fitted loop cannot tell apart."""
    spread = {}
    for j in order[1:]:
        H, B = loops[j]
        predicted = [nrmse_of_b(*_predict(f, H, B, f"{stem} loop {j}"), H.size, 2 * H.size) for f in good]
        spread[f"{np.max(np.abs(H)):.3g} A/m"] = [min(predicted), max(predicted)]
    return {"fits": len(good), "starts": starts, "nrmse_range": spread}


def plot_holdout(stem, best, loops, order, fit):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for j in order:
        H, B = loops[j]
        _, m = predict_loop(fit, H, B, "plot")
        ax.plot(H, B, "k.", ms=2)
        ax.plot(H, MU0 * (H + m[H.size:]), lw=1, label=f"{np.max(np.abs(H)):.3g} A/m: "
                f"{100 * best['nrmse_B'][f'{np.max(np.abs(H)):.3g} A/m']:.1f} %")
    ax.set_xlabel("H (A/m)")
    ax.set_ylabel("B (T)")
    ax.set_title(f"{MATERIALS.get(stem, stem)}: fitted on the largest loop ({best['variant']}); dots = measured",
                 fontsize=9)
    ax.legend(fontsize=8, title="NRMSE of B")
    fig.tight_layout()
    FIGURES.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURES / f"real_{stem}_holdout.png", dpi=110)
    plt.close(fig)


def scores_json(stem, results, best, how, transfer=None):
    """The per-material entry of ``--json``: the chosen variant, how the rule chose it, its fitted loop,
    validation loop and predicted loops, its fit time, and every candidate's numbers beside it."""
    scores = list(best["nrmse_B"].items())
    roles = ["fitted"] + (["validation"] if how == "validation" else []) + ["predicted"] * len(scores)
    return {"variant": best["variant"], "chosen_by": CHOSEN_BY[how], "rule": how,
            "fitted_loop_nrmse": scores[0][1],
            "validation_loop_nrmse": scores[1][1] if how == "validation" else None,
            "loops": [{"peak_field": float(name.split()[0]), "nrmse": value, "role": role}
                      for (name, value), role in zip(scores, roles)],
            "fit_seconds": best["fit_seconds"], "fit_cpu_seconds": best["cpu_seconds"],
            "all_candidates_fit_seconds": float(sum(r["own_fit_seconds"] for r in results)),
            "all_candidates_cpu_seconds": float(sum(r["own_cpu_seconds"] for r in results)),
            "params": best["params"], "uncertainties": best["uncertainties"],
            "at_bound": best["at_bound"], "prediction_spread": best.get("prediction_spread"),
            "transfer_scores": transfer or {},
            "variants": {r["variant"]: {"nrmse_B": r["nrmse_B"], "loop_shape": r["loop_shape"],
                                      "fit_seconds": r["fit_seconds"],
                                      "params": r["params"], "at_bound": r["at_bound"]} for r in results}}


def material_line(name, entry) -> str:
    loops = ", ".join(f"{loop['peak_field']:g} A/m {100 * loop['nrmse']:.1f} % ({loop['role']})"
                      for loop in entry["loops"])
    return (f"{name}: {entry['variant']} ({entry['rule']}): {loops}; fit {entry['fit_seconds']:.2f} s "
            f"(CPU {entry['fit_cpu_seconds']:.2f} s), "
            f"all candidates {entry['all_candidates_fit_seconds']:.2f} s "
            f"(CPU {entry['all_candidates_cpu_seconds']:.2f} s)")


def score_folder(folder: Path, json_path: Path, model="auto") -> int:
    """``--data DIR --json FILE [--model M]``: the amplitude hold-out on any folder of loop pairs, each
    material's candidate chosen by the selection rule (the shipped materials give the transfer scores,
    computed only for a material with fewer than three loops)."""
    materials = find_materials(folder)
    out = {}
    for stem in materials:
        results, loops, _, _ = holdout_study(stem, folder, materials, model)
        transfer = {}
        if needs_transfer(results):
            shared = {s: rows for s, (rows, *_) in shared_studies(model).items()}
            transfer = transfer_scores(shared, held_out_materials(loops, shared_studies(model)))
        best, how = choose_variant(results, transfer)
        out[materials[stem]] = scores_json(stem, results, best, how, transfer)
        print(material_line(materials[stem], out[materials[stem]]))
    json_path.parent.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps(out, indent=2, default=float) + "\n")
    print(f"wrote {json_path}")
    return 0


def main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(description="Amplitude hold-out and blind diagnosis on measured B-H loops.")
    parser.add_argument("--data", type=Path, help="folder of B_<name>.mat / H_<name>.mat pairs (one loop per "
                        "column); with --json, score only these (default: the shipped MnZn loops, full study)")
    parser.add_argument("--json", type=Path, help="write per-material scores here (fitted_loop_nrmse, loops, "
                        "fit_seconds, variant)")
    parser.add_argument("--model", choices=sorted(MODEL_CANDIDATES), default="auto",
                        help="candidates: the domain-wall model (6) and its small-loop extension, the homogenized "
                        "energy model (hyst_gym.physics.hem), or both (auto); the selection rule picks one")
    args = parser.parse_args(argv)
    if args.data is not None or args.json is not None:
        try:
            return score_folder(args.data or DATA, args.json or Path("real_loops_scores.json"), args.model)
        except (ValueError, OSError) as error:  # bad input: one line, exit status 2
            print(f"real_loops: error: {error}", file=sys.stderr)
            return 2
    RESULTS.mkdir(parents=True, exist_ok=True)
    summary = {}
    shared = {stem: rows for stem, (rows, *_) in shared_studies(args.model).items()}
    for stem in MATERIALS:
        results, loops, order, fits = shared_studies(args.model)[stem]
        # the transfer score decides only below three loops; it is reported for every candidate anyway
        transfer = transfer_scores(shared, exclude={stem})
        best, how = choose_variant(results, transfer)
        plot_holdout(stem, best, loops, order, fits[best["variant"]])
        rec = loop_recording([loops[j] for j in order], f"{MATERIALS[stem]}, all loops, largest first")
        # diagnose is the domain-wall tool: its curve is the domain-wall variant the rule would choose alone
        walls = [r for r in results if r["curve"] is not None]
        curve = choose_variant(walls, transfer)[0]["curve"] if walls else "langevin"
        stability, report = stability_checks(rec, anhysteretic=curve, holdout=0.5)
        write_json(report, RESULTS / f"real_{stem}_report.json")
        write_plots(report, FIGURES / f"real_{stem}")
        summary[stem] = {"scores": scores_json(stem, results, best, how, transfer), "holdout": results,
                         "diagnose": {"verdict": report.verdict, "confidence": report.confidence,
                                      "baseline_heldout": report.baseline_heldout,
                                      "improvement": report.improvement,
                                      "explanation": report.explanation,
                                      "seconds": report.seconds},
                         "stability": stability}
        print(material_line(MATERIALS[stem], summary[stem]["scores"]))
    # Gadolinium warmed from -38 to +15 C, loops played in order of temperature, temperature left out
    gd = gd_recording()
    stability, report = stability_checks(gd, anhysteretic="langevin")
    write_json(report, RESULTS / "real_gadolinium_report.json")
    write_plots(report, FIGURES / "real_gadolinium")
    summary["gadolinium_temperature_concealed"] = {"samples": gd.size, "stability": stability,
                                                   "explanation": report.explanation}
    print(json.dumps(summary["gadolinium_temperature_concealed"], indent=1, default=float))
    summary["run"] = {"load_average": os.getloadavg()[0], "cores": os.cpu_count()}
    (RESULTS / "real_loops.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")
    from experiments.report_markdown import update_readme

    update_readme(PAGE, loops_table(summary), area="real-loops-table")
    return 0


def _spread_cell(row) -> str:
    spread = row.get("prediction_spread")
    if not spread:
        return "–"
    ranges = ", ".join(f"{100 * lo:.1f}–{100 * hi:.1f} % ({k.split()[0]})"
                       for k, (lo, hi) in spread["nrmse_range"].items())
    return f"{ranges}; {spread['fits']} of {spread['starts']} fits"


def loops_table(summary) -> str:
    """Markdown table of the amplitude hold-out, every candidate, the chosen one in bold; fit times are
    wall-clock seconds at the load of the run (``summary["run"]``)."""
    lines = ["| material | candidate | fitted loop | validation loop | predicted amplitudes (A/m) | transfer score "
             "(other material) | fit time (CPU) | at a bound | equally good fits predict |",
             "|---|---|---|---|---|---|---|---|---|"]
    for entry in summary.values():
        if "holdout" not in entry:
            continue
        chosen, rule = entry["scores"]["variant"], entry["scores"]["rule"]
        predicted_from = 2 if rule == "validation" else 1
        for row in entry["holdout"]:
            scores = list(row["nrmse_B"].items())
            name = f"**{row['variant']}**" if row["variant"] == chosen else row["variant"]
            validation = f"{100 * scores[1][1]:.1f} % ({scores[1][0].split()[0]})" if predicted_from == 2 else "–"
            predicted = ", ".join(f"{100 * v:.1f} % ({k.split()[0]})" for k, v in scores[predicted_from:])
            transfer = entry["scores"]["transfer_scores"].get(row["variant"])
            lines.append(f"| {row['material']} | {name} | {100 * scores[0][1]:.2f} % | {validation} | {predicted} | "
                         + (f"{100 * transfer:.1f} % | " if transfer is not None else "– | ") +
                         f"{row['fit_seconds']:.2f} s ({row['cpu_seconds']:.2f} s) | "
                         f"{', '.join(row['at_bound']) or '–'} | {_spread_cell(row)} |")
    for stem, entry in summary.items():
        if "holdout" in entry:
            scores = entry["scores"]
            lines.append(f"\n{MATERIALS.get(stem, stem)}: chosen by the {scores['rule']} rule; all "
                         f"{len(scores['variants'])} candidates fitted in "
                         f"{scores['all_candidates_fit_seconds']:.1f} s wall clock, "
                         f"{scores['all_candidates_cpu_seconds']:.1f} s of CPU time (one process).")
    run = summary.get("run", {})
    lines.append(f"\nFit times: wall clock on {run.get('cores', '?')} cores at 1-min load average "
                 f"{run.get('load_average', float('nan')):.1f} (other jobs running inflate them), CPU time in "
                 "parentheses.")
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
