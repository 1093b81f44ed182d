"""The homogenized energy model (HEM) of ferromagnetic hysteresis, batched and compiled.

A second hysteresis model beside the domain-wall model (6), built for what (6) lacks: minor
loops and the low-field (Rayleigh) region come out of a distribution of pinning sites, with no
special term. The model (R. C. Smith, M. J. Dapino, T. R. Braun, A. P. Mortensen, "A homogenized
energy framework for ferromagnetic hysteresis", IEEE Trans. Magn. 42(7), 1747-1769, 2006; R. C.
Smith, S. Seelecke, M. J. Dapino, Z. Ounaies, "A unified framework for modeling hysteresis in
ferroic materials", J. Mech. Phys. Solids 54, 46-85, 2006) averages a local kernel over densities
of the coercive field ``Hc`` (lognormal) and of the interaction field ``HI`` (normal)::

    M(H) = int_0^inf int_-inf^inf nu_c(Hc) nu_I(HI) Mbar(H + HI; Hc) dHI dHc

In the limit of negligible thermal activation the kernel is ``Mbar = (H + HI)/eta + M_R*delta``:
a reversible slope ``1/eta`` and a relay ``delta`` that switches to +1 when ``H + HI >= Hc`` and
to -1 when ``H + HI <= -Hc``. The reversible part integrates to ``H/eta`` (the interaction
density has zero mean).

Exact integration over the interaction field. At one coercive field, the relays of all
interaction fields have the same width ``2*Hc`` and differ by a shift ``s = -HI``; the relays with
``s`` below the output ``p`` of the play operator of half-width ``Hc`` are up, the others down
(the play operator: ``p <- min(max(p, H - Hc), H + Hc)``). So the relay part at one ``Hc`` is
``M_R*(2*F(p) - 1)`` with ``F`` the cumulative distribution of ``s``, in closed form:
``erf(p/(sqrt(2)*b))`` for the normal density of standard deviation ``b``. The only
discretization left is the coercive-field integral (:func:`coercive_rule`, ``coercive_nodes``
cells in ``ln Hc``), and the state is one play-operator output per node. The play
operator is exact for any field path that is monotone between samples, so unlike (6) the model
takes no substeps: one update per sample, whatever the field change.

Options: the interaction density may be ``"lorentzian"`` (Cauchy, half-width ``b``: relay part
``(2/pi)*atan(p/b)``), the factorized Lorentzian density of the Preisach-type models of
G. Bertotti, *Hysteresis in Magnetism*, Academic Press 1998, ch. 8, whose heavy tails approach
saturation slowly; or ``"student_t2"``, Student's t density with two degrees of freedom and scale
``b`` (relay part ``x/sqrt(2 + x^2)``, ``x = p/b``), whose tails (``|HI|^-3``) lie between the two
and whose distribution function costs one square root and one division (the cheapest of the three).
And the reversible part may saturate (:data:`SATURATING_REVERSIBLE`), and the coercive density may hold a
population of zero coercivity besides the lognormal one (:data:`ANHYSTERETIC_POPULATION`).

The model is a Preisach model with the density of these two coordinates, so it has return-point
memory (wiping out) and congruent minor loops between the same two fields (Mayergoyz's
characterization; tests/physics/test_hem.py checks both).

Two batch layouts over a batch of independent models, as for (6): :func:`simulate_shared` /
:func:`advance_shared` (a bank under one shared field) and :func:`advance_each` (every model its own
field). Parameters are ``(B,)`` arrays; the state is node-major, ``(N, B)``, so that the innermost loop
runs over models and vectorizes.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit, types
from numba.extending import overload
from scipy.special import ndtr, ndtri

from .anhysteretic import tanh_expm1


#: The saturating reversible part, an option (``reversible_saturation`` > 0): the HEM's kernel has the
#: reversible slope 1/eta at every field, so the reversible magnetization grows without bound. Reversible
#: wall bowing and rotation saturate with the material; this option bounds the reversible part by the
#: Ising form of the anhysteretic curve (2), as the reversible part c*Man of the domain-wall model (5):
SATURATING_REVERSIBLE = "M_rev = (h_s/eta)*tanh(H/h_s): slope 1/eta at low field, bounded by h_s/eta"

#: The anhysteretic population, an option (``anhysteretic_magnetization`` > 0): the coercive density is the
#: lognormal one plus a point mass at Hc = 0, sites with negligible pinning (walls that move freely between
#: pinning sites, rotation). The relays of that population have no hysteresis, their play output is H itself,
#: so their integral over the interaction field is the HEM's anhysteretic curve (the Hc -> 0 limit of the
#: kernel; Smith et al. 2006) with a field scale of its own, b_A. A reversible part that saturates with the
#: interaction density's shape, beside the pinned, hysteretic relays:
ANHYSTERETIC_POPULATION = "M_an = M_A*(2*F(H; b_A) - 1), F the interaction density's distribution, scale b_A"

#: Codes of the interaction densities in the compiled kernels.
NORMAL = 0
LORENTZIAN = 1
STUDENT_T2 = 2
INTERACTION_DENSITIES = {"normal": NORMAL, "lorentzian": LORENTZIAN, "student_t2": STUDENT_T2}
#: Default number of coercive-field nodes: against an adaptive quadrature of the double integral the rule
#: is within 3e-3 of M_R here (2e-5 with 2000 nodes; tests/physics/test_hem.py).
DEFAULT_COERCIVE_NODES = 16

_PARAMETER_NAMES = ("relay_magnetization", "reversible_susceptibility", "coercive_median", "coercive_spread",
                    "interaction_scale")


def interaction_density_code(name: str) -> int:
    """Map ``"normal"``/``"lorentzian"`` to the kernels' integer code."""
    try:
        return INTERACTION_DENSITIES[str(name).lower()]
    except KeyError:
        raise ValueError(f"interaction_density must be one of {sorted(INTERACTION_DENSITIES)}, got {name!r}") from None


