"""The heated floor of the calibration tasks (experiments/floors.py, hyst_gym.estimation.information_bound)
against an adversarial search: admissible inputs (field, slew and heat limits kept), random and optimized,
with the heating moving a during the episode as in the env, never collect more information than the
ceiling; and the best of them comes close to it (the ceiling is not vacuous)."""

import subprocess
import sys

import numpy as np
import pytest

from experiments.floors import calibration_specs, main, task_inputs
from hyst_gym.estimation.information_bound import (current_field_envelope, heated_information_ceiling,
                                                   random_admissible_fields, structured_admissible_fields)
from hyst_gym.physics import HysteresisBatch
from hyst_gym.physics.hysteresis import advance_each

HORIZONS = (60, 120, 200)
#: relative step of the central difference in a0
STEP = 1e-3


@pytest.fixture(scope="module")
def hot_calibrate():
    config, setting, thermal, params_list = task_inputs(calibration_specs()["hyst_gym/HotCalibrate-v0"])
    a_range = (thermal.a_per_kelvin * thermal.start_low, thermal.a_per_kelvin * thermal.temperature_limit)
    envelope = current_field_envelope(params_list, a_range, config.field_limit, config.max_field_change,
                                      config.max_field_step, config.max_field_change / 4, n_paths=512)
    ceiling = heated_information_ceiling(envelope, thermal, config.max_field_change, HORIZONS, 4)
    return config, thermal, ceiling


def collected(fields, start_temperatures, config, thermal):
    """sum_{j<=t} (dM_j/da0)^2 at each horizon (rows) for each input (columns of ``fields``, A/m) and start
    (K): a central difference in a0 with a_t = a0 + (da/dT)*D_t, D_t the input's heating (the hysteresis
    step s uses the a of the temperature before it); shape (horizons, inputs, starts)."""
    steps, n_inputs = fields.shape
    rise = thermal.rise(fields)
    lanes = []
    for start in start_temperatures:
        a_path = thermal.a_per_kelvin * (start + np.vstack([np.zeros((1, n_inputs)), rise[:-1]]))
        step = STEP * thermal.a_per_kelvin * start
        lanes += [a_path - step, a_path + step]
    a_lanes = np.concatenate(lanes, axis=1)
    field = np.tile(fields, (1, 2 * len(start_temperatures)))
    batch = HysteresisBatch.from_params(config.hysteresis, a_lanes.shape[1])
    magnetization = np.zeros(a_lanes.shape[1])
    previous = np.zeros(a_lanes.shape[1])
    squares = np.zeros((steps, n_inputs, len(start_temperatures)))
    for s in range(steps):
        advance_each(magnetization, previous.copy(), field[s].copy(), a_lanes[s].copy(), batch.k, batch.alpha,
                     batch.Ms, batch.c, batch.kind, config.max_field_step)
        previous = field[s].copy()
        for i, start in enumerate(start_temperatures):
            low = magnetization[2 * i * n_inputs:(2 * i + 1) * n_inputs]
            high = magnetization[(2 * i + 1) * n_inputs:(2 * i + 2) * n_inputs]
            squares[s, :, i] = ((high - low) / (2 * STEP * thermal.a_per_kelvin * start)) ** 2
    total = np.cumsum(squares, axis=0)
    return np.array([total[h - 1] for h in HORIZONS])


def within_budget(fields, thermal, budget):
    """Scale each input down (keeping its slew and field limits) until its rise stays <= budget at every step."""
    peak = thermal.rise(fields).max(axis=0)
    return fields * np.minimum(1.0, np.sqrt(budget / np.maximum(peak, 1e-300)))


def ramp_hold_sustain(levels, switches, sustains, config, steps=200):
    """Ramp at the slew limit to a level, hold it until the switch step, then slew to a sustaining level."""
    fields = np.zeros((steps, len(levels)))
    for column, (level, switch, sustain) in enumerate(zip(levels, switches, sustains)):
        current = 0.0
        for s in range(steps):
            target = level if s < switch else sustain
            current += np.clip(target - current, -config.max_field_change, config.max_field_change)
            fields[s, column] = current
    return fields


