"""Compiled per-step kernels of the batched simulator (one call per control step).

:func:`plant_step` moves every sub-env's true plant through one control period: field
limits, the domain-wall model (6) (the physics kernel, called inside), the transducer's
exact first-order-hold update, the exact thermal update and the noisy measurement.
:func:`score_step` turns the estimates into rewards, penalties and terminations. Both
loop over sub-envs independently, so a sub-env's numbers do not depend on the batch.

The kernels are compiled on first use and cached on disk by numba (``cache=True``); the
first environment of a fresh install needs 10-30 s to compile them. The ones Python calls are
:func:`~hyst_gym.physics.background_compile.background_kernel`: a helper process compiles
them while their plain-Python twins serve the first steps (same numbers bit for bit), and
:func:`announce_compilation` says so once, on stderr, when their cache is missing.
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np
from numba import njit

from collections import namedtuple

from ..estimation._kernels import (BankParams, BankState, EstimatorState, advance_bank, estimator_step,
                                  interpolate_bank)
from ..physics.background_compile import BACKGROUND, PYTHON, background_kernel, effective_mode
from ..physics.hysteresis import advance_each, advance_shared
from ..physics.linear_system import lti_step
from ..physics.thermal import a_law_kernel, mean_square_linear_kernel, temperature_step_kernel

# Named state and parameters of the step kernels (namedtuples of arrays and numbers, as in the
# estimation layer, gymnax's EnvState/EnvParams the model). The kernels that Python calls once
# per step (plant_step, finish_step, excitation_step) take them as plain tuples, made with
# ``as_kernel_tuples``, and name them again on entry: numba types a plain tuple in its C
# dispatcher but a namedtuple in Python, at about twice the cost per field.

#: The true plants of the n sub-envs, changed in place: field H (A/m, H0 on entry of a step, H1
#: on exit), magnetization M and M at the start of the step (A/m), transducer state and its
#: scratch (n, s), temperature T and ambient at t = 0 (K), ambient drift (K/s), step counters,
#: a(T) (A/m), measured outputs (n, w) and temperature (K), the pre-drawn standard normals
#: (n, B, w) and the next index into them.
PlantState = namedtuple("PlantState", [
    "field", "magnetization", "magnetization_prev", "state", "state_next", "temperature", "ambient0",
    "drift_rate", "steps", "a_true", "measured", "measured_temperature", "noise", "noise_pos"])
#: The plants' fixed data: hysteresis parameters (n,) but a, the curve ``kind`` and
#: ``max_field_step``; field limits (A/m per step); the transducer's exact discretization
#: (``phi``, ``gamma0``, ``gamma1``), drive (``quadratic``, ``drive_gain``) and output indices
#: (velocity -1: none); the thermal model (``drifting``, ``dt`` s, ``decay`` exp(-dt/tau),
#: R/n^2, R_th, tau, a(T) of (4): a_reference at t_reference); the noise (sigma per measured
#: column, whether any, whether a temperature sensor is measured).
PlantParams = namedtuple("PlantParams", [
    "k", "alpha", "Ms", "c", "kind", "max_field_step", "field_limit", "max_change", "phi", "gamma0", "gamma1",
    "quadratic", "drive_gain", "output_index", "velocity_index", "drifting", "dt", "decay", "power_per_h2",
    "thermal_resistance", "tau", "a_reference", "t_reference", "noise_sigma", "noisy", "temperature_sensor"])
#: What the env reads of the estimate, (n,) arrays: thetahat (A/m), f(u, thetahat) and
#: d2f/dtheta2 at it, the tuning error y_eps and the min-max gap nu_star (the estimator's
#: live arrays; without an estimator the agent's estimate and filled scratch).
EstimateView = namedtuple("EstimateView", ["a_estimate", "value_hat", "curvature", "tuning", "gap"])
#: Rewards, terminations and the per-step truth: the time limit (steps), Theta and its width
#: (A/m), the temperature and stroke limits with their penalty bands (stroke_limit <= 0: none),
#: the penalty weight, the output read (index, offset), dt (s), the gain of the PE integrand,
#: and whether the estimate is the agent's (action column ``estimate_column``).
ScoreParams = namedtuple("ScoreParams", [
    "truncation_steps", "theta_min", "theta_max", "theta_width", "temperature_limit", "temperature_band",
    "stroke_limit", "stroke_band", "penalty_weight", "output_index", "output_offset", "dt", "pe_gain",
    "agent_estimate", "estimate_column"])
#: The observation layout: output scales, field and time normalization, Theta, the tuning
#: features (eps, log-gap normalization, decades, present only with an estimator), the
#: temperature feature (reference, scale, present only with a sensor) and the bounds.
ObservationLayout = namedtuple("ObservationLayout", [
    "scales", "field_limit", "episode_steps", "theta_min", "theta_width", "eps", "gap_norm", "decades",
    "excitation", "t_reference", "temperature_scale", "temperature_sensor", "low", "high"])
#: What one step writes besides the plant and the estimate: clipped actions (n, k), field
#: commands, observations (n, d) float32, the info rows (len(INFO_KEYS), n) and the rows filled,
#: rewards, terminations, truncations, errors, penalties, strokes, and scratch for f at the truth.
StepBuffers = namedtuple("StepBuffers", [
    "clipped", "command", "obs", "info", "rows", "reward", "terminated", "truncated", "error", "penalty", "stroke",
    "truth_clipped", "value_true", "slope_scratch", "second_scratch"])
#: All fixed data of one env step: action tolerance, then PlantParams, ScoreParams, ObservationLayout.
EnvParams = namedtuple("EnvParams", ["tolerance", "plant", "score", "layout"])
#: The Gaussian likelihood of a grid posterior (:class:`~hyst_gym.envs.posterior.GridPosterior`): the measured
#: columns it reads, their normalization scales, the noise variance sigma**2 (normalized units) and the node
#: simulators per sub-env (one row each of the node plants' :class:`PlantState`).
LikelihoodParams = namedtuple("LikelihoodParams", ["channels", "scales", "variance", "per"])
#: The alive rows of a grid posterior's sub-envs (its pruning state, changed in place): per sub-env (n,) the first
#: T0 node whose node plants are simulated and the one past the last (int64); the nodes outside are dead
#: (:func:`prune_rows`).
AliveRows = namedtuple("AliveRows", ["first", "stop"])
#: A grid posterior's pruning: its T0 and k nodes, the gap (nats) below the sub-env's best node past which a node
#: is dead (inf: none dies) and the log-posterior a dead node is given (finite: see the grid posterior's module doc).
PruneParams = namedtuple("PruneParams", ["nodes", "k_nodes", "dead_gap", "dead_log_post"])


# plant_step, score_step, clip_actions, finish_step and the estimator's estimator_step,
# advance_bank and observer_step are inline="always" (numba IR inlining): their one compiled
# caller (excitation_step, or a kernel it calls) compiles them as part of itself instead of
# building each as a library of its own first (about 1.5 s less on a fresh install's first
# step; their callees stay ordinary calls, so the inlining is cheap: see the note on inlining
# in physics/hysteresis.py). Python still calls them as usual.
@background_kernel(inline="always")
def plant_step(command, active, plant, params):
    """One control period for every sub-env, in place in ``plant`` (a :class:`PlantState`;
    ``params`` a :class:`PlantParams`, both as plain tuples).

    ``plant.field`` holds H0 on entry and H1 on exit (A/m); the step counters are
    incremented. Sub-envs with ``active[i] == False`` draw no noise.
    """
    plant, params = PlantState(*plant), PlantParams(*params)
    field_from = limit_fields(command, plant, params)
    advance_each(plant.magnetization, field_from, plant.field, plant.a_true, params.k, params.alpha, params.Ms,
                 params.c, params.kind, params.max_field_step)
    finish_plants(field_from, active, plant, params)


@njit(cache=True, inline="always")
def limit_fields(command, plant, params):
    """The first part of :func:`plant_step` (named ``plant`` and ``params``): the field H1 within the field
    and slew limits into ``plant.field``, M kept as the step's start; returns H0 (a new array)."""
    field, magnetization, magnetization_prev = plant.field, plant.magnetization, plant.magnetization_prev
    field_from = field.copy()
    for i in range(field.shape[0]):
        field[i] = limited_field(command[i], field_from[i], params)
        magnetization_prev[i] = magnetization[i]
    return field_from