@dataclass(frozen=True)
class HEMParams:
    """Parameters of the homogenized energy model (relay kernel). Defaults are illustrative, of the
    order of a soft ferrite, not fitted to any material.

    Attributes
    ----------
    relay_magnetization : float
        ``M_R``, the magnetization the relays switch between (+-), A/m (> 0): the saturation of
        the irreversible part.
    reversible_susceptibility : float
        ``1/eta``, the kernel's reversible slope, dimensionless (>= 0).
    coercive_median : float
        Median of the lognormal coercive-field density, A/m (> 0).
    coercive_spread : float
        Standard deviation of ``ln Hc``, dimensionless (> 0).
    interaction_scale : float
        ``b``: standard deviation of the normal interaction density (half-width of the Lorentzian,
        scale of the Student t one), A/m (> 0).
    interaction_density : str
        ``"normal"`` (the HEM's), ``"lorentzian"`` or ``"student_t2"``.
    coercive_nodes : int
        Nodes of the coercive-field quadrature (>= 1).
    reversible_saturation : float
        ``h_s``, A/m (>= 0). 0, the default, is the HEM's linear reversible part ``H/eta``; above 0 the
        reversible part saturates, ``(h_s/eta)*tanh(H/h_s)`` (:data:`SATURATING_REVERSIBLE`).
    anhysteretic_magnetization : float
        ``M_A``, A/m (>= 0): the magnetization of the population of zero coercivity
        (:data:`ANHYSTERETIC_POPULATION`). 0, the default, is the HEM's lognormal coercive density alone.
    anhysteretic_scale : float
        ``b_A``, A/m (> 0): the interaction scale of that population (its standard deviation, half-width or
        scale as for ``interaction_scale``); unused while ``anhysteretic_magnetization`` is 0.
    """

    relay_magnetization: float = 3.0e5
    reversible_susceptibility: float = 50.0
    coercive_median: float = 20.0
    coercive_spread: float = 0.6
    interaction_scale: float = 30.0
    interaction_density: str = "normal"
    coercive_nodes: int = DEFAULT_COERCIVE_NODES
    reversible_saturation: float = 0.0
    anhysteretic_magnetization: float = 0.0
    anhysteretic_scale: float = 1.0

    def __post_init__(self):
        _check_saturation(self.reversible_saturation, "HEMParams")
        _check_anhysteretic(self.anhysteretic_magnetization, self.anhysteretic_scale, "HEMParams")
        for name in ("reversible_saturation",) + _ANHYSTERETIC_NAMES:
            object.__setattr__(self, name, float(getattr(self, name)))
        for name in _PARAMETER_NAMES:
            object.__setattr__(self, name, float(getattr(self, name)))
        validate_hem_parameters(*(getattr(self, n) for n in _PARAMETER_NAMES), owner="HEMParams")
        interaction_density_code(self.interaction_density)
        object.__setattr__(self, "interaction_density", str(self.interaction_density).lower())
        _check_nodes(self.coercive_nodes, "HEMParams")
        object.__setattr__(self, "coercive_nodes", int(self.coercive_nodes))

    def replace(self, **changes) -> "HEMParams":
        """A copy with some fields changed (validated)."""
        return dataclasses.replace(self, **changes)


