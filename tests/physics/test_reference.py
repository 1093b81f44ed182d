"""Cross-check against the independent reference solutions in shared/data/reference."""

import json
import pathlib

import numpy as np
import pytest

from hyst_gym import simulate_magnetization

REFERENCE = pathlib.Path(__file__).resolve().parents[2].parent / "shared" / "data" / "reference"


@pytest.mark.parametrize("name", ["paper", "hysteretic", "soft"])
def test_matches_independent_reference(name):
    data = np.load(REFERENCE / "ja_golden.npz")
    params = json.loads((REFERENCE / "ja_golden_params.json").read_text())[name]
    magnetization = simulate_magnetization(data["field"], data["time"], **params)
    error = np.max(np.abs(magnetization - data[f"magnetization_{name}"])) / params["Ms"]
    # Both solutions converge (ours at 2nd order); their difference is the discretization error.
    assert error < 5e-6