@njit(cache=True, inline="always")
def limited_field(command, field_from, params):
    """H1 of one plant (A/m): the command within the field limit, then within the slew limit of H0 ``field_from``."""
    target = min(max(command, -params.field_limit), params.field_limit)
    return min(max(target, field_from - params.max_change), field_from + params.max_change)


@njit(cache=True, inline="always")
def finish_plants(field_from, active, plant, params):
    """The part of :func:`plant_step` after model (6) has moved M (named ``plant`` and ``params``): the
    transducer, the thermal model, a(T) and the (noisy) measurement."""
    measured, measured_temperature = plant.measured, plant.measured_temperature
    finish_transducers(0, plant.field.shape[0], plant, params)
    for i in range(plant.field.shape[0]):
        finish_thermal(i, field_from[i], plant.field[i], plant, params)
        if params.noisy and active[i]:
            p = plant.noise_pos[i]
            noise, noise_sigma = plant.noise, params.noise_sigma
            for r in range(measured.shape[1]):
                measured[i, r] += noise_sigma[r] * noise[i, p, r]
            if params.temperature_sensor:
                measured_temperature[i] += noise_sigma[measured.shape[1]] * noise[i, p, measured.shape[1]]
            plant.noise_pos[i] = p + 1


@njit(cache=True, inline="always")
def finish_transducers(first, stop, plant, params):
    """The transducers of plants ``first..stop-1`` over the step (their drive from M at the step's start,
    ``plant.magnetization_prev``, to M at its end) and their noise-free outputs into ``plant.measured``. A loop
    over a range of plants, not a helper per plant: inlined per plant, the helper ran about 10x slower in
    :func:`posterior_step` (measured)."""
    state, state_next, measured = plant.state, plant.state_next, plant.measured
    magnetization, magnetization_prev = plant.magnetization, plant.magnetization_prev
    drive_gain = params.drive_gain
    s = state.shape[1]
    if s == 1:
        _finish_first_order(first, stop, plant, params)
        return
    for i in range(first, stop):
        u0 = _drive_forcing(magnetization_prev[i], drive_gain, params.quadratic)
        u1 = _drive_forcing(magnetization[i], drive_gain, params.quadratic)
        lti_step(params.phi, params.gamma0, params.gamma1, state[i], u0, u1, state_next[i])
        for r in range(s):
            state[i, r] = state_next[i, r]
        measured[i, 0] = state[i, params.output_index]
        if params.velocity_index >= 0:
            measured[i, 1] = state[i, params.velocity_index]


@njit(cache=True, inline="always")
def _drive_forcing(m, drive_gain, quadratic):
    """The transducer's forcing at magnetization ``m``: ``drive_gain*M^2`` for the quadratic law, else
    ``drive_gain*M`` (the arithmetic of both finishing loops, in its order)."""
    return drive_gain * m * m if quadratic else drive_gain * m


