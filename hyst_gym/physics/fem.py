"""The finite-element Terfenol-D rod (10) with a tip mass, spring and damper.

Weak form of the rod PDE (8)-(9) with ``N`` linear elements of length ``h = L/N``
(node 0 fixed, nodes 1..N free, node N is the tip)::

    Mass M   = rho*A*h/6 * [[2, 1], [1, 2]] per element (consistent mass) + ML at the tip
    K        = (Y*A/h)  * tridiag(-1, 2, -1)                               + kL at the tip
    C        = (cD*A/h) * tridiag(-1, 2, -1)  (Kelvin-Voigt)               + cL at the tip
    M x'' + C x' + K x = b * zeta * M(t)**2,   b = e_N,  zeta = Y*A*gamma

Under the uniform field (11) the magnetostrictive stress ``Y*gamma*M**2`` is uniform
along the rod, so its weak form integrates to a single force at the tip node.

The rod's longitudinal modes are in the kHz range and the Kelvin-Voigt damping makes
the highest modes of a fine mesh decay at up to ~1e10 1/s (N = 256), far too stiff for
explicit steps. :meth:`FEMRod.discretize` therefore discretizes the linear mechanics
exactly per control period (matrix exponential with a first-order hold on the drive),
which is unconditionally stable and costs one (2N x 2N) matrix-vector product per step.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from .linear_system import LINEAR_DRIVE, QUADRATIC_DRIVE, DiscreteTransducer, first_order_hold
from .transducers import RodParams, _Transducer, check_dt

#: largest supported number of elements (the state has 2N entries)
MAX_ELEMENTS = 1024


@dataclass(frozen=True)
class FEMRod(_Transducer):
    """Finite-element rod (10): ``N`` linear elements, state ``[x_1..x_N, v_1..v_N]`` (m, m/s).

    Attributes
    ----------
    rod : RodParams
        Material, geometry and tip data.
    n_elements : int
        N, number of linear elements (1 <= N <= 1024; tested up to 256).
    bias_magnetization : float or None
        ``None``: the nonlinear forcing ``zeta*M**2`` of (10). A value M0 (A/m): the
        model linearized about M0 as in the paper's Figure 4, with tip force
        ``2*zeta*M0*M`` (the constant ``-zeta*M0**2`` is dropped, so the displacement
        is directly comparable with (13)).
    """

    rod: RodParams = field(default_factory=RodParams)
    n_elements: int = 16
    bias_magnetization: float | None = None

    def __post_init__(self):
        if not isinstance(self.rod, RodParams):
            raise ValueError(f"FEMRod: rod must be a RodParams, got {type(self.rod).__name__}")
        if isinstance(self.n_elements, bool) or not isinstance(self.n_elements, (int, np.integer)) \
                or not 1 <= self.n_elements <= MAX_ELEMENTS:
            raise ValueError(f"FEMRod: n_elements must be an integer in [1, {MAX_ELEMENTS}], got {self.n_elements!r}")
        object.__setattr__(self, "n_elements", int(self.n_elements))
        if self.bias_magnetization is not None:
            if not math.isfinite(self.bias_magnetization):
                raise ValueError(f"FEMRod: bias_magnetization must be finite or None, got {self.bias_magnetization!r}")
            object.__setattr__(self, "bias_magnetization", float(self.bias_magnetization))

    @property
    def element_length(self) -> float:
        return self.rod.L / self.n_elements

    def _tridiagonal(self, coefficient):
        n = self.n_elements
        matrix = coefficient * (2.0 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1))
        matrix[-1, -1] = coefficient  # the tip node belongs to one element only
        return matrix

    def mass_matrix(self) -> np.ndarray:
        """Consistent mass matrix plus the tip mass, kg, shape (N, N)."""
        n, rod = self.n_elements, self.rod
        element = rod.rho * rod.A * self.element_length / 6.0
        matrix = element * (4.0 * np.eye(n) + np.eye(n, k=1) + np.eye(n, k=-1))
        matrix[-1, -1] = 2.0 * element + rod.ML
        return matrix

    def stiffness_matrix(self) -> np.ndarray:
        """``(Y*A/h)*tridiag(-1, 2, -1)`` plus the tip spring, N/m, shape (N, N)."""
        matrix = self._tridiagonal(self.rod.Y * self.rod.A / self.element_length)
        matrix[-1, -1] += self.rod.kL
        return matrix

    def damping_matrix(self) -> np.ndarray:
        """Kelvin-Voigt ``(cD*A/h)*tridiag(-1, 2, -1)`` plus the tip damper, N s/m."""
        matrix = self._tridiagonal(self.rod.cD * self.rod.A / self.element_length)
        matrix[-1, -1] += self.rod.cL
        return matrix

    def forcing_vector(self) -> np.ndarray:
        """``b`` of (10): the uniform magnetostrictive stress acts at the tip node only."""
        b = np.zeros(self.n_elements)
        b[-1] = 1.0
        return b

    def natural_frequencies(self, count: int = 3) -> np.ndarray:
        """Lowest undamped natural frequencies of the discrete rod, Hz."""
        eigenvalues = scipy.linalg.eigh(self.stiffness_matrix(), self.mass_matrix(), eigvals_only=True,
                                        subset_by_index=[0, min(count, self.n_elements) - 1])
        return np.sqrt(eigenvalues) / (2 * math.pi)

    def state_matrices(self):
        """``(A, b)`` of ``z' = A z + b u``, ``z = [x, v]``, ``u`` the tip force in N."""
        n = self.n_elements
        mass = self.mass_matrix()
        factor = scipy.linalg.cho_factor(mass)
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :n] = -scipy.linalg.cho_solve(factor, self.stiffness_matrix())
        A[n:, n:] = -scipy.linalg.cho_solve(factor, self.damping_matrix())
        b = np.zeros(2 * n)
        b[n:] = scipy.linalg.cho_solve(factor, self.forcing_vector())
        return A, b

    def discretize(self, dt: float) -> DiscreteTransducer:
        """Exact first-order-hold discretization for the control period ``dt`` (s)."""
        dt = check_dt("FEMRod.discretize", dt)
        n = self.n_elements
        A, b = self.state_matrices()
        omega = math.sqrt(self.rod.lumped_stiffness / self.rod.lumped_mass)
        phi, g0, g1 = first_order_hold(A, b, dt, scale=np.r_[np.ones(n), np.full(n, omega)])
        zeta = self.rod.force_coefficient
        if self.bias_magnetization is None:
            drive, gain = QUADRATIC_DRIVE, zeta
        else:
            drive, gain = LINEAR_DRIVE, 2.0 * zeta * self.bias_magnetization
        static = np.r_[np.linalg.solve(self.stiffness_matrix(), self.forcing_vector()), np.zeros(n)]
        return DiscreteTransducer(dt, phi, g0, g1, drive, float(gain), n - 1, 2 * n - 1,
                                  name=f"FEMRod(N={n})", static_response=static)

    def replace(self, **changes) -> "FEMRod":
        return dataclasses.replace(self, **changes)


