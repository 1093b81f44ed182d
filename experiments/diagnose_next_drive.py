"""Does the designed next drive decide what one record could not? First record -> designed follow-up -> joint
diagnosis, against a control follow-up (the first drive again, a new noise draw) -> joint diagnosis, on hidden
systems of all three generators.

The own generator's hidden system (:mod:`hyst_gym.diagnose.make_recording`) is replayed here under a given drive
with the same hidden parameters, the same start state (demagnetized, mechanics settled, the same bias M0), the
same absolute noise level and a new noise draw (:func:`replay`). The replay reuses the generator's own pieces in
the generator's order of random draws; it covers the effects of ``REPLAYABLE``. A static map's frame stays the
first record's: the amplifier's saturation field by passing the first drive ahead of the new one and keeping the
tail, the sensor map's range by applying the generator's drawn map over the first record's output range
(:func:`_framed_sensor_map`). The independent and other-forms generators replay with their own ``replay``.

Run: ``python -m experiments.diagnose_next_drive [--cases generator:effect:seed:channels ...] [--samples N]
[--resume]``; writes ``experiments/results/diagnose/next_drive.json`` (after every case), ``next_drive.md`` and
the generated section of ``docs/results/next-drive.md``; ``--rewrite`` redoes the tables from the JSON.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hyst_gym.diagnose import diagnose
from hyst_gym.diagnose.effects import EFFECT_SLOTS
from hyst_gym.diagnose.identifiability import channel_set
from hyst_gym.diagnose.kernels import AMBIENT_TEMPERATURE, MAGNETIC_COLUMNS, simulate_members
from hyst_gym.diagnose.next_drive import design_next_drive
from hyst_gym.diagnose.recording import Recording

from experiments import independent_recordings as ir
from experiments import other_forms

# the module, not the function of the same name that the package exports
generator = importlib.import_module("hyst_gym.diagnose.make_recording")
OUT = Path(__file__).resolve().parent / "results" / "diagnose"
PAGE = Path(__file__).resolve().parents[1] / "docs" / "results" / "next-drive.md"
SECTION = "next-drive"
GENERATORS = ("own", "independent", "other_forms")
#: Effects whose generator this replay reproduces faithfully (the ties of the issue: input vs sensor lag,
#: input vs sensor map; and the lag and map themselves).
REPLAYABLE = ("input_lag", "sensor_lag", "input_map", "sensor_map", "none")


def _conditions(seed, n_samples, effect):
    """The generator's draws of the conditions (its first stream), in its order."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 6]))
    fs = rng.uniform(40e3, 60e3)
    time_axis = np.arange(n_samples) / fs
    fine_time = np.arange(n_samples * generator.OVERSAMPLE) / (fs * generator.OVERSAMPLE)
    field, amplitude, _ = generator._excitation(rng, fine_time)
    a, k, rho, Ms, c = (rng.uniform(4000, 9000), rng.uniform(800, 3000), rng.uniform(-0.6, 0.4),
                        rng.uniform(6e5, 9e5), rng.uniform(0.1, 0.4))
    curve = "langevin" if effect == "anhysteretic_shape" else "ising"
    if curve == "langevin":
        a = a / 3.0
    alpha = rho * a / Ms * (3.0 if curve == "langevin" else 1.0)
    mechanics = (generator.PAPER_CHAT * rng.uniform(0.8, 1.25), generator.PAPER_KHAT * rng.uniform(0.8, 1.25),
                 generator.PAPER_ZETAHAT * rng.uniform(0.8, 1.25))
    noise_rel = rng.uniform(0.5e-3, 1.5e-3)
    return dict(fs=fs, time=time_axis, fine_time=fine_time, field=field, amplitude=amplitude,
                material=dict(a=a, k=k, alpha=alpha, Ms=Ms, c=c, curve=curve), mechanics=mechanics,
                noise_rel=noise_rel)


