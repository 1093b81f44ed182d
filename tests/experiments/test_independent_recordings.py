"""The independent recording generator: its numerics converge and meet closed-form limits, its
draws are deterministic and paired across effects, every effect shows above the noise, and it
shares no code with the fitter."""

import ast
import itertools
import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from experiments import independent_recordings as ir

ROOT = pathlib.Path(__file__).resolve().parents[2]
MODULE = ROOT / "experiments" / "independent_recordings.py"
#: The smallest noise the generator draws, as a fraction of an output's peak-to-peak.
MIN_NOISE = 1e-3
#: Short records keep the file fast; the draws are the same as at full length.
SHORT = 1500


def short_field(seed, n_samples=SHORT):
    base = ir.draw_base(seed, n_samples)
    time, field, _ = ir.excitation(base)
    return base, time, field


# ---------------------------------------------------------------------------- hysteresis numerics

@pytest.mark.parametrize("seed", [1, 8])  # a chirp and a PRBS: many reversals, fast edges
def test_magnetization_converges_far_below_the_noise(seed):
    base, time, field = short_field(seed)
    mat = base.material
    coarse = ir.simulate_magnetization(time, field, mat)
    fine = ir.simulate_magnetization(time, field, mat, tol=ir.TOLERANCE / 32)  # ~ half the step (5th order)
    span = np.ptp(coarse)
    assert np.max(np.abs(coarse - fine)) < 0.02 * MIN_NOISE * span
    rate = np.abs(np.gradient(coarse, time))
    k_e = 0.1 * base.conditions.amplitude / np.percentile(rate, 99)
    eddy = ir.simulate_magnetization(time, field, mat, eddy_k=k_e)
    eddy_fine = ir.simulate_magnetization(time, field, mat, eddy_k=k_e, tol=ir.EDDY_TOLERANCE / 8)  # half (2nd order)
    assert np.max(np.abs(eddy - eddy_fine)) < 0.02 * MIN_NOISE * span
    # and the eddy field matters: the check above is not comparing two copies of "none"
    assert np.max(np.abs(eddy - coarse)) > 10 * MIN_NOISE * span


def test_magnetization_matches_scipy_lsoda():
    """Cross-check against SciPy's LSODA (Adams/BDF multistep) on the same field spline."""
    base, time, field = short_field(1, 400)
    mat = base.material
    ours = ir.simulate_magnetization(time, field, mat)
    spline = CubicSpline(time, field)
    rate = spline.derivative()

    def rhs(t, y):
        r = float(rate(t))
        return [ir.hysteresis_slope(float(spline(t)), y[0], 1.0 if r >= 0 else -1.0, mat.a, mat.k, mat.alpha,
                                    mat.Ms, mat.c) * r]

    ref = solve_ivp(rhs, (time[0], time[-1]), [ours[0]], method="LSODA", t_eval=time, rtol=1e-10, atol=1e-6)
    assert ref.success
    assert np.max(np.abs(ref.y[0] - ours)) < 0.01 * MIN_NOISE * np.ptp(ours)


@pytest.mark.parametrize("curve,rho", [("ising", -8.0), ("ising", 0.5), ("langevin", -2.0)])
def test_reversible_limit_is_the_anhysteretic_curve(curve, rho):
    """c = 1 removes the irreversible term: M = Man(H + alpha*M) exactly, on every branch."""
    a = 6000.0 if curve == "ising" else 2000.0
    Ms = 7.65e5
    slope_factor = 1.0 if curve == "ising" else 1.0 / 3.0
    mat = ir.Material(a=a, k=400.0, alpha=rho * a / (Ms * slope_factor), Ms=Ms, c=1.0, curve=curve)
    assert not mat.problems()
    time = np.linspace(0.0, 0.02, 801)
    field = 8e4 * np.sin(2 * np.pi * 100 * time) * (0.4 + 0.6 * time / time[-1]) + 5e3
    M = ir.simulate_magnetization(time, field, mat)
    assert np.max(np.abs(M - ir.anhysteretic_magnetization(field, mat))) < 1e-6 * Ms


