"""Compiled per-step kernels of the batched simulator (one call per control step).

:func:`plant_step` moves every sub-env's true plant through one control period: field
limits, the domain-wall model (6) (the physics kernel, called inside), the transducer's
exact first-order-hold update, the exact thermal update and the noisy measurement.
:func:`score_step` turns the estimates into rewards, penalties and terminations. Both
loop over sub-envs independently, so a sub-env's numbers do not depend on the batch.

The kernels are compiled on first use and cached on disk by numba (``cache=True``); the
first environment of a fresh install spends 15-60 s compiling them, so
:func:`announce_compilation` says so once, on stderr, when their cache is missing.
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np
from numba import njit

from ..estimation._kernels import EstimatorState, estimator_step, interpolate_bank
from ..physics.hysteresis import advance_each
from ..physics.linear_system import lti_step
from ..physics.thermal import a_law_kernel, mean_square_linear_kernel, temperature_step_kernel


@njit(cache=True)
def plant_step(command, active, field, magnetization, magnetization_prev, state, state_next, temperature,
               ambient0, drift_rate, steps, a_true, measured, measured_temperature,
               noise, noise_pos, noise_sigma, noisy, temperature_sensor,
               k, alpha, Ms, c, kind, max_field_step, field_limit, max_change,
               phi, gamma0, gamma1, quadratic, drive_gain, output_index, velocity_index,
               drifting, dt, decay, power_per_h2, thermal_resistance, tau, a_reference, t_reference):
    """One control period for every sub-env (arrays of shape (n,) or (n, s), in place).

    ``field`` holds H0 on entry and H1 on exit (A/m); ``temperature`` K; ``steps`` the
    step counters (incremented). Sub-envs with ``active[i] == False`` draw no noise.
    ``noise`` (n, B, w) holds pre-drawn standard normals, ``noise_pos`` the next index.
    """
    n = field.shape[0]
    s = state.shape[1]
    field_from = field.copy()
    for i in range(n):
        target = min(max(command[i], -field_limit), field_limit)
        field[i] = min(max(target, field_from[i] - max_change), field_from[i] + max_change)
        magnetization_prev[i] = magnetization[i]
    advance_each(magnetization, field_from, field, a_true, k, alpha, Ms, c, kind, max_field_step)
    for i in range(n):
        m0 = magnetization_prev[i]
        m1 = magnetization[i]
        if quadratic:
            u0 = drive_gain * m0 * m0
            u1 = drive_gain * m1 * m1
        else:
            u0 = drive_gain * m0
            u1 = drive_gain * m1
        lti_step(phi, gamma0, gamma1, state[i], u0, u1, state_next[i])
        for r in range(s):
            state[i, r] = state_next[i, r]
        if drifting:
            power = power_per_h2 * mean_square_linear_kernel(field_from[i], field[i])
            amb0 = ambient0[i] + drift_rate[i] * (steps[i] * dt)
            amb1 = amb0 + drift_rate[i] * dt
            temperature[i] = temperature_step_kernel(temperature[i], amb0, amb1,
                                                     thermal_resistance * power - drift_rate[i] * tau, decay)
        steps[i] += 1
        a_true[i] = a_law_kernel(a_reference, temperature[i], t_reference)
        measured[i, 0] = state[i, output_index]
        if velocity_index >= 0:
            measured[i, 1] = state[i, velocity_index]
        measured_temperature[i] = temperature[i]
        if noisy and active[i]:
            p = noise_pos[i]
            for r in range(measured.shape[1]):
                measured[i, r] += noise_sigma[r] * noise[i, p, r]
            if temperature_sensor:
                measured_temperature[i] += noise_sigma[measured.shape[1]] * noise[i, p, measured.shape[1]]
            noise_pos[i] = p + 1


@njit(cache=True)
def score_step(a_estimate, a_true, temperature, state, output_index, steps, truncation_steps, theta_width,
               temperature_limit, temperature_band, stroke_limit, stroke_band, penalty_weight,
               reward, terminated, truncated, error, penalty, stroke):
    """Reward ``-|a_estimate - a_true|/width - penalty`` (minus ``remaining steps`` on a
    violation), terminations (constraints) and truncations (time limit). ``stroke_limit``
    <= 0 means no stroke constraint."""
    for i in range(a_true.shape[0]):
        x = abs(state[i, output_index])
        stroke[i] = x
        error[i] = abs(a_estimate[i] - a_true[i]) / theta_width
        excess = (temperature[i] - (temperature_limit - temperature_band)) / temperature_band
        p = excess * excess if excess > 0.0 else 0.0
        violated = temperature[i] > temperature_limit
        if stroke_limit > 0.0:
            excess = (x / stroke_limit - (1.0 - stroke_band)) / stroke_band
            if excess > 0.0:
                p += excess * excess
            if x > stroke_limit:
                violated = True
        p *= penalty_weight
        penalty[i] = p
        r = -error[i] - p
        if violated:
            remaining = truncation_steps - steps[i]
            if remaining > 0:
                r -= remaining
        reward[i] = r
        terminated[i] = violated
        truncated[i] = steps[i] >= truncation_steps


@njit(cache=True)
def fill_observation(obs, measured, scales, field, field_limit, steps, episode_steps, a_estimate, theta_min,
                     theta_width, tuning, eps, curvature, gap, gap_norm, decades, excitation,
                     measured_temperature, t_reference, temperature_scale, temperature_sensor, low, high):
    """Normalized observations (n, d), float32, clipped to the documented bounds."""
    n_out = measured.shape[1]
    for i in range(obs.shape[0]):
        col = 0
        for r in range(n_out):
            obs[i, col] = measured[i, r] / scales[r]
            col += 1
        obs[i, col] = field[i] / field_limit
        obs[i, col + 1] = steps[i] / episode_steps
        obs[i, col + 2] = 2.0 * (a_estimate[i] - theta_min) / theta_width - 1.0
        col += 3
        if excitation:
            t = tuning[i]
            magnitude = math.log10(1.0 + abs(t) / eps) / decades
            obs[i, col] = magnitude if t >= 0.0 else -magnitude
            obs[i, col + 1] = 1.0 if curvature[i] >= 0.0 else -1.0
            obs[i, col + 2] = math.log1p(gap[i]) / gap_norm
            col += 3
        if temperature_sensor:
            obs[i, col] = (measured_temperature[i] - t_reference) / temperature_scale
            col += 1
        for j in range(col):
            v = obs[i, j]
            if v < low[j]:
                obs[i, j] = low[j]
            elif v > high[j]:
                obs[i, j] = high[j]





@njit(cache=True)
def fill_info(info, rows, a_true, a_estimate, temperature, field, magnetization, state, output_index,
              output_offset, steps, dt, value_hat, value_true, curvature, pe_gain, stroke_limit, temperature_limit,
              penalty, theta_width):
    """Write the per-step truth of sub-envs ``rows`` into ``info`` (len(INFO_KEYS), n).

    Row order is :data:`~hyst_gym.envs.core.INFO_KEYS`. ``value_hat``/``value_true`` are
    f(u, thetahat) and f(u, a_true) from the bank, ``curvature`` the sign beta at thetahat.
    """
    for i in rows:
        x = state[i, output_index] + output_offset
        beta = 1.0 if curvature[i] >= 0.0 else -1.0
        info[0, i] = a_true[i]
        info[1, i] = a_estimate[i]
        info[2, i] = abs(a_estimate[i] - a_true[i]) / theta_width
        info[3, i] = temperature[i]
        info[4, i] = field[i]
        info[5, i] = magnetization[i]
        info[6, i] = x
        info[7, i] = steps[i] * dt
        info[8, i] = beta * pe_gain * (value_hat[i] - value_true[i])
        info[9, i] = beta
        info[10, i] = 1.0 - abs(x) / stroke_limit if stroke_limit > 0.0 else np.inf
        info[11, i] = temperature_limit - temperature[i]
        info[12, i] = penalty[i]



@njit(cache=True)
def clip_actions(actions, tolerance, clipped):
    """Copy ``actions`` (n, k) into ``clipped``, clipped to [-1, 1]; returns False (nothing
    written) if a value is not finite or exceeds 1 + ``tolerance`` in magnitude."""
    n, k = actions.shape
    for i in range(n):
        for j in range(k):
            v = actions[i, j]
            if not (abs(v) <= 1.0 + tolerance):  # also catches NaN
                return False
    for i in range(n):
        for j in range(k):
            clipped[i, j] = min(max(actions[i, j], -1.0), 1.0)
    return True


@njit(cache=True)
def finish_step(clipped, agent_estimate, estimate_column, a_estimate, theta_min, theta_max, theta_width,
                a_true, temperature, state, output_index, output_offset, steps, truncation_steps,
                temperature_limit, temperature_band, stroke_limit, stroke_band, penalty_weight,
                reward, terminated, truncated, error, penalty, stroke,
                info, rows, field, magnetization, dt, grid, bank_values, value_hat, curvature, truth_clipped,
                value_true, slope_scratch, second_scratch, pe_gain,
                obs, measured, scales, field_limit, episode_steps, tuning, eps, gap, gap_norm, decades, excitation,
                measured_temperature, t_reference, temperature_scale, temperature_sensor, low, high):
    """Everything after the estimate of one step: rewards and terminations
    (:func:`score_step`), the per-step truth (:func:`fill_info`, with the PE integrand
    from the bank at clip(a_true, Theta)) and the observations (:func:`fill_observation`).

    ``agent_estimate``: the estimate is the agent's (action column ``estimate_column``
    mapped onto Theta); ``value_hat``/``curvature`` are then filled from the bank at it.
    Otherwise they are the estimator's f(u, thetahat) and d2f/dtheta2.
    """
    n = a_true.shape[0]
    if agent_estimate:
        for i in range(n):
            a_estimate[i] = theta_min + 0.5 * (clipped[i, estimate_column] + 1.0) * theta_width
        interpolate_bank(grid, bank_values, a_estimate, value_hat, slope_scratch, curvature)
    score_step(a_estimate, a_true, temperature, state, output_index, steps, truncation_steps, theta_width,
               temperature_limit, temperature_band, stroke_limit, stroke_band, penalty_weight,
               reward, terminated, truncated, error, penalty, stroke)
    for i in range(n):
        truth_clipped[i] = min(max(a_true[i], theta_min), theta_max)
    interpolate_bank(grid, bank_values, truth_clipped, value_true, slope_scratch, second_scratch)
    fill_info(info, rows, a_true, a_estimate, temperature, field, magnetization, state, output_index,
              output_offset, steps, dt, value_hat, value_true, curvature, pe_gain,
              stroke_limit, temperature_limit, penalty, theta_width)
    fill_observation(obs, measured, scales, field, field_limit, steps, episode_steps, a_estimate, theta_min,
                     theta_width, tuning, eps, curvature, gap, gap_norm, decades, excitation,
                     measured_temperature, t_reference, temperature_scale, temperature_sensor, low, high)


@njit(cache=True)
def excitation_step(actions, tolerance, clipped, command, active,
                    field, magnetization, magnetization_prev, state, state_next, temperature, ambient0, drift_rate,
                    steps, a_true, measured, measured_temperature, noise, noise_pos, noise_sigma, noisy,
                    temperature_sensor, k, alpha, Ms, c, kind, max_field_step, field_limit, max_change,
                    phi, gamma0, gamma1, quadratic, drive_gain, output_index, velocity_index,
                    drifting, dt, decay, power_per_h2, thermal_resistance, tau, a_reference, t_reference,
                    bank, bank_params, estimator, observer, hold,
                    agent_estimate, estimate_column, a_estimate, theta_min, theta_max, theta_width,
                    f_a_true, f_temperature, f_state, f_output_index, output_offset, f_steps, truncation_steps,
                    temperature_limit, temperature_band, stroke_limit, stroke_band, penalty_weight,
                    reward, terminated, truncated, error, penalty, stroke,
                    info, rows, f_field, f_magnetization, f_dt, f_grid, f_bank_values, value_hat, curvature,
                    truth_clipped, value_true, slope_scratch, second_scratch, pe_gain,
                    obs, f_measured, scales, f_field_limit, episode_steps, tuning, f_eps, gap, gap_norm, decades,
                    excitation, measured_temperature_obs, t_reference_obs, temperature_scale,
                    temperature_sensor_obs, low, high):
    """One whole Excitation step in one call: actions -> :func:`plant_step` -> the
    estimator's :func:`~hyst_gym.estimation._kernels.estimator_step` -> :func:`finish_step`.

    Argument groups are, in order, those of the four kernels (the ``f_`` names of the
    last group repeat arrays passed before); the estimator's are its named state
    (:class:`~hyst_gym.estimation._kernels.BankState`, ``BankParams``, ``EstimatorState``,
    ``ObserverParams``, ``HoldParams``) as plain tuples (``as_kernel_tuples``). Returns 0, 1 (an action is not finite or
    outside [-1, 1]; nothing changed) or 2 (the estimator got a non-finite input).
    """
    if not clip_actions(actions, tolerance, clipped):
        return 1
    for i in range(command.shape[0]):
        command[i] = clipped[i, 0] * field_limit
    plant_step(command, active, field, magnetization, magnetization_prev, state, state_next, temperature,
               ambient0, drift_rate, steps, a_true, measured, measured_temperature, noise, noise_pos, noise_sigma,
               noisy, temperature_sensor, k, alpha, Ms, c, kind, max_field_step, field_limit, max_change,
               phi, gamma0, gamma1, quadratic, drive_gain, output_index, velocity_index,
               drifting, dt, decay, power_per_h2, thermal_resistance, tau, a_reference, t_reference)
    if estimator_step(field, measured, bank, bank_params, estimator, observer, hold):
        return 2
    theta = EstimatorState(*estimator).theta
    for i in range(theta.shape[0]):
        a_estimate[i] = theta[i]
    finish_step(clipped, agent_estimate, estimate_column, a_estimate, theta_min, theta_max, theta_width,
                f_a_true, f_temperature, f_state, f_output_index, output_offset, f_steps, truncation_steps,
                temperature_limit, temperature_band, stroke_limit, stroke_band, penalty_weight,
                reward, terminated, truncated, error, penalty, stroke,
                info, rows, f_field, f_magnetization, f_dt, f_grid, f_bank_values, value_hat, curvature,
                truth_clipped, value_true, slope_scratch, second_scratch, pe_gain,
                obs, f_measured, scales, f_field_limit, episode_steps, tuning, f_eps, gap, gap_norm, decades,
                excitation, measured_temperature_obs, t_reference_obs, temperature_scale,
                temperature_sensor_obs, low, high)
    return 0


__all__ = ["clip_actions", "excitation_step", "fill_info", "fill_observation", "finish_step", "plant_step",
           "score_step"]


#: printed once per process, on stderr, before the first environment compiles its kernels
COMPILE_NOTICE = ("hyst-gym: compiling the simulation kernels (first use only, 20-60 s on 2 cores; "
                  "cached afterwards)")
_compile_notice_shown = False


def is_cached(kernel) -> bool:
    """Whether numba's on-disk cache holds an index for ``kernel`` (it is then loaded, not
    compiled). The index path is numba's own choice of cache folder (``__pycache__``
    beside the module, ``NUMBA_CACHE_DIR``, or the user-wide cache); it is read from
    numba's cache object, which is internal: where it cannot be read (another numba, or
    ``NUMBA_DISABLE_JIT``), this says True, so the notice is never printed on every run."""
    try:
        index_path = kernel._cache._cache_file._index_path
    except AttributeError:
        return True
    return os.path.exists(index_path)


def announce_compilation(kernels) -> None:
    """Print :data:`COMPILE_NOTICE` to stderr, once per process, if any of ``kernels`` is
    not in numba's cache (so its first call compiles it). A print, not a warning: it is
    news, not a problem, and must show even where warnings are filtered."""
    global _compile_notice_shown
    if _compile_notice_shown or all(is_cached(kernel) for kernel in kernels):
        return
    _compile_notice_shown = True
    print(COMPILE_NOTICE, file=sys.stderr, flush=True)
