"""The five stages of the mismatch tool: calibrate, locate, hypothesize, decide, report.

``diagnose(recording_or_path, model="lumped", ...)`` returns a :class:`~.results.Report`.

The recording is split in time (:class:`~.fit.Split`): the first ``1 - holdout`` of the samples
fit every model, the last ``holdout`` (a contiguous block) is only predicted. Errors are in noise
units (each channel's residual divided by its noise level, estimated from second differences, which
see the white part of the noise), so a model that explains the data to within white noise has a
held-out RMSE near 1; coloured noise is found and handled in the materiality check (:mod:`.decide`,
"Coloured noise"), and a note reports it. The decision rule, the
plausibility checks and the meaning of ``confidence`` are in :mod:`.decide`.
"""

from __future__ import annotations

import os
import time as _time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm.auto import tqdm

from . import locate
from .continuum import CONTINUUM_POWER_SHARE, resonance_power_share, try_continuum
from .decide import EXPLAINED_RMSE, MATERIAL_SHARE, check_plausibility, decide
from .effects import RATE_EFFECTS, applicable_effects
from .fit import Split
from .joint import joint_decision
from .hypothesize import calibrate, cross_start, fit_candidate, guard_base
from .identifiability import describe_direction, invisible_effects, unidentified_directions
from .model import MECHANICS_TOLERANCE, Structure
from .priors import pinned_priors, prior_notes, release_prior
from .recording import Recording, read_recording
from .report import explain
from .results import Candidate, Report

#: Largest |value| of any column, in its SI unit: beyond it the record is in the wrong units (no field,
#: magnetization, displacement or time of a transducer comes near it), and the fit's squares and products
#: would leave the floating-point range.
MAX_MAGNITUDE = 1e30
#: Smallest span of the field and of an output channel, in its SI unit (a displacement of 1e-30 m is far
#: below any sensor); below it, or below 1e-12 of the channel's magnitude, the channel is constant.
MIN_SPAN = 1e-30

#: Default number of threads that fit candidates at once: the cores, at most 4 (each thread runs
#: compiled simulations that release the GIL; beyond the cores, threads only compete).
DEFAULT_WORKERS = max(1, min(4, os.cpu_count() or 1))


def diagnose(recording, model: str = "lumped", anhysteretic: str = "ising", fit_mechanics: bool = True,
             holdout: float = 0.3, effects=None, progress: bool = True, locate_windows: int = 4,
             mechanics_tolerance: float = MECHANICS_TOLERANCE, workers: int | None = None) -> Report:
    """Run the five stages on a recording (a :class:`Recording` or a CSV path), or on several recordings of
    the same system under different drives (a list or tuple of them): then the first is diagnosed alone and
    every hypothesis is refitted to all of them jointly (:mod:`.joint`). A list of one is the one record.

    Parameters
    ----------
    model : {"first_order", "lumped", "lumped_nonlinear", "fem"}
        Base transducer for a displacement channel (ignored for magnetization-only data).
    anhysteretic : {"ising", "langevin"}
        Base anhysteretic curve (2)/(3).
    fit_mechanics : bool
        Fit the lumped coefficients chat, khat (True) or fix them at the paper's values (13).
    holdout : float
        Fraction of the recording, at its end, held out for the decision.
    effects : list of str, optional
        Restrict the candidates (default: every applicable vocabulary effect).
    mechanics_tolerance : float
        Factor (>= 1) within which the fit keeps khat and chat of their nominal values.
    workers : int, optional
        Threads that fit candidate extensions at once (default :data:`DEFAULT_WORKERS`). The
        report does not depend on it: each candidate's fit is the same in any thread and order.
    """
    workers = DEFAULT_WORKERS if workers is None else workers
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    # Small dense linear algebra (4x4 matrix exponentials, SVDs of tall Jacobians) runs slower
    # with BLAS threads than without: one 8000-sample diagnosis took 61 s with them and 8.4 s
    # without on a loaded 2-core machine.
    if isinstance(recording, (list, tuple)):
        if not recording:
            raise ValueError("recording: an empty list; give one recording or several")
        recordings = [r if isinstance(r, Recording) else read_recording(r) for r in recording]
        if len(recordings) > 1:
            with threadpool_limits(limits=1, user_api="blas"):
                return _diagnose_jointly(recordings, model, anhysteretic, fit_mechanics, holdout, effects, progress,
                                         locate_windows, mechanics_tolerance, workers)
        recording = recordings[0]
    with threadpool_limits(limits=1, user_api="blas"):
        return _diagnose(recording, model, anhysteretic, fit_mechanics, holdout, effects, progress,
                         locate_windows, mechanics_tolerance, workers)


