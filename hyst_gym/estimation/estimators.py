"""Adaptive estimators of the hysteresis parameter ``a`` (A/m), batched over E systems.

Every estimator carries its own model of the plant (``yhat``) driven by the bank value
``f(u, thetahat)`` and shares one interface:

``reset(a_estimate=None, field=0.0, output=None, magnetization=0.0, indices=None)``
    start (some of) the systems;
``update(field, measured_output, dt) -> a_estimate``
    advance one control step of ``dt`` s: ``field`` (E,) is the applied field (A/m) at
    the *end* of the step, ``measured_output`` the plant output at the end of the step:
    shape (E,) for :class:`~.config.FirstOrderPlant`, (E, 2) = (displacement m,
    velocity m/s) for :class:`~.config.LumpedPlant`.

and the read-only arrays (E,) ``a_estimate``, ``tuning_error``, ``minmax_gap``,
``curvature_sign`` plus ``pe_integrand(a_true)``.

Time discretization (one control step): the linear part of the ``yhat`` dynamics is
integrated exactly, with ``f(u, thetahat)`` taken linear in time between the two field
samples (first-order hold) and the feedback terms (dead zone, min-max) held from the
start of the step; ``thetahat`` takes an explicit Euler step of its law and is then
clipped into Theta. The plant dynamics are stable by assumption, so any ``dt`` is
stable for ``yhat``; the adaptation law needs ``dt`` small against its own time
constant (about 1 s in the paper's cases).
"""

from __future__ import annotations

import numpy as np

from ..physics.linear_system import hold_and_ramp
from ._kernels import (EstimatorState, HoldParams, Law, ObserverParams, as_kernel_tuples, estimator_step,
                       observer_step, pe_integrand_batch, refresh)
from .bank import ModelBank, _readonly
from .config import EstimatorConfig


def hold_matrices(state_matrix: np.ndarray, input_vector: np.ndarray, dt: float):
    """Exact discretization of ``y' = A y + B u`` over ``dt`` for ``u`` linear in time.

    Returns ``(Phi, G0, G1)`` with ``y(t+dt) = Phi y(t) + G0 u(t) + G1 (u(t+dt) - u(t))``
    (zero-order hold ``G0`` plus the first-order-hold correction ``G1``): the increment
    form of the physics layer's :func:`~hyst_gym.physics.linear_system.hold_and_ramp`.
    """
    return hold_and_ramp(state_matrix, input_vector, dt)


