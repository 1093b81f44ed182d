"""The three single environments: the batch-of-one view of :class:`~.core.BatchSimulator`.

* :class:`ExcitationEnv` (``hyst_gym/Excitation-v0``): action = normalized field command;
  a built-in estimator estimates ``a``.
* :class:`EstimationEnv` (``hyst_gym/Estimation-v0``): the field follows a schedule;
  action = the agent's estimate of ``a`` normalized to Theta.
* :class:`IdentificationEnv` (``hyst_gym/Identification-v0``): action = (field command,
  estimate).

Constructor: ``Env(config=None, render_mode=None, **overrides)``; ``overrides`` are
:class:`~.config.EnvConfig` field names, so ``gymnasium.make(id, dt=0.005)`` works.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .config import EnvConfig, make_config
from .core import ESTIMATION, EXCITATION, IDENTIFICATION, BatchSimulator, action_array

RENDER_MODES = ("rgb_array", "human")


class HystEnv(gym.Env):
    """A Terfenol-D transducer with drifting temperature (base of the three modes).

    Parameters
    ----------
    config : EnvConfig, optional
        The system (default :class:`EnvConfig`).
    render_mode : {None, "rgb_array", "human"}
    temperature_prior, pinning_prior
        The episode draws of :class:`~.core.BatchSimulator` (the start-temperature shape and a prior
        of k); the defaults draw T0 uniformly and keep k at the config's.
    **overrides
        Fields of :class:`EnvConfig` to change.

    Notes
    -----
    Reset options: ``initial_temperature`` (K), ``ambient_drift_rate`` (K/s), ``a_true``
    (A/m, sets the initial temperature), ``a_estimate`` (A/m, thetahat(0)); each must lie
    in the range the config makes physical (``ValueError`` naming it otherwise).

    ``step`` takes an array of numbers of shape ``action_space.shape`` exactly; anything
    else (None, strings, another shape) is a ``ValueError`` saying what was given.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 30}
    mode = EXCITATION

    def __init__(self, config: EnvConfig | None = None, render_mode: str | None = None,
                 temperature_prior: str = "uniform", pinning_prior=None, **overrides):
        self.config = make_config(config, **overrides)
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.sim = BatchSimulator(self.config, self.mode, 1, record=render_mode is not None,
                                  temperature_prior=temperature_prior, pinning_prior=pinning_prior)
        self.observation_space = spaces.Box(self.sim.obs_low, self.sim.obs_high, dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.sim.action_size,), dtype=np.float32)
        self._figure = None

    @property
    def observation_names(self) -> list[str]:
        """Names of the observation entries, in order."""
        return list(self.sim.obs_names)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None or self.sim.episode_rngs[0] is None:
            self.sim.set_generator(0, self.np_random)
        self.sim.reset(np.zeros(1, dtype=np.int64), options)
        if self.render_mode == "human":
            self.render()
        return self.sim.observation()[0], self.sim.info_of(0)

    def step(self, action):
        sim = self.sim
        action = action_array(action, self.action_space.shape)
        reward, terminated, truncated = sim.step_views(action.reshape(1, -1))
        if self.render_mode == "human":
            self.render()
        return (sim.observation()[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]),
                sim.info_of(0))

    def render(self):
        """``"rgb_array"``: an (H, W, 3) uint8 frame; ``"human"``: draws it in a window."""
        if self.render_mode is None:
            gym.logger.warn("render() called with render_mode=None; pass render_mode='rgb_array' or 'human'")
            return None
        from .rendering import draw_figure, figure_to_array, show_human
        if self.render_mode == "rgb_array":
            return figure_to_array(draw_figure(self.sim.history[0], self.config, title=type(self).__name__))
        self._figure = show_human(self._figure, self.sim.history[0], self.config, title=type(self).__name__)
        return None

    def episode_history(self) -> list[dict]:
        """Per-step records of the current episode (needs a render_mode or ``record=True``)."""
        return list(self.sim.history[0])

    def close(self):
        if self._figure is not None:
            from .rendering import close_figure
            close_figure(self._figure)
            self._figure = None


