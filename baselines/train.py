"""``hyst-gym train``: train a PPO or SAC (Stable-Baselines3) or RecurrentPPO (sb3-contrib,
LSTM policy) excitation policy.

Writes into ``--out``: ``model.zip`` and ``config.json`` beside it (every setting needed
to rebuild the run), ``checkpoints/`` (every ``--checkpoint-every`` steps), ``tb/``
(TensorBoard logs) and ``learning_curve.csv`` (the convergence metrics on a fixed
validation set, disjoint from the benchmark's held-out draws, against env steps; the last
row scores the saved model).
``--resume`` continues from the newest checkpoint in ``--out`` (else ``model.zip``), under
the settings the run was started with (a changed algorithm, history, reward or
hyperparameter is a one-line error), up to
``--timesteps``; SAC also saves and reloads its replay buffer (``replay_buffer.pkl``, at the
end of each session; checkpoints do not carry it).

History: PPO and SAC see ``--n-stack`` stacked frames (default 8); RecurrentPPO sees one
frame and keeps an LSTM state instead, so its ``--n-stack`` is 1 (the default for it).
"""

from __future__ import annotations

import copy
import csv
import inspect
import json
import pathlib
import re
import time

import numpy as np

from hyst_gym.envs.registration import ENV_IDS

from .environment import EpisodeSpec, make_sb3_vec_env
from .rl import ALGORITHMS, RECURRENT_ALGORITHMS, PolicyAgent, algorithm_class
from .scenarios import SCENARIOS, VALIDATION_SEEDS, scenario_spec

#: the names of :data:`baselines.rewards.REWARDS`, repeated here because that module needs
#: Stable-Baselines3 and ``hyst-gym train --help`` must work without the rl extra
#: (tests/baselines/test_cli.py checks that the two agree)
REWARD_NAMES = ("dense", "information", "band")

#: constructor arguments of the SB3 algorithms that train() sets itself (not hyperparameters)
SET_BY_TRAIN = frozenset({"self", "policy", "env", "seed", "device", "verbose", "tensorboard_log"})
#: constructor arguments of the SB3 policies that the algorithm sets (not policy_kwargs)
SET_BY_ALGORITHM = frozenset({"self", "observation_space", "action_space", "lr_schedule"})

#: Default hyperparameters (small networks: the observation is a short stacked vector).
DEFAULT_HYPERPARAMS = {
    "ppo": {"n_steps": 256, "batch_size": 256, "n_epochs": 10, "learning_rate": 3e-4, "gamma": 0.995,
            "gae_lambda": 0.95, "ent_coef": 0.0, "policy_kwargs": {"net_arch": [64, 64]}},
    # 8 gradient steps per env step (one step of 8 sub-envs is 8 transitions), after 2000
    # random steps: with SB3's 1 and 1000, no SAC seed settled on the validation draws within
    # 20k steps; with these SAC learns (sac_stack8 in experiments/RESULTS.md); not swept
    "sac": {"buffer_size": 100_000, "learning_starts": 2000, "batch_size": 256, "learning_rate": 3e-4,
            "gamma": 0.995, "train_freq": 1, "gradient_steps": 8, "policy_kwargs": {"net_arch": [64, 64]}},
    # as PPO, with one small LSTM (64 units) before the same heads; the rollout of
    # n_envs*n_steps steps is cut into sequences per sub-env, batch_size steps per minibatch
    "recurrent_ppo": {"n_steps": 256, "batch_size": 256, "n_epochs": 10, "learning_rate": 3e-4, "gamma": 0.995,
                      "gae_lambda": 0.95, "ent_coef": 0.0,
                      "policy_kwargs": {"lstm_hidden_size": 64, "n_lstm_layers": 1, "net_arch": [64, 64]}},
}

#: policy class name per algorithm
POLICIES = {"ppo": "MlpPolicy", "sac": "MlpPolicy", "recurrent_ppo": "MlpLstmPolicy"}

#: frames of history by default: a recurrent policy keeps its own history
DEFAULT_N_STACK = 8


