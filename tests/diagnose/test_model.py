"""The fitted model's pieces: exact LTI steps, nesting of extensions, the fitter on known truth."""

import numpy as np
import pytest

from hyst_gym.diagnose.fit import local_fit
from hyst_gym.diagnose.kernels import AMBIENT_TEMPERATURE, MAGNETIC_COLUMNS, lti_response, simulate_members
from hyst_gym.diagnose.make_recording import make_recording_with_truth
from hyst_gym.diagnose.model import Model, Structure, base_parameters, extension_parameters, noise_level
from hyst_gym.physics import simulate_magnetization


def test_first_order_lag_is_exact_for_ramps():
    """FOH is exact for piecewise-linear input: compare with the closed-form ramp response."""
    tau = 0.01
    t = np.sort(np.concatenate([np.linspace(0, 0.1, 57), [0.0123, 0.0456]]))  # non-uniform steps
    u = 3.0 * t
    y = lti_response(t, u, [[-1 / tau]], [1 / tau], [1.0])
    exact = 3.0 * (t - tau * (1 - np.exp(-t / tau)))
    assert np.max(np.abs(y - exact)) < 1e-12


def test_plain_members_match_physics_kernel():
    """With every extension off, the extended kernel is the physics model (6) driven from 0."""
    time = np.linspace(0, 1, 801)
    field = 8e4 * np.sin(2 * np.pi * 2 * time) * np.exp(-time)
    row = dict(a=6000, k=1500, alpha=-0.05, Ms=8e5, c=0.2, H0=0, k_e=0, heating=0, tau_th=1, beta_Ms=0,
               chi_r=0, heating_exponent=2)
    ours = simulate_members(time, field, np.array([[row[c] for c in MAGNETIC_COLUMNS]]), 0, 10.0,
                            AMBIENT_TEMPERATURE)[:, 0]
    ref = simulate_magnetization(np.concatenate([[0.0], field]), max_field_step=10.0, a=6000, k=1500,
                                 alpha=-0.05, Ms=8e5, c=0.2)[1:]
    assert np.max(np.abs(ours - ref)) < 1e-9 * 8e5


def test_small_loop_members_match_the_physics_extension_and_share_the_bank_with_plain_ones():
    """Members with chi_r run through the physics layer's small-loop kernel, plain members through
    (6): both give the physics layer's numbers when simulated together."""
    time = np.linspace(0, 1, 801)
    field = 8e4 * np.sin(2 * np.pi * 2 * time) * np.exp(-time)
    plain = dict(a=6000, k=1500, alpha=-0.05, Ms=8e5, c=0.2, H0=0, k_e=0, heating=0, tau_th=1, beta_Ms=0,
               chi_r=0, heating_exponent=2)
    rows = np.array([[dict(plain, chi_r=chi)[c] for c in MAGNETIC_COLUMNS] for chi in (0.0, 30.0, 60.0)])
    ours = simulate_members(time, field, rows, 0, 10.0, AMBIENT_TEMPERATURE)
    for column, chi in enumerate((0.0, 30.0, 60.0)):
        ref = simulate_magnetization(np.concatenate([[0.0], field]), max_field_step=10.0, a=6000, k=1500,
                                     alpha=-0.05, Ms=8e5, c=0.2, chi_r=chi)[1:]
        assert np.max(np.abs(ours[:, column] - ref)) < 1e-9 * 8e5
    assert np.max(np.abs(ours[:, 2] - ours[:, 0])) > 1e-2 * 8e5  # and chi_r matters


def test_eddy_current_converges_and_lags():
    """The semi-implicit eddy step converges under time refinement and widens the loop."""
    def run(n, k_e):
        time = np.linspace(0, 0.05, n)
        field = 6e4 * np.sin(2 * np.pi * 40 * time)
        row = dict(a=6000, k=1500, alpha=-0.05, Ms=8e5, c=0.2, H0=0, k_e=k_e, heating=0, tau_th=1,
                   beta_Ms=0, chi_r=0, heating_exponent=2)
        return simulate_members(time, field, np.array([[row[c] for c in MAGNETIC_COLUMNS]]), 0, 10.0,
                                AMBIENT_TEMPERATURE)[:, 0]
    coarse, fine, finest = run(501, 2e-5)[::1], run(2001, 2e-5)[::4], run(8001, 2e-5)[::16]
    assert np.max(np.abs(fine - finest)) < 0.5 * np.max(np.abs(coarse - finest))
    assert np.max(np.abs(finest - run(8001, 0.0)[::16])) > 1e4   # the effect is not negligible


@pytest.mark.parametrize("effect", ["field_bias", "eddy_current", "thermal_drift", "sensor_lag",
                                    "quadratic_magnetostriction", "rod_dynamics", "small_loop"])
