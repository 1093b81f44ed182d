"""Speed of the hysteresis bank (``hyst-gym bench``, section "hysteresis bank").

Measures the estimator's hot loop: a bank of 64 parameter sets (a on a grid over
[6300, 7300] A/m, the paper's other parameters) under one shared input, single thread,
and reports nanoseconds per model-substep (one explicit-midpoint step of (6) for one
model). For context, the same run times

* a plain ``scipy.integrate.solve_ivp`` implementation of the same model: one RK45
  solve of the 64-model state vector in time, with the same piecewise-linear H(t) and
  the tolerance tightened until its max error against a converged solution is no larger
  than the bank's at :data:`DEFAULT_MAX_FIELD_STEP`;
* when a C compiler is available, a C ``-O3`` implementation of the same midpoint step
  (libm ``tanh``, scalar), compiled on the spot, so the ratio to it is measured under
  the same machine load.

and it times the homogenized energy model (``hem.py``) in the same bank layout and on the same
input, for each interaction density: the HEM takes no substeps (one exact update per sample), so
its cost is reported per model-update, beside (6)'s per model-substep and both per model-sample.

Timings are the minimum over repeats of the process CPU time (robust to other jobs
sharing the cores); wall-clock figures are reported alongside.
"""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import tempfile
import time

import numpy as np
import scipy.integrate

from . import hem
from .hysteresis import DEFAULT_MAX_FIELD_STEP, HysteresisBatch, HysteresisParams, simulate_shared

BANK_SIZE = 64
A_GRID = (6300.0, 7300.0)