class AdaptiveEstimator:
    """Shared machinery of the bank-based estimators (see the module docstring).

    Subclasses pick the parameter law run by the compiled step (``law``, a :class:`Law`:
    min-max (16)/(25), gradient, or held with their own ``_next_theta``). The min-max solution (15)/(25) is computed at
    every step for every estimator so that all of them expose the same observation
    arrays.

    Parameters
    ----------
    config : EstimatorConfig
    n_systems : int
        Number E of independent systems estimated at once.
    """

    #: short name used by :func:`make_estimator` and in reports
    name = "base"
    #: parameter law run by the compiled step (Law.HELD: the subclass sets theta in Python)
    law = Law.MINMAX

    def __init__(self, config: EstimatorConfig, n_systems: int = 1):
        if not isinstance(config, EstimatorConfig):
            raise ValueError(f"{type(self).__name__}: config must be an EstimatorConfig, got {type(config).__name__}")
        self.config = config
        self.bank = ModelBank(config, n_systems)
        self.n_systems = self.bank.n_systems
        E = self.n_systems
        plant = config.plant
        self._vector = config.is_vector
        self._n = plant.output_size
        self._A = plant.state_matrix
        self._B = plant.input_matrix
        if self._vector:
            self._P = plant.lyapunov_matrix
            self._BP = self._B @ self._P  # y_eps = B^T P ytilde, (24)
            self._gain = 1.0  # f = M enters through B
        else:
            self._P = None
            self._BP = None
            self._gain = plant.gain  # f = nu*M in (14)
        self._tuning_row = np.ascontiguousarray(self._BP if self._vector else np.zeros(self._n))
        self._eps = config.eps
        self._gamma = config.gamma
        self._lo = config.theta_min
        self._hi = config.theta_max
        self._hold_dt = None
        self._hold = None
        self._step_tuples = None
        self._theta = np.full(E, config.initial_estimate)
        self._yhat = np.zeros((E, self._n))
        self._y = np.zeros((E, self._n))
        self._f_hat = np.zeros(E)
        self._slope = np.zeros(E)
        self._curvature = np.zeros(E)
        self._ytilde = np.zeros((E, self._n))
        self._y_eps = np.zeros(E)
        self._sat = np.zeros(E)
        self._sign = np.ones(E)
        self._nu = np.zeros(E)
        self._phi = np.zeros(E)
        #: what the compiled kernels read and change (live arrays): see :class:`~._kernels.EstimatorState`
        self.kernel_state = EstimatorState(self._theta, self._f_hat, self._yhat, self._y, self._slope,
                                           self._curvature, self._ytilde, self._y_eps, self._sat, self._sign,
                                           self._nu, self._phi)
        #: the law and its constants: see :class:`~._kernels.ObserverParams`
        self.observer_params = ObserverParams(int(self.law), self._vector, self._tuning_row, self._eps,
                                              self._dead_zone_offset, self._gamma, self._gain, self._lo, self._hi)
        self._a_estimate_view = _readonly(self._theta)
        self.reset()

    def __setstate__(self, state):
        self.__dict__.update(state)
        # a pickled view is restored as a copy: point it at the live array again
        self._a_estimate_view = _readonly(self._theta)

    # ------------------------------------------------------------------ public API

    @property
    def a_estimate(self) -> np.ndarray:
        """thetahat, A/m, (E,), always inside Theta (read-only view of live state)."""
        return self._a_estimate_view

    @property
    def tuning_error(self) -> np.ndarray:
        """y_eps, (E,): ``ytilde - eps*sat(ytilde/eps)`` (14) or ``B^T P ytilde`` (24)."""
        return _readonly(self._y_eps)

    @property
    def tracking_error(self) -> np.ndarray:
        """ytilde = yhat - y: (E,) for the scalar plant, (E, 2) for the lumped plant."""
        return _readonly(self._ytilde[:, 0] if not self._vector else self._ytilde)

    @property
    def output_estimate(self) -> np.ndarray:
        """yhat: (E,) for the scalar plant, (E, 2) for the lumped plant."""
        return _readonly(self._yhat[:, 0] if not self._vector else self._yhat)

    @property
    def minmax_gap(self) -> np.ndarray:
        """nu_star (15) / a_star (25) on M, A/m, (E,), >= 0: how far f is from convex
        (sign +) or concave (sign -) around thetahat; 0 where the gradient is exact."""
        return _readonly(self._nu)

    @property
    def minmax_slope(self) -> np.ndarray:
        """phi_star of (15)/(25) on M, A/m per A/m, (E,)."""
        return _readonly(self._phi)

    @property
    def model_output(self) -> np.ndarray:
        """f(u, thetahat) = M under thetahat, A/m, (E,)."""
        return _readonly(self._f_hat)

    @property
    def model_slope(self) -> np.ndarray:
        """df/dtheta at thetahat (bank interpolant), (E,)."""
        return _readonly(self._slope)

    @property
    def curvature_sign(self) -> np.ndarray:
        """beta of Theorem 1: +1 where f(u, .) is convex at thetahat, -1 where concave, (E,)."""
        return np.where(self._curvature >= 0.0, 1.0, -1.0)

    def pe_integrand(self, a_true) -> np.ndarray:
        """Integrand of (22), ``beta*nu*(f(u, thetahat) - f(u, a_true))``, (E,).

        ``a_true`` (A/m, scalar or (E,), inside Theta) is the truth, known only in
        simulation: use for info/diagnostics, never as an observation. ``f(u, a_true)``
        comes from the bank (the estimator's own model). ``nu`` is the scalar plant's
        gain; for the lumped plant (where the paper states no (22)) it is 1, so the
        integrand is in A/m.
        """
        values = np.asarray(a_true, dtype=np.float64)
        if values.ndim > 1 or values.size not in (1, self.n_systems):
            self._as_theta(a_true, "a_true")  # raises naming the shape
        out = np.empty(self.n_systems)
        if pe_integrand_batch(self.bank.grid, self.bank._magnetization, values.reshape(-1), self._f_hat,
                              self._curvature, self._gain, self._lo, self._hi, out):
            self._as_theta(a_true, "a_true")  # raises naming the problem
        return out

    def lyapunov_function(self, a_true) -> np.ndarray:
        """V, (E,): ``y_eps^2 + (thetahat - a)^2/gamma`` (scalar, paper's V for gamma = 1)
        or ``gamma*ytilde^T P ytilde + (thetahat - a)^2`` (vector, (26))."""
        a_true = self._as_theta(a_true, "a_true", check_box=False)
        error = self._theta - a_true
        if self._vector:
            quadratic = np.einsum("ei,ij,ej->e", self._ytilde, self._P, self._ytilde)
            return self._gamma * quadratic + error ** 2
        return self._y_eps ** 2 + error ** 2 / self._gamma

    def reset(self, a_estimate=None, field=0.0, output=None, magnetization=0.0, indices=None):
        """Restart systems ``indices`` (all if None).

        Parameters
        ----------
        a_estimate : float or array, optional
            thetahat(0), A/m, inside Theta (default ``config.initial_estimate``).
        field : float or array
            The applied field at the start, A/m.
        output : array, optional
            The measured plant output at the start ((n,) or (k, n) for the lumped plant,
            scalar/(k,) for the scalar plant); ``yhat`` starts there. Default 0 (at rest).
        magnetization : float or array
            M of every bank model at the start, A/m (default 0: demagnetized).
        indices : array of int or bool mask, optional
            Which systems to restart (the vector env auto-resets single sub-envs).
        """
        rows = self._rows(indices)
        count = len(rows)
        theta = self.config.initial_estimate if a_estimate is None else a_estimate
        theta = np.broadcast_to(np.asarray(theta, dtype=np.float64), (count,))
        if not np.all(np.isfinite(theta)) or np.any(theta < self._lo) or np.any(theta > self._hi):
            bad = theta[~((theta >= self._lo) & (theta <= self._hi))][0]
            raise ValueError(f"{type(self).__name__}.reset: a_estimate (thetahat(0)) = {bad!r} lies outside "
                             f"Theta = [{self._lo!r}, {self._hi!r}]")
        field = self._finite_batch(field, count, "field")
        if output is None:
            output = np.zeros((count, self._n))
        else:
            output = np.asarray(output, dtype=np.float64)
            output = np.broadcast_to(output.reshape(-1, self._n) if output.ndim else output, (count, self._n))
            if not np.all(np.isfinite(output)):
                raise ValueError(f"{type(self).__name__}.reset: output must be finite")
        self._theta[rows] = theta
        self.bank.reset(field, magnetization, rows)
        self._yhat[rows] = output
        self._y[rows] = output
        self._reset_extra(rows)
        self._refresh()

    def update(self, field, measured_output, dt: float) -> np.ndarray:
        """Advance every system by one control step; returns ``a_estimate`` (E,), A/m.

        ``field`` (E,) A/m and ``measured_output`` ((E,) or (E, 2)) are the values at the
        end of the step, ``dt`` (s, > 0) its length.
        """
        if dt != self._hold_dt:
            if not (dt > 0.0 and np.isfinite(dt)):
                raise ValueError(f"{type(self).__name__}.update: dt must be a finite number > 0 s, got {dt!r}")
            self._set_hold(float(dt))
        field = np.asarray(field, dtype=np.float64)
        if field.shape != (self.n_systems,):
            field = self._finite_batch(field, self.n_systems, "field")
        measured = np.asarray(measured_output, dtype=np.float64)
        if measured.shape != self._y.shape:
            if self._n == 1 and measured.shape == (self.n_systems,):
                measured = measured.reshape(self.n_systems, 1)
            else:
                measured = self._output_batch(measured)
        if self.law == Law.HELD:
            self._update_python(field, measured, dt)
            return self._a_estimate_view
        # Open-loop response of yhat over the step (f(thetahat) linear in time), plus the
        # saturation feedback taken implicitly, at the end of the step: with z = ytilde
        # (scalar) or B^T P ytilde (vector), z + kappa_sign(z)*sat(z/eps) = z_free. A
        # held (explicit) feedback chatters across the boundary layer as soon as
        # gain*dt exceeds eps, and the chatter biases thetahat (the two signs use
        # different phi). The parameter law then takes an Euler step with the new y_eps.
        status = estimator_step(field, measured, *self._step_tuples)
        if status:
            name = "field" if status == 1 else "measured_output"
            raise ValueError(f"{type(self).__name__}.update: {name} must be finite")
        return self._a_estimate_view

    def _update_python(self, field, measured, dt):
        """The step of a subclass law that runs in Python (:attr:`Law.HELD`)."""
        if not np.all(np.isfinite(field)):
            raise ValueError(f"{type(self).__name__}: field must be finite")
        if not np.all(np.isfinite(measured)):
            raise ValueError(f"{type(self).__name__}.update: measured_output must be finite")
        measured = np.ascontiguousarray(measured)
        self._before_advance()
        self.bank.advance(field)
        observer_step(self.bank.grid, self.bank.kernel_state.magnetization, measured, self.kernel_state,
                      self.observer_params, self._hold)
        self._y[...] = measured
        self._after_advance(measured, dt)
        self._theta[:] = self._next_theta(None, dt)
        self._refresh()

    # ------------------------------------------------------------------ internals

    def hold_params(self, dt: float) -> HoldParams:
        """The observer's exact discretization for control steps of ``dt`` s (see
        :class:`~._kernels.HoldParams`): with :attr:`kernel_state`, :attr:`observer_params` and
        the bank's, what :func:`~._kernels.estimator_step` takes (the env's fused step kernel)."""
        if dt != self._hold_dt:
            self._set_hold(float(dt))
        return self._hold

    def _set_hold(self, dt):
        phi_matrix, hold0, hold1 = hold_matrices(self._A, self._B, dt)
        # weight: how much one unit (A/m) of held feedback moves z over the step
        weight = hold0[0] if not self._vector else float(self._BP @ hold0)
        if not weight > 0:
            raise ValueError(f"{type(self).__name__}.update: dt = {dt!r} s is too long for this plant "
                             f"(B^T P G0 = {weight!r} <= 0); use a shorter control step")
        self._hold = HoldParams(float(dt), phi_matrix, hold0, hold1, weight)
        self._hold_dt = dt
        # what estimator_step takes after (field, measured); the arrays are live, changed in place
        self._step_tuples = as_kernel_tuples(self.bank.kernel_state, self.bank.kernel_params, self.kernel_state,
                                             self.observer_params, self._hold)

    def _refresh(self):
        """Bank values at thetahat, errors and the min-max solution at the current time."""
        refresh(self.bank.grid, self.bank.kernel_state.magnetization, self._y, self.kernel_state, self.observer_params)

    @property
    def _dead_zone_offset(self):
        """``lambda*eps/nu``: the dead-zone term ``+lambda*eps*sat`` of (14) written as a
        feedback gain in A/m (0 for the vector law (24), which has no such term)."""
        if self._vector:
            return 0.0
        return self.config.plant.decay_rate * self._eps / self._gain

    def _reset_extra(self, rows):
        pass

    def _before_advance(self):
        pass

    def _after_advance(self, measured, dt):
        pass

    def _rows(self, indices):
        if indices is None:
            return np.arange(self.n_systems)
        rows = np.asarray(indices)
        if rows.dtype == bool:
            if rows.shape != (self.n_systems,):
                raise ValueError(f"{type(self).__name__}.reset: boolean indices must have shape ({self.n_systems},)")
            return np.flatnonzero(rows)
        rows = rows.astype(np.int64).ravel()
        if np.any(rows < 0) or np.any(rows >= self.n_systems):
            raise ValueError(f"{type(self).__name__}.reset: indices must lie in [0, {self.n_systems}), "
                             f"got {rows.tolist()}")
        return rows

    def _finite_batch(self, value, count, name):
        array = np.asarray(value, dtype=np.float64)
        if array.ndim == 0 or array.shape == (count,):
            array = np.broadcast_to(array, (count,)).copy()
        else:
            raise ValueError(f"{type(self).__name__}: {name} must be a scalar or have shape ({count},), "
                             f"got shape {array.shape}")
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{type(self).__name__}: {name} must be finite")
        return array

    def _output_batch(self, measured):
        E, n = self._y.shape
        if n == 1 and measured.shape in ((E,), ()):
            measured = np.broadcast_to(measured, (E,)).reshape(E, 1)
        if measured.shape != (E, n):
            want = f"({E},)" if n == 1 else f"({E}, {n}) = (displacement, velocity)"
            raise ValueError(f"{type(self).__name__}.update: measured_output must have shape {want}, "
                             f"got {measured.shape}")
        if not np.all(np.isfinite(measured)):
            raise ValueError(f"{type(self).__name__}.update: measured_output must be finite")
        return measured

    def _as_theta(self, value, name, check_box=True):
        value = np.broadcast_to(np.asarray(value, dtype=np.float64), (self.n_systems,))
        if not np.all(np.isfinite(value)):
            raise ValueError(f"{type(self).__name__}: {name} must be finite")
        if check_box and (np.any(value < self._lo) or np.any(value > self._hi)):
            raise ValueError(f"{type(self).__name__}: {name} must lie in Theta = [{self._lo!r}, {self._hi!r}]")
        return np.ascontiguousarray(value)


