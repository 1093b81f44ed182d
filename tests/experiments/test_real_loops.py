"""experiments/real_loops.py --data/--json: anyone's loops in the shipped layout are scored."""

import json
import shutil
from pathlib import Path

import scipy.io

from experiments import real_loops

SHIPPED = Path(__file__).resolve().parents[2] / "data" / "real" / "jamodel-loops"


def test_scores_a_folder_of_loop_pairs(tmp_path):
    folder = tmp_path / "loops"
    folder.mkdir()
    for prefix in ("B", "H"):
        shutil.copy(SHIPPED / f"{prefix}_MnZn_ferrite.mat", folder / f"{prefix}_my_sample.mat")
    assert real_loops.main(["--data", str(folder), "--json", str(tmp_path / "s.json")]) == 0
    entry = json.loads((tmp_path / "s.json").read_text())["my sample"]
    candidates = set(real_loops.MODEL_CANDIDATES["auto"])
    assert entry["variant"] in candidates and set(entry["variants"]) == candidates
    # four loops: the second largest is the validation loop, and it decides
    assert entry["rule"] == "validation" and entry["chosen_by"].startswith("validation loop")
    assert [loop["role"] for loop in entry["loops"]] == ["fitted", "validation", "predicted", "predicted"]
    validation = {name: list(v["nrmse_B"].values())[1] for name, v in entry["variants"].items()}
    assert entry["validation_loop_nrmse"] == min(validation.values()) == validation[entry["variant"]]
    peaks = [loop["peak_field"] for loop in entry["loops"]]
    assert peaks == sorted(peaks, reverse=True) and len(peaks) == 4 and 75 < peaks[0] < 85
    # the fitted (largest) loop is matched closely; the smaller ones are predicted, not fitted
    assert entry["fitted_loop_nrmse"] == entry["loops"][0]["nrmse"] < 0.01  # the 1 % target
    assert all(0 < loop["nrmse"] < 0.2 for loop in entry["loops"])
    # the 40 and 16 A/m loops are predicted within the 8 % (docs/results/real-loops.md)
    assert all(loop["nrmse"] < 0.08 for loop in entry["loops"][1:3])
    assert 0 < entry["fit_seconds"] <= entry["all_candidates_fit_seconds"]
    assert 0 < entry["fit_cpu_seconds"] <= entry["all_candidates_cpu_seconds"]
    if entry["variant"] in real_loops.MODEL_CANDIDATES["domain_wall"]:
        assert {"a", "k", "alpha", "Ms", "c"} <= set(entry["params"])
        assert ("chi_r" in entry["params"]) == entry["variant"].endswith("small_loop")
        # the equally good fits bracket the reported prediction of every smaller loop
        for loop in entry["loops"][1:]:
            low, high = entry["prediction_spread"]["nrmse_range"][f"{loop['peak_field']:.3g} A/m"]
            assert low <= loop["nrmse"] + 1e-12 and loop["nrmse"] <= high + 1e-12
    # the HEM with the anhysteretic population fits the largest loop within 1 % and predicts the smaller ones
    # no worse than the HEM without it
    hem = entry["variants"]["hem normal + saturating reversible + anhysteretic population"]["nrmse_B"]
    nested = entry["variants"]["hem normal + saturating reversible"]["nrmse_B"]
    assert list(hem.values())[0] < 0.01
    assert all(a <= b for a, b in zip(list(hem.values())[1:], list(nested.values())[1:]))


def test_two_loops_fall_back_to_the_transfer_score(tmp_path):
    folder = tmp_path / "two"
    folder.mkdir()
    for prefix in ("B", "H"):
        matrix = scipy.io.loadmat(SHIPPED / f"{prefix}_MnZn_HP_ferrite.mat")
        name = [k for k in matrix if not k.startswith("__")][0]
        scipy.io.savemat(folder / f"{prefix}_pair.mat", {name: matrix[name][:, [0, 3]]})
    assert real_loops.main(["--data", str(folder), "--json", str(tmp_path / "s.json"), "--model", "hem"]) == 0
    entry = json.loads((tmp_path / "s.json").read_text())["pair"]
    assert entry["rule"] == "transfer" and [loop["role"] for loop in entry["loops"]] == ["fitted", "predicted"]
    # the target's own loops are not in the shipped set under another name: both shipped materials score it
    scores = entry["transfer_scores"]
    assert entry["variant"] == min(scores, key=scores.get) and set(scores) == set(entry["variants"])


def test_small_loop_variant_predicts_the_small_hp_ferrite_loops_better_than_model_6(tmp_path):
    """The amplitude hold-out on the shipped HP ferrite: fitted on the 80 A/m loop only, the
    small-loop extension predicts the 6 A/m loop better than (6) with the same curve, and the
    variant chosen by the validation loop predicts every smaller loop within the issue's 8 %."""
    folder = tmp_path / "hp"
    folder.mkdir()
    for prefix in ("B", "H"):
        shutil.copy(SHIPPED / f"{prefix}_MnZn_HP_ferrite.mat", folder / f"{prefix}_hp.mat")
    real_loops.main(["--data", str(folder), "--json", str(tmp_path / "s.json")])
    entry = json.loads((tmp_path / "s.json").read_text())["hp"]
    smallest = {name: list(v["nrmse_B"].values())[-1] for name, v in entry["variants"].items()}
    for curve in ("ising", "langevin"):
        assert smallest[f"{curve} + small_loop"] < smallest[curve], curve
    assert entry["fitted_loop_nrmse"] < 0.01 and all(loop["nrmse"] < 0.08 for loop in entry["loops"])
    assert entry["fit_seconds"] < 20.0  # 2 s on the 2-core machine (results page); generous for a loaded one


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


def test_page_table_is_the_committed_study():
    """The real-loops-table section of docs/results/real-loops.md is what the script writes from the committed
    real_loops.json (rerun: python -m experiments.real_loops); the chosen candidate of each material is the one
    the selection rule picks from the stored rows."""
    from tests.test_docs_sections import section

    summary = json.loads((real_loops.RESULTS / "real_loops.json").read_text())
    assert section(real_loops.PAGE, "real-loops-table") == real_loops.loops_table(summary).strip()
    for stem in real_loops.MATERIALS:
        rows = summary[stem]["holdout"]
        chosen, how = real_loops.choose_variant(rows, summary[stem]["scores"]["transfer_scores"])
        assert (chosen["variant"], how) == (summary[stem]["scores"]["variant"], summary[stem]["scores"]["rule"])
        assert f"**{chosen['variant']}**" in section(real_loops.PAGE, "real-loops-table")
