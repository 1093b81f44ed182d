"""The speed paths of the mismatch tool give the numbers of the plain ones, to the last bit: the lanes kernel
(members under their own fields, with eddy currents or heating, in one pass) against the bank and the
one-member kernel, a model's magnetization of many members against each member alone, and the Jacobian
simulated with its point (Objective.__call__) against the Jacobian simulated on its own."""

from __future__ import annotations

import numpy as np
import pytest

from hyst_gym.diagnose import make_recording
from hyst_gym.diagnose.effects import extension_parameters
from hyst_gym.diagnose.fit import Objective, Split
from hyst_gym.diagnose.kernels import (BANK_LANES, heating_reference, lane_passes, member_passes, simulate_lanes,
                                       simulate_members)
from hyst_gym.diagnose.model import Model, Structure, base_parameters


@pytest.fixture(scope="module")
def recording():
    return make_recording("none", seed=3, output="both", n_samples=1500)[0]


def _rows(kind_of_member, count, seed=0):
    rng = np.random.default_rng(seed)
    rows = np.repeat(np.array([[2000.0, 3000.0, 1e-3, 7.65e5, 0.3, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0]]),
                     count, axis=0)
    rows[:, 0] *= 1 + 0.1 * rng.random(count)
    rows[:, 1] *= 1 + 0.1 * rng.random(count)
    if kind_of_member == "bias":
        rows[:, 5] = 1000.0 * rng.random(count)
    elif kind_of_member == "small_loop":
        rows[:, 10] = 0.1 + 0.5 * rng.random(count)
    elif kind_of_member in ("heating", "heating_law"):
        rows[:, 7], rows[:, 8], rows[:, 9] = 2e-9 * (1 + rng.random(count)), 0.01, 1e-3
        rows[:, 12] = 1e-3 * rng.random(count)
        if kind_of_member == "heating_law":
            rows[:, 11] = 1.5
    elif kind_of_member == "eddy":
        rows[:, 6] = 1e-5 * (1 + rng.random(count))
    return rows


@pytest.mark.parametrize("curve", [0, 1])
@pytest.mark.parametrize("kind_of_member", ["plain", "bias", "small_loop", "heating", "heating_law", "eddy"])
def test_lanes_give_the_kernels_numbers(recording, curve, kind_of_member):
    split = Split.of(recording, 0.3)
    rows = _rows(kind_of_member, 5)
    field = recording.field
    expected = simulate_members(recording.time, field, rows, curve, split.max_field_step, 293.0)
    lanes = simulate_lanes(recording.time, field[None, :].copy(), np.zeros(5, dtype=np.int64), rows,
                           np.array([heating_reference(field)]), curve, split.max_field_step, 293.0)
    assert np.all(np.isfinite(expected))
    assert np.array_equal(lanes, expected)


def test_passes_count_banks_and_lanes():
    assert member_passes(_rows("plain", BANK_LANES)) == 1
    assert member_passes(_rows("plain", BANK_LANES + 1)) == 2
    assert member_passes(_rows("heating", 3)) == 3
    assert member_passes(_rows("bias", 3)) == 3
    assert lane_passes(1) == 1 and lane_passes(BANK_LANES) == 1 and lane_passes(BANK_LANES + 1) == 2


def _model(recording, extension):
    structure = Structure("lumped", "ising", extension)
    split = Split.of(recording, 0.3)
    params = base_parameters(recording, structure)
    base_values = {n: p.value for n, p in params.items()}
    params.update(extension_parameters(recording, structure, base_values))
    return Model(recording, structure, params, split.max_field_step), split


@pytest.mark.parametrize("extension, changes", [
    ("input_lag", [{"tau_in": 2e-5}, {"delay_in": 1e-5, "tau_in": 1e-5}, {}]),
    ("input_map", [{"input_cubic": -0.1}, {"input_saturation": 0.5}, {}]),
    ("field_bias", [{"H0": 500.0}, {"H0": -300.0}, {}]),
    ("thermal_drift", [{"heating": 1e-9}, {"heating": 2e-9, "beta_k": 1e-3}, {}]),
    ("eddy_current", [{"k_e": 1e-5}, {"k_e": 3e-5}, {}]),
])
def test_magnetization_of_many_members_is_each_alone(recording, extension, changes):
    model, _ = _model(recording, extension)
    values = [dict(model.values(), **change, a=model.values()["a"] * (1 + 0.05 * i)) for i, change in
              enumerate(changes)]
    together = model.magnetization(values)
    for i, v in enumerate(values):
        assert np.array_equal(together[:, i], model.magnetization([v])[:, 0]), (extension, i)