def _check_saturation(values, owner):
    values = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(values) & (values >= 0.0)):
        raise ValueError(f"{owner}: reversible_saturation must be finite and >= 0 A/m, got {values.ravel()[:1]}")


_ANHYSTERETIC_NAMES = ("anhysteretic_magnetization", "anhysteretic_scale")


def _check_anhysteretic(magnetization, scale, owner):
    magnetization = np.asarray(magnetization, dtype=np.float64)
    scale = np.asarray(scale, dtype=np.float64)
    if not np.all(np.isfinite(magnetization) & (magnetization >= 0.0)):
        raise ValueError(f"{owner}: anhysteretic_magnetization must be finite and >= 0 A/m, "
                         f"got {magnetization.ravel()[:1]}")
    if not np.all(np.isfinite(scale) & (scale > 0.0)):
        raise ValueError(f"{owner}: anhysteretic_scale must be finite and > 0 A/m, got {scale.ravel()[:1]}")


def _check_nodes(nodes, owner):
    if int(nodes) != nodes or nodes < 1:
        raise ValueError(f"{owner}: coercive_nodes must be an integer >= 1, got {nodes!r}")


def validate_hem_parameters(relay_magnetization, reversible_susceptibility, coercive_median, coercive_spread,
                            interaction_scale, owner="HEM"):
    """Raise ``ValueError`` naming the first parameter outside its range (scalars or arrays)."""
    checks = (("relay_magnetization", relay_magnetization, "> 0 A/m", lambda v: v > 0),
              ("reversible_susceptibility", reversible_susceptibility, ">= 0", lambda v: v >= 0),
              ("coercive_median", coercive_median, "> 0 A/m", lambda v: v > 0),
              ("coercive_spread", coercive_spread, "> 0", lambda v: v > 0),
              ("interaction_scale", interaction_scale, "> 0 A/m", lambda v: v > 0))
    for name, value, rule, ok in checks:
        value = np.asarray(value, dtype=np.float64)
        good = np.isfinite(value) & ok(value)
        if not np.all(good):
            raise ValueError(f"{owner}: {name} must be finite and {rule}, got {float(value[~good].ravel()[0])!r}")


def coercive_rule(nodes: int):
    """Nodes (standard-normal quantiles ``u``) and weights of the coercive-field rule: the nodes of a
    model are ``coercive_median*exp(coercive_spread*u)``.

    ``nodes`` cells of equal width in ``u`` over ``[-L, L]``, ``L = 1 + sqrt(2 ln nodes)``, the two outer
    cells extended to infinity; each cell's weight is its probability and its node the median of the
    cell. Equal cells in ``ln Hc`` (not equal probabilities) put nodes into the low tail of the
    coercive density, where small loops live: with 16 nodes the lowest is at ``u = -3.1`` rather than
    at the 1/32 quantile (``u = -1.9``) of an equal-weight rule."""
    half_width = 1.0 + math.sqrt(2.0 * math.log(max(nodes, 2)))
    edges = np.linspace(-half_width, half_width, nodes + 1)
    cumulative = ndtr(edges)
    cumulative[0], cumulative[-1] = 0.0, 1.0
    weights = np.diff(cumulative)
    return ndtri(0.5 * (cumulative[:-1] + cumulative[1:])), weights


