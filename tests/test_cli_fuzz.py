"""Bad input to the ``hyst-gym`` command and to the environments: one line naming the
argument (field, file) and the problem, exit status 2 at the CLI, never a traceback.

Most cases call :func:`hyst_gym.cli.main` in-process; a few run the command as users do
(a subprocess), where the import machinery matters: the rl extra missing, a user's own
``experiments`` package on the path.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import types
import zipfile

import gymnasium
import numpy as np
import pytest

from hyst_gym import __version__, cli
from hyst_gym.cli import main
from hyst_gym.envs import kernels

REPOSITORY = cli.repository_root()


def run_cli(capsys, argv):
    """(exit status, stdout, stderr lines) of ``hyst-gym ARGV`` run in-process; the
    first-use compile notice (cold numba cache) is not an error line."""
    try:
        status = main([str(arg) for arg in argv])
    except SystemExit as exit_info:  # argparse: usage errors and --help
        status = exit_info.code
    captured = capsys.readouterr()
    errors = [line for line in captured.err.splitlines() if line != kernels.COMPILE_NOTICE]
    return status, captured.out, errors


def assert_one_line_error(status, errors, command, *expected):
    assert status == 2, errors
    assert len(errors) == 1, errors
    line = errors[0]
    assert "Traceback" not in line and "np.float64" not in line
    prefix = f"hyst-gym {command}: error: " if command else "hyst-gym: error: "
    assert line.startswith(prefix), line
    for text in expected:
        assert text in line, line


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Bad input files: recordings, models, a plain file where a folder belongs."""
    root = tmp_path_factory.mktemp("bad_inputs")
    (root / "not_increasing.csv").write_text("time,field,magnetization\n0,0,0\n0.5,1,1\n0.5,2,2\n")
    (root / "nan_cell.csv").write_text("time,field,magnetization\n0,0,0\n0.5,nan,1\n")
    (root / "no_time.csv").write_text("t,field,magnetization\n0,0,0\n")
    (root / "word_cell.csv").write_text("time,field,magnetization\n0,0,0\n0.5,high,1\n")
    (root / "empty.csv").write_text("")
    (root / "a_file").write_text("not a folder")
    (root / "no_model").mkdir()
    garbage = root / "garbage_model"
    garbage.mkdir()
    (garbage / "model.zip").write_text("not a zip file")
    bad_config = root / "bad_config"
    bad_config.mkdir()
    zipfile.ZipFile(bad_config / "model.zip", "w").close()  # a zip, but no model: config.json is read first
    (bad_config / "config.json").write_text("{not json")
    return root


@pytest.fixture(scope="module")
def excitation_policy(tmp_path_factory):
    """An (untrained) PPO policy of Excitation-v0 with 2 stacked frames, saved as train does."""
    from stable_baselines3 import PPO

    from baselines.environment import make_sb3_vec_env
    from baselines.scenarios import scenario_spec

    folder = tmp_path_factory.mktemp("policy")
    spec = scenario_spec("paper")
    venv = make_sb3_vec_env(spec, 1, 0, n_stack=2)
    PPO("MlpPolicy", venv, n_steps=64, batch_size=64, device="cpu").save(folder / "model.zip")
    venv.close()
    (folder / "config.json").write_text(json.dumps({"algo": "ppo", "n_stack": 2, "env_id": spec.env_id,
                                                    "scenario": "paper"}))
    return folder


TRAIN = ["train", "--algo", "ppo", "--timesteps", "64", "--no-progress"]
EVALUATE = ["evaluate", "--agent", "ramp", "--episodes", "1"]