def test_initial_curve_without_coupling_matches_its_closed_form():
    """alpha = 0 on a rising field: (6) is the linear ODE dM/dH = (Man - M)/k + c*Man'(H), so
    M(H) = exp(-H/k) * integral_0^H exp(s/k) (Man(s)/k + c*Man'(s)) ds from the demagnetized state."""
    Ms, a, k, c = 7.65e5, 7012.0, 2500.0, 0.3
    mat = ir.Material(a=a, k=k, alpha=0.0, Ms=Ms, c=c)
    time = np.linspace(0.0, 0.01, 401)
    field = 5e4 * (time / time[-1]) ** 2 * (3 - 2 * time / time[-1])  # smooth ramp 0 -> 50 kA/m
    M = ir.simulate_magnetization(time, field, mat)
    s = np.linspace(0.0, field[-1], 400001)
    integrand = np.exp((s - s[-1]) / k) * (Ms * np.tanh(s / a) / k + c * Ms / a / np.cosh(s / a) ** 2)
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(s))])
    closed = np.interp(field, s, cumulative) * np.exp((s[-1] - field) / k)
    assert np.max(np.abs(M - closed)) < 1e-5 * Ms


def test_small_pinning_approaches_the_anhysteretic_curve():
    """k -> 0: the loop closes onto the anhysteretic curve, its width shrinking ~ k."""
    Ms, a = 7.65e5, 7012.0
    time = np.linspace(0.0, 0.02, 801)
    field = 6e4 * np.sin(2 * np.pi * 100 * time)
    deviations = []
    for k in (2000.0, 1000.0, 500.0, 250.0):
        mat = ir.Material(a=a, k=k, alpha=-0.01, Ms=Ms, c=0.18)
        M = ir.simulate_magnetization(time, field, mat)
        deviations.append(np.max(np.abs(M - ir.anhysteretic_magnetization(field, mat))[400:]))
    assert deviations[0] > 0.05 * Ms                       # a real loop to begin with
    for wide, narrow in itertools.pairwise(deviations):
        assert 1.7 < wide / narrow < 2.3                     # first order in k


def test_hysteresis_loop_is_traversed_counterclockwise_with_positive_slope():
    """Physics sanity: dM/dH > 0 on both branches; the descending branch lies above the
    ascending one (the loop encloses positive area, the dissipated energy)."""
    mat = ir.Material(a=7012.0, k=4000.0, alpha=-0.01, Ms=7.65e5, c=0.18)
    time = np.linspace(0.0, 0.03, 1501)
    field = 1e5 * np.sin(2 * np.pi * 100 * time)
    M = ir.simulate_magnetization(time, field, mat)
    dH, dM = np.diff(field), np.diff(M)
    moving = np.abs(dH) > 1.0
    assert np.all(dM[moving] * dH[moving] > 0)
    last = slice(1000, 1501)  # the third cycle
    area = -np.sum(0.5 * (M[last][1:] + M[last][:-1]) * np.diff(field[last]))  # loop integral of M dH
    assert area > 0.05 * 1e5 * mat.Ms


def test_material_draws_are_numerically_safe():
    for seed in range(40):
        mat = ir.draw_material(ir._stream(seed, "material"))
        assert not mat.problems()
        He = np.linspace(-20 * mat.a, 20 * mat.a, 2001)
        man_slope = mat.Ms / mat.a / np.cosh(He / mat.a) ** 2
        assert np.all(1 - mat.alpha * mat.c * man_slope > 0.2)
        gap = np.linspace(0, 2 * mat.Ms, 101)                     # |Man - M| with dhat = 1
        assert np.all((1 - mat.c) * mat.k - mat.alpha * gap > 0)


# ---------------------------------------------------------------------------- mechanics numerics

def test_lumped_mechanics_static_gain_and_resonance():
    mech = ir.Mechanics(chat=ir.PAPER_CHAT, khat=ir.PAPER_KHAT, zetahat=ir.PAPER_ZETAHAT)
    dt = 1e-5
    t = np.arange(40000) * dt
    constant = ir.lumped_displacement(np.full(t.size, mech.zetahat * 3e5), dt, mech.chat, mech.khat)
    assert np.allclose(constant, mech.zetahat * 3e5 / mech.khat, rtol=1e-12)
    w = 2 * np.pi * 900.0
    x = ir.lumped_displacement(np.sin(w * t), dt, mech.chat, mech.khat)
    response = 1.0 / (mech.khat - w ** 2 + 1j * mech.chat * w)
    settled = slice(20000, 20000 + 18 * 1111)  # ~200 whole periods after the start transient
    expected = (response * np.exp(1j * w * t)).imag  # the steady state: Im(G(iw) e^{iwt})
    assert np.max(np.abs(x[settled] - expected[settled])) < 1e-4 * abs(response)


