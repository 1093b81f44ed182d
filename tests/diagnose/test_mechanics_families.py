"""The mechanical slots' flexible families: the magnetostriction law's even term (``zeta_4``), the
Delta-E stiffness's cubic and quartic terms (``delta_e_cubic``, ``delta_e_quartic``) and the second mode's range
below the lumped one (a rod on a compliant mount). Each holds today's formula at its zero value exactly, and each is
what it says: the even law is recovered from a displacement written in its form, the stiffness terms are zero at the
bias, and a second mode below the first is the modal sum of two second-order systems."""

from dataclasses import replace

import numpy as np
import pytest
from scipy import signal

from hyst_gym.diagnose.effects import EVEN_LAW_NAMES, SECOND_MODE_BELOW, effect_starts
from hyst_gym.diagnose.hypothesize import _quadratic_outputs
from hyst_gym.diagnose.make_recording import make_recording_with_truth
from hyst_gym.diagnose.model import (Model, Structure, base_parameters, even_law_forcing, extension_parameters,
                                     relative_stiffness_change)


def _model(recording, extension):
    structure = Structure(extension=extension)
    base = base_parameters(recording, structure)
    values = {n: p.value for n, p in base.items()}
    return Model(recording, structure, {**base, **extension_parameters(recording, structure, values)}, 100.0)


@pytest.fixture(scope="module")
def recording():
    return make_recording_with_truth("none", 4, n_samples=700)[0]


def test_even_law_at_zero_is_the_m2_law_exactly(recording):
    """The even terms at 0 (their initial values) give today's forcing zetahat*(M - M0) + zeta_q*(M - M0)^2
    bit for bit; the even terms vanish at the bias and are even in M/Ms."""
    model = _model(recording, "quadratic_magnetostriction")
    assert all(model.parameters[n].value == 0.0 for n in EVEN_LAW_NAMES)
    values = model.values()
    Ms = values["Ms"]
    values.update(zeta_q=0.3 * values["zetahat"] / Ms, M0=0.2 * Ms)
    m = model.magnetization([values])[:, 0]
    today = _model(recording, None)
    unit = dict(values, zeta_q=0.0, M0=0.0)  # the forcing below passed as M: deviation = forcing
    deviation = m - values["M0"]
    forcing = deviation + (values["zeta_q"] / values["zetahat"]) * deviation ** 2
    np.testing.assert_array_equal(model.displacement(values, m), today.displacement(unit, forcing))
    grid = np.linspace(-Ms, Ms, 41)
    coefficients = {n: 0.7 for n in EVEN_LAW_NAMES}
    even = even_law_forcing(grid, Ms, values["M0"], coefficients)
    np.testing.assert_allclose(even, even[::-1], rtol=0, atol=1e-12 * Ms)
    assert even_law_forcing(np.array([values["M0"]]), Ms, values["M0"], coefficients)[0] == 0.0


def test_linear_start_recovers_a_displacement_written_in_the_even_law(recording):
    """A noise-free displacement made with a saturating law (M^2 flattening toward Ms: zeta_4 < 0)
    about a bias: the linear least-squares start returns its coefficients and bias to solver precision."""
    model = _model(recording, "quadratic_magnetostriction")
    values = model.values()
    Ms, gain = values["Ms"], values["zetahat"]
    truth = dict(values, zeta_q=0.5 * gain / Ms, zeta_4=-0.4 * gain, M0=0.1 * Ms)
    m = model.magnetization([truth])[:, 0]
    written = model.displacement(truth, m)
    model = _model(replace(recording, displacement=written), "quadratic_magnetostriction")
    solved = _quadratic_outputs(model, dict(values), m, np.ones(m.size, bool))
    for name in ("zeta_q", *EVEN_LAW_NAMES):
        assert solved[name] == pytest.approx(truth[name], rel=1e-6)
    # the bias is a root of the law nearest the median M (the law has others: each one, with its zetahat, is the
    # same forcing), so the law, not (zetahat, M0), is compared
    np.testing.assert_allclose(model.displacement(solved, m), written, rtol=0, atol=1e-8 * np.ptp(written))