#: (id, argv with {files} and {out} placeholders, command, texts the error line must contain)
CLI_CASES = [
    ("train-unknown-env", TRAIN + ["--env", "hyst_gym/Nope-v0", "--out", "{out}"], "train",
     ["argument --env", "'hyst_gym/Nope-v0'"]),
    ("train-unknown-hyperparameter", TRAIN + ["--hyperparams", '{"nope": 1}', "--out", "{out}"], "train",
     ["--hyperparams: unknown hyperparameter(s) nope for ppo", "accepted: batch_size"]),
    ("train-hyperparams-not-json", TRAIN + ["--hyperparams", "{n_steps: 64}", "--out", "{out}"], "train",
     ["--hyperparams is not valid JSON"]),
    ("train-hyperparams-not-object", TRAIN + ["--hyperparams", "[64]", "--out", "{out}"], "train",
     ["--hyperparams must be a JSON object", "list"]),
    ("train-unknown-policy-kwarg", TRAIN + ["--hyperparams", '{"policy_kwargs": {"layers": 2}}', "--out", "{out}"],
     "train", ["--hyperparams: unknown policy_kwargs key(s) layers", "net_arch"]),
    ("train-sac-ppo-hyperparameter", ["train", "--algo", "sac", "--timesteps", "64", "--hyperparams",
                                      '{"n_epochs": 3}', "--out", "{out}"], "train",
     ["unknown hyperparameter(s) n_epochs for sac"]),
    ("train-negative-timesteps", ["train", "--algo", "ppo", "--timesteps", "-5", "--out", "{out}"], "train",
     ["--timesteps must be > 0, got -5"]),
    ("train-zero-envs", TRAIN + ["--n-envs", "0", "--out", "{out}"], "train", ["--n-envs must be > 0, got 0"]),
    ("train-negative-seed", TRAIN + ["--seed", "-1", "--out", "{out}"], "train", ["--seed must be >= 0, got -1"]),
    ("train-negative-checkpoints", TRAIN + ["--checkpoint-every", "-10", "--out", "{out}"], "train",
     ["--checkpoint-every must be >= 0, got -10"]),
    ("train-too-many-eval-episodes", TRAIN + ["--eval-episodes", "17", "--out", "{out}"], "train",
     ["--eval-episodes must be in 1..16", "got 17"]),
    ("train-zero-eval-episodes", TRAIN + ["--eval-episodes", "0", "--out", "{out}"], "train",
     ["--eval-episodes must be in 1..16"]),
    ("train-recurrent-stack", ["train", "--algo", "recurrent_ppo", "--timesteps", "64", "--n-stack", "4",
                               "--out", "{out}"], "train", ["--n-stack must be 1 for recurrent_ppo"]),
    ("train-unknown-algo", ["train", "--algo", "dqn", "--timesteps", "64", "--out", "{out}"], "train",
     ["argument --algo: invalid choice: 'dqn'"]),
    ("train-timesteps-not-int", ["train", "--algo", "ppo", "--timesteps", "lots", "--out", "{out}"], "train",
     ["argument --timesteps: invalid int value: 'lots'"]),
    ("train-unknown-reward", TRAIN + ["--reward", "sparse", "--out", "{out}"], "train",
     ["argument --reward: invalid choice: 'sparse'"]),
    ("train-unknown-scenario", TRAIN + ["--scenario", "moon", "--out", "{out}"], "train",
     ["argument --scenario: invalid choice: 'moon'"]),
    ("train-missing-out", TRAIN, "train", ["the following arguments are required: --out"]),
    ("train-out-is-a-file", TRAIN + ["--out", "{files}/a_file"], "train", ["--out", "a_file", "is not a folder"]),
    ("evaluate-unknown-agent", ["evaluate", "--agent", "no_such_agent", "--episodes", "1", "--out", "{out}"],
     "evaluate", ["unknown agent 'no_such_agent'"]),
    ("evaluate-zero-episodes", ["evaluate", "--agent", "ramp", "--episodes", "0", "--out", "{out}"], "evaluate",
     ["--episodes must be > 0, got 0"]),
    ("evaluate-negative-seed", EVALUATE + ["--seed", "-3", "--out", "{out}"], "evaluate",
     ["--seed must be >= 0, got -3"]),
    ("evaluate-missing-artifacts", EVALUATE + ["--artifacts", "{files}/nowhere", "--out", "{out}"], "evaluate",
     ["--artifacts", "nowhere: no such folder"]),
    ("evaluate-unknown-env", EVALUATE + ["--env", "CartPole-v1", "--out", "{out}"], "evaluate",
     ["argument --env: invalid choice: 'CartPole-v1'"]),
    ("evaluate-folder-without-model", ["evaluate", "--agent", "{files}/no_model", "--episodes", "1", "--out",
                                       "{out}"], "evaluate", ["no trained model at", "no_model"]),
    ("evaluate-model-not-a-zip", ["evaluate", "--agent", "{files}/garbage_model", "--episodes", "1", "--out",
                                  "{out}"], "evaluate",
     ["garbage_model/model.zip: not a saved Stable-Baselines3 model (not a zip file)"]),
    ("evaluate-config-not-json", ["evaluate", "--agent", "{files}/bad_config", "--episodes", "1", "--out",
                                  "{out}"], "evaluate", ["bad_config/config.json: not valid JSON"]),
    ("diagnose-time-not-increasing", ["diagnose", "{files}/not_increasing.csv", "--quiet"], "diagnose",
     ["not_increasing.csv: row 4: time 0.5 s is not greater than the previous 0.5 s"]),
    ("diagnose-nan-sample", ["diagnose", "{files}/nan_cell.csv", "--quiet"], "diagnose",
     ["nan_cell.csv: row 3, column 'field'", "nan"]),
    ("diagnose-word-sample", ["diagnose", "{files}/word_cell.csv", "--quiet"], "diagnose",
     ["word_cell.csv: row 3, column 'field': 'high' is not"]),
    ("diagnose-no-time-column", ["diagnose", "{files}/no_time.csv", "--quiet"], "diagnose",
     ["no_time.csv: row 1: missing column 'time'"]),
    ("diagnose-empty-file", ["diagnose", "{files}/empty.csv", "--quiet"], "diagnose", ["empty.csv: empty file"]),
    ("diagnose-missing-file", ["diagnose", "{files}/nowhere.csv", "--quiet"], "diagnose", ["nowhere.csv"]),
    ("diagnose-folder", ["diagnose", "{files}", "--quiet"], "diagnose", ["is a directory, not a recording CSV"]),
    ("diagnose-holdout-not-float", ["diagnose", "{files}/empty.csv", "--holdout", "most"], "diagnose",
     ["argument --holdout: invalid float value: 'most'"]),
    ("make-recording-unknown-effect", ["make-recording", "--effect", "gremlins", "--seed", "1", "--out",
                                       "{out}/r.csv"], "make-recording", ["argument --effect: invalid choice"]),
    ("make-recording-few-samples", ["make-recording", "--effect", "none", "--seed", "1", "--samples", "-5",
                                    "--out", "{out}/r.csv"], "make-recording",
     ["--samples must be an integer >= 400, got -5"]),
    ("make-recording-negative-seed", ["make-recording", "--effect", "none", "--seed", "-1", "--out",
                                      "{out}/r.csv"], "make-recording", ["--seed must be an integer >= 0, got -1"]),
    ("reproduce-negative-dt", ["reproduce", "--out", "{out}", "--dt", "-1"], "reproduce", ["--dt must be in"]),
    ("unknown-command", ["fly"], None, ["argument COMMAND: invalid choice: 'fly'"]),
    ("unknown-top-level-flag", ["--verbose"], None, ["unrecognized arguments: --verbose"]),
]


