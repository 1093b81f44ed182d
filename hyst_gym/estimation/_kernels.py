"""Compiled inner loops of the estimators: bank advance, interpolation, min-max covers,
and the parameter laws.

All kernels work on a batch of E independent systems; the bank of each system holds
G hysteresis models on the same grid over Theta. ``cache=True`` everywhere so the
compilation cost is paid once per machine.

The parameter laws, one function each (selected by :class:`Law`):

* :func:`minmax_law` -- the min-max law of Nealis & Smith: the min-max problem (15) solved
  at the sign of the tuning error, its gap nu_star fed back into yhat ((14) scalar, (24)
  vector) and its slope phi_star driving the adaptation (16) (scalar) / (25) (vector);
* :func:`gradient_law` -- the gradient law: df/dtheta(thetahat) in place of phi_star and
  no min-max term (the baseline the paper argues against, §1);
* :func:`held_law` -- no law in the kernel: thetahat is held and set in Python
  (the multiple-model estimator).

All three then take the same explicit Euler step of the adaptation, :func:`adaptation_step`.
"""

from __future__ import annotations

from collections import namedtuple
from enum import IntEnum

import numpy as np
from numba import njit

from ..physics.background_compile import background_kernel
from ..physics.hysteresis import advance_shared


class Law(IntEnum):
    """The parameter law run by the compiled estimator step (its value is what the kernels see)."""

    #: the min-max law: (14)-(16) for the scalar plant, (24)-(25) for the vector plant
    MINMAX = 0
    #: the gradient law: df/dtheta in place of phi_star of (16)/(25), no min-max term
    GRADIENT = 1
    #: no law in the kernel: thetahat is held here and set by the estimator in Python
    HELD = 2


# The small helpers below are forceinline=True (LLVM inlining), not inline="always" (numba's
# IR inliner, which re-translates the callee at every call site): the same machine code for
# less compilation (see the note on inlining in physics/hysteresis.py).

# plain integers for the kernels (numba freezes module globals as compile-time constants)
_MINMAX = int(Law.MINMAX)
_GRADIENT = int(Law.GRADIENT)

# Named state and parameters of the kernels (namedtuples of arrays and numbers: numba compiles
# and caches them, and a field is read by name, so two arrays of one type cannot be swapped).
# The kernels called from Python once per control step (estimator_step here, the env's step
# kernels) take them as plain tuples, made by tuple(named) (:func:`as_kernel_tuples`), and name
# them again on entry: numba's dispatcher types a plain tuple in C but a namedtuple in Python,
# about twice the cost per field (+4-6 us per call of estimator_step at E = 1, measured), and
# renaming costs nothing in compiled code.

#: An E x G model bank: ``magnetization`` (E, G) A/m, and ``field`` (E,) A/m, the field each
#: row has reached. Changed in place.
BankState = namedtuple("BankState", ["magnetization", "field"])
#: The bank's fixed data: ``grid`` (G,) over Theta, A/m; the hysteresis parameters (G,) of its
#: models (``a`` = grid), ``kind`` (anhysteretic curve) and ``max_field_step`` (A/m).
BankParams = namedtuple("BankParams", ["grid", "a", "k", "alpha", "Ms", "c", "kind", "max_field_step"])
#: An estimator's live state, changed in place: thetahat ``theta`` (E,), f(thetahat) ``f_hat``,
#: the observer ``yhat`` and the measured ``y`` (E, n), and the quantities derived at thetahat
#: (slope and curvature of f, ytilde (E, n), y_eps, sat, sign, min-max gap nu and slope phi, (E,)).
EstimatorState = namedtuple("EstimatorState", ["theta", "f_hat", "yhat", "y", "slope", "curvature", "ytilde",
                                               "y_eps", "sat", "sign", "nu", "phi"])
#: The law and its constants: ``law`` (a :class:`Law` value), ``vector`` (lumped plant (24)),
#: ``tuning_row`` B^T P (n,), dead-zone width ``eps``, dead-zone offset (A/m), ``gamma``, plant
#: ``gain`` nu, and Theta = [``lo``, ``hi``].
ObserverParams = namedtuple("ObserverParams", ["law", "vector", "tuning_row", "eps", "offset", "gamma", "gain",
                                               "lo", "hi"])