@njit(cache=True, inline="always")
def _finish_first_order(first, stop, plant, params):
    """:func:`finish_transducers` of a transducer with one state (the first-order plant): :func:`lti_step`'s
    arithmetic in its order, without its loops over the state, so that the compiler vectorizes the loop over the
    plants (measured: about 1.5x faster on a grid posterior's node plants)."""
    state, state_next, measured = plant.state, plant.state_next, plant.measured
    magnetization, magnetization_prev = plant.magnetization, plant.magnetization_prev
    drive_gain, phi, gamma0, gamma1 = params.drive_gain, params.phi[0, 0], params.gamma0[0], params.gamma1[0]
    for i in range(first, stop):
        u0 = _drive_forcing(magnetization_prev[i], drive_gain, params.quadratic)
        u1 = _drive_forcing(magnetization[i], drive_gain, params.quadratic)
        acc = gamma0 * u0 + gamma1 * u1
        acc += phi * state[i, 0]
        state_next[i, 0] = acc
        state[i, 0] = acc
        measured[i, 0] = acc  # the output is the one state (output_index 0)
        if params.velocity_index >= 0:
            measured[i, 1] = acc


@njit(cache=True, inline="always")
def finish_thermal(i, field_from, field_to, plant, params):
    """The thermal model of plant ``i`` over the step (the field from ``field_from`` to ``field_to``, A/m), its step
    counter, a(T) and its noise-free measured temperature. Reads nothing of the magnetic or transducer state."""
    temperature, steps = plant.temperature, plant.steps
    if params.drifting:
        drift_rate = plant.drift_rate[i]
        power = params.power_per_h2 * mean_square_linear_kernel(field_from, field_to)
        amb0 = plant.ambient0[i] + drift_rate * (steps[i] * params.dt)
        amb1 = amb0 + drift_rate * params.dt
        temperature[i] = temperature_step_kernel(temperature[i], amb0, amb1,
                                                 params.thermal_resistance * power - drift_rate * params.tau,
                                                 params.decay)
    steps[i] += 1
    plant.a_true[i] = a_law_kernel(params.a_reference, temperature[i], params.t_reference)
    plant.measured_temperature[i] = temperature[i]


@njit(cache=True, inline="always")
def score_step(plant, view, buffers, score):
    """Reward ``-|a_estimate - a_true|/width - penalty`` (minus ``remaining steps`` on a
    violation), terminations (constraints) and truncations (time limit), into ``buffers``.
    ``score.stroke_limit`` <= 0 means no stroke constraint."""
    a_true, temperature, state, steps = plant.a_true, plant.temperature, plant.state, plant.steps
    a_estimate = view.a_estimate
    temperature_limit, temperature_band = score.temperature_limit, score.temperature_band
    stroke_limit, stroke_band = score.stroke_limit, score.stroke_band
    for i in range(a_true.shape[0]):
        x = abs(state[i, score.output_index])
        buffers.stroke[i] = x
        error = abs(a_estimate[i] - a_true[i]) / score.theta_width
        buffers.error[i] = error
        excess = (temperature[i] - (temperature_limit - temperature_band)) / temperature_band
        p = excess * excess if excess > 0.0 else 0.0
        violated = temperature[i] > temperature_limit
        if stroke_limit > 0.0:
            excess = (x / stroke_limit - (1.0 - stroke_band)) / stroke_band
            if excess > 0.0:
                p += excess * excess
            if x > stroke_limit:
                violated = True
        p *= score.penalty_weight
        buffers.penalty[i] = p
        r = -error - p
        if violated:
            remaining = score.truncation_steps - steps[i]
            if remaining > 0:
                r -= remaining
        buffers.reward[i] = r
        buffers.terminated[i] = violated
        buffers.truncated[i] = steps[i] >= score.truncation_steps


@background_kernel()
def fill_observation(obs, plant, view, layout):
    """Normalized observations (n, d), float32, clipped to the documented bounds
    (``plant`` a :class:`PlantState`, ``view`` an :class:`EstimateView`, ``layout`` an
    :class:`ObservationLayout`)."""
    measured, field, steps = plant.measured, plant.field, plant.steps
    tuning, curvature, gap = view.tuning, view.curvature, view.gap
    scales, low, high = layout.scales, layout.low, layout.high
    n_out = measured.shape[1]
    for i in range(obs.shape[0]):
        col = 0
        for r in range(n_out):
            obs[i, col] = measured[i, r] / scales[r]
            col += 1
        obs[i, col] = field[i] / layout.field_limit
        obs[i, col + 1] = steps[i] / layout.episode_steps
        obs[i, col + 2] = 2.0 * (view.a_estimate[i] - layout.theta_min) / layout.theta_width - 1.0
        col += 3
        if layout.excitation:
            t = tuning[i]
            magnitude = math.log10(1.0 + abs(t) / layout.eps) / layout.decades
            obs[i, col] = magnitude if t >= 0.0 else -magnitude
            obs[i, col + 1] = 1.0 if curvature[i] >= 0.0 else -1.0
            obs[i, col + 2] = math.log1p(gap[i]) / layout.gap_norm
            col += 3
        if layout.temperature_sensor:
            obs[i, col] = (plant.measured_temperature[i] - layout.t_reference) / layout.temperature_scale
            col += 1
        for j in range(col):
            v = obs[i, j]
            if v < low[j]:
                obs[i, j] = low[j]
            elif v > high[j]:
                obs[i, j] = high[j]


