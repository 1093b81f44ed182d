"""Compiled forward kernels of the extended model the mismatch tool fits.

The magnetic part is the domain-wall model (6) (slope from
:func:`hyst_gym.physics.hysteresis.magnetization_slope`), driven in time with three
optional extensions, each of which reduces exactly to the plain model when its
parameter is zero:

* ``field_bias``: the material sees ``H + H0`` (A/m);
* ``eddy_current``: the material sees ``H_eff = H + H0 - k_e*dM/dt`` (k_e in s). Per
  sample the effective-field increment solves the linearized implicit relation
  ``dHe = (H_new + H0 - He_old)/(1 + k_e*chi/dt)`` with ``chi`` the secant
  susceptibility (one predictor with the tangent, one corrector with the secant), which is
  unconditionally stable (the denominator is >= 1 because chi >= 0);
* ``small_loop``: the reversible low-field susceptibility chi_r of the physics layer's
  small-loop extension (:data:`hyst_gym.physics.hysteresis.SMALL_LOOP_EXTENSION`);
* ``anhysteretic_shape``'s knee: the Ising curve (2) becomes the knee family of the physics layer,
  ``tanh(|x|^p)^(1/p)`` (:func:`hyst_gym.physics.anhysteretic.knee_unit`), with its exponent p per member
  (:data:`CURVE_COLUMNS`; p = 1 is the Ising curve itself);
* ``thermal_drift``: a lumped coil temperature rise ``theta`` (K) obeys
  ``theta' = q*H^2 - theta/tau`` (Joule heating ~ I^2 ~ H^2, eq. (11)), integrated
  exactly with H^2 held at its step mean, and ``a(T) = a*(T_amb + theta)/T_amb`` (4)
  (a proportional to absolute temperature); optionally ``Ms(T) = Ms*(1 - beta*theta)``,
  ``k(T) = k*(1 - beta_k*theta)`` and ``c(T) = c*(1 - beta_c*theta)`` (:data:`PINNING_DRIFT_COLUMNS`);
  optionally a second thermal stage (:data:`THERMAL_LAG_COLUMNS`): the rod lags the coil,
  ``tau2*theta2' = theta - theta2``, and sees ``share*theta + (1 - share)*theta2``.

Every model starts demagnetized (M = 0) at H = 0 and is first brought quasi-statically to
the first recorded field, so that the first sample is on the virgin curve.

Mechanical and sensor parts are linear time-invariant systems, integrated exactly for a
forcing that is linear between samples (first-order hold), see :func:`lti_response`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numba.core import types
from numba.extending import overload

from ..physics.anhysteretic import KneeCurve
from ..physics.constants import ROOM_TEMPERATURE
from ..physics.hysteresis import (ISING, LaneConstants, _midpoint, _small_loop_slope, advance_one, lane_constants,
                                  magnetization_slope, monotone_substeps, simulate_shared, simulate_shared_small_loop)
from ..physics.linear_system import first_order_hold, lti_step
from ..physics.thermal import a_law_kernel, mean_square_linear_kernel

# Every kernel here releases the GIL (nogil=True): the tool fits its candidates in threads
# (core.diagnose, ``workers``), and nearly all of a fit's time is spent in these simulations.

#: Columns of the per-member magnetic parameter matrix used by :func:`simulate_members`.
MAGNETIC_COLUMNS = ("a", "k", "alpha", "Ms", "c", "H0", "k_e", "heating", "tau_th", "beta_Ms", "chi_r",
                    "heating_exponent")
#: Optional trailing columns after :data:`MAGNETIC_COLUMNS`: the time variation of the pinning k and of the
#: reversibility c with the heating's temperature rise theta (K), ``k(T) = k*(1 - beta_k*theta)`` and
#: ``c(T) = c*(1 - beta_c*theta)`` (1/K each). A row without them (12 columns) has both zero: the plain heating
#: law, so rows written before them keep their numbers.
PINNING_DRIFT_COLUMNS = ("beta_k", "beta_c")
#: Optional trailing column after :data:`PINNING_DRIFT_COLUMNS`: the knee exponent p of the Ising curve
#: (dimensionless; 1, or no such column: the Ising curve itself, and the only value a Langevin row may have).
#: Rows with another p run in :func:`simulate_lanes` only, which steps each lane with its own curve.
CURVE_COLUMNS = ("knee_exponent",)
KNEE_COLUMN = len(MAGNETIC_COLUMNS) + len(PINNING_DRIFT_COLUMNS)
#: Optional trailing columns after :data:`CURVE_COLUMNS`: the heating network's second stage. The rod's temperature
#: lags the coil's (the heated stage, ``theta``) with the time constant ``tau_th2`` (s), ``tau_th2*theta2' = theta -
#: theta2``, and the material sees ``thermal_share*theta + (1 - thermal_share)*theta2``: a series network (coil, then
#: rod) at share 0, two parallel paths (a fast and a slow one) at a share between. ``tau_th2 = 0``, or no such
#: columns, is the one-stage law (the rod at the coil's temperature), so rows written before them keep their numbers.
#: Why: a coil that heats a rod through its former and its mount warms it with two time constants; the one-stage law
#: starts the rise at full slope where the rod's starts flat (experiments/other_forms.py's heating networks).
THERMAL_LAG_COLUMNS = ("tau_th2", "thermal_share")
THERMAL_LAG_COLUMN = KNEE_COLUMN + len(CURVE_COLUMNS)
AMBIENT_TEMPERATURE = ROOM_TEMPERATURE  # K, reference temperature of the fitted a (eq. 4)
#: The Delta-E family's relative stiffness change is clipped at this (a stiffness that stays positive) before the
#: lumped step integrates it (:func:`varying_stiffness_response`); the report plots the same clipped law.
MIN_RELATIVE_STIFFNESS = -0.95


def knee_exponents(params) -> np.ndarray:
    """The knee exponent of each row of ``params`` (rows as :func:`simulate_lanes` takes them; 1 without the
    column)."""
    params = np.asarray(params)
    return params[:, KNEE_COLUMN] if params.shape[1] > KNEE_COLUMN else np.ones(params.shape[0])


def _lane_curve(curve, i):
    """The curve argument of the physics kernels for lane ``i``: the code ``curve`` itself, or the
    :data:`~hyst_gym.physics.anhysteretic.KneeCurve` of the lane's exponent where ``curve`` holds one per lane."""
    return curve if isinstance(curve, int) else KneeCurve(curve[i])