def test_extensions_reduce_to_base_when_switched_off(effect):
    rec, _, truth = make_recording_with_truth("none", 3, n_samples=600)
    base = Model(rec, Structure(), base_parameters(rec, Structure()), 100.0)
    values = base.values()
    structure = Structure(extension=effect)
    extra = extension_parameters(rec, structure, values)
    ext = Model(rec, structure, {**base.parameters, **extra}, 100.0)
    off = dict(values, **{n: 0.0 for n in extra if n in ("H0", "k_e", "heating", "tau_m", "tau_x", "zeta_q", "g2",
                                                        "beta_Ms", "chi_r")})
    off.update({n: extra[n].value for n in extra if n not in off})
    a, b = base.predict(values), ext.predict(off)
    for ch in a:
        assert np.array_equal(a[ch], b[ch])


def test_base_fit_recovers_truth_to_noise():
    rec, _, truth = make_recording_with_truth("none", 11, n_samples=1500)
    structure = Structure()
    model = Model(rec, structure, base_parameters(rec, structure), float(np.ptp(rec.field)) / 1000)
    noise = {ch: noise_level(rec.output(ch)) for ch in rec.channels}
    start = {n: truth[n] * 1.05 for n in ("a", "k", "Ms", "khat", "chat", "zetahat", "M0")}
    start.update(rho=truth["rho"], c=truth["c"])
    fit = local_fit(model, noise, np.ones(rec.size, bool), start, max_nfev=60)
    assert fit.sse / fit.n_residuals < 1.3          # explained to within noise
    for name in ("a", "k", "Ms"):
        assert abs(fit.values[name] / truth[name] - 1) < 0.03
        assert fit.uncertainties[name] > 0


def test_fem_base_model_matches_physics_femrod_and_statics():
    """The ``fem`` base model's tip displacement against FEMRod.simulate (an independent stepping
    path) on a non-uniform grid, and its quasi-static limit against the rod's static compliance."""
    from hyst_gym.diagnose.kernels import step_classes
    from hyst_gym.diagnose.model import _fem_tip_displacement, fem_rod
    steps = np.where(np.arange(900) % 3 == 0, 2e-5, 3e-5)
    time = np.r_[0.0, np.cumsum(steps)]
    forcing = np.sin(2 * np.pi * 900 * time) + 0.3
    values = dict(Y=3e10, ML=0.1, cD=3e4)
    ours = _fem_tip_displacement(time, forcing, 2.0, values, step_classes(time))
    rod = fem_rod(values)
    rod = rod.replace(bias_magnetization=2.0 / (2 * rod.rod.force_coefficient))
    reference = rod.simulate(time, forcing, state0=rod.discretize(2e-5).steady_state(np.array([forcing[0]])))
    assert np.max(np.abs(ours - reference)) < 1e-8 * np.ptp(reference)
    slow = np.sin(2 * np.pi * 2.0 * time) + 0.3          # 2 Hz << first mode (~2.4 kHz)
    quasi = _fem_tip_displacement(time, slow, 2.0, values, step_classes(time))
    compliance = np.linalg.solve(rod.stiffness_matrix(), rod.forcing_vector())[-1]
    # the damping's lag (c/k)*dF/dt is ~0.3 % of the swing at 2 Hz; a wrong gain or compliance is O(1)
    assert np.max(np.abs(quasi - 2.0 * compliance * slow)) < 1e-2 * np.ptp(quasi)


def test_rod_dynamics_generator_excites_a_visible_second_mode():
    """The concealed rod has a lightly damped second mode below Nyquist, inside the chirp's band,
    and far from the first: the lumped one-mode model cannot follow it."""
    from hyst_gym.diagnose.make_recording import _rod_state_space
    for seed in range(5):
        A, B, C, static = _rod_state_space(np.random.default_rng(seed))
        poles = np.linalg.eigvals(A)
        poles = poles[poles.imag > 0]
        poles = poles[np.argsort(np.abs(poles))]
        freq, damping = np.abs(poles) / (2 * np.pi), -poles.real / np.abs(poles)
        assert 2.5 * freq[0] < freq[1] < 12e3 and damping[1] < 0.15   # the default cD=3e6 Pa s overdamps it
        assert static > 0