@background_kernel()
def fill_info(info, rows, plant, view, value_true, penalty, score):
    """Write the per-step truth of sub-envs ``rows`` into ``info`` (len(INFO_KEYS), n).

    Row order is :data:`~hyst_gym.envs.core.INFO_KEYS`. ``view.value_hat`` and ``value_true``
    are f(u, thetahat) and f(u, a_true) from the bank, ``view.curvature`` the sign beta at thetahat.
    """
    a_true, a_estimate, temperature, state = plant.a_true, view.a_estimate, plant.temperature, plant.state
    stroke_limit = score.stroke_limit
    for i in rows:
        x = state[i, score.output_index] + score.output_offset
        beta = 1.0 if view.curvature[i] >= 0.0 else -1.0
        info[0, i] = a_true[i]
        info[1, i] = a_estimate[i]
        info[2, i] = abs(a_estimate[i] - a_true[i]) / score.theta_width
        info[3, i] = temperature[i]
        info[4, i] = plant.field[i]
        info[5, i] = plant.magnetization[i]
        info[6, i] = x
        info[7, i] = plant.steps[i] * score.dt
        info[8, i] = beta * score.pe_gain * (view.value_hat[i] - value_true[i])
        info[9, i] = beta
        info[10, i] = 1.0 - abs(x) / stroke_limit if stroke_limit > 0.0 else np.inf
        info[11, i] = score.temperature_limit - temperature[i]
        info[12, i] = penalty[i]


@njit(cache=True)
def field_commands(actions, params, buffers):
    """The field commands (A/m) of the actions: ``buffers.clipped`` the actions clipped to [-1, 1] and
    ``buffers.command`` its first column times the field limit; ``params`` an :class:`EnvParams`,
    ``buffers`` a :class:`StepBuffers`. Returns False (nothing written) as :func:`clip_actions` does."""
    clipped, command = buffers.clipped, buffers.command
    if not clip_actions(actions, params.tolerance, clipped):
        return False
    field_limit = PlantParams(*params.plant).field_limit
    for i in range(command.shape[0]):
        command[i] = clipped[i, 0] * field_limit
    return True


@background_kernel(inline="always")
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


@background_kernel(inline="always")
def finish_step(plant, view, buffers, score, layout, bank, bank_params):
    """Everything after the estimate of one step: rewards and terminations
    (:func:`score_step`), the per-step truth (:func:`fill_info`, with the PE integrand
    from the bank at clip(a_true, Theta)) and the observations (:func:`fill_observation`).
    All seven structures come as plain tuples (``as_kernel_tuples``).

    ``score.agent_estimate``: the estimate is the agent's (action column
    ``score.estimate_column`` mapped onto Theta); ``view.value_hat``/``view.curvature`` are
    then filled from the bank at it. Otherwise they are the estimator's f(u, thetahat) and
    d2f/dtheta2.
    """
    plant, view, buffers = PlantState(*plant), EstimateView(*view), StepBuffers(*buffers)
    score, layout = ScoreParams(*score), ObservationLayout(*layout)
    grid, bank_values = BankParams(*bank_params).grid, BankState(*bank).magnetization
    a_true, a_estimate = plant.a_true, view.a_estimate
    theta_min, theta_max, theta_width = score.theta_min, score.theta_max, score.theta_width
    n = a_true.shape[0]
    if score.agent_estimate:
        for i in range(n):
            a_estimate[i] = theta_min + 0.5 * (buffers.clipped[i, score.estimate_column] + 1.0) * theta_width
        interpolate_bank(grid, bank_values, a_estimate, view.value_hat, buffers.slope_scratch, view.curvature)
    score_step(plant, view, buffers, score)
    for i in range(n):
        buffers.truth_clipped[i] = min(max(a_true[i], theta_min), theta_max)
    interpolate_bank(grid, bank_values, buffers.truth_clipped, buffers.value_true, buffers.slope_scratch,
                     buffers.second_scratch)
    fill_info(buffers.info, buffers.rows, plant, view, buffers.value_true, buffers.penalty, score)
    fill_observation(buffers.obs, plant, view, layout)


@background_kernel()
def excitation_step(actions, active, plant, view, buffers, params, estimator):
    """One whole Excitation step in one call: actions -> :func:`plant_step` -> the
    estimator's :func:`~hyst_gym.estimation._kernels.estimator_step` -> :func:`finish_step`.

    ``plant`` (:class:`PlantState`), ``view`` (:class:`EstimateView`), ``buffers``
    (:class:`StepBuffers`), ``params`` (:class:`EnvParams`) and ``estimator`` (the estimation
    layer's BankState, BankParams, EstimatorState, ObserverParams and HoldParams, in that
    order) come as plain tuples. Returns 0, 1 (an action is not finite or outside [-1, 1];
    nothing changed) or 2 (the estimator got a non-finite input).
    """
    # named copies for what this kernel reads itself; the callees take the plain tuples
    named = EnvParams(*params)
    named_buffers, named_plant = StepBuffers(*buffers), PlantState(*plant)
    bank, bank_params, state, observer, hold = estimator
    if not field_commands(actions, named, named_buffers):
        return 1
    plant_step(named_buffers.command, active, plant, named.plant)
    if estimator_step(named_plant.field, named_plant.measured, bank, bank_params, state, observer, hold):
        return 2
    theta, a_estimate = EstimatorState(*state).theta, EstimateView(*view).a_estimate
    for i in range(theta.shape[0]):
        a_estimate[i] = theta[i]
    finish_step(plant, view, buffers, named.score, named.layout, bank, bank_params)
    return 0


@background_kernel()
def identification_commands(actions, params, buffers):
    """The first part of :func:`identification_step` (as plain tuples: ``params`` an :class:`EnvParams`, ``buffers``
    a :class:`StepBuffers`): the clipped actions and the field commands of every sub-env (:func:`field_commands`).
    Returns False (nothing written) as :func:`clip_actions` does."""
    return field_commands(actions, EnvParams(*params), StepBuffers(*buffers))