#: The exact discretization of the observer over one control period ``dt`` (s): ``transition``
#: (n, n), ``hold0``/``hold1`` (n,) of the increment form, and ``weight``, how much one A/m of
#: held feedback moves the tuning error over the step.
HoldParams = namedtuple("HoldParams", ["dt", "transition", "hold0", "hold1", "weight"])


def as_kernel_tuples(*structures) -> tuple:
    """The named structures as plain tuples (nested ones too), in their field order, for a
    kernel that names them again on entry (see above)."""
    return tuple(_plain(structure) for structure in structures)


def _plain(value):
    return tuple(_plain(field) for field in value) if isinstance(value, tuple) else value


@background_kernel(inline="always")
def advance_bank(bank, field_to, params):
    """Move each system's bank (:class:`BankState`) along its own field, in place.

    Row ``e`` goes from ``bank.field[e]`` to ``field_to[e]`` (A/m) through the physics
    kernel :func:`advance_shared`, so a bank node equals a single-model run bit for bit;
    ``bank.field`` then holds ``field_to``. Returns the number of model substeps taken.
    """
    bank, params = BankState(*bank), BankParams(*params)  # plain tuples from Python: see above
    total = 0
    magnetization = bank.magnetization
    G = magnetization.shape[1]
    for e in range(magnetization.shape[0]):
        total += G * advance_shared(magnetization[e], bank.field[e], field_to[e], params.a, params.k,
                                    params.alpha, params.Ms, params.c, params.kind, params.max_field_step)
        bank.field[e] = field_to[e]
    return total


@njit(cache=True, forceinline=True)
def _locate(grid, theta):
    """Index j of the interval [grid[j], grid[j+1]) holding theta (clamped to the ends)."""
    G = grid.shape[0]
    h = (grid[G - 1] - grid[0]) / (G - 1)
    j = int((theta - grid[0]) / h)
    if j < 0:
        j = 0
    if j > G - 2:
        j = G - 2
    # Rounding in (theta - grid[0])/h may land one interval off; fix it on the grid itself.
    while j > 0 and theta < grid[j]:
        j -= 1
    while j < G - 2 and theta >= grid[j + 1]:
        j += 1
    return j


@njit(cache=True, forceinline=True)
def _node_slope(values, grid, j):
    """Finite-difference slope at node j: centred inside, 2nd-order one-sided at the ends."""
    G = grid.shape[0]
    if j == 0:
        return (-3.0 * values[0] + 4.0 * values[1] - values[2]) / (grid[2] - grid[0])
    if j == G - 1:
        return (3.0 * values[G - 1] - 4.0 * values[G - 2] + values[G - 3]) / (grid[G - 1] - grid[G - 3])
    return (values[j + 1] - values[j - 1]) / (grid[j + 1] - grid[j - 1])


@background_kernel()
def interpolate_bank(grid, values, theta, out_value, out_slope, out_curvature):
    """Cubic Hermite interpolation of each row of ``values`` (E, G) at ``theta`` (E,).

    Node slopes are finite differences, so the interpolant is C1 and exact at the nodes
    (at a node the node value itself is returned, bit for bit). Writes f, df/dtheta and
    d2f/dtheta2 (the latter piecewise linear) into the three output arrays (E,).
    """
    for e in range(values.shape[0]):
        value, slope, curvature = _interpolate_one(grid, values[e], theta[e])
        out_value[e] = value
        out_slope[e] = slope
        out_curvature[e] = curvature


@njit(cache=True)
def interpolate_rows(grid, values, rows, theta, out_value, out_slope, out_curvature):
    """:func:`interpolate_bank` at ``theta[i]`` on row ``rows[i]`` of ``values`` (R, G), all (N,):
    the bank's interpolant evaluated on recorded bank traces (one row per instant)."""
    for i in range(theta.shape[0]):
        value, slope, curvature = _interpolate_one(grid, values[rows[i]], theta[i])
        out_value[i] = value
        out_slope[i] = slope
        out_curvature[i] = curvature