def test_mechanics_converge_and_the_two_schemes_agree():
    """The Delta-E integrator (RK4) with beta = 0 is the lumped model that the exact FOH
    filter solves; both are converged (halving their steps changes x by << the noise)."""
    base, time, field = short_field(1)  # a chirp at 12.8 kHz: the fastest content for its grid
    mech, mat = base.mechanics, base.material
    dt = time[1] - time[0]
    M = ir.simulate_magnetization(time, field, mat)
    foh = ir.lumped_displacement(mech.zetahat * M, dt, mech.chat, mech.khat)
    span = np.ptp(foh)
    finer = ir.lumped_displacement(mech.zetahat * M, dt, mech.chat, mech.khat, refine=2 * ir.LINEAR_REFINE)
    assert np.max(np.abs(finer - foh)) < 0.02 * MIN_NOISE * span
    rk4 = ir.delta_e_displacement(M, dt, mech, 0.0, mat.Ms)
    assert np.max(np.abs(rk4 - foh)) < 0.02 * MIN_NOISE * span
    with_e = ir.delta_e_displacement(M, dt, mech, 0.8, mat.Ms)
    halved = ir.delta_e_displacement(M, dt, mech, 0.8, mat.Ms, refine=4)
    assert np.max(np.abs(with_e - halved)) < 0.02 * MIN_NOISE * span
    assert np.max(np.abs(with_e - foh)) > 10 * MIN_NOISE * span  # and Delta-E does change x


# ---------------------------------------------------------------------------- determinism, format

def test_same_arguments_give_identical_arrays_and_seeds_differ():
    first, truth = ir.generate("eddy_current", 4, "both", n_samples=SHORT)
    again, truth_again = ir.generate("eddy_current", 4, "both", n_samples=SHORT)
    for name in ("time", "field", "magnetization", "displacement"):
        assert np.array_equal(getattr(first, name), getattr(again, name))
    assert truth == truth_again
    other, other_truth = ir.generate("eddy_current", 5, "both", n_samples=SHORT)
    assert not np.allclose(first.magnetization, other.magnetization)
    assert not np.isclose(truth["sample_rate"], other_truth["sample_rate"])


def test_effects_share_the_seed_draws_and_channel_sets_share_the_clean_arrays():
    none = ir.simulate("none", 4, "both", n_samples=SHORT)
    bias = ir.simulate("field_bias", 4, "both", n_samples=SHORT)
    assert np.array_equal(none.field, bias.field)            # the bias is not recorded
    assert np.array_equal(none.clean["magnetization"], bias.reference["magnetization"])
    for key in ("material", "mechanics", "conditions", "excitation_details"):
        assert none.truth[key] == bias.truth[key]
    only_m = ir.simulate("field_bias", 4, "magnetization", n_samples=SHORT)
    assert np.array_equal(only_m.clean["magnetization"], bias.clean["magnetization"])
    assert only_m.truth["effect_parameters"] == bias.truth["effect_parameters"]


@pytest.mark.parametrize("channels,columns", [("magnetization", ("magnetization",)),
                                              ("displacement", ("displacement",)),
                                              ("both", ("magnetization", "displacement"))])
def test_channel_sets_have_exactly_their_columns(channels, columns, tmp_path):
    from hyst_gym.diagnose.recording import read_recording, write_recording

    recording, truth = ir.generate("sensor_lag", 2, channels, n_samples=SHORT)
    assert recording.channels == columns
    assert recording.temperature is None
    path = write_recording(tmp_path / "r.csv", recording, recording.metadata)
    header = path.read_text().splitlines()[0].split(",")
    assert header == ["time", "field", *columns]
    back = read_recording(path)
    assert np.array_equal(back.field, recording.field)
    assert truth["channels"] == channels and set(truth["noise_std"]) == set(columns)


def test_displacement_only_effects_refuse_a_magnetization_recording():
    for effect in ("quadratic_magnetostriction", "rod_dynamics", "delta_e"):
        with pytest.raises(ValueError, match="displacement only"):
            ir.simulate(effect, 0, "magnetization")


