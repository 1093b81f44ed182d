"""No numeric failure on a valid recording, and one-line errors for what the tool cannot use."""

import codecs
import subprocess
import sys
import time

import numpy as np
import pytest

from hyst_gym.cli import main as cli_main
from hyst_gym.diagnose import Recording, diagnose, make_recording, read_recording, write_recording
from hyst_gym.diagnose.fit import NONFINITE_RESIDUAL, RESIDUAL_CAP, Objective, local_fit
from hyst_gym.diagnose.model import Model, Structure, base_parameters


@pytest.fixture(scope="module")
def short():
    return make_recording("none", 2, output="both", n_samples=600)[0]


@pytest.fixture()
def csv_text(tmp_path, short):
    path = write_recording(tmp_path / "r.csv", short)
    return path.read_text(encoding="utf-8")


# ---------------------------------------------------------------------------- reading


def test_a_utf8_byte_order_mark_is_skipped_and_said(tmp_path, csv_text, short):
    path = tmp_path / "bom.csv"
    path.write_bytes(codecs.BOM_UTF8 + csv_text.encode("utf-8"))
    read = read_recording(path)
    np.testing.assert_array_equal(read.magnetization, short.magnetization)
    assert "byte-order mark" in " ".join(read.metadata["read_notes"])


@pytest.mark.parametrize("delimiter", [";", "\t"])
def test_a_semicolon_or_tab_delimiter_is_read_and_said(tmp_path, csv_text, short, delimiter):
    path = tmp_path / "other.csv"
    path.write_text(csv_text.replace(",", delimiter), encoding="utf-8")
    read = read_recording(path)
    np.testing.assert_array_equal(read.field, short.field)
    np.testing.assert_array_equal(read.displacement, short.displacement)
    assert "not a comma" in read.metadata["read_notes"][0]


def test_the_report_says_what_the_reader_accepted(tmp_path, csv_text):
    path = tmp_path / "semicolons.csv"
    path.write_bytes(codecs.BOM_UTF8 + csv_text.replace(",", ";").encode("utf-8"))
    report = diagnose(path, effects=["field_bias"], progress=False, workers=1)
    notes = " ".join(report.notes)
    assert "byte-order mark" in notes and "';', not a comma" in notes
    plain = diagnose(write_recording(tmp_path / "plain.csv", read_recording(path)), effects=["field_bias"],
                     progress=False, workers=1)
    assert "not a comma" not in " ".join(plain.notes)