def check_usable(recording: Recording) -> None:
    """A one-line ``ValueError`` naming the recording and the column when the tool cannot fit it: values
    beyond ``MAX_MAGNITUDE`` (wrong units), or a field or output channel that does not vary."""
    units = {"time": "s", "field": "A/m", "magnetization": "A/m", "displacement": "m"}
    for name in ("time", "field") + recording.channels:
        values = getattr(recording, name)
        peak = float(np.max(np.abs(values)))
        if peak > MAX_MAGNITUDE:
            raise ValueError(f"{recording.source}: column '{name}' reaches {peak:.3g} {units[name]}, beyond "
                             f"{MAX_MAGNITUDE:.0e}: no transducer record comes near it (check the units)")
        if name == "time":
            continue
        span = float(np.ptp(values))
        if span <= max(MIN_SPAN, 1e-12 * peak):
            what = "is constant" if span == 0.0 else f"spans only {span:.3g} {units[name]} (constant to the fit)"
            raise ValueError(f"{recording.source}: column '{name}' {what}, at {float(values[0]):.6g} {units[name]}: "
                             "the tool needs a field that varies and outputs that respond to it (check the units)")


def _effects_to_try(recording, structure, effects):
    """Candidate effects, and the vocabulary effects left out with the reason why."""
    skipped = {e: "this channel set cannot show it" for e in invisible_effects(recording.channels)}
    if effects is not None:
        return list(effects), skipped
    chosen = applicable_effects(recording, structure)
    if recording.metadata.get("time_axis") == "synthetic":
        # quasi-static loops on a made-up time axis: a rate, a delay or a resonance has no meaning
        for effect in RATE_EFFECTS:
            if effect in chosen:
                chosen.remove(effect)
                skipped[effect] = "the time axis is synthetic (sidecar time_axis), so it carries no rate"
    return chosen, skipped


#: Candidates whose fits take longest (several starts, a global search, two curves or a heating law per
#: simulation): they start first, so that no thread is left with one of them alone at the end (on a
#: 20,000-sample rod record anhysteretic_shape, last but two in the vocabulary, ran alone for seconds).
#: Only the order of the work; the candidates come back in the vocabulary's order, and each fit is the
#: same in any order.
SLOW_CANDIDATES = ("anhysteretic_shape", "thermal_drift", "rod_dynamics", "small_loop", "sensor_lag",
                   "quadratic_magnetostriction")


def _candidates(split, base, names, bar, workers):
    """Stage 3: every candidate fitted and held out, then the runners-up refitted from the best."""
    def fitted(name):
        return Candidate.fitted(name, fit_candidate(split, base, name), split)

    names = list(names)
    order = sorted(range(len(names)), key=lambda i: (names[i] not in SLOW_CANDIDATES,
                                                      SLOW_CANDIDATES.index(names[i]) if names[i] in SLOW_CANDIDATES
                                                      else i))
    by_position = {}
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for position, candidate in zip(order, pool.map(fitted, [names[i] for i in order])):
            by_position[position] = candidate
            bar.update(1)
    candidates = [by_position[i] for i in range(len(names))]  # in the vocabulary's order
    cross_start(candidates, split.heldout(base.model, base.values)[0], split, workers=workers)
    return candidates


def _check_candidates(split, base, base_heldout, candidates):
    """Plausibility of the accepted candidates, and the base's pinned priors released. Returns the
    prior record, the released fit (None unless a prior is pinned) and whether the mechanics bind."""
    for candidate in candidates:
        if candidate.accepted:
            candidate.plausibility = check_plausibility(candidate, split.noise)
    pinned = pinned_priors(base)
    release, released = ({}, None) if not pinned else release_prior(base, pinned, split, base_heldout)
    mechanics_pinned = bool(release.get("binds"))
    if mechanics_pinned:
        # a candidate that frees the mechanics is evidence too (decide.freeing_candidates)
        for candidate in candidates:
            candidate.mechanics_pinned = bool(pinned_priors(candidate.fit))
            if not candidate.accepted and not candidate.mechanics_pinned and candidate.heldout_rmse <= EXPLAINED_RMSE:
                candidate.plausibility = check_plausibility(candidate, split.noise)
    return release, released, mechanics_pinned


