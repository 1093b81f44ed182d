"""Transducer models driven by the magnetization M (A/m): eqs. (12), (13) and the scalar plant.

Every model here is a frozen parameter dataclass with ``discretize(dt)``, which returns
a :class:`~hyst_gym.physics.linear_system.DiscreteTransducer` that advances a batch of
independent systems exactly over one control period ``dt`` (first-order hold on the
drive, see :mod:`~hyst_gym.physics.linear_system`)::

    model = LumpedLinear().discretize(1e-4)
    state = model.initial_state(n_systems)
    state = model.advance(state, magnetization_start, magnetization_end)
    displacement = model.output(state)                  # m

Models
------
:class:`FirstOrderPlant`
    ``y' = -lambda*y + nu*M`` (paper §3.1; lambda = 100 1/s, nu = 1). Output ``y``.
:class:`LumpedLinear`
    (13) ``x'' + chat*x' + khat*x = zetahat*M`` with the paper's chat = 7.8899e3 1/s,
    khat = 6.4251e7 1/s^2, zetahat = 1.3724e-2 m/s^2 per A/m. Output x (m).
:class:`LumpedNonlinear`
    (12) ``m*x'' + c*x' + k*x = zeta*M**2`` with quadratic magnetostriction; by default
    lumped from the rod data of :class:`RodParams`. Output x (m).
:class:`~hyst_gym.physics.fem.FEMRod`
    the finite-element rod (10), in :mod:`~hyst_gym.physics.fem`.

The rod data and the bias
-------------------------
:class:`RodParams` holds the Terfenol-D rod of the paper's §2.2. Lumping it with the rod's
static (linear) mode shape gives ``m = ML + rho*A*L/3``, ``k = kL + Y*A/L``,
``c = cL + cD*A/L`` and the tip forcing ``zeta*M**2`` with ``zeta = Y*A*gamma`` and
``gamma = (3/2)*lambda_s/Ms**2``. Linearizing ``zeta*M**2`` about a bias ``M0``,
``zeta*M**2 ~ 2*zeta*M0*M - zeta*M0**2``, gives (13) with ``zetahat = 2*zeta*M0/m``; the
displacement of (13) is then that of (12) plus the constant ``zeta*M0**2/k``.
:meth:`RodParams.bias_magnetization` returns the ``M0`` that reproduces the paper's
``zetahat``: **M0 = 3.839e5 A/m** (about 0.50 Ms) with the default data.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .constants import PAPER_COUPLING, PAPER_DAMPING, PAPER_STIFFNESS
from .linear_system import LINEAR_DRIVE, QUADRATIC_DRIVE, DiscreteTransducer, first_order_hold, simulate_sampled



def check_positive(owner, **values):
    """Raise ``ValueError`` unless every value is a finite number > 0."""
    for name, value in values.items():
        if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value) and value > 0):
            raise ValueError(f"{owner}: {name} must be a finite number > 0, got {value!r}")


def check_nonnegative(owner, **values):
    for name, value in values.items():
        if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value) and value >= 0):
            raise ValueError(f"{owner}: {name} must be a finite number >= 0, got {value!r}")


def check_dt(owner, dt):
    check_positive(owner, dt=dt)
    return float(dt)


class _Transducer:
    """Shared conveniences of the transducer parameter classes."""

    def discretize(self, dt: float) -> DiscreteTransducer:  # pragma: no cover - abstract
        raise NotImplementedError

    def simulate(self, time, magnetization, state0=None) -> np.ndarray:
        """Output (m, or ``y``) at every sample of ``time`` (s) under ``magnetization`` (A/m).

        ``magnetization`` has shape ``(T,)`` or ``(T, n_systems)``; the drive is linear
        between samples; starts at rest unless ``state0`` is given. Non-uniform sampling
        is allowed (one discretization per distinct step length).
        """
        return simulate_sampled(self, time, magnetization, state0)

    def replace(self, **changes):
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class RodParams:
    """Terfenol-D rod with a tip mass, spring and damper (paper §2.2, Fig. 3, eq. 10).

    Attributes
    ----------
    Y : float
        Young's modulus, Pa.
    rho : float
        Density, kg/m^3.
    L : float
        Rod length, m.
    A : float
        Cross-section, m^2.
    cD : float
        Kelvin-Voigt damping coefficient, N s/m^2 (Pa s).
    ML : float
        Tip point mass, kg.
    kL : float
        Tip spring stiffness, N/m.
    cL : float
        Tip damper, N s/m.
    saturation_magnetostriction : float
        lambda_s, dimensionless (about 1e-3 for Terfenol-D).
    Ms : float
        Saturation magnetization used in ``gamma``, A/m.
    """

    Y: float = 3.0e10
    rho: float = 9250.0
    L: float = 0.115
    A: float = 1.2668e-4
    cD: float = 3.0e6
    ML: float = 0.5
    kL: float = 2.0e6
    cL: float = 1.0e3
    saturation_magnetostriction: float = 1.0e-3
    Ms: float = 7.65e5

    def __post_init__(self):
        check_positive("RodParams", Y=self.Y, rho=self.rho, L=self.L, A=self.A,
                       saturation_magnetostriction=self.saturation_magnetostriction, Ms=self.Ms)
        check_nonnegative("RodParams", cD=self.cD, ML=self.ML, kL=self.kL, cL=self.cL)

    @property
    def gamma(self) -> float:
        """Magnetoelastic coupling of the strain ``gamma*M**2``, (A/m)^-2: ``(3/2)*lambda_s/Ms**2``."""
        return 1.5 * self.saturation_magnetostriction / self.Ms ** 2

    @property
    def force_coefficient(self) -> float:
        """``zeta = Y*A*gamma``: tip force per M**2, N/(A/m)^2."""
        return self.Y * self.A * self.gamma

    @property
    def wave_speed(self) -> float:
        """Longitudinal wave speed ``sqrt(Y/rho)``, m/s."""
        return math.sqrt(self.Y / self.rho)

    @property
    def lumped_mass(self) -> float:
        """``ML + rho*A*L/3``, kg."""
        return self.ML + self.rho * self.A * self.L / 3.0

    @property
    def lumped_stiffness(self) -> float:
        """``kL + Y*A/L``, N/m."""
        return self.kL + self.Y * self.A / self.L

    @property
    def lumped_damping(self) -> float:
        """``cL + cD*A/L``, N s/m."""
        return self.cL + self.cD * self.A / self.L

    def bias_magnetization(self, coupling: float = PAPER_COUPLING) -> float:
        """The bias M0 (A/m) at which linearizing (12) gives ``zetahat = coupling``.

        ``zetahat = 2*zeta*M0/m``, so ``M0 = zetahat*m/(2*zeta)``; 3.839e5 A/m by default.
        """
        check_positive("RodParams.bias_magnetization", coupling=coupling)
        return coupling * self.lumped_mass / (2.0 * self.force_coefficient)

    def replace(self, **changes) -> "RodParams":
        return dataclasses.replace(self, **changes)


#: the bias M0 (A/m) that links (12) to (13) with the default rod data (about 3.84e5)
DEFAULT_BIAS_MAGNETIZATION = RodParams().bias_magnetization()


@dataclass(frozen=True)
class FirstOrderPlant(_Transducer):
    """The scalar plant ``y' = -lambda*y + nu*M`` of the paper's first example (§3.1).

    The one first-order plant of the package: the true plant of the environments, the
    model the scalar estimator (14) assumes, and the filter of the Fisher information.

    Attributes
    ----------
    decay_rate : float
        lambda, 1/s (> 0). Paper: 100.
    gain : float
        nu, (units of y)/s per A/m. Paper: 1.
    """

    decay_rate: float = 100.0
    gain: float = 1.0

    def __post_init__(self):
        check_positive("FirstOrderPlant", decay_rate=self.decay_rate)
        if not math.isfinite(self.gain):
            raise ValueError(f"FirstOrderPlant: gain must be finite, got {self.gain!r}")

    def discretize(self, dt: float) -> DiscreteTransducer:
        dt = check_dt("FirstOrderPlant.discretize", dt)
        phi, g0, g1 = first_order_hold(np.array([[-self.decay_rate]]), np.array([1.0]), dt)
        return DiscreteTransducer(dt, phi, g0, g1, LINEAR_DRIVE, float(self.gain), 0, None,
                                  name="FirstOrderPlant", static_response=np.array([1.0 / self.decay_rate]))

    @property
    def output_size(self) -> int:
        """One output, ``y``."""
        return 1

    @property
    def state_matrix(self) -> np.ndarray:
        """A of ``y' = A y + B M``: ``[[-lambda]]``, 1/s."""
        return np.array([[-self.decay_rate]], dtype=np.float64)

    @property
    def input_matrix(self) -> np.ndarray:
        """B of ``y' = A y + B M``: ``[nu]``."""
        return np.array([self.gain], dtype=np.float64)