@njit(cache=True)
def _lower_hull(xs, ys, n, hull):
    """Andrew's monotone chain on sorted xs[:n]: indices of the lower convex hull.

    Collinear middle points are dropped. Returns the number of hull vertices.
    """
    m = 0
    for i in range(n):
        while m >= 2:
            o = hull[m - 2]
            p = hull[m - 1]
            cross = (xs[p] - xs[o]) * (ys[i] - ys[o]) - (ys[p] - ys[o]) * (xs[i] - xs[o])
            if cross <= 0.0:
                m -= 1
            else:
                break
        hull[m] = i
        m += 1
    return m


@njit(cache=True)
def minmax_one(grid, g, theta_hat, sign, gradient, xs, ys, hull):
    """Closed-form solution (nu_star, phi_star) of the min-max problem (15) for one system.

    ``g`` (G,) holds ``f(theta_i) - f(thetahat)`` on the grid, ``sign`` is sign(ytilde)
    (+1 or -1), ``gradient`` is df/dtheta at thetahat. With ``h = sign*g`` and the point
    (thetahat, 0) added, ``nu_star = -conv(h)(thetahat)`` and ``phi_star = sign*slope``
    where slope is that of conv(h) at thetahat (eq. (15): conv(g) for sign +1, conc(g)
    for sign -1). At a vertex of the envelope the gradient is clipped into the
    subdifferential [left slope, right slope] (a valid subgradient; it *is* the gradient
    where g is locally convex); at an end of Theta the missing side is unbounded.
    ``xs``, ``ys``, ``hull`` are work arrays of length G + 1.
    """
    G = grid.shape[0]
    n = 0
    hat_index = -1
    inserted = False
    for i in range(G):
        if not inserted and theta_hat <= grid[i]:
            xs[n] = theta_hat
            ys[n] = 0.0
            hat_index = n
            n += 1
            inserted = True
            if theta_hat == grid[i]:
                continue  # the node coincides with thetahat: g is 0 there by construction
        xs[n] = grid[i]
        ys[n] = sign * g[i]
        n += 1
    if not inserted:
        xs[n] = theta_hat
        ys[n] = 0.0
        hat_index = n
        n += 1
    m = _lower_hull(xs, ys, n, hull)
    for v in range(m):
        if hull[v] == hat_index:
            lo = -np.inf
            hi = np.inf
            if v > 0:
                p = hull[v - 1]
                lo = (ys[hat_index] - ys[p]) / (xs[hat_index] - xs[p])
            if v < m - 1:
                q = hull[v + 1]
                hi = (ys[q] - ys[hat_index]) / (xs[q] - xs[hat_index])
            slope = sign * gradient
            if slope < lo:
                slope = lo
            if slope > hi:
                slope = hi
            return 0.0, sign * slope
    # thetahat lies strictly inside a hull edge (above the envelope, or collinear).
    for v in range(m - 1):
        p = hull[v]
        q = hull[v + 1]
        if xs[p] <= theta_hat and theta_hat <= xs[q]:
            slope = (ys[q] - ys[p]) / (xs[q] - xs[p])
            value = ys[p] + slope * (theta_hat - xs[p])
            nu = -value
            if nu < 0.0:
                nu = 0.0
            return nu, sign * slope
    return 0.0, sign * gradient  # unreachable: the hull spans [xs[0], xs[n-1]]


@njit(cache=True, forceinline=True)
def _minmax_workspace(G):
    """Work arrays of :func:`minmax_one` on a grid of G nodes: xs, ys, hull (G + 1) and g (G)."""
    return np.empty(G + 1), np.empty(G + 1), np.empty(G + 1, dtype=np.int64), np.empty(G)


@njit(cache=True)
def minmax_batch(grid, values, theta_hat, value_hat, gradient, sign, out_nu, out_phi):
    """:func:`minmax_one` for every system: ``values`` (E, G), the rest (E,)."""
    G = grid.shape[0]
    xs, ys, hull, g = _minmax_workspace(G)
    for e in range(values.shape[0]):
        for i in range(G):
            g[i] = values[e, i] - value_hat[e]
        nu, phi = minmax_one(grid, g, theta_hat[e], sign[e], gradient[e], xs, ys, hull)
        out_nu[e] = nu
        out_phi[e] = phi


