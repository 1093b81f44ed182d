"""RL excitation policies (PPO, SAC from Stable-Baselines3; RecurrentPPO from sb3-contrib)
behind the common agent interface.

History: hysteresis is not Markov in (H, y), so the policy needs the past. Two ways are
offered, to be compared by the benchmark:

* frame stacking (``ppo``, ``sac``): the policy sees the last ``n_stack`` observations
  (SB3's ``VecFrameStack``: zeros after a reset, newest frame last). :class:`PolicyAgent`
  rebuilds exactly that stack from raw observations;
* a recurrent policy (``recurrent_ppo``: sb3-contrib's RecurrentPPO with an LSTM): the
  policy sees one raw observation per step (``n_stack`` is 1) and carries an LSTM state.
  :class:`PolicyAgent` keeps that state per sub-environment and zeroes it where an
  episode starts, as RecurrentPPO does in training.

Either way a trained model is evaluated through the same interface and on the same envs
as every baseline.
"""

from __future__ import annotations

import json
import pathlib
import zipfile

import numpy as np

from .agents import Agent

ALGORITHMS = ("ppo", "sac", "recurrent_ppo")

#: algorithms whose policy carries a recurrent state (and therefore sees no frame stack)
RECURRENT_ALGORITHMS = ("recurrent_ppo",)


def algorithm_class(algo: str):
    algo = str(algo).lower()
    if algo not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algo!r}; expected one of {ALGORITHMS}")
    if algo == "recurrent_ppo":
        from sb3_contrib import RecurrentPPO  # imported only when asked: an optional part of the rl extra

        return RecurrentPPO
    from stable_baselines3 import PPO, SAC

    return {"ppo": PPO, "sac": SAC}[algo]


def is_recurrent(model) -> bool:
    """Whether ``model``'s policy carries an LSTM state (sb3-contrib's recurrent policies)."""
    return getattr(model.policy, "lstm_hidden_state_shape", None) is not None


class PolicyAgent(Agent):
    """A trained SB3 / sb3-contrib model playing on raw (unstacked) observations.

    Feed-forward models see a rebuilt frame stack of ``n_stack`` observations; recurrent
    models (``n_stack`` must be 1) see the raw observation and an LSTM state kept per
    sub-environment, zeroed by ``episode_start`` (that sub-environment only) and by
    :meth:`reset` (all of them).
    """

    def __init__(self, model, n_stack: int = 1, deterministic: bool = True, name: str = "policy",
                 trained_on: str | None = None):
        super().__init__()
        self.model, self.n_stack, self.deterministic, self.name = model, int(n_stack), deterministic, name
        #: where the policy was trained ("env id (scenario)"), for error messages; None if unknown
        self.trained_on = trained_on
        self.recurrent = is_recurrent(model)
        if self.n_stack < 1:
            raise ValueError(f"n_stack must be >= 1, got {n_stack}")
        if self.recurrent and self.n_stack != 1:
            raise ValueError(f"n_stack must be 1 for a recurrent policy (it keeps its own history), got {n_stack}")
        self._stack = None
        self._lstm_state = None  # (hidden, cell), each (n_layers, n_envs, hidden_size), or None: zeros

    @classmethod
    def load(cls, path, name=None, device="cpu"):
        """Load ``model.zip`` (or a folder holding it) and its ``config.json`` (for ``n_stack``)."""
        path = pathlib.Path(path)
        model_path = path / "model.zip" if path.is_dir() else path
        if not model_path.exists():
            raise OSError(f"no trained model at {model_path}")
        if not zipfile.is_zipfile(model_path):
            raise ValueError(f"{model_path}: not a saved Stable-Baselines3 model (not a zip file)")
        config_path = model_path.parent / "config.json"
        try:
            config = json.loads(config_path.read_text()) if config_path.exists() else {}
        except json.JSONDecodeError as error:
            raise ValueError(f"{config_path}: not valid JSON ({error})") from None
        if not isinstance(config, dict):
            raise ValueError(f"{config_path}: must hold a JSON object, got {type(config).__name__}")
        guessed = next((a for a in ("recurrent_ppo", "sac") if a in model_path.name.lower()), "ppo")
        algo = config.get("algo") or guessed
        model = algorithm_class(algo).load(model_path, device=device)
        trained_on = config.get("env_id") and (f"{config['env_id']} ({config['scenario']})" if config.get("scenario")
                                               else config["env_id"])
        return cls(model, config.get("n_stack", 1), name=name or algo, trained_on=trained_on)

    def check_env(self, env: str, observation_size: int, action_size: int) -> None:
        """Raise a one-line ``ValueError`` if this policy cannot play ``env`` (a label such
        as "env id (scenario)"), whose observations have ``observation_size`` entries and
        actions ``action_size``: the policy's input is ``n_stack`` such observations, its
        output one such action."""
        policy_input = int(np.prod(self.model.observation_space.shape))
        policy_output = int(np.prod(self.model.action_space.shape))
        if policy_input == self.n_stack * observation_size and policy_output == action_size:
            return
        frames = f"{self.n_stack} frames of {policy_input / self.n_stack:g}" if self.n_stack > 1 else "one frame"
        raise ValueError(f"policy {self.name!r} was trained on {self.trained_on or 'another environment'} with "
                         f"observations of {policy_input} entries ({frames}) and actions of {policy_output}, but "
                         f"{env} has observations of {observation_size} entries and actions of {action_size}")

    def reset(self, seed=None):
        super().reset(seed)
        self._stack = None
        self._lstm_state = None

    def act_batch(self, observations, episode_start):
        observations = np.asarray(observations, dtype=np.float32)
        n, size = observations.shape
        if self.recurrent:
            return self._act_recurrent(observations, np.asarray(episode_start, dtype=bool).reshape(n))
        if self._stack is None or self._stack.shape[0] != n:
            self._stack = np.zeros((n, size * self.n_stack), dtype=np.float32)
        self._stack[np.asarray(episode_start, dtype=bool)] = 0.0
        self._stack = np.roll(self._stack, -size, axis=1)
        self._stack[:, -size:] = observations
        actions, _ = self.model.predict(self._stack, deterministic=self.deterministic)
        return np.asarray(actions, dtype=np.float32).reshape(n, -1)

    def _act_recurrent(self, observations, episode_start):
        n = observations.shape[0]
        if self._lstm_state is None or self._lstm_state[0].shape[1] != n:
            # a new batch of sub-envs: every one starts from the zero state
            self._lstm_state, episode_start = None, np.ones(n, dtype=bool)
        # the policy zeroes the state of the sub-envs flagged in episode_start before this step
        actions, self._lstm_state = self.model.predict(observations, state=self._lstm_state,
                                                       episode_start=episode_start,
                                                       deterministic=self.deterministic)
        return np.asarray(actions, dtype=np.float32).reshape(n, -1)


__all__ = ["ALGORITHMS", "RECURRENT_ALGORITHMS", "algorithm_class", "is_recurrent", "PolicyAgent"]