@pytest.mark.parametrize("extension", [None, "thermal_drift", "input_lag"])
def test_jacobian_simulated_with_its_point_is_the_same(recording, extension):
    model, split = _model(recording, extension)
    x = model.x_from_values(model.values())
    speculating = Objective(model, split.noise, split.fit_mask)
    residual = speculating(x)
    jacobian = speculating.jacobian(x)
    fresh = Objective(model, split.noise, split.fit_mask)
    assert np.array_equal(residual, fresh(x.copy()))
    fresh._speculated = None  # the Jacobian simulated on its own
    assert np.array_equal(jacobian, fresh.jacobian(x.copy()))
    assert np.any(jacobian != 0.0)
    assert speculating.evaluations == fresh.evaluations


@pytest.mark.parametrize("extension, change", [
    (None, {}),
    ("thermal_drift", {"heating": 2e-9, "heating_exponent": 1.5, "beta_k": 1e-3}),
    ("input_map", {"input_cubic": -0.1, "input_saturation": 0.5}),
    ("input_lag", {"tau_in": 2e-5, "delay_in": 1e-5}),
    ("sensor_gain_drift", {}),
    ("sensor_drift", {}),
    ("mains_pickup", {}),
    ("sensor_lag", {"tau_x": 3e-5, "tau2_m": 1e-5, "tau_m": 1e-5}),
    ("delta_e", {"delta_e": 0.4}),
    ("anhysteretic_shape", {"mix_weight": 0.3, "mix_a_ratio": 0.5}),
    ("rod_dynamics", {}),
])
def test_a_model_up_to_a_sample_predicts_the_whole_models_start(recording, extension, change):
    model, split = _model(recording, extension)
    values = dict(model.values(), **change)
    for name, parameter in model.parameters.items():  # every coefficient of the family away from zero
        if extension and parameter.free and values[name] == 0.0 and name not in change:
            values[name] = 0.1 * parameter.upper if parameter.upper > 0 else 0.1 * parameter.lower
    whole = model.predict(values)
    cut = split.cut
    short = model.up_to(cut)
    assert short.horizon == cut and model.horizon is None
    part = short.predict(values)
    for channel in model.channels:
        assert part[channel].shape == (cut,)
        assert np.all(np.isfinite(whole[channel]))
        assert np.array_equal(part[channel], whole[channel][:cut]), channel
    objective = Objective(model, split.noise, split.fit_mask)
    x = model.x_from_values(values)
    whole = model.predict(model.values_from_x(x))
    expected = np.concatenate([(whole[ch][split.fit_mask] - recording.output(ch)[split.fit_mask]) / split.noise[ch]
                               for ch in model.channels])
    assert np.array_equal(objective(x), np.clip(expected, -1e100, 1e100))


def test_up_to_checks_its_argument(recording):
    model, _ = _model(recording, None)
    with pytest.raises(ValueError, match="samples must be in"):
        model.up_to(0)


def test_global_search_on_the_fitting_block_alone_gives_the_same_starts(recording, monkeypatch):
    from hyst_gym.diagnose.fit import global_search

    model, split = _model(recording, None)
    names = ["a", "k", "rho", "Ms", "c"]
    starts = global_search(model, split.noise, split.fit_mask, names, n_points=16, keep=3, linear_outputs=("zetahat",
                                                                                                           "M0"))
    plain_init = Objective.__init__

    def whole_record(self, model, noise, mask):  # the objective simulating the whole record, as before
        plain_init(self, model, noise, mask)
        self._simulated, self._simulated_mask = model, mask

    monkeypatch.setattr(Objective, "__init__", whole_record)
    whole = global_search(model, split.noise, split.fit_mask, names, n_points=16, keep=3, linear_outputs=("zetahat",
                                                                                                          "M0"))
    assert starts == whole
    assert len(starts) == 3
