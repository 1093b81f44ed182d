"""Agents of the discriminate task (``hyst_gym/Discriminate-v0``): the agent designs the field that tells three
explanations of a recording apart.

* :func:`triangle` (open loop, a :class:`FieldSequence`): a triangle wave of ``amplitude`` (fraction of the field
  limit) about ``bias``, period ``period_s``, through the slew limit; :func:`replay_recording` plays the
  recording's own drive.
* :class:`GreedySeparation` (feedback, model-based): keeps its own copies of the three candidate models (the
  env's :class:`~hyst_gym.envs.discriminate.Candidates`, which the task publishes; never the truth), driven by the
  field it applies and the measured temperature, and each step picks, among a few field moves within the slew
  limit, the one whose predicted outputs differ most between the candidates, weighted by the posterior
  (``sum over pairs p_i p_j (M_i - M_j)^2``); it only raises |H| while the coil, braked from there at the slew
  limit, would stay ``margin`` K below the temperature limit.
* :class:`ClairvoyantSeparation` (reads the truth: a check of the information bound, not a benchmark agent): the
  greedy rule weighing only the truth's pairs, each by the alternative's posterior.
"""

from __future__ import annotations

import numpy as np

from hyst_gym.physics.thermal import mean_square_linear, temperature_step

from .agents import Agent

#: the field moves the greedy rule weighs, in slew-limit steps
MOVES = (1.0, 0.5, 0.0, -0.5, -1.0)  # relative to the last move's direction: ties keep going


def _slewed(target: np.ndarray, field: np.ndarray, config) -> np.ndarray:
    change = config.max_field_change
    return np.clip(np.clip(target, field - change, field + change), -config.field_limit, config.field_limit)


class FieldSequence(Agent):
    """Open loop: the normalized field ``values[t]`` at step t of each episode (the last one after the end)."""

    def __init__(self, values, name: str):
        super().__init__()
        self._field = np.asarray(values, dtype=np.float64)
        self.name = name
        self.reads_truth = False
        self._count = np.zeros(0, dtype=np.int64)

    def reset(self, seed=None):
        super().reset(seed)
        self._count = np.zeros(0, dtype=np.int64)

    def act_batch(self, observations, episode_start):
        n = observations.shape[0]
        if self._count.shape[0] != n:
            self._count = np.zeros(n, dtype=np.int64)
        self._count[np.asarray(episode_start, dtype=bool)] = 0
        action = self._field[np.minimum(self._count, self._field.shape[0] - 1)]
        self._count += 1
        return action[:, None].astype(np.float32)


def triangle(config, amplitude: float, period_s: float, bias: float = 0.0) -> FieldSequence:
    """The open-loop triangle (module doc): from ``bias`` up to ``bias + amplitude``, down to ``bias - amplitude``
    and back, each period, through the slew limit (fractions of the field limit)."""
    if not 0.0 <= amplitude <= 1.0 or not period_s > 0 or not -1.0 <= bias <= 1.0:
        raise ValueError(f"triangle: amplitude in [0, 1], period_s > 0, bias in [-1, 1], got {amplitude!r}, "
                         f"{period_s!r}, {bias!r}")
    phase = (np.arange(1, config.episode_steps + 1) * config.dt / period_s) % 1.0
    wave = np.where(phase < 0.25, 4 * phase, np.where(phase < 0.75, 2 - 4 * phase, 4 * phase - 4))
    field, values = np.zeros(1), np.empty(phase.shape[0])
    for i, target in enumerate((bias + amplitude * wave) * config.field_limit):
        field = _slewed(np.array([target]), field, config)
        values[i] = field[0] / config.field_limit
    return FieldSequence(values, f"triangle_{amplitude:g}_{period_s:g}_{bias:g}")


def replay_recording(config) -> FieldSequence:
    """The recording's own drive (:func:`hyst_gym.envs.discriminate.recording_drive`)."""
    from hyst_gym.envs.discriminate import recording_drive

    return FieldSequence(recording_drive(config.episode_steps) / config.field_limit, "replay_recording")