def test_cubic_and_quartic_stiffness_at_zero_are_the_quadratic_law_and_vanish_at_the_bias():
    Ms, M0 = 8e5, 2e5
    m = np.linspace(-Ms, Ms, 31)
    values = {"Ms": Ms, "M0": M0, "delta_e": 0.4, "delta_e_linear": -0.3}
    quadratic = 0.4 * ((m / Ms) ** 2 - (M0 / Ms) ** 2) - 0.3 * (m / Ms - M0 / Ms)
    np.testing.assert_array_equal(relative_stiffness_change(m, dict(values, delta_e_quartic=0.0)),
                                  relative_stiffness_change(m, values))
    np.testing.assert_allclose(relative_stiffness_change(m, values), quadratic, rtol=0, atol=1e-15)
    with_quartic = relative_stiffness_change(m, dict(values, delta_e_quartic=-0.9))
    np.testing.assert_allclose(with_quartic - quadratic, -0.9 * ((m / Ms) ** 4 - (M0 / Ms) ** 4), rtol=0, atol=1e-15)
    assert relative_stiffness_change(np.array([M0]), dict(values, delta_e_quartic=-0.9))[0] == 0.0
    # the cubic term: a law about a centre away from M = 0 that is not symmetric about it (|M - Mb|^p expanded)
    np.testing.assert_array_equal(relative_stiffness_change(m, dict(values, delta_e_cubic=0.0)),
                                  relative_stiffness_change(m, values))
    with_cubic = relative_stiffness_change(m, dict(values, delta_e_cubic=0.7, delta_e_quartic=-0.9))
    np.testing.assert_allclose(with_cubic - with_quartic, 0.7 * ((m / Ms) ** 3 - (M0 / Ms) ** 3), rtol=0, atol=1e-15)
    assert relative_stiffness_change(np.array([M0]), dict(values, delta_e_cubic=0.7))[0] == 0.0


def test_second_mode_below_the_lumped_one_is_the_modal_sum(recording):
    """The mode's range and one of its starts lie below the lumped mode (a mount's mode), and there the family
    is the sum of the lumped mode and a second-order system of static gain g2 times the first's (scipy's lsim,
    the forcing linear between samples, from the steady state)."""
    model = _model(recording, "rod_dynamics")
    values = model.values()
    f1 = np.sqrt(values["khat"]) / (2 * np.pi)
    assert model.parameters["f2"].lower == pytest.approx(SECOND_MODE_BELOW * f1)
    assert min(s["f2"] for s in effect_starts(model, "rod_dynamics", values)) < f1
    values.update(f2=0.5 * f1, damping2=0.1, g2=0.3)
    m = model.magnetization([values])[:, 0]
    ours = model.displacement(values, m)
    gain, khat, chat, omega = values["zetahat"], values["khat"], values["chat"], 2 * np.pi * values["f2"]
    modes = [([gain], [1.0, chat, khat]), ([0.3 * gain * omega ** 2 / khat], [1.0, 2 * 0.1 * omega, omega ** 2])]
    forcing = m - values["M0"]
    time = recording.time - recording.time[0]
    reference = np.zeros_like(ours)
    for numerator, denominator in modes:
        system = signal.StateSpace(*signal.tf2ss(numerator, denominator))
        start = -np.linalg.solve(system.A, system.B[:, 0] * forcing[0])
        reference += signal.lsim(system, forcing, time, X0=start)[1]
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-6 * np.ptp(reference))


def test_the_report_plots_the_fitted_law_against_the_m2_law(recording):
    """``magnetostriction.png``'s curves: the fitted forcing over M and the M^2 law with the same gains; the two
    are one curve where the even terms vanish, and part by exactly the even terms where they do not."""
    from types import SimpleNamespace

    from hyst_gym.diagnose.report import slot_shapes
    model = _model(recording, "quadratic_magnetostriction")
    values = dict(model.values(), zeta_q=0.2 * model.values()["zetahat"] / model.values()["Ms"])
    for zeta_4 in (0.0, -0.3 * values["zetahat"]):
        fit = SimpleNamespace(values=dict(values, zeta_4=zeta_4), model=model)
        [(stem, _, _, _, [(_, m, fitted), (_, _, quadratic)])] = slot_shapes(fit)
        assert stem == "magnetostriction"
        expected = even_law_forcing(m, values["Ms"], values["M0"], {"zeta_4": zeta_4})
        np.testing.assert_allclose(fitted - quadratic, expected, rtol=0, atol=1e-12 * np.ptp(quadratic))