@pytest.mark.parametrize("seed", [0, 3, 6])
def test_noise_is_white_gaussian_within_the_stated_range(seed):
    recording, truth = ir.generate("none", seed, "both", n_samples=4000)
    sim = ir.simulate("none", seed, "both", n_samples=4000)
    assert 1e-3 <= truth["noise_rel"] <= 1e-2
    for ch in ("magnetization", "displacement"):
        residual = getattr(recording, ch) - sim.clean[ch]
        relative = residual.std() / np.ptp(sim.clean[ch])
        assert relative == pytest.approx(truth["noise_rel"], rel=0.05)
        assert abs(np.corrcoef(residual[1:], residual[:-1])[0, 1]) < 0.06   # white
        assert abs(np.mean(residual ** 4) / residual.var() ** 2 - 3.0) < 0.3  # Gaussian kurtosis


def test_conditions_span_their_ranges():
    bases = [ir.draw_base(seed) for seed in range(60)]
    rates = [b.conditions.sample_rate for b in bases]
    sizes = [b.conditions.n_samples for b in bases]
    assert 10e3 <= min(rates) and max(rates) <= 60e3 and max(rates) - min(rates) > 35e3
    assert 5000 <= min(sizes) and max(sizes) <= 20000
    assert {b.conditions.family for b in bases} == set(ir.FAMILIES)
    rhos = [b.material.rho for b in bases]
    assert min(rhos) < -8 and max(rhos) > 0                     # paper-like and positive feedback


# ---------------------------------------------------------------------------- effects

VISIBLE_SEED = 0  # a seed whose draws show every effect at SHORT samples (checked below)


@pytest.mark.parametrize("effect", [e for e in ir.ALL_EFFECTS if e != "none"])
def test_every_effect_changes_the_clean_output_by_several_noise_units(effect):
    sim = ir.simulate(effect, VISIBLE_SEED, "both", n_samples=SHORT)
    noise_rel = sim.truth["noise_rel"]
    judged = ("displacement",) if ir.EFFECT_SPECS[effect].displacement_only else ("magnetization", "displacement")
    for ch in judged:
        diff = sim.clean[ch] - sim.reference[ch]
        sigma = noise_rel * np.ptp(sim.clean[ch])
        assert np.sqrt(np.mean((diff - diff.mean()) ** 2)) > 3.0 * sigma, (effect, ch)
    untouched = {"magnetization"} - set(judged)
    for ch in untouched:  # displacement-only effects leave M exactly as it was
        assert np.array_equal(sim.clean[ch], sim.reference[ch])
    assert sim.truth["visible"] and sim.truth["in_vocabulary"] == ir.EFFECT_SPECS[effect].in_vocabulary
    json.dumps(sim.truth)


def test_effects_act_the_way_their_physics_says():
    seed = VISIBLE_SEED
    base, time, field = short_field(seed)
    none = ir.simulate("none", seed, n_samples=SHORT)
    # field_bias: the same as recording the true field, H + H0
    bias = ir.simulate("field_bias", seed, n_samples=SHORT)
    H0 = bias.truth["effect_parameters"]["H0"]
    shifted = ir.simulate_magnetization(time, field + H0, base.material)[::ir.OVERSAMPLE]
    assert np.allclose(bias.clean["magnetization"], shifted, rtol=0, atol=1e-9 * base.material.Ms)
    # sensor_lag: each recorded output obeys tau*y' + y = (the clean one), to finite differences
    lag = ir.simulate("sensor_lag", seed, n_samples=SHORT)
    dt = 1 / none.truth["sample_rate"]
    for ch, tag in (("magnetization", "m"), ("displacement", "x")):
        tau = lag.truth["effect_parameters"][f"tau_{tag}_effective"]
        y, ref = lag.clean[ch], none.clean[ch]
        residual = tau * np.gradient(y, dt) + y - ref
        assert np.sqrt(np.mean(residual[5:-5] ** 2)) < 0.05 * np.sqrt(np.mean((y - ref) ** 2))
    # quadratic magnetostriction: the extra displacement is the mechanics' response to the
    # M^2 term kappa*zetahat*(M - M_b)^2/(2*M_b) (kappa = 1: the pure M^2 law about M_b)
    quad = ir.simulate("quadratic_magnetostriction", seed, n_samples=SHORT)
    kappa, M_b = quad.truth["effect_parameters"]["kappa"], quad.truth["effect_parameters"]["M_b"]
    assert 0.4 <= kappa <= 1.0
    M = ir.simulate_magnetization(time, field, base.material)
    mech = base.mechanics
    extra = ir.lumped_displacement(kappa * mech.zetahat * (M - M_b) ** 2 / (2 * M_b), time[1] - time[0],
                                   mech.chat, mech.khat)[::ir.OVERSAMPLE]
    change = quad.clean["displacement"] - none.clean["displacement"]
    assert np.max(np.abs(change - extra)) < 1e-9 * np.ptp(change)
    # thermal drift: the coil warms up, a grows with T, and the truth has no temperature column
    therm = ir.simulate("thermal_drift", seed, n_samples=SHORT)
    assert therm.truth["effect_parameters"]["temperature_rise_at_end"] > 5.0
    assert therm.truth["effect_parameters"]["a_at_end"] > base.material.a
    # amplifier saturation: the recorded field is the commanded one; the rod sees less
    sat = ir.simulate("amplifier_saturation", seed, n_samples=SHORT)
    assert np.array_equal(sat.field, none.field)
    assert sat.truth["effect_parameters"]["H_sat"] < np.max(np.abs(none.field))


