"""Diagnose a recording: which physics does it show that the model leaves out?

    python examples/diagnose_csv.py --csv my_recording.csv     # your own CSV (format: docs/recording-format.md)
    python examples/diagnose_csv.py                            # a made-up recording with a concealed effect

Prints the verdict, its confidence and the held-out error before and after, and writes the
report as JSON and its plots.
"""
import argparse

from hyst_gym.diagnose import diagnose, make_recording, write_json, write_plots, write_recording

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--csv", help="a recording CSV (default: make one with a concealed eddy-current effect)")
parser.add_argument("--out", default="diagnosis", help="prefix of the report files")
args = parser.parse_args()

if args.csv is None:
    recording, sidecar = make_recording("eddy_current", seed=3, n_samples=1000)
    args.csv = f"{args.out}_recording.csv"
    write_recording(args.csv, recording, sidecar)

report = diagnose(args.csv, model="lumped", effects=["eddy_current", "field_bias", "sensor_lag"])
print(f"verdict: {report.verdict} (confidence {report.confidence:.2f})")
print(report.explanation)
baseline = report.to_json()["baseline"]["heldout_rmse"]
print(f"held-out error: {baseline:.2f} noise units with the base model, "
      f"{baseline * (1 - report.improvement):.2f} with the verdict's extension")
print(f"wrote {write_json(report, args.out + '.json')} and {len(write_plots(report, args.out + '_plots'))} plots")