def default_n_stack(algo) -> int:
    return 1 if algo in RECURRENT_ALGORITHMS else DEFAULT_N_STACK


def configure_parser(parser):
    parser.add_argument("--algo", choices=ALGORITHMS, required=True,
                        help="learning algorithm: PPO or SAC (Stable-Baselines3), or RecurrentPPO with an LSTM "
                             "policy (sb3-contrib)")
    parser.add_argument("--env", choices=sorted(ENV_IDS), default="hyst_gym/Excitation-v0",
                        help="environment id (default hyst_gym/Excitation-v0)")
    parser.add_argument("--scenario", choices=sorted(SCENARIOS), default="paper",
                        help="environment settings (default: the paper's case)")
    parser.add_argument("--timesteps", type=int, required=True, help="total environment steps (> 0)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the policy and of the environments (>= 0, "
                        "default 0)")
    parser.add_argument("--out", required=True, help="output folder (created if missing)")
    parser.add_argument("--n-envs", type=int, default=8, help="parallel sub-environments (default 8)")
    parser.add_argument("--n-stack", type=int, default=None,
                        help=f"frames of history the policy sees (1 = none; default {DEFAULT_N_STACK}, "
                             "and 1 for recurrent_ppo, which must be 1)")
    parser.add_argument("--reward", choices=REWARD_NAMES, default="dense",
                        help="training reward: the env's own dense error (default), the Fisher-information "
                             "increment (uses no truth), or -1 per step outside the settle band")
    parser.add_argument("--checkpoint-every", type=int, default=10_000,
                        help="env steps between checkpoints (0: none; default 10000)")
    parser.add_argument("--eval-every", type=int, default=0,
                        help="env steps between learning-curve points (0: only the final one when resuming "
                             "or never; default 0)")
    parser.add_argument("--eval-episodes", type=int, default=8,
                        help=f"validation episodes per learning-curve point (1..{len(VALIDATION_SEEDS)}, default 8)")
    parser.add_argument("--hyperparams", default="{}",
                        help='JSON object overriding the algorithm\'s hyperparameters, e.g. \'{"n_steps": 128}\'')
    parser.add_argument("--resume", action="store_true", help="continue from the newest checkpoint in --out")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _positive(name, value):
    if value <= 0:
        raise ValueError(f"--{name} must be > 0, got {value}")


def _nonnegative(name, value):
    if value < 0:
        raise ValueError(f"--{name} must be >= 0, got {value}")


def parse_hyperparams(text: str) -> dict:
    """The ``--hyperparams`` JSON object (a ``ValueError`` naming the flag otherwise)."""
    try:
        overrides = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"--hyperparams is not valid JSON: {error}") from None
    if not isinstance(overrides, dict):
        raise ValueError(f"--hyperparams must be a JSON object of name: value, got {type(overrides).__name__} "
                         f"{text.strip()[:40]!r}")
    return overrides


def check_hyperparams(algo: str, hyperparams: dict) -> None:
    """Raise a ``ValueError`` naming any hyperparameter (or ``policy_kwargs`` entry) that
    the algorithm's constructor (or its policy's) does not take, and the ones it takes.
    Imports the algorithm (Stable-Baselines3 / sb3-contrib)."""
    cls = algorithm_class(algo)
    accepted = sorted(name for name in inspect.signature(cls.__init__).parameters
                      if name not in SET_BY_TRAIN and not name.startswith("_"))
    unknown = sorted(set(hyperparams) - set(accepted))
    if unknown:
        raise ValueError(f"--hyperparams: unknown hyperparameter(s) {', '.join(unknown)} for {algo}; "
                         f"accepted: {', '.join(accepted)}")
    policy_kwargs = hyperparams.get("policy_kwargs")
    if policy_kwargs is None:
        return
    if not isinstance(policy_kwargs, dict):
        raise ValueError(f"--hyperparams: policy_kwargs must be a JSON object, got {policy_kwargs!r}")
    policy = cls.policy_aliases[POLICIES[algo]]
    accepted = sorted(name for name in inspect.signature(policy.__init__).parameters if name not in SET_BY_ALGORITHM)
    unknown = sorted(set(policy_kwargs) - set(accepted))
    if unknown:
        raise ValueError(f"--hyperparams: unknown policy_kwargs key(s) {', '.join(unknown)} for {algo}'s "
                         f"{POLICIES[algo]}; accepted: {', '.join(accepted)}")


