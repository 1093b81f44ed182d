"""``hyst-gym bench``: speed of every layer, printed and optionally written as JSON.

Each layer contributes a section through a module-level ``run_benchmark(report)``
function that prints human-readable lines with ``report(str)`` and returns a dict whose
keys are merged into the top level of the JSON output.
"""

from __future__ import annotations

import importlib
import json
import platform

import numpy as np

#: (section title, module providing run_benchmark)
SECTIONS = (
    ("hysteresis bank", "hyst_gym.physics.benchmark"),
    ("estimators", "hyst_gym.estimation.benchmark"),
    ("environments", "hyst_gym.envs.benchmark"),
)


def configure_parser(parser):
    parser.add_argument("--json", metavar="FILE", help="also write the figures as JSON to FILE")
    parser.add_argument("--only", choices=[m.rsplit(".", 2)[-2] for _, m in SECTIONS], action="append",
                        help="run only this layer's section (repeatable)")


def main(args) -> int:
    results = {"machine": {"platform": platform.platform(), "processor": platform.processor(),
                           "numpy": np.__version__}}
    for title, module_name in SECTIONS:
        layer = module_name.rsplit(".", 2)[-2]
        if args.only and layer not in args.only:
            continue
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as error:
            if error.name == module_name:
                print(f"[{title}] not available yet")
                continue
            raise
        print(f"== {title} ==", flush=True)
        results.update(module.run_benchmark(lambda line: print("  " + line, flush=True)))
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(results, handle, indent=2)
        print(f"wrote {args.json}")
    return 0