def read_notes(recording) -> list:
    """What the reader accepted that a user should know of (a byte-order mark, a ';' or tab delimiter)."""
    return [f"{recording.source}: {note}" for note in (recording.metadata or {}).get("read_notes", [])]


def _failure_notes(candidates) -> list:
    """One note per candidate that failed (never accepted, so never named), with the reason."""
    return [f"{c.effect} could not be fitted and was left out ({c.failure})" for c in candidates if c.failure]


def _structure_left(split, base, located):
    """The structured part of the base model's held-out residual (each channel read as its noise's colour
    allows, :func:`.locate.residual_structure`), that residual, and the note on coloured noise (None if white)."""
    _, heldout_by_channel, base_residual = split.heldout(base.model, base.values)
    recording = split.recording
    predicted = base.model.predict(base.values)
    state = locate.drive_state(recording.field, recording.time)

    def normalized(ch, mask):
        return (predicted[ch][mask] - recording.output(ch)[mask]) / split.noise[ch]

    structure_left = locate.residual_structure({ch: normalized(ch, split.held_mask) for ch in base.model.channels},
                                               {ch: normalized(ch, split.fit_mask) for ch in base.model.channels},
                                               state[split.held_mask], state[split.fit_mask])
    structure_left.update(material_share=MATERIAL_SHARE, material=bool(structure_left["share"] >= MATERIAL_SHARE),
                          where=located["summary"])
    return structure_left, base_residual, locate.colour_note(structure_left, heldout_by_channel)


def _diagnose(recording, model, anhysteretic, fit_mechanics, holdout, effects, progress, locate_windows,
              mechanics_tolerance, workers=1) -> Report:
    started = _time.perf_counter()
    if not isinstance(recording, Recording):
        recording = read_recording(recording)
    if not (0.05 <= holdout <= 0.5):
        raise ValueError(f"holdout must be in [0.05, 0.5], got {holdout!r}")
    check_usable(recording)
    transducer = model if "displacement" in recording.channels else "none"
    structure = Structure(transducer, anhysteretic, None, fit_mechanics, mechanics_tolerance)
    split = Split.of(recording, holdout)
    candidates_to_try, skipped = _effects_to_try(recording, structure, effects)
    bar = tqdm(total=2 + len(candidates_to_try) + 1, desc="diagnose", disable=not progress, leave=False)

    bar.set_postfix_str("calibrate")
    base = calibrate(split, structure, progress=bar, workers=workers)
    if base.failure is not None:
        raise ValueError(f"{recording.source}: the base model could not be fitted to this recording ({base.failure})")
    bar.set_postfix_str("locate")
    located = locate.locate_mismatch(base, split.noise, windows=locate_windows)
    bar.set_postfix_str("candidates")
    candidates = _candidates(split, base, candidates_to_try, bar, workers)

    bar.set_postfix_str("decide")
    base, base_heldout = guard_base(base, candidates, split)
    release, released, mechanics_pinned = _check_candidates(split, base, base_heldout, candidates)
    notes_on_priors = prior_notes(base, release)
    structure_left, base_residual, colour_note = _structure_left(split, base, located)
    decision = decide(candidates, base_heldout, recording.channels, mechanics_pinned=mechanics_pinned,
                      base_structure=structure_left, base_residual=base_residual)
    continuum = {}
    # a second mode that names the mechanical slot but leaves a material residual (a continuum rod whose
    # modes one extra mode cannot all follow) gets the slot's richer family too; it replaces the second
    # mode only where it explains the record, so the verdict can only gain
    second_mode_short = (decision.verdict == "rod_dynamics" and decision.chosen is not None
                         and decision.chosen.heldout_rmse > EXPLAINED_RMSE)
    if ((decision.verdict == "unexplained" or second_mode_short) and structure.transducer == "lumped"
            and "displacement" in recording.channels):
        share = resonance_power_share(base, split.noise)
        if share >= CONTINUUM_POWER_SHARE:
            bar.set_postfix_str("continuum")
            continued, continuum = try_continuum(split, base, released if mechanics_pinned else None, decision,
                                                 base_heldout, share, workers)
            if decision.verdict == "unexplained" or continuum["named"]:
                decision = continued
            else:
                decision.notes.append(f"the second mode leaves {decision.chosen.heldout_rmse:.2f} noise units "
                                      "held out; continuum mechanics tried, neither explains more: "
                                      + "; ".join(f"{label}: {tried['heldout_rmse']:.2f}"
                                                  for label, tried in continuum["tried"].items()))
    directions = unidentified_directions(base, split.noise, split.fit_mask)
    if directions:
        notes_on_priors.append("the record does not determine " + "; ".join(
            f"{describe_direction(d)}: to identify it, {d['measurement']}" for d in directions))
    bar.update(1)
    bar.close()

    heldout_by_channel = {"baseline": split.heldout(base.model, base.values)[1]}
    chosen = decision.chosen
    if chosen is not None:
        heldout_by_channel["verdict"] = split.heldout(chosen.fit.model, chosen.fit.values)[1]
    report = Report(source=recording.source, verdict=decision.verdict, confidence=decision.confidence,
                    explanation="", baseline=base, baseline_heldout=base_heldout, candidates=candidates,
                    located=located, improvement=float(chosen.improvement) if chosen else 0.0, structure=structure,
                    split_index=split.cut, noise=split.noise, seconds=0.0, chosen=chosen,
                    heldout_by_channel=heldout_by_channel, tied=decision.tied, advice=decision.advice,
                    notes=read_notes(recording) + ([colour_note] if colour_note else []) + decision.notes
                    + notes_on_priors + _failure_notes(candidates),
                    skipped=skipped,
 material_structure=structure_left,
                    identifiability={"priors": release, "unidentified": directions}, continuum=continuum)
    report.explanation = explain(report)
    report.seconds = _time.perf_counter() - started
    return report