def main(args) -> int:
    train(args.algo, scenario_spec(args.scenario, args.env), args.timesteps, args.seed, args.out,
          n_envs=args.n_envs, n_stack=args.n_stack, checkpoint_every=args.checkpoint_every,
          eval_every=args.eval_every, eval_episodes=args.eval_episodes, hyperparams=parse_hyperparams(args.hyperparams),
          resume=args.resume, progress=not args.no_progress, scenario=args.scenario, reward=args.reward)
    return 0


def _new_model(cls, algo, env, seed, out, params, overrides):
    """The algorithm, built with ``params``. Its constructor checks the values (SB3 asserts, e.g.,
    ``n_steps * n_envs > 1``): a value that ``--hyperparams`` set and the constructor rejects is a
    one-line ``ValueError`` naming the flag; with the defaults alone, a failure is a bug and propagates."""
    try:
        return cls(POLICIES[algo], env, seed=int(seed), device="cpu", verbose=0,
                   tensorboard_log=str(out / "tb"), **copy.deepcopy(params))
    except (AssertionError, ValueError, TypeError) as error:
        env.close()
        if not overrides:
            raise
        reason = " ".join(str(error).split()) or type(error).__name__
        raise ValueError(f"--hyperparams {json.dumps(overrides)} rejected by {algo}: {reason}") from None


def _latest_checkpoint(out: pathlib.Path):
    found = []
    for path in (out / "checkpoints").glob("model_*_steps.zip"):
        match = re.search(r"model_(\d+)_steps\.zip$", path.name)
        if match:
            found.append((int(match.group(1)), path))
    return max(found)[1] if found else None