def test_effect_lists_match_the_tools_vocabulary():
    """EFFECTS_IN_VOCABULARY (less "none") is the tool's EFFECTS (read from its source, so the
    fitter is not imported: the ``name`` of each ``Effect(...)`` entry of its registry), each by the name
    the tool gives it (TOOL_NAMES: a family of the tool can hold an effect of another name); when the tool
    learns an effect such as delta_e, flip its ``in_vocabulary`` flag in EFFECT_SPECS."""
    tree = ast.parse((ROOT / "hyst_gym" / "diagnose" / "effects.py").read_text())
    tool = [ast.literal_eval(keyword.value) for node in ast.walk(tree)
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "Effect"
            for keyword in node.keywords if keyword.arg == "name"]
    assert len(tool) >= 10 and len(set(tool)) == len(tool)
    assert {ir.TOOL_NAMES.get(e, e) for e in ir.EFFECTS_IN_VOCABULARY} - {"none"} == set(tool) - set(ir.NOT_CONCEALED)
    assert set(ir.TOOL_NAMES) <= set(ir.EFFECTS_IN_VOCABULARY)
    assert "none" in ir.EFFECTS_IN_VOCABULARY
    assert len(ir.EFFECTS_OUTSIDE) >= 1
    assert not set(ir.EFFECTS_OUTSIDE) & set(tool)


# ---------------------------------------------------------------------------- independence

FORBIDDEN = ("hyst_gym.physics", "hyst_gym.estimation", "hyst_gym.diagnose.kernels", "hyst_gym.diagnose.model",
             "hyst_gym.diagnose.fit", "hyst_gym.diagnose.make_recording",
             "hyst_gym.diagnose.effects", "hyst_gym.diagnose.hypothesize", "hyst_gym.diagnose.pipeline")


