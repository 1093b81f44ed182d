"""The calibration's first stage (the hysteresis fitted to the magnetization channel alone) does not depend on the
transducer: the finite-element base of the continuum stage reuses the lumped base's magnetic fits instead of
fitting them again, and starts its joint fit from their hysteresis with its own transducer."""

import numpy as np

from hyst_gym.diagnose.fit import Split
from hyst_gym.diagnose.hypothesize import HYSTERESIS_NAMES, calibrate
from hyst_gym.diagnose.make_recording import make_recording_with_truth
from hyst_gym.diagnose.model import Model, Structure, base_parameters


def test_the_magnetization_channel_does_not_see_the_transducer():
    """The same hysteresis predicts the same magnetization, bit for bit, under the lumped and the FEM base."""
    recording = make_recording_with_truth("rod_dynamics", 3, output="both", n_samples=600)[0]
    lumped, fem = (Model(recording, Structure(t), base_parameters(recording, Structure(t)), 100.0)
                   for t in ("lumped", "fem"))
    hysteresis = {n: lumped.values()[n] for n in HYSTERESIS_NAMES}
    np.testing.assert_array_equal(lumped.predict({**lumped.values(), **hysteresis})["magnetization"],
                                  fem.predict({**fem.values(), **hysteresis})["magnetization"])


def test_a_base_calibrated_from_another_bases_magnetic_fits_fits_none_of_its_own(monkeypatch):
    recording = make_recording_with_truth("rod_dynamics", 3, output="both", n_samples=400)[0]
    split = Split.of(recording, 0.3)
    lumped = calibrate(split, Structure("lumped"), n_points=8, keep=2)
    assert len(lumped.magnetic_fits) == 2
    magnetic_only = []
    fit = Split.fit

    def counted(self, model, start=None, **kwargs):
        if model.channels == ("magnetization",):
            magnetic_only.append(start)
        return fit(self, model, start, **kwargs)

    monkeypatch.setattr(Split, "fit", counted)
    fem = calibrate(split, Structure("fem"), n_points=8, keep=2, magnetic_fits=lumped.magnetic_fits)
    assert magnetic_only == []
    assert fem.model.structure.transducer == "fem" and np.isfinite(fem.sse)
    assert fem.magnetic_values == lumped.magnetic_values
    # without them it fits its own first stage
    calibrate(split, Structure("fem"), n_points=8, keep=2)
    assert len(magnetic_only) == 2
