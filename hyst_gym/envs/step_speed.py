"""Speed of the default ``hyst_gym/Excitation-v0`` under random actions (``hyst-gym bench``).

Measures env steps per second and simulated seconds per wall second for a single env
(through ``gymnasium.make``, wrappers included) and for the native vector env at
n = 1, 64 and 1024. Targets (2-core machine; ``docs/targets.md``): >= 5,000 steps/s single and
>= 100,000 aggregate steps/s at n = 1024. Each task of the benchmark suite
(:mod:`hyst_gym.envs.suite_v1`) is timed the same way, single and at n = 1024 (targets:
>= 20,000 and >= 200,000 steps/s). Where the time goes: run
``python -m cProfile -s tottime -m hyst_gym.envs.step_speed``.
"""

from __future__ import annotations

import time

import gymnasium
import numpy as np

from .config import EnvConfig

ENV_ID = "hyst_gym/Excitation-v0"
VECTOR_SIZES = (1, 64, 1024)
#: wall-clock seconds spent timing each case (after a warm-up)
TIME_BUDGET = 2.0


def _time_single(budget: float, env_id: str = ENV_ID) -> float:
    env = gymnasium.make(env_id)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.0, 1.0, (4096, 1)).astype(np.float32)
    env.reset(seed=0)
    for action in actions[:200]:  # warm-up (compiled kernels load from the numba cache)
        env.step(action)
    steps = 0
    start = time.perf_counter()
    while time.perf_counter() - start < budget:
        for action in actions[:500]:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        steps += 500
    return steps / (time.perf_counter() - start)


def _time_vector(n: int, budget: float, env_id: str = ENV_ID) -> float:
    venv = gymnasium.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.0, 1.0, (16, n, 1))
    venv.reset(seed=0)
    for k in range(3):
        venv.step(actions[k])
    calls = 0
    start = time.perf_counter()
    while time.perf_counter() - start < budget:
        venv.step(actions[calls % 16])
        calls += 1
    return calls * n / (time.perf_counter() - start)


def run_benchmark(report) -> dict:
    """Print and return the env speeds: ``env_single_steps_per_s`` and
    ``env_vector_steps_per_s`` (keyed by n as a string)."""
    config = EnvConfig()
    report(f"config: {ENV_ID} defaults: {config.summary()}")
    report(f"random actions, {TIME_BUDGET:g} s per case; dt = {config.dt:g} s of simulated time per step")
    single = _time_single(TIME_BUDGET)
    report(f"single env (gymnasium.make): {single:,.0f} steps/s = {single * config.dt:,.1f} simulated s per wall s"
           f"  (target >= 5,000 steps/s)")
    vector = {}
    for n in VECTOR_SIZES:
        rate = _time_vector(n, TIME_BUDGET)
        vector[str(n)] = rate
        target = "  (target >= 100,000)" if n == 1024 else ""
        report(f"native vector env n={n}: {rate:,.0f} env steps/s = {rate * config.dt:,.0f} simulated s per "
               f"wall s{target}")
    return {"env_single_steps_per_s": single, "env_vector_steps_per_s": vector,
            "env_benchmark_config": config.summary(), "suite_steps_per_s": run_suite_benchmark(report)}


#: the suite's vector size and targets, steps/s
SUITE_VECTOR_SIZE = 1024
SUITE_TARGETS = {"single": 20_000, str(SUITE_VECTOR_SIZE): 200_000}


def run_suite_benchmark(report, budget: float = TIME_BUDGET / 2, env_ids=None) -> dict:
    """Steps/s of the suite tasks' envs (registered ids; default all), single and at n = 1024."""
    from .suite_v1 import TASKS

    speeds = {}
    for env_id in TASKS if env_ids is None else env_ids:
        single = _time_single(budget, env_id)
        vector = _time_vector(SUITE_VECTOR_SIZE, budget, env_id)
        speeds[env_id] = {"single": single, str(SUITE_VECTOR_SIZE): vector}
        report(f"suite task {env_id}: single {single:,.0f} steps/s, n={SUITE_VECTOR_SIZE} {vector:,.0f} steps/s "
               f"(targets >= {SUITE_TARGETS['single']:,} and >= {SUITE_TARGETS[str(SUITE_VECTOR_SIZE)]:,})")
    return speeds


if __name__ == "__main__":
    # time the compiled kernels: compile them on first use, not in the background behind their Python twins
    import os

    from ..physics.background_compile import FOREGROUND, MODE_VARIABLE

    os.environ[MODE_VARIABLE] = FOREGROUND
    run_benchmark(print)
