"""The effect registry: every registered effect has a kernel, a generator, words and a confusable entry,
and a missing or wrong entry fails loudly."""

from dataclasses import replace

import numpy as np
import pytest

from hyst_gym.diagnose import effects as registry
from hyst_gym.diagnose.effects import (CONFUSABLE, EFFECTS, REGISTRY, Effect, applicable_effects, effect,
                                       extension_parameters)
from hyst_gym.diagnose.make_recording import WRITABLE_EFFECTS, make_recording
from hyst_gym.diagnose.model import Model, Structure, base_parameters
from hyst_gym.diagnose.report import EFFECT_WORDS


@pytest.fixture(scope="module")
def recording():
    # 5000 samples at 40-60 kHz: long enough for mains pickup (three 50 Hz cycles)
    return make_recording("none", 4, output="both", n_samples=5000)[0]


def test_every_effect_is_applicable_to_some_recording(recording):
    assert set(applicable_effects(recording, Structure("lumped"))) == set(EFFECTS)


@pytest.mark.parametrize("name", EFFECTS)
def test_every_effect_has_a_kernel(recording, name):
    """Its parameters, moved from their neutral values, change the model's prediction (or, for an effect
    that swaps a law, the swap does): the forward model reads them."""
    structure = Structure("lumped", "ising", name)
    base = base_parameters(recording, structure)
    values = {n: p.value for n, p in base.items()}
    extra = extension_parameters(recording, structure, values)
    assert set(extra) == set(effect(name).parameter_names)
    model = Model(recording, structure, {**base, **extra}, 200.0)
    neutral = {**values, **{n: 0.0 if p.lower <= 0.0 <= p.upper else p.value for n, p in extra.items()}}
    plain = model.predict(neutral)
    if not extra:
        other = Model(recording, Structure("lumped", "ising"), base, 200.0).predict(neutral)
        assert any(np.max(np.abs(plain[ch] - other[ch])) > 0 for ch in plain)
        return
    # every parameter moved by a tenth of its range (inside it), then each one put back: the prediction changes
    active = dict(neutral)
    for n, p in extra.items():
        if p.free:
            step = 0.1 * (p.upper - p.lower)
            active[n] = neutral[n] + step if neutral[n] + step <= p.upper else neutral[n] - step
    moved = model.predict(active)
    assert not any(np.array_equal(moved[ch], plain[ch]) for ch in plain if ch in effect_channels(name))
    for n, p in extra.items():
        if p.free:
            back = model.predict(dict(active, **{n: neutral[n]}))
            assert any(np.max(np.abs(back[ch] - moved[ch])) > 1e-9 * np.ptp(moved[ch]) for ch in moved), n


def effect_channels(name):
    return ("displacement",) if effect(name).mechanical else ("magnetization", "displacement")


@pytest.mark.parametrize("name", EFFECTS)
def test_every_effect_has_a_generator(name):
    """make_recording writes it: the record differs from the same seed's record without it, in its channels."""
    assert name in WRITABLE_EFFECTS
    output = "displacement" if effect(name).mechanical else "magnetization"
    broadband = True if name == "rod_dynamics" else None
    with_effect = make_recording(name, 5, output=output, n_samples=800)[0]
    without = make_recording("none", 5, output=output, n_samples=800, broadband=broadband)[0]
    np.testing.assert_array_equal(with_effect.field, without.field)
    difference = np.max(np.abs(with_effect.output(output) - without.output(output)))
    assert difference > 1e-3 * np.ptp(without.output(output))


def test_every_effect_has_words_a_slot_and_a_confusable_entry():
    partners = {name for table in CONFUSABLE.values() for pair in table for name in pair}
    for name in EFFECTS:
        assert EFFECT_WORDS[name] and effect(name).slot and effect(name).words
        assert name in partners, f"{name} has no confusable partner in any channel set"
    for channels, table in CONFUSABLE.items():
        for pair, measurement in table.items():
            assert len(pair) == 2 and pair <= set(EFFECTS) and measurement, (channels, pair)


def test_rate_and_mechanical_flags_match_the_physics():
    """A lag, a rod mode and eddy loss need a real time axis, a static law does not; the mechanics-side
    effects need a displacement, the magnetic and input-side ones do not."""
    static = {"field_bias", "anhysteretic_shape", "small_loop", "input_map", "sensor_map",
              "quadratic_magnetostriction", "delta_e"}
    assert {"eddy_current", "sensor_lag", "rod_dynamics"} <= set(registry.RATE_EFFECTS)
    assert not static & set(registry.RATE_EFFECTS)
    assert {"quadratic_magnetostriction", "rod_dynamics", "delta_e"} <= set(registry.MECHANICAL_EFFECTS)
    assert not {"thermal_drift", "eddy_current", "field_bias", "anhysteretic_shape", "small_loop", "input_map",
                "sensor_lag", "sensor_map"} & set(registry.MECHANICAL_EFFECTS)
    magnetic_only = make_recording("none", 4, output="magnetization", n_samples=5000)[0]
    assert not set(applicable_effects(magnetic_only, Structure("none"))) & set(registry.MECHANICAL_EFFECTS)


def test_unknown_effect_fails_with_one_line_naming_the_vocabulary():
    with pytest.raises(ValueError, match="unknown effect 'bogus'; expected one of thermal_drift"):
        effect("bogus")
    with pytest.raises(ValueError, match="unknown effect"):
        Structure("lumped", "ising", "bogus")


def test_an_entry_without_a_required_field_fails_when_it_is_built():
    with pytest.raises(TypeError):
        Effect(name="x", slot="s", words="w", parameter_names=(), parameters=lambda *a: {},
               applies=lambda *a: True, rate_dependent=False, confusable={}, rescue=None)  # no identified_by


def test_a_confusable_entry_with_an_unknown_partner_or_twice_fails(monkeypatch):
    bad = replace(REGISTRY["field_bias"], confusable={"bogus": {"both": "x"}})
    monkeypatch.setattr(registry, "_REGISTERED", (bad,))
    with pytest.raises(ValueError, match="partner 'bogus' is not another registered effect"):
        registry._confusable_table()
    twice = replace(REGISTRY["anhysteretic_shape"], confusable={"field_bias": {"magnetization": "y"}})
    monkeypatch.setattr(registry, "_REGISTERED", (REGISTRY["field_bias"], twice))
    with pytest.raises(ValueError, match="listed twice"):
        registry._confusable_table()


def test_main_parameter_is_never_silently_missing(recording):
    """Every effect names how it is identified; an effect with a parameter always has a main parameter."""
    from types import SimpleNamespace

    for name in EFFECTS:
        one = effect(name)
        structure = Structure("lumped", "ising", name)
        base = base_parameters(recording, structure)
        values = {n: p.value for n, p in base.items()}
        extra = extension_parameters(recording, structure, values)
        model = Model(recording, structure, {**base, **extra}, 200.0)
        values.update({n: p.value + 0.01 * p.scale for n, p in extra.items()})
        fit = SimpleNamespace(model=model, values=values, uncertainties={n: 1.0 for n in extra})
        main = one.main_parameter(fit)
        if one.parameter_names:
            assert main in extra and model.parameters[main].free, name
        else:
            assert main is None and isinstance(one.identified_by, registry.NoParameter) and one.identified_by.why