class ExcitationEnv(HystEnv):
    """``hyst_gym/Excitation-v0``: design the field; a built-in estimator estimates ``a``.

    **Description.** A Terfenol-D transducer (hysteresis model (6), plant set by
    ``transducer``) whose coil temperature drifts and moves the material parameter ``a``
    (eq. (4)). The agent chooses the applied field H(t); the built-in min-max estimator
    (eq. (15)) identifies ``a`` from the measured output without the truth. The task is
    the paper's input design: excite so that the estimate converges fast and stays on the
    drifting truth.

    **Action Space.** Box([-1], [1], (1,)): field command / ``field_limit``; the applied field
    moves towards it by at most ``slew_rate_limit*dt`` (A/m) per step.

    **Rewards.** Each step ``-|a_estimate - a_true|/width(Theta)`` minus
    ``penalty_weight`` times the squared intrusions into the stroke band (10 % of
    ``stroke_limit``) and the temperature band (5 K below ``temperature_limit``).

    **Starting State.** The coil temperature is drawn uniformly from
    ``initial_temperature_range`` (K; 278.15-298.15 by default) and sets the true ``a`` by eq. (4)
    (``temperature_mode="fixed"`` holds it); the field and M start at 0 and the estimate at
    ``initial_estimate`` (A/m). Reset options override the draw: ``initial_temperature`` (K),
    ``ambient_drift_rate`` (K/s), ``a_true`` (A/m), ``a_estimate`` (A/m).

    **Episode End.** *Terminated* when the coil passes ``temperature_limit`` (K) or the
    output passes ``stroke_limit``; the step then also pays minus the steps left to the time
    limit, so a violation never pays. *Truncated* after ``episode_steps`` steps (1000 by
    default; a shorter ``max_episode_steps`` on request).

    **Arguments.** ``gymnasium.make(id, **fields)`` with any field of
    :class:`~hyst_gym.envs.EnvConfig` (frozen and validated, units in its docstring), or
    ``config=EnvConfig(...)``; ``render_mode`` in {None, "rgb_array", "human"}.
    """

    mode = EXCITATION


class EstimationEnv(HystEnv):
    """``hyst_gym/Estimation-v0``: the field follows ``config.schedule``; the agent estimates.

    **Description.** The transducer of ``Excitation-v0``, driven by a fixed schedule
    (``schedule``: the paper's ramp, a sine, a chirp or a PRBS, through the same field and
    slew limits); the agent is the estimator: it reads the outputs and reports ``a``.

    **Action Space.** Box([-1], [1], (1,)): the estimate of ``a`` normalized to Theta,
    ``a = theta_min + (action + 1)/2 * width(Theta)`` (A/m).

    **Rewards.** Each step ``-|a_reported - a_true|/width(Theta)`` minus the constraint
    penalties of ``Excitation-v0``.

    **Starting State.** The coil temperature is drawn uniformly from
    ``initial_temperature_range`` (K; 278.15-298.15 by default) and sets the true ``a`` by eq. (4)
    (``temperature_mode="fixed"`` holds it); the field and M start at 0 and the estimate at
    ``initial_estimate`` (A/m). Reset options override the draw: ``initial_temperature`` (K),
    ``ambient_drift_rate`` (K/s), ``a_true`` (A/m), ``a_estimate`` (A/m).

    **Episode End.** *Terminated* when the coil passes ``temperature_limit`` (K) or the
    output passes ``stroke_limit``; the step then also pays minus the steps left to the time
    limit, so a violation never pays. *Truncated* after ``episode_steps`` steps (1000 by
    default; a shorter ``max_episode_steps`` on request).

    **Arguments.** ``gymnasium.make(id, **fields)`` with any field of
    :class:`~hyst_gym.envs.EnvConfig` (frozen and validated, units in its docstring), or
    ``config=EnvConfig(...)``; ``render_mode`` in {None, "rgb_array", "human"}.
    """

    mode = ESTIMATION


class IdentificationEnv(HystEnv):
    """``hyst_gym/Identification-v0``: the agent designs the field and estimates ``a``.

    **Description.** The transducer of ``Excitation-v0`` with no built-in estimator: the
    agent both excites and identifies.

    **Action Space.** Box([-1, -1], [1, 1], (2,)): (field command / ``field_limit``, estimate
    of ``a`` normalized to Theta as in ``Estimation-v0``).

    **Rewards.** Each step ``-|a_reported - a_true|/width(Theta)`` minus the constraint
    penalties of ``Excitation-v0``.

    **Starting State.** The coil temperature is drawn uniformly from
    ``initial_temperature_range`` (K; 278.15-298.15 by default) and sets the true ``a`` by eq. (4)
    (``temperature_mode="fixed"`` holds it); the field and M start at 0 and the estimate at
    ``initial_estimate`` (A/m). Reset options override the draw: ``initial_temperature`` (K),
    ``ambient_drift_rate`` (K/s), ``a_true`` (A/m), ``a_estimate`` (A/m).

    **Episode End.** *Terminated* when the coil passes ``temperature_limit`` (K) or the
    output passes ``stroke_limit``; the step then also pays minus the steps left to the time
    limit, so a violation never pays. *Truncated* after ``episode_steps`` steps (1000 by
    default; a shorter ``max_episode_steps`` on request).

    **Arguments.** ``gymnasium.make(id, **fields)`` with any field of
    :class:`~hyst_gym.envs.EnvConfig` (frozen and validated, units in its docstring), or
    ``config=EnvConfig(...)``; ``render_mode`` in {None, "rgb_array", "human"}.
    """

    mode = IDENTIFICATION


__all__ = ["EstimationEnv", "ExcitationEnv", "HystEnv", "IdentificationEnv", "RENDER_MODES"]