def test_rod_mode_damping_and_the_m2_gain_are_separate_parameters():
    # zeta2 is the M^2 gain of lumped_nonlinear (12); the rod mode's damping ratio is damping2.
    # Before they were split, one overwrote the other in lumped_nonlinear x rod_dynamics.
    from hyst_gym.diagnose.make_recording import make_recording
    from hyst_gym.diagnose.model import Model, Structure, base_parameters, extension_parameters

    recording, _ = make_recording("none", 2, n_samples=1500, output="displacement")
    structure = Structure("lumped_nonlinear", "ising", "rod_dynamics")
    params = base_parameters(recording, structure)
    params.update(extension_parameters(recording, structure, {n: p.value for n, p in params.items()}))
    assert {"zeta2", "damping2", "f2", "g2"} <= set(params)
    assert params["zeta2"].unit != params["damping2"].unit
    model = Model(recording, structure, params, max_field_step=float(np.ptp(recording.field)) / 400)
    values = dict(model.values(), M0=0.0, g2=0.3, f2=9e3)
    m = model.magnetization([values])[:, 0]
    x = model.displacement(values, m)
    # the M^2 gain scales the whole (linear-in-gain) response ...
    np.testing.assert_allclose(model.displacement(dict(values, zeta2=2 * values["zeta2"]), m), 2 * x, rtol=1e-9)
    # ... while the mode's damping changes its shape, not its scale
    damped = model.displacement(dict(values, damping2=1.5), m)
    ratio = damped / np.where(np.abs(x) > 1e-3 * np.ptp(x), x, np.nan)
    assert np.nanstd(ratio) > 1e-3


def test_delta_e_displacement_matches_an_independent_integration():
    from scipy.integrate import solve_ivp

    from hyst_gym.diagnose.kernels import varying_stiffness_response

    time = np.arange(3000) / 40e3
    forcing = 5e1 * np.sin(2 * np.pi * 250 * time) + 2e1 * np.sin(2 * np.pi * 1900 * time)   # m/s^2
    relative = 0.5 * np.sin(2 * np.pi * 90 * time) ** 2
    khat, chat = 6.4251e7, 7.8899e3
    x = varying_stiffness_response(time, forcing, relative, khat, chat)
    sol = solve_ivp(lambda t, y: [y[1], np.interp(t, time, forcing) - chat * y[1]
                                  - khat * (1 + np.interp(t, time, relative)) * y[0]],
                    (0, time[-1]), [x[0], 0.0], t_eval=time, method="DOP853", rtol=1e-10, atol=1e-15,
                    max_step=5e-6)
    effect = np.max(np.abs(x - varying_stiffness_response(time, forcing, 0 * relative, khat, chat)))
    assert effect > 0.1 * np.ptp(x)                       # the stiffness change is large here ...
    assert np.max(np.abs(sol.y[0] - x)) < 1e-3 * np.ptp(x)  # ... and integrated to 0.1 % of the response


# ---------------------------------------------------------------------------- families (issue 22)


def test_delta_e_family_holds_a_law_about_another_centre():
    """A stiffness law in (M - Mb)^2 about a centre Mb != 0 is the family's member with
    delta_e_linear = -2*delta_e*Mb/Ms (expanded by hand here), zero at the bias M0."""
    from hyst_gym.diagnose.model import relative_stiffness_change

    rng = np.random.default_rng(5)
    Ms, M0, Mb, delta = 7e5, 1.2e5, -2.5e5, 0.8
    m = rng.uniform(-Ms, Ms, 500)
    shifted = delta * (((m - Mb) / Ms) ** 2 - ((M0 - Mb) / Ms) ** 2)
    values = {"Ms": Ms, "M0": M0, "delta_e": delta, "delta_e_linear": -2 * delta * Mb / Ms}
    np.testing.assert_allclose(relative_stiffness_change(m, values), shifted, rtol=1e-12, atol=1e-12)
    assert relative_stiffness_change(np.array([M0]), values)[0] == pytest.approx(0.0, abs=1e-15)


def test_input_map_family_identity_and_algebraic_sigmoid():
    """The input map is the identity at zero coefficients and, with only its saturation term, the
    algebraic sigmoid H/sqrt(1 + s*(H/Hmax)^2), which stays within a few % of Hs*tanh(H/Hs) for a
    moderate saturation (gain at the peak 0.8 of the small-signal gain)."""
    from hyst_gym.diagnose.model import mapped_field

    h = np.linspace(-3e4, 3e4, 301)
    assert mapped_field(h, 0.0, 0.0, 0.0, 0.0) is h
    s = 0.6
    np.testing.assert_allclose(mapped_field(h, 0.0, 0.0, s, s), h / np.sqrt(1 + s * (h / 3e4) ** 2), rtol=1e-12)
    # a tanh with the same peak value and slope 1 at 0: Hs*tanh(Hmax/Hs) = Hmax/sqrt(1 + s)
    from scipy.optimize import brentq

    peak = 3e4 / np.sqrt(1 + s)
    hs = brentq(lambda x: x * np.tanh(3e4 / x) - peak, 1e3, 1e7)
    assert np.max(np.abs(mapped_field(h, 0.0, 0.0, s, s) - hs * np.tanh(h / hs))) < 0.05 * peak