class MinMaxEstimator(AdaptiveEstimator):
    """The min-max adaptive estimator of Nealis & Smith: scalar (14)-(15) or vector (24)-(25).

    Scalar (``FirstOrderPlant``), with ``s = sat(ytilde/eps)``::

        yhat' = -lam*(yhat - eps*s) + nu*(f(thetahat) - nu_star*s)        (14)
        (nu_star, phi_star): the min-max problem                          (15)
        thetahat' = -gamma*y_eps*nu*phi_star,   y_eps = ytilde - eps*s    (16)  (dead zone)

    Vector (``LumpedPlant``)::

        yhat' = A*yhat + B*(f(thetahat) - a_star*sat(y_eps/eps)),  y_eps = B^T P ytilde   (24)
        thetahat' = -gamma*y_eps*phi_star, (a_star, phi_star) of the min-max problem       (25)

    The law itself is :func:`~._kernels.minmax_law` (``Law.MINMAX``) followed by
    :func:`~._kernels.adaptation_step`.

    (nu_star, phi_star) / (a_star, phi_star) solve the min-max problem (15) on the bank
    in closed form (lower convex / upper concave envelope, eq. (15)), with the sign of
    ytilde (scalar) or y_eps (vector). V = y_eps^2 + theta_tilde^2/gamma (scalar) and
    V = gamma*ytilde^T P ytilde + theta_tilde^2 (vector, (26)) do not increase.
    """

    name = "minmax"
    law = Law.MINMAX


