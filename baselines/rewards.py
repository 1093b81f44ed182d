"""Alternative training rewards for the excitation policy (the reward-form ablation).

The environment's own reward (``Excitation-v0``) is the *dense error* reward
``-|a_estimate - a_true| / width(Theta)`` per step: it needs the truth ``a_true``, which a
simulator has but a real rig does not. :class:`InformationRewardVecEnv` replaces it by an
*information increment* about a that uses no truth at all; :class:`BandRewardVecEnv` by the
benchmark's own metric, time outside the settle band (truth needed, like the dense reward).

Band reward
-----------
``r_t = -1`` while ``|a_estimate - a_true| > band_fraction*a_true`` (default 0.1 %, the
settle band of the benchmark), else 0. The undiscounted return is minus the number of
steps spent outside the band, a lower bound on (minus) the settle time in steps that
equals it when the estimate enters the band once and stays: the reward is the metric.

Information increment
---------------------
With additive white noise of standard deviation ``sigma`` (A/m, referred to M) on each
sample of ``f(u, a) = M(H; a)`` (paper (22): the estimator's model output), the Fisher
information about a accumulated over an episode is ``I = sum_t s_t**2 / sigma**2``
(1/(A/m)**2), where ``s_t = df/da(u_t, a)`` (dimensionless, A/m per A/m). The per-step
reward is the increment of I, evaluated at the *estimate* (the truth is unknown) and
normalized to order 1::

    r_t = (s_t / slope_scale)**2,   s_t = df/da(u_t, a_estimate_t)

``s_t`` is the built-in min-max estimator's ``model_slope`` (its bank interpolant of
df/dtheta at thetahat, :class:`hyst_gym.estimation.MinMaxEstimator`). ``sigma`` is fixed in
a scenario, so dividing by ``sigma**2`` and by the reference increment
``slope_scale**2/sigma**2`` leaves ``r_t`` as above: ``sigma`` cancels. ``slope_scale``
(default 10, dimensionless) is about the largest |df/da| on a full-range +-100 kA/m sweep in
the paper scenario (measured 9.5 at |H| ~ 75 kA/m), so r_t lies in about [0, 1].

Why: an input that maximizes the information about a is the classical optimal-design
objective (``baselines.information``, ``baselines.optimal_design``); rewarding its
increment lets a policy learn excitation without the truth, i.e. a signal that could be
used on hardware.

Approximations, stated plainly:

* the sensitivity is that of M, not of the measured y: the first-order plant
  (lambda = 100 1/s, dt = 0.01 s) follows M within about a step, so this is the
  quasi-static information; the lumped plants' dynamics are ignored;
* it is evaluated at a_estimate, not a_true (the local Fisher information at the
  current estimate, as in a sequential design);
* SB3 vector envs reset a finished sub-env within the same step, so the reward of an
  episode's last step is read from the fresh episode's first state (|s| ~ 0 at H ~ 0):
  one step in ``episode_steps``;
* a static field away from zero keeps earning information (each new noisy sample of a
  non-zero ``s_t`` is informative), so this reward does not by itself ask for the motion
  that the min-max estimator's persistent-excitation conditions 3.1 need. That is part of
  what the ablation tests.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env import VecEnvWrapper

#: default normalizing slope, dimensionless (A/m per A/m); see the module docstring
DEFAULT_SLOPE_SCALE = 10.0


def information_increment(model_slope, slope_scale: float = DEFAULT_SLOPE_SCALE) -> np.ndarray:
    """Per-step reward ``(model_slope/slope_scale)**2`` (dimensionless, >= 0)."""
    if not slope_scale > 0:
        raise ValueError(f"slope_scale must be > 0, got {slope_scale}")
    slope = np.asarray(model_slope, dtype=np.float64)
    return (slope / slope_scale) ** 2


def _simulator(venv):
    """The native batch simulator under an SB3 adapter (``hyst_gym.envs.sb3``)."""
    inner = getattr(venv, "venv", None)
    sim = getattr(getattr(inner, "unwrapped", inner), "sim", None)
    if sim is None or getattr(sim, "estimator", None) is None or not hasattr(sim.estimator, "model_slope"):
        raise ValueError("InformationRewardVecEnv needs hyst-gym's SB3 adapter over a native vector env with a "
                         "built-in estimator (Excitation-v0, first-order or lumped plant)")
    return sim


class InformationRewardVecEnv(VecEnvWrapper):
    """SB3 ``VecEnv`` wrapper: the reward becomes the information increment about a.

    Wrap the :class:`hyst_gym.envs.sb3.SB3VecEnvAdapter` directly (below ``VecMonitor``
    and ``VecFrameStack``, so that the logged returns are the rewards trained on).
    Observations, dones and infos are unchanged; the original reward is kept in
    ``infos[i]["dense_reward"]`` for diagnostics. Uses no truth (see the module docstring).
    """

    def __init__(self, venv, slope_scale: float = DEFAULT_SLOPE_SCALE):
        super().__init__(venv)
        information_increment(0.0, slope_scale)  # validates slope_scale
        self.slope_scale = float(slope_scale)
        self._sim = _simulator(venv)

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        observations, dense, dones, infos = self.venv.step_wait()
        rewards = information_increment(self._sim.estimator.model_slope, self.slope_scale).astype(np.float32)
        for info, value in zip(infos, dense):
            info["dense_reward"] = float(value)
        return observations, rewards, dones, infos


class BandRewardVecEnv(VecEnvWrapper):
    """SB3 ``VecEnv`` wrapper: the reward becomes ``-1`` per step outside the settle band.

    Placed like :class:`InformationRewardVecEnv` (directly on the adapter). Reads
    ``a_estimate`` and ``a_true`` from the native simulator after the step; as with the
    information reward, the last step of an episode is read from the fresh episode that
    SB3's same-step reset has already started (one step in ``episode_steps``).
    """

    def __init__(self, venv, band_fraction: float = 1e-3):
        super().__init__(venv)
        if not 0 < band_fraction < 1:
            raise ValueError(f"band_fraction must be in (0, 1), got {band_fraction}")
        self.band_fraction = float(band_fraction)
        self._sim = _simulator(venv)

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        observations, dense, dones, infos = self.venv.step_wait()
        outside = np.abs(self._sim.a_estimate - self._sim.a_true) > self.band_fraction * self._sim.a_true
        for info, value in zip(infos, dense):
            info["dense_reward"] = float(value)
        return observations, -outside.astype(np.float32), dones, infos


#: training rewards by name; "dense" is the environment's own
REWARDS = ("dense", "information", "band")


def reward_wrapper(name: str):
    """The ``VecEnv`` wrapper class of reward ``name`` (``None`` for the env's own dense reward)."""
    wrappers = {"dense": None, "information": InformationRewardVecEnv, "band": BandRewardVecEnv}
    try:
        return wrappers[name]
    except KeyError:
        raise ValueError(f"unknown reward {name!r}; expected one of {REWARDS}") from None


__all__ = ["DEFAULT_SLOPE_SCALE", "REWARDS", "information_increment", "reward_wrapper", "InformationRewardVecEnv",
           "BandRewardVecEnv"]