@background_kernel(nogil=True)
def identification_plants(command, active, plant, plant_params, bank, bank_params):
    """The middle part of :func:`identification_step` for a block of sub-envs (views of the simulator's arrays, as
    plain tuples): :func:`plant_step` with the field commands ``command`` and the model bank at the new field
    (:func:`~hyst_gym.estimation._kernels.advance_bank`). A sub-env's numbers depend on its row alone, and the
    kernel runs without the GIL: the simulator steps two blocks in two threads at once. The last part is
    :func:`finish_step` for all sub-envs."""
    plant_step(command, active, plant, plant_params)
    advance_bank(bank, PlantState(*plant).field, bank_params)


@background_kernel(nogil=True)
def posterior_step(updating, measured, log_post, field, stepping, alive, plant, plant_params, likelihood, pruning):
    """One step of a grid posterior's node simulators (the plants only: no estimator bank, score or
    observation), with its log-likelihood update and its pruning first. It runs without the GIL: the grid posterior
    may step two disjoint blocks of sub-envs (views of its arrays) in two threads at once.

    ``updating``: (n,) bool, the sub-envs whose ``log_post`` rows ((n, per), node-major as the node plants: node
    ``t*k_nodes + q`` is T0 node t, k node q) gain, at their alive nodes, the Gaussian log-likelihood
    ``-0.5*sum(residual**2)/sigma**2`` of their normalized outputs ``measured`` ((n, channels)) against the node
    plants' noise-free outputs (before this step); then :func:`prune_rows` narrows their alive rows. Then, if
    ``stepping``, every node plant of sub-env ``i`` takes the field command ``clip(field[i], -1, 1)*field_limit``
    (:func:`plant_step`'s arithmetic, without noise: the node plants are noise-free) at its alive nodes; a dead node
    plant stays as it was, but for the *width nodes* (k node 0 of T0 nodes 0 and 1), whose field, thermal model and
    a(T) step on (the spread's cell width reads a there: :func:`posterior_moments`). ``alive``
    (:class:`AliveRows`), ``plant`` (:class:`PlantState`), ``plant_params`` (:class:`PlantParams`), ``likelihood``
    (:class:`LikelihoodParams`) and ``pruning`` (:class:`PruneParams`) come as plain tuples. Returns 1 (nothing
    changed) if a field is NaN, else 0."""
    like, nodes, rows, prune = LikelihoodParams(*likelihood), PlantState(*plant), AliveRows(*alive), \
        PruneParams(*pruning)
    if stepping:
        for i in range(field.shape[0]):
            if field[i] != field[i]:
                return 1
    params = PlantParams(*plant_params)
    # one pass over the sub-envs, each updated and stepped in turn (a row's numbers depend on that row alone): its
    # node plants are read by the update and the step while they are in the cache
    for i in range(log_post.shape[0]):
        if updating[i]:
            _node_likelihood(i, measured, log_post[i], nodes, rows, like, prune.k_nodes)
            prune_rows(i, log_post[i], rows, prune)
        if stepping:
            _step_nodes(i, field[i], nodes, params, rows, like.per, prune.k_nodes)
    return 0


@njit(cache=True, inline="always")
def _node_likelihood(i, measured, log_post, nodes, rows, like, k_nodes):
    """Sub-env ``i``'s log-posterior ``log_post`` (per,) gains, at its alive nodes, the Gaussian log-likelihood of
    its normalized outputs ``measured[i]`` against its node plants' noise-free outputs (:func:`posterior_step`)."""
    channels, scales, variance, predicted = like.channels, like.scales, like.variance, nodes.measured
    base = i * like.per
    for j in range(rows.first[i] * k_nodes, rows.stop[i] * k_nodes):
        total = 0.0
        for c in range(channels.shape[0]):
            residual = measured[i, c] - predicted[base + j, channels[c]] / scales[c]
            total += residual * residual
        log_post[j] -= 0.5 * total / variance


@njit(cache=True, inline="always")
def _step_nodes(i, command, nodes, params, rows, per, k_nodes):
    """Sub-env ``i``'s node plants through one step of the normalized field command ``command`` (:func:`posterior_step`:
    the alive ones, and the width nodes' field and thermal model where they are dead)."""
    # a sub-env's node plants share their field path (same commands since their common restart): one H0 and H1 for
    # all of them, and model (6) moves its alive ones as one bank (advance_shared, the arithmetic of advance_each,
    # vectorized over the nodes)
    base = i * per
    field_from = nodes.field[base]  # current: node 0 is a width node
    field_to = limited_field(min(max(command, -1.0), 1.0) * params.field_limit, field_from, params)
    lo, hi = base + rows.first[i] * k_nodes, base + rows.stop[i] * k_nodes
    for j in range(lo, hi):
        nodes.field[j] = field_to
        nodes.magnetization_prev[j] = nodes.magnetization[j]
    advance_shared(nodes.magnetization[lo:hi], field_from, field_to, nodes.a_true[lo:hi], params.k[lo:hi],
                   params.alpha[lo:hi], params.Ms[lo:hi], params.c[lo:hi], params.kind, params.max_field_step)
    finish_transducers(lo, hi, nodes, params)
    # The thermal model reads nothing of the magnetic state, and the k nodes of a T0 node share their start (the
    # node's T0, the one drift rate) and their field path: their thermal state, step count and a(T) are equal at
    # every step (they live and die together, and a restart sets them alike). It is stepped at k node 0 and
    # copied to the others: the numbers finish_thermal would give each of them, at a k_nodes-th of the cost.
    for j in range(lo, hi, k_nodes):
        finish_thermal(j, field_from, field_to, nodes, params)
        for q in range(j + 1, j + k_nodes):
            nodes.temperature[q] = nodes.temperature[j]
            nodes.steps[q] = nodes.steps[j]
            nodes.a_true[q] = nodes.a_true[j]
            nodes.measured_temperature[q] = nodes.measured_temperature[j]
    for j in (base, base + k_nodes):  # the width nodes, where dead
        if j < lo or j >= hi:
            nodes.field[j] = field_to
            finish_thermal(j, field_from, field_to, nodes, params)


