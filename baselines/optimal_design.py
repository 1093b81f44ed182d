"""Open-loop optimal input design: a multisine H(t) that maximizes Fisher information about a.

Parameterization: ``H(t) = H0 + s * sum_k A_k sin(2*pi*k*t/period + phi_k)``, k = 1..n,
with a bias ``H0 = field_max*tanh(x_0)``, amplitudes ``A_k = |x_k|`` and phases
``phi_k = pi*x_{n+k}``; the sum is scaled by ``s`` so that the peak of ``|H|`` is at most
``field_max`` (a bias lets the design dwell where M is most sensitive to a, which a
zero-mean multisine cannot). The field is then passed through the common slew limit
(:func:`~baselines.schedules.apply_limits`), so the design obeys the same limits as every other agent.
The period repeats over the episode.

Criterion: the log Fisher information ``log I(a)``
(:mod:`baselines.information`) of one period

* at the nominal a (``a_values=[7012]``, a locally D-optimal design), or
* averaged over the temperature prior (``a_values`` = a(T) at prior quantiles: the
  ED-optimal / robust design of Pronzato & Walter, maximizing ``E_a[log I(a)]``).

Optimizer: CMA-ES (pycma) with a fixed seed, so the design is reproducible.
"""

from __future__ import annotations

from dataclasses import dataclass, field as dataclass_field

import numpy as np

from hyst_gym.physics import FirstOrderPlant, HysteresisParams

from .cma_search import cma_minimize
from .information import fisher_information
from .schedules import ExcitationLimits, Schedule, apply_limits

#: the default models of the signatures below (frozen dataclasses: one shared instance is safe)
DEFAULT_HYSTERESIS = HysteresisParams()
DEFAULT_PLANT = FirstOrderPlant()


@dataclass(frozen=True)
class MultisineDesign(Schedule):
    """A designed multisine (see module doc). ``coefficients`` has length ``2*n + 1``."""

    coefficients: tuple = (0.0, 1.0, 0.0)
    period: float = 6.0
    field_max: float = 1.2e5
    name = "optimal_design"

    @property
    def n_harmonics(self) -> int:
        return (len(self.coefficients) - 1) // 2

    def _raw(self, time):
        x = np.asarray(self.coefficients, dtype=np.float64)[1:]
        n = self.n_harmonics
        k = np.arange(1, n + 1)
        amplitudes, phases = np.abs(x[:n]), np.pi * x[n:]
        return (amplitudes * np.sin(2 * np.pi * np.multiply.outer(time, k) / self.period + phases)).sum(-1)

    def field(self, time):
        time = np.asarray(time, dtype=np.float64)
        grid = np.linspace(0.0, self.period, 2049)
        peak = max(np.max(np.abs(self._raw(grid))), 1e-12)
        bias = np.tanh(self.coefficients[0])
        return self.field_max * (bias + (1 - abs(bias)) * self._raw(time) / peak)


@dataclass(frozen=True)
class DesignResult:
    design: MultisineDesign
    log_information: float
    evaluations: int
    history: tuple = dataclass_field(default=())


def design_input(limits: ExcitationLimits, a_values=(7012.0,), period: float = 6.0, n_harmonics: int = 6,
                 params: HysteresisParams = DEFAULT_HYSTERESIS, plant: FirstOrderPlant = DEFAULT_PLANT,
                 max_evaluations: int = 400, seed: int = 0) -> DesignResult:
    """Run CMA-ES on the multisine coefficients; return the best design found.

    ``a_values`` (A/m): the nominal a, or quantiles of the temperature prior of a.
    """
    a_values = np.atleast_1d(np.asarray(a_values, dtype=np.float64))
    n_steps = int(round(period / limits.dt))

    def loss(x):
        design = MultisineDesign(tuple(float(v) for v in x), period, limits.field_max)
        field = apply_limits(design.field(limits.dt * np.arange(1, n_steps + 1)), limits)
        information = fisher_information(field, limits.dt, a_values, params, plant)
        return -float(np.mean(np.log(information + 1e-300)))

    rng = np.random.default_rng(seed)
    x0 = np.concatenate([[0.0], np.full(n_harmonics, 0.5), rng.uniform(-1, 1, n_harmonics)])
    best, best_loss, evaluations, history = cma_minimize(loss, x0, 0.5, 2.0, max_evaluations, seed)
    design = MultisineDesign(tuple(float(v) for v in best), period, limits.field_max)
    return DesignResult(design, -best_loss, evaluations, tuple(-value for value in history))


__all__ = ["MultisineDesign", "DesignResult", "design_input"]