def _clean_outputs(effect, seed, conditions, fine_field, M0=None, frame_field=None, frame_outputs=None):
    """The noiseless outputs on the fine grid under ``fine_field``, M0, and the outputs ahead of the static
    sensor map (a replay's ``frame_outputs``); the effect's draws in the generator's order."""
    effect_rng = np.random.default_rng(np.random.SeedSequence([int(seed), 6, 1]))
    fine_time, original = conditions["fine_time"], conditions["field"]
    row, kind = generator._magnetic_row(effect, 1.0, effect_rng, conditions["material"], original, fine_time,
                                        conditions["amplitude"])
    applied = fine_field
    if effect in generator.INPUT_GENERATORS:
        if effect == "input_map" and frame_field is not None:
            joined = np.concatenate([frame_field, fine_field])
            applied = generator.INPUT_GENERATORS[effect](joined, 1.0, effect_rng, fine_time, conditions["fs"])
            applied = np.ascontiguousarray(applied[frame_field.size:])
        else:
            applied = generator.INPUT_GENERATORS[effect](fine_field, 1.0, effect_rng, fine_time, conditions["fs"])
    magnetization = simulate_members(fine_time, applied, np.array([[row[c] for c in MAGNETIC_COLUMNS]]), kind, 25.0,
                                     AMBIENT_TEMPERATURE)[:, 0]
    M0 = float(np.median(magnetization)) if M0 is None else M0
    displacement = generator._displacement(effect, 1.0, effect_rng, fine_time, magnetization, M0,
                                           conditions["material"]["Ms"], conditions["mechanics"])
    outputs = {"magnetization": magnetization, "displacement": displacement}
    if effect == "sensor_lag":
        tau = effect_rng.uniform(2.0, 4.0) / conditions["fs"]
        outputs = {ch: generator.lti_response(fine_time, sig, [[-1 / tau]], [1 / tau], [1.0], start="steady")
                   for ch, sig in outputs.items()}
    unmapped = outputs
    if effect == "sensor_map":
        outputs = {ch: _framed_sensor_map(sig, sig if frame_outputs is None else frame_outputs[ch], effect_rng,
                                          fine_time) for ch, sig in sorted(outputs.items())}
    return outputs, M0, unmapped


def _framed_sensor_map(signal, frame, effect_rng, fine_time):
    """The generator's sensor map (its draws from ``effect_rng``, in its order) over the range of ``frame`` (the
    first record's output): the map is the sensor's, whatever range a replayed drive reaches. The generator's
    map, ``y + s*(q2*v^2 + q3*v^3)`` with v = (y - centre)/s over the signal's own range, is read off on the
    probe (-1, 0.5, 1) (centre 0, s 1): q2 + q3 = out(1) - 1, q2/4 + q3/8 = out(0.5) - 0.5."""
    probe = generator._sensor_map(np.array([-1.0, 0.5, 1.0]), 1.0, effect_rng, fine_time)
    top, middle = probe[2] - 1.0, probe[1] - 0.5
    q3 = 2.0 * top - 8.0 * middle  # from q2 = top - q3: (top - q3)/4 + q3/8 = middle
    q2 = top - q3
    lo, hi = float(np.min(frame)), float(np.max(frame))
    centre, half = 0.5 * (lo + hi), (0.5 * (hi - lo) or 1.0)
    v = (signal - centre) / half
    return signal + half * (q2 * v ** 2 + q3 * v ** 3)


def replay(effect: str, seed: int, output: str, n_samples: int, drive=None, noise_seed: int = 0) -> Recording:
    """The generator's hidden system under ``drive`` (A/m at the record's samples; None: its own drive), with the
    same hidden parameters, start state and absolute noise level as its own record and noise stream
    ``noise_seed`` (0: the generator's own noise draw)."""
    if effect not in REPLAYABLE:
        raise ValueError(f"effect must be one of {', '.join(REPLAYABLE)} to be replayed, got {effect!r}")
    conditions = _conditions(seed, n_samples, effect)
    original_outputs, M0, unmapped = _clean_outputs(effect, seed, conditions, conditions["field"])
    fine_field = conditions["field"]
    outputs = original_outputs
    if drive is not None:
        drive = np.asarray(drive, dtype=float)
        # the drive as recorded (its samples), held linearly between them on the generator's fine grid
        fine_field = np.interp(conditions["fine_time"], conditions["time"][:drive.size], drive)
        outputs, _, _ = _clean_outputs(effect, seed, conditions, fine_field, M0=M0, frame_field=conditions["field"],
                                       frame_outputs=unmapped)
    keep = slice(None, None, generator.OVERSAMPLE)
    channels = ("magnetization", "displacement") if output == "both" else (output,)
    noise_rng = np.random.default_rng(np.random.SeedSequence([int(seed), 6, 2] + ([int(noise_seed)] if noise_seed
                                                                                   else [])))
    recorded = {}
    for ch in channels:
        sigma = conditions["noise_rel"] * float(np.ptp(original_outputs[ch][keep]))  # the first record's level
        clean = outputs[ch][keep]
        recorded[ch] = clean + sigma * noise_rng.standard_normal(clean.size)
    n = recorded[channels[0]].size
    return Recording(time=conditions["time"][:n], field=fine_field[keep][:n],
                     source=f"replay {effect} seed {seed} noise {noise_seed}", **recorded)


