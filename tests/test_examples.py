"""The scripts in examples/ run as a user would run them (issue 24), with small settings, and
print what they claim: each in a fresh interpreter in an empty folder, from the installed
package."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples"


def run_example(name: str, *args: str, cwd: Path) -> str:
    env = dict(os.environ, MPLBACKEND="Agg", OMP_NUM_THREADS="1")
    env.pop("PYTHONPATH", None)
    done = subprocess.run([sys.executable, str(EXAMPLES / name), *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=900)
    assert done.returncode == 0, f"{name} failed:\n{done.stderr[-3000:]}"
    return done.stdout


def test_every_example_is_tested():
    tested = set(re.findall(r'run_example\("([\w.]+)"', Path(__file__).read_text(encoding="utf-8")))
    assert {path.name for path in EXAMPLES.glob("*.py")} == tested


def test_simulate_loops(tmp_path):
    out = run_example("simulate_loops.py", "--out", "loops.png", cwd=tmp_path)
    spans = [float(v) for v in re.findall(r"M spans\s+([\d.]+) kA/m", out)]
    assert len(spans) == 3 and spans == sorted(spans)           # larger field, wider loop
    assert spans[-1] < 2 * 765.0 + 1e-6                          # never beyond -Ms..Ms (Ms = 765 kA/m)
    assert (tmp_path / "loops.png").stat().st_size > 10_000


def test_train_then_evaluate(tmp_path):
    pytest.importorskip("stable_baselines3")
    out = run_example("train_ppo_suite_task.py", "--timesteps", "1024", "--out", "ppo.zip", cwd=tmp_path)
    assert "trained 1024 steps" in out and (tmp_path / "ppo.zip").exists()
    out = run_example("evaluate_agent.py", "--policy", "ppo.zip", "--out", "estimate.png", cwd=tmp_path)
    steps, error = re.search(r"(\d+) steps, mean \|a_estimate - a_true\| = ([\d.]+) A/m", out).groups()
    # HotCoil-v1: 200 steps of 0.05 s unless the coil overheats; the error is below width(Theta) = 1600 A/m
    assert 0 < int(steps) <= 200 and 0 <= float(error) <= 1600
    assert (tmp_path / "estimate.png").stat().st_size > 10_000


def test_diagnose_csv_names_the_concealed_effect(tmp_path):
    out = run_example("diagnose_csv.py", "--out", "diag", cwd=tmp_path)
    assert "verdict: eddy_current" in out                        # the effect concealed in the made-up recording
    assert (tmp_path / "diag.json").exists() and any((tmp_path / "diag_plots").glob("*.png"))
