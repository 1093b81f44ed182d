"""Exact discretization of linear time-invariant mechanics driven by the magnetization.

Every transducer model of this package has the form::

    z' = A z + b u(t),      u = gain * M        (linear drive, eqs. 13 and first-order plant)
                            u = gain * M**2     (quadratic drive, eqs. 10 and 12)

with ``z`` the mechanical state (displacements and velocities) and ``M`` the
magnetization in A/m. Over one control period ``dt`` the drive ``u`` is taken as
linear between its values at the two ends of the period (first-order hold). The
state then moves *exactly* (up to rounding) by::

    z[k+1] = Phi z[k] + Gamma0 u[k] + Gamma1 u[k+1]

where ``Phi``, ``Gamma0`` and ``Gamma1`` come from one matrix exponential of an
augmented matrix (Van Loan's construction). The update is unconditionally stable
(``Phi`` inherits the damping of ``A``) however stiff ``A`` is, so one control step is
one matrix-vector product, whatever the finite-element rod's highest mode.

The nonlinearity of the transducer is confined to ``M(H)`` (and the square of a
quadratic drive); nothing nonlinear is ever integrated here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numba import njit

LINEAR_DRIVE = "linear"
QUADRATIC_DRIVE = "quadratic"
#: above this state size the update uses BLAS (numpy matmul) instead of the numba loop
_BLAS_THRESHOLD = 16


def first_order_hold(A, b, dt, scale=None):
    """Return ``(Phi, Gamma0, Gamma1)`` of ``z' = A z + b u`` with ``u`` linear over ``dt``.

    ``z[k+1] = Phi z[k] + Gamma0 u[k] + Gamma1 u[k+1]``. ``scale`` (optional, shape ``(n,)``)
    is a diagonal similarity applied before the exponential to balance states of very
    different size (metres against m/s); the result is transformed back, so it changes only
    rounding, not the answer.
    """
    phi, hold, ramp = hold_and_ramp(A, b, dt, scale)
    return phi, hold - ramp, ramp


def hold_and_ramp(A, b, dt, scale=None):
    """The same exact discretization in the increment form ``(Phi, Hold, Ramp)``:
    ``z[k+1] = Phi z[k] + Hold u[k] + Ramp (u[k+1] - u[k])`` (Hold is the zero-order hold,
    Ramp the response to a unit increment spread linearly over the step). The one
    place the matrix exponential of a linear system is taken; ``scale`` as above.
    """
    A = np.asarray(A, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64).reshape(-1)
    n = A.shape[0]
    if scale is None:
        scale = np.ones(n)
    scale = np.asarray(scale, dtype=np.float64)
    A_s = A * (1.0 / scale)[:, None] * scale[None, :]
    b_s = b / scale
    # Time is measured in periods (tau = t/dt); the augmented states are u and
    # du/dtau = u[k+1] - u[k], so the blocks come out already divided by dt.
    augmented = np.zeros((n + 2, n + 2))
    augmented[:n, :n] = A_s * dt
    augmented[:n, n] = b_s * dt
    augmented[n, n + 1] = 1.0
    exponential = scipy.linalg.expm(augmented)
    phi_s = exponential[:n, :n]
    hold = exponential[:n, n]        # response to a constant u[k]
    ramp = exponential[:n, n + 1]    # response to the increment u[k+1] - u[k]
    phi = phi_s * scale[:, None] * (1.0 / scale)[None, :]
    return phi, hold * scale, ramp * scale


@njit(cache=True, inline="always")
def lti_step(phi, gamma0, gamma1, state, u0, u1, out):
    """One first-order-hold step of one system: ``out = phi state + gamma0 u0 + gamma1 u1``.

    The stepping loop of every linear system of the package (transducers, the batched
    env plant, the mismatch tool's mechanics and sensors); ``out`` may not be ``state``."""
    n_state = phi.shape[0]
    for i in range(n_state):
        acc = gamma0[i] * u0 + gamma1[i] * u1
        for j in range(n_state):
            acc += phi[i, j] * state[j]
        out[i] = acc


@njit(cache=True)
def _advance_small(phi, gamma0, gamma1, state, u0, u1, out):
    for s in range(state.shape[0]):
        lti_step(phi, gamma0, gamma1, state[s], u0[s], u1[s], out[s])


@dataclass(frozen=True, eq=False)
class DiscreteTransducer:
    """A transducer model discretized for a fixed control period ``dt`` (s).

    Made by the ``discretize(dt)`` method of a transducer parameter class
    (:class:`~hyst_gym.physics.transducers.FirstOrderPlant`,
    :class:`~hyst_gym.physics.transducers.LumpedLinear`,
    :class:`~hyst_gym.physics.transducers.LumpedNonlinear`,
    :class:`~hyst_gym.physics.fem.FEMRod`). Works over a leading batch axis of
    independent systems that share these parameters: states have shape
    ``(n_systems, state_size)``.

    Attributes
    ----------
    dt : float
        Control period, s.
    phi, gamma0, gamma1 : ndarray
        Exact first-order-hold update ``z1 = phi z0 + gamma0 u0 + gamma1 u1``.
    drive : str
        ``"linear"`` (``u = drive_gain*M``) or ``"quadratic"`` (``u = drive_gain*M**2``).
    drive_gain : float
        Units such that ``u`` is in the units of ``b`` in ``z' = A z + b u``.
    output_index : int
        Index of the state component returned by :meth:`output` (tip displacement in
        m for the mechanical models, ``y`` for the first-order plant).
    velocity_index : int or None
        Index of the tip velocity (m/s), if the model has one.
    output_offset : float
        Added to the output; 0 unless documented by the model that made it.
    static_response : ndarray
        Rest state per unit drive ``u`` (``-A^-1 b``).
    """

    dt: float
    phi: np.ndarray
    gamma0: np.ndarray
    gamma1: np.ndarray
    drive: str
    drive_gain: float
    output_index: int
    velocity_index: int | None = None
    output_offset: float = 0.0
    name: str = "transducer"
    static_response: np.ndarray | None = None

    def __post_init__(self):
        if self.static_response is None:
            # equilibrium per unit drive from the discrete map; models that know their
            # continuous A, b pass -A^-1 b instead (better conditioned for stiff rods)
            static = np.linalg.solve(np.eye(np.shape(self.phi)[0]) - np.asarray(self.phi),
                                     np.asarray(self.gamma0) + np.asarray(self.gamma1))
            object.__setattr__(self, "static_response", static)
        for attr in ("phi", "gamma0", "gamma1", "static_response"):
            arr = np.array(getattr(self, attr), dtype=np.float64)
            arr.setflags(write=False)
            object.__setattr__(self, attr, arr)
        if self.drive not in (LINEAR_DRIVE, QUADRATIC_DRIVE):
            raise ValueError(f"{self.name}: drive must be 'linear' or 'quadratic', got {self.drive!r}")

    @property
    def state_size(self) -> int:
        return self.phi.shape[0]

    def drive_of(self, magnetization):
        """The forcing ``u`` (units of ``b``) for a magnetization M (A/m)."""
        magnetization = np.asarray(magnetization, dtype=np.float64)
        if self.drive == QUADRATIC_DRIVE:
            return self.drive_gain * magnetization * magnetization
        return self.drive_gain * magnetization

    def initial_state(self, n_systems: int = 1) -> np.ndarray:
        """At rest at the origin: zeros of shape ``(n_systems, state_size)``."""
        n_systems = int(n_systems)
        if n_systems < 1:
            raise ValueError(f"{self.name}: n_systems must be >= 1, got {n_systems}")
        return np.zeros((n_systems, self.state_size))

    def steady_state(self, magnetization) -> np.ndarray:
        """The equilibrium under a constant magnetization (A/m), one row per value.

        ``z = static_response * u``: the rest state of ``z' = A z + b u`` (velocities 0);
        useful to start at a bias.
        """
        u = np.atleast_1d(self.drive_of(magnetization)).ravel()
        return np.outer(u, self.static_response)

    def advance(self, state, magnetization_start, magnetization_end, out=None) -> np.ndarray:
        """State after one control period.

        Parameters
        ----------
        state : ndarray, shape (n_systems, state_size)
        magnetization_start, magnetization_end : float or ndarray, shape (n_systems,)
            M (A/m) at the start and the end of the period; the drive is linear in
            between (first-order hold).
        out : ndarray, optional
            Where to write the result (may not be ``state``).

        Returns
        -------
        ndarray, shape (n_systems, state_size)
        """
        state = np.asarray(state, dtype=np.float64)
        if state.ndim != 2 or state.shape[1] != self.state_size:
            raise ValueError(f"{self.name}: state must have shape (n_systems, {self.state_size}), "
                             f"got {state.shape}")
        n_systems = state.shape[0]
        u0 = np.ascontiguousarray(np.broadcast_to(self.drive_of(magnetization_start), (n_systems,)))
        u1 = np.ascontiguousarray(np.broadcast_to(self.drive_of(magnetization_end), (n_systems,)))
        if out is None:
            out = np.empty_like(state)
        if self.state_size <= _BLAS_THRESHOLD:
            _advance_small(self.phi, self.gamma0, self.gamma1, np.ascontiguousarray(state), u0, u1, out)
        else:
            np.matmul(state, self.phi.T, out=out)
            out += u0[:, None] * self.gamma0[None, :]
            out += u1[:, None] * self.gamma1[None, :]
        return out

    def output(self, state) -> np.ndarray:
        """Tip displacement (m) or plant output ``y``, shape ``(n_systems,)``."""
        return np.asarray(state)[:, self.output_index] + self.output_offset

    def velocity(self, state) -> np.ndarray:
        """Tip velocity (m/s), shape ``(n_systems,)``."""
        if self.velocity_index is None:
            raise ValueError(f"{self.name}: this model has no velocity state")
        return np.asarray(state)[:, self.velocity_index]

    def simulate(self, magnetization, state0=None) -> np.ndarray:
        """Outputs at every sample of a magnetization history sampled every ``dt``.

        ``magnetization`` has shape ``(T,)`` or ``(T, n_systems)`` (A/m). Starts at rest
        (or at ``state0``); returns outputs of the same shape as ``magnetization``.
        """
        magnetization = np.asarray(magnetization, dtype=np.float64)
        single = magnetization.ndim == 1
        history = magnetization[:, None] if single else magnetization
        n_samples, n_systems = history.shape
        state = self.initial_state(n_systems) if state0 is None else np.array(state0, dtype=np.float64)
        outputs = np.empty((n_samples, n_systems))
        outputs[0] = self.output(state)
        scratch = np.empty_like(state)
        for t in range(1, n_samples):
            self.advance(state, history[t - 1], history[t], out=scratch)
            state, scratch = scratch, state
            outputs[t] = self.output(state)
        return outputs[:, 0] if single else outputs


def simulate_sampled(params, time, magnetization, state0=None, rel_tol: float = 1e-9) -> np.ndarray:
    """Outputs of a transducer model at arbitrary (increasing) sample times.

    ``params`` is any transducer parameter object with ``discretize(dt)``. The drive is
    linear between samples. Steps whose lengths agree to ``rel_tol`` share one
    discretization, so a uniformly sampled record costs one matrix exponential.
    ``magnetization`` has shape ``(T,)`` or ``(T, n_systems)`` (A/m); ``time`` (s) has
    shape ``(T,)``. Starts at rest unless ``state0`` is given.
    """
    time = np.asarray(time, dtype=np.float64)
    magnetization = np.asarray(magnetization, dtype=np.float64)
    if time.ndim != 1 or time.shape[0] != magnetization.shape[0] or time.shape[0] == 0:
        raise ValueError(f"time must be a non-empty 1-D array as long as magnetization, got shapes "
                         f"{time.shape} and {magnetization.shape}")
    steps = np.diff(time)
    if not (np.all(np.isfinite(time)) and np.all(steps > 0)):
        raise ValueError("time must be finite and strictly increasing")
    if not np.all(np.isfinite(magnetization)):
        raise ValueError("magnetization must be finite")
    single = magnetization.ndim == 1
    history = magnetization[:, None] if single else magnetization
    n_samples, n_systems = history.shape
    models: dict[float, DiscreteTransducer] = {}
    keys = []
    for dt in steps:
        key = next((k for k in models if abs(k - dt) <= rel_tol * k), None)
        if key is None:
            key = float(dt)
            models[key] = params.discretize(key)
        keys.append(key)
    first = models[keys[0]] if keys else params.discretize(1.0)
    state = first.initial_state(n_systems) if state0 is None else np.array(state0, dtype=np.float64)
    outputs = np.empty((n_samples, n_systems))
    outputs[0] = first.output(state)
    for t, key in enumerate(keys, start=1):
        state = models[key].advance(state, history[t - 1], history[t])
        outputs[t] = models[key].output(state)
    return outputs[:, 0] if single else outputs


__all__ = ["DiscreteTransducer", "LINEAR_DRIVE", "QUADRATIC_DRIVE", "first_order_hold", "hold_and_ramp", "lti_step",
           "simulate_sampled"]
