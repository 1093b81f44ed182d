"""The base model's priors: which ones pin the fit, and whether releasing them changes the held-out fit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .decide import MATERIAL_SHARE
from .fit import BASE_FIT_TOLERANCE, FitResult, Split
from .model import Model

#: Base-model parameters that carry a prior (nominal x/÷ tolerance). One at its bound means the base
#: model bends its mechanics to absorb something only if releasing it improves the held-out fit
#: materially (:func:`release_prior`): a bound binds, or the record does not determine the parameter.
PRIOR_PARAMETERS = ("khat", "chat")
#: Factor from nominal to which :func:`release_prior` widens a pinned prior.
RELEASED_TOLERANCE = 10.0


def pinned_priors(fit: FitResult) -> list:
    """Names of ``PRIOR_PARAMETERS`` that sit at their tolerance in ``fit``."""
    pinned = []
    for name in PRIOR_PARAMETERS:
        p = fit.model.parameters.get(name)
        if p is not None and p.free and (fit.values[name] <= p.lower * 1.001 or fit.values[name] >= p.upper * 0.999):
            pinned.append(name)
    return pinned


def release_prior(base: FitResult, pinned, split: Split, base_heldout) -> tuple[dict, FitResult]:
    """Refit the base model with the ``pinned`` priors widened to ``RELEASED_TOLERANCE`` of nominal.

    The prior binds when the released fit lowers the held-out mean square by at least
    ``MATERIAL_SHARE`` (noise units squared); otherwise the record does not determine the pinned
    parameters, and their sitting at the bound says nothing about missing physics.
    Returns the record of what was tried and the released fit."""
    params = dict(base.model.parameters)
    for name in pinned:
        p = params[name]
        nominal = float(np.sqrt(p.lower * p.upper))
        params[name] = replace(p, lower=nominal / RELEASED_TOLERANCE, upper=nominal * RELEASED_TOLERANCE)
    model = Model(base.model.recording, base.model.structure, params, base.model.max_field_step)
    released = split.fit(model, base.values, max_nfev=60, tolerance=BASE_FIT_TOLERANCE)
    # a released fit that failed (the solver gave up) explains nothing: no gain
    heldout = split.heldout(model, released.values)[0] if released.failure is None else float("inf")
    gain = base_heldout ** 2 - heldout ** 2 if np.isfinite(heldout) else float("-inf")
    return {"pinned": {n: base.values[n] for n in pinned}, "released_values": {n: released.values[n] for n in pinned},
            "released_heldout_rmse": heldout, "heldout_mean_square_gain": gain,
            "binds": bool(gain >= MATERIAL_SHARE)}, released


def prior_notes(base: FitResult, release: dict) -> list:
    """What the pinned priors mean, after :func:`release_prior`."""
    notes = []
    for name, value in release.get("pinned", {}).items():
        p = base.model.parameters[name]
        nominal = np.sqrt(p.lower * p.upper)
        head = (f"the base model's {name} = {value:.4g} is pinned at its tolerance ({nominal:.4g} x/÷ "
                f"{np.sqrt(p.upper / p.lower):.3g})")
        if release["binds"]:
            notes.append(f"{head}, and releasing it lowers the held-out mean square by "
                         f"{release['heldout_mean_square_gain']:.2f} noise units^2 (material): the base model bends "
                         "its mechanics to absorb something")
        else:
            notes.append(f"{head}, but releasing it changes the held-out mean square by only "
                         f"{release['heldout_mean_square_gain']:+.2f} noise units^2 (material from "
                         f"{MATERIAL_SHARE:.2f}): the record does not determine {name}; the bound absorbs nothing")
    return notes