class HEMConstants(NamedTuple):
    """What the kernels need of a batch of ``B`` models with ``N`` coercive nodes."""

    coercive: np.ndarray  # (N, B) coercive field of each node, A/m
    relay_weight: np.ndarray  # (N, B) M_R times the node's weight: magnetization per node, A/m
    inverse_scale: np.ndarray  # (B,) 1/(sqrt(2) b) (normal) or 1/b (Lorentzian), 1/(A/m)
    reversible_susceptibility: np.ndarray  # (B,) 1/eta, dimensionless
    reversible_saturation: np.ndarray  # (B,) h_s, A/m; 0: linear reversible part
    anhysteretic_weight: np.ndarray  # (B,) M_A, A/m; 0: no population of zero coercivity
    anhysteretic_inverse_scale: np.ndarray  # (B,) as inverse_scale, for b_A, 1/(A/m)
    #: which stateless parts the bank needs: 0 the linear reversible part alone, 1 some model's reversible part
    #: saturates, 2 some model has an anhysteretic population. The kernels run only the parts needed, so an
    #: option left at its default costs nothing per sample (the numbers are the same: the omitted terms are 0).
    stateless_parts: int


#: Codes of HEMConstants.stateless_parts.
LINEAR_REVERSIBLE_ONLY = 0
SATURATING_REVERSIBLE_PARTS = 1
WITH_ANHYSTERETIC_POPULATION = 2


def stateless_parts(batch) -> int:
    """The :attr:`HEMConstants.stateless_parts` code of a :class:`HEMBatch`: the least work that gives every
    model's stateless parts."""
    if np.any(batch.anhysteretic_magnetization > 0.0):
        return WITH_ANHYSTERETIC_POPULATION
    if np.any(batch.reversible_saturation > 0.0):
        return SATURATING_REVERSIBLE_PARTS
    return LINEAR_REVERSIBLE_ONLY


class HEMState(NamedTuple):
    """State of a batch: the play-operator output of every coercive node, ``(N, B)`` (node-major, so that
    the kernels' loop over models is contiguous), A/m. The relays of that node whose shift ``-HI`` lies
    below it are up. All zero: the demagnetized state."""

    play: np.ndarray