@njit(cache=True, forceinline=True)
def _interpolate_one(grid, row, t):
    """(f, df, d2f) of the cubic Hermite interpolant of ``row`` at ``t`` (see interpolate_bank)."""
    j = _locate(grid, t)
    h = grid[j + 1] - grid[j]
    m0 = _node_slope(row, grid, j) * h
    m1 = _node_slope(row, grid, j + 1) * h
    f0 = row[j]
    f1 = row[j + 1]
    if t == grid[j]:
        return f0, m0 / h, (-6.0 * f0 - 4.0 * m0 + 6.0 * f1 - 2.0 * m1) / (h * h)
    if t == grid[j + 1]:
        return f1, m1 / h, (6.0 * f0 + 2.0 * m0 - 6.0 * f1 + 4.0 * m1) / (h * h)
    u = (t - grid[j]) / h
    u2 = u * u
    u3 = u2 * u
    value = ((2.0 * u3 - 3.0 * u2 + 1.0) * f0 + (u3 - 2.0 * u2 + u) * m0
             + (-2.0 * u3 + 3.0 * u2) * f1 + (u3 - u2) * m1)
    slope = ((6.0 * u2 - 6.0 * u) * f0 + (3.0 * u2 - 4.0 * u + 1.0) * m0
             + (-6.0 * u2 + 6.0 * u) * f1 + (3.0 * u2 - 2.0 * u) * m1) / h
    curvature = ((12.0 * u - 6.0) * f0 + (6.0 * u - 4.0) * m0
                 + (-12.0 * u + 6.0) * f1 + (6.0 * u - 2.0) * m1) / (h * h)
    return value, slope, curvature


@njit(cache=True, forceinline=True)
def _boundary_layer(z_free, kappa_pos, kappa_neg, eps):
    """Root z of ``z + kappa_sign(z)*sat(z/eps) = z_free`` (both kappas > -eps)."""
    if z_free >= eps + kappa_pos:
        return z_free - kappa_pos
    if z_free >= 0.0:
        return z_free / (1.0 + kappa_pos / eps)
    if z_free > -eps - kappa_neg:
        return z_free / (1.0 + kappa_neg / eps)
    return z_free + kappa_neg


@njit(cache=True, forceinline=True)
def minmax_law(grid, g, theta_hat, z_free, slope, weight, offset, eps, xs, ys, hull):
    """The min-max law at one system: returns ``(z, nu_star, phi_star)``.

    ``g`` (G,) holds ``f(theta_i) - f(thetahat)``; ``z_free`` is the tuning error the step
    would reach without feedback. The min-max problem (15) (scalar) / (25) (vector) is solved
    for the sign of z_free; the boundary layer of (14)/(24) then gives z, which has that sign
    (both kappas > -eps), and only if it came out with the other sign after all is (15)
    solved again for that one. nu_star feeds back into yhat ((14)/(24)); phi_star drives the
    adaptation (16) / (25) in :func:`adaptation_step`.
    """
    nu_pos = 0.0
    nu_neg = 0.0
    phi_pos = 0.0
    phi_neg = 0.0
    if z_free >= 0.0:
        nu_pos, phi_pos = minmax_one(grid, g, theta_hat, 1.0, slope, xs, ys, hull)
    else:
        nu_neg, phi_neg = minmax_one(grid, g, theta_hat, -1.0, slope, xs, ys, hull)
    z = _boundary_layer(z_free, weight * (nu_pos - offset), weight * (nu_neg - offset), eps)
    if (z >= 0.0) != (z_free >= 0.0):
        if z >= 0.0:
            nu_pos, phi_pos = minmax_one(grid, g, theta_hat, 1.0, slope, xs, ys, hull)
        else:
            nu_neg, phi_neg = minmax_one(grid, g, theta_hat, -1.0, slope, xs, ys, hull)
    if z >= 0.0:
        return z, nu_pos, phi_pos
    return z, nu_neg, phi_neg


