"""``hyst-gym diagnose RECORDING.csv``: find which physics a recording shows that the model lacks."""

from __future__ import annotations

import argparse
from pathlib import Path

from .pipeline import diagnose
from .model import TRANSDUCERS
from .report import write_json, write_plots


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", type=Path, nargs="+",
                        help="recording CSV (format: docs/recording-format.md), optional sidecar .json beside it; "
                             "several: one diagnosis of the same system under several drives")
    parser.add_argument("--model", default="lumped", choices=[t for t in TRANSDUCERS if t != "none"],
                        help="base transducer model for a displacement channel (default lumped, eq. 13)")
    parser.add_argument("--anhysteretic", default="ising", choices=("ising", "langevin"),
                        help="base anhysteretic curve (default ising, eq. 2)")
    parser.add_argument("--fix-mechanics", action="store_true",
                        help="fix the mechanics at the paper's values instead of fitting them "
                             "(lumped: chat, khat; fem: Y, ML, cD, cL)")
    parser.add_argument("--holdout", type=float, default=0.3, help="fraction held out at the end (default 0.3)")
    parser.add_argument("--json", type=Path, help="write the machine-readable report here (its folder must exist)")
    parser.add_argument("--plots", type=Path, help="write PNG plots into this folder (made if its parent exists)")
    parser.add_argument("--next-drive", type=Path, dest="next_drive",
                        help="write the drive (CSV time,field) that best separates the hypotheses left standing; "
                             "nothing is written when the verdict is a confident single name")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--workers", type=int, default=None,
                        help="threads fitting candidates at once (default: the cores, at most 4)")


def check_outputs(args) -> None:
    """One-line errors, before the diagnosis runs, for output paths it could not write: a ``--json`` file
    whose folder does not exist (no folders are made for it), a ``--plots`` folder that is a file or
    whose parent folder does not exist."""
    if args.json is not None:
        if args.json.is_dir():
            raise ValueError(f"--json {args.json}: is a folder; give a file name")
        if not args.json.parent.is_dir():
            raise ValueError(f"--json {args.json}: folder {args.json.parent} does not exist")
    next_drive = getattr(args, "next_drive", None)
    if next_drive is not None:
        if next_drive.is_dir():
            raise ValueError(f"--next-drive {next_drive}: is a folder; give a file name")
        if not next_drive.parent.is_dir():
            raise ValueError(f"--next-drive {next_drive}: folder {next_drive.parent} does not exist")
    if args.plots is not None:
        if args.plots.exists() and not args.plots.is_dir():
            raise ValueError(f"--plots {args.plots}: is a file, not a folder")
        if not args.plots.parent.is_dir():
            raise ValueError(f"--plots {args.plots}: folder {args.plots.parent} does not exist")


def main(args) -> int:
    check_outputs(args)
    recordings = args.recording if isinstance(args.recording, list) else [args.recording]
    report = diagnose(recordings, model=args.model, anhysteretic=args.anhysteretic,
                      fit_mechanics=not args.fix_mechanics, holdout=args.holdout, progress=not args.quiet,
                      workers=args.workers)
    print(f"verdict: {report.verdict} (confidence {report.confidence:.2f}, held-out RMSE "
          f"{report.baseline_heldout:.3g} -> "
          f"{report.chosen.heldout_rmse if report.chosen else report.baseline_heldout:.3g} noise units)")
    print(report.explanation)
    if args.json:
        print(f"report: {write_json(report, args.json)}")
    if getattr(args, "next_drive", None) is not None:
        design = report.next_drive(args.next_drive)
        if design is None:
            print(f"next drive: none written (the verdict {report.verdict} is a confident single name)")
        else:
            print(design.words())
            print(f"next drive: {args.next_drive}")
    if args.plots:
        for path in write_plots(report, args.plots):
            print(f"plot: {path}")
    return 0
