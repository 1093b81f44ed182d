"""What each channel set can tell apart, and which measurement separates what it cannot.

A recording holds the field (or the coil current) and one or both outputs: magnetization M
and tip displacement x. The three channel sets see different things:

* **magnetization only** -- the hysteresis itself. Effects that act on the mechanics
  (``quadratic_magnetostriction``, ``rod_dynamics``, ``delta_e``) cannot show.
* **displacement only** -- M is seen through the mechanics. A lag of the displacement sensor,
  a rod mode above the first resonance and eddy-current loss all add phase lag that grows
  with frequency; a bias field, a different anhysteretic curve and an M^2 law all bend the
  static x-H curve. Which of them is present is then a question of degree, not of kind.
* **both** -- M pins the hysteresis, so what is left in x is mechanical, and a lag seen in
  M too is magnetic (eddy currents) or a sensor lag common to both.

``CONFUSABLE`` lists, per channel set, the pairs of vocabulary effects whose signatures
overlap, with the measurement that would separate them (each effect's ``confusable`` in the
registry, :mod:`.effects`). The decision stage uses it to word
an ``ambiguous`` verdict; it never uses it to pick a winner.
"""

from __future__ import annotations

import numpy as np

# The channel sets, the effects each cannot show (``mechanical``), the rate-dependent ones and the confusable
# pairs with their separating measurements are fields of the registry (:mod:`.effects`); these are its views.
from .effects import CHANNEL_SETS, CONFUSABLE, MECHANICAL_EFFECTS, RATE_EFFECTS


def channel_set(channels) -> str:
    """``"magnetization"``, ``"displacement"`` or ``"both"`` for a recording's output channels."""
    channels = set(channels)
    if channels == {"magnetization", "displacement"}:
        return "both"
    if channels in ({"magnetization"}, {"displacement"}):
        return next(iter(channels))
    raise ValueError(f"a recording needs magnetization and/or displacement, got {sorted(channels)}")


def separating_measurement(channels, effects) -> str:
    """The measurements that would tell ``effects`` (two or more) apart in this channel set."""
    table = CONFUSABLE[channel_set(channels)]
    effects = sorted(effects)
    advice = []
    for i, first in enumerate(effects):
        for second in effects[i + 1:]:
            text = table.get(frozenset({first, second}))
            if text is None:
                text = ("refit on a longer record with a richer drive (minor loops, several rates): "
                        "the two fit this one equally well")
            if text not in advice:
                advice.append(text)
    return "; ".join(advice)


def invisible_effects(channels) -> tuple:
    """Vocabulary effects this channel set cannot show at all."""
    return MECHANICAL_EFFECTS if channel_set(channels) == "magnetization" else ()


__all__ = ["CHANNEL_SETS", "CONFUSABLE", "MECHANICAL_EFFECTS", "RATE_EFFECTS", "channel_set",
           "invisible_effects", "separating_measurement"]


# ---------------------------------------------------------------------------- the base fit


#: A direction of the fitted parameters is unidentified when its 1-sigma exceeds this, in relative
#: units (ln of a positive parameter; a linear one over its magnitude): the record does not fix
#: that combination to within a factor of e.
UNIDENTIFIED_SIGMA = 1.0
#: Components of an unidentified direction listed in the report (|component| at least this).
DIRECTION_COMPONENT = 0.3


def measurement_for(names, values) -> str:
    """The measurement that would identify a direction made of ``names`` (fitted values ``values``)."""
    mechanical = {"khat", "chat", "lam", "Y", "ML", "cD", "cL", "f2", "damping2"}
    if mechanical & set(names):
        if "khat" in values:
            f1 = float(np.sqrt(values["khat"]) / (2 * np.pi))
            return f"excite near the first mechanical resonance (about {f1:.3g} Hz): a chirp or steps through it"
        return "excite near the mechanical resonances (a chirp or steps through them)"
    if {"zetahat", "nu", "zeta_fem", "zeta2", "M0", "zeta_q"} & set(names):
        return "record the magnetization beside the displacement (it pins the magnetostrictive gain and bias)"
    if "Ms" in names:
        return "drive closer to saturation"
    if {"a", "k", "rho", "c", "chi_r"} & set(names):
        return "drive loops at several amplitudes with reversals (minor loops)"
    if {"heating", "tau_th", "beta_Ms", "tau_th2", "thermal_share"} & set(names):
        return "record the coil or rod temperature, or a longer record"
    return "a longer record with a richer drive"


def unidentified_directions(fit, noise, mask) -> list:
    """Directions of the fitted parameters that the record does not determine (Fisher information).

    The Gauss-Newton covariance ``sigma^2 (J^T J)^-1`` of the fit (J: the Jacobian of the normalized
    residuals on ``mask``, in the fitted coordinates), taken to relative units (ln for positive
    parameters, value/|value| for linear ones) and diagonalized: an eigen-direction whose 1-sigma
    exceeds ``UNIDENTIFIED_SIGMA`` is a combination of parameters the record leaves open. Returns,
    largest first, ``{"sigma", "components": {name: weight}, "measurement"}``."""
    from .fit import Objective

    model = fit.model
    names = model.free_names
    if not names:
        return []
    x = model.x_from_values(fit.values)
    objective = Objective(model, noise, mask)
    J = objective.jacobian(x)
    dof = max(J.shape[0] - len(names), 1)
    covariance = np.linalg.pinv(J.T @ J) * (fit.sse / dof)
    relative = np.ones(len(names))
    for i, name in enumerate(names):
        p = model.parameters[name]
        if not p.log:
            relative[i] = p.scale / max(abs(fit.values[name]), 0.05 * (p.upper - p.lower))
    covariance = covariance * np.outer(relative, relative)
    eigenvalues, vectors = np.linalg.eigh(covariance)
    out = []
    for value, vector in sorted(zip(eigenvalues, vectors.T), key=lambda item: -item[0]):
        sigma = float(np.sqrt(max(value, 0.0)))
        if sigma <= UNIDENTIFIED_SIGMA:
            break
        components = {names[i]: float(vector[i]) for i in np.argsort(-np.abs(vector))
                      if abs(vector[i]) >= DIRECTION_COMPONENT}
        out.append({"sigma": sigma, "components": components,
                    "measurement": measurement_for(list(components), fit.values)})
    return out


def describe_direction(direction) -> str:
    terms = " ".join(f"{w:+.2f} {name}" for name, w in direction["components"].items())
    return f"{terms} (1-sigma {direction['sigma']:.2g} relative units)"