def test_a_decimal_comma_gets_a_hint(tmp_path):
    path = tmp_path / "comma.csv"
    path.write_text("time;field;magnetization\n0,0;1,5;2,5\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"row 2, column 'time': '0,0' is not a number \(a decimal comma"):
        read_recording(path)


def test_utf16_is_named(tmp_path, csv_text):
    path = tmp_path / "utf16.csv"
    path.write_bytes(csv_text.encode("utf-16"))
    with pytest.raises(ValueError, match="UTF-16 text .* save it as UTF-8"):
        read_recording(path)


def test_a_huge_file_of_nul_bytes_is_rejected_without_reading_it(tmp_path):
    path = tmp_path / "zeros.csv"
    subprocess.run(["truncate", "-s", "1G", str(path)], check=True)  # sparse: no disk, NUL bytes when read
    started = time.perf_counter()
    with pytest.raises(ValueError, match="contains NUL bytes; not a text CSV file"):
        read_recording(path)
    assert time.perf_counter() - started < 2.0  # reading 1 GB would take far longer


# ---------------------------------------------------------------------------- values the fit cannot use


@pytest.mark.parametrize("scale, column, words", [(1e300, "field", "reaches .* A/m, beyond 1e\\+30"),
                                                  (1e-300, "field", "spans only"),
                                                  (0.0, "field", "is constant")])
def test_values_near_the_float_limits_or_all_zero_end_in_one_line(short, scale, column, words):
    scaled = Recording(time=short.time, field=short.field * scale,
                       **{c: short.output(c) * scale for c in short.channels})
    with pytest.raises(ValueError, match=f"column '{column}' {words}") as error:
        diagnose(scaled, progress=False)
    assert "\n" not in str(error.value)


def test_a_constant_output_channel_is_named(short):
    flat = Recording(time=short.time, field=short.field, magnetization=short.magnetization,
                     displacement=np.zeros(short.size))
    with pytest.raises(ValueError, match="column 'displacement' is constant"):
        diagnose(flat, progress=False)


def test_residuals_and_jacobians_are_capped_and_non_finite_ones_penalized(short, monkeypatch):
    structure = Structure("lumped")
    model = Model(short, structure, base_parameters(short, structure), 200.0)
    objective = Objective(model, {"magnetization": 1.0, "displacement": 1.0}, np.ones(short.size, bool))
    monkeypatch.setattr(objective, "residuals_many",
                        lambda values_list, mask=None: [np.array([1e200, np.nan, -np.inf, 2.0])] * len(values_list))
    np.testing.assert_array_equal(objective(model.x_from_values(model.values())),
                                  [RESIDUAL_CAP, NONFINITE_RESIDUAL, -NONFINITE_RESIDUAL, 2.0])
    J = objective.jacobian(model.x_from_values(model.values()))
    assert np.all(np.isfinite(J)) and np.max(np.abs(J)) <= RESIDUAL_CAP


def test_a_fit_the_solver_gives_up_on_is_a_failure_with_its_reason(short, monkeypatch):
    import scipy.optimize

    structure = Structure("lumped")
    model = Model(short, structure, base_parameters(short, structure), 200.0)

    def broken(*args, **kwargs):
        raise ValueError("array must not contain infs or NaNs")

    monkeypatch.setattr(scipy.optimize, "least_squares", broken)
    fit = local_fit(model, {"magnetization": 1.0, "displacement": 1.0}, np.ones(short.size, bool))
    assert fit.sse == float("inf")
    assert "array must not contain infs or NaNs" in fit.failure


def test_a_failed_candidate_is_left_out_with_the_reason_in_the_report(short, monkeypatch):
    from hyst_gym.diagnose import pipeline
    from hyst_gym.diagnose.fit import FitResult

    real = pipeline.fit_candidate

    def failing(split, base, name):
        fit = real(split, base, name)
        if name != "eddy_current":
            return fit
        return FitResult(fit.model, fit.values, {}, float("inf"), fit.n_residuals, fit.n_free, 0,
                         failure="the least-squares solver stopped: test")

    monkeypatch.setattr(pipeline, "fit_candidate", failing)
    report = diagnose(short, progress=False, effects=["eddy_current", "field_bias"])
    failed = next(c for c in report.candidates if c.effect == "eddy_current")
    assert failed.heldout_rmse == float("inf") and not failed.accepted
    assert any("eddy_current could not be fitted and was left out" in note for note in report.notes)
    assert report.to_json()["candidates"][0]["failed"] == "the least-squares solver stopped: test"
    assert report.verdict != "eddy_current"


def test_a_failed_base_fit_is_a_one_line_error(short, monkeypatch):
    from hyst_gym.diagnose import pipeline

    real = pipeline.calibrate

    def failing(split, structure, **kwargs):
        fit = real(split, structure, n_points=8, keep=1)
        fit.failure = "the least-squares solver stopped: test"
        return fit

    monkeypatch.setattr(pipeline, "calibrate", failing)
    with pytest.raises(ValueError, match="the base model could not be fitted to this recording .*: test") as error:
        diagnose(short, progress=False)
    assert "\n" not in str(error.value)


# ---------------------------------------------------------------------------- the commands


def _cli(argv, capsys):
    status = cli_main(argv)
    return status, capsys.readouterr()


def test_json_into_a_missing_folder_fails_before_running_and_makes_no_folder(tmp_path, short, capsys, monkeypatch):
    from hyst_gym.diagnose import command

    monkeypatch.setattr(command, "diagnose", lambda *a, **k: pytest.fail("the diagnosis ran"))
    path = write_recording(tmp_path / "r.csv", short)
    target = tmp_path / "missing" / "deeper" / "r.json"
    status, out = _cli(["diagnose", str(path), "--json", str(target), "--quiet"], capsys)
    assert status == 2 and "folder" in out.err and "does not exist" in out.err
    assert len(out.err.strip().splitlines()) == 1
    assert not (tmp_path / "missing").exists()


def test_plots_at_an_existing_file_fails_before_running(tmp_path, short, capsys, monkeypatch):
    from hyst_gym.diagnose import command

    monkeypatch.setattr(command, "diagnose", lambda *a, **k: pytest.fail("the diagnosis ran"))
    path = write_recording(tmp_path / "r.csv", short)
    (tmp_path / "plots").write_text("not a folder")
    status, out = _cli(["diagnose", str(path), "--plots", str(tmp_path / "plots"), "--quiet"], capsys)
    assert status == 2 and "is a file, not a folder" in out.err


def test_make_recording_in_python_names_arguments_not_flags():
    with pytest.raises(ValueError) as error:
        make_recording("bogus")
    assert "--" not in str(error.value) and "effect must be one of" in str(error.value)
    with pytest.raises(ValueError, match="^n_samples must be an integer >= 400"):
        make_recording("none", n_samples=10)


def test_make_recording_cli_names_its_flags(tmp_path, capsys):
    status, out = _cli(["make-recording", "--effect", "none", "--seed", "1", "--samples", "10",
                        "--out", str(tmp_path / "r.csv")], capsys)
    assert status == 2 and "--samples must be an integer >= 400" in out.err


@pytest.mark.parametrize("effect", ["input_map", "sensor_map", "sensor_drift", "mains_pickup"])
def test_make_recording_cli_writes_the_flexible_families(tmp_path, effect):
    out = tmp_path / f"{effect}.csv"
    done = subprocess.run([sys.executable, "-m", "hyst_gym.cli", "make-recording", "--effect", effect, "--seed", "3",
                           "--samples", "800", "--out", str(out)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    written = read_recording(out)
    plain = make_recording("none", 3, n_samples=800)[0]
    assert written.size == 800
    assert np.max(np.abs(written.magnetization - plain.magnetization)) > 1e-3 * np.ptp(plain.magnetization)
