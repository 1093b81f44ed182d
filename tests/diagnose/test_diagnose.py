"""End to end: the five stages name a concealed effect, and say `none` on clean data."""

import json

import numpy as np
import pytest

from hyst_gym import cli
from hyst_gym.diagnose import diagnose, make_recording, write_recording


@pytest.fixture(scope="module")
def bias_report():
    rec, _ = make_recording("field_bias", 21, n_samples=1000)
    return diagnose(rec, effects=["field_bias", "sensor_lag"], progress=False)


def test_concealed_bias_is_named_and_fixed(bias_report):
    r = bias_report
    assert r.verdict == "field_bias"
    assert r.improvement > 0.5
    assert r.chosen.heldout_rmse < 1.5          # within noise after the extension
    assert abs(r.chosen.fit.values["H0"]) > 10 * r.chosen.fit.uncertainties["H0"]


def test_report_json_has_the_issue_keys(bias_report, tmp_path):
    from hyst_gym.diagnose import write_json, write_plots
    data = json.loads(write_json(bias_report, tmp_path / "r.json").read_text())
    for key in ("verdict", "confidence", "explanation", "baseline", "candidates", "located", "improvement"):
        assert key in data
    assert {"heldout_rmse", "params"} <= set(data["baseline"])
    assert all({"effect", "heldout_rmse", "bic", "params"} <= set(c) for c in data["candidates"])
    paths = write_plots(bias_report, tmp_path / "plots")
    assert all(p.stat().st_size > 10_000 for p in paths)


def test_clean_recording_gives_none_via_cli(tmp_path, capsys):
    rec, side = make_recording("none", 22, n_samples=1000, output="magnetization")
    path = write_recording(tmp_path / "clean.csv", rec, side)
    assert "effect" not in json.dumps(side) and list(side) == ["material", "notes"]
    status = cli.main(["diagnose", str(path), "--quiet", "--json", str(tmp_path / "c.json")])
    assert status == 0
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["verdict"] == "none" and data["improvement"] == 0.0
    assert data["baseline"]["heldout_rmse"] < 1.3


def test_generator_is_deterministic_and_conceals():
    a, _ = make_recording("thermal_drift", 5, n_samples=600)
    b, _ = make_recording("thermal_drift", 5, n_samples=600)
    c, _ = make_recording("thermal_drift", 6, n_samples=600)
    assert np.array_equal(a.magnetization, b.magnetization) and not np.array_equal(a.field, c.field)
    assert a.temperature is None and set(a.channels) == {"magnetization", "displacement"}
    with pytest.raises(ValueError, match="displacement only"):
        make_recording("rod_dynamics", 1, output="magnetization")


def test_fem_base_model_via_cli(tmp_path):
    """``--model fem`` calibrates the finite-element rod base model and explains clean data."""
    rec, side = make_recording("none", 3, n_samples=800)
    path = write_recording(tmp_path / "clean.csv", rec, side)
    status = cli.main(["diagnose", str(path), "--model", "fem", "--quiet", "--json", str(tmp_path / "f.json")])
    assert status == 0
    data = json.loads((tmp_path / "f.json").read_text())
    assert data["baseline"]["model"] == "fem"
    assert {"Y", "ML", "cD", "zeta_fem", "M0"} <= set(data["baseline"]["params"])
    assert "rod_dynamics" not in {c["effect"] for c in data["candidates"]}   # the FEM rod has every mode
    assert data["verdict"] == "none" and data["baseline"]["heldout_rmse"] < 1.3


def test_record_temperature_rise_matches_the_first_order_law():
    """Constant H: T(t) = heating*tau*H^2*(1 - exp(-t/tau)); a tau far longer than the record gives
    the linear rise heating*H^2*t, not the (meaningless) steady state."""
    from types import SimpleNamespace

    from hyst_gym.diagnose.report import record_temperature_rise

    time = np.linspace(0.0, 2.0, 2001)
    recording = SimpleNamespace(time=time, field=np.full_like(time, 3.0e4))
    for tau in (0.5, 1e6):
        values = {"heating": 1e-8, "tau_th": tau}
        expected = 1e-8 * tau * 9e8 * (1.0 - np.exp(-2.0 / tau))
        assert record_temperature_rise(recording, values) == pytest.approx(expected, rel=1e-6)
    assert record_temperature_rise(recording, {"heating": 1e-8, "tau_th": 1e6}) == pytest.approx(1e-8 * 9e8 * 2.0,
                                                                                                 rel=1e-5)
