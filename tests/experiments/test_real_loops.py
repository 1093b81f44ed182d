"""experiments/real_loops.py --data/--json: anyone's loops in the shipped layout are scored."""

import json
import shutil
from pathlib import Path

from experiments import real_loops

SHIPPED = Path(__file__).resolve().parents[2] / "data" / "real" / "jamodel-loops"


def test_scores_a_folder_of_loop_pairs(tmp_path):
    folder = tmp_path / "loops"
    folder.mkdir()
    for prefix in ("B", "H"):
        shutil.copy(SHIPPED / f"{prefix}_MnZn_ferrite.mat", folder / f"{prefix}_my_sample.mat")
    assert real_loops.main(["--data", str(folder), "--json", str(tmp_path / "s.json")]) == 0
    entry = json.loads((tmp_path / "s.json").read_text())["my sample"]
    assert entry["variant"] in ("ising", "langevin") and entry["chosen_by"].startswith("held-out segment")
    peaks = [loop["peak_field"] for loop in entry["loops"]]
    assert peaks == sorted(peaks, reverse=True) and len(peaks) == 4 and 75 < peaks[0] < 85
    # the fitted (largest) loop is matched closely; the smaller ones are predicted, not fitted
    assert entry["fitted_loop_nrmse"] == entry["loops"][0]["nrmse"] < 0.02
    assert all(0 < loop["nrmse"] < 0.2 for loop in entry["loops"])
    assert entry["fit_seconds"] > 0 and set(entry["params"]) == {"a", "k", "alpha", "Ms", "c"}


def test_bad_folders_are_one_line_errors(tmp_path, capsys):
    def error_of(folder):
        status = real_loops.main(["--data", str(folder), "--json", str(tmp_path / "s.json")])
        err = capsys.readouterr().err
        assert status == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
        return err

    assert "not a folder" in error_of(tmp_path / "missing")
    assert "no B_<name>.mat" in error_of(tmp_path)
    (tmp_path / "B_x.mat").write_text("not a mat file")
    (tmp_path / "H_x.mat").write_text("not a mat file")
    assert "B_x.mat: not a readable .mat file" in error_of(tmp_path)