# ---------------------------------------------------------------------------- the three generators

@dataclass(frozen=True)
class StudyCase:
    """One hidden system: which generator, its effect (the other-forms generator: its case), seed and channels."""

    generator: str
    effect: str
    seed: int
    channels: str

    @property
    def expected(self) -> frozenset:
        """The verdicts that count as right: an effect name (scored by its slot), ``none``, or (an effect
        outside the tool's vocabulary) ``unexplained``/``ambiguous``."""
        if self.generator == "own":
            return frozenset({self.effect})
        if self.generator == "independent":
            if not ir.EFFECT_SPECS[self.effect].in_vocabulary:
                return frozenset({"unexplained", "ambiguous"})
            return frozenset({ir.TOOL_NAMES.get(self.effect, self.effect)})
        return other_forms.CASES[self.effect].expected

    @property
    def label(self) -> str:
        return f"{self.generator}:{self.effect}:{self.seed}:{self.channels}"


def first_record(case: StudyCase, n_samples: int) -> Recording:
    """The case's first record (the generator's own drive and noise)."""
    if case.generator == "own":
        return replay(case.effect, case.seed, case.channels, n_samples)
    module = ir if case.generator == "independent" else other_forms
    return module.generate(case.effect, case.seed, case.channels, n_samples=n_samples)[0]


def replay_record(case: StudyCase, n_samples: int, drive, noise_seed: int) -> Recording:
    """The case's hidden system under ``drive`` with noise draw ``noise_seed`` (>= 1: never the first record's)."""
    if case.generator == "own":
        return replay(case.effect, case.seed, case.channels, n_samples, drive, noise_seed=noise_seed)
    module = ir if case.generator == "independent" else other_forms
    return module.replay(case.effect, case.seed, case.channels, drive, noise_seed=noise_seed,
                         n_samples=n_samples)[0]


def _right(report, expected) -> bool:
    """The verdict is right: it names an expected effect's slot, or is an expected ``none``/``unexplained``/
    ``ambiguous``."""
    if report.verdict in expected and report.verdict in ("none", "unexplained", "ambiguous"):
        return True
    return report.slot is not None and report.slot in {EFFECT_SLOTS[n] for n in expected if n in EFFECT_SLOTS}


def _wrong(report, expected) -> bool:
    """A single name of another slot than the expected ones."""
    return report.slot is not None and not _right(report, expected)


def _outcome(report, expected, follow_up: bool) -> dict:
    return {"verdict": report.verdict, "slot": report.slot, "confidence": report.confidence,
            "tied": [c.effect for c in report.tied] if report.verdict == "ambiguous" else [],
            "right": _right(report, expected), "wrong": _wrong(report, expected),
            "false_alarm": "none" in expected and report.verdict != "none", "follow_up": follow_up}


