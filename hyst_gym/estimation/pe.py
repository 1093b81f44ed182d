"""Persistent-excitation diagnostics of Theorem 1 (conditions 3.1(a) and 3.1(b)).

The integrand of (22) is ``beta*nu*(f(u, thetahat) - f(u, a))`` with ``beta = +1``
where ``f(u, .)`` is convex at thetahat and ``-1`` where it is concave
(:meth:`AdaptiveEstimator.pe_integrand`, :attr:`AdaptiveEstimator.curvature_sign`).
Read literally, the paper's conditions over a stretch of time are:

* 3.1(a): the input reverses the sign of the integrand while beta stays fixed;
* 3.1(b): the input reverses beta while the sign of the integrand stays fixed.

:class:`PEMonitor` tests both over a sliding window of the last ``window`` control
steps, for E systems at once, and summarizes an episode: which condition held and for
what fraction of the steps.
"""

from __future__ import annotations

import numpy as np


class PEMonitor:
    """Windowed online test of 3.1(a)/(b) for E systems.

    Parameters
    ----------
    n_systems : int
        Batch size E.
    window : int
        Window length in control steps (>= 2).
    """

    def __init__(self, n_systems: int, window: int):
        if isinstance(n_systems, bool) or not isinstance(n_systems, (int, np.integer)) or n_systems < 1:
            raise ValueError(f"PEMonitor: n_systems must be an integer >= 1, got {n_systems!r}")
        if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 2:
            raise ValueError(f"PEMonitor: window must be an integer >= 2 steps, got {window!r}")
        self.n_systems = int(n_systems)
        self.window = int(window)
        E, W = self.n_systems, self.window
        # ring buffers of signs (+1/-1; 0 = empty slot) and running counts of each sign
        self._integrand_sign = np.zeros((E, W), dtype=np.int8)
        self._curvature_sign = np.zeros((E, W), dtype=np.int8)
        self._counts = np.zeros((E, 4), dtype=np.int64)  # integrand +, integrand -, beta +, beta -
        self._position = np.zeros(E, dtype=np.int64)
        self._steps = np.zeros(E, dtype=np.int64)
        self._steps_a = np.zeros(E, dtype=np.int64)
        self._steps_b = np.zeros(E, dtype=np.int64)
        self._positive = np.zeros(E, dtype=np.int64)
        self._integral = np.zeros(E)
        self.condition_a = np.zeros(E, dtype=bool)
        self.condition_b = np.zeros(E, dtype=bool)

    def reset(self, indices=None) -> None:
        rows = slice(None) if indices is None else indices
        for array in (self._integrand_sign, self._curvature_sign, self._counts, self._position, self._steps,
                      self._steps_a, self._steps_b, self._positive, self._integral,
                      self.condition_a, self.condition_b):
            array[rows] = 0

    def update(self, integrand, curvature_sign, dt: float = 1.0) -> None:
        """Record one step: ``integrand`` of (22) (E,) and beta (E,) (+1/-1); ``dt`` in s."""
        integrand = np.asarray(integrand, dtype=np.float64)
        new_i = np.where(integrand >= 0.0, 1, -1).astype(np.int8)
        new_b = np.where(np.asarray(curvature_sign) >= 0.0, 1, -1).astype(np.int8)
        rows = np.arange(self.n_systems)
        slot = self._position
        old_i = self._integrand_sign[rows, slot]
        old_b = self._curvature_sign[rows, slot]
        # leave the window
        self._counts[:, 0] -= old_i == 1
        self._counts[:, 1] -= old_i == -1
        self._counts[:, 2] -= old_b == 1
        self._counts[:, 3] -= old_b == -1
        # enter the window
        self._integrand_sign[rows, slot] = new_i
        self._curvature_sign[rows, slot] = new_b
        self._counts[:, 0] += new_i == 1
        self._counts[:, 1] += new_i == -1
        self._counts[:, 2] += new_b == 1
        self._counts[:, 3] += new_b == -1
        self._position = (slot + 1) % self.window
        integrand_reverses = (self._counts[:, 0] > 0) & (self._counts[:, 1] > 0)
        beta_reverses = (self._counts[:, 2] > 0) & (self._counts[:, 3] > 0)
        self.condition_a = integrand_reverses & ~beta_reverses
        self.condition_b = beta_reverses & ~integrand_reverses
        self._steps += 1
        self._steps_a += self.condition_a
        self._steps_b += self.condition_b
        self._positive += new_i == 1
        self._integral += integrand * dt

    def summary(self) -> dict:
        """Per-system episode summary (lists of length E).

        ``fraction_a`` / ``fraction_b``: share of steps at which the window ending there
        met 3.1(a) / 3.1(b); ``held``: ``"a"``, ``"b"``, ``"both"`` (at different times)
        or ``"neither"``; ``fraction_integrand_positive``; ``integral``: the integral of
        (22) over the episode (units of the integrand times s).
        """
        steps = np.maximum(self._steps, 1)
        frac_a = self._steps_a / steps
        frac_b = self._steps_b / steps
        held = np.where((frac_a > 0) & (frac_b > 0), "both",
                        np.where(frac_a > 0, "a", np.where(frac_b > 0, "b", "neither")))
        return {
            "steps": self._steps.tolist(),
            "fraction_a": frac_a.tolist(),
            "fraction_b": frac_b.tolist(),
            "held": held.tolist(),
            "fraction_integrand_positive": (self._positive / steps).tolist(),
            "integral": self._integral.tolist(),
        }


__all__ = ["PEMonitor"]
