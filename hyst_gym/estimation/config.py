"""Frozen, validated settings of the adaptive estimators (Nealis & Smith §3).

Two plant models are supported; each is the model the *estimator* assumes for the
output dynamics (the true plant may differ):

* :class:`~hyst_gym.physics.transducers.FirstOrderPlant` -- ``y' = -lambda*y + nu*M(H; a)``
  (``decay_rate``, ``gain``; §3.1, §4.1), output ``y`` (E,);
* :class:`LumpedPlant` -- the linearized lumped transducer (13) written as
  ``y' = A*y + B*M(H; a)`` with ``y = (displacement m, velocity m/s)`` (§3.2, §4.2),
  output (E, 2).

:class:`EstimatorConfig` holds the parameter box Theta, the bank grid, the dead-zone
width ``eps`` and gain ``gamma`` of (14)/(24), the hysteresis parameters other than
``a`` and the accuracy of the hysteresis integration.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from ..physics.constants import PAPER_COUPLING, PAPER_DAMPING, PAPER_STIFFNESS
from ..physics.hysteresis import DEFAULT_MAX_FIELD_STEP, HysteresisParams
from ..physics.transducers import FirstOrderPlant

#: Lumped-model coefficients (13) from the paper, §2.2, under the estimation layer's names
#: (the paper's hats); the values are the physics layer's.
PAPER_KHAT = PAPER_STIFFNESS  # 1/s^2
PAPER_CHAT = PAPER_DAMPING  # 1/s
PAPER_ZETAHAT = PAPER_COUPLING  # m s^-2 per A/m
#: The paper's Lyapunov weight for the vector estimator, §4.2.
PAPER_Q = ((1.0e10, 0.0), (0.0, 1.0e-8))

#: Grid sizes the bank accepts.
MIN_GRID_SIZE = 16
MAX_GRID_SIZE = 128


def _finite(value, name, owner):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{owner}: {name} must be a number, got {value!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{owner}: {name} must be finite, got {value!r}")
    return value


@dataclass(frozen=True)
class LumpedPlant:
    """Linear plant ``y' = A*y + B*M`` assumed by the vector estimator (24)-(25).

    For the lumped transducer (13), ``x'' + chat*x' + khat*x = zetahat*M``, the state is
    ``y = (x [m], x' [m/s])``, ``A = [[0, 1], [-khat, -chat]]`` and ``B = (0, zetahat)``
    (build it with :meth:`from_coefficients`; the defaults are the paper's values).

    Attributes
    ----------
    A : tuple of tuples, 2x2
        State matrix, 1/s and 1/s^2; must be Hurwitz (the Lyapunov equation needs it).
    B : tuple, length 2
        Input vector, state units per second per A/m.
    Q : tuple of tuples, 2x2
        Symmetric positive-definite weight of ``A^T P + P A = -Q``. Paper §4.2:
        ``diag(1e10, 1e-8)``.
    """

    A: tuple = ((0.0, 1.0), (-PAPER_KHAT, -PAPER_CHAT))
    B: tuple = (0.0, PAPER_ZETAHAT)
    Q: tuple = PAPER_Q

    def __post_init__(self):
        owner = "LumpedPlant"
        A = _matrix(self.A, (2, 2), "A", owner)
        B = _matrix(self.B, (2,), "B", owner)
        Q = _matrix(self.Q, (2, 2), "Q", owner)
        eigenvalues = np.linalg.eigvals(A)
        if not np.all(eigenvalues.real < 0):
            raise ValueError(f"{owner}: A must be Hurwitz (all eigenvalues with negative real part), "
                             f"got eigenvalues {np.round(eigenvalues, 6).tolist()}")
        if not np.any(B != 0):
            raise ValueError(f"{owner}: B must not be zero")
        if not np.allclose(Q, Q.T, rtol=1e-12, atol=0.0):
            raise ValueError(f"{owner}: Q must be symmetric, got {Q.tolist()}")
        if not np.all(np.linalg.eigvalsh(Q) > 0):
            raise ValueError(f"{owner}: Q must be positive definite, got {Q.tolist()}")
        object.__setattr__(self, "A", tuple(map(tuple, A.tolist())))
        object.__setattr__(self, "B", tuple(B.tolist()))
        object.__setattr__(self, "Q", tuple(map(tuple, Q.tolist())))

    @classmethod
    def from_coefficients(cls, khat=PAPER_KHAT, chat=PAPER_CHAT, zetahat=PAPER_ZETAHAT, Q=PAPER_Q):
        """The lumped model (13) ``x'' + chat*x' + khat*x = zetahat*M`` (khat 1/s^2, chat 1/s)."""
        return cls(((0.0, 1.0), (-float(khat), -float(chat))), (0.0, float(zetahat)), Q)

    @property
    def output_size(self) -> int:
        return 2

    @property
    def state_matrix(self) -> np.ndarray:
        return np.array(self.A)

    @property
    def input_matrix(self) -> np.ndarray:
        return np.array(self.B)

    @property
    def lyapunov_matrix(self) -> np.ndarray:
        """P solving ``A^T P + P A = -Q`` (symmetric positive definite since A is Hurwitz)."""
        A = self.state_matrix
        P = scipy.linalg.solve_continuous_lyapunov(A.T, -np.array(self.Q))
        return 0.5 * (P + P.T)


def _matrix(value, shape, name, owner):
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{owner}: {name} must be numeric with shape {shape}, got {value!r}") from None
    if array.shape != shape:
        raise ValueError(f"{owner}: {name} must have shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{owner}: {name} must be finite, got {array.tolist()}")
    return array


#: Default dead-zone width eps (units of the tuning error) and adaptation gain gamma per
#: plant model: the paper's §4.1 case (scalar, gamma = 1) and §4.2 case (vector, gamma from
#: the paper, eps = 1e-8 in units of y_eps = B^T P ytilde) (see README, section estimation).
PLANT_DEFAULTS = {FirstOrderPlant: {"eps": 0.01, "gamma": 1.0}, LumpedPlant: {"eps": 1e-8, "gamma": 5e10}}


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings shared by every estimator of :mod:`hyst_gym.estimation`.

    Attributes
    ----------
    theta_min, theta_max : float
        The parameter box Theta = [theta_min, theta_max] for ``a``, A/m. Paper §4: [6300, 7300].
    initial_estimate : float
        thetahat(0), A/m, inside Theta. Paper §4: 6990. ``reset`` may override it.
    grid_size : int
        Number G of bank models, evenly spaced over Theta, 16..128.
    eps : float or None
        Width of the saturation / dead zone of (14) and (24), units of the tuning error
        (y for the scalar plant, ``B^T P ytilde`` for the lumped plant); > 0. ``None``:
        the plant's default in :data:`PLANT_DEFAULTS`.
    gamma : float or None
        Adaptation gain of ``thetahat' = -gamma*y_eps*phi_star``, > 0. ``None``: the
        plant's default in :data:`PLANT_DEFAULTS` (1 for the scalar case, 5e10 for the vector case).
    plant : FirstOrderPlant or LumpedPlant
        The output dynamics the estimator assumes.
    hysteresis : HysteresisParams
        Parameters of the hysteresis model (6) of every bank model; its ``a`` is ignored
        (``a`` is what the bank spans).
    max_field_step : float
        Largest field substep of the hysteresis integration, A/m (> 0).
    pe_window : int
        Length, in control steps, of the sliding window of the 3.1(a)/(b) test (>= 2).
    """

    theta_min: float = 6300.0
    theta_max: float = 7300.0
    initial_estimate: float = 6990.0
    grid_size: int = 64
    eps: float | None = None
    gamma: float | None = None
    plant: FirstOrderPlant | LumpedPlant = field(default_factory=FirstOrderPlant)
    hysteresis: HysteresisParams = field(default_factory=HysteresisParams)
    max_field_step: float = DEFAULT_MAX_FIELD_STEP
    pe_window: int = 200

    def __post_init__(self):
        owner = "EstimatorConfig"
        lo = _finite(self.theta_min, "theta_min", owner)
        hi = _finite(self.theta_max, "theta_max", owner)
        if not hi > lo:
            raise ValueError(f"{owner}: Theta = [theta_min, theta_max] = [{lo!r}, {hi!r}] is empty; "
                             f"need theta_min < theta_max")
        if lo <= 0:
            raise ValueError(f"{owner}: theta_min must be > 0 A/m (a is positive), got {lo!r}")
        initial = _finite(self.initial_estimate, "initial_estimate", owner)
        if not lo <= initial <= hi:
            raise ValueError(f"{owner}: initial_estimate (thetahat(0)) = {initial!r} lies outside "
                             f"Theta = [{lo!r}, {hi!r}]")
        if isinstance(self.grid_size, bool) or not isinstance(self.grid_size, (int, np.integer)):
            raise ValueError(f"{owner}: grid_size must be an integer, got {self.grid_size!r}")
        if not MIN_GRID_SIZE <= int(self.grid_size) <= MAX_GRID_SIZE:
            raise ValueError(f"{owner}: grid_size must be between {MIN_GRID_SIZE} and {MAX_GRID_SIZE}, "
                             f"got {self.grid_size!r}")
        if not isinstance(self.plant, (FirstOrderPlant, LumpedPlant)):
            raise ValueError(f"{owner}: plant must be a FirstOrderPlant or LumpedPlant, "
                             f"got {type(self.plant).__name__}")
        if not isinstance(self.hysteresis, HysteresisParams):
            raise ValueError(f"{owner}: hysteresis must be a HysteresisParams, got {type(self.hysteresis).__name__}")
        if isinstance(self.plant, FirstOrderPlant) and not self.plant.gain > 0:
            raise ValueError(f"{owner}: the scalar plant's gain nu must be > 0 for the estimator (14), "
                             f"got {self.plant.gain!r}")
        defaults = PLANT_DEFAULTS[type(self.plant)]
        eps = defaults["eps"] if self.eps is None else _finite(self.eps, "eps", owner)
        if eps <= 0:
            raise ValueError(f"{owner}: eps must be > 0 (dead-zone width), got {eps!r}")
        gamma = defaults["gamma"] if self.gamma is None else _finite(self.gamma, "gamma", owner)
        if gamma <= 0:
            raise ValueError(f"{owner}: gamma must be > 0 (adaptation gain), got {gamma!r}")
        step = _finite(self.max_field_step, "max_field_step", owner)
        if step <= 0:
            raise ValueError(f"{owner}: max_field_step must be > 0 A/m, got {step!r}")
        if isinstance(self.pe_window, bool) or not isinstance(self.pe_window, (int, np.integer)) \
                or self.pe_window < 2:
            raise ValueError(f"{owner}: pe_window must be an integer >= 2 (control steps), got {self.pe_window!r}")
        # Every bank model must be a valid hysteresis model.
        for a in (lo, hi):
            self.hysteresis.replace(a=a)
        for name, value in (("theta_min", lo), ("theta_max", hi), ("initial_estimate", initial),
                            ("eps", eps), ("gamma", gamma), ("max_field_step", step)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "grid_size", int(self.grid_size))
        object.__setattr__(self, "pe_window", int(self.pe_window))

    @property
    def theta_grid(self) -> np.ndarray:
        """The G bank nodes over Theta, A/m (``np.linspace``: both ends exact)."""
        return np.linspace(self.theta_min, self.theta_max, self.grid_size)

    @property
    def is_vector(self) -> bool:
        return isinstance(self.plant, LumpedPlant)

    def replace(self, **changes) -> "EstimatorConfig":
        """A validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    @classmethod
    def paper_scalar(cls, **changes) -> "EstimatorConfig":
        """§4.1: ``y' = -100*y + M``, Theta = [6300, 7300], thetahat(0) = 6990, gamma = 1."""
        return cls(plant=FirstOrderPlant(100.0, 1.0), **changes)

    @classmethod
    def paper_vector(cls, **changes) -> "EstimatorConfig":
        """§4.2: lumped model (13), Q = diag(1e10, 1e-8), gamma = 5e10, same Theta."""
        return cls(plant=LumpedPlant.from_coefficients(), **changes)


__all__ = ["EstimatorConfig", "FirstOrderPlant", "LumpedPlant", "MIN_GRID_SIZE", "MAX_GRID_SIZE", "PLANT_DEFAULTS",
           "PAPER_CHAT", "PAPER_KHAT", "PAPER_Q", "PAPER_ZETAHAT"]
