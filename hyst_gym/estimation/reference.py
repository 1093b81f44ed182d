"""Brute-force solver of the min-max problem (15), independent of the closed form.

Used only in tests, to check :func:`hyst_gym.estimation.minmax.minmax_solution`.

For a sign ``s`` of ytilde the problem is::

    nu_star = min over phi of  max over theta in {theta_i} u {thetahat} of
              s*[f(thetahat) - f(theta) - phi*(thetahat - theta)]

Written as a linear program in (phi, t) -- minimize t subject to
``t >= s*(-g_i + phi*(theta_i - thetahat))`` for every node and ``t >= 0`` (the point
thetahat itself) -- it is solved by HiGHS through :func:`scipy.optimize.linprog`,
with no envelope, hull or sorting involved.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog


def minmax_objective(theta_nodes, g, theta_hat, sign, phi) -> float:
    """max over theta of s*[-g(theta) - phi*(thetahat - theta)] (with (thetahat, 0) included)."""
    theta_nodes = np.asarray(theta_nodes, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    s = 1.0 if sign >= 0 else -1.0
    return float(max(0.0, np.max(s * (-g - phi * (theta_hat - theta_nodes)))))


def minmax_brute_force(theta_nodes, g, theta_hat, sign):
    """(nu_star, phi_star) by linear programming. phi_star is *one* minimizer."""
    theta_nodes = np.asarray(theta_nodes, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    s = 1.0 if sign >= 0 else -1.0
    # variables (phi, t): minimize t;  s*(theta_i - thetahat)*phi - t <= s*g_i
    a_ub = np.column_stack([s * (theta_nodes - theta_hat), -np.ones_like(theta_nodes)])
    b_ub = s * g
    result = linprog(c=[0.0, 1.0], A_ub=a_ub, b_ub=b_ub,
                     bounds=[(None, None), (0.0, None)], method="highs")
    if result.status != 0:
        raise RuntimeError(f"brute-force min-max LP failed: {result.message}")
    return float(result.x[1]), float(result.x[0])


__all__ = ["minmax_brute_force", "minmax_objective"]