class _Callbacks:
    """Progress bar, learning curve and checkpoints as one SB3 callback (built lazily)."""

    @staticmethod
    def build(total, out, spec, n_stack, eval_every, eval_episodes, checkpoint_every, n_envs, progress, start,
              wall_start):
        from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback
        from tqdm.auto import tqdm

        class Progress(BaseCallback):
            def _on_training_start(self):
                self.bar = tqdm(total=total, initial=self.model.num_timesteps, unit="step", disable=not progress,
                                desc="train")

            def _on_step(self):
                self.bar.n = self.model.num_timesteps
                self.bar.refresh() if self.n_calls % 50 == 0 else None
                return True

            def _on_training_end(self):
                self.bar.n = self.model.num_timesteps
                self.bar.close()

        class LearningCurve(BaseCallback):
            def __init__(self):
                super().__init__()
                self.next_at = start + eval_every if eval_every else None

            def _on_step(self):
                if self.next_at is not None and self.model.num_timesteps >= self.next_at:
                    self.next_at += eval_every
                    record_learning_point(self.model, out, spec, n_stack, eval_episodes, wall_start)
                return True

        callbacks = [Progress(), LearningCurve()]
        if checkpoint_every > 0:
            callbacks.append(CheckpointCallback(max(checkpoint_every // n_envs, 1), str(out / "checkpoints"),
                                                name_prefix="model"))
        return CallbackList(callbacks)


def record_learning_point(model, out, spec, n_stack, episodes, wall_start=None):
    """Append one learning-curve row (validation IQM of the convergence metrics)."""
    from baselines.stats import iqm
    from baselines.survival import censor

    from .evaluation import run_episodes

    records, _ = run_episodes(PolicyAgent(model, n_stack), spec, VALIDATION_SEEDS[:episodes])
    settle, _ = censor([r["settle_time_s"] for r in records], max(r["episode_time_s"] for r in records))
    wall_s = None if wall_start is None else round(time.time() - wall_start, 2)
    row = {"env_steps": int(model.num_timesteps), "wall_s": wall_s,
           "settle_time_iqm_s": iqm(settle), "rms_error_iqm": iqm([r["rms_error"] for r in records]),
           "success_rate": float(np.mean([np.isfinite(r["settle_time_s"]) for r in records]))}
    path = out / "learning_curve.csv"
    new = not path.exists()
    with path.open("a", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(row))
        if new:
            writer.writeheader()
        writer.writerow(row)
    return row


def changed_settings(out, algo, n_stack, reward, hyperparams) -> list:
    """Names of the settings that differ from the run saved in ``out/config.json`` (empty if
    none, or if there is no saved run): a run is only continued under its own settings."""
    path = pathlib.Path(out) / "config.json"
    if not path.exists():
        return []
    saved = json.loads(path.read_text())
    now = {"algo": algo, "n_stack": int(n_stack), "reward": reward,
           "hyperparams": json.loads(json.dumps(hyperparams))}  # as JSON stores it (tuples -> lists)
    defaults = {"reward": "dense"}  # runs saved before the reward was recorded used the dense one
    return [key for key, value in now.items() if saved.get(key, defaults.get(key)) != value]


def _drop_curve_rows_at(out: pathlib.Path, env_steps: int):
    path = out / "learning_curve.csv"
    if not path.exists():
        return
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    kept = [r for r in rows if int(r["env_steps"]) != env_steps]
    if len(kept) != len(rows):
        with path.open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(kept)


def _last_curve_steps(out: pathlib.Path):
    path = out / "learning_curve.csv"
    if not path.exists():
        return None
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    return int(rows[-1]["env_steps"]) if rows else None


def _check_settings(algo, spec, timesteps, seed, n_envs, n_stack, checkpoint_every, eval_every, eval_episodes,
                    hyperparams, reward) -> None:
    """A ``ValueError`` naming the flag of the first bad setting of :func:`train`."""
    if algo not in ALGORITHMS:
        raise ValueError(f"--algo must be one of {ALGORITHMS}, got {algo!r}")
    if spec.env_id not in ENV_IDS:
        raise ValueError(f"--env {spec.env_id!r} is not a hyst-gym environment; expected one of {sorted(ENV_IDS)}")
    if reward not in REWARD_NAMES:
        raise ValueError(f"--reward must be one of {REWARD_NAMES}, got {reward!r}")
    for name, value in (("timesteps", timesteps), ("n-envs", n_envs), ("n-stack", n_stack)):
        _positive(name, value)
    for name, value in (("seed", seed), ("checkpoint-every", checkpoint_every), ("eval-every", eval_every)):
        _nonnegative(name, value)
    if not 1 <= eval_episodes <= len(VALIDATION_SEEDS):
        raise ValueError(f"--eval-episodes must be in 1..{len(VALIDATION_SEEDS)} (the validation set has "
                         f"{len(VALIDATION_SEEDS)} draws), got {eval_episodes}")
    if algo in RECURRENT_ALGORITHMS and n_stack != 1:
        raise ValueError(f"--n-stack must be 1 for {algo} (the LSTM keeps the history), got {n_stack}")
    check_hyperparams(algo, hyperparams or {})


def train(algo, spec: EpisodeSpec, timesteps, seed, out, n_envs=8, n_stack=None, checkpoint_every=10_000,
          eval_every=0, eval_episodes=8, hyperparams=None, resume=False, progress=True, scenario=None,
          reward="dense"):
    """Train and save; returns the path of ``model.zip``. See the module docstring.

    ``n_stack`` None means :func:`default_n_stack` (8 frames; 1 for a recurrent policy);
    ``reward`` names the training reward (:data:`baselines.rewards.REWARDS`). The learning
    curve always scores the benchmark's metrics, whatever the reward."""
    # every setting is checked before anything is written: a bad one leaves no output folder
    n_stack = default_n_stack(algo) if n_stack is None else n_stack
    _check_settings(algo, spec, timesteps, seed, n_envs, n_stack, checkpoint_every, eval_every, eval_episodes,
                    hyperparams, reward)
    out = pathlib.Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} exists and is not a folder")

    import torch

    torch.set_num_threads(1)
    wall_start = time.time()  # learning-curve rows report wall time since this call
    # deep copies: SB3 writes into policy_kwargs (SAC adds use_sde), which must reach neither
    # the module's defaults nor the recorded config
    params = copy.deepcopy({**DEFAULT_HYPERPARAMS[algo], **(hyperparams or {})})
    config = {"algo": algo, "policy": POLICIES[algo], "env_id": spec.env_id, "env_kwargs": spec.env_kwargs,
              "dt": spec.dt, "scenario": scenario, "reward": reward, "timesteps": int(timesteps), "seed": int(seed),
              "n_envs": int(n_envs), "n_stack": int(n_stack), "hyperparams": params,
              "checkpoint_every": int(checkpoint_every), "eval_every": int(eval_every),
              "eval_episodes": int(eval_episodes)}
    checkpoint = _latest_checkpoint(out) if resume else None
    if resume and checkpoint is None and (out / "model.zip").exists():
        checkpoint = out / "model.zip"
    if checkpoint is not None:
        changed = changed_settings(out, algo, n_stack, reward, params)
        if changed:
            raise ValueError(f"{out / 'config.json'}: --resume under other settings ({', '.join(changed)}) than the "
                             "run was started with; use another --out, or drop --resume to start afresh")
    env = make_sb3_vec_env(spec, n_envs, seed, n_stack, reward=reward)
    cls = algorithm_class(algo)
    if checkpoint is not None:
        model = cls.load(checkpoint, env=env, device="cpu", tensorboard_log=str(out / "tb"))
        if algo == "sac" and (out / "replay_buffer.pkl").exists():
            model.load_replay_buffer(out / "replay_buffer.pkl")  # off-policy: keep the experience
        print(f"[train] resuming from {checkpoint} at {model.num_timesteps} steps")
    else:
        if resume:
            print(f"[train] --resume: no checkpoint in {out}, starting fresh")
        model = _new_model(cls, algo, env, seed, out, params, hyperparams or {})
    # the model is built (its constructor checks the hyperparameters' values): now write
    out.mkdir(parents=True, exist_ok=True)
    if checkpoint is None:
        (out / "learning_curve.csv").unlink(missing_ok=True)  # a fresh run: no rows of an earlier one
    (out / "config.json").write_text(json.dumps(config, indent=2))
    remaining = int(timesteps) - int(model.num_timesteps)
    start_wall = time.time()
    if remaining > 0:
        callback = _Callbacks.build(int(timesteps), out, spec, n_stack, eval_every, eval_episodes,
                                    checkpoint_every, n_envs, progress, int(model.num_timesteps), wall_start)
        model.learn(remaining, callback=callback, reset_num_timesteps=checkpoint is None,
                    tb_log_name=f"{algo}_seed{seed}")
    if eval_every and (remaining > 0 or _last_curve_steps(out) != int(model.num_timesteps)):
        # periodic points are taken inside a rollout (PPO) or before the gradient steps (SAC),
        # so a point at the final step count may predate the last update: score the saved model
        _drop_curve_rows_at(out, int(model.num_timesteps))
        record_learning_point(model, out, spec, n_stack, eval_episodes, wall_start)
    model.save(out / "model.zip")
    if algo == "sac":
        model.save_replay_buffer(out / "replay_buffer.pkl")
    env.close()
    config["trained_steps"] = int(model.num_timesteps)
    config["wall_s_last_session"] = round(time.time() - start_wall, 2)
    (out / "config.json").write_text(json.dumps(config, indent=2))
    print(f"[train] {algo} seed {seed}: {model.num_timesteps} steps, saved {out / 'model.zip'}")
    return out / "model.zip"


__all__ = ["DEFAULT_HYPERPARAMS", "POLICIES", "DEFAULT_N_STACK", "REWARD_NAMES", "default_n_stack", "configure_parser",
           "main", "parse_hyperparams", "check_hyperparams", "train", "record_learning_point", "changed_settings"]