@pytest.mark.parametrize("argv, command, expected", [case[1:] for case in CLI_CASES],
                         ids=[case[0] for case in CLI_CASES])
def test_bad_cli_input_is_one_line_and_status_2(capsys, tmp_path, files, argv, command, expected):
    out = tmp_path / "out"
    argv = [arg.replace("{files}", str(files)).replace("{out}", str(out)) for arg in argv]
    status, _, errors = run_cli(capsys, argv)
    assert_one_line_error(status, errors, command, *expected)
    if command in ("train", "evaluate"):
        assert not out.exists()  # validated before anything was written


def test_policy_on_another_env_is_our_one_line_error(capsys, tmp_path, excitation_policy):
    status, _, errors = run_cli(capsys, ["evaluate", "--agent", excitation_policy, "--env", "hyst_gym/Estimation-v0",
                                         "--episodes", "1", "--out", tmp_path / "eval"])
    assert_one_line_error(status, errors, "evaluate",
                          f"--agent {excitation_policy}: policy 'ppo' was trained on hyst_gym/Excitation-v0 (paper) "
                          "with observations of 14 entries (2 frames of 7) and actions of 1, but "
                          "hyst_gym/Estimation-v0 (paper) has observations of 4 entries and actions of 1")
    status, _, errors = run_cli(capsys, ["evaluate", "--agent", excitation_policy, "--scenario", "lumped",
                                         "--episodes", "1", "--out", tmp_path / "eval"])
    assert_one_line_error(status, errors, "evaluate", "hyst_gym/Excitation-v0 (lumped) has observations of 8 entries")


def test_rl_extra_missing_in_process(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "cma", None)  # as if the rl extra (here: cma) were not installed
    status, _, errors = run_cli(capsys, ["demo", "--out", tmp_path / "demo"])
    assert_one_line_error(status, errors, "demo", "needs cma; install the RL extra: pip install 'hyst-gym[rl]'")
    assert not (tmp_path / "demo").exists()


