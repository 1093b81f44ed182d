"""The min-max problem (15)/(25) on a grid: closed form, envelopes for plots.

For ``g(theta) = f(u, theta) - f(u, thetahat)`` sampled at the bank nodes, with the
point (thetahat, 0) added (eq. (15)):

* sign(ytilde) = +1: ``nu_star = -conv(g)(thetahat)``, ``phi_star`` = slope of conv(g);
* sign(ytilde) = -1: ``nu_star = conc(g)(thetahat)``, ``phi_star`` = slope of conc(g);

conv / conc being the lower convex / upper concave envelopes over Theta. At a kink
any slope between the neighbouring edge slopes is optimal; the gradient clipped into
that interval is returned. The compiled batch version is
:func:`hyst_gym.estimation._kernels.minmax_batch`; an independent brute-force solver
lives in :mod:`hyst_gym.estimation.reference` (tests only).
"""

from __future__ import annotations

import numpy as np

from ._kernels import _lower_hull, minmax_one


def _grid_and_values(theta_nodes, g):
    theta_nodes = np.ascontiguousarray(theta_nodes, dtype=np.float64)
    g = np.ascontiguousarray(g, dtype=np.float64)
    if theta_nodes.ndim != 1 or theta_nodes.shape != g.shape or theta_nodes.size < 2:
        raise ValueError(f"theta_nodes and g must be 1-D of equal length >= 2, got {theta_nodes.shape}, {g.shape}")
    if np.any(np.diff(theta_nodes) <= 0):
        raise ValueError("theta_nodes must be strictly increasing")
    return theta_nodes, g


def minmax_solution(theta_nodes, g, theta_hat: float, sign: float, gradient: float = 0.0):
    """(nu_star, phi_star) of (15) for one system; ``sign`` = sign(ytilde) (+1/-1).

    ``theta_nodes`` (G,) increasing, ``g`` (G,) = f(theta_i) - f(thetahat), ``theta_hat``
    inside [theta_nodes[0], theta_nodes[-1]], ``gradient`` = df/dtheta(thetahat) (used
    only to pick a subgradient at a kink).
    """
    theta_nodes, g = _grid_and_values(theta_nodes, g)
    if not theta_nodes[0] <= theta_hat <= theta_nodes[-1]:
        raise ValueError(f"theta_hat={theta_hat!r} outside [{theta_nodes[0]!r}, {theta_nodes[-1]!r}]")
    sign = 1.0 if sign >= 0 else -1.0
    n = theta_nodes.size + 1
    nu, phi = minmax_one(theta_nodes, g, float(theta_hat), sign, float(gradient),
                         np.empty(n), np.empty(n), np.empty(n, dtype=np.int64))
    return float(nu), float(phi)


def envelopes(theta_nodes, g, theta_hat: float):
    """Lower convex and upper concave envelopes of the points (theta_i, g_i) and (thetahat, 0).

    Returns ``(x, lower, upper)``: the sorted abscissae (nodes with thetahat inserted)
    and both envelopes evaluated there (piecewise linear in between).
    """
    theta_nodes, g = _grid_and_values(theta_nodes, g)
    keep = theta_nodes != theta_hat
    x = np.concatenate([theta_nodes[keep], [theta_hat]])
    y = np.concatenate([g[keep], [0.0]])
    order = np.argsort(x, kind="stable")
    x, y = x[order], y[order]
    hull = np.empty(x.size, dtype=np.int64)
    m = _lower_hull(x, y, x.size, hull)
    lower = np.interp(x, x[hull[:m]], y[hull[:m]])
    m = _lower_hull(x, -y, x.size, hull)
    upper = np.interp(x, x[hull[:m]], y[hull[:m]])
    return x, lower, upper


__all__ = ["envelopes", "minmax_solution"]
