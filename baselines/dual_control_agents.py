"""Agents of the dual-control task (``hyst_gym/DualControl-v0``): the agent's action is a probe field added
to the inverse-compensation controller's command, so "no probe" is the certainty-equivalence controller.

* :class:`ProbeBurst` (open loop): a square wave of ``amplitude`` (fraction of the field limit), ``half_period``
  steps per half wave, for the first ``steps`` steps of the episode, then no probe. Amplitude 0: no probe.
* :class:`ProbeWhileUnsure` (feedback): the same square wave while the estimator's spread (the observation's
  ``estimate_spread``, std of a / width(Theta)) is above ``threshold``, no probe once it is below.
"""

from __future__ import annotations

import numpy as np

from .agents import Agent


def _square_wave(count: np.ndarray, half_period: int) -> np.ndarray:
    """+1, -1 alternating every ``half_period`` steps of ``count`` (steps since the episode start)."""
    return np.where((count // half_period) % 2 == 0, 1.0, -1.0)


class _SquareWaveProbe(Agent):
    """The square-wave probe of ``amplitude``, ``half_period`` steps per half wave, counted from each sub-env's
    episode start, where :meth:`_probing` says so (subclasses)."""

    def __init__(self, amplitude: float, half_period: int, name: str):
        super().__init__()
        if not 0.0 <= amplitude <= 1.0 or half_period < 1:
            raise ValueError(f"{type(self).__name__}: amplitude must be in [0, 1] and half_period >= 1, got "
                             f"{amplitude!r}, {half_period!r}")
        self.amplitude, self.half_period, self.name = float(amplitude), int(half_period), name
        self.reads_truth = False
        self._count = np.zeros(0, dtype=np.int64)

    def reset(self, seed=None):
        super().reset(seed)
        self._count = np.zeros(0, dtype=np.int64)

    def _probing(self, observations) -> np.ndarray:
        raise NotImplementedError  # pragma: no cover

    def act_batch(self, observations, episode_start):
        n = observations.shape[0]
        if self._count.shape[0] != n:
            self._count = np.zeros(n, dtype=np.int64)
        self._count[np.asarray(episode_start, dtype=bool)] = 0
        wave = self.amplitude * _square_wave(self._count, self.half_period)
        probe = np.where(self._probing(observations), wave, 0.0)
        self._count += 1
        return probe[:, None].astype(np.float32)


class ProbeBurst(_SquareWaveProbe):
    """The open-loop probe burst (module doc)."""

    def __init__(self, amplitude: float, steps: int, half_period: int = 2, name: str | None = None):
        if steps < 0:
            raise ValueError(f"ProbeBurst: steps must be >= 0, got {steps!r}")
        super().__init__(amplitude, half_period,
                         name or ("no_probe" if amplitude == 0 or steps == 0 else f"probe_{amplitude:g}x{steps}"))
        self.steps = int(steps)

    def _probing(self, observations):
        return self._count < self.steps


class ProbeWhileUnsure(_SquareWaveProbe):
    """The feedback probe rule (module doc); ``spread_index``: the observation column of the spread."""

    def __init__(self, spread_index: int, threshold: float, amplitude: float, half_period: int = 2,
                 name: str | None = None):
        if not threshold >= 0.0:
            raise ValueError(f"ProbeWhileUnsure: threshold must be >= 0, got {threshold!r}")
        super().__init__(amplitude, half_period, name or f"probe_while_unsure_{amplitude:g}_{threshold:g}")
        self.spread_index, self.threshold = int(spread_index), float(threshold)

    def _probing(self, observations):
        return observations[:, self.spread_index] > self.threshold


__all__ = ["ProbeBurst", "ProbeWhileUnsure"]
