"""What a diagnosis produces: the fitted candidates and the report."""

from __future__ import annotations

from dataclasses import dataclass, field as dataclass_field

import numpy as np

from .decide import Plausibility
from .effects import EFFECT_SLOTS
from .fit import FitResult, Split
from .identifiability import channel_set
from .model import Structure
from .report import physical_params


@dataclass
class Candidate:
    effect: str
    fit: FitResult
    heldout_rmse: float
    bic: float
    improvement: float
    accepted: bool
    plausibility: Plausibility = dataclass_field(default_factory=Plausibility)
    #: normalized residual on the held-out block (channels concatenated), for the tie test
    heldout_residual: np.ndarray | None = dataclass_field(default=None, repr=False)
    #: its mechanics ran into their prior (like the base model's, :func:`.priors.pinned_priors`)
    mechanics_pinned: bool = False
    #: why it failed (a fit the solver gave up on, a prediction that is not finite); None: it did not.
    #: A failed candidate has an infinite held-out RMSE and is never accepted.
    failure: str | None = None

    @classmethod
    def fitted(cls, effect: str, fit: FitResult, split: Split) -> "Candidate":
        """A candidate for ``fit`` of ``effect``, with its held-out error; not yet scored against the base
        (improvement 0, not accepted)."""
        heldout, residual, failure = heldout_or_failure(split, fit)
        return cls(effect, fit, heldout, fit.bic, improvement=0.0, accepted=False, heldout_residual=residual,
                   failure=failure)

    def refitted(self, fit: FitResult, split: Split):
        """Take ``fit`` (a better fit of the same extension) with its held-out error."""
        self.fit = fit
        self.heldout_rmse, self.heldout_residual, self.failure = heldout_or_failure(split, fit)
        self.bic = fit.bic

    def to_json(self) -> dict:
        return {"effect": self.effect, "heldout_rmse": self.heldout_rmse, "bic": self.bic,
                "delta_bic": None, "improvement": self.improvement, "accepted": self.accepted,
                "plausible": self.plausibility.plausible, "implausible_because": self.plausibility.reasons,
                "block_values": self.plausibility.block_values,
                "params": physical_params(self.fit), "uncertainties": self.fit.uncertainties,
                "failed": self.failure}


def heldout_or_failure(split: Split, fit: FitResult) -> tuple[float, np.ndarray, str | None]:
    """(held-out RMSE, held-out residual, why it failed or None) of ``fit``: a failed fit, or a prediction
    of the held-out block that is not finite, gives an infinite RMSE and the reason."""
    if fit.failure is not None:
        return float("inf"), None, fit.failure
    with np.errstate(over="ignore", invalid="ignore"):
        heldout, _, residual = split.heldout(fit.model, fit.values)
    if not np.isfinite(heldout):
        return float("inf"), None, "its prediction of the held-out block is not finite (the simulation diverged)"
    return heldout, residual, None


@dataclass
class Report:
    """What the tool found. ``to_json()`` gives the machine-readable report."""

    source: str
    verdict: str
    confidence: float
    explanation: str
    baseline: FitResult
    baseline_heldout: float
    candidates: list
    located: dict
    improvement: float
    structure: Structure
    split_index: int
    noise: dict
    seconds: float
    chosen: Candidate | None = None
    heldout_by_channel: dict = dataclass_field(default_factory=dict)
    tied: list = dataclass_field(default_factory=list)
    advice: str = ""
    notes: list = dataclass_field(default_factory=list)
    skipped: dict = dataclass_field(default_factory=dict)
    #: structured part of the base model's held-out residual (:func:`.locate.structured_power`)
    material_structure: dict = dataclass_field(default_factory=dict)
    #: pinned priors and whether they bind; directions the record leaves open
    identifiability: dict = dataclass_field(default_factory=dict)
    #: continuum mechanics tried when the residual lives near or above the first resonance (:func:`try_continuum`)
    continuum: dict = dataclass_field(default_factory=dict)
    #: every recording diagnosed together (empty: the baseline's own, one record)
    recordings: list = dataclass_field(default_factory=list, repr=False)
    #: each record's held-out errors when several were diagnosed together (:mod:`.joint`); empty for one
    per_record: list = dataclass_field(default_factory=list)

    def next_drive(self, path=None, seed: int = 0):
        """The drive that best separates the hypotheses this report leaves standing
        (:func:`.next_drive.design_next_drive`), written as CSV ``time,field`` to ``path`` if given; None (and
        nothing written) when the verdict is a confident single name."""
        from .next_drive import design_next_drive

        design = design_next_drive(self, records=self.recordings or None, seed=seed)
        if design is not None and path is not None:
            design.write_csv(path)
        return design

    @property
    def slot(self) -> str | None:
        """The slot of the model chain the verdict fills, in an engineer's words (None unless an effect)."""
        return EFFECT_SLOTS.get(self.verdict)

    def to_json(self) -> dict:
        items = []
        for c in self.candidates:
            item = c.to_json()
            item["delta_bic"] = c.bic - self.baseline.bic
            items.append(item)
        return {
            "source": self.source, "verdict": self.verdict, "slot": self.slot,
            "slots_tied": [EFFECT_SLOTS[c.effect] for c in self.tied] if self.verdict == "ambiguous" else [],
            "confidence": self.confidence,
            "confidence_means": "margin of the verdict over its nearest alternative, as a share of the held-out "
                                "reduction (0-1; not a probability: see the reliability table in the README)",
            "channel_set": channel_set(self.baseline.model.recording.channels),
            "candidates_tied": [c.effect for c in self.tied] if self.verdict == "ambiguous" else [],
            "separating_measurement": self.advice, "notes": self.notes, "effects_not_tried": self.skipped,
            "explanation": self.explanation,
            "baseline": {"model": self.structure.transducer, "anhysteretic": self.structure.anhysteretic,
                         "heldout_rmse": self.baseline_heldout, "bic": self.baseline.bic,
                         "params": physical_params(self.baseline),
                         "uncertainties": self.baseline.uncertainties},
            "candidates": items, "located": self.located, "improvement": self.improvement,
            "heldout_rmse_units": "noise units (residual / channel noise level); 1 = explained to within noise",
            "heldout_rmse_by_channel": self.heldout_by_channel, "noise_level": self.noise,
            "split": {"fit_samples": self.split_index, "heldout_from_time_s": None},
            "material_structure": self.material_structure, "identifiability": self.identifiability,
            "continuum": self.continuum, "seconds": self.seconds,
        } | ({"records": self.per_record} if self.per_record else {})
