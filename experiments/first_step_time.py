"""Time from ``import`` to the first ``env.step`` for a user who installs the wheel.

Builds the wheel from this checkout, installs it (no extras) into a fresh virtual
environment in a temporary folder, and runs a fresh interpreter that imports gymnasium,
makes ``hyst_gym/Excitation-v0``, resets and steps once, then runs the rest of that first
episode and waits until the kernels are compiled:

1. **first**: an empty numba cache, the default ``HYST_GYM_COMPILE=background``: a helper process
   compiles the kernels while their plain-Python twins step the env (same numbers bit for bit);
   the probe also says how long the first episode took and when the helper was done;
2. **cached**: again, the compiled kernels now in the installed package's numba cache;
3. **foreground**: ``HYST_GYM_COMPILE=foreground`` on another empty cache (``NUMBA_CACHE_DIR``): the
   first step compiles the kernels itself, as it did before the background compile.

Writes the figures to ``experiments/results/first_step_time.json`` and into the ``first-step``
section of ``docs/speed.md``, with whether the targets of :mod:`experiments.targets` are met,
and prints them.

    .venv/bin/python -m experiments.first_step_time [--no-readme | --from-json]

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
first = time.perf_counter() - started
steps = 1
while steps < env.unwrapped.config.episode_steps:
    _, _, terminated, truncated, _ = env.step(env.action_space.sample())
    steps += 1
    if terminated or truncated:
        break
episode = time.perf_counter() - started
from hyst_gym.physics.background_compile import wait_for_background_compiles
compiled = wait_for_background_compiles(timeout=600)
print(first, steps, episode, compiled, time.perf_counter() - started)
"""


def run(command, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(command, check=True, capture_output=True, text=True, **kwargs)


def probe(python: Path, cwd: Path, env: dict) -> dict:
    """One run of :data:`PROBE`: seconds to the first step, steps and seconds of the first episode,
    whether and when the background compile was done, the last line on stderr and the load before."""
    load = os.getloadavg()[0]
    done = run([str(python), "-c", PROBE], cwd=cwd, env=env)
    first, steps, episode, compiled, compiled_at = done.stdout.strip().splitlines()[-1].split()
    notice = done.stderr.strip().splitlines()[-1] if done.stderr.strip() else ""
    return {"first_step_s": float(first), "episode_steps": int(steps), "episode_s": float(episode),
            "compiled": compiled == "True", "compiled_at_s": float(compiled_at), "notice": notice,
            "load_average_1min": load}


def measure(work: Path) -> dict:
    """The three runs of the module docstring, in a fresh venv built in ``work``."""
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(work), str(ROOT)])
    wheel = next(work.glob("hyst_gym-*.whl"))
    venv = work / "venv"
    run([sys.executable, "-m", "venv", str(venv)])
    python = venv / "bin" / "python"
    run([str(python), "-m", "pip", "install", "-q", str(wheel)])
    probe_dir = work / "project"  # not the checkout: the installed wheel must be what is imported
    probe_dir.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR", "HYST_GYM_COMPILE")}
    first = probe(python, probe_dir, env)
    cached = probe(python, probe_dir, env)
    foreground = probe(python, probe_dir, {**env, "HYST_GYM_COMPILE": "foreground",
                                           "NUMBA_CACHE_DIR": str(work / "empty-cache")})
    return {"first_s": first["first_step_s"], "cached_s": cached["first_step_s"],
            "first_notice": first["notice"], "cached_notice": cached["notice"],
            "load_average_1min": max(run["load_average_1min"] for run in (first, cached, foreground)),
            "cores": os.cpu_count(), "first": first, "cached": cached, "foreground": foreground}


def _per_step_ms(run: dict) -> float:
    """Milliseconds per step of a run's first episode after its first step."""
    return 1e3 * (run["episode_s"] - run["first_step_s"]) / max(run["episode_steps"] - 1, 1)


def markdown(result: dict) -> str:
    from experiments.targets import BY_KEY

    notice = result["first_notice"] or "(none)"
    verdicts = []
    for key, seconds in (("first_step_install", result["first_s"]), ("first_step_cached", result["cached_s"])):
        target = BY_KEY[key]
        verdicts.append(f"{target.stated()} {'met' if target.met(seconds) else 'not met'}")
    first, cached, foreground = result["first"], result["cached"], result["foreground"]
    compiled = (f"the helper process had compiled them {first['compiled_at_s']:.0f} s after the start"
                if first["compiled"] else "the helper process had not finished after 600 s")
    return (f"Measured by `python -m experiments.first_step_time` (wheel, no extras, fresh venv, "
            f"{result['cores']} cores, 1-min load up to {result['load_average_1min']:.1f}): `import` to the first "
            f"`env.step` takes **{result['first_s']:.1f} s** the first time, which prints once on stderr "
            f"\"{notice}\", and **{result['cached_s']:.1f} s** afterwards. Targets: {verdicts[0]} the first "
            f"time, {verdicts[1]} afterwards. The first time, the kernels compile in a background process while "
            f"plain Python steps the env (the same numbers bit for bit): the first episode "
            f"({first['episode_steps']} steps) ended {first['episode_s']:.1f} s after the start "
            f"({_per_step_ms(first):.2f} ms per step, against {_per_step_ms(cached):.3f} ms compiled), and "
            f"{compiled}. Compiling in the foreground instead (`HYST_GYM_COMPILE=foreground`, an empty cache), "
            f"the first step takes {foreground['first_step_s']:.1f} s.")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-readme", action="store_true",
                        help="print only; leave docs/speed.md and experiments/results/first_step_time.json alone")
    parser.add_argument("--from-json", action="store_true",
                        help="do not measure: rewrite the docs/speed.md section from the committed "
                             "experiments/results/first_step_time.json")
    args = parser.parse_args(argv)
    if args.from_json:
        result = json.loads(RESULT.read_text(encoding="utf-8"))
    else:
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
        if not args.from_json:
            RESULT.write_text(json.dumps(result, indent=2) + "\n")
        from experiments.report_markdown import update_readme

        update_readme(ROOT / "docs" / "speed.md", text, area="first-step")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
