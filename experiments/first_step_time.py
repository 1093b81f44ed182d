"""Time from ``import`` to the first ``env.step`` for a user who installs the wheel.

Builds the wheel from this checkout, installs it (no extras) into a fresh virtual
environment in a temporary folder, and runs, twice, a fresh interpreter that imports
gymnasium, makes ``hyst_gym/Excitation-v0``, resets and steps once. The first run compiles
the numba kernels (and says so on stderr); the second finds them in numba's on-disk cache.
Writes the figures to ``experiments/results/first_step_time.json`` and into the ``first-step``
section of ``docs/speed.md``, with whether the targets of :mod:`experiments.targets` are met,
and prints them.

    .venv/bin/python -m experiments.first_step_time [--no-readme]

Needs the package index (pip installs the core dependencies into the fresh venv).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULT = ROOT / "experiments" / "results" / "first_step_time.json"

PROBE = """
import time
started = time.perf_counter()
import gymnasium as gym
env = gym.make("hyst_gym:hyst_gym/Excitation-v0")
env.reset(seed=0)
env.step(env.action_space.sample())
print(time.perf_counter() - started)
"""


def run(command, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(command, check=True, capture_output=True, text=True, **kwargs)


def measure(work: Path) -> dict:
    """Seconds from import to the first step: first run, second run, and the notice printed."""
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(work), str(ROOT)])
    wheel = next(work.glob("hyst_gym-*.whl"))
    venv = work / "venv"
    run([sys.executable, "-m", "venv", str(venv)])
    python = venv / "bin" / "python"
    run([str(python), "-m", "pip", "install", "-q", str(wheel)])
    probe_dir = work / "project"  # not the checkout: the installed wheel must be what is imported
    probe_dir.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR")}
    times, notices = [], []
    for _ in range(2):
        done = run([str(python), "-c", PROBE], cwd=probe_dir, env=env)
        times.append(float(done.stdout.strip().splitlines()[-1]))
        notices.append(done.stderr.strip())
    return {"first_s": times[0], "cached_s": times[1], "first_notice": notices[0], "cached_notice": notices[1],
            "load_average_1min": os.getloadavg()[0], "cores": os.cpu_count()}


def markdown(result: dict) -> str:
    from experiments.targets import BY_KEY

    notice = result["first_notice"].splitlines()[-1] if result["first_notice"] else "(none)"
    verdicts = []
    for key, seconds in (("first_step_install", result["first_s"]), ("first_step_cached", result["cached_s"])):
        target = BY_KEY[key]
        verdicts.append(f"{target.stated()} {'met' if target.met(seconds) else 'not met'}")
    return (f"Measured by `python -m experiments.first_step_time` (wheel, no extras, fresh venv, "
            f"{result['cores']} cores, 1-min load {result['load_average_1min']:.1f}): `import` to the first "
            f"`env.step` takes **{result['first_s']:.1f} s** the first time, which prints once on stderr "
            f"\"{notice}\", and **{result['cached_s']:.1f} s** afterwards. Targets: {verdicts[0]} the first "
            f"time, {verdicts[1]} afterwards.")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-readme", action="store_true",
                        help="print only; leave docs/speed.md and experiments/results/first_step_time.json alone")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        try:
            result = measure(Path(folder))
        except subprocess.CalledProcessError as error:
            print(f"first_step_time: error: {' '.join(map(str, error.cmd[:4]))} failed: "
                  f"{(error.stderr or '').strip().splitlines()[-1:]}", file=sys.stderr)
            return 2
    text = markdown(result)
    print(text)
    if not args.no_readme:
        RESULT.write_text(json.dumps(result, indent=2) + "\n")
        from experiments.report_markdown import update_readme

        update_readme(ROOT / "docs" / "speed.md", text, area="first-step")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