@dataclass(frozen=True)
class HEMBatch:
    """Parameter arrays of a batch of HEM models, each ``(size,)``; units as in :class:`HEMParams`. All
    models share one interaction density and one number of coercive nodes."""

    relay_magnetization: np.ndarray
    reversible_susceptibility: np.ndarray
    coercive_median: np.ndarray
    coercive_spread: np.ndarray
    interaction_scale: np.ndarray
    interaction_density: str = "normal"
    coercive_nodes: int = DEFAULT_COERCIVE_NODES
    reversible_saturation: np.ndarray | float = 0.0
    anhysteretic_magnetization: np.ndarray | float = 0.0
    anhysteretic_scale: np.ndarray | float = 1.0

    def __post_init__(self):
        saturation = np.asarray(self.reversible_saturation, dtype=np.float64)
        _check_saturation(saturation, "HEMBatch")
        _check_anhysteretic(self.anhysteretic_magnetization, self.anhysteretic_scale, "HEMBatch")
        arrays = np.broadcast_arrays(*(np.asarray(getattr(self, n), dtype=np.float64) for n in _PARAMETER_NAMES))
        if arrays[0].ndim != 1:
            raise ValueError(f"HEMBatch: parameters must be 1-D arrays, got shape {arrays[0].shape}")
        validate_hem_parameters(*arrays, owner="HEMBatch")
        interaction_density_code(self.interaction_density)
        _check_nodes(self.coercive_nodes, "HEMBatch")
        for name, array in zip(_PARAMETER_NAMES, arrays):
            array = np.array(array, dtype=np.float64)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        object.__setattr__(self, "interaction_density", str(self.interaction_density).lower())
        object.__setattr__(self, "coercive_nodes", int(self.coercive_nodes))
        for name in ("reversible_saturation",) + _ANHYSTERETIC_NAMES:
            array = np.array(np.broadcast_to(np.asarray(getattr(self, name), dtype=np.float64), arrays[0].shape))
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    @property
    def size(self) -> int:
        return self.relay_magnetization.shape[0]

    @property
    def kind(self) -> int:
        """Integer code of the interaction density used by the kernels."""
        return interaction_density_code(self.interaction_density)

    @classmethod
    def from_params(cls, params: HEMParams, size: int = 1) -> "HEMBatch":
        one = np.ones(int(size))
        return cls(*(getattr(params, n) * one for n in _PARAMETER_NAMES), params.interaction_density,
                   params.coercive_nodes, params.reversible_saturation * one,
                   params.anhysteretic_magnetization * one, params.anhysteretic_scale * one)

    @classmethod
    def stack(cls, params_list) -> "HEMBatch":
        params_list = list(params_list)
        if not params_list:
            raise ValueError("HEMBatch.stack: empty list of parameter sets")
        shared = {(p.interaction_density, p.coercive_nodes) for p in params_list}
        if len(shared) != 1:
            raise ValueError(f"HEMBatch.stack: mixed densities or node counts {sorted(shared)}")
        density, nodes = shared.pop()
        return cls(*(np.array([getattr(p, n) for p in params_list]) for n in _PARAMETER_NAMES), density, nodes,
                   *(np.array([getattr(p, n) for p in params_list]) for n in ("reversible_saturation",)
                     + _ANHYSTERETIC_NAMES))

    def constants(self) -> HEMConstants:
        quantiles, weights = coercive_rule(self.coercive_nodes)
        coercive = self.coercive_median[None, :] * np.exp(quantiles[:, None] * self.coercive_spread[None, :])
        factor = math.sqrt(2.0) if self.kind == NORMAL else 1.0
        return HEMConstants(np.ascontiguousarray(coercive),
                            np.ascontiguousarray(weights[:, None] * self.relay_magnetization[None, :]),
                            1.0 / (factor * self.interaction_scale), self.reversible_susceptibility.copy(),
                            self.reversible_saturation.copy(), self.anhysteretic_magnetization.copy(),
                            1.0 / (factor * self.anhysteretic_scale), stateless_parts(self))

    def demagnetized(self) -> HEMState:
        """The ideally demagnetized state: every play output 0, M = 0 at H = 0."""
        return HEMState(np.zeros((self.coercive_nodes, self.size)))


# --------------------------------------------------------------------------- kernels


#: erf(z) = 1 - t*(a1 + a2 t + ... + a5 t^4)*exp(-z^2), t = 1/(1 + p z), z >= 0: M. Abramowitz and I. A.
#: Stegun, *Handbook of Mathematical Functions*, 1964, eq. 7.1.26 (absolute error below 1.5e-7).
_ERF_P = 0.3275911
_ERF_A = (0.254829592, -0.284496736, 1.421413741, -1.453152027, 1.061405429)
#: exp(y) as (Taylor polynomial at y/2^8)^(2^8): the reduced argument of exp(-z^2) lies in [-0.16, 0] for
#: |z| <= 6.4 (where erf is 1 to double precision), so the degree-9 polynomial is exact to 1e-14 relative,
#: 3e-12 after the 8 squarings.
_EXP_SQUARINGS = 8
_EXP_TAYLOR = (1.0, 1.0, 1.0 / 2, 1.0 / 6, 1.0 / 24, 1.0 / 120, 1.0 / 720, 1.0 / 5040, 1.0 / 40320, 1.0 / 362880)
_ERF_SATURATION = 6.4


@njit(cache=True, inline="always", error_model="numpy")
def erf_inline(x):
    """erf(x) to an absolute error below 1.5e-7, branch free and inlined so that the bank loop
    vectorizes (a libm ``erf`` call does not)."""
    z = min(abs(x), _ERF_SATURATION)
    t = 1.0 / (1.0 + _ERF_P * z)
    a = _ERF_A
    y = -z * z * (1.0 / 2.0 ** _EXP_SQUARINGS)
    c = _EXP_TAYLOR
    e = c[0] + y * (c[1] + y * (c[2] + y * (c[3] + y * (c[4] + y * (c[5] + y * (c[6] + y * (c[7] + y * (
        c[8] + y * c[9]))))))))
    for _ in range(_EXP_SQUARINGS):
        e = e * e
    return math.copysign(1.0 - t * (a[0] + t * (a[1] + t * (a[2] + t * (a[3] + t * a[4])))) * e, x)