def _diagnose_jointly(recordings, model, anhysteretic, fit_mechanics, holdout, effects, progress, locate_windows,
                      mechanics_tolerance, workers) -> Report:
    """The first record diagnosed alone, then every hypothesis refitted to all the records (:mod:`.joint`)."""
    started = _time.perf_counter()
    first = recordings[0]
    for other in recordings[1:]:
        check_usable(other)
        if other.channels != first.channels:
            raise ValueError(f"{other.source}: records channels {', '.join(other.channels)} but {first.source} "
                             f"records {', '.join(first.channels)}; a joint diagnosis needs the same channels")
    single = _diagnose(first, model, anhysteretic, fit_mechanics, holdout, effects, progress, locate_windows,
                       mechanics_tolerance, workers)
    base, base_heldout, candidates, decision, per_record, structure_left, noise = joint_decision(
        single, recordings, holdout, workers)
    chosen = decision.chosen
    heldout_by_channel = {"baseline": per_record[0]["baseline_heldout_rmse_by_channel"]}
    if chosen is not None:
        heldout_by_channel["verdict"] = per_record[0]["verdict_heldout_rmse_by_channel"]
    notes = decision.notes + [f"diagnosed jointly from {len(recordings)} records (parameters shared, drives and "
                              "start states per record); the plausibility checks, the location and the priors' "
                              f"notes are the first record's ({first.source})"] + _failure_notes(candidates)
    report = Report(source=" + ".join(r.source for r in recordings), verdict=decision.verdict,
                    confidence=decision.confidence, explanation="", baseline=base, baseline_heldout=base_heldout,
                    candidates=candidates, located=single.located,
                    improvement=float(chosen.improvement) if chosen else 0.0, structure=single.structure,
                    split_index=single.split_index, noise=noise, seconds=0.0, chosen=chosen,
                    heldout_by_channel=heldout_by_channel, tied=decision.tied, advice=decision.advice, notes=notes,
                    skipped=single.skipped, material_structure=structure_left,
                    identifiability=single.identifiability, continuum={}, recordings=list(recordings),
                    per_record=per_record)
    report.explanation = explain(report)
    report.seconds = _time.perf_counter() - started
    return report