def run_case(case: StudyCase, n_samples: int, workers: int = 1) -> dict:
    """First record -> diagnosis -> designed drive; designed and control follow-ups -> joint diagnoses."""
    started = time.perf_counter()
    expected = case.expected
    first = first_record(case, n_samples)
    single = diagnose(first, progress=False, workers=workers)
    design = design_next_drive(single, seed=0)
    row = {"generator": case.generator, "effect": case.effect, "seed": case.seed, "channels": case.channels,
           "channel_set": channel_set(first.channels), "expected": sorted(expected),
           "slot": " / ".join(sorted({EFFECT_SLOTS.get(n, n) for n in expected})),
           "before": _outcome(single, expected, False), "load_average": round(os.getloadavg()[0], 2)}
    if design is None:  # a confident single name: no follow-up, the verdict stands
        row["design"] = None
        row["designed"] = row["control"] = dict(row["before"])
    else:
        row["design"] = design.to_json()
        designed = diagnose([first, replay_record(case, n_samples, design.field, 1)], progress=False,
                            workers=workers)
        control = diagnose([first, replay_record(case, n_samples, first.field, 2)], progress=False,
                           workers=workers)
        row["designed"] = _outcome(designed, expected, True)
        row["control"] = _outcome(control, expected, True)
    row["seconds"] = round(time.perf_counter() - started, 1)
    return row


#: The cases of the study, fixed before the run (two busy cores: 2000 samples each), in the order they run:
#: each round takes one seed of every effect of every generator, so that a run cut short still covers them all.
#: Own generator: the ties of the issue (input against sensor lag, amplifier against sensor map) and no effect.
#: Independent: the same ties in its forms, eddy current and heating (confused with the lags and the
#: anhysteretic shape) and no effect. Other forms: the amplifier's bandwidth and saturation, the resonant
#: sensor, the pinning's heating, the gain drift and no effect.
_ROUNDS = (
    [("own", e, "magnetization") for e in ("input_lag", "sensor_lag", "input_map", "sensor_map", "none")]
    + [("independent", e, "magnetization") for e in ("input_lag", "sensor_lag", "amplifier_saturation",
                                                     "sensor_nonlinearity", "eddy_current", "thermal_drift", "none")]
    + [("other_forms", e, c) for e, c in (("input_dynamics", "magnetization"),
                                          ("saturating_amplifier", "magnetization"), ("sensor_resonance", "both"),
                                          ("pinning_temperature", "magnetization"),
                                          ("sensor_gain_drift", "magnetization"),
                                          ("none_other_numerics", "magnetization"))])
#: Seeds 1-3 (the other-forms generator's study counts from 0: 0-2).
DEFAULT_CASES = tuple(StudyCase(g, e, seed - 1 if g == "other_forms" else seed, c) for seed in (1, 2, 3)
                      for g, e, c in _ROUNDS)
#: Bootstrap resamples of the paired difference (designed - control) in right verdicts.
BOOTSTRAP = 2000
STAGES = ("before", "designed", "control")


def summarize(rows) -> list:
    """Per generator, channel set and slot: right, wrong names and false alarms before / designed / control."""
    out = []
    for key in sorted({(r["generator"], r["channel_set"], r["slot"]) for r in rows}):
        group = [r for r in rows if (r["generator"], r["channel_set"], r["slot"]) == key]
        out.append({"generator": key[0], "channel_set": key[1], "slot": key[2], "cases": len(group),
                    "follow_ups": sum(r["design"] is not None for r in group),
                    **{k: sum(r[k]["right"] for r in group) for k in STAGES},
                    **{f"{k}_wrong": sum(r[k]["wrong"] for r in group) for k in STAGES},
                    **{f"{k}_confidence": float(np.mean([r[k]["confidence"] for r in group])) for k in STAGES}})
    return out


def paired_difference(rows, seed: int = 0) -> dict:
    """Designed minus control, right verdicts per case: the mean and a bootstrap 95 % interval over the cases."""
    difference = np.array([float(r["designed"]["right"]) - float(r["control"]["right"]) for r in rows])
    if difference.size == 0:
        return {"mean": float("nan"), "ci95": [float("nan"), float("nan")], "designed_only": 0, "control_only": 0,
                "cases": 0}
    rng = np.random.default_rng(seed)
    means = rng.choice(difference, (BOOTSTRAP, difference.size)).mean(axis=1)
    return {"mean": float(np.mean(difference)), "ci95": [float(np.percentile(means, 2.5)),
                                                         float(np.percentile(means, 97.5))],
            "designed_only": int(np.sum(difference > 0)), "control_only": int(np.sum(difference < 0)),
            "cases": int(difference.size)}