def test_outside_a_clone_the_checkout_commands_say_so(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(cli, "repository_root", lambda: tmp_path)  # as installed from the wheel
    for command in ("demo", "reproduce", "train", "evaluate"):
        status, _, errors = run_cli(capsys, [command, "--out", tmp_path / "x"])
        assert_one_line_error(status, errors, command, "this command runs from a clone of the repository",
                              "git clone https://github.com/hyst-gym/hyst-gym && cd hyst-gym && bash scripts/setup.sh")
        status, out, errors = run_cli(capsys, [command, "--help"])
        assert status == 0 and not errors and "runs from a clone of the repository" in " ".join(out.split())


def test_a_foreign_experiments_package_is_named(capsys, tmp_path, monkeypatch):
    foreign = types.ModuleType("experiments")
    foreign.__file__ = str(tmp_path / "experiments" / "__init__.py")
    monkeypatch.setitem(sys.modules, "experiments", foreign)
    status, _, errors = run_cli(capsys, EVALUATE + ["--out", tmp_path / "out"])
    assert_one_line_error(status, errors, "evaluate", f"the 'experiments' package was imported from {foreign.__file__}",
                          f"not from this checkout ({REPOSITORY / 'experiments'})")


def test_version_and_plain_description(capsys):
    status, out, _ = run_cli(capsys, ["--version"])
    assert status == 0 and out.strip() == f"hyst-gym {__version__}"
    status, out, _ = run_cli(capsys, ["--help"])
    assert status == 0 and "``" not in out and "--version" in out


@pytest.mark.parametrize("command", list(cli.SUBCOMMANDS))
def test_every_flag_has_help(command):
    parser = cli.build_parser(command, cli._load(command))
    subparsers = next(a for a in parser._actions if isinstance(a, cli.argparse._SubParsersAction))
    assert all(action.help for action in parser._actions if action is not subparsers)
    missing = [action.option_strings or action.dest for action in subparsers.choices[command]._actions
               if not action.help]
    assert not missing, f"{command}: no help for {missing}"


# ---------------------------------------------------------------- as users run it


def run_command(argv, cwd=None, pythonpath=None):
    env = {**os.environ, "PYTHONPATH": str(pythonpath) if pythonpath else ""}
    env.pop("HYST_GYM_DEBUG", None)
    result = subprocess.run([sys.executable, "-m", "hyst_gym.cli", *map(str, argv)], capture_output=True,
                            text=True, cwd=cwd, env=env, timeout=120)
    errors = [line for line in result.stderr.splitlines() if line != kernels.COMPILE_NOTICE]
    return result.returncode, result.stdout, errors


def test_unknown_env_as_users_run_it(tmp_path):
    status, _, errors = run_command(TRAIN + ["--env", "hyst_gym/Nope-v0", "--out", tmp_path / "out"])
    assert_one_line_error(status, errors, "train", "argument --env: invalid choice: 'hyst_gym/Nope-v0'")
    assert not (tmp_path / "out").exists()


BLOCK_RL_EXTRA = '''
import importlib.machinery

BLOCKED = {"stable_baselines3", "sb3_contrib", "torch", "tensorboard", "cma"}
_find_spec = importlib.machinery.PathFinder.find_spec


def _find_spec_without_rl_extra(fullname, path=None, target=None):
    if fullname.split(".")[0] in BLOCKED:
        return None  # as if the rl extra were not installed
    return _find_spec(fullname, path, target)


importlib.machinery.PathFinder.find_spec = staticmethod(_find_spec_without_rl_extra)
'''


def test_without_the_rl_extra_help_works_and_running_says_what_is_missing(tmp_path):
    (tmp_path / "sitecustomize.py").write_text(textwrap.dedent(BLOCK_RL_EXTRA))
    status, out, errors = run_command(["train", "--help"], pythonpath=tmp_path)
    assert status == 0 and "--hyperparams" in out and not errors
    status, _, errors = run_command(["demo", "--out", tmp_path / "demo"], pythonpath=tmp_path)
    assert_one_line_error(status, errors, "demo", "needs torch, stable_baselines3, tensorboard, cma; "
                                                  "install the RL extra: pip install 'hyst-gym[rl]'")
    assert not (tmp_path / "demo").exists()


@pytest.mark.parametrize("package", ["baselines", "experiments"])
def test_a_user_package_does_not_shadow_the_benchmark(tmp_path, package):
    # evaluate reads the IQM from baselines.stats; a same-named user package earlier on the path must not win
    project = tmp_path / "project"
    (project / package).mkdir(parents=True)
    (project / package / "__init__.py").write_text("")
    (project / package / "stats.py").write_text("def iqm(values):\n    raise RuntimeError('user iqm')\n")
    status, out, errors = run_command(["evaluate", "--help"], cwd=project, pythonpath=project)
    assert status == 0 and "--agent" in out and not errors
    status, out, errors = run_command(EVALUATE + ["--out", project / "eval"], cwd=project, pythonpath=project)
    assert status == 0 and not errors, errors
    assert "settle-time IQM" in out and (project / "eval" / "episodes.csv").exists()


# ---------------------------------------------------------------- environments


def one_line(error) -> str:
    message = str(error.value)
    assert "\n" not in message
    return message


@pytest.mark.parametrize("value", [0, -5, "x", 2.5, None, True])
def test_bad_episode_steps(value):
    with pytest.raises(ValueError, match=r"EnvConfig: episode_steps must be an integer >= 1, got ") as error:
        gymnasium.make("hyst_gym/Excitation-v0", episode_steps=value)
    assert repr(value) in one_line(error)


@pytest.mark.parametrize("action, expected", [
    (None, "action is None; expected an array of numbers of shape (1,)"),
    (np.array([np.nan], dtype=np.float32), "action contains nan"),
    (np.array([np.inf]), "action contains inf"),
    (np.array(["0.5"]), "action must be an array of numbers of shape (1,), got ndarray"),
    (np.array([0.5 + 0j]), "action must be an array of numbers of shape (1,)"),
    ({"field": 0.5}, "action must be an array of numbers of shape (1,), got dict"),
    (np.zeros((1, 1), dtype=np.float32), "action must have shape (1,), got shape (1, 1)"),
    (np.array([1.5], dtype=np.float32), "action value 1.5 is outside [-1, 1]"),
])
def test_bad_single_env_actions(action, expected):
    env = gymnasium.make("hyst_gym/Excitation-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError) as error:
        env.step(action)
    assert expected in one_line(error)


def test_bad_vector_env_actions():
    venv = gymnasium.make_vec("hyst_gym/Excitation-v0", num_envs=4, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    for actions, expected in ((np.zeros(4), "actions must have shape (4, 1), got shape (4,)"),
                              (np.zeros((4, 1), dtype=bool), "actions must be an array of numbers of shape (4, 1)"),
                              (None, "actions is None")):
        with pytest.raises(ValueError) as error:
            venv.step(actions)
        assert expected in one_line(error)


@pytest.mark.parametrize("kwargs, expected", [
    ({"dtt": 0.1}, "unknown EnvConfig field(s) ['dtt']"),
    ({"dt": "fast"}, "EnvConfig: dt must be a number, got 'fast'"),
    ({"field_limit": float("nan")}, "EnvConfig: field_limit must be finite, got nan"),
    ({"temperature_sensor": "yes"}, "EnvConfig: temperature_sensor must be True or False, got 'yes'"),
])
def test_bad_env_kwargs(kwargs, expected):
    with pytest.raises(ValueError) as error:
        gymnasium.make("hyst_gym/Excitation-v0", **kwargs)
    assert expected in one_line(error)


def test_reset_option_out_of_physical_range():
    env = gymnasium.make("hyst_gym/Identification-v0")
    with pytest.raises(ValueError) as error:
        env.reset(seed=0, options={"a_true": 1e9})
    assert one_line(error).startswith("reset option a_true = 1000000000.0 A/m is out of range")


# ---------------------------------------------------------------- first use


def test_compile_notice_is_printed_once_when_a_kernel_is_not_cached(capsys, tmp_path, monkeypatch):
    uncached = types.SimpleNamespace(_cache=types.SimpleNamespace(
        _cache_file=types.SimpleNamespace(_index_path=str(tmp_path / "kernel.nbi"))))
    monkeypatch.setattr(kernels, "_compile_notice_shown", False)
    assert not kernels.is_cached(uncached)
    kernels.announce_compilation([kernels.fill_info, uncached])
    kernels.announce_compilation([uncached])
    assert capsys.readouterr().err == kernels.COMPILE_NOTICE + "\n"
    assert kernels.is_cached(lambda: None)  # not a numba kernel: never announced
