"""The recording reader: good files round-trip, bad files give one-line errors, no tracebacks."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from hyst_gym import cli
from hyst_gym.diagnose.recording import MIN_SAMPLES, Recording, read_recording, write_recording


def _good_rows(n=MIN_SAMPLES + 10):
    t = np.arange(n) * 1e-3
    return t, 1e4 * np.sin(2 * np.pi * 5 * t), 3e5 * np.tanh(np.sin(2 * np.pi * 5 * t))


def _write(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(str(v) for v in row) for row in rows) + "\n")
    return path


def test_round_trip_is_exact(tmp_path):
    t, h, m = _good_rows()
    rec = Recording(time=t, field=h, magnetization=m)
    path = write_recording(tmp_path / "r.csv", rec, {"material": "x"})
    back = read_recording(path)
    assert np.array_equal(back.time, t) and np.array_equal(back.field, h) and np.array_equal(back.magnetization, m)
    assert back.metadata == {"material": "x"} and back.channels == ("magnetization",)


def test_current_column_uses_turns_per_meter(tmp_path):
    t, h, m = _good_rows()
    path = _write(tmp_path / "c.csv", "time,current,magnetization", zip(t, h / 500.0, m))
    with pytest.raises(ValueError, match="turns_per_meter"):
        read_recording(path)
    (tmp_path / "c.json").write_text('{"turns_per_meter": 500}')
    assert np.allclose(read_recording(path).field, h)


def test_flux_density_in_tesla_is_read_as_magnetization(tmp_path):
    t, h, m = _good_rows()
    mu0 = 4e-7 * np.pi
    b = mu0 * (h + m)  # T; 0.38 T at the peak of this loop
    path = _write(tmp_path / "b.csv", "time,field,flux_density", zip(t, h, b))
    back = read_recording(path)
    assert back.channels == ("magnetization",)
    np.testing.assert_allclose(back.magnetization, m, rtol=0, atol=1e-9 * np.ptp(m))
    both = _write(tmp_path / "both.csv", "time,field,flux_density,magnetization", zip(t, h, b, m))
    with pytest.raises(ValueError, match="not both"):
        read_recording(both)


@pytest.mark.parametrize("mutate, message", [
    (lambda rows, header: ("time,magnetization", [(r[0], r[2]) for r in rows]), "missing column 'field'"),
    (lambda rows, header: ("time,field", [(r[0], r[1]) for r in rows]), "magnetization' or a 'displacement"),
    (lambda rows, header: (header, rows[:5] + [(rows[5][0], "abc", rows[5][2])] + rows[6:]), "row 7, column 'field'"),
    (lambda rows, header: (header, rows[:8] + [(rows[8][0], "nan", rows[8][2])] + rows[9:]), "row 10, column 'field'"),
    (lambda rows, header: (header, rows[:20] + [(rows[18][0],) + tuple(rows[20][1:])] + rows[21:]), "row 22: time"),
    (lambda rows, header: (header, rows[:50]), "only 50 samples"),
    (lambda rows, header: (header, []), "no samples"),
    (lambda rows, header: (header, rows[:3] + [rows[3][:2]] + rows[4:]), "row 5: has 2 cells"),
])
def test_bad_files_name_row_and_problem(tmp_path, mutate, message):
    t, h, m = _good_rows()
    header, rows = mutate([tuple(r) for r in zip(t, h, m)], "time,field,magnetization")
    path = _write(tmp_path / "bad.csv", header, rows)
    with pytest.raises(ValueError) as info:
        read_recording(path)
    text = str(info.value)
    assert message in text and str(path) in text and "\n" not in text


def test_empty_file(tmp_path):
    path = tmp_path / "empty.csv"
    path.write_text("")
    with pytest.raises(ValueError, match="empty file"):
        read_recording(path)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzzed_files_never_escape_the_cli(tmp_path_factory, capsys, data):
    """Mangle a good file (cut, replace cells, insert bytes); the CLI must exit non-zero with one
    line on stderr, or succeed only if the file is still valid -- never a traceback."""
    t, h, m = _good_rows()
    lines = ["time,field,magnetization"] + [f"{a},{b},{c}" for a, b, c in zip(t, h, m)]
    text = "\n".join(lines)
    kind = data.draw(st.sampled_from(["truncate", "replace", "insert", "header"]))
    if kind == "truncate":
        text = text[:data.draw(st.integers(0, len(text)))]
    elif kind == "replace":
        i = data.draw(st.integers(1, len(lines) - 1))
        cells = lines[i].split(",")
        cells[data.draw(st.integers(0, 2))] = data.draw(st.sampled_from(["", "x", "nan", "inf", "1e999", "--", "0x1"]))
        lines[i] = ",".join(cells)
        text = "\n".join(lines)
    elif kind == "insert":
        pos = data.draw(st.integers(0, len(text)))
        text = text[:pos] + data.draw(st.text(min_size=1, max_size=5)) + text[pos:]
    else:
        text = data.draw(st.text(max_size=30)) + "\n" + "\n".join(lines[1:])
    path = tmp_path_factory.mktemp("fuzz") / "rec.csv"
    path.write_text(text, encoding="utf-8", errors="surrogatepass") if False else path.write_bytes(
        text.encode("utf-8", errors="replace"))
    try:
        read_recording(path)
        valid = True
    except ValueError as error:
        valid = False
        assert "\n" not in str(error) and str(path) in str(error)
    if not valid:
        status = cli.main(["diagnose", str(path), "--quiet"])
        err = capsys.readouterr().err
        assert status == 2 and "Traceback" not in err and err.count("\n") == 1
