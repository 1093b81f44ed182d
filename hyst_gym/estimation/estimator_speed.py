"""``hyst-gym bench`` section: cost of one estimator control step (bank + min-max + laws).

Measured on the paper's §4.1 setting (a 1 ms step of a 1e5 A/m / 6 s ramp, i.e. one
hysteresis substep per bank model and step), for grid sizes 32 and 64, a single
system (E = 1, the Python-overhead worst case) and a batch of E = 64 systems.
"""

from __future__ import annotations

import time

import numpy as np

from ..physics.background_compile import foreground_compiles
from .config import EstimatorConfig
from .estimators import MinMaxEstimator


def _steps_per_second(grid_size: int, n_systems: int, steps: int) -> tuple[float, float]:
    """(estimator steps per second, bank-only steps per second) for one batch size, the kernels compiled
    before the clock starts (never their plain-Python twins)."""
    with foreground_compiles():
        return _time_estimator(grid_size, n_systems, steps)


def _time_estimator(grid_size: int, n_systems: int, steps: int) -> tuple[float, float]:
    config = EstimatorConfig.paper_scalar(grid_size=grid_size)
    estimator = MinMaxEstimator(config, n_systems)
    dt = 1e-3
    field_step = 1e5 / 6000.0
    outputs = np.zeros(n_systems)
    estimator.update(np.full(n_systems, field_step), outputs, dt)  # compile / warm up
    start = time.perf_counter()
    for i in range(2, steps + 2):
        estimator.update(np.full(n_systems, i * field_step), outputs, dt)
    full = steps / (time.perf_counter() - start)
    bank = estimator.bank
    start = time.perf_counter()
    for i in range(steps + 2, 2 * steps + 2):
        bank.advance(np.full(n_systems, i * field_step))
    bank_only = steps / (time.perf_counter() - start)
    return full, bank_only


def run_benchmark(report) -> dict:
    per_grid = {}
    batched = {}
    for grid_size in (32, 64):
        full, bank_only = _steps_per_second(grid_size, 1, 3000)
        per_grid[str(grid_size)] = full
        report(f"min-max estimator, G={grid_size}, E=1: {1e6 / full:7.1f} us/step = {full:9.0f} steps/s "
               f"(bank alone {1e6 / bank_only:6.1f} us/step)")
        full_b, bank_b = _steps_per_second(grid_size, 64, 500)
        batched[str(grid_size)] = full_b * 64
        report(f"min-max estimator, G={grid_size}, E=64: {1e6 / full_b:7.1f} us/step = "
               f"{full_b * 64:9.0f} system-steps/s (bank alone {1e6 / bank_b:6.1f} us/step)")
    return {"estimator_steps_per_s": per_grid, "estimator_system_steps_per_s_batch64": batched}