@dataclass(frozen=True)
class LumpedLinear(_Transducer):
    """The linearized lumped transducer (13): ``x'' + chat*x' + khat*x = zetahat*M``.

    Defaults are the paper's identified values: 1276 Hz natural frequency, damping
    ratio 0.49, 150 um static displacement at M = 7e5 A/m. State ``[x (m), x' (m/s)]``.

    Attributes
    ----------
    damping : float
        chat, 1/s (>= 0).
    stiffness : float
        khat, 1/s^2 (> 0).
    coupling : float
        zetahat, (m/s^2) per A/m.
    """

    damping: float = PAPER_DAMPING
    stiffness: float = PAPER_STIFFNESS
    coupling: float = PAPER_COUPLING

    def __post_init__(self):
        check_positive("LumpedLinear", stiffness=self.stiffness)
        check_nonnegative("LumpedLinear", damping=self.damping)
        if not math.isfinite(self.coupling):
            raise ValueError(f"LumpedLinear: coupling must be finite, got {self.coupling!r}")

    @classmethod
    def from_rod(cls, rod: RodParams = RodParams(), bias_magnetization: float | None = None) -> "LumpedLinear":
        """(13) lumped from rod data and linearized about ``bias_magnetization`` (A/m).

        With the default bias (:data:`DEFAULT_BIAS_MAGNETIZATION`) and rod data this is
        within 0.15 % of the paper's coefficients.
        """
        m0 = DEFAULT_BIAS_MAGNETIZATION if bias_magnetization is None else float(bias_magnetization)
        m = rod.lumped_mass
        return cls(rod.lumped_damping / m, rod.lumped_stiffness / m, 2.0 * rod.force_coefficient * m0 / m)

    @property
    def natural_frequency(self) -> float:
        """Undamped natural frequency, Hz."""
        return math.sqrt(self.stiffness) / (2 * math.pi)

    @property
    def damping_ratio(self) -> float:
        return self.damping / (2 * math.sqrt(self.stiffness))

    def state_matrices(self):
        """``(A, b)`` of ``z' = A z + b u`` with ``z = [x, x']`` and ``u = zetahat*M``."""
        return np.array([[0.0, 1.0], [-self.stiffness, -self.damping]]), np.array([0.0, 1.0])

    def discretize(self, dt: float) -> DiscreteTransducer:
        dt = check_dt("LumpedLinear.discretize", dt)
        A, b = self.state_matrices()
        phi, g0, g1 = first_order_hold(A, b, dt, scale=np.array([1.0, math.sqrt(self.stiffness)]))
        return DiscreteTransducer(dt, phi, g0, g1, LINEAR_DRIVE, float(self.coupling), 0, 1,
                                  name="LumpedLinear", static_response=np.array([1.0 / self.stiffness, 0.0]))


