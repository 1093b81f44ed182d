"""Temperature-law fit of experiments/gd_temperature.py: synthetic round trip and CLI errors."""

import numpy as np
import pytest

from experiments import gd_temperature as gd
from hyst_gym.physics.hysteresis import simulate_magnetization
from hyst_gym.physics.temperature_laws import celsius_to_kelvin

MU0 = 4e-7 * np.pi
TRUE = {"a0": 3000.0, "n_a": -0.5, "k0": 60.0, "n_k": -2.0, "c": 0.4, "Ms0": 2.2e6, "beta": 0.32}


def synthetic_record(T_C, amplitude, peak, n=600):
    """0 -> +peak -> -peak -> +peak with a little sampling noise, B from the true laws."""
    s = np.linspace(0.0, 1.25, n)
    H = peak * np.sin(2 * np.pi * s)
    H = H + np.random.default_rng(int(T_C) + 100).normal(0.0, 2e-3 * peak, n)  # noise, as in the data
    values = gd.FAMILIES["critical"].build(TRUE)(celsius_to_kelvin(T_C))
    clean = gd.clean_record(H, np.zeros(n), T_C, amplitude, stride=1)  # the field the model sees
    M = simulate_magnetization(clean.field, a=float(values["a"]), k=float(values["k"]), alpha=0.0,
                               Ms=float(values["Ms"]), c=float(values["c"]), anhysteretic=gd.ANHYSTERETIC,
                               max_field_step=clean.max_field_step)
    B = MU0 * (clean.field + M)
    return gd.Record(float(T_C), amplitude, clean.field, B, clean.loop_start, 0.0, clean.peak_field,
                     clean.max_field_step)


@pytest.fixture(scope="module")
def synthetic():
    temps = (-30.0, -15.0, -5.0, 10.0)
    return [synthetic_record(T, amp, peak) for T in temps for amp, peak in (("major", 5.5e4), ("mid", 1e4))]


def test_clean_record_is_monotone_between_reversals_and_keeps_them():
    rng = np.random.default_rng(0)
    n = 2000
    H = 400 * np.sin(2 * np.pi * np.linspace(0, 1.25, n)) + rng.normal(0, 8, n)
    rec = gd.clean_record(H, np.linspace(0, 1, n), -10.0, "minor", stride=7)
    i_max, i_min = gd.reversal_indices(H)
    d = np.diff(rec.field)
    j_max, j_min = rec.loop_start, int(np.argmin(rec.field))
    assert np.all(d[:j_max] >= 0) and np.all(d[j_max:j_min] <= 0) and np.all(d[j_min:] >= 0)
    # the reversal samples are kept, with their measured B
    assert rec.B[j_max] == pytest.approx(np.linspace(0, 1, n)[i_max])
    assert rec.B[j_min] == pytest.approx(np.linspace(0, 1, n)[i_min])
    assert rec.field.size < n / 6
    assert gd.tag_for(-38) == "m38C" and gd.tag_for(5) == "p05C" and gd.tag_for(0) == "p00C"


def test_round_trip_recovers_laws_and_predicts_held_out_temperature(synthetic):
    family = gd.FAMILIES["critical"]
    train = [r for r in synthetic if r.temperature_C != -5.0]
    test = [r for r in synthetic if r.temperature_C == -5.0]
    start = {"a0": 4500.0, "n_a": 0.0, "k0": 150.0, "n_k": -1.0, "c": 0.25, "Ms0": 1.8e6, "beta": 0.4}
    fit = gd.fit_family(train, family, x0=[start[n] for n in family.names], max_nfev=150)
    # the starting point is visibly wrong ...
    start_rows = gd.score(test, family, gd.FitResult("critical", start, (), 0, 0, 0, True), "predicted")
    assert max(r["nrmse"] for r in start_rows) > 0.05
    # ... the fit recovers the true laws ...
    for name in ("a0", "k0", "c", "Ms0"):
        assert fit.params[name] == pytest.approx(TRUE[name], rel=0.05), name
    for name in ("n_a", "n_k", "beta"):
        assert fit.params[name] == pytest.approx(TRUE[name], abs=0.05), name
    # ... and predicts the held-out temperature
    rows = gd.score(test, family, fit, "predicted")
    assert len(rows) == 2 and all(r["role"] == "predicted" for r in rows)
    assert max(r["nrmse"] for r in rows) < 0.005