def test_the_stiffness_family_is_fitted_no_worse_than_its_quadratic_member():
    """The staged fit of ``delta_e``: the quadratic law (the cubic and quartic held at 0) first, then both
    released from it and kept only if the fitting block asks for it; the result fits the block at least as well as
    the quadratic member's own fit (the candidate's model, the cubic and quartic fixed, from the same start), on a
    Clark M^2-law record."""
    from hyst_gym.diagnose.effects import effect
    from hyst_gym.diagnose.fit import Split
    from hyst_gym.diagnose.hypothesize import calibrate, fit_candidate

    assert effect("delta_e").strategy == "staged"
    assert effect("delta_e").held_first == ("delta_e_cubic", "delta_e_quartic")
    recording = make_recording_with_truth("delta_e", 5, output="displacement", n_samples=1200)[0]
    split = Split.of(recording, 0.3)
    base = calibrate(split, Structure(), n_points=32, keep=1)
    fitted = fit_candidate(split, base, "delta_e")
    structure = Structure(base.model.structure.transducer, base.model.structure.anhysteretic, "delta_e",
                          base.model.structure.fit_mechanics)
    parameters = {**base.model.parameters, **extension_parameters(recording, structure, base.values)}
    for held in ("delta_e_cubic", "delta_e_quartic"):
        parameters[held] = replace(parameters[held], free=False)
    member = Model(recording, structure, parameters, split.max_field_step)
    alone = min((split.fit(member, start, max_nfev=40) for start in effect_starts(member, "delta_e", base.values)),
                key=lambda result: result.sse)
    # the candidate is refitted from the member's fit once more: equal to the solver's tolerance, never worse
    assert fitted.sse <= alone.sse * (1 + 1e-3)
    if not fitted.model.parameters["delta_e_quartic"].free:
        assert fitted.values["delta_e_quartic"] == fitted.values["delta_e_cubic"] == 0.0


def _with_second_mode(recording, ratio):
    """The recording's displacement replaced by the lumped model's with a second mode at ``ratio`` times the
    lumped mode (g2 = 0.3), and the rod model on it at the base values (g2 = 0)."""
    from hyst_gym.diagnose.recording import Recording

    model = _model(recording, "rod_dynamics")
    values = model.values()
    f1 = np.sqrt(values["khat"]) / (2 * np.pi)
    truth = dict(values, f2=ratio * f1, damping2=0.05, g2=0.3)
    displacement = model.predict(truth)["displacement"]
    noise = 1e-3 * np.ptp(displacement) * np.random.default_rng(0).standard_normal(displacement.size)
    made = Recording(time=recording.time, field=recording.field, magnetization=recording.magnetization,
                     displacement=displacement + noise)
    model = _model(made, "rod_dynamics")
    # the lumped gain refitted (as the base fit does; the displacement is linear in it): the residual left is
    # what the lumped mode cannot follow, not a static gain
    lumped = model.predict(values)["displacement"]
    values["zetahat"] *= float(lumped @ made.displacement) / float(lumped @ lumped)
    return model, values, f1


@pytest.fixture(scope="module")
def rod_drive():
    """A record whose drive reaches the lumped mode's band (the own generator's rod_dynamics drive)."""
    return make_recording_with_truth("rod_dynamics", 4, output="both", n_samples=1500)[0]


@pytest.mark.parametrize("ratio, below_asked", [(0.3, True), (0.5, True), (2.0, False), (3.0, False)])
def test_the_start_below_the_lumped_mode_is_fitted_where_the_residual_asks_for_a_mode_there(rod_drive, ratio,
                                                                                          below_asked):
    """The linear probe of the base residual: a record whose second mode lies below the lumped one (a mount's)
    is explained better by a mode below than by one above, and the start below is kept; a record whose second
    mode lies above (a rod's higher mode) the reverse, and only the starts above are fitted."""
    from types import SimpleNamespace

    from hyst_gym.diagnose.effects import effect
    from hyst_gym.diagnose.fit import Split
    from hyst_gym.diagnose.hypothesize import STRATEGIES, second_mode_probe

    model, values, f1 = _with_second_mode(rod_drive, ratio)
    split = Split.of(model.recording, 0.3)
    below, above = second_mode_probe(split, model, values, f1)
    assert (below > above) == below_asked
    _, starts = STRATEGIES[effect("rod_dynamics").strategy](split, SimpleNamespace(values=values),
                                                            effect("rod_dynamics"), model)
    every = effect_starts(model, "rod_dynamics", values)
    assert any(s["f2"] < f1 for s in starts) == below_asked
    assert [s for s in every if s["f2"] > f1] == [s for s in starts if s["f2"] > f1]