@njit(cache=True, inline="always")
def prune_rows(i, log_post, alive, prune):
    """Narrow the alive rows of sub-env ``i`` (``alive``, an :class:`AliveRows`; ``prune`` a :class:`PruneParams`)
    after its log-posterior ``log_post`` (per,) was updated: to the T0 rows of every node within ``prune.dead_gap``
    of its best node, widened by one row on each side (where a row is the first or last T0 node, by the two rows the
    parabola vertex reads beside it: the vertex of :func:`posterior_vertex` clips its centre to the interior), never
    beyond the old alive rows (a dead row's node plants were not simulated). The nodes of the rows that die get
    ``prune.dead_log_post``. Nothing changes where no node is within the gap (a NaN log-posterior)."""
    k_nodes = prune.k_nodes
    first, stop = alive.first[i], alive.stop[i]
    best = log_post[first * k_nodes]
    for j in range(first * k_nodes + 1, stop * k_nodes):
        if log_post[j] > best:
            best = log_post[j]
    floor = best - prune.dead_gap
    lowest, highest = stop, first - 1
    for t in range(first, stop):
        for q in range(k_nodes):
            if log_post[t * k_nodes + q] >= floor:
                lowest, highest = min(lowest, t), max(highest, t)
                break
    if highest < lowest:
        return
    new_first = max(first, min(max(lowest, 1), prune.nodes - 2) - 1)
    new_stop = min(stop, min(max(highest, 1), prune.nodes - 2) + 2)
    for j in range(first * k_nodes, new_first * k_nodes):
        log_post[j] = prune.dead_log_post
    for j in range(new_stop * k_nodes, stop * k_nodes):
        log_post[j] = prune.dead_log_post
    alive.first[i], alive.stop[i] = new_first, new_stop


@background_kernel(nogil=True)
def posterior_vertex(log_post, joint, weights, a_nodes, mean, concentrated, first, stop, estimate):
    """The grid posterior's estimate of a (:meth:`~hyst_gym.envs.posterior.GridPosterior.estimate`): per
    sub-env ``i`` where the largest of ``weights[i]`` exceeds ``concentrated``, the vertex of the parabola
    through the marginal ``log_post[i]`` (n, nodes) at its best node (clipped to the interior) and its
    neighbours (the offset within one cell; none where it has no maximum) -- with a k grid (``joint`` (n, nodes,
    k_nodes), k_nodes > 1), the vertex of the quadratic through the joint log-posterior's 3 x 3 neighbourhood of
    its best interior node where that has a maximum; the posterior mean ``mean[i]`` otherwise. ``a_nodes``
    (n, nodes): a at the nodes (A/m); ``first``, ``stop`` (n,): the alive T0 nodes (:class:`AliveRows`); writes
    ``estimate`` (n,). The arithmetic of the numpy form, element by
    element (the sums stay in numpy, whose pairwise order they keep)."""
    n, nodes = log_post.shape
    k_nodes = joint.shape[2]
    for i in range(n):
        best, top, heaviest = 0, log_post[i, 0], weights[i, 0]
        for j in range(1, nodes):
            if log_post[i, j] > top:
                best, top = j, log_post[i, j]
            heaviest = max(heaviest, weights[i, j])
        if not heaviest > concentrated:
            estimate[i] = mean[i]
            continue
        best = min(max(best, 1), nodes - 2)
        left, centre, right = log_post[i, best - 1], log_post[i, best], log_post[i, best + 1]
        curvature = left - 2 * centre + right
        offset = 0.5 * (left - right) / curvature if curvature < 0 else 0.0
        if k_nodes > 1:
            best, offset = _joint_vertex(joint[i], best, offset, first[i], stop[i])
        offset = min(max(offset, -1.0), 1.0)
        estimate[i] = a_nodes[i, best] + offset * (a_nodes[i, best + 1] - a_nodes[i, best])


#: numpy's pairwise summation: blocks of at most this many terms are summed with 8 accumulators
PAIRWISE_BLOCK = 128


@njit(cache=True)
def pairwise_sum(values, start, count):
    """``0.0 + sum(values[start:start + count])`` in the order of numpy's ``ndarray.sum`` along a contiguous last
    axis (its pairwise summation, numpy/_core/src/umath/loops_utils.h.src, after the identity 0.0): the same
    number bit for bit (``tests/envs/test_posterior_speed.py`` checks it against numpy). numpy's recursion (halves
    of a multiple of 8 terms until a block holds at most :data:`PAIRWISE_BLOCK`) is unrolled on a stack here:
    numba's cache does not load recursive functions reliably."""
    if count <= PAIRWISE_BLOCK:
        return 0.0 + _pairwise_block(values, start, count)
    # frames: start, count, stage (0: left half next, 1: right half next, 2: both done), the halves' sums
    frame_start = np.empty(64, dtype=np.int64)
    frame_count = np.empty(64, dtype=np.int64)
    frame_stage = np.empty(64, dtype=np.int64)
    left, right = np.empty(64), np.empty(64)
    frame_start[0], frame_count[0], frame_stage[0] = start, count, 0
    top, result = 1, 0.0
    while top > 0:
        f = top - 1
        size = frame_count[f]
        half = size // 2
        half -= half % 8
        if size <= PAIRWISE_BLOCK or frame_stage[f] == 2:
            value = _pairwise_block(values, frame_start[f], size) if size <= PAIRWISE_BLOCK else left[f] + right[f]
            top -= 1
            if top == 0:
                result = value
            elif frame_stage[top - 1] == 1:
                left[top - 1] = value
            else:
                right[top - 1] = value
        elif frame_stage[f] == 0:
            frame_stage[f] = 1
            frame_start[top], frame_count[top], frame_stage[top] = frame_start[f], half, 0
            top += 1
        else:
            frame_stage[f] = 2
            frame_start[top], frame_count[top], frame_stage[top] = frame_start[f] + half, size - half, 0
            top += 1
    return 0.0 + result