def test_eq4_cannot_follow_the_critical_drop_of_ms(synthetic):
    """The paper's law (constant Ms) misses loops whose Ms follows the critical law."""
    fit = gd.fit_family(synthetic, gd.FAMILIES["eq4"], max_nfev=60)
    rows = gd.score(synthetic, gd.FAMILIES["eq4"], fit, "fitted")
    assert max(r["nrmse"] for r in rows if r["amplitude"] == "major") > 0.03


def test_cli_rejects_missing_and_bad_files(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        gd.main(["--data", str(tmp_path / "missing.npz"), "--no-artifacts"])
    assert exc.value.code == 2
    assert "no such file" in capsys.readouterr().err
    bad = tmp_path / "bad.npz"
    bad.write_text("not an npz")
    with pytest.raises(SystemExit) as exc:
        gd.main(["--data", str(bad), "--no-artifacts"])
    assert exc.value.code == 2
    keys = tmp_path / "keys.npz"
    np.savez(keys, temperatures_C=np.array([-10.0, 0.0, 5.0]))
    with pytest.raises(SystemExit) as exc:
        gd.main(["--data", str(keys), "--no-artifacts"])
    assert exc.value.code == 2
    assert "m10C_major" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        gd.main(["--predict", str(tmp_path / "missing.npz"), "--no-artifacts"])
    assert exc.value.code == 2


def test_cli_runs_on_a_small_file_and_writes_rows(synthetic, tmp_path):
    payload = {"temperatures_C": np.array([-30.0, -15.0, -5.0])}
    for T in (-30.0, -15.0, -5.0):
        for amp, peak in (("major", 5.5e4), ("mid", 1e4), ("minor", 400.0)):
            n = 400
            H = peak * np.sin(2 * np.pi * np.linspace(0, 1.25, n))
            rec = synthetic_record(T, amp, peak, n)
            payload[f"{gd.tag_for(T)}_{amp}_H"] = H
            payload[f"{gd.tag_for(T)}_{amp}_B"] = np.interp(np.arange(n), np.arange(n), rec.B)
    data = tmp_path / "small.npz"
    np.savez(data, **payload)
    out = tmp_path / "rows.json"
    other = tmp_path / "other.npz"
    np.savez(other, temperatures_C=np.array([10.0]),
             **{f"p10C_{amp}_{q}": payload[f"m15C_{amp}_{q}"] for amp in gd.AMPLITUDES for q in "HB"})
    assert gd.main(["--data", str(data), "--predict", str(other), "--json", str(out), "--quick",
                    "--no-artifacts"]) == 0
    import json

    rows = json.loads(out.read_text())
    assert {r["role"] for r in rows} == {"fitted", "predicted"}
    from_file = [r for r in rows if r["protocol"] == "predict_file"]
    assert {r["temperature_C"] for r in from_file} == {10.0} and len(from_file) == 3 * 2  # two laws in --quick
    rows = [r for r in rows if r["protocol"] != "predict_file"]
    assert {r["amplitude"] for r in rows} == {"major", "mid", "minor"}
    predicted = [r for r in rows if r["role"] == "predicted"]
    assert {r["temperature_C"] for r in predicted} == {-15.0}
    assert all(set(r) >= {"temperature_C", "amplitude", "peak_field", "nrmse", "role"} for r in rows)


def test_start_state_is_not_one_noisy_sample():
    """The model starts from the line fitted to the foot of the initial curve, not from the first
    sample: a spike there would act as a remanent state carried through a small loop."""
    rng = np.random.default_rng(3)
    n = 2000
    H = 400 * np.sin(2 * np.pi * np.linspace(0, 1.25, n)) + rng.normal(0, 8, n)
    M = 50.0 * H + 1500.0 + rng.normal(0, 300, n)  # remanent 1500 A/m, linear foot
    B = MU0 * (H + M)
    B[0] += 0.02  # a 20 mT spike on the first sample
    rec = gd.clean_record(H, B, -10.0, "minor", stride=4)
    assert rec.M0 == pytest.approx(1500.0 + 50.0 * rec.field[0], abs=150.0)


def test_reversal_pinning_families_build_rayleigh_field_from_k():
    family = gd.FAMILIES["smooth_pinning"]
    z = family.to_z(family.x0)[None, :]
    T = celsius_to_kelvin(np.array([-20.0, 0.0]))
    table = gd.parameter_table(family, z, T)
    np.testing.assert_array_equal(table["rayleigh_field"], table["k"])
    assert not np.any(gd.parameter_table(gd.FAMILIES["smooth"], z, T)["rayleigh_field"])


def test_held_out_temperature_of_the_shipped_data_is_predicted_within_the_targets():
    """Leave -10 C out of the shipped gadolinium set, fit the domain-wall law (smooth laws with the
    reversal-dependent pinning) on the seven others at all amplitudes and predict -10 C: major
    within 2 %, mid and minor within 8 % (the issue's targets; coarse subsampling to keep it short)."""
    records = gd.load_records(gd.DEFAULT_DATA, stride=16)
    family = gd.FAMILIES["smooth_pinning"]
    fit = gd.fit_family([r for r in records if r.temperature_C != -10.0], family, max_nfev=60)
    rows = {r["amplitude"]: r["nrmse"] for r in gd.score([r for r in records if r.temperature_C == -10.0],
                                                         family, fit, "predicted")}
    assert rows["major"] < 0.02 and rows["mid"] < 0.08 and rows["minor"] < 0.08, rows


def test_bad_input_is_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        gd.main(["--data", str(tmp_path / "missing.npz"), "--no-artifacts"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1 and "no such file" in err


def _study(values):
    """A study of leave-one-out rows: ``values[law][T]`` the NRMSE at every amplitude; -40 and +20 C fitted."""
    temps = sorted({T for v in values.values() for T in v} | {-40.0, 20.0})
    rows = [{"law": law, "temperature_C": T, "amplitude": amp, "peak_field": 1.0, "nrmse": 0.01, "protocol": "all"}
            for law in values for T in temps for amp in gd.AMPLITUDES]
    rows += [{"law": law, "temperature_C": T, "amplitude": amp, "peak_field": 1.0, "nrmse": v, "protocol": "loo"}
             for law, by_T in values.items() for T, v in by_T.items() for amp in gd.AMPLITUDES]
    return {"rows": rows, "fits": []}


def test_rule_reads_the_interior_temperatures_only():
    # "smooth" interpolates better, "eq4" extrapolates to the warmest temperature better: the interior decides
    study = _study({"smooth": {-20.0: 0.02, 5.0: 0.03, 20.0: 0.5}, "eq4": {-20.0: 0.04, 5.0: 0.05, 20.0: 0.01}})
    assert gd.loo_temperatures(study) == ([-20.0, 5.0], 20.0)
    scores = gd.selection_scores(study, ["smooth", "eq4"])
    assert scores == {"smooth": pytest.approx(0.025), "eq4": pytest.approx(0.045)}
    assert "(the selection rule): **smooth laws for a and k" in gd.summary_table(study, ["smooth", "eq4"])


def test_near_tc_words_name_the_amplitude_no_law_predicts():
    study = _study({"smooth": {-20.0: 0.02, 5.0: 0.03}, "eq4": {-20.0: 0.04, 5.0: 0.05}})
    for row in study["rows"]:
        if row["temperature_C"] == 5.0 and row["amplitude"] == "minor" and row["protocol"] == "loo":
            row["nrmse"] = 0.12 if row["law"] == "smooth" else 0.10
    words = gd.near_tc_words(study, ["smooth", "eq4"])
    assert len(words) == 1 and words[0].startswith("- +5 °C")
    assert "minor: **no law within 8 %** (best eq4, 10.0 %)" in words[0]
    assert "major: 2 of 2 laws within 8 % (best smooth, 3.0 %)" in words[0]


def test_protocol_check_flags_a_short_record_and_a_remanent_start(tmp_path):
    payload = {"temperatures_C": np.array([-30.0, -15.0, -5.0, 10.0])}
    for T in payload["temperatures_C"]:
        for amp, peak in (("major", 5.5e4), ("mid", 1e4), ("minor", 400.0)):
            n = 300 if T == 10.0 else 600  # the warmest: half the samples per drive period
            H = peak * np.sin(2 * np.pi * np.linspace(0, 1.25, n))
            B = synthetic_record(T, amp, peak, n).B
            if T == -15.0 and amp == "minor":  # a remanent start: offset on the whole record
                B = B - 0.3 * np.ptp(B) / 2
            payload[f"{gd.tag_for(T)}_{amp}_H"] = H
            payload[f"{gd.tag_for(T)}_{amp}_B"] = B
    np.savez(tmp_path / "p.npz", **payload)
    rows = gd.record_protocol(tmp_path / "p.npz")
    assert len(rows) == 12 and all(r["sine_deviation"] < 0.01 for r in rows if r["amplitude"] == "major")
    # 299 sample steps over 1.25 periods: 239.2 samples per period (the reversals fall on whole samples)
    assert all(abs(r["samples_per_period"] - 239.2) <= 2 for r in rows if r["temperature_C"] == 10.0)
    notes = gd.protocol_differences(rows)
    assert sum("+10 °C" in n and "300 samples" in n for n in notes) == 3
    assert any(n.startswith("-15 °C minor: start_share") for n in notes)
    assert not any(n.startswith("-30 °C") or n.startswith("-5 °C") for n in notes)


def test_sampling_check_compares_the_records_of_the_common_length(tmp_path):
    payload = {"temperatures_C": np.array([-30.0, -15.0, 10.0])}
    for T in payload["temperatures_C"]:
        for amp, peak in (("major", 5.5e4), ("mid", 1e4), ("minor", 400.0)):
            n = 400 if T == 10.0 else 800
            payload[f"{gd.tag_for(T)}_{amp}_H"] = peak * np.sin(2 * np.pi * np.linspace(0, 1.25, n))
            payload[f"{gd.tag_for(T)}_{amp}_B"] = synthetic_record(T, amp, peak, n).B
    np.savez(tmp_path / "p.npz", **payload)
    family = gd.FAMILIES["critical"]
    study = {"protocol": gd.record_protocol(tmp_path / "p.npz"),
             "fits": [{"family": "critical", "protocol": "all", "params": dict(zip(family.names, [
                 TRUE[n] for n in family.names]))}]}
    change = gd.sampling_check(study, tmp_path / "p.npz", 2, "critical")
    assert set(change) == set(gd.AMPLITUDES)
    # the true law on its own (noise-free B) records: half the samples move the score by a small amount only
    assert all(0.0 <= v < 0.005 for v in change.values()), change


def test_page_section_and_results_tables_are_the_stored_study(capsys):
    """The gd-summary section of docs/results/real-loops.md and results.md are what the script writes from the
    committed results.json (a study rerun without rewriting them, or a hand edit inside the markers, fails)."""
    import json

    from tests.test_docs_sections import section

    stored = gd.RESULTS_DIR / "results.json"
    study = json.loads(stored.read_text())
    families = [f for f in gd.MODEL_FAMILIES["auto"] if any(r["law"] == f for r in study["rows"])]
    assert section(gd.PAGE, "gd-summary") == gd.page_section(study, families).strip(), \
        "rerun: python -m experiments.gd_temperature --from-results " \
        "experiments/results/gd_temperature/results.json --page"
    assert (gd.RESULTS_DIR / "results.md").read_text() == (gd.markdown_table(study, families) + "\n"
                                                          + gd.summary_table(study, families) + "\n")
    # the page names every record that differs, which the full table in results.md lists
    for difference in gd.protocol_differences(study["protocol"]):
        assert difference in section(gd.PAGE, "gd-summary")
    with pytest.raises(SystemExit) as exit_info:
        gd.main(["--page"])
    assert exit_info.value.code == 2 and "--from-results" in capsys.readouterr().err


def test_fit_takes_the_steps_of_separate_residual_and_jacobian_calls(synthetic):
    """A domain-wall fit simulates each trial point with its forward-difference neighbours in one bank.
    Every model of a bank runs on its own, so the point's column equals the point simulated alone, bit
    for bit, and the fit ends where the former separate calls ended."""
    family = gd.FAMILIES["smooth_small_loop"]
    z = family.to_z(family.x0)
    bank = np.repeat(z[None, :], 4, axis=0)
    bank[1:, :3] += 1e-4 * np.eye(3)
    together = gd.simulate_records(synthetic, family, bank)
    alone = gd.simulate_records(synthetic, family, z[None, :])
    assert all(np.array_equal(t[:, 0], a[:, 0]) for t, a in zip(together, alone))

    from scipy.optimize import least_squares
    from threadpoolctl import threadpool_limits

    records = synthetic[:4]
    lo, hi = family.bounds_z()
    z0 = np.clip(z, lo + 1e-9, hi - 1e-9)

    def fun(x):
        return gd._scaled_residuals(records, gd.simulate_records(records, family, x[None, :]))[:, 0]

    def jac(x):
        xs = np.repeat(x[None, :], x.size + 1, axis=0)
        steps = np.where(xs[0] + gd.FD_STEP <= hi, gd.FD_STEP, -gd.FD_STEP)
        xs[1:] += np.diag(steps)
        R = gd._scaled_residuals(records, gd.simulate_records(records, family, xs))
        return (R[:, 1:] - R[:, :1]) / steps

    with threadpool_limits(limits=1, user_api="blas"):
        separate = least_squares(fun, z0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=12,
                                 xtol=1e-8, ftol=1e-8)
    fit = gd.fit_family(records, family, max_nfev=12)
    assert fit.params == family.from_z(separate.x) and fit.nfev == separate.nfev