@overload(_lane_curve, jit_options={"forceinline": True})
def _lane_curve_compiled(curve, i):
    # resolved when compiled: the lanes' loop for a code holds no trace of the knee family
    if isinstance(curve, types.Integer):
        return lambda curve, i: curve
    return lambda curve, i: KneeCurve(curve[i])


@njit(cache=True, nogil=True)
def _advance(m, field_from, field_to, a, k, alpha, Ms, c, kind, max_field_step):
    # One member, scalar: the physics layer's substeps and midpoint rule of (6), so a member
    # gives the bank kernel's numbers.
    m, _ = advance_one(m, field_from, field_to, a, k, alpha, Ms, c, kind, max_field_step)
    return m


@njit(cache=True, nogil=True)
def simulate_members(time, field, params, kind, max_field_step, ambient):
    """Magnetization (A/m), shape ``(T, B)``, of ``B`` extended models under one field.

    ``params`` has shape ``(B, len(MAGNETIC_COLUMNS))`` with the columns of :data:`MAGNETIC_COLUMNS`.
    Members without eddy currents or heating that see the same bias H0 share one field:
    they run together through the physics bank kernel (members in the inner, vectorized
    loop), which is several times faster than one member after the other. The others
    (and the arithmetic of both paths) follow the same midpoint rule of (6).
    """
    n_samples = time.shape[0]
    n_members = params.shape[0]
    if params.shape[1] > KNEE_COLUMN:
        for b in range(n_members):
            if params[b, KNEE_COLUMN] != 1.0:
                raise ValueError("a knee exponent other than 1 runs in simulate_lanes, not simulate_members")
    out = np.empty((n_samples, n_members))
    done = np.zeros(n_members, dtype=np.bool_)
    for b in range(n_members):
        if done[b] or params[b, 6] != 0.0 or params[b, 7] != 0.0:
            continue
        members = np.zeros(n_members, dtype=np.bool_)
        for j in range(b, n_members):
            # same bias H0, and the small-loop extension (chi_r, column 10) on in all or in none
            members[j] = ((not done[j]) and params[j, 6] == 0.0 and params[j, 7] == 0.0 and params[j, 5] == params[b, 5]
                          and (params[j, 10] == 0.0) == (params[b, 10] == 0.0))
        group = np.flatnonzero(members)
        _simulate_shared_field(field + params[b, 5], params[group], kind, max_field_step, out, group)
        done[group] = True
    for b in range(n_members):
        if not done[b]:
            _simulate_one(time, field, params[b], kind, max_field_step, ambient, out, b)
    return out


@njit(cache=True, nogil=True)
def heating_reference(field):
    """The heating drive's reference field (A/m) for ``field``: its RMS (:func:`_simulate_one`'s ``h_ref``)."""
    return math.sqrt(np.mean(field * field)) + 1e-300


class LanePlan(NamedTuple):
    """Per lane of :func:`simulate_lanes`, the advance under way: its start field (A/m), substep (A/m),
    direction (+1 or -1), number of substeps, and the lane's constants (``(8, lanes)``, :func:`lane_constants`)."""

    start: np.ndarray
    step: np.ndarray
    delta: np.ndarray
    count: np.ndarray
    constants: np.ndarray


