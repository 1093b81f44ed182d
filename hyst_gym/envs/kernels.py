"""Compiled per-step kernels of the batched simulator (one call per control step).

:func:`plant_step` moves every sub-env's true plant through one control period: field
limits, the domain-wall model (6) (the physics kernel, called inside), the transducer's
exact first-order-hold update, the exact thermal update and the noisy measurement.
:func:`score_step` turns the estimates into rewards, penalties and terminations. Both
loop over sub-envs independently, so a sub-env's numbers do not depend on the batch.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..physics.hysteresis import advance_each


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
        for r in range(s):
            acc = gamma0[r] * u0 + gamma1[r] * u1
            for q in range(s):
                acc += phi[r, q] * state[i, q]
            state_next[i, r] = acc
        for r in range(s):
            state[i, r] = state_next[i, r]
        if drifting:
            h0 = field_from[i]
            h1 = field[i]
            power = power_per_h2 * (h0 * h0 + h0 * h1 + h1 * h1) / 3.0
            time0 = steps[i] * dt
            amb0 = ambient0[i] + drift_rate[i] * time0
            amb1 = amb0 + drift_rate[i] * dt
            offset = thermal_resistance * power - drift_rate[i] * tau
            temperature[i] = (amb1 + offset) + (temperature[i] - (amb0 + offset)) * decay
        steps[i] += 1
        a_true[i] = a_reference * temperature[i] / t_reference
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

__all__ = ["fill_info", "fill_observation", "plant_step", "score_step"]