def test_module_imports_only_numpy_scipy_stdlib_and_the_recording_format():
    tree = ast.parse(MODULE.read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, "no relative imports"
            imported.add(node.module)
    third_party = {name for name in imported if name.split(".")[0] not in sys.stdlib_module_names}
    assert {name.split(".")[0] for name in third_party} <= {"numpy", "scipy", "hyst_gym"}
    assert {name for name in third_party if name.startswith("hyst_gym")} == {"hyst_gym.diagnose.recording"}
    assert not any(name.startswith(FORBIDDEN) for name in imported)


def test_simulation_runs_without_loading_hyst_gym():
    code = ("import sys; from experiments import independent_recordings as ir; "
            "ir.simulate('eddy_current', 1, 'both', n_samples=400); "
            "print(sorted(m for m in sys.modules if m.startswith('hyst_gym')))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                         check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_generate_calls_no_hyst_gym_code_but_the_recording_dataclass():
    import hyst_gym.diagnose.recording as recording_module  # loads the package before tracing

    allowed = pathlib.Path(recording_module.__file__).resolve()
    package = allowed.parents[1]
    called = set()

    def profile(frame, event, arg):
        if event == "call":
            path = pathlib.Path(frame.f_code.co_filename)
            if package in path.parents and path.resolve() != allowed:
                called.add(f"{path.name}:{frame.f_code.co_name}")

    sys.setprofile(profile)
    try:
        ir.generate("two_phase_rod", 2, "both", n_samples=400)
    finally:
        sys.setprofile(None)
    assert not called


# ---------------------------------------------------------------------------- command line

def test_cli_writes_csv_sidecar_and_separate_truth(tmp_path):
    out, truth_path = tmp_path / "rec.csv", tmp_path / "truth.json"
    assert ir.main(["--effect", "rod_dynamics", "--seed", "3", "--channels", "displacement", "--samples", "800",
                    "--out", str(out), "--truth", str(truth_path)]) == 0
    assert out.read_text().splitlines()[0] == "time,field,displacement"
    sidecar = (tmp_path / "rec.json").read_text().lower()
    effect_words = {word for effect in ir.ALL_EFFECTS for word in effect.split("_") if len(word) > 2}
    assert effect_words and not [word for word in effect_words | {"mode", "effect", "truth"} if word in sidecar]
    truth = json.loads(truth_path.read_text())
    assert truth["effect"] == "rod_dynamics" and truth["in_vocabulary"] is True
    assert {"f2", "zeta2", "g2"} <= set(truth["effect_parameters"])
    assert truth["excitation_family"] in ir.FAMILIES and truth["n_samples"] == 800


@pytest.mark.parametrize("args", [
    ["--effect", "nonsense", "--seed", "1", "--out", "x.csv"],
    ["--effect", "none", "--seed", "-3", "--out", "x.csv"],
    ["--effect", "none", "--seed", "one", "--out", "x.csv"],
    ["--effect", "none", "--seed", "1", "--channels", "voltage", "--out", "x.csv"],
    ["--effect", "none", "--seed", "1", "--samples", "10", "--out", "x.csv"],
    ["--effect", "none", "--seed", "1", "--out", "x.txt"],
    ["--effect", "rod_dynamics", "--seed", "1", "--channels", "magnetization", "--out", "x.csv"],
    ["--seed", "1", "--out", "x.csv"],
])
def test_cli_rejects_bad_arguments_with_exit_2(args, tmp_path, capsys):
    with pytest.raises(SystemExit) as raised:
        ir.main([a if a != "x.csv" else str(tmp_path / "x.csv") for a in args])
    assert raised.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert error[-1].startswith("python -m experiments.independent_recordings: error: ")
    assert not (tmp_path / "x.csv").exists()


def test_cli_unwritable_output_is_a_one_line_error(tmp_path, capsys):
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a folder")
    with pytest.raises(SystemExit) as raised:
        ir.main(["--effect", "none", "--seed", "1", "--samples", "400", "--out", str(blocker / "x.csv")])
    assert raised.value.code == 2
    assert "error: cannot write" in capsys.readouterr().err.strip().splitlines()[-1]


def test_cli_entry_point_exit_status():
    out = subprocess.run([sys.executable, "-m", "experiments.independent_recordings", "--effect", "bogus",
                          "--seed", "1", "--out", "x.csv"], cwd=ROOT, capture_output=True, text=True, timeout=60,
                         check=False)
    assert out.returncode == 2 and "invalid choice: 'bogus'" in out.stderr.splitlines()[-1]


# ---------------------------------------------------------------------------- replay (all three generators)

REPLAY_SAMPLES = 800


def _replayers():
    """Per generator: (first record and truth, replay(drive, noise_seed) -> (recording, truth)) of one hidden system
    with an effect whose frame a drive could move (a sensor map, the heating, a drift)."""
    from experiments import diagnose_next_drive as study
    from experiments import other_forms as of

    def own(effect="sensor_map", seed=2):
        first = study.replay(effect, seed, "magnetization", REPLAY_SAMPLES)
        return (first, None), lambda drive, noise_seed: (
            study.replay(effect, seed, "magnetization", REPLAY_SAMPLES, drive, noise_seed=noise_seed), None)

    def independent(effect="thermal_drift", seed=3):
        return (ir.generate(effect, seed, "both", n_samples=REPLAY_SAMPLES),
                lambda drive, noise_seed: ir.replay(effect, seed, "both", drive, noise_seed=noise_seed,
                                                    n_samples=REPLAY_SAMPLES))

    def other_forms(case="sensor_nonlinearity", seed=4):
        return (of.generate(case, seed, "both", n_samples=REPLAY_SAMPLES),
                lambda drive, noise_seed: of.replay(case, seed, "both", drive, noise_seed=noise_seed,
                                                    n_samples=REPLAY_SAMPLES))

    return {"own": own, "independent": independent, "other_forms": other_forms}


@pytest.mark.parametrize("generator", ["own", "independent", "other_forms"])
def test_replay_keeps_the_hidden_system_and_start_state_and_draws_new_noise(generator):
    (first, truth), replay = _replayers()[generator]()
    n = first.size
    # a different drive: the first half the same, then the first drive reversed in time (other rates, reversals)
    other = first.field.copy()
    other[n // 2:] = first.field[::-1][n // 2:] * 0.8
    same_noise_a, info_a = replay(other, 5)
    same_noise_b, info_b = replay(first.field, 5)
    if truth is not None:  # the same hidden parameters and conditions as the first record
        for key in ("effect_parameters", "material", "mechanics", "noise_std", "sample_rate"):
            assert info_a[key] == truth[key] == info_b[key]
        assert info_a["replay"] == {"noise_seed": 5, "own_drive": False}
    np.testing.assert_array_equal(same_noise_a.field, other)
    for ch in first.channels:
        a, b, y = same_noise_a.output(ch), same_noise_b.output(ch), first.output(ch)
        sigma = (truth["noise_std"][ch] if truth else float(np.std(b - y)) / np.sqrt(2.0))
        # same start state: with the same noise draw, the two drives give the same record until they part
        # (up to the cubic spline's reach of a few samples where the generator holds the drive by one)
        early = slice(0, n // 2 - 20)
        assert np.max(np.abs(a[early] - b[early])) < 0.05 * sigma
        # ... and a different one after (the drive matters)
        assert np.sqrt(np.mean((a[n // 2 + 20:] - b[n // 2 + 20:]) ** 2)) > 3 * sigma
        # under the first drive the replay differs from the first record by noise only: the difference is
        # white with the variance of two independent draws, no trend, no structure
        difference = b - y
        assert np.std(difference) == pytest.approx(np.sqrt(2.0) * sigma, rel=0.12)
        assert abs(np.mean(difference)) < 4 * np.sqrt(2.0) * sigma / np.sqrt(n)
        lag1 = np.corrcoef(difference[1:], difference[:-1])[0, 1]
        assert abs(lag1) < 4 / np.sqrt(n)
        # a third noise seed gives another draw again
        c = replay(first.field, 6)[0].output(ch)
        assert np.std(c - b) == pytest.approx(np.sqrt(2.0) * sigma, rel=0.12)


@pytest.mark.parametrize("generator", ["independent", "other_forms"])
def test_replay_under_its_own_drive_is_the_first_record_up_to_noise(generator):
    (first, truth), replay = _replayers()[generator]()
    own, info = replay(None, 1)
    resampled, _ = replay(first.field, 1)
    for ch in first.channels:
        clean_gap = resampled.output(ch) - own.output(ch)  # the same noise draw: the clean difference alone
        # other forms hold the drive linearly (bit for bit); the independent generator refits its cubic spline
        # to the samples in place of the coil-filtered fine grid: far below the noise
        assert np.sqrt(np.mean(clean_gap ** 2)) < 0.02 * truth["noise_std"][ch]
    assert info["replay"]["own_drive"] is True


def test_replay_refuses_a_bad_drive_or_noise_seed():
    from experiments import other_forms as of

    with pytest.raises(ValueError, match="drive must be a 1-D array of 800 samples"):
        ir.replay("none", 1, "both", np.zeros(10), noise_seed=1, n_samples=REPLAY_SAMPLES)
    with pytest.raises(ValueError, match="drive must be finite"):
        of.replay("none_other_numerics", 1, "both", np.full(REPLAY_SAMPLES, np.nan), noise_seed=1,
                  n_samples=REPLAY_SAMPLES)
    with pytest.raises(ValueError, match="noise_seed must be an integer >= 0"):
        ir.replay("none", 1, "both", None, noise_seed=-1, n_samples=REPLAY_SAMPLES)
