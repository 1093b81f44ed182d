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


def test_thermal_words_state_the_changes_and_that_the_rise_is_an_inference():
    """The report states the fitted change of a (rise/T_amb under a ~ T, eq. 4) and of Ms
    (-beta_Ms*rise), and says that the temperature rise is inferred through the a(T) law."""
    from types import SimpleNamespace

    from hyst_gym.diagnose.report import record_temperature_rise, thermal_change_words
    from hyst_gym.physics.constants import ROOM_TEMPERATURE

    time = np.linspace(0.0, 2.0, 2001)
    recording = SimpleNamespace(time=time, field=np.full_like(time, 3.0e4))
    values = {"heating": 1e-8, "tau_th": 1e6, "beta_Ms": 0.002}
    rise = record_temperature_rise(recording, values)
    words = thermal_change_words(recording, values)
    assert f"a changes by {100 * rise / ROOM_TEMPERATURE:+.3g} %" in words
    assert f"Ms by {-100 * 0.002 * rise:+.3g} %" in words
    assert f"{rise:.3g} K" in words and "not a measurement" in words


def test_heating_law_family_against_an_independent_integration():
    """The thermal family's drive heating*h_ref^2*(|H|/h_ref)^p: the report's temperature trace for
    p = 1 matches scipy's solve_ivp of dT/dt = drive - T/tau (field held between samples), and the
    kernel's magnetization does not depend on p when |H| is constant (then (|H|/h_ref)^p = 1)."""
    from types import SimpleNamespace

    from scipy.integrate import solve_ivp

    from hyst_gym.diagnose.kernels import AMBIENT_TEMPERATURE, MAGNETIC_COLUMNS, simulate_members
    from hyst_gym.diagnose.report import temperature_rise_trace

    time = np.linspace(0.0, 1.0, 401)
    field = 4e4 * np.sin(2 * np.pi * 3.0 * time) + 1e4
    values = {"heating": 2e-8, "tau_th": 0.4, "heating_exponent": 1.0}
    h_ref = np.sqrt(np.mean(field ** 2))
    held = lambda t: field[min(int(np.searchsorted(time, t, side="right")) - 1, time.size - 2)]  # noqa: E731
    ode = solve_ivp(lambda t, T: [2e-8 * h_ref ** 2 * abs(held(t)) / h_ref - T[0] / 0.4], (0.0, 1.0), [0.0],
                    t_eval=time, max_step=time[1] - time[0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(temperature_rise_trace(SimpleNamespace(time=time, field=field), values), ode.y[0],
                               rtol=2e-3, atol=1e-3)

    square = 3e4 * np.sign(np.sin(2 * np.pi * 2.0 * time) + 1e-9)
    row = dict(a=6000, k=1500, alpha=-0.05, Ms=8e5, c=0.2, H0=0, k_e=0, heating=1e-8, tau_th=0.3, beta_Ms=1e-3,
               chi_r=0)
    rows = np.array([[dict(row, heating_exponent=p)[c] for c in MAGNETIC_COLUMNS] for p in (1.0, 2.0, 3.0)])
    m = simulate_members(time, square, rows, 0, 500.0, AMBIENT_TEMPERATURE)
    np.testing.assert_allclose(m[:, 0], m[:, 2], rtol=1e-12, atol=1e-9 * 8e5)
    # p = 2 averages H^2 exactly over the linear sample interval (the other p by the trapezoid rule):
    # they differ only on the few intervals where the square wave flips sign
    np.testing.assert_allclose(m[:, 0], m[:, 1], rtol=0, atol=1e-4 * 8e5)
    m_sine = simulate_members(time, field, rows, 0, 500.0, AMBIENT_TEMPERATURE)
    assert np.max(np.abs(m_sine[:, 0] - m_sine[:, 2])) > 1e-3 * 8e5   # a varying |H| feels the law


def test_candidates_fitted_in_threads_give_the_same_report(tmp_path, capsys):
    """Fitting the candidates in 1 or 3 threads gives the same report, number for number (each fit
    is deterministic and independent of the others); a bad thread count is a one-line error."""
    rec, _ = make_recording("field_bias", 7, n_samples=700)
    one = diagnose(rec, progress=False, workers=1).to_json()
    three = diagnose(rec, progress=False, workers=3).to_json()
    one.pop("seconds"), three.pop("seconds")
    assert json.dumps(one, sort_keys=True, default=str) == json.dumps(three, sort_keys=True, default=str)
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="workers"):
            diagnose(rec, progress=False, workers=bad)
    path = write_recording(tmp_path / "r.csv", rec, {})
    assert cli.main(["diagnose", str(path), "--quiet", "--workers", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "workers" in err[0]


def test_fem_base_fits_the_tip_damper():
    """The ``fem`` base fits the tip damper cL as well as the distributed damping cD (issue 22): with a
    heavy tip mass cL sets the first mode's damping. On the generator's FEM rod (true cL = 1000 N s/m,
    integrated by scipy from the state matrices, not by the fitter's first-order hold) the fit recovers
    it within 40 %."""
    from hyst_gym.diagnose.fit import Split
    from hyst_gym.diagnose.hypothesize import calibrate
    from hyst_gym.diagnose.model import Structure

    recording, _ = make_recording("rod_dynamics", 0, output="displacement", n_samples=2000)
    fit = calibrate(Split.of(recording, 0.3), Structure("fem"))
    assert fit.model.parameters["cL"].free
    assert 700.0 < fit.values["cL"] < 1400.0