class LaneMaterial(NamedTuple):
    """Per lane of :func:`simulate_lanes`, the material's present a (A/m), k (A/m), Ms (A/m) and c (1), which
    heating moves."""

    a: np.ndarray
    k: np.ndarray
    Ms: np.ndarray
    c: np.ndarray


class LaneHeat(NamedTuple):
    """Per lane of :func:`simulate_lanes`, the heating network's state: the coil's temperature rise and the lagged
    stage's (K; :data:`THERMAL_LAG_COLUMNS`)."""

    coil: np.ndarray
    lagged: np.ndarray


def lane_passes(count: int) -> int:
    """Compiled passes over the record of :func:`simulate_lanes` for ``count`` lanes: one per
    :data:`BANK_LANES` of them (a pass costs about the same for one lane as for a full bank)."""
    return max(1, (int(count) + BANK_LANES - 1) // BANK_LANES)


@njit(cache=True, nogil=True)
def simulate_lanes(time, fields, field_index, params, h_ref, kind, max_field_step, ambient):
    """Magnetization (A/m), shape ``(T, B)``, of ``B`` extended models, each under its own field, in one
    pass: lane ``b`` sees ``fields[field_index[b]] + H0`` (``fields`` shape ``(F, T)``; ``h_ref[f]`` the RMS
    of field ``f``, the heating drive's reference). ``params`` as :func:`simulate_members`, and a row may carry
    a knee exponent (:data:`CURVE_COLUMNS`; ``kind`` ISING then).

    Why: a bank of members that share one field (:func:`simulate_members`) costs one pass, but a member with
    its own field (another input map or bias), eddy currents or heating cost a pass each. Here every lane
    computes its own substeps, with the arithmetic of :func:`_simulate_one` (and so of the bank: each lane
    gives the same numbers as alone), and the substeps run outer, the lanes inner, so that the lanes'
    independent chains overlap in the processor as the bank's do."""
    n_samples = time.shape[0]
    n_members = params.shape[0]
    width = n_members if n_members == 1 else ((n_members + BANK_LANES - 1) // BANK_LANES) * BANK_LANES
    out = np.empty((n_samples, n_members))
    row_of = np.empty(width, dtype=np.int64)
    for i in range(width):
        row_of[i] = min(i, n_members - 1)
    m = np.zeros(width)
    he = np.zeros(width)
    heat = LaneHeat(np.zeros(width), np.zeros(width))
    a = np.empty(width)
    k = np.empty(width)
    Ms = np.empty(width)
    c = np.empty(width)
    # per lane, the advance under way: start field, substep, direction, count, and the lane's constants
    start = np.zeros(width)
    step = np.zeros(width)
    delta = np.zeros(width)
    count = np.zeros(width, dtype=np.int64)
    constants = np.zeros((8, width))
    plan = LanePlan(start, step, delta, count, constants)
    material = LaneMaterial(a, k, Ms, c)
    gap = np.zeros(width)
    d_he = np.zeros(width)
    m_old = np.zeros(width)
    chi_r = np.empty(width)
    small_loop = False
    knee, kneed = _lane_knees(params, row_of)
    for i in range(width):
        chi_r[i] = params[row_of[i], 10]
        small_loop = small_loop or chi_r[i] != 0.0
        row = params[row_of[i]]
        if row[10] != 0.0 and (row[6] != 0.0 or row[7] != 0.0):
            # extensions are nested one at a time: small loops never meet eddy currents or heating here
            raise ValueError("the small-loop extension (chi_r) does not combine with eddy currents or heating")
        a[i], k[i], Ms[i], c[i] = row[0], row[1], row[3], row[4]
        start[i] = 0.0
        target = fields[field_index[row_of[i]], 0] + row[5]
        _plan(i, 0.0, target, material, row[2], max_field_step, plan)
        he[i] = target
    if kneed and kind != ISING:
        raise ValueError("the knee family generalizes the Ising curve: kind must be ISING")
    _substeps(m, start, step, delta, count, constants, chi_r, small_loop, kind, knee, kneed)
    for i in range(n_members):
        out[0, i] = m[i]
    for t in range(1, n_samples):
        dt = time[t] - time[t - 1]
        eddy = False
        for i in range(width):
            row = params[row_of[i]]
            f = field_index[row_of[i]]
            heating, k_e = row[7], row[6]
            if heating != 0.0:
                _heat(i, row, fields[f, t - 1], fields[f, t], h_ref[f], dt, ambient, heat, a, k, Ms, c)
            target = fields[f, t] + row[5]
            m_old[i] = m[i]
            if k_e > 0.0:
                eddy = True
                gap[i] = target - he[i]
                direction = 1.0 if gap[i] > 0.0 else -1.0
                chi = _lane_slope(he[i], m[i], direction, a[i], k[i], row[2], Ms[i], c[i], kind, knee[i], kneed)
                d_he[i] = gap[i] / (1.0 + k_e * chi / dt)
                target = he[i] + d_he[i]
            _plan(i, he[i], target, material, row[2], max_field_step, plan)
        _substeps(m, start, step, delta, count, constants, chi_r, small_loop, kind, knee, kneed)
        if eddy:
            _correct(m, m_old, he, gap, d_he, dt, material, params, row_of, max_field_step, plan)
            _substeps(m, start, step, delta, count, constants, chi_r, small_loop, kind, knee, kneed)
        for i in range(width):
            row = params[row_of[i]]
            if row[6] > 0.0:
                he[i] = he[i] + d_he[i]
            else:
                he[i] = fields[field_index[row_of[i]], t] + row[5]
        for i in range(n_members):
            out[t, i] = m[i]
    return out


@njit(cache=True, nogil=True, inline="always")
def _lane_knees(params, row_of):
    """Per lane, its knee exponent (:data:`CURVE_COLUMNS`, 1 without the column), and whether any is not 1."""
    knee = np.ones(row_of.shape[0])
    if params.shape[1] > KNEE_COLUMN:
        for i in range(row_of.shape[0]):
            knee[i] = params[row_of[i], KNEE_COLUMN]
    return knee, bool(np.any(knee != 1.0))


@njit(cache=True, nogil=True, inline="always")
def _lane_slope(field, magnetization, direction, a, k, alpha, Ms, c, kind, knee, kneed):
    """dM/dH of (6) for one lane, on the curve ``kind`` or, where ``kneed``, the knee family of exponent ``knee``."""
    if kneed:
        return magnetization_slope(field, magnetization, direction, a, k, alpha, Ms, c, KneeCurve(knee))
    return magnetization_slope(field, magnetization, direction, a, k, alpha, Ms, c, kind)


@njit(cache=True, nogil=True, inline="always")
def _correct(m, m_old, he, gap, d_he, dt, material, params, row_of, max_field_step, plan):
    """The eddy-current lanes' corrector (_simulate_one's): the secant susceptibility of the predictor's step,
    and that lane's step planned again from its start (the other lanes take no substep)."""
    for i in range(m.shape[0]):
        row = params[row_of[i]]
        plan.count[i] = 0
        if row[6] > 0.0 and d_he[i] != 0.0:
            chi = (m[i] - m_old[i]) / d_he[i]
            if chi < 0.0:
                chi = 0.0
            d_he[i] = gap[i] / (1.0 + row[6] * chi / dt)
            m[i] = m_old[i]
            _plan(i, he[i], he[i] + d_he[i], material, row[2], max_field_step, plan)


@njit(cache=True, nogil=True, inline="always")
def _plan(i, field_from, field_to, material, alpha, max_field_step, plan):
    """Lane ``i``'s advance from ``field_from`` to ``field_to``: its substeps (advance_one's) and constants."""
    n, length, direction = monotone_substeps(field_to - field_from, max_field_step)
    plan.start[i] = field_from
    plan.step[i] = length
    plan.delta[i] = direction
    plan.count[i] = n
    constants = plan.constants
    lane = lane_constants(material.a[i], material.k[i], alpha, material.Ms[i], material.c[i], direction)
    constants[0, i] = lane.alpha
    constants[1, i] = lane.inv_a
    constants[2, i] = lane.Ms
    constants[3, i] = lane.ms_over_a
    constants[4, i] = lane.k_delta
    constants[5, i] = lane.alphahat
    constants[6, i] = lane.c
    constants[7, i] = lane.alpha_c


@njit(cache=True, nogil=True, inline="always")
def thermal_lag(row) -> tuple:
    """(tau_th2 (s), thermal_share) of a magnetic row (:data:`THERMAL_LAG_COLUMNS`; (0, 1), the one-stage law,
    without the columns)."""
    if row.shape[0] > THERMAL_LAG_COLUMN + 1:
        return row[THERMAL_LAG_COLUMN], row[THERMAL_LAG_COLUMN + 1]
    return 0.0, 1.0


@njit(cache=True, nogil=True, inline="always")
def thermal_stages_step(coil, lagged, heating, h_sq, tau, tau2, dt) -> tuple:
    """One sample interval of the heating network: (coil rise, lagged rise), both K. The coil's stage
    ``theta' = heating*H^2 - theta/tau`` exactly with H^2 held at its step mean ``h_sq``; the second stage
    ``tau2*theta2' = theta - theta2`` exactly for a coil rise linear over the interval (first-order hold), and
    equal to the coil's where ``tau2`` is 0."""
    decay = math.exp(-dt / tau)
    new_coil = coil * decay + heating * h_sq * tau * (1.0 - decay)
    if tau2 <= 0.0:
        return new_coil, new_coil
    return new_coil, _lag_step(coil, new_coil, lagged, tau2, dt)


@njit(cache=True, nogil=True, inline="always")
def _lag_step(coil_from, coil_to, lagged, tau2, dt) -> float:
    """The second stage ``tau2*theta2' = theta - theta2`` over one interval, exact for a coil rise linear from
    ``coil_from`` to ``coil_to``: theta2(dt) = coil_to + (theta2(0) - coil_from)*e - slope*tau2*(1 - e)."""
    decay2 = math.exp(-dt / tau2)
    slope = (coil_to - coil_from) / dt
    return coil_to + (lagged - coil_from) * decay2 - slope * tau2 * (1.0 - decay2)


@njit(cache=True, nogil=True)
def lagged_rise_trace(time, coil, tau2) -> np.ndarray:
    """K per sample: the second stage's rise under the coil's rise ``coil`` (K per sample, linear between
    samples), from 0 (:func:`_lag_step`; the coil's own trace where ``tau2`` is 0)."""
    if tau2 <= 0.0:
        return coil.copy()
    out = np.zeros(coil.shape[0])
    for t in range(1, coil.shape[0]):
        out[t] = _lag_step(coil[t - 1], coil[t], out[t - 1], tau2, time[t] - time[t - 1])
    return out


@njit(cache=True, nogil=True, inline="always")
def material_temperature_rise(coil, lagged, tau2, share) -> float:
    """K: the rise the material sees, ``share*coil + (1 - share)*lagged`` (the coil's where ``tau2`` is 0)."""
    if tau2 <= 0.0:
        return coil
    return share * coil + (1.0 - share) * lagged


@njit(cache=True, nogil=True, inline="always")
def _heat(i, row, field_from, field_to, h_ref, dt, ambient, heat, a, k, Ms, c):
    """Lane ``i``'s temperature rise over one sample and its material parameters there (_simulate_one's)."""
    tau, beta, exponent = row[8], row[9], row[11]
    beta_k = row[12] if row.shape[0] > 12 else 0.0
    beta_c = row[13] if row.shape[0] > 13 else 0.0
    tau2, share = thermal_lag(row)
    if exponent == 2.0:
        h_sq = mean_square_linear_kernel(field_from, field_to)
    else:  # trapezoid over the sample interval
        h_sq = h_ref * h_ref * 0.5 * ((abs(field_from) / h_ref) ** exponent + (abs(field_to) / h_ref) ** exponent)
    heat.coil[i], heat.lagged[i] = thermal_stages_step(heat.coil[i], heat.lagged[i], row[7], h_sq, tau, tau2, dt)
    theta = material_temperature_rise(heat.coil[i], heat.lagged[i], tau2, share)
    a[i] = a_law_kernel(row[0], ambient + theta, ambient)
    Ms[i] = row[3] * (1.0 - beta * theta)
    if Ms[i] < 1e-3 * row[3]:
        Ms[i] = 1e-3 * row[3]
    if beta_k != 0.0:
        k[i] = max(row[1] * (1.0 - beta_k * theta), 1e-3 * row[1])
    if beta_c != 0.0:
        c[i] = min(max(row[4] * (1.0 - beta_c * theta), 0.0), 0.999)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _substeps(m, start, step, delta, count, constants, chi_r, small_loop, kind, knee, kneed):
    """The planned substeps of every lane: substeps outer, lanes inner (a lane with fewer keeps its M).
    ``kneed``: the lanes step the knee family with their exponents ``knee`` (in place of ``kind``)."""
    most = 0
    for i in range(m.shape[0]):
        most = max(most, count[i])
    # one copy of the loop per curve and slope, as in the physics layer's bank: behind the tests the compiler
    # knows both and keeps the lanes' loop free of branches
    if kneed:
        if small_loop:
            _small_loop_substeps(m, start, step, delta, count, constants, chi_r, knee, most)
        else:
            _masked_substeps(m, start, step, delta, count, constants, knee, most)
    elif small_loop:
        if kind == ISING:
            _small_loop_substeps(m, start, step, delta, count, constants, chi_r, kind, most)
        else:
            _small_loop_substeps(m, start, step, delta, count, constants, chi_r, kind, most)
    elif kind == ISING:
        _masked_substeps(m, start, step, delta, count, constants, kind, most)
    else:
        _masked_substeps(m, start, step, delta, count, constants, kind, most)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _masked_substeps(m, start, step, delta, count, constants, kind, most):
    """Every lane's substeps of (6); ``kind`` a curve's code, or the knee exponents of the lanes."""
    alpha, inv_a, Ms, ms_over_a = constants[0], constants[1], constants[2], constants[3]
    k_delta, alphahat, c, alpha_c = constants[4], constants[5], constants[6], constants[7]
    for s in range(most):
        for i in range(m.shape[0]):
            lane = LaneConstants(alpha[i], inv_a[i], Ms[i], ms_over_a[i], k_delta[i], alphahat[i], c[i], alpha_c[i])
            new = _midpoint(start[i] + s * step[i], m[i], step[i], delta[i], lane, _lane_curve(kind, i))
            m[i] = new if s < count[i] else m[i]


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _small_loop_substeps(m, start, step, delta, count, constants, chi_r, kind, most):
    """:func:`_masked_substeps` with the small-loop slope (the physics layer's, chi_r per lane)."""
    alpha, inv_a, Ms, ms_over_a = constants[0], constants[1], constants[2], constants[3]
    k_delta, alphahat, c, alpha_c = constants[4], constants[5], constants[6], constants[7]
    for s in range(most):
        for i in range(m.shape[0]):
            lane = LaneConstants(alpha[i], inv_a[i], Ms[i], ms_over_a[i], k_delta[i], alphahat[i], c[i], alpha_c[i])
            field = start[i] + s * step[i]
            curve = _lane_curve(kind, i)
            slope_start = _small_loop_slope(field, m[i], delta[i], lane, chi_r[i], curve)
            slope_mid = _small_loop_slope(field + 0.5 * step[i], m[i] + (0.5 * step[i]) * slope_start, delta[i], lane,
                                          chi_r[i], curve)
            new = m[i] + step[i] * slope_mid
            m[i] = new if s < count[i] else m[i]


def member_passes(params) -> int:
    """Compiled passes over the record that :func:`simulate_members` makes for ``params`` (rows as there):
    one per bank of up to :data:`BANK_LANES` members sharing a field (same bias H0, small-loop extension on
    or off in all), one per member with eddy currents or heating. A pass costs about the same for one
    member as for a full bank, so this is the simulation's cost."""
    params = np.asarray(params)
    extended = (params[:, 6] != 0.0) | (params[:, 7] != 0.0)
    passes = int(np.count_nonzero(extended))
    plain = params[~extended]
    if plain.shape[0]:
        keys = np.column_stack([plain[:, 5], plain[:, 10] == 0.0])
        _, counts = np.unique(keys, axis=0, return_counts=True)
        passes += int(np.sum((counts + BANK_LANES - 1) // BANK_LANES))
    return passes


#: The bank's members are padded to a multiple of this many lanes (copies of the last member,
#: discarded). Why: the bank's model loop is vectorized in blocks of SIMD lanes and the members
#: left over run in a scalar remainder loop several times slower per member: on a 2-core x86
#: machine, 20,000 samples of 16 substeps took 143 ms for 7 members and 39 ms for 8
#: (experiments/diagnose_speed.py times the tool). A Jacobian call has 2-12 members.
BANK_LANES = 8


@njit(cache=True, nogil=True)
def _simulate_shared_field(field, params, kind, max_field_step, out, columns):
    # every member starts demagnetized at H = 0 and is brought to the first sample: the physics
    # layer's bank trajectory over the field with H = 0 put in front
    n_members = params.shape[0]
    width = n_members if n_members == 1 else ((n_members + BANK_LANES - 1) // BANK_LANES) * BANK_LANES
    padded = np.empty((width, params.shape[1]))
    for i in range(width):
        padded[i] = params[min(i, n_members - 1)]
    a = np.ascontiguousarray(padded[:, 0])
    k = np.ascontiguousarray(padded[:, 1])
    alpha = np.ascontiguousarray(padded[:, 2])
    Ms = np.ascontiguousarray(padded[:, 3])
    c = np.ascontiguousarray(padded[:, 4])
    chi_r = np.ascontiguousarray(padded[:, 10])
    from_zero = np.empty(field.shape[0] + 1)
    from_zero[0] = 0.0
    from_zero[1:] = field
    start = np.zeros(width)
    if chi_r[0] != 0.0:  # the group is all-on or all-off (simulate_members)
        trajectory = simulate_shared_small_loop(from_zero, start, a, k, alpha, Ms, c, chi_r, kind, max_field_step)
    else:
        trajectory = simulate_shared(from_zero, start, a, k, alpha, Ms, c, kind, max_field_step)
    for t in range(field.shape[0]):
        for i in range(columns.shape[0]):
            out[t, columns[i]] = trajectory[t + 1, i]


@njit(cache=True, nogil=True)
def _simulate_one(time, field, row, kind, max_field_step, ambient, out, b):
    """One extended member (eddy currents or heating), sample after sample, into ``out[:, b]``."""
    if row[10] != 0.0:
        # extensions are nested one at a time: small loops never meet eddy currents or heating here
        raise ValueError("the small-loop extension (chi_r) does not combine with eddy currents or heating")
    n_samples = time.shape[0]
    a0 = row[0]
    k = row[1]
    alpha = row[2]
    Ms0 = row[3]
    c = row[4]
    H0 = row[5]
    k_e = row[6]
    heating = row[7]
    tau = row[8]
    beta = row[9]
    exponent = row[11]
    beta_k = row[12] if row.shape[0] > 12 else 0.0
    beta_c = row[13] if row.shape[0] > 13 else 0.0
    tau2, share = thermal_lag(row)
    k0 = k
    c0 = c
    # the heating drive heating*|H|^p is written heating*h_ref^2*(|H|/h_ref)^p with h_ref the record's RMS
    # field, so that ``heating`` keeps its unit (K/s per (A/m)^2) and its size whatever p is
    h_ref = math.sqrt(np.mean(field * field)) + 1e-300
    m = _advance(0.0, 0.0, field[0] + H0, a0, k, alpha, Ms0, c, kind, max_field_step)
    he = field[0] + H0
    coil = 0.0
    lagged = 0.0
    out[0, b] = m
    a = a0
    Ms = Ms0
    for t in range(1, n_samples):
        dt = time[t] - time[t - 1]
        if heating != 0.0:
            if exponent == 2.0:
                h_sq = mean_square_linear_kernel(field[t - 1], field[t])
            else:  # trapezoid over the sample interval
                h_sq = h_ref * h_ref * 0.5 * ((abs(field[t - 1]) / h_ref) ** exponent
                                              + (abs(field[t]) / h_ref) ** exponent)
            coil, lagged = thermal_stages_step(coil, lagged, heating, h_sq, tau, tau2, dt)
            theta = material_temperature_rise(coil, lagged, tau2, share)
            a = a_law_kernel(a0, ambient + theta, ambient)  # (4), a0 at the ambient temperature
            Ms = Ms0 * (1.0 - beta * theta)
            if Ms < 1e-3 * Ms0:
                Ms = 1e-3 * Ms0
            if beta_k != 0.0:
                # pinning that collapses toward a Curie point: floored like Ms (a k of zero has no loop)
                k = max(k0 * (1.0 - beta_k * theta), 1e-3 * k0)
            if beta_c != 0.0:
                c = min(max(c0 * (1.0 - beta_c * theta), 0.0), 0.999)
        target = field[t] + H0
        if k_e > 0.0:
            gap = target - he
            delta = 1.0 if gap > 0.0 else -1.0
            chi = magnetization_slope(he, m, delta, a, k, alpha, Ms, c, kind)
            d_he = gap / (1.0 + k_e * chi / dt)
            m_new = _advance(m, he, he + d_he, a, k, alpha, Ms, c, kind, max_field_step)
            if d_he != 0.0:
                chi = (m_new - m) / d_he
                if chi < 0.0:
                    chi = 0.0
                d_he = gap / (1.0 + k_e * chi / dt)
                m_new = _advance(m, he, he + d_he, a, k, alpha, Ms, c, kind, max_field_step)
            m = m_new
            he = he + d_he
        else:
            m = _advance(m, he, target, a, k, alpha, Ms, c, kind, max_field_step)
            he = target
        out[t, b] = m


@njit(cache=True, nogil=True)
def _step_lti(forcing, classes, phis, gamma0s, gamma1s, C, x0):
    n = forcing.shape[0]
    order = x0.shape[0]
    out = np.empty(n)
    x = x0.copy()
    new = np.empty(order)
    out[0] = 0.0
    for i in range(order):
        out[0] += C[i] * x[i]
    for t in range(1, n):
        j = classes[t - 1]
        lti_step(phis[j], gamma0s[j], gamma1s[j], x, forcing[t - 1], forcing[t], new)
        x, new = new, x
        y = 0.0
        for i in range(order):
            y += C[i] * x[i]
        out[t] = y
    return out


def step_classes(time):
    """Group the sample steps into classes of equal length (relative 1e-9); returns
    ``(steps, class_index)``: the distinct step lengths (s) and, per step, its class."""
    dt = np.diff(np.asarray(time, dtype=np.float64))
    scale = float(np.median(dt))
    keys = np.round(dt / scale, 9)
    unique, classes = np.unique(keys, return_inverse=True)
    return unique * scale, classes.astype(np.int64)


def lti_response(time, forcing, A, B, C, *, start="rest", classes=None):
    """Output ``C x`` of ``x' = A x + B u`` for a forcing ``u`` linear between samples.

    Exact (first-order hold) discretization per distinct step length, via the matrix
    exponential of the augmented generator. ``start="rest"`` starts at x = 0;
    ``start="steady"`` starts at the static equilibrium for ``u[0]`` (A must be invertible).
    ``classes`` may pass a precomputed :func:`step_classes` result.
    """
    A = np.atleast_2d(np.asarray(A, dtype=np.float64))
    B = np.asarray(B, dtype=np.float64).reshape(-1)
    C = np.asarray(C, dtype=np.float64).reshape(-1)
    steps, index = step_classes(time) if classes is None else classes
    phis, gamma0s, gamma1s = _first_order_hold(A, B, steps)
    forcing = np.ascontiguousarray(forcing, dtype=np.float64)
    if start == "steady":
        x0 = -np.linalg.solve(A, B * forcing[0])
    else:
        x0 = np.zeros(A.shape[0])
    return _step_lti(forcing, index, phis, gamma0s, gamma1s, C, x0)


def _first_order_hold(A, B, steps):
    """Exact discretization of ``x' = A x + B u`` for ``u`` linear over each step, one per step
    length: ``x+ = phi x + gamma0 u + gamma1 u+``."""
    order = A.shape[0]
    phis = np.empty((steps.size, order, order))
    gamma0s = np.empty((steps.size, order))
    gamma1s = np.empty((steps.size, order))
    for j, dt in enumerate(steps):
        phis[j], gamma0s[j], gamma1s[j] = first_order_hold(A, B, dt)
    return phis, gamma0s, gamma1s


@njit(cache=True, nogil=True)
def _step_varying_stiffness(forcing, relative_stiffness, stiffness, classes, phis, gamma0s, gamma1s, x0):
    # The stiffness change enters as a force -stiffness*e(t)*x on the exactly discretized
    # constant-stiffness system; a predictor-corrector step makes that coupling second order.
    n = forcing.shape[0]
    out = np.empty(n)
    x_pos, x_vel = x0[0], x0[1]
    out[0] = x_pos
    for t in range(1, n):
        j = classes[t - 1]
        u_start = forcing[t - 1] - stiffness * relative_stiffness[t - 1] * x_pos
        guess = x_pos
        for _ in range(2):
            u_end = forcing[t] - stiffness * relative_stiffness[t] * guess
            new_pos = (phis[j, 0, 0] * x_pos + phis[j, 0, 1] * x_vel + gamma0s[j, 0] * u_start
                       + gamma1s[j, 0] * u_end)
            guess = new_pos
        new_vel = (phis[j, 1, 0] * x_pos + phis[j, 1, 1] * x_vel + gamma0s[j, 1] * u_start
                   + gamma1s[j, 1] * u_end)
        x_pos, x_vel = new_pos, new_vel
        out[t] = x_pos
    return out


def varying_stiffness_response(time, forcing, relative_stiffness, stiffness, damping, *, classes=None):
    """Displacement (m) of ``x'' + damping*x' + stiffness*(1 + e(t))*x = u(t)`` (the Delta-E
    effect on the lumped model (13)), starting at the static equilibrium of the first sample.

    ``forcing`` u in m/s^2, ``relative_stiffness`` e (dimensionless, > -1), ``stiffness`` in
    1/s^2, ``damping`` in 1/s; both samples linear between samples."""
    steps, index = step_classes(time) if classes is None else classes
    A, B, _ = second_order_system(stiffness, damping, 1.0)
    phis, gamma0s, gamma1s = _first_order_hold(A, B, steps)
    forcing = np.ascontiguousarray(forcing, dtype=np.float64)
    relative = np.ascontiguousarray(np.maximum(relative_stiffness, MIN_RELATIVE_STIFFNESS), dtype=np.float64)
    x0 = np.array([forcing[0] / (stiffness * (1.0 + relative[0])), 0.0])
    return _step_varying_stiffness(forcing, relative, float(stiffness), index, phis, gamma0s, gamma1s, x0)


def second_order_system(stiffness, damping, gain):
    """State space of ``x'' + damping*x' + stiffness*x = gain*u`` (lumped model (13))."""
    return (np.array([[0.0, 1.0], [-stiffness, -damping]]), np.array([0.0, gain]), np.array([1.0, 0.0]))


def first_order_system(rate, gain):
    """State space of ``y' = -rate*y + gain*u`` (the scalar plant of the paper's §4.1)."""
    return np.array([[-rate]]), np.array([gain]), np.array([1.0])


__all__ = ["AMBIENT_TEMPERATURE", "CURVE_COLUMNS", "KNEE_COLUMN", "MAGNETIC_COLUMNS", "PINNING_DRIFT_COLUMNS",
           "first_order_system", "heating_reference", "knee_exponents", "lane_passes", "lti_response", "member_passes",
           "second_order_system", "simulate_lanes", "simulate_members", "step_classes", "varying_stiffness_response"]


#: The compiled first-order-hold stepping loop, for models that build their own discretization.
step_lti = _step_lti