def rates(rows) -> dict:
    """Per channel set and stage: right share, wrong single names share, ``none`` false alarms share."""
    out = {}
    for channels in sorted({r["channel_set"] for r in rows}):
        group = [r for r in rows if r["channel_set"] == channels]
        nones = [r for r in group if "none" in r["expected"]]
        out[channels] = {k: {"right": float(np.mean([r[k]["right"] for r in group])),
                             "wrong": float(np.mean([r[k]["wrong"] for r in group])),
                             "false_alarms": float(np.mean([r[k]["false_alarm"] for r in nones])) if nones else None,
                             "cases": len(group)} for k in STAGES}
    return out


def payload_of(rows, samples: int) -> dict:
    generators = sorted({r["generator"] for r in rows})
    return {"samples": samples, "rows": rows, "summary": summarize(rows), "rates": rates(rows),
            "paired_designed_minus_control": paired_difference(rows),
            "paired_by_generator": {g: paired_difference([r for r in rows if r["generator"] == g])
                                    for g in generators},
            "design_seconds": {"median": float(np.median([r["design"]["seconds"] for r in rows if r["design"]]))
                               if any(r["design"] for r in rows) else None,
                               "max": max((r["design"]["seconds"] for r in rows if r["design"]), default=None)}}


def _ci(paired) -> str:
    return (f"{paired['mean']:+.2f} [{paired['ci95'][0]:+.2f}, {paired['ci95'][1]:+.2f}] over {paired['cases']} "
            f"hidden systems ({paired['designed_only']} right only after the designed drive, "
            f"{paired['control_only']} only after the control)")


