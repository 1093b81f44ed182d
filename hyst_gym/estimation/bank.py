"""The model bank: G hysteresis models on a grid over Theta, for each of E systems.

``f(u, theta)`` of the paper is M at the current time for the whole field history
under the parameter ``a = theta`` (a hysteretic, history-dependent function). The bank
runs one hysteresis state per grid node, all driven by the measured field of their
system, and gives ``f``, ``df/dtheta`` and ``d2f/dtheta2`` at any ``thetahat`` in Theta
by C1 cubic Hermite interpolation that is exact at the nodes (``docs/model.md``, estimation).
"""

from __future__ import annotations

import numpy as np

from ..physics.hysteresis import HysteresisBatch
from ._kernels import BankParams, BankState, advance_bank, as_kernel_tuples, interpolate_bank
from .config import EstimatorConfig


class ModelBank:
    """E x G hysteresis models (A/m) on ``config.theta_grid``, one row per system.

    Parameters
    ----------
    config : EstimatorConfig
        Grid, hysteresis parameters and ``max_field_step``.
    n_systems : int
        Batch size E.
    """

    def __init__(self, config: EstimatorConfig, n_systems: int = 1):
        if isinstance(n_systems, bool) or not isinstance(n_systems, (int, np.integer)) or n_systems < 1:
            raise ValueError(f"ModelBank: n_systems must be an integer >= 1, got {n_systems!r}")
        self.config = config
        self.n_systems = int(n_systems)
        self.grid = config.theta_grid
        self.grid.setflags(write=False)
        params = HysteresisBatch.grid(config.hysteresis, self.grid)
        self._magnetization = np.zeros((self.n_systems, config.grid_size))
        self._field = np.zeros(self.n_systems)
        #: what the compiled kernels read and change (live arrays): see :class:`~._kernels.BankState`
        self.kernel_state = BankState(self._magnetization, self._field)
        #: the fixed data of the kernels: see :class:`~._kernels.BankParams`
        self.kernel_params = BankParams(self.grid, params.a, params.k, params.alpha, params.Ms, params.c,
                                        params.kind, float(config.max_field_step))
        # plain tuples of the same live arrays for the per-step call: numba's dispatcher types a
        # plain tuple in C and a namedtuple in Python (_kernels, above BankState)
        self._kernel_tuples = as_kernel_tuples(self.kernel_state, self.kernel_params)

    @property
    def magnetization(self) -> np.ndarray:
        """M of every node, A/m, shape (E, G) (read-only view)."""
        return _readonly(self._magnetization)

    @property
    def field(self) -> np.ndarray:
        """The field each system's bank has reached, A/m, shape (E,) (read-only view)."""
        return _readonly(self._field)

    def reset(self, field=0.0, magnetization=0.0, indices=None) -> None:
        """Put the banks of ``indices`` (all if None) at ``field`` with every node at ``magnetization`` (A/m)."""
        rows = slice(None) if indices is None else indices
        self._field[rows] = field
        if np.ndim(magnetization) == 0:
            self._magnetization[rows] = magnetization
        else:
            self._magnetization[rows] = np.asarray(magnetization, dtype=np.float64).reshape(-1, 1)

    def advance(self, field: np.ndarray) -> int:
        """Drive each system's bank to its new field (A/m, shape (E,)); returns model substeps."""
        return advance_bank(self._kernel_tuples[0], field, self._kernel_tuples[1])

    def evaluate(self, theta, out_value=None, out_slope=None, out_curvature=None):
        """f, df/dtheta, d2f/dtheta2 at ``theta`` (A/m, shape (E,)); each (E,)."""
        theta = np.ascontiguousarray(theta, dtype=np.float64)
        if out_value is None:
            out_value = np.empty(self.n_systems)
            out_slope = np.empty(self.n_systems)
            out_curvature = np.empty(self.n_systems)
        interpolate_bank(self.grid, self._magnetization, theta, out_value, out_slope, out_curvature)
        return out_value, out_slope, out_curvature


def _readonly(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


__all__ = ["ModelBank"]
