"""The README's main job, `hyst-gym demo`, end to end on a few draws."""

import re

from baselines.scenarios import HELDOUT_SEEDS
from hyst_gym import cli


def test_demo_writes_its_table_and_figures_and_the_ramp_is_slower_than_the_floor(tmp_path, capsys):
    assert cli.main(["demo", "--out", str(tmp_path), "--episodes", "3"]) == 0
    for name in ("loops.png", "comparison.md", "comparison.png", "survival.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    table = (tmp_path / "comparison.md").read_text()
    floor = float(re.search(r"settles before ([0-9.]+) s", table).group(1))
    ramp = float(re.search(r"\| ramp \| ([0-9.]+) ", table).group(1))
    assert 2.0 < floor < 2.5
    assert ramp > floor + 1.0  # the paper's ramp spends seconds below the peak sensitivity
    assert "[table] wrote" in capsys.readouterr().out


def test_bad_counts_are_one_line_errors_before_any_stage_runs(tmp_path, capsys):
    n_draws = len(HELDOUT_SEEDS)
    for flag, value in (("--episodes", "0"), ("--episodes", str(n_draws + 1)), ("--ppo-steps", "-5")):
        out = tmp_path / f"demo{flag}{value}"
        assert cli.main(["demo", "--out", str(out), flag, value]) == 2
        assert not out.exists()  # no stage ran: not even the output folder was made
    captured = capsys.readouterr()
    errors = captured.err.strip().splitlines()
    assert captured.out == ""
    episodes = f"hyst-gym demo: error: --episodes must be in 1..{n_draws} (the held-out draws), got"
    assert errors == [f"{episodes} 0", f"{episodes} {n_draws + 1}",
                      "hyst-gym demo: error: --ppo-steps must be > 0, got -5"]