class GradientEstimator(AdaptiveEstimator):
    """Gradient adaptation: the min-max law with ``df/dtheta(thetahat)`` in place of
    phi_star and no min-max term in ``yhat`` (the baseline the paper argues against, §1).

    On convex f it coincides with the min-max law; where f(u, .) is not convex/concave
    around thetahat the linearization error ``f(thetahat) - f(a) - f'(thetahat)*theta_tilde``
    can make V grow, so the estimate may drift or go unstable.
    """

    name = "gradient"
    law = Law.GRADIENT


class MultipleModelEstimator(AdaptiveEstimator):
    """Output-error least squares over the bank (a multiple-model estimator).

    Why this baseline: every bank node already *is* a candidate plant, so running the
    plant model once per node (E x G linear filters, cheap beside the hysteresis bank)
    gives each candidate's predicted output. The estimate minimizes the exponentially
    forgotten squared output error over Theta: the node of least cost refined by a
    parabola through its neighbours. This is the nonlinear least-squares estimate
    restricted to the grid; unlike the gradient and min-max laws it searches Theta
    globally, so it cannot be trapped or pushed away by a nonconvex f, needs no gain
    tuned to the size of df/dtheta, and tracks drift through its forgetting time. An
    EKF on the bank would linearize f(u, .) around thetahat and inherit the gradient
    law's nonconvexity problem; immersion-and-invariance needs an analytic f. Its cost
    is resolution (grid + parabola) and G filters per system.

    ``yhat`` (and so ``tuning_error``) follows the gradient-form observer driven by
    f(thetahat); the parameter ignores gamma.

    Parameters
    ----------
    memory_s : float
        Forgetting time constant of the squared output error, s (> 0).
    """

    name = "multiple_model"
    law = Law.HELD

    def __init__(self, config: EstimatorConfig, n_systems: int = 1, memory_s: float = 1.0):
        if not (np.isfinite(memory_s) and memory_s > 0):
            raise ValueError(f"MultipleModelEstimator: memory_s must be a finite number > 0 s, got {memory_s!r}")
        self.memory_s = float(memory_s)
        G = config.grid_size
        E = int(n_systems) if isinstance(n_systems, (int, np.integer)) else 1
        n = config.plant.output_size
        self._node_output = np.zeros((E, G, n))
        self._cost = np.zeros((E, G))
        self._nodes_start = np.zeros((E, G))
        if config.is_vector:
            # weight velocity by 1/omega_n so both components are in metres
            self._weight = np.array([1.0, 1.0 / np.sqrt(abs(np.linalg.det(config.plant.state_matrix)))])
        else:
            self._weight = np.ones(1)
        super().__init__(config, n_systems)

    def _reset_extra(self, rows):
        self._node_output[rows] = self._y[rows][:, None, :]
        self._cost[rows] = 0.0

    def _before_advance(self):
        self._nodes_start[...] = self.bank._magnetization

    def _after_advance(self, measured, dt):
        hold = self._hold
        nodes_end = self.bank._magnetization
        self._node_output = (self._node_output @ hold.transition.T + self._nodes_start[..., None] * hold.hold0
                             + (nodes_end - self._nodes_start)[..., None] * hold.hold1)
        residual = (self._node_output - measured.reshape(self.n_systems, 1, -1)) * self._weight
        forget = np.exp(-dt / self.memory_s)
        self._cost = forget * self._cost + (1.0 - forget) * np.sum(residual ** 2, axis=2)

    def _next_theta(self, theta_rate, dt):
        cost = self._cost
        best = np.argmin(cost, axis=1)
        rows = np.arange(self.n_systems)
        G = cost.shape[1]
        inner = np.clip(best, 1, G - 2)
        left, mid, right = cost[rows, inner - 1], cost[rows, inner], cost[rows, inner + 1]
        curvature = left - 2.0 * mid + right
        with np.errstate(divide="ignore", invalid="ignore"):
            offset = np.where(curvature > 0, 0.5 * (left - right) / curvature, 0.0)
        offset = np.where(best == inner, np.clip(offset, -0.5, 0.5), 0.0)
        grid = self.bank.grid
        spacing = grid[1] - grid[0]
        estimate = grid[best] + offset * spacing
        informative = np.ptp(cost, axis=1) > 0.0  # all nodes agree: no information yet
        return np.clip(np.where(informative, estimate, self._theta), self._lo, self._hi)


ESTIMATORS = {cls.name: cls for cls in (MinMaxEstimator, GradientEstimator, MultipleModelEstimator)}


def make_estimator(name: str, config: EstimatorConfig, n_systems: int = 1, **options) -> AdaptiveEstimator:
    """Build an estimator by name: ``"minmax"``, ``"gradient"`` or ``"multiple_model"``."""
    try:
        cls = ESTIMATORS[name]
    except KeyError:
        raise ValueError(f"unknown estimator {name!r}; expected one of {sorted(ESTIMATORS)}") from None
    return cls(config, n_systems, **options)


__all__ = ["AdaptiveEstimator", "ESTIMATORS", "GradientEstimator", "Law", "MinMaxEstimator",
           "MultipleModelEstimator", "hold_matrices", "make_estimator"]
