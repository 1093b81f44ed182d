"""Several records, one diagnosis: every hypothesis refitted to all the records jointly.

The first record is diagnosed alone by the five stages (:func:`.pipeline.diagnose`); its base model and every
candidate it fitted are then refitted to all the records at once, from their single-record fits: one set of
parameters -- material, transducer, sensor and the effect's own -- shared by every record, the residual
vectors of the records' fitting blocks stacked (each record's channels over that record's own noise level).
Per record stay: the drive, the start state (each simulation starts from the model's start state at the
record's first sample: demagnetized, the mechanics settled) and the split into fitting and held-out blocks.

The sensors are shared, and so is their noise: each channel's noise level is the smallest of the records'
estimates (:func:`.model.noise_level`, from second differences, can only be raised by the signal's own content,
which a fast drive -- a designed one, say -- puts there), so no record is weighted down by its drive.

Each refit is scored on every record's held-out block; the verdict comes from the decision stage
(:func:`.decide.decide`) on the stacked held-out residuals, with the same bars. What stays single-record:
the plausibility checks (the block consistency is checked on the first record, with the joint parameters),
the location of the mismatch, the priors' notes and the identifiability of the base model (the first record's).
The frames of the static maps are per record (:func:`.model.channel_range` of each record's output, the
largest |field| of each record's drive), so a shared map coefficient is one map only where the records span
the same range.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.optimize

from . import locate
from .decide import MATERIAL_SHARE, check_plausibility, decide
from .fit import FIT_TOLERANCE, FitResult, Objective, Split, _uncertainties
from .hypothesize import in_threads, score
from .model import Model
from .results import Candidate

#: Most evaluations of one joint refit (each a simulation of every record).
JOINT_MAX_NFEV = 40


class JointObjective:
    """The stacked normalized residuals of one parameter set on the fitting blocks of several records."""

    def __init__(self, models, splits):
        self.parts = [Objective(m, s.noise, s.fit_mask) for m, s in zip(models, splits)]

    def __call__(self, x):
        return np.concatenate([part(x) for part in self.parts])

    def jacobian(self, x):
        return np.vstack([part.jacobian(x) for part in self.parts])

    @property
    def evaluations(self) -> int:
        return sum(part.evaluations for part in self.parts)


def record_models(model: Model, splits) -> list:
    """``model`` (a fit's model, its parameters shared) on each record of ``splits``."""
    return [Model(s.recording, model.structure, model.parameters, s.max_field_step) for s in splits]


def joint_fit(fit: FitResult, splits, max_nfev: int = JOINT_MAX_NFEV, tolerance: float = FIT_TOLERANCE) -> FitResult:
    """``fit`` (a single-record fit) refitted to every record of ``splits`` at once, from its values; the
    result's model is on the first record. A refit that is worse than the start keeps the start's values."""
    models = record_models(fit.model, splits)
    model = models[0]
    objective = JointObjective(models, splits)
    names = model.free_names
    lower = np.array([model.parameters[n].x_bounds[0] for n in names])
    upper = np.array([model.parameters[n].x_bounds[1] for n in names])
    span = upper - lower
    x0 = np.clip(np.clip(model.x_from_values(fit.values), lower, upper), lower + 1e-9 * span, upper - 1e-9 * span)
    failure = None
    start_residual = objective(x0)
    x, residual, J = x0, start_residual, np.zeros((start_residual.size, len(names)))
    if names:
        try:
            result = scipy.optimize.least_squares(objective, x0, jac=objective.jacobian, bounds=(lower, upper),
                                                  method="trf", x_scale="jac", max_nfev=max_nfev,
                                                  xtol=tolerance, ftol=tolerance)
            if float(result.fun @ result.fun) <= float(start_residual @ start_residual):
                x, residual, J = result.x, result.fun, result.jac
        except (ValueError, np.linalg.LinAlgError) as error:
            failure = f"the joint least-squares solver stopped: {str(error).splitlines()[0] if str(error) else error!r}"
    with np.errstate(over="ignore"):
        sse = float(residual @ residual)
    if not np.isfinite(sse) or fit.failure is not None:
        failure = failure or fit.failure or "the joint prediction is not finite"
        sse = float("inf")
    values = model.values_from_x(x)
    return FitResult(model.with_values(values), values, _uncertainties(model, names, x, J, sse, residual.size), sse,
                     residual.size, len(names), objective.evaluations, failure=failure)


def heldout_per_record(fit: FitResult, splits) -> tuple[list, np.ndarray]:
    """Per record: (RMSE, RMSE per channel) on its held-out block; and the held-out residuals stacked."""
    per_record, stacked = [], []
    for model, split in zip(record_models(fit.model, splits), splits):
        with np.errstate(over="ignore", invalid="ignore"):
            rmse, by_channel, residual = split.heldout(model, fit.values)
        per_record.append({"source": split.recording.source, "heldout_rmse": rmse,
                           "heldout_rmse_by_channel": by_channel})
        stacked.append(residual)
    return per_record, np.concatenate(stacked)


def joint_candidate(candidate: Candidate, splits) -> tuple[Candidate, list]:
    """``candidate`` refitted to every record, held out on each; and its per-record held-out errors."""
    fit = joint_fit(candidate.fit, splits)
    per_record, residual = heldout_per_record(fit, splits)
    rmse = float(np.sqrt(np.mean(residual ** 2))) if fit.failure is None else float("inf")
    failure = fit.failure
    if failure is None and not np.isfinite(rmse):
        failure, rmse = "its joint prediction of the held-out blocks is not finite", float("inf")
    joint = Candidate(candidate.effect, fit, rmse, fit.bic, improvement=0.0, accepted=False,
                      heldout_residual=residual if failure is None else None, failure=failure)
    return joint, per_record


def shared_noise(splits) -> list:
    """``splits`` with one noise level per channel, the smallest of their estimates (module docstring)."""
    noise = {ch: min(s.noise[ch] for s in splits) for ch in splits[0].noise}
    return [replace(s, noise=noise) for s in splits]


def joint_decision(single, recordings, holdout: float, workers: int = 1):
    """The report ``single`` (of the first record) redone on every record of ``recordings`` (module docstring).
    Returns (base fit, base held-out RMSE, joint candidates, decision, per-record errors, structure left, noise)."""
    splits = shared_noise([Split.of(r, holdout) for r in recordings])
    base = joint_fit(single.baseline, splits)
    base_records, base_residual = heldout_per_record(base, splits)
    base_heldout = float(np.sqrt(np.mean(base_residual ** 2)))
    refits = in_threads(lambda c: joint_candidate(c, splits), single.candidates, workers)
    candidates = [c for c, _ in refits]
    score(candidates, base, base_heldout)
    for candidate in candidates:
        if candidate.accepted:
            candidate.plausibility = check_plausibility(candidate, splits[0].noise)
    structure_left = locate.structured_power(base_residual)
    structure_left.update(material_share=MATERIAL_SHARE, material=bool(structure_left["share"] >= MATERIAL_SHARE),
                          where=single.located["summary"])
    decision = decide(candidates, base_heldout, recordings[0].channels, base_structure=structure_left,
                      base_residual=base_residual)
    per_record = []
    for i, record in enumerate(base_records):
        entry = {"source": record["source"], "samples": int(recordings[i].size),
                 "baseline_heldout_rmse": record["heldout_rmse"],
                 "baseline_heldout_rmse_by_channel": record["heldout_rmse_by_channel"],
                 "candidates": {c.effect: r[i]["heldout_rmse"] for c, r in refits}}
        if decision.chosen is not None:
            chosen = next(r for c, r in refits if c is decision.chosen)[i]
            entry.update(verdict_heldout_rmse=chosen["heldout_rmse"],
                         verdict_heldout_rmse_by_channel=chosen["heldout_rmse_by_channel"])
        per_record.append(entry)
    return base, base_heldout, candidates, decision, per_record, structure_left, dict(splits[0].noise)