@njit(cache=True, inline="always", error_model="numpy")
def atan_inline(x):
    """atan(x) to 1e-12 absolute, branch free and inlined (a libm ``atan`` call does not vectorize):
    ``atan(|x|) = pi/2 - atan(1/|x|)`` above 1 (one division of min by max), two half-angle steps
    ``atan(r) = 2*atan(r/(1 + sqrt(1 + r^2)))`` down to ``r <= tan(pi/16) = 0.199``, then the odd Taylor
    series to ``r^15`` (truncation below 2.3e-12, times 4)."""
    a = abs(x)
    r = min(a, 1.0) / max(a, 1.0)
    r = r / (1.0 + math.sqrt(1.0 + r * r))
    r = r / (1.0 + math.sqrt(1.0 + r * r))
    q = r * r
    series = r * (1.0 + q * (-1.0 / 3 + q * (1.0 / 5 + q * (-1.0 / 7 + q * (1.0 / 9 + q * (-1.0 / 11 + q * (
        1.0 / 13 - q / 15)))))))
    reduced = 4.0 * series
    angle = (0.5 * math.pi - reduced) if a > 1.0 else reduced
    return math.copysign(angle, x)


@njit(cache=True, inline="always", error_model="numpy")
def relay_share(play, inverse_scale, kind):
    """``2*F(p) - 1`` of one node: the share of its relays that are up minus those down."""
    x = play * inverse_scale
    if kind == NORMAL:
        return erf_inline(x)
    if kind == STUDENT_T2:
        return x / math.sqrt(2.0 + x * x)
    return (2.0 / math.pi) * atan_inline(x)


@njit(cache=True, inline="always", error_model="numpy")
def reversible_magnetization(field, susceptibility, saturation):
    """The reversible part (A/m) at ``field`` (A/m): ``susceptibility*field`` for ``saturation`` 0, else
    :data:`SATURATING_REVERSIBLE`."""
    bounded = susceptibility * saturation * tanh_expm1(field / saturation)
    return susceptibility * field if saturation == 0.0 else bounded


@njit(cache=True, inline="always", error_model="numpy")
def stateless_magnetization(field, constants, b, kind):
    """The parts of model ``b`` that carry no state (A/m): the reversible part and the anhysteretic
    population (:data:`ANHYSTERETIC_POPULATION`; its weight 0 adds exactly 0)."""
    reversible = reversible_magnetization(field, constants.reversible_susceptibility[b],
                                          constants.reversible_saturation[b])
    return reversible + constants.anhysteretic_weight[b] * relay_share(
        field, constants.anhysteretic_inverse_scale[b], kind)


@njit(cache=True, inline="always", error_model="numpy")
def _advance_node(play, coercive, weight, inverse_scale, field, kind):
    """One node of one model moved to ``field``: (new play output, its relay magnetization), A/m."""
    low = field - coercive
    high = field + coercive
    play = low if play < low else play
    play = high if play > high else play
    return play, weight * relay_share(play, inverse_scale, kind)


def field_of(field, b):
    """The field of model ``b``: ``field`` itself when one field is shared, ``field[b]`` when each model has
    its own (compiled overload below)."""
    return field if np.ndim(field) == 0 else field[b]


@overload(field_of, inline="always")
def _field_of_compiled(field, b):
    if isinstance(field, types.Array):
        return lambda field, b: field[b]
    return lambda field, b: field