@njit(cache=True, inline="always")
def _pairwise_block(values, start, count):
    """numpy's pairwise sum of at most :data:`PAIRWISE_BLOCK` terms (one block, no identity)."""
    if count < 8:
        total = 0.0
        for i in range(start, start + count):
            total += values[i]
        return total
    r0, r1, r2, r3 = values[start], values[start + 1], values[start + 2], values[start + 3]
    r4, r5, r6, r7 = values[start + 4], values[start + 5], values[start + 6], values[start + 7]
    i = 8
    while i < count - count % 8:
        j = start + i
        r0 += values[j]
        r1 += values[j + 1]
        r2 += values[j + 2]
        r3 += values[j + 3]
        r4 += values[j + 4]
        r5 += values[j + 5]
        r6 += values[j + 6]
        r7 += values[j + 7]
        i += 8
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < count:
        total += values[start + i]
        i += 1
    return total


@njit(cache=True, inline="always")
def _maximum(current, value):
    """``np.maximum(current, value)`` of two floats: NaN if either is NaN, else the larger."""
    if current != current:
        return current
    if value != value or value > current:
        return value
    return current


@background_kernel(nogil=True)
def marginal_terms(joint, peak, threshold, first, stop, values, index):
    """The first half of the log-sum-exp over k of a grid posterior's joint log-posterior ``joint`` (n, nodes,
    k_nodes): ``peak`` (n, nodes) its maximum over k (``joint.max(axis=2)``), and of ``joint - peak`` the entries
    that are not ``<= threshold`` (NaN included) in order into ``values``, their flat positions into ``index``;
    returns how many. Their exp (numpy's) goes to :func:`marginal_sums`. Only the alive T0 nodes
    ``first[i]..stop[i]-1`` of sub-env ``i`` have terms; a dead one's peak is its dead nodes' log-posterior."""
    n, nodes, k_nodes = joint.shape
    count = 0
    for i in range(n):
        for t in range(nodes):
            top = joint[i, t, 0]
            if t < first[i] or t >= stop[i]:
                peak[i, t] = top
                continue
            for q in range(1, k_nodes):
                top = _maximum(top, joint[i, t, q])
            peak[i, t] = top
            for q in range(k_nodes):
                shifted = joint[i, t, q] - top
                if not shifted <= threshold:
                    values[count] = shifted
                    index[count] = (i * nodes + t) * k_nodes + q
                    count += 1
    return count


@background_kernel(nogil=True)
def marginal_sums(exps, index, first, stop, terms, sums):
    """The second half: ``sums`` (n, nodes) the sum over k of the exp of ``joint - peak`` in numpy's order, from
    ``exps`` at ``index`` (in the order :func:`marginal_terms` wrote them) and 0.0 at the other entries (where it
    underflows); 1.0 at a dead T0 node (outside ``first[i]..stop[i]-1``: its marginal is then its peak, the dead
    nodes' log-posterior). ``terms`` (k_nodes,): scratch, one T0 node's terms at a time (the terms are read in
    their order, so no array of all of them is filled and read again)."""
    n, nodes = sums.shape
    k_nodes = terms.shape[0]
    cursor = 0
    for i in range(n):
        for t in range(nodes):
            if t < first[i] or t >= stop[i]:
                sums[i, t] = 1.0
                continue
            base = (i * nodes + t) * k_nodes
            for q in range(k_nodes):
                if cursor < exps.shape[0] and index[cursor] == base + q:
                    terms[q] = exps[cursor]
                    cursor += 1
                else:
                    terms[q] = 0.0
            # pairwise_sum's first case, inlined (a call per T0 node cost as much as the sums)
            sums[i, t] = 0.0 + _pairwise_block(terms, 0, k_nodes) if k_nodes <= PAIRWISE_BLOCK else \
                pairwise_sum(terms, 0, k_nodes)


@background_kernel(nogil=True)
def weight_terms(log_post, threshold, values, index):
    """Of ``log_post - log_post.max(axis=1)`` ((n, nodes), the marginal log-posterior over the T0 nodes) the
    entries that are not ``<= threshold`` (NaN included), in order, into ``values`` and their flat positions into
    ``index``; returns how many. Their exp (numpy's) goes to :func:`posterior_moments`."""
    n, nodes = log_post.shape
    count = 0
    for i in range(n):
        top = log_post[i, 0]
        for t in range(1, nodes):
            top = _maximum(top, log_post[i, t])
        for t in range(nodes):
            shifted = log_post[i, t] - top
            if not shifted <= threshold:
                values[count] = shifted
                index[count] = i * nodes + t
                count += 1
    return count