@njit(cache=True, forceinline=True)
def gradient_law(z_free, slope, weight, offset, eps):
    """The gradient law at one system: returns ``(z, 0, df/dtheta)``: the min-max law of
    (16)/(25) with the bank's slope at thetahat in place of phi_star and no min-max gap in yhat."""
    z = _boundary_layer(z_free, weight * (0.0 - offset), weight * (0.0 - offset), eps)
    return z, 0.0, slope


@njit(cache=True, forceinline=True)
def held_law(z_free, weight, offset, eps):
    """No parameter law: returns ``(z, 0, 0)``, so :func:`adaptation_step` leaves thetahat
    where it is (the estimator sets it in Python); yhat keeps the dead-zone feedback of (14)."""
    z = _boundary_layer(z_free, weight * (0.0 - offset), weight * (0.0 - offset), eps)
    return z, 0.0, 0.0


@njit(cache=True, forceinline=True)
def adaptation_step(theta_hat, dt, gamma, gain, y_eps, phi, lo, hi):
    """Explicit Euler step of ``thetahat' = -gamma*nu*y_eps*phi`` ((16) scalar, with nu the
    plant gain; (25) vector, gain 1), clipped into Theta = [lo, hi]."""
    t_new = theta_hat - dt * gamma * gain * y_eps * phi
    return min(hi, max(lo, t_new))


@njit(cache=True, inline="always")
def observer_step(grid, values, measured, state, observer, hold):
    """One control step of every system after the bank (``values`` (E, G)) has moved (see
    AdaptiveEstimator.update).

    In place, in ``state`` (:class:`EstimatorState`): ``theta`` (thetahat_k -> thetahat_k+1),
    ``f_hat`` (f(thetahat_k) on the old bank -> f(thetahat_k+1) on the new one), ``yhat`` and
    the quantities at thetahat (:func:`refresh`). ``observer.law``: a :class:`Law` value
    (min-max (16)/(25), gradient, or held). ``observer.tuning_row`` is B^T P (vector) and
    unused for the scalar plant.
    """
    theta, f_hat, yhat = state.theta, state.f_hat, state.yhat
    transition, hold0, hold1, weight = hold.transition, hold.hold0, hold.hold1, hold.weight
    law, vector, tuning_row, eps, offset = (observer.law, observer.vector, observer.tuning_row, observer.eps,
                                            observer.offset)
    E, n = yhat.shape
    G = grid.shape[0]
    xs, ys, hull, g = _minmax_workspace(G)
    free = np.empty(n)
    new_state = np.empty(n)
    for e in range(E):
        row = values[e]
        f_end, slope_end, _ = _interpolate_one(grid, row, theta[e])
        for i in range(n):
            acc = f_hat[e] * hold0[i] + (f_end - f_hat[e]) * hold1[i] - measured[e, i]
            for j in range(n):
                acc += transition[i, j] * yhat[e, j]
            free[i] = acc
        if vector:
            z_free = 0.0
            for i in range(n):
                z_free += tuning_row[i] * free[i]
        else:
            z_free = free[0]
        if law == _MINMAX:
            for i in range(G):
                g[i] = row[i] - f_end
            z, nu, phi = minmax_law(grid, g, theta[e], z_free, slope_end, weight, offset, eps, xs, ys, hull)
        elif law == _GRADIENT:
            z, nu, phi = gradient_law(z_free, slope_end, weight, offset, eps)
        else:
            z, nu, phi = held_law(z_free, weight, offset, eps)
        sat = min(1.0, max(-1.0, z / eps))
        applied = (nu - offset) * sat
        for i in range(n):
            new_state[i] = free[i] - applied * hold0[i] + measured[e, i]
            yhat[e, i] = new_state[i]
        y_eps = z if vector else z - eps * sat
        theta[e] = adaptation_step(theta[e], hold.dt, observer.gamma, observer.gain, y_eps, phi, observer.lo,
                                   observer.hi)
    refresh(grid, values, measured, state, observer)