def test_static_maps_must_be_monotone_to_be_plausible():
    """The plausibility check computes the maps' slopes analytically; they agree with finite
    differences of the maps themselves, and a map that folds back is caught."""
    from hyst_gym.diagnose.decide import static_map_slopes
    from hyst_gym.diagnose.model import mapped_field

    values = {"input_quadratic": 0.3, "input_cubic": -0.2, "input_saturation": 2.0, "input_saturation_negative": 6.0}
    (_, slope), = static_map_slopes("input_map", values, ())
    u = np.linspace(-1.0, 1.0, 201)
    numeric = np.gradient(mapped_field(u, 0.3, -0.2, 2.0, 6.0), u)
    np.testing.assert_allclose(slope[1:-1], numeric[1:-1], atol=2e-3)
    # unequal rails alone never fold back, however unequal
    rails = dict(input_quadratic=0.0, input_cubic=0.0, input_saturation=0.5, input_saturation_negative=30.0)
    assert np.min(static_map_slopes("input_map", rails, ())[0][1]) > 0.0
    folding = {"input_quadratic": 0.5, "input_cubic": -0.33, "input_saturation": 0.0, "input_saturation_negative": 0.0}
    assert np.min(static_map_slopes("input_map", folding, ())[0][1]) < 0.0
    sensor = {"sensor_quadratic_x": 0.1, "sensor_cubic_x": -0.2, "sensor_quadratic_m": 0.0, "sensor_cubic_m": 0.0}
    (_, x_slope), = static_map_slopes("sensor_map", sensor, ("displacement",))
    assert np.all(x_slope > 0.0)


def test_additive_sensor_terms_are_what_they_say():
    """sensor_drift adds f, f^2 and 1 - exp(-f/tau) (f: the time mapped to [0, 1], 0 at the start) in units of
    the channel's half-span, mains_pickup a 50/60 Hz sinusoid and its third harmonic (the FFT peaks at the stated
    frequencies); both vanish at zero coefficients."""
    from hyst_gym.diagnose.hypothesize import mains_starts
    from hyst_gym.diagnose.model import channel_range

    recording, _, _ = make_recording_with_truth("none", 3, output="both", n_samples=4000)
    structure = Structure("lumped", "ising", "sensor_drift")
    base = base_parameters(recording, structure)
    params = {**base, **extension_parameters(recording, structure, {n: p.value for n, p in base.items()})}
    model = Model(recording, structure, params, 200.0)
    values = model.values()
    plain = model.predict(values)
    drifted = model.predict(dict(values, drift_linear_x=0.1, drift_quadratic_x=-0.05))
    time = recording.time
    fraction = (time - time[0]) / (time[-1] - time[0])
    half = channel_range(recording.displacement)[1]
    np.testing.assert_allclose(drifted["displacement"] - plain["displacement"],
                               half * (0.1 * fraction - 0.05 * fraction ** 2), rtol=1e-9, atol=1e-15)
    # the settling term: a warm-up of the offset, 1 - exp(-f/tau_drift), the gain drift's basis
    settled = model.predict(dict(values, drift_settling_x=0.07, tau_drift=0.2))
    np.testing.assert_allclose(settled["displacement"] - plain["displacement"],
                               half * 0.07 * (1.0 - np.exp(-fraction / 0.2)), rtol=1e-9, atol=1e-15)
    # a drift of the offset since the start: the first sample is the sensor's zero
    assert drifted["displacement"][0] == plain["displacement"][0]
    np.testing.assert_array_equal(drifted["magnetization"], plain["magnetization"])

    structure = Structure("lumped", "ising", "mains_pickup")
    params = {**base, **extension_parameters(recording, structure, values)}
    model = Model(recording, structure, params, 200.0)
    values = dict(model.values(), mains_hz=60.0)
    picked = model.predict(dict(values, mains_sin_m=0.2, mains3_cos_m=0.1))["magnetization"]
    added = picked - model.predict(values)["magnetization"]
    spectrum = np.abs(np.fft.rfft(added))
    freqs = np.fft.rfftfreq(added.size, float(np.median(np.diff(time))))
    peaks = freqs[np.argsort(spectrum)[-2:]]
    assert np.allclose(sorted(peaks), [60.0, 180.0], atol=2 * (freqs[1] - freqs[0]))
    # the frequency choice reads the residual: pickup at 60 Hz added to the recording is found at 60 Hz
    from dataclasses import replace as replaced

    noisy = replaced(recording, magnetization=recording.magnetization + added)
    fitted = Model(noisy, structure, params, 200.0)
    fit_mask = np.arange(time.size) < 0.75 * time.size
    noise = {ch: noise_level(noisy.output(ch)) for ch in noisy.channels}
    best = mains_starts(fitted, values, noise, fit_mask)[0]
    assert best["mains_hz"] == 60.0
    assert best["mains_sin_m"] > 0.05 and best["mains3_cos_m"] > 0.05  # the pickup's own sign and order