def thermostat(targets, thermal, config, steps=200):
    """Greedy: each step the largest field within the slew limit that keeps the rise at or below the target."""
    fields = np.zeros((steps, len(targets)))
    for column, target in enumerate(targets):
        current, rise = 0.0, 0.0
        for s in range(steps):
            options = np.linspace(min(current + config.max_field_change, config.field_limit),
                                  max(current - config.max_field_change, 0.0), 41)
            mean_square = (current ** 2 + current * options + options ** 2) / 3
            rises = thermal.decay * rise + thermal.rise_per_mean_square * mean_square
            pick = int(np.argmax(rises <= target)) if np.any(rises <= target) else options.size - 1
            current, rise = options[pick], rises[pick]
            fields[s, column] = current
    return fields


@pytest.mark.parametrize("budget", [15.0, 35.0])
def test_no_admissible_input_collects_more_than_the_ceiling(hot_calibrate, budget):
    """Random admissible inputs, the ramp-hold-sustain family searched at random and then refined around its
    best, thermostats at several set points and the structured dithers, each scaled into the heat budget:
    for none does the information, averaged over the starts of a 1 K piece of the prior whose hottest start
    has exactly that budget (what Van Trees uses, point 1 of the derivation), exceed the ceiling at any
    horizon; the best reaches 70 % of it. Single starts can exceed it: a dither that happens to sit on a
    near-switch of model (6) at that a (the caveat of calibration_heated_floor), printed here."""
    config, thermal, ceiling = hot_calibrate
    bound = ceiling.at(budget)
    starts = thermal.temperature_limit - budget - np.linspace(0.0, 1.0, 9)
    rng = np.random.default_rng(11)
    levels, switches, sustains = rng.uniform(2e4, 1e5, 64), rng.integers(10, 120, 64), rng.uniform(0, 4e4, 64)
    candidates = [random_admissible_fields(48, 200, config.max_field_change, config.field_limit, seed=5),
                  ramp_hold_sustain(levels, switches, sustains, config),
                  thermostat(budget * np.array([0.6, 0.8, 0.9, 0.95, 0.99]), thermal, config),
                  structured_admissible_fields(config.field_limit, config.max_field_change, 200)[:, ::3]]
    fields = within_budget(np.concatenate(candidates, axis=1), thermal, budget)
    info = collected(fields, starts, config, thermal)
    column = int(np.argmax(info[-1, 48:112].mean(axis=1)))
    # a second, local round around the family's best
    local = ramp_hold_sustain(np.clip(levels[column] + rng.normal(0, 5e3, 32), 1e3, 1e5),
                              np.clip(switches[column] + rng.integers(-10, 11, 32), 1, 199),
                              np.clip(sustains[column] + rng.normal(0, 3e3, 32), 0, 1e5), config)
    fields = np.concatenate([fields, within_budget(local, thermal, budget)], axis=1)
    info = np.concatenate([info, collected(fields[:, -32:], starts, config, thermal)], axis=1)
    assert np.all(thermal.rise(fields).max(axis=0) <= budget * (1 + 1e-9))
    averaged = info.mean(axis=2)
    print(f"budget {budget:g} K: best input {averaged[-1].max() / bound[-1]:.3f} of the ceiling, largest "
          f"piece average {np.max(averaged / bound[:, None]):.3f}, largest single start "
          f"{np.max(info / bound[:, None, None]):.3f}")
    assert np.all(averaged <= bound[:, None]), np.max(averaged / bound[:, None])
    assert averaged[-1].max() >= 0.7 * bound[-1]
    assert bound[-1] < 0.9 * ceiling.free[-1]      # and the budget binds


def test_cli_rejects_bad_arguments_in_one_line(capsys, tmp_path):
    assert main(["--tasks", "hyst_gym/NoSuchTask-v0"]) == 2
    assert main(["--paths", "0"]) == 2
    assert main(["--markdown-only", "--out", str(tmp_path)]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 3 and "--tasks" in errors[0] and "--paths" in errors[1] and "floors.json" in errors[2]
    process = subprocess.run([sys.executable, "-m", "experiments.floors", "--paths", "-3"], capture_output=True,
                             text=True)
    assert process.returncode == 2 and "Traceback" not in process.stderr