_C_REFERENCE = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
static inline double slope(double H, double M, double d, double a, double k, double al, double Ms, double c) {
    double t = tanh((H + al * M) / a), man = Ms * t, mp = Ms / a * (1 - t * t), gap = man - M, irr = 0;
    if (gap * d > 0) { double den = k * d - al / (1 - c) * gap; if (den * d > 0) irr = gap / den; }
    return (irr + c * mp) / (1 - al * c * mp);
}
int main(int argc, char **argv) {
    int T = atoi(argv[1]), B = atoi(argv[2]), reps = atoi(argv[3]); double step = atof(argv[4]);
    double *f = malloc(T * sizeof(double)), *a = malloc(B * sizeof(double)), *m = malloc(B * sizeof(double));
    for (int i = 0; i < T; i++) if (scanf("%lf", &f[i]) != 1) return 2;
    for (int b = 0; b < B; b++) a[b] = @a0@ + (@a1@ - @a0@) * b / (B - 1);
    double best = 1e30; long substeps = 0;
    for (int r = 0; r < reps; r++) {
        for (int b = 0; b < B; b++) m[b] = 0;
        struct timespec t0, t1; clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t0); substeps = 0;
        for (int t = 1; t < T; t++) {
            double ch = f[t] - f[t - 1]; if (ch == 0) continue;
            int n = (int)ceil(fabs(ch) / step); if (n < 1) n = 1;
            double h = ch / n, d = ch > 0 ? 1 : -1;
            for (int s = 0; s < n; s++) {
                double H = f[t - 1] + s * h;
                for (int b = 0; b < B; b++) {
                    double s0 = slope(H, m[b], d, a[b], @k@, @alpha@, @Ms@, @c@);
                    m[b] += h * slope(H + 0.5 * h, m[b] + 0.5 * h * s0, d, a[b], @k@, @alpha@, @Ms@, @c@);
                }
            }
            substeps += n;
        }
        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t1);
        double dt = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec); if (dt < best) best = dt;
    }
    printf("%.17g %ld %.17g\n", best, substeps, m[B - 1]);
    return 0;
}
"""


def benchmark_input(periods: int = 2, samples_per_period: int = 1000, amplitude: float = 1e5) -> np.ndarray:
    """The shared input: major loops of a 1e5 A/m sine, sampled uniformly (A/m)."""
    phase = np.linspace(0.0, 2 * np.pi * periods, periods * samples_per_period + 1)
    return amplitude * np.sin(phase)


def _substeps(field, max_field_step):
    return int(np.sum(np.maximum(1, np.ceil(np.abs(np.diff(field)) / max_field_step))))


def _best_time(run, repeats):
    cpu_best, wall_best, result = np.inf, np.inf, None
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        result = run()
        cpu_best = min(cpu_best, time.process_time() - cpu)
        wall_best = min(wall_best, time.perf_counter() - wall)
    return cpu_best, wall_best, result


def time_bank(field, batch: HysteresisBatch, max_field_step=DEFAULT_MAX_FIELD_STEP, repeats=7):
    """(cpu seconds, wall seconds, trajectory) of the compiled bank over ``field``."""
    start = np.zeros(batch.size)
    args = (batch.a, batch.k, batch.alpha, batch.Ms, batch.c, batch.kind, float(max_field_step))
    simulate_shared(field[:3], start, *args)  # compile / load from cache
    return _best_time(lambda: simulate_shared(field, start, *args), repeats)


def solve_ivp_bank(field, batch: HysteresisBatch, rtol: float, atol: float):
    """The same bank as one plain ``solve_ivp`` (RK45) problem in time.

    Time runs over sample indices (H is linear in between, as for the compiled kernel);
    the state is the 64 magnetizations and the right-hand side is (6), vectorized with
    numpy, times dH/dt of the current segment (its sign is delta).
    """
    p = batch
    alphahat = p.alpha / (1.0 - p.c)
    rates = np.diff(field)
    samples = np.arange(field.size, dtype=float)

    def rhs(t, magnetization):
        segment = min(int(t), rates.size - 1)
        rate = rates[segment]
        if rate == 0.0:
            return np.zeros_like(magnetization)
        delta = 1.0 if rate > 0 else -1.0
        field_now = field[segment] + rate * (t - segment)
        man, man_slope = _anhysteretic(field_now + p.alpha * magnetization, p)
        gap = man - magnetization
        denominator = p.k * delta - alphahat * gap
        on = (gap * delta > 0) & (denominator * delta > 0)
        irreversible = np.where(on, gap / np.where(on, denominator, 1.0), 0.0)
        return rate * (irreversible + p.c * man_slope) / (1.0 - p.alpha * p.c * man_slope)

    solution = scipy.integrate.solve_ivp(rhs, (0.0, samples[-1]), np.zeros(p.size), method="RK45", t_eval=samples,
                                         rtol=rtol, atol=atol)
    return solution.y.T, solution.nfev


def _anhysteretic(effective_field, p):
    """Man and dMan/dHe in plain numpy (Ising (2) or Langevin (3))."""
    x = effective_field / p.a
    if p.anhysteretic == "ising":
        t = np.tanh(x)
        return p.Ms * t, p.Ms / p.a * (1.0 - t * t)
    small = np.abs(x) < 1e-3
    safe = np.where(small, 1.0, x)
    coth = 1.0 / np.tanh(safe)
    value = np.where(small, x / 3 - x ** 3 / 45, coth - 1.0 / safe)
    slope = np.where(small, 1 / 3 - x ** 2 / 15, 1.0 / safe ** 2 - (coth ** 2 - 1.0))
    return p.Ms * value, p.Ms / p.a * slope


def _c_reference(field, params, a_grid, size, max_field_step, repeats=5):
    """(cpu seconds, substeps) of the C -O3 midpoint bank, or None without a C compiler."""
    compiler = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc") or shutil.which("clang")
    if compiler is None:
        return None
    source = _C_REFERENCE
    for key, value in {"a0": a_grid[0], "a1": a_grid[1], "k": params.k, "alpha": params.alpha,
                       "Ms": params.Ms, "c": params.c}.items():
        source = source.replace(f"@{key}@", repr(float(value)))
    with tempfile.TemporaryDirectory() as folder:
        folder = pathlib.Path(folder)
        (folder / "bank.c").write_text(source)
        built = subprocess.run([compiler, "-O3", "-o", str(folder / "bank"), str(folder / "bank.c"), "-lm"],
                               capture_output=True, text=True)
        if built.returncode != 0:
            return None
        ran = subprocess.run([str(folder / "bank"), str(field.size), str(size), str(repeats), repr(max_field_step)],
                             input="\n".join(repr(float(v)) for v in field), capture_output=True, text=True)
        if ran.returncode != 0:
            return None
        seconds, substeps, last = ran.stdout.split()
        return float(seconds), int(substeps), float(last)


def run_benchmark(report) -> dict:
    """Print the bank's speed and its comparisons; return the figures for ``--json``."""
    params = HysteresisParams()
    batch = HysteresisBatch.grid(params, np.linspace(*A_GRID, BANK_SIZE))
    field = benchmark_input()
    substeps = _substeps(field, DEFAULT_MAX_FIELD_STEP)
    model_substeps = substeps * batch.size

    cpu, wall, trajectory = time_bank(field, batch)
    ns = cpu / model_substeps * 1e9
    report(f"bank: {batch.size} models (a in [{A_GRID[0]:.0f}, {A_GRID[1]:.0f}] A/m), one shared input, "
           f"{substeps} substeps of <= {DEFAULT_MAX_FIELD_STEP:g} A/m, single thread")
    report(f"bank: {ns:.1f} ns per model-substep (cpu; wall {wall / model_substeps * 1e9:.1f}), "
           f"{cpu * 1e3:.1f} ms for the input")

    # accuracy of the bank at the default step, against a converged (64x finer) solution
    _, _, converged = time_bank(field, batch, DEFAULT_MAX_FIELD_STEP / 64, repeats=1)
    bank_error = float(np.max(np.abs(trajectory - converged)) / params.Ms)
    report(f"bank: max error {bank_error:.2e} Ms at the default step (vs a 64x finer step)")

    results = {"bank_ns_per_model_substep": ns, "bank_models": batch.size, "bank_substeps": substeps,
               "bank_max_error_over_Ms": bank_error, "bank_wall_ns_per_model_substep": wall / model_substeps * 1e9}

    # plain solve_ivp at the same accuracy: tighten the tolerance by decades until it
    # matches, then try half a decade looser and keep the loosest that still matches
    def attempt(tolerance):
        start = time.process_time()
        values, evaluations = solve_ivp_bank(field, batch, rtol=tolerance, atol=tolerance * params.Ms)
        seconds = time.process_time() - start
        error = float(np.max(np.abs(values - converged)) / params.Ms)
        report(f"solve_ivp RK45 rtol={tolerance:.1e}: max error {error:.2e} Ms, {evaluations} rhs calls, "
               f"{seconds:.2f} s")
        return (tolerance, seconds, error) if error <= bank_error else None

    matched = None
    for tolerance in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11):
        matched = attempt(tolerance)
        if matched is not None:
            matched = attempt(tolerance * 10 ** 0.5) or matched
            break
    if matched is None:
        report("solve_ivp: did not reach the bank's accuracy down to rtol=1e-11")
        results["solve_ivp_ratio"] = None
    else:
        tolerance, seconds, error = matched
        ratio = seconds / cpu
        report(f"solve_ivp at matched accuracy ({error:.2e} <= {bank_error:.2e} Ms, rtol={tolerance:.0e}): "
               f"{seconds:.2f} s, {ratio:.0f}x the bank's time")
        results.update(solve_ivp_ratio=ratio, solve_ivp_seconds=seconds, solve_ivp_rtol=tolerance,
                       solve_ivp_max_error_over_Ms=error, bank_seconds=cpu)

    results["hem_bank"] = time_hem_banks(field, ns, cpu / (field.size * batch.size) * 1e9, report)

    c_run = _c_reference(field, params, A_GRID, BANK_SIZE, DEFAULT_MAX_FIELD_STEP)
    if c_run is None:
        report("C -O3 reference: no working C compiler, skipped")
    else:
        c_seconds, c_substeps, c_last = c_run
        c_ns = c_seconds / (c_substeps * BANK_SIZE) * 1e9
        agrees = abs(c_last - trajectory[-1, -1]) / params.Ms
        report(f"C -O3 reference (scalar, libm tanh): {c_ns:.1f} ns per model-substep; "
               f"bank/C = {ns / c_ns:.2f} (final M agrees to {agrees:.1e} Ms)")
        results.update(c_reference_ns_per_model_substep=c_ns, bank_over_c_reference=ns / c_ns)
    return results