@njit(cache=True, inline="always", error_model="numpy")
def _set_stateless(field, constants, kind, magnetization):
    """``magnetization[b]`` = the stateless parts of every model at its field (:func:`field_of`). One loop per
    case of ``constants.stateless_parts``, each vectorizing: an option at its default is not evaluated at all
    (its weight-0 term would add exactly 0 and cost one interaction-density evaluation per model and sample)."""
    if constants.stateless_parts == WITH_ANHYSTERETIC_POPULATION:
        for b in range(magnetization.shape[0]):
            magnetization[b] = stateless_magnetization(field_of(field, b), constants, b, kind)
    elif constants.stateless_parts == SATURATING_REVERSIBLE_PARTS:
        for b in range(magnetization.shape[0]):
            magnetization[b] = reversible_magnetization(field_of(field, b), constants.reversible_susceptibility[b],
                                                        constants.reversible_saturation[b])
    else:
        for b in range(magnetization.shape[0]):
            magnetization[b] = constants.reversible_susceptibility[b] * field_of(field, b)


@njit(cache=True, error_model="numpy")
def advance_shared(state, field, constants, kind, magnetization):
    """Every model of a bank moved to one shared ``field`` (A/m); writes M (A/m) into ``magnetization``
    ``(B,)``. Exact for any path monotone since the previous call. The loop over models is innermost, so
    that it compiles to SIMD code as (6)'s bank does; each model sums its nodes in node order, so a model
    gives the same numbers bit for bit alone and in any bank."""
    play = state.play
    _set_stateless(field, constants, kind, magnetization)
    for i in range(play.shape[0]):
        for b in range(play.shape[1]):
            play[i, b], part = _advance_node(play[i, b], constants.coercive[i, b], constants.relay_weight[i, b],
                                             constants.inverse_scale[b], field, kind)
            magnetization[b] += part


@njit(cache=True, error_model="numpy")
def advance_each(state, fields, constants, kind, magnetization):
    """Every model moved to its own field ``fields[b]`` (A/m); writes M (A/m) into ``magnetization``."""
    play = state.play
    _set_stateless(fields, constants, kind, magnetization)
    for i in range(play.shape[0]):
        for b in range(play.shape[1]):
            play[i, b], part = _advance_node(play[i, b], constants.coercive[i, b], constants.relay_weight[i, b],
                                             constants.inverse_scale[b], fields[b], kind)
            magnetization[b] += part


@njit(cache=True)
def simulate_shared(field, state, constants, kind):
    """M (A/m) of a bank along one sampled field, shape ``(T, B)``; ``state`` is advanced in place
    (row 0 is the state moved to ``field[0]``)."""
    out = np.empty((field.shape[0], state.play.shape[1]))
    for t in range(field.shape[0]):
        advance_shared(state, field[t], constants, kind, out[t])
    return out


# --------------------------------------------------------------------------- user API


def state_with_magnetization(batch: HEMBatch, field: float, magnetization, iterations: int = 60) -> HEMState:
    """A state at ``field`` (A/m) whose M is ``magnetization`` (A/m, scalar or ``(B,)``): every play output
    the same offset, clipped to the play operator's band ``|H - p| <= Hc``, found by bisection (M grows
    with the offset). The state of a remanent or measured start; M beyond what the band allows is
    clipped to its nearest reachable value. Solved with scipy's erf: the compiled kernel's (1.5e-7 absolute)
    then starts within 1.5e-7 of M_R of ``magnetization``."""
    return states_with_magnetization([batch.constants()], batch.kind, [field], [magnetization], iterations)[0]


