"""``hyst-gym train`` and ``hyst-gym evaluate`` end to end (tiny sizes)."""

import csv
import json

import numpy as np
import pytest

from baselines.scenarios import HELDOUT_SEEDS
from hyst_gym.cli import main


def test_train_resume_and_evaluate(tmp_path, capsys):
    out = tmp_path / "ppo"
    args = ["train", "--algo", "ppo", "--env", "hyst_gym/Excitation-v0", "--timesteps", "2048", "--seed", "3",
            "--out", str(out), "--n-stack", "2", "--checkpoint-every", "1024", "--eval-every", "2048",
            "--eval-episodes", "1", "--no-progress"]
    assert main(args) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["algo"] == "ppo" and config["seed"] == 3 and config["n_stack"] == 2 and config["reward"] == "dense"
    assert config["trained_steps"] == 2048 and config["env_kwargs"]["a_true"] == 7012.0
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == ["model_1024_steps.zip", "model_2048_steps.zip"]
    assert any((out / "tb").rglob("events.out.tfevents.*"))
    with (out / "learning_curve.csv").open() as handle:
        curve = list(csv.DictReader(handle))
    assert [int(r["env_steps"]) for r in curve] == [2048]

    args[args.index("--timesteps") + 1] = "4096"
    assert main(args + ["--resume"]) == 0
    assert "resuming from" in capsys.readouterr().out
    assert json.loads((out / "config.json").read_text())["trained_steps"] == 4096

    assert main(["evaluate", "--agent", str(out), "--env", "hyst_gym/Excitation-v0", "--episodes", "2",
                 "--out", str(tmp_path / "eval")]) == 0
    with (tmp_path / "eval" / "episodes.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [int(r["seed"]) for r in rows] == list(HELDOUT_SEEDS[:2])
    assert all(float(r["rms_error"]) > 0 for r in rows)


def test_bad_input_is_one_line_error(tmp_path, capsys):
    assert main(["train", "--algo", "ppo", "--timesteps", "0", "--out", str(tmp_path)]) == 2
    assert main(["evaluate", "--agent", "no_such_agent", "--episodes", "1", "--out", str(tmp_path)]) == 2
    assert main(["evaluate", "--agent", "ramp", "--episodes", "0", "--out", str(tmp_path)]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 3 and all(line.startswith("hyst-gym ") and "error:" in line for line in errors)
    assert "--timesteps must be > 0" in errors[0] and "no_such_agent" in errors[1]


def test_train_recurrent_ppo_from_cli(tmp_path, capsys):
    out = tmp_path / "rppo"
    args = ["train", "--algo", "recurrent_ppo", "--timesteps", "64", "--n-envs", "2", "--out", str(out),
            "--checkpoint-every", "0", "--hyperparams", '{"n_steps": 32, "batch_size": 32}', "--no-progress"]
    assert main(args) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["algo"] == "recurrent_ppo" and config["policy"] == "MlpLstmPolicy"
    assert config["n_stack"] == 1 and config["trained_steps"] == 64  # no frame stack by default
    assert config["hyperparams"]["n_steps"] == 32 and config["hyperparams"]["n_epochs"] == 10

    assert main(["evaluate", "--agent", str(out), "--episodes", "1", "--out", str(tmp_path / "eval")]) == 0
    with (tmp_path / "eval" / "episodes.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 1 and int(rows[0]["steps"]) == config["env_kwargs"]["episode_steps"]
    assert np.isfinite(float(rows[0]["rms_error"])) and float(rows[0]["rms_error"]) > 0

    assert main(args[:-1] + ["--n-stack", "4", "--out", str(tmp_path / "bad"), "--no-progress"]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "--n-stack must be 1 for recurrent_ppo" in error[0]


def test_missing_rl_extra_is_a_one_line_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "torch", None)  # as if the rl extra were not installed
    assert main(["train", "--algo", "ppo", "--timesteps", "64", "--out", str(tmp_path), "--no-progress"]) == 2
    error = capsys.readouterr().err.strip()
    assert error == "hyst-gym train: error: needs torch; install the RL extra: pip install 'hyst-gym[rl]'"


def test_reward_names_of_the_parser_are_those_of_the_rewards_module():
    from baselines.rewards import REWARDS
    from baselines.train import REWARD_NAMES

    assert REWARD_NAMES == REWARDS  # train.py repeats them so that its --help needs no Stable-Baselines3


def test_bad_settings_leave_no_output_folder(tmp_path, capsys):
    out = tmp_path / "run"
    common = ["--algo", "ppo", "--timesteps", "64", "--out", str(out), "--no-progress"]
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "--env", "hyst_gym/Nope-v0", *common])
    assert exit_info.value.code == 2
    assert main(["train", "--hyperparams", '{"nope": 1, "n_steps": 64}', *common]) == 2
    assert main(["train", "--hyperparams", '{"policy_kwargs": {"net_arch": [8], "width": 3}}', *common]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 3 and "Traceback" not in "".join(errors)
    assert errors[0].startswith("hyst-gym train: error: argument --env: invalid choice: 'hyst_gym/Nope-v0'")
    assert errors[1].startswith("hyst-gym train: error: --hyperparams: unknown hyperparameter(s) nope for ppo; "
                                "accepted: batch_size, ")
    assert "n_steps" in errors[1].split("accepted:")[1]
    assert "unknown policy_kwargs key(s) width for ppo's MlpPolicy; accepted: " in errors[2]
    assert not out.exists()


def test_hyperparameter_values_the_algorithm_rejects_are_one_line_errors(tmp_path, capsys):
    out = tmp_path / "run"
    common = ["--timesteps", "64", "--out", str(out), "--no-progress"]
    assert main(["train", "--algo", "ppo", "--hyperparams", '{"n_steps": -1}', *common]) == 2
    assert main(["train", "--algo", "sac", "--hyperparams", '{"learning_rate": "fast"}', *common]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 2 and "Traceback" not in "".join(errors)
    # SB3's own reason follows the flag and the values that were passed
    assert errors[0].startswith('hyst-gym train: error: --hyperparams {"n_steps": -1} rejected by ppo: ')
    assert "n_steps=-1" in errors[0]
    assert errors[1].startswith('hyst-gym train: error: --hyperparams {"learning_rate": "fast"} rejected by sac: ')
    assert not out.exists()  # rejected before anything was written