#: HEM parameters of the benchmark bank: the relays saturate within the input's 1e5 A/m, the coercive
#: median spread over the bank as a over [6300, 7300] A/m is for (6).
HEM_BENCH_PARAMS = dict(relay_magnetization=7.0e5, reversible_susceptibility=1.0, coercive_spread=0.6,
                        interaction_scale=8000.0)


def time_hem_banks(field, eq6_ns_per_substep, eq6_ns_per_sample, report, repeats=7) -> dict:
    """ns per model-update of HEM banks of BANK_SIZE models (coercive median on a grid) for each interaction
    density, and the ratios to (6)'s per-substep and per-sample costs measured on the same input."""
    out = {}
    for density in hem.INTERACTION_DENSITIES:
        batch = hem.HEMBatch(coercive_median=np.linspace(3000.0, 5000.0, BANK_SIZE), interaction_density=density,
                             **HEM_BENCH_PARAMS)
        constants = batch.constants()
        hem.simulate_shared(field[:3], batch.demagnetized(), constants, batch.kind)  # compile / load from cache
        cpu, _, _ = _best_time(lambda batch=batch, constants=constants:
                                hem.simulate_shared(field, batch.demagnetized(), constants, batch.kind),
                               repeats)
        ns = cpu / (field.size * batch.size) * 1e9
        out[density] = {"ns_per_model_update": ns, "nodes": batch.coercive_nodes,
                        "ratio_to_eq6_per_substep": ns / eq6_ns_per_substep,
                        "ratio_to_eq6_per_sample": ns / eq6_ns_per_sample}
        report(f"HEM bank ({density} interaction density, {batch.coercive_nodes} coercive nodes): {ns:.1f} ns per "
               f"model-update = {ns / eq6_ns_per_substep:.2f}x (6)'s model-substep, "
               f"{ns / eq6_ns_per_sample:.2f}x (6)'s cost per model-sample on this input")
    return out
