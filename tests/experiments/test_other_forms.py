"""The other-forms generator (experiments/other_forms.py): deterministic, its effects vanish at
zero size, its maps, rod and pickup have the stated physics, and it shares no code with the fitter.
Nothing here reads the mismatch tool's verdicts."""

import ast
import math
import pathlib
from dataclasses import replace

import numpy as np
import pytest
from scipy import linalg, signal

from experiments import independent_recordings as ir
from experiments import other_forms as of

ROOT = pathlib.Path(__file__).resolve().parents[2]
SHORT = 600
#: Cases whose effect has a size knob that switches it off at 0.
SIZED = ("delta_e_shifted", "saturating_amplifier", "sensor_nonlinearity", "heating_other_law",
         "sensor_offset_drift", "sensor_gain_drift", "mains_pickup", "two_phase_rod", "magnetostriction_law",
         "sensor_resonance", "pinning_temperature", "other_anhysteretic", "rod_on_mount")


def test_imports_nothing_of_the_fitter():
    tree = ast.parse((ROOT / "experiments" / "other_forms.py").read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            names.add(node.module or "")
    hyst = {n for n in names if n.startswith("hyst_gym")}
    assert hyst <= {"hyst_gym.diagnose.recording"}, hyst


@pytest.mark.parametrize("case", ["saturating_amplifier", "sensor_offset_drift"])
def test_same_seed_same_data(case):
    a, b = (of.simulate(case, 0, "both", n_samples=SHORT, size=1.0) for _ in range(2))
    for ch in a.clean:
        np.testing.assert_array_equal(a.clean[ch], b.clean[ch])
    assert a.truth == b.truth
    c = of.simulate(case, 5, "both", n_samples=SHORT, size=1.0)
    assert not np.array_equal(a.clean["magnetization"], c.clean["magnetization"])


def test_generate_is_deterministic_with_noise():
    (r1, t1), (r2, _) = (of.generate("mains_pickup", 6, "displacement", n_samples=SHORT) for _ in range(2))
    np.testing.assert_array_equal(r1.displacement, r2.displacement)
    assert r1.magnetization is None and t1["noise_std"]["displacement"] > 0
    assert "mains" not in str(r1.metadata).lower()


def test_coloured_noise_has_unit_variance_and_the_drawn_correlation():
    """AR(1) noise: the lag-1 autocorrelation is the white share's 0 plus the coloured share times
    exp(-1/tau); flicker: correlated at short lags, and decorrelated beyond its longest period. Both
    deterministic per stream and of unit variance."""
    n = 40000
    seen = set()
    for seed in range(12):
        noise, drawn = of.coloured_noise(ir._stream(seed, "test", "colour"), n)
        again, _ = of.coloured_noise(ir._stream(seed, "test", "colour"), n)
        np.testing.assert_array_equal(noise, again)
        assert abs(np.std(noise) - 1.0) < 0.05
        rho1 = float(np.mean(noise[:-1] * noise[1:]) / np.mean(noise * noise))
        seen.add(drawn["form"])
        if drawn["form"] == "ar1":
            expected = drawn["share"] * math.exp(-1.0 / drawn["correlation_samples"])
            assert abs(rho1 - expected) < 0.03, (rho1, drawn)
        else:
            far = int(3 * of.FLICKER_LONGEST_PERIOD)
            rho_far = float(np.mean(noise[:-far] * noise[far:]) / np.mean(noise * noise))
            assert rho1 > 0.1 and abs(rho_far) < 0.1, (rho1, rho_far, drawn)
    assert seen == {"ar1", "flicker"}


def test_coloured_recordings_keep_the_clean_signal_and_the_noise_level():
    (white, t_white), (coloured, t_col) = (of.generate("mains_pickup", 6, "both", n_samples=4000, noise=n)
                                           for n in ("white", "coloured"))
    assert "noise_colour" in t_col and "noise_colour" not in t_white
    sim = of.simulate("mains_pickup", 6, "both", n_samples=4000)
    for ch in ("magnetization", "displacement"):
        residual = getattr(coloured, ch) - sim.clean[ch]
        assert abs(np.std(residual) / t_col["noise_std"][ch] - 1.0) < 0.15
        assert not np.array_equal(getattr(white, ch), getattr(coloured, ch))
    with pytest.raises(ValueError, match="noise must be one of"):
        of.generate("mains_pickup", 6, "both", n_samples=600, noise="pink")


@pytest.mark.parametrize("case", SIZED)
def test_effect_vanishes_at_zero_size(case):
    st = of.setup(case, 6, SHORT)
    st = replace(st, form="mixture") if st.form == "split_roles" else st
    with_zero = of.forward(st.sized(0.0))
    plain = of.forward(replace(st, case="none_other_numerics"))
    for ch in of.BOTH:
        np.testing.assert_allclose(with_zero[ch], plain[ch], rtol=0, atol=1e-12 * np.ptp(plain[ch]))
    effect = of.forward(st)
    assert max(np.ptp(effect[ch] - plain[ch]) / np.ptp(plain[ch]) for ch in of.BOTH) > 1e-4


@pytest.mark.parametrize("form", ["tanh", "arctan", "erf", "asymmetric_tanh"])
def test_saturating_amplifier_is_monotone_and_saturates(form):
    h = np.linspace(-1.0, 1.0, 4001) * 1e5
    out = of.amplifier(h, form, overdrive=4.0, asymmetry=1.5)
    hs = 1e5 / 4.0
    assert np.all(np.diff(out) > 0)
    assert np.max(out) < hs and np.min(out) > -1.5 * hs
    assert out[-1] > 0.85 * hs  # 4 Hs in: within 15 % of the ceiling
    slope0 = (out[2001] - out[1999]) / (h[2001] - h[1999])
    assert slope0 == pytest.approx(1.0, abs=1e-3)  # unit small-signal gain
    np.testing.assert_allclose(of.amplifier(h, form, 1e-7, 1.5), h, rtol=1e-6)


@pytest.mark.parametrize("form", ["arctan", "tanh", "exponential"])
def test_sensor_map_is_monotone_and_not_a_cubic(form):
    y = np.sin(np.linspace(0, 6, 3000)) * 2e-5 + 1e-5
    out = of.sensor_map(y, form, 1.0, 0.1)
    order = np.argsort(y)
    assert np.all(np.diff(out[order]) >= 0)
    # the best cubic in y leaves a residual: the form is not the tool's polynomial
    v = (y - y.mean()) / np.ptp(y)
    basis = np.column_stack([v ** p for p in range(4)])
    residual = out - basis @ np.linalg.lstsq(basis, out, rcond=None)[0]
    assert np.std(residual) > 1e-4 * np.ptp(out)


def test_heating_laws_start_at_ambient_and_differ_from_the_tools():
    time = np.linspace(0, 1, 2001)
    field = 1e4 * np.sin(2 * np.pi * 20 * time)
    for network in ("series", "parallel"):
        law = {"drive": "abs", "network": network, "tau1": 0.05, "tau2": 0.5, "fast_share": 0.5,
               "a_law": "linear", "a_slope": 2e-3, "ms_law": "bloch", "curie": 650.0}
        theta = of.thermal_rise(time, field, law, 40.0)
        assert theta[0] == pytest.approx(0.0, abs=1e-9) and 0 < theta[-1] < 40.0
        a_scale, ms_scale = of.material_scales(theta, law)
        assert a_scale[0] == 1.0 and ms_scale[0] == 1.0 and theta[-1] > theta[500] > theta[100]
        assert ms_scale[-1] < 1.0  # Bloch: Ms falls as T rises


def test_rod_first_resonance_matches_the_frequency_equation_and_a_finite_difference_rod():
    mu = 2.0  # rod mass / tip mass
    roots, compliance = of.rod_modes(mu)
    # frequency equation beta*L*tan(beta*L) = mu
    assert np.allclose(roots * np.tan(roots), mu, rtol=1e-9)
    assert compliance.sum() == pytest.approx(1.0, abs=2e-3)  # static tip compliance L/(EA) = 1
    # independent check: a lumped-mass chain (N segments, L = EA = rho*A = 1) with the tip mass
    n = 200
    h = 1.0 / n
    stiffness = (np.diag(np.full(n, 2.0)) - np.diag(np.ones(n - 1), 1) - np.diag(np.ones(n - 1), -1)) / h
    stiffness[-1, -1] = 1.0 / h
    mass = np.full(n, h)
    mass[-1] = 0.5 * h + 1.0 / mu
    omega = np.sqrt(linalg.eigh(stiffness, np.diag(mass), eigvals_only=True, subset_by_index=[0, 2]))
    np.testing.assert_allclose(omega, roots[:3], rtol=1e-3)


def test_simulated_rod_rings_at_its_first_mode():
    """The Newmark-integrated modal rod, released from a static load, rings at f1."""
    f1, mu = 1300.0, 1.0
    roots, compliance = of.rod_modes(mu)
    omega = 2 * np.pi * f1 * roots / roots[0]
    fs = 50e3
    force = np.zeros(2000)
    force[:5] = 1.0  # released after 5 samples
    gain = omega ** 2 * compliance
    x = of.newmark(force, 1 / fs, omega ** 2, 2 * 0.002 * omega, gain, np.ones(omega.size), substeps=16)
    tail = x[50:] - x[50:].mean()
    crossings = np.flatnonzero(np.diff(np.sign(tail)) > 0)
    period = np.mean(np.diff(crossings[2:-2])) / fs
    assert 1 / period == pytest.approx(f1, rel=5e-3)


def test_newmark_matches_an_exact_lti_response():
    fs, khat, chat, gain = 20e3, 6.4e7, 7.9e3, 1.4e-2
    t = np.arange(3000) / fs
    forcing = 1e5 * np.sin(2 * np.pi * 300 * t) * np.exp(-t * 10)
    ours = of.newmark(forcing, 1 / fs, khat, chat, gain, 1.0, substeps=16)
    system = signal.lti([gain], [1.0, chat, khat])
    _, exact, _ = signal.lsim(system, forcing, t, X0=[0.0, 0.0], interp=True)
    assert np.max(np.abs(ours - exact)) < 2e-3 * np.ptp(exact)


def test_field_domain_magnetization_agrees_with_the_time_domain_solver():
    base = ir.draw_base(1, 400)  # a chirp: many reversals
    time, field, _ = ir.excitation(base)
    ours = of.magnetization(time, field, base.material)
    theirs = ir.simulate_magnetization(time, field, base.material)
    assert np.max(np.abs(ours - theirs)) < 1e-3 * np.ptp(theirs)


def test_mains_pickup_peaks_at_its_frequency():
    fs = 5000.0
    t = np.arange(int(20 * fs)) / fs
    y = of.mains(t, 50.1, 1.0, (0.3, 0.1), (0.1, 0.2, 0.3))
    spectrum = np.abs(np.fft.rfft(y * np.hanning(y.size)))
    freqs = np.fft.rfftfreq(y.size, 1 / fs)
    assert freqs[np.argmax(spectrum)] == pytest.approx(50.1, abs=0.06)
    third = (freqs > 140) & (freqs < 160)
    assert freqs[third][np.argmax(spectrum[third])] == pytest.approx(150.3, abs=0.06)


def test_effect_is_visible_and_skipped_channel_sets_refuse():
    for case, channels in (("sensor_offset_drift", "magnetization"), ("mains_pickup", "displacement")):
        sim = of.simulate(case, 6, channels, n_samples=SHORT)
        assert sim.truth["visible"] and sim.truth["visibility"][channels] >= of.MIN_VISIBILITY
    with pytest.raises(ValueError, match="cannot show"):
        of.simulate("continuum_rod", 0, "magnetization")


def test_command_line_writes_csv_sidecar_and_truth(tmp_path):
    out = tmp_path / "rec.csv"
    assert of.main(["--case", "saturating_amplifier", "--seed", "1", "--channels", "magnetization",
                    "--out", str(out), "--truth", str(tmp_path / "truth.json"), "--samples", str(SHORT)]) == 0
    header = out.read_text().splitlines()[0]
    assert header == "time,field,magnetization"
    assert out.with_suffix(".json").exists() and (tmp_path / "truth.json").exists()
    assert math.isfinite(float(out.read_text().splitlines()[1].split(",")[2]))


@pytest.mark.parametrize("form", ["tanh_saturating", "gaussian_saturating", "power"])
def test_magnetostriction_laws_are_even_zero_at_zero_and_not_polynomials(form):
    m = np.linspace(-1.0, 1.0, 2001)
    law = of.magnetostriction(m * 8e5, 8e5, form, 0.4, 3.0)
    np.testing.assert_allclose(law, law[::-1], rtol=0, atol=1e-15)
    assert law[1000] == 0.0 and np.all(law >= 0.0)
    # no even polynomial of degree <= 6 holds it to 1e-4 of its span (the tool's family does not contain it)
    design = np.column_stack([m ** 2, m ** 4, m ** 6])
    residual = law - design @ np.linalg.lstsq(design, law, rcond=None)[0]
    assert np.max(np.abs(residual)) > 1e-4 * np.ptp(law)


@pytest.mark.parametrize("form", ["two_stage", "random_walk", "sqrt_creep"])
def test_gain_drift_starts_at_zero_and_multiplies_the_channel(form):
    st = of.setup("sensor_gain_drift", 2, SHORT)
    st = replace(st, form=form, params=dict(st.params, channel="both"))
    drifted, plain = of.forward(st), of.forward(st.sized(0.0))
    for channel, ratio in (("magnetization", 1.0), ("displacement", st.params["displacement_ratio"])):
        change = of.gain_drift(st.time, form, ratio * st.params["amplitude"], st.params["tau"], of._walk(st, channel),
                               st.params["share"])
        np.testing.assert_allclose(drifted[channel], plain[channel] * (1.0 + change), rtol=1e-12)
        assert drifted[channel][0] == pytest.approx(plain[channel][0], rel=1e-12)
        assert 0.01 < np.max(np.abs(change)) < 0.5  # a drift of a few %, not a broken sensor


# ---------------------------------------------------------------------------- the blind cases' physics

@pytest.mark.parametrize("frequency, damping", [(1000.0, 0.05), (2500.0, 0.2)])
def test_resonant_sensor_peaks_at_its_resonance_and_keeps_the_static_gain(frequency, damping):
    fs = 40e3
    rng = np.random.default_rng(0)
    u = rng.standard_normal(2 ** 15)
    y = of.resonant_sensor(np.arange(u.size) / fs, u, frequency, damping)
    # the empirical transfer |Puy/Puu| (Welch averages) peaks where the second-order section does
    freqs, puu = signal.welch(u, fs, nperseg=4096)
    _, puy = signal.csd(u, y, fs, nperseg=4096)
    gain = np.abs(puy / puu)
    peak = frequency * math.sqrt(1.0 - 2.0 * damping ** 2)
    # within two bins or 2 % (a broad peak's top is flat)
    assert freqs[np.argmax(gain)] == pytest.approx(peak, abs=max(2 * fs / 4096, 0.02 * peak))
    assert np.max(gain) == pytest.approx(1.0 / (2 * damping * math.sqrt(1 - damping ** 2)), rel=0.25)
    assert gain[1] == pytest.approx(1.0, abs=0.05)  # unit gain well below the resonance
    constant = of.resonant_sensor(np.arange(200) / fs, np.full(200, 3.0), frequency, damping)
    np.testing.assert_allclose(constant, 3.0, rtol=1e-12)  # started settled


def test_sensor_resonance_case_rings_in_the_recorded_channel():
    st = of.setup("sensor_resonance", 3, 2000)
    st = replace(st, params=dict(st.params, channel="displacement"))
    ringing, plain = of.forward(st), of.forward(st.sized(0.0))
    np.testing.assert_array_equal(ringing["magnetization"], plain["magnetization"])  # the other sensor is clean
    difference = ringing["displacement"] - plain["displacement"]
    fs = st.base.conditions.sample_rate
    freqs = np.fft.rfftfreq(difference.size, 1 / fs)
    spectrum = np.abs(np.fft.rfft(difference * np.hanning(difference.size)))
    # the error the resonant sensor adds is largest near its resonance (above the slow drive)
    f0 = st.params["frequency_displacement"]
    assert abs(freqs[np.argmax(spectrum * (freqs > 200))] - f0) < 0.35 * f0


def test_pinning_collapses_toward_the_curie_point():
    theta = np.linspace(0.0, 150.0, 301)
    material = ir.Material(a=7000.0, k=2000.0, alpha=-0.05, Ms=8e5, c=0.2)
    for form in ("power_law_k", "exponential_k"):
        p = {"curie": ir.T_AMBIENT + 100.0, "k_power": 2.0, "k_temperature": 20.0}
        k_scale, ms_scale, notes = of.pinning_scales(theta, p, form, material)
        assert k_scale[0] == pytest.approx(1.0) and ms_scale[0] == pytest.approx(1.0)
        assert np.all(np.diff(k_scale) <= 0) and np.all(np.diff(ms_scale) <= 0)
        assert k_scale[theta == 80.0][0] < 0.1  # 20 K below Tc the pinning has nearly gone
        assert notes["temperature_capped"]  # theta reaches past Tc - 5 K: said, not hidden
    # alpha > 0: the pinning is floored where eq. (6)'s irreversible denominator would reach 0, and it says so
    positive = replace(material, alpha=0.05)
    k_scale, ms_scale, notes = of.pinning_scales(theta, p, "power_law_k", positive)
    assert notes["k_floored"] and np.all((1 - positive.c) * positive.k * k_scale
                                         > 2 * positive.alpha * positive.Ms * ms_scale)


def test_pinning_scale_is_the_same_as_a_material_with_that_pinning():
    """A constant k(t)/k = s gives the loop of the material with pinning s*k: an independent check of the
    time-varying path; and a smaller pinning gives a narrower loop (less hysteresis loss)."""
    time = np.linspace(0.0, 1.0, 1201)
    field = 3e4 * np.sin(2 * np.pi * 3 * time)
    material = ir.Material(a=7000.0, k=3000.0, alpha=-0.02, Ms=8e5, c=0.2)
    scaled = of.magnetization(time, field, material, k_scale=np.full(time.size, 0.4))
    direct = of.magnetization(time, field, replace(material, k=0.4 * material.k))
    np.testing.assert_allclose(scaled, direct, rtol=0, atol=1e-6 * np.ptp(direct))
    full = of.magnetization(time, field, material)
    last = time > 2.0 / 3.0  # the last cycle
    def loss(m):
        return abs(np.trapezoid(m[last], field[last]))
    assert loss(scaled) < 0.8 * loss(full)


@pytest.mark.parametrize("form, shape", [("brillouin", 5.0), ("two_langevin", 0.5), ("sharp_knee", 4.0)])
@pytest.mark.parametrize("base", ["ising", "langevin"])
def test_other_anhysteretic_curves_are_odd_monotone_saturating_with_the_base_slope(form, shape, base):
    curve = of.AnhystereticCurve(base=base, form=form, blend=1.0, shape=shape, width_ratio=5.0)
    x = np.linspace(-400.0, 400.0, 16001)
    values = np.array([curve(v)[0] for v in x])
    slopes = np.array([curve(v)[1] for v in x])
    np.testing.assert_allclose(values, -values[::-1], rtol=0, atol=1e-12)  # odd (to rounding of the grid)
    inner = np.abs(x[1:]) < 10.0  # further out the curve is flat to double precision
    assert np.all(np.diff(values) >= -1e-15) and np.all(np.diff(values)[inner] > 0) and np.all(slopes >= 0)
    assert values[-1] == pytest.approx(1.0, abs=0.05) and np.max(np.abs(values)) <= 1.0 + 1e-12  # saturates at Ms
    s0 = 1.0 if base == "ising" else 1.0 / 3.0
    assert curve(0.0)[1] == pytest.approx(s0, rel=1e-6)  # the base's slope at 0 (same rho)
    assert np.max(slopes) == pytest.approx(s0, rel=1e-6)  # steepest at 0 (the draw's safety margins hold)
    # the slope is the derivative of the value (central differences)
    fine = np.linspace(-20.0, 20.0, 40001)
    np.testing.assert_allclose(np.gradient([curve(v)[0] for v in fine], fine)[1:-1],
                               [curve(v)[1] for v in fine[1:-1]], rtol=0, atol=1e-4 * s0)
    # not the base curve: the shape differs by more than 1 % of Ms somewhere
    base_values = np.array([ir.anhysteretic(v, base)[0] for v in x])
    assert np.max(np.abs(values - base_values)) > 0.01


def test_brillouin_limits_are_tanh_and_langevin():
    x = np.linspace(-5.0, 5.0, 101)
    np.testing.assert_allclose([of.brillouin(v, 0.5)[0] for v in x], np.tanh(x), atol=1e-12)
    large = np.array([of.brillouin(v, 1e4)[0] for v in x])
    np.testing.assert_allclose(large, [ir.anhysteretic(v, "langevin")[0] for v in x], atol=1e-3)


def test_custom_curve_slope_at_zero_blend_is_eq6():
    material = ir.Material(a=7000.0, k=2000.0, alpha=-0.05, Ms=8e5, c=0.3)
    curve = of.AnhystereticCurve(base="ising", form="sharp_knee", blend=0.0, shape=4.0)
    m = material
    for H, M, delta in ((1e4, 2e5, 1.0), (-5e3, 3e5, -1.0), (2e4, 7e5, 1.0), (-3e4, -6e5, 1.0)):
        assert curve.slope(H, M, delta, m.a, m.k, m.alpha, m.Ms, m.c) == pytest.approx(
            ir.hysteresis_slope(H, M, delta, m.a, m.k, m.alpha, m.Ms, m.c), rel=1e-12, abs=1e-15)


def test_rod_on_mount_keeps_the_static_gain_and_adds_the_mount_mode():
    mech = ir.Mechanics(chat=7.9e3, khat=6.4e7, zetahat=1.4e-2)
    p = {"mass_ratio": 2.0, "compliance": 1.5, "mount_damping": 0.05}
    for form in ("ground_referenced", "mount_referenced"):
        num, den = of.mount_transfer(mech, p, form)
        assert num[-1] / den[-1] == pytest.approx(1.0 / mech.khat, rel=1e-12)  # the lumped static gain
        assert den.size == 5  # two modes
    undamped = of.mount_transfer(mech, dict(p, mount_damping=0.0), "ground_referenced")
    # the poles of the undamped-mount system, with the rod's damping removed, are the eigenfrequencies
    free = replace(mech, chat=0.0)
    _, den = of.mount_transfer(free, dict(p, mount_damping=0.0), "ground_referenced")
    poles = np.sort(np.abs(np.roots(den).imag)[::2]) / (2 * np.pi)
    np.testing.assert_allclose(poles, of.mount_modes(free, p), rtol=1e-6)
    modes = of.mount_modes(mech, p)
    lumped = math.sqrt(mech.khat) / (2 * math.pi)
    assert modes[0] < lumped < modes[1]  # a soft mount splits the lumped mode into two
    assert undamped[1].size == 5


def test_rod_on_mount_follows_the_lumped_model_on_a_slow_drive():
    st = of.setup("rod_on_mount", 1, 2000)  # modes at 383 and 1336 Hz; 0.156 s long
    slow = replace(st, field=st.base.conditions.bias + st.base.conditions.amplitude
                   * np.sin(2 * np.pi * st.time / st.time[-1]))  # one cycle: 6.4 Hz, quasi-static
    mounted, lumped = of.forward(slow), of.forward(slow.sized(0.0))
    np.testing.assert_array_equal(mounted["magnetization"], lumped["magnetization"])
    assert np.max(np.abs(mounted["displacement"] - lumped["displacement"])) < 1e-3 * np.ptp(lumped["displacement"])
    # and on the drawn drive (steps that excite the modes) it does not
    fast, plain = of.forward(st), of.forward(st.sized(0.0))
    assert np.max(np.abs(fast["displacement"] - plain["displacement"])) > 1e-2 * np.ptp(plain["displacement"])


@pytest.mark.parametrize("case", ["sensor_resonance", "pinning_temperature", "other_anhysteretic",
                                  "rod_on_mount"])
def test_blind_cases_are_drawn_deterministically_and_name_the_expected_slot(case):
    a, b = (of.simulate(case, 2, "both", n_samples=SHORT) for _ in range(2))
    for ch in a.clean:
        np.testing.assert_array_equal(a.clean[ch], b.clean[ch])
    assert a.truth == b.truth and a.truth["form"] in of.CASES[case].forms
    from hyst_gym.diagnose.effects import EFFECT_SLOTS
    assert of.CASES[case].expected <= set(EFFECT_SLOTS)
