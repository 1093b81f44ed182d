"""The HEM temperature laws of experiments/gd_temperature.py: synthetic round trip through the critical laws."""

import numpy as np
import pytest

from experiments import gd_temperature as gd
from hyst_gym.physics.hem import simulate_hem_batch, state_with_magnetization

MU0 = 4e-7 * np.pi
TRUE = {"M0": 2.0e6, "beta": 0.35, "chi0": 3.0, "gamma": 0.8, "Hc0": 2000.0, "n_c": 1.5, "b0": 6000.0,
        "n_b": 1.0, "sigma": 0.6}


def synthetic_record(T_C, amplitude, peak, M0=0.0, n=400):
    """0 -> +peak -> -peak -> +peak, B from the HEM with the critical laws at TRUE, started at M0 (A/m)."""
    H = peak * np.sin(2 * np.pi * np.linspace(0.0, 1.25, n))
    clean = gd.clean_record(H, np.zeros(n), T_C, amplitude, stride=1)
    batch = gd.FAMILIES["hem_critical"].build(TRUE).batch(np.array([gd.celsius_to_kelvin(T_C)]), "normal",
                                                          gd.HEM_NODES)
    M = simulate_hem_batch(clean.field, batch, state_with_magnetization(batch, float(clean.field[0]), M0))[:, 0]
    return gd.Record(float(T_C), amplitude, clean.field, MU0 * (clean.field + M), clean.loop_start, M0,
                     clean.peak_field, clean.max_field_step)


@pytest.fixture(scope="module")
def synthetic():
    temps = (-30.0, -15.0, -5.0, 5.0)
    return [synthetic_record(T, amp, peak, M0) for T in temps
            for amp, peak, M0 in (("major", 5.5e4, 0.0), ("minor", 4e3, 2e4))]


def test_hem_critical_laws_are_recovered_and_predict_a_left_out_temperature(synthetic):
    family = gd.FAMILIES["hem_critical"]
    train = [r for r in synthetic if r.temperature_C != -5.0]
    test = [r for r in synthetic if r.temperature_C == -5.0]
    start_rows = gd.score(test, family, gd.FitResult("hem_critical", dict(zip(family.names, family.x0)), (), 0, 0, 0,
                                                     True), "predicted")
    assert max(r["nrmse"] for r in start_rows) > 0.05  # the family's own start is visibly wrong
    fit = gd.fit_family(train, family, max_nfev=150)
    rows = gd.score(test, family, fit, "predicted")
    assert max(r["nrmse"] for r in rows) < 0.01
    for name in ("M0", "Hc0", "b0"):
        assert fit.params[name] == pytest.approx(TRUE[name], rel=0.1), name
    assert fit.params["beta"] == pytest.approx(TRUE["beta"], abs=0.05)


def test_a_record_starts_at_its_measured_magnetization(synthetic):
    record = next(r for r in synthetic if r.amplitude == "minor")
    family = gd.FAMILIES["hem_critical"]
    B = gd.simulate_records([record], family, family.to_z([TRUE[n] for n in family.names])[None, :])[0][:, 0]
    # to the compiled erf's accuracy (1.5e-7 of the relay magnetization; the start state is solved with scipy's)
    assert abs(B[0] - MU0 * (record.field[0] + record.M0)) < MU0 * 2e-7 * TRUE["M0"]
    np.testing.assert_allclose(B, record.B, rtol=0, atol=1e-9)
