"""The heating network's second stage (``thermal_drift``, :data:`~hyst_gym.diagnose.kernels.THERMAL_LAG_COLUMNS`):
the rod lags the coil with ``tau_th2`` and sees the share ``thermal_share`` of the coil's rise directly. The lag
against scipy's linear simulation of the same network, the one-stage law as its member (bit for bit), the two
kernel paths against each other, and the physics: a rod heated through a series network starts flat."""

import numpy as np
import pytest
from scipy import integrate

from hyst_gym.diagnose import Recording
from hyst_gym.diagnose.effects import temperature_rise_trace
from hyst_gym.diagnose.kernels import (AMBIENT_TEMPERATURE, KNEE_COLUMN, MAGNETIC_COLUMNS, PINNING_DRIFT_COLUMNS,
                                       THERMAL_LAG_COLUMN, THERMAL_LAG_COLUMNS, heating_reference,
                                       lagged_rise_trace, simulate_lanes, simulate_members)
from hyst_gym.diagnose.model import Model, Structure, base_parameters, extension_parameters

ROW = dict(a=6000.0, k=1500.0, alpha=-0.05, Ms=8e5, c=0.2, H0=0.0, k_e=0.0, heating=4e-8, tau_th=0.1,
           beta_Ms=1e-3, chi_r=0.0, heating_exponent=2.0)


def _row(tau2=None, share=None):
    row = [ROW[c] for c in MAGNETIC_COLUMNS] + [0.0] * len(PINNING_DRIFT_COLUMNS) + [1.0]
    return row if tau2 is None else row + [tau2, share]


def _drive():
    time = np.linspace(0.0, 1.0, 1500)
    return time, 5e4 * np.sin(2 * np.pi * 6.0 * time) * (time < 0.6)  # heats, then cools with the drive off


def test_the_columns_follow_the_knee():
    assert THERMAL_LAG_COLUMN == KNEE_COLUMN + 1 and THERMAL_LAG_COLUMNS == ("tau_th2", "thermal_share")


def test_the_lag_is_the_linear_network_scipy_simulates():
    """lagged_rise_trace integrates tau2*theta2' = theta - theta2 for theta linear between samples: against scipy's
    ODE solver on the same linear interpolation, on an uneven time axis."""
    rng = np.random.default_rng(3)
    time = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, 800))
    time -= time[0]
    coil = 30.0 * (1.0 - np.exp(-time / 0.1)) + 2.0 * np.sin(2 * np.pi * 7.0 * time)
    coil -= coil[0]
    for tau2 in (0.004, 0.05, 0.4):
        def lag(t, y, tau2=tau2):
            return (np.interp(t, time, coil) - y) / tau2

        solved = integrate.solve_ivp(lag, (0.0, time[-1]), [0.0], t_eval=time, rtol=1e-10, atol=1e-12,
                                     max_step=float(np.min(np.diff(time))))
        np.testing.assert_allclose(lagged_rise_trace(time, coil, tau2), solved.y[0], rtol=0, atol=1e-6 * np.ptp(coil))
    np.testing.assert_array_equal(lagged_rise_trace(time, coil, 0.0), coil)


def test_the_one_stage_law_is_the_member_at_tau2_zero_and_at_share_one():
    """A row with tau_th2 = 0, or with share 1, gives the row without the columns its numbers bit for bit (rows
    written before them keep them), on both kernel paths; the model's row carries the two columns."""
    time, field = _drive()
    old = simulate_members(time, field, np.array([_row()]), 0, 200.0, AMBIENT_TEMPERATURE)
    for tau2, share in ((0.0, 0.3), (0.2, 1.0)):
        rows = np.array([_row(tau2, share)])
        np.testing.assert_array_equal(simulate_members(time, field, rows, 0, 200.0, AMBIENT_TEMPERATURE), old)
        lanes = simulate_lanes(time, field[None, :], np.zeros(1, dtype=np.int64), rows,
                               np.array([heating_reference(field)]), 0, 200.0, AMBIENT_TEMPERATURE)
        np.testing.assert_array_equal(lanes, old)
    recording = Recording(time=time, field=field, magnetization=old[:, 0])
    structure = Structure("none", "ising", "thermal_drift")
    base = base_parameters(recording, structure)
    model = Model(recording, structure, {**base, **extension_parameters(
        recording, structure, {n: p.value for n, p in base.items()})}, 200.0)
    row = model.magnetic_row(dict(model.values(), tau_th2=0.05, thermal_share=0.25))
    assert list(row[THERMAL_LAG_COLUMN:]) == [0.05, 0.25]
    assert model.values()["thermal_share"] == 1.0  # the family's start: the one-stage law


@pytest.mark.parametrize("share", [0.0, 0.4])
def test_the_kernel_paths_agree_and_the_series_rod_starts_flat(share):
    """One member alone (_simulate_one) and among lanes give the same numbers; and the physics: through a series
    network (share 0) the rod's rise starts with zero slope, so early on its loop stays closer to the cold one than
    the one-stage law's, while both reach the same steady rise (tau2 only delays it)."""
    time, field = _drive()
    rows = np.array([_row(0.08, share), _row(0.0, 1.0), _row(0.0, 0.0)])
    alone = simulate_members(time, field, rows[:1], 0, 200.0, AMBIENT_TEMPERATURE)
    lanes = simulate_lanes(time, field[None, :], np.zeros(3, dtype=np.int64), rows,
                           np.array([heating_reference(field)]), 0, 200.0, AMBIENT_TEMPERATURE)
    np.testing.assert_array_equal(lanes[:, :1], alone)

    recording = Recording(time=time, field=field, magnetization=alone[:, 0])
    values = dict(ROW, tau_th2=0.08, thermal_share=share)
    two_stage = temperature_rise_trace(recording, values)
    one_stage = temperature_rise_trace(recording, dict(ROW))
    early = np.searchsorted(time, 0.02)
    assert two_stage[early] < (share + 0.5 * (1 - share)) * one_stage[early]
    # the same temperature when the network has settled: a long constant drive
    long_time = np.linspace(0.0, 5.0, 5000)
    steady = Recording(time=long_time, field=np.full(5000, 3e4), magnetization=np.zeros(5000))
    expected = ROW["heating"] * 3e4 ** 2 * ROW["tau_th"]
    assert temperature_rise_trace(steady, values)[-1] == pytest.approx(expected, rel=1e-6)
    assert temperature_rise_trace(steady, dict(ROW))[-1] == pytest.approx(expected, rel=1e-6)
