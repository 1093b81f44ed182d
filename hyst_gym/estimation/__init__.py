"""Adaptive estimators, min-max covers and persistent-excitation diagnostics (uses physics).

Public API
----------
:class:`EstimatorConfig`, :class:`FirstOrderPlant`, :class:`LumpedPlant`
    frozen, validated settings;
:class:`MinMaxEstimator` (14)-(16) / (24)-(25), :class:`GradientEstimator`,
:class:`MultipleModelEstimator`, :func:`make_estimator`
    batched estimators sharing ``reset`` / ``update(field, measured_output, dt)``;
:class:`Law`
    the parameter law each estimator runs (min-max (16)/(25), gradient, held);
:class:`BankState`, :class:`BankParams`, :class:`EstimatorState`, :class:`ObserverParams`, :class:`HoldParams`
    the named state of the compiled kernels (an estimator's ``kernel_state``,
    ``observer_params``, ``hold_params(dt)``, its bank's ``kernel_state``, ``kernel_params``);
:class:`ModelBank`
    the E x G hysteresis bank;
:func:`minmax_solution`, :func:`envelopes`
    the closed-form min-max;
:class:`PEMonitor`
    windowed test of the excitation conditions 3.1(a)/(b);
:func:`sensitivity_curve`, :func:`sensitivity_envelope`, :func:`error_bound`, :func:`first_passage`
    the linearized bound on how fast any slew-limited input can make the scalar
    estimator converge (:mod:`hyst_gym.estimation.convergence`).
"""

from ._kernels import (BankParams, BankState, EstimatorState, HoldParams, ObserverParams,
                       as_kernel_tuples)
from .bank import ModelBank
from .config import EstimatorConfig, FirstOrderPlant, LumpedPlant
from .convergence import error_bound, first_passage, sensitivity_curve, sensitivity_envelope
from .estimators import (ESTIMATORS, AdaptiveEstimator, GradientEstimator, Law, MinMaxEstimator,
                         MultipleModelEstimator, hold_matrices, make_estimator)
from .minmax import envelopes, minmax_solution
from .pe import PEMonitor

__all__ = [
    "AdaptiveEstimator", "BankParams", "BankState", "ESTIMATORS", "EstimatorState", "HoldParams", "ObserverParams",
    "as_kernel_tuples", "EstimatorConfig", "FirstOrderPlant", "GradientEstimator", "Law", "LumpedPlant",
    "MinMaxEstimator", "ModelBank", "MultipleModelEstimator", "PEMonitor", "envelopes", "error_bound",
    "first_passage", "hold_matrices", "make_estimator", "minmax_solution", "sensitivity_curve", "sensitivity_envelope",
]