def page_section(payload) -> str:
    """The generated section of docs/results/next-drive.md (between its markers)."""
    rows, paired = payload["rows"], payload["paired_designed_minus_control"]
    excludes = paired["ci95"][0] > 0
    planned = [c.label for c in DEFAULT_CASES]
    labels = [StudyCase(r["generator"], r["effect"], r["seed"], r["channels"]).label for r in rows]
    scope = (f"the first {len(rows)} of the {len(planned)} default cases, in their order: the run was cut short "
             "to fit the machine's time" if labels == planned[:len(rows)] and len(rows) < len(planned) else
             "the default cases" if labels == planned else "a chosen set of cases")
    present = [g for g in GENERATORS if any(r["generator"] == g for r in rows)]
    missing = [g for g in GENERATORS if g not in present]
    source = " and ".join(present) + (f" generators (none yet from {', '.join(missing)})" if missing else
                                      " generators")
    lines = [f"{len(rows)} hidden systems from the {source} ({scope}; {payload['samples']} samples per "
             "record), "
             "each replayed under the designed drive and, as the control, under its first drive again, each "
             "follow-up with a new noise draw; then the joint diagnosis of the two records. Right: the verdict "
             "names the concealed effect's slot (no effect: `none`). A first record named with confidence >= 0.8 "
             "gets no follow-up and keeps its verdict.", "",
             f"**Designed minus control, right verdicts per hidden system: {_ci(paired)}.** The target (a paired "
             f"95 % interval excluding 0) is {'met' if excludes else 'not met'} on this set.", "",
             "| generator | paired difference (designed - control) |", "|---|---|"]
    for generator, by in payload["paired_by_generator"].items():
        lines.append(f"| {generator} | {_ci(by)} |")
    lines += ["", "Per channel set, right / wrong single names / `none` false alarms (share of the hidden "
              "systems), before -> after the designed follow-up -> after the control:", "",
              "| channel set | systems | right | wrong names | false alarms |", "|---|---|---|---|---|"]

    def share(value):
        return "-" if value is None else f"{value:.2f}"

    for channels, by in payload["rates"].items():
        cells = [" / ".join(share(by[k][m]) for k in STAGES) for m in ("right", "wrong", "false_alarms")]
        lines.append(f"| {channels} | {by['before']['cases']} | " + " | ".join(cells) + " |")
    lines += ["", "| generator | channel set | slot | systems | follow-ups | right before | after designed | "
              "after control | wrong names (before / designed / control) | mean confidence "
              "(before / designed / control) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in payload["summary"]:
        lines.append(f"| {r['generator']} | {r['channel_set']} | {r['slot']} | {r['cases']} | {r['follow_ups']} | "
                     f"{r['before']} | {r['designed']} | {r['control']} | {r['before_wrong']} / "
                     f"{r['designed_wrong']} / {r['control_wrong']} | {r['before_confidence']:.2f} / "
                     f"{r['designed_confidence']:.2f} / {r['control_confidence']:.2f} |")
    seconds = payload["design_seconds"]
    if seconds["median"] is not None:
        lines += ["", f"Designing one drive took {seconds['median']:.1f} s (median), {seconds['max']:.1f} s at most "
                  f"({payload['samples']} samples; the machine shared, load average "
                  f"{np.median([r['load_average'] for r in rows]):.1f})."]
    lines += ["", "| generator | effect | seed | channels | before | designed | control | smallest predicted "
              "separation |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        smallest = min((p["separation"] for p in r["design"]["pairs"]), default=float("nan")) if r["design"] \
            else float("nan")
        lines.append(f"| {r['generator']} | {r['effect']} | {r['seed']} | {r['channels']} | "
                     + " | ".join(f"{r[k]['verdict']} ({r[k]['confidence']:.2f})" for k in STAGES)
                     + f" | {smallest:.3g} |")
    return "\n".join(lines) + "\n"


def write_page(payload, page: Path = PAGE) -> None:
    """Rewrite the generated section of ``page`` (between its markers) from ``payload``, and the same tables as
    ``next_drive.md`` beside the JSON."""
    (OUT / "next_drive.md").write_text("# The designed next drive against a control follow-up\n\n"
                                       + page_section(payload), encoding="utf-8")
    text = page.read_text(encoding="utf-8")
    start, end = f"<!-- section:{SECTION} -->", f"<!-- /section:{SECTION} -->"
    before, rest = text.split(start, 1)
    after = rest.split(end, 1)[1]
    page.write_text(before + start + "\n" + page_section(payload) + end + after, encoding="utf-8")


def _parse_case(text: str) -> StudyCase:
    parts = text.split(":")
    if len(parts) != 4 or parts[0] not in GENERATORS or not parts[2].isdigit():
        raise argparse.ArgumentTypeError(f"a case is generator:effect:seed:channels with generator one of "
                                         f"{', '.join(GENERATORS)}, got {text!r}")
    return StudyCase(parts[0], parts[1], int(parts[2]), parts[3])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", type=_parse_case, help="generator:effect:seed:channels (default: "
                        "the built-in list)")
    parser.add_argument("--generators", nargs="*", choices=GENERATORS, default=GENERATORS)
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path, default=OUT / "next_drive.json")
    parser.add_argument("--resume", action="store_true", help="keep the rows already in --out, run the rest")
    parser.add_argument("--rewrite", action="store_true",
                        help="rewrite the page section from --out (no diagnosis is run)")
    args = parser.parse_args(argv)
    stored = json.loads(args.out.read_text(encoding="utf-8")) if (args.rewrite or args.resume) and \
        args.out.exists() else {"rows": []}
    if args.rewrite:
        write_page(payload_of(stored["rows"], stored["samples"]))
        return
    cases = [c for c in (args.cases or DEFAULT_CASES) if c.generator in args.generators]
    done = {StudyCase(r["generator"], r["effect"], r["seed"], r["channels"]).label for r in stored["rows"]}
    rows = list(stored["rows"])
    for case in cases:
        if case.label in done:
            continue
        rows.append(run_case(case, args.samples, args.workers))
        r = rows[-1]
        print(f"{case.label}: {r['before']['verdict']} -> designed {r['designed']['verdict']}, control "
              f"{r['control']['verdict']} ({r['seconds']:.0f} s)", flush=True)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        payload = payload_of(rows, args.samples)
        args.out.write_text(json.dumps(payload, indent=1, default=float) + "\n", encoding="utf-8")
    if args.out.resolve() == (OUT / "next_drive.json").resolve() and rows:
        write_page(payload_of(rows, args.samples))


if __name__ == "__main__":
    main()