@dataclass(frozen=True)
class LumpedNonlinear(_Transducer):
    """The lumped transducer (12): ``m*x'' + c*x' + k*x = zeta*M**2``.

    Defaults are lumped from :class:`RodParams` (``m`` = 0.5449 kg, ``k`` = 3.505e7 N/m,
    ``c`` = 4305 N s/m, ``zeta`` = 9.74e-9 N per (A/m)^2). State ``[x (m), x' (m/s)]``.

    Attributes
    ----------
    mass : float
        m, kg (> 0).
    damping : float
        c, N s/m (>= 0).
    stiffness : float
        k, N/m (> 0).
    force_coefficient : float
        zeta, N/(A/m)^2.
    """

    mass: float = RodParams().lumped_mass
    damping: float = RodParams().lumped_damping
    stiffness: float = RodParams().lumped_stiffness
    force_coefficient: float = RodParams().force_coefficient

    def __post_init__(self):
        check_positive("LumpedNonlinear", mass=self.mass, stiffness=self.stiffness)
        check_nonnegative("LumpedNonlinear", damping=self.damping)
        if not math.isfinite(self.force_coefficient):
            raise ValueError(f"LumpedNonlinear: force_coefficient must be finite, got {self.force_coefficient!r}")

    @classmethod
    def from_rod(cls, rod: RodParams = RodParams()) -> "LumpedNonlinear":
        return cls(rod.lumped_mass, rod.lumped_damping, rod.lumped_stiffness, rod.force_coefficient)

    def linearized(self, bias_magnetization: float = DEFAULT_BIAS_MAGNETIZATION) -> LumpedLinear:
        """(13) obtained by linearizing about ``bias_magnetization`` M0 (A/m).

        Its displacement equals this model's plus ``zeta*M0**2/k`` to first order in M - M0.
        """
        return LumpedLinear(self.damping / self.mass, self.stiffness / self.mass,
                            2.0 * self.force_coefficient * bias_magnetization / self.mass)

    def state_matrices(self):
        """``(A, b)`` of ``z' = A z + b u`` with ``z = [x, x']`` and ``u = zeta*M**2`` (N)."""
        A = np.array([[0.0, 1.0], [-self.stiffness / self.mass, -self.damping / self.mass]])
        return A, np.array([0.0, 1.0 / self.mass])

    def discretize(self, dt: float) -> DiscreteTransducer:
        dt = check_dt("LumpedNonlinear.discretize", dt)
        A, b = self.state_matrices()
        phi, g0, g1 = first_order_hold(A, b, dt, scale=np.array([1.0, math.sqrt(self.stiffness / self.mass)]))
        return DiscreteTransducer(dt, phi, g0, g1, QUADRATIC_DRIVE, float(self.force_coefficient), 0, 1,
                                  name="LumpedNonlinear", static_response=np.array([1.0 / self.stiffness, 0.0]))


__all__ = [
    "DEFAULT_BIAS_MAGNETIZATION", "FirstOrderPlant", "LumpedLinear", "LumpedNonlinear", "PAPER_COUPLING",
    "PAPER_DAMPING", "PAPER_STIFFNESS", "RodParams",
]