def states_with_magnetization(constants, kind: int, fields, magnetizations, iterations: int = 60) -> list:
    """:func:`state_with_magnetization` for many banks at once, each at its own field: bank ``i``
    (``constants[i]``, a :class:`HEMConstants`; all of one interaction density ``kind``) at ``fields[i]``
    (A/m) with M ``magnetizations[i]`` (A/m, scalar or one per model). The banks' models stand side by
    side in one array, so the bisection takes one numpy pass per step for all of them, and each bank's
    state is the one it would get alone, bit for bit (every operation is per model)."""
    sizes = [c.coercive.shape[1] for c in constants]
    field = np.repeat(np.asarray(fields, dtype=np.float64), sizes)
    target = np.concatenate([np.broadcast_to(np.asarray(m, dtype=np.float64), (size,))
                             for m, size in zip(magnetizations, sizes)])
    coercive = np.concatenate([c.coercive for c in constants], axis=1)
    relay_weight = np.concatenate([c.relay_weight for c in constants], axis=1)
    inverse_scale = np.concatenate([c.inverse_scale for c in constants])
    stateless = np.array([reversible_magnetization(float(f), chi, h) for c, f in zip(constants, fields)
                          for chi, h in zip(c.reversible_susceptibility, c.reversible_saturation)])
    stateless += np.concatenate([c.anhysteretic_weight for c in constants]) * _share_numpy(
        field * np.concatenate([c.anhysteretic_inverse_scale for c in constants]), kind)
    relay_target = target - stateless
    low = field - coercive.max(axis=0)
    high = field + coercive.max(axis=0)

    def relay_part(offset):
        play = np.clip(offset[None, :], field - coercive, field + coercive)
        share = _share_numpy(play * inverse_scale[None, :], kind)
        return (relay_weight * share).sum(axis=0), play

    for _ in range(iterations):
        middle = 0.5 * (low + high)
        below = relay_part(middle)[0] < relay_target
        low = np.where(below, middle, low)
        high = np.where(below, high, middle)
    play = relay_part(0.5 * (low + high))[1]
    edges = np.cumsum([0] + sizes)
    return [HEMState(np.ascontiguousarray(play[:, lo:hi])) for lo, hi in zip(edges[:-1], edges[1:])]


def _share_numpy(scaled, kind):
    from scipy.special import erf

    if kind == NORMAL:
        return erf(scaled)
    if kind == STUDENT_T2:
        return scaled / np.sqrt(2.0 + scaled * scaled)
    return (2.0 / np.pi) * np.arctan(scaled)


def simulate_hem_batch(field, batch: HEMBatch, state: HEMState | None = None) -> np.ndarray:
    """M (A/m) of every model of ``batch`` along one sampled field (A/m), shape ``(len(field), size)``.

    Starts from ``state`` (default: demagnetized) and moves it to ``field[0]`` first, so a demagnetized
    start at ``field[0] != 0`` is the initial curve's point there."""
    field = np.ascontiguousarray(np.asarray(field, dtype=np.float64))
    if field.ndim != 1 or field.size == 0 or not np.all(np.isfinite(field)):
        raise ValueError(f"field must be a non-empty finite 1-D array of A/m, got shape {field.shape}")
    state = batch.demagnetized() if state is None else HEMState(np.array(state.play, dtype=np.float64))
    if state.play.shape != (batch.coercive_nodes, batch.size):
        raise ValueError(f"state.play has shape {state.play.shape}, expected {(batch.coercive_nodes, batch.size)}")
    return simulate_shared(field, state, batch.constants(), batch.kind)


def simulate_hem(field, **params) -> np.ndarray:
    """M (A/m) of one HEM model (:class:`HEMParams` fields as keywords) along ``field`` (A/m), from the
    demagnetized state.

    Examples
    --------
    >>> import numpy as np
    >>> H = 100 * np.sin(np.linspace(0, 4 * np.pi, 801))
    >>> M = simulate_hem(H, coercive_median=20.0, interaction_scale=30.0)
    """
    return simulate_hem_batch(field, HEMBatch.from_params(HEMParams(**params)))[:, 0]


__all__ = [
    "ANHYSTERETIC_POPULATION", "DEFAULT_COERCIVE_NODES", "HEMBatch", "HEMConstants", "HEMParams", "HEMState",
    "INTERACTION_DENSITIES", "LINEAR_REVERSIBLE_ONLY", "LORENTZIAN", "NORMAL", "SATURATING_REVERSIBLE",
    "SATURATING_REVERSIBLE_PARTS", "STUDENT_T2", "WITH_ANHYSTERETIC_POPULATION", "advance_each", "advance_shared",
    "atan_inline", "coercive_rule", "erf_inline", "field_of", "interaction_density_code", "relay_share",
    "reversible_magnetization", "simulate_hem", "simulate_hem_batch", "simulate_shared", "stateless_magnetization",
    "stateless_parts", "state_with_magnetization", "states_with_magnetization", "validate_hem_parameters",
]