#: the default rod of :func:`analytic_frequencies` (frozen: one shared instance is safe)
_DEFAULT_ROD = RodParams()


def analytic_frequencies(rod: RodParams = _DEFAULT_ROD, count: int = 3) -> np.ndarray:
    """Undamped longitudinal natural frequencies (Hz) of the continuous rod with tip mass.

    Modes ``w = sin(beta*x)`` (fixed at x = 0) satisfy the tip balance
    ``Y*A*beta*cos(beta*L) = (ML*omega**2 - kL)*sin(beta*L)``, ``omega = beta*sqrt(Y/rho)``.
    """
    # imported here, not at the top: scipy.optimize costs about a tenth of a second of every
    # `import hyst_gym` (and of an env's first step), and only this function needs it
    import scipy.optimize

    c = rod.wave_speed

    def residual(beta_l):
        beta = beta_l / rod.L
        return rod.Y * rod.A * beta * math.cos(beta_l) - (rod.ML * (c * beta) ** 2 - rod.kL) * math.sin(beta_l)

    roots = []
    grid = np.linspace(1e-9, (count + 2) * math.pi, 2000 * (count + 2))
    values = [residual(x) for x in grid]
    for left, right, f_left, f_right in zip(grid[:-1], grid[1:], values[:-1], values[1:]):
        if f_left == 0.0 or f_left * f_right < 0:
            roots.append(scipy.optimize.brentq(residual, left, right, xtol=1e-15, rtol=1e-15))
            if len(roots) == count:
                break
    return np.array(roots) / rod.L * c / (2 * math.pi)


__all__ = ["FEMRod", "MAX_ELEMENTS", "analytic_frequencies"]