@background_kernel(nogil=True)
def posterior_moments(exps, index, a_nodes, weights, scratch, mean, spread):
    """The posterior's weights over the T0 nodes ``weights`` (n, nodes): ``exps`` at ``index`` (0.0 elsewhere)
    over their sum; the posterior mean of a ``mean`` (n,) and its standard deviation with the node cell's
    ``spread`` (n,): ``sqrt(sum(w*(a - mean)**2) + spacing**2/12)``, spacing ``|a_1 - a_0|``. ``a_nodes`` (n, nodes):
    a at the T0 nodes (A/m); ``scratch`` (nodes,). The numbers of numpy's ``w = e/e.sum(axis=1)``,
    ``(w*a).sum(axis=1)`` and ``(w*(a - mean)**2).sum(axis=1)`` (:func:`pairwise_sum`)."""
    n, nodes = weights.shape
    flat = weights.reshape(n * nodes)
    for j in range(flat.shape[0]):
        flat[j] = 0.0
    for j in range(exps.shape[0]):
        flat[index[j]] = exps[j]
    for i in range(n):
        total = pairwise_sum(flat, i * nodes, nodes)
        for t in range(nodes):
            weights[i, t] = weights[i, t] / total
        for t in range(nodes):
            scratch[t] = weights[i, t] * a_nodes[i, t]
        centre = pairwise_sum(scratch, 0, nodes)
        mean[i] = centre
        for t in range(nodes):
            deviation = a_nodes[i, t] - centre
            scratch[t] = weights[i, t] * (deviation * deviation)
        spacing = abs(a_nodes[i, 1] - a_nodes[i, 0])
        spread[i] = math.sqrt(pairwise_sum(scratch, 0, nodes) + spacing * spacing / 12.0)


@njit(cache=True, inline="always")
def _joint_vertex(joint, best_marginal, offset_marginal, first, stop):
    """(T0 node, offset in T0 cells) of the vertex of the quadratic through ``joint`` (nodes, k_nodes) about its
    first largest entry (clipped to the interior); ``(best_marginal, offset_marginal)`` where it has no maximum.
    ``first``, ``stop``: the alive T0 nodes; the dead ones' entries all hold the dead log-posterior (prune_rows), so
    of them only the first in the order of the scan can be the first largest: entry (0, 0), where the scan starts
    anyway, or (stop, 0) after the alive ones. The scan reads those two and the alive entries: the entry of a scan
    of all of them (the numpy form's ``argmax``)."""
    nodes, k_nodes = joint.shape
    flat, top = 0, joint[0, 0]
    for t in range(first, stop):
        for q in range(k_nodes):
            if joint[t, q] > top:
                flat, top = t * k_nodes + q, joint[t, q]
    if stop < nodes and joint[stop, 0] > top:
        flat, top = stop * k_nodes, joint[stop, 0]
    i = min(max(flat // k_nodes, 1), nodes - 2)
    j = min(max(flat % k_nodes, 1), k_nodes - 2)
    centre = joint[i, j]
    g_t, g_k = 0.5 * (joint[i + 1, j] - joint[i - 1, j]), 0.5 * (joint[i, j + 1] - joint[i, j - 1])
    h_tt = joint[i + 1, j] - 2 * centre + joint[i - 1, j]
    h_kk = joint[i, j + 1] - 2 * centre + joint[i, j - 1]
    h_tk = 0.25 * (joint[i + 1, j + 1] - joint[i + 1, j - 1] - joint[i - 1, j + 1] + joint[i - 1, j - 1])
    det = h_tt * h_kk - h_tk * h_tk
    if h_tt < 0 and det > 0:
        return i, -(h_kk * g_t - h_tk * g_k) / det
    return best_marginal, offset_marginal


@background_kernel()
def identification_step(actions, active, plant, view, buffers, params, bank, bank_params):
    """One whole step of an env whose estimate is the agent's (Identification) in one call: actions ->
    :func:`plant_step` -> the model bank at the new field (:func:`~hyst_gym.estimation._kernels.advance_bank`,
    for the PE integrand) -> :func:`finish_step`. Arguments as :func:`excitation_step`, then the bank's
    BankState and BankParams; all plain tuples. Returns 0, or 1 (an action is not finite or outside [-1, 1];
    nothing changed)."""
    named = EnvParams(*params)
    named_buffers = StepBuffers(*buffers)
    if not field_commands(actions, named, named_buffers):
        return 1
    plant_step(named_buffers.command, active, plant, named.plant)
    advance_bank(bank, PlantState(*plant).field, bank_params)
    finish_step(plant, view, buffers, named.score, named.layout, bank, bank_params)
    return 0


__all__ = ["AliveRows", "EnvParams", "EstimateView", "LikelihoodParams", "ObservationLayout", "PlantParams",
           "PlantState", "PruneParams", "ScoreParams", "StepBuffers", "clip_actions", "excitation_step", "fill_info",
           "fill_observation", "finish_plants", "finish_step", "finish_thermal", "finish_transducers",
           "identification_commands", "identification_plants", "identification_step", "limit_fields", "limited_field",
           "marginal_sums", "marginal_terms", "pairwise_sum", "plant_step", "posterior_moments", "posterior_step",
           "posterior_vertex", "prune_rows", "score_step", "weight_terms"]


#: printed once per process, on stderr, before the first environment compiles its kernels (HYST_GYM_COMPILE=foreground)
COMPILE_NOTICE = ("hyst-gym: compiling the simulation kernels (first use only, 10-30 s on 2 cores; "
                  "cached afterwards)")
#: the same news where they compile in a background process (the default; see physics/background_compile.py)
BACKGROUND_NOTICE = ("hyst-gym: compiling the simulation kernels in a background process (first use only, 10-30 s "
                     "on 2 cores; cached afterwards); until then the environments step in plain Python: the same "
                     "numbers, roughly 100x slower per step")
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
    """Print :data:`COMPILE_NOTICE` (:data:`BACKGROUND_NOTICE` in the background mode) to stderr,
    once per process, if any of ``kernels`` is not in numba's cache (so its first call compiles
    it). A print, not a warning: it is news, not a problem, and must show even where warnings
    are filtered. Nothing in the ``python`` mode, which compiles nothing."""
    global _compile_notice_shown
    mode = effective_mode()
    if _compile_notice_shown or mode == PYTHON or all(is_cached(kernel) for kernel in kernels):
        return
    _compile_notice_shown = True
    print(BACKGROUND_NOTICE if mode == BACKGROUND else COMPILE_NOTICE, file=sys.stderr, flush=True)