class GreedySeparation(Agent):
    """The greedy model-based separation rule (module doc). ``env``: the task's vector env (for its published
    candidates and observation layout; the rule reads only observations)."""

    def __init__(self, env, margin: float = 2.0, name: str | None = None):
        super().__init__()
        from hyst_gym.envs.discriminate import advance_candidates, candidate_a

        self.config = env.config
        self.margin = float(margin)
        self.name = name or f"greedy_separation_{margin:g}"
        self.reads_truth = False
        self._advance = advance_candidates
        self._candidate_a = candidate_a
        self._models = env.models  # the candidates' models the task publishes
        names = env.observation_names
        self._temperature = names.index("temperature")
        self._posterior = [names.index(name) for name in names if name.startswith("p_")]
        thermal = self.config.thermal
        self._decay = np.exp(-self.config.dt / thermal.time_constant)
        self._gain = thermal.thermal_resistance * thermal.power_per_square_field
        self._field = np.zeros(0)
        self._m = np.zeros((0, 3))
        self._direction = np.zeros(0)

    def reset(self, seed=None):
        super().reset(seed)
        self._field = np.zeros(0)

    def _temperature_of(self, observations) -> np.ndarray:
        from hyst_gym.envs.core import TEMPERATURE_SCALE

        return self.config.thermal.reference_temperature + TEMPERATURE_SCALE * observations[:, self._temperature]

    def _braked_peak(self, temperature, field) -> np.ndarray:
        """The highest temperature (K) if the field slews from ``field`` down to 0 now, from ``temperature``
        with the ambient at the start temperature taken as ``temperature`` (the coil cools towards it no
        faster than this assumes, so the estimate errs on the hot side)."""
        config = self.config
        peak, h, t = temperature.copy(), np.abs(field), temperature.copy()
        while np.any(h > 0):
            nxt = np.maximum(h - config.max_field_change, 0.0)
            offset = self._gain * mean_square_linear(h, nxt)
            t = temperature_step(t, temperature, temperature, offset, self._decay)
            peak = np.maximum(peak, t)
            h = nxt
        return peak

    def _pair_weights(self, posterior) -> dict:
        """The weight of each pair's squared output gap: the product of their posteriors."""
        return {(i, j): posterior[:, i] * posterior[:, j] for i in range(3) for j in range(i + 1, 3)}

    def act_batch(self, observations, episode_start):
        config = self.config
        n = observations.shape[0]
        start = np.asarray(episode_start, dtype=bool)
        if self._field.shape[0] != n:
            self._field, self._m, self._direction = np.zeros(n), np.zeros((n, 3)), np.ones(n)
            start = np.ones(n, dtype=bool)
        self._field[start], self._m[start], self._direction[start] = 0.0, 0.0, 1.0
        temperature = self._temperature_of(observations)
        a = self._candidate_a(self._models, temperature, config.thermal)
        posterior = observations[:, self._posterior].astype(np.float64)
        best_score, best_field = np.full(n, -np.inf), self._field.copy()
        for move in MOVES:
            target = _slewed(self._field + self._direction * move * config.max_field_change, self._field, config)
            rising = np.abs(target) > np.abs(self._field)
            hot = self._braked_peak(temperature, target) >= config.temperature_limit - self.margin
            models = self._m.copy()
            self._advance(models, self._field, target, a, self._models)
            m = models / config.hysteresis.Ms
            weights = self._pair_weights(posterior)
            score = sum(weights[(i, j)] * (m[:, i] - m[:, j]) ** 2 for i in range(3) for j in range(i + 1, 3))
            score = np.where(rising & hot, -np.inf, score)
            better = score > best_score + 1e-15
            best_score, best_field = np.where(better, score, best_score), np.where(better, target, best_field)
        self._advance(self._m, self._field, best_field, a, self._models)
        moved = best_field - self._field
        self._direction = np.where(moved != 0, np.sign(moved), self._direction)
        self._field = best_field
        return (best_field / config.field_limit)[:, None].astype(np.float32)


class ClairvoyantSeparation(GreedySeparation):
    """:class:`GreedySeparation` that reads the truth (not an admissible agent of the benchmark: a check of the
    information bound, which holds for policies that know the truth too): it weighs only the truth's pairs, each
    by the alternative's posterior, the terms of the truth's posterior. ``truth_of``: a callable returning the
    truth per sub-env (e.g. ``lambda: env.truth``), settable after construction."""

    def __init__(self, env, truth_of, margin: float = 1.0, name: str | None = None):
        super().__init__(env, margin, name or f"clairvoyant_separation_{margin:g}")
        self.reads_truth = True
        self.truth_of = truth_of

    def _pair_weights(self, posterior) -> dict:
        truth = np.asarray(self.truth_of())
        return {(i, j): np.where(truth == i, posterior[:, j], np.where(truth == j, posterior[:, i], 0.0))
                for i in range(3) for j in range(i + 1, 3)}


__all__ = ["ClairvoyantSeparation", "FieldSequence", "GreedySeparation", "replay_recording", "triangle"]