@background_kernel()
def refresh(grid, values, measured, state, observer):
    """Into ``state``: bank values at thetahat (``f_hat``, ``slope``, ``curvature``), ytilde,
    y_eps, sat, sign and the min-max (15) at that sign (``nu``, ``phi``)."""
    theta, yhat = state.theta, state.yhat
    out_value, out_slope, out_curvature, out_ytilde, out_y_eps = (state.f_hat, state.slope, state.curvature,
                                                                  state.ytilde, state.y_eps)
    out_sat, out_sign, out_nu, out_phi = state.sat, state.sign, state.nu, state.phi
    tuning_row, vector, eps = observer.tuning_row, observer.vector, observer.eps
    E, n = yhat.shape
    G = grid.shape[0]
    xs, ys, hull, g = _minmax_workspace(G)
    for e in range(E):
        row = values[e]
        value, slope, curvature = _interpolate_one(grid, row, theta[e])
        out_value[e] = value
        out_slope[e] = slope
        out_curvature[e] = curvature
        for i in range(n):
            out_ytilde[e, i] = yhat[e, i] - measured[e, i]
        if vector:
            z = 0.0
            for i in range(n):
                z += tuning_row[i] * out_ytilde[e, i]
            out_y_eps[e] = z
        else:
            z = out_ytilde[e, 0]
        sat = min(1.0, max(-1.0, z / eps))
        out_sat[e] = sat
        if not vector:
            out_y_eps[e] = z - eps * sat
        sign = 1.0 if z >= 0.0 else -1.0
        out_sign[e] = sign
        for i in range(G):
            g[i] = row[i] - value
        nu, phi = minmax_one(grid, g, theta[e], sign, slope, xs, ys, hull)
        out_nu[e] = nu
        out_phi[e] = phi


# inline="always" here, on advance_bank and on observer_step: the env compiles them as part of
# its excitation_step (see envs/kernels.py)
@njit(cache=True, inline="always")
def estimator_step(field, measured, bank, bank_params, state, observer, hold):
    """One whole control step of every system: bank advance, then :func:`observer_step`.

    ``field`` (E,) and ``measured`` (E, n) are the values at the end of the step; ``bank``
    (:class:`BankState`) and ``state`` (:class:`EstimatorState`) change in place. Returns
    0, or (before touching any state) 1 if ``field`` or 2 if ``measured`` is not finite.
    The five structures come as plain tuples (:func:`as_kernel_tuples`). ``observer.law`` :attr:`Law.MINMAX`
    or :attr:`Law.GRADIENT` only: :attr:`Law.HELD` runs in Python.
    """
    bank, bank_params, state = BankState(*bank), BankParams(*bank_params), EstimatorState(*state)
    observer, hold = ObserverParams(*observer), HoldParams(*hold)
    y = state.y
    E, n = y.shape
    for e in range(E):
        if not np.isfinite(field[e]):
            return 1
        for i in range(n):
            if not np.isfinite(measured[e, i]):
                return 2
    advance_bank(bank, field, bank_params)
    observer_step(bank_params.grid, bank.magnetization, measured, state, observer, hold)
    for e in range(E):
        for i in range(n):
            y[e, i] = measured[e, i]
    return 0


@njit(cache=True)
def pe_integrand_batch(grid, values, a_true, f_hat, curvature, gain, lo, hi, out):
    """``beta*gain*(f(u, thetahat) - f(u, a_true))`` per system into ``out`` (E,).

    ``a_true`` has length E or 1 (broadcast). Returns 0, or 1 (``out`` untouched) if an
    ``a_true`` is not finite or lies outside [lo, hi].
    """
    E = values.shape[0]
    count = a_true.shape[0]
    for i in range(count):
        t = a_true[i]
        if not (np.isfinite(t) and lo <= t <= hi):
            return 1
    for e in range(E):
        t = a_true[e] if count == E else a_true[0]
        value, _, _ = _interpolate_one(grid, values[e], t)
        beta = 1.0 if curvature[e] >= 0.0 else -1.0
        out[e] = beta * gain * (f_hat[e] - value)
    return 0
