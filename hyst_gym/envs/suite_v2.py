"""Benchmark suite v2: task envs with their own stories, behind versioned ids.

Two kinds of task, both on the compiled simulator of :mod:`hyst_gym.envs.core`:

* **calibration** tasks (``Identification`` mode: the agent drives the coil *and* reports its
  estimate of a every step), whose floor is a Van Trees bound
  (:mod:`hyst_gym.estimation.information_bound`): :class:`HotCalibrateEnv` and its noisy and
  displacement-only variants;
* the **several unknowns** task :class:`HotCalibrateUnknownKEnv`: the same calibration with the pinning
  constant k of model (6) drawn per episode from a uniform prior (:class:`PinningPrior`);
* **drift-jump** task (``Excitation`` mode, the built-in min-max estimator identifies a): a
  jumps at an unknown time, :class:`DriftJumpEnv`; its floor is an oracle.

Each id's class docstring is its documentation page (Gymnasium's sections). The presets live in
:data:`TASKS_V2`; ``gymnasium.make(id)`` and ``gymnasium.make_vec(id, num_envs=n,
vectorization_mode="vector_entry_point")`` build them through :func:`hyst_gym.envs.tasks.make_env` and
:func:`hyst_gym.envs.tasks.make_vector_env`.
"""

from __future__ import annotations

import numpy as np

from .core import PINNING_OPTION as CORE_PINNING_OPTION
from .posterior import GridPosterior
from .single import ExcitationEnv, IdentificationEnv
from .suite_v1 import COMMON, ENV_KEYWORDS, HOT_THERMAL
from .task_spec import PinningPrior, TaskSpec
from .vector import ExcitationVectorEnv, IdentificationVectorEnv

#: calibration presets: the hot coil of v1, no ambient drift (the heating is then a known function
#: of the input), the starting temperature drawn from a raised-cosine prior over 5..45 C
CALIBRATE = {**COMMON, "thermal": HOT_THERMAL, "ambient_drift_rate_range": (0.0, 0.0)}
#: the drift-jump preset: v1's hot coil with its usual ambient drift
JUMP = {**COMMON, "thermal": HOT_THERMAL}
#: jump of the coil's surroundings (K): a magnitude in JUMP_MAGNITUDE, at a step in JUMP_WINDOW
JUMP_MAGNITUDE = (5.0, 12.0)
JUMP_WINDOW = (40, 160)   # steps: 2..8 s at dt = 0.05 s
#: the temperatures a jump may lead to (K): the sign is flipped when the drawn one leaves them
JUMP_RANGE = (278.15, 323.15)


#: the discriminate task's sensor noise (standard deviation of the measured M/Ms per step)
DISCRIMINATE_NOISE = 3.0e-3

#: the calibration tasks score the estimate from this step on (the job starts after a 5 s warm-up)
CALIBRATE_SCORED_FROM = 100


#: k of the "several unknowns" task: +-20 % about the Terfenol-D value of model (6), 400 A/m
K_PRIOR = PinningPrior(320.0, 480.0)


def _task(task_id, kind, family, description, difficulty, config, sensors_hidden=(), k_prior=None):
    calibrate = kind == "calibrate"
    if k_prior is not None:
        kind = "calibrate_unknown_k"
    return TaskSpec(task_id, "v2", kind, family, description, difficulty, config, sensors_hidden, k_prior,
                    temperature_prior="raised_cosine" if calibrate else "uniform",
                    scored_from=CALIBRATE_SCORED_FROM if calibrate else 0)


#: suite v2's tasks (:class:`~hyst_gym.envs.task_spec.TaskSpec`; kind ``calibrate``, ``jump`` or, measured by
#: their own scripts in ``experiments/suite/`` and rejected, ``dual_control`` and ``discriminate``)
TASKS_V2 = (
    _task("hyst_gym/HotCalibrate-v0",
          "calibrate", "hot coil (calibrate)", "Calibrate a hot coil: report a every step while exciting; the coil "
          "overheats if excited at full field for about a second from a warm start", 1, CALIBRATE),
    _task("hyst_gym/HotCalibrateNoisy-v0",
          "calibrate", "hot coil (calibrate)", "The hot-coil calibration with a 10x noisier sensor (1e-3 of full "
          "scale)", 2, {**CALIBRATE, "output_noise": 1.0e-3}),
    _task("hyst_gym/DisplacementOnly-v0",
          "calibrate", "displacement-only sensing", "The hot-coil calibration on the lumped transducer (13) with "
          "only the tip displacement sensed (no velocity), 10x sensor noise", 3,
          {**CALIBRATE, "transducer": "lumped", "output_noise": 1.0e-3}, sensors_hidden=("velocity",)),
    _task("hyst_gym/HotCalibrateUnknownK-v0",
          "calibrate", "several unknowns", "The hot-coil calibration with the pinning constant k also unknown "
          "(uniform over 320..480 A/m, +-20 % about nominal, per episode); k shapes the loops, so an estimate "
          "of a that assumes the nominal k is biased unless the input makes reversals that tell k apart", 3,
          CALIBRATE, k_prior=K_PRIOR),
    _task("hyst_gym/DriftJump-v0",
          "jump", "drift events", "Mount change: at an unknown time in 2..8 s the coil and its surroundings step by "
          "5..12 K, so a jumps by 120..290 A/m; the min-max estimator must be re-excited without overheating", 4,
          JUMP),
    TaskSpec("hyst_gym/DualControl-v0", "v2", "dual_control", "dual control (milling)",
             "Identify while working: track a milling stroke through an inverse-compensation controller that uses "
             "the estimator's current a; the agent adds a probe field, which informs the estimator but costs "
             "tracking error (a rejected candidate: every probe measured costs more tracking error than the "
             "estimator's passive learning leaves; python -m experiments.suite.dual_control)", 0,
             {**CALIBRATE, "output_noise": 1.0e-3}, temperature_prior="raised_cosine", rejected=True),
    TaskSpec("hyst_gym/Discriminate-v0", "v2", "discriminate", "discriminate (active diagnosis)",
             "Tell three explanations of a recording apart (small-loop susceptibility, a different pinning k, a "
             "different anhysteretic width a, each fitted to the recording): design the field that brings the "
             "posterior of the truth to 0.99 fastest without overheating the coil (a rejected candidate: no floor "
             "below the agents; python -m experiments.suite.discriminate)", 0,
             {**CALIBRATE, "output_noise": DISCRIMINATE_NOISE}, temperature_prior="raised_cosine", rejected=True),
)


#: suite v2's tasks by id (a view of :data:`TASKS_V2`; every suite's tasks: :data:`hyst_gym.envs.tasks.TASKS`)
V2_BY_ID = {spec.id: spec for spec in TASKS_V2}


def _spec(task: str, kind: str | None = None) -> TaskSpec:
    if task not in V2_BY_ID:
        raise ValueError(f"unknown suite task {task!r}; expected one of {sorted(V2_BY_ID)}")
    spec = V2_BY_ID[task]
    if kind is not None and (spec.calibrates if kind == "calibrate" else spec.kind == kind) is False:
        raise ValueError(f"{task!r} is not a {'calibration' if kind == 'calibrate' else 'drift-jump'} task")
    return spec


def task_config_v2(task: str, **overrides):
    """The :class:`~hyst_gym.envs.config.EnvConfig` of a v2 task (with ``overrides``)."""
    return _spec(task).env_config(**overrides)


# ---------------------------------------------------------------------------- calibration

#: the reset option of the "several unknowns" task: the episode's k (A/m), bypassing the prior
PINNING_OPTION = CORE_PINNING_OPTION


#: who reports the estimate of a in a calibration task: the task's estimator (the grid posterior,
#: :class:`~hyst_gym.envs.posterior.GridPosterior`; the agent drives the field only) or the agent itself
#: (the agent-reports track: the action is (field, estimate))
REPORTERS = ("estimator", "agent")


def scored_reward(error, terminated, steps_done, scored_from: int, total: int, width: float, power: int):
    """The dense reward whose episode sum is minus the task metric in units of width(Theta)**power: per step
    t (0-based, ``steps_done = t + 1``) in the scored window ``t >= scored_from``, ``-(error/width)**power/N``
    (N = total - scored_from scored steps); at an overheat (``terminated``) also ``-1/N`` for every scored step
    after t (the metric counts width(Theta) for each)."""
    steps_done = np.asarray(steps_done)
    in_window = steps_done - 1 >= scored_from
    reward = -np.where(in_window, (np.asarray(error) / width) ** power, 0.0)
    remaining = total - np.maximum(steps_done, scored_from)
    reward = reward - np.where(terminated, remaining, 0)
    return reward / (total - scored_from)


class _Scored:
    """The scored reward (:func:`scored_reward`) of a task; ``_elapsed`` counts each sub-env's steps."""

    def _setup_scored(self, spec, power: int, n: int):
        self.scored_from = spec.scored_from
        self._power = power
        self._elapsed = np.zeros(n, dtype=np.int64)

    def _scored(self, error, terminated):
        config = self.config
        self._elapsed += 1
        return scored_reward(error, terminated, self._elapsed, self.scored_from, config.episode_steps,
                             config.theta_width, self._power)

    def _scored_one(self, error: float, terminated: bool) -> float:
        """:meth:`_scored` of a single env in plain floats (the same formula; numpy on one element costs more
        than the step)."""
        config = self.config
        self._elapsed[0] += 1
        done = int(self._elapsed[0])
        total, first = config.episode_steps, self.scored_from
        ratio = error / config.theta_width
        term = ratio * ratio if self._power == 2 else ratio  # numpy's x**2 is x*x; Python's pow may round apart
        reward = -term if done - 1 >= first else 0.0
        if terminated:
            reward -= total - max(done, first)
        return reward / (total - first)


def heat_scale(config) -> tuple[float, float]:
    """The ``heat_used`` observation of the calibration envs: (1/margin, bound). ``heat_used = (T - T0)/margin``,
    the coil's temperature rise above its start T0 over ``margin = temperature_limit - (hottest start of the
    prior)``: 1 when the hottest start would reach the limit, ``bound = (temperature_limit - coldest start)/margin``
    when the coldest would (clipped to [0, bound]). With the calibration presets' ambient equal to T0 and no
    drift, the rise obeys ``tau*r' = -r + R_th*P(H)`` from r = 0, with a constant coil resistance: a function of
    the applied field's history alone, the same for every T0, so it tells the agent nothing about a that the
    field it applied does not."""
    t_lo, t_hi = config.initial_temperature_range
    margin = config.temperature_limit - t_hi
    if margin <= 0.0:
        raise ValueError(f"heat_used needs temperature_limit above the hottest start; got {config.temperature_limit:g} "
                         f"<= {t_hi:g} K")
    return 1.0 / margin, (config.temperature_limit - t_lo) / margin


class _Calibrate(_Scored):
    """Shared by the single and the vector calibration env: the sensor selection (observation columns
    kept), the reporter (the grid posterior in the loop, or the agent) and the scored reward. The simulator
    draws the start temperature and, where the task has one, k from the task's priors."""

    def _setup_calibrate(self, spec, reporter: str, n: int, posterior_nodes, heat_state: bool = True):
        if reporter not in REPORTERS:
            raise ValueError(f"reporter must be one of {REPORTERS}, got {reporter!r}")
        self.reporter = reporter
        self.k_prior = spec.k_prior
        self._setup_scored(spec, 2, n)
        hidden = spec.sensors_hidden
        names = self.sim.obs_names
        self._keep = np.array([i for i, name in enumerate(names) if name not in hidden])
        kept = [names[i] for i in self._keep]
        low, high = self.sim.obs_low[self._keep], self.sim.obs_high[self._keep]
        outputs = ["displacement", "velocity"] if self.config.is_mechanical else ["output"]
        self._channels = [i for i, name in enumerate(outputs) if name not in hidden]
        self.posterior = None
        if reporter == "estimator":
            self.posterior = GridPosterior(self.config, self._channels, n, spec.k_prior, posterior_nodes)
            kept = ["a_estimate" if name == "previous_estimate" else name for name in kept] + ["estimate_spread"]
            low, high = np.append(low, np.float32(0.0)), np.append(high, np.float32(1.0))
            self._measured = np.zeros((n, len(self._channels)))
            self._fresh = np.ones(n, dtype=bool)
        self._heat_scale, heat_high = heat_scale(self.config)
        self._heat_high = heat_high
        self._start_temperature = np.zeros(n)
        self.heat_state = bool(heat_state)
        if self.heat_state:
            kept = kept + ["heat_used"]
            low, high = np.append(low, np.float32(0.0)), np.append(high, np.float32(heat_high))
        self.kept_names = kept
        return low, high

    @property
    def k_true(self) -> np.ndarray:
        """The pinning constant k of each sub-env's episode (A/m; the preset's k where the task has no prior)."""
        return self.sim.pinning

    def _restart(self, rows) -> None:
        """Sub-envs ``rows`` start new episodes: their step count and (in the loop) their posterior."""
        self._elapsed[rows] = 0
        self._start_temperature[rows] = self.sim.ambient0[rows]  # = the start temperature (reset sets both)
        if self.posterior is not None:
            self.posterior.restart(rows)
            self._fresh[rows] = True

    def _full_action(self, actions: np.ndarray, skip=None) -> np.ndarray:
        """The simulator's (field, estimate) actions: the agent's own, or its field with the grid posterior's
        estimate (updated with the last measured outputs, stepped with this field; ``skip``: rows whose
        action the vector env ignores). The estimate goes through the action's float32, as an agent's would."""
        if self.posterior is None:
            return actions
        field = np.asarray(actions, dtype=np.float32).astype(np.float64)[:, 0]
        going = ~self._fresh if skip is None else ~self._fresh & ~skip
        self.posterior.advance(self._measured, np.flatnonzero(going), field)  # update, then step
        self._fresh[:] = False
        config = self.config
        normalized = 2.0 * (self.posterior.estimate() - config.theta_min) / config.theta_width - 1.0
        full = np.empty((field.shape[0], 2), dtype=np.float32)
        full[:, 0] = field
        # np.clip's value for a finite number, without its Python-level dispatch (slower than the arithmetic here)
        full[:, 1] = np.minimum(np.maximum(normalized, -1.0), 1.0)
        return full

    def _spread(self) -> np.ndarray:
        """The estimator's spread per sub-env: posterior standard deviation of a / width(Theta), in [0, 1]."""
        return np.minimum(np.maximum(self.posterior.spread() / self.config.theta_width, 0.0), 1.0)

    def _heat(self, temperature, start) -> np.ndarray:
        """The ``heat_used`` column: the coil's temperature rise above its start / the hottest start's overheat
        margin, clipped to [0, its bound]."""
        return np.minimum(np.maximum((temperature - start) * self._heat_scale, 0.0), self._heat_high)

    def _observation(self, full: np.ndarray) -> np.ndarray:
        """The agent's observation rows from the simulator's: the task's sensors, (in the loop) the estimator's
        estimate (in place of the reported one) and its spread (std of a / width(Theta)), and the heat used."""
        kept = self._keep.size
        out = np.empty((full.shape[0], len(self.kept_names)), dtype=np.float32)
        out[:, :kept] = full[:, self._keep]
        if self.posterior is not None:
            self._measured = out[:, :len(self._channels)].astype(np.float64)
            out[:, kept] = self._spread()
        if not self.heat_state:
            return out
        if full.shape[0] == 1:  # a single env: the same arithmetic in Python floats (numpy on one element is slower)
            rise = (float(self.sim.temperature[0]) - float(self._start_temperature[0])) * self._heat_scale
            out[0, -1] = min(max(rise, 0.0), self._heat_high)
        else:
            out[:, -1] = self._heat(self.sim.temperature, self._start_temperature)
        return out


class HotCalibrateEnv(_Calibrate, IdentificationEnv):
    """``hyst_gym/HotCalibrate-v0`` (also ``HotCalibrateNoisy-v0``, ``DisplacementOnly-v0``).

    ## Description
    A milling actuator's small, lightly cooled coil (C_th 5 J/K, R_th 4 K/W) must be calibrated
    before a job: the agent designs the coil field H(t) and the task's estimator identifies the
    anhysteretic parameter a from what that input reveals. a follows the coil temperature (eq. (4),
    about 24 A/m per K); the start temperature is unknown (a raised-cosine prior over 5..45 C), the
    ambient equals it and does not drift, and Joule heating ``R*(H/n)**2`` heats the coil by about
    13 K/s at 81 kA/m, so a warm coil affords about a second of full excitation. The estimator is the
    grid posterior over the start temperature (:class:`~hyst_gym.envs.posterior.GridPosterior`, the
    Bayes estimate: the posterior mean, the parabola vertex once one node holds most of the mass); every
    agent plays with it, so agents differ only in the input they design. The floor is a Van Trees bound
    on the RMS error of any estimate under any admissible input (``experiments/suite/v2.py``).

    ## Action Space
    ``Box(-1, 1, (1,))``: field command / field_limit (1e5 A/m); the applied field moves towards it by at
    most 2500 A/m per step. With ``reporter="agent"`` (the agent-reports track): ``Box(-1, 1, (2,))``,
    (field command, the agent's estimate of a mapped onto Theta = [6500, 8100] A/m).

    ## Observation Space
    ``Box(float32)``, normalized, clipped to the bounds:

    | index | name | min | max | meaning (unit) |
    |---|---|---|---|---|
    | 0 | output (or displacement) | -2 | 2 | y / y(Ms) (first-order plant) or x / x(Ms) (lumped) |
    | 1 | velocity (HotCalibrate on the lumped transducer only; hidden in DisplacementOnly) | -2 | 2 | v / (x(Ms) w1) |
    | next | field | -1 | 1 | H / 1e5 A/m |
    | next | elapsed | 0 | 1 | step / 200 |
    | next | a_estimate | -1 | 1 | the estimator's estimate of a (the one scored), mapped from Theta |
    | next | estimate_spread | 0 | 1 | its posterior standard deviation / width(Theta) |
    | last | heat_used | 0 | 11/3 | the coil's temperature rise above its start / 15 K (see below) |

    With ``reporter="agent"``: ``previous_estimate`` (the agent's last reported estimate) in place of
    ``a_estimate``, and no ``estimate_spread``. Measurement noise: ``output_noise`` (1e-4; 1e-3 in the noisy
    and displacement-only tasks) times each output's scale, Gaussian, per step.

    ``heat_used`` is the coil's heat state, on both tracks: the rise ``T - T0`` over the margin
    ``60 C - 45 C = 15 K`` of the prior's hottest start (:func:`heat_scale`), so 1 is where the hottest start
    overheats and 11/3 (55 K) where the coldest does. The ambient equals T0 and does not drift, and the coil's
    resistance does not depend on its temperature, so the rise obeys ``tau*r' = -r + R_th*R*(H/n)**2`` from 0:
    a function of the applied field's history alone, equal for every T0 (to rounding). It tells the agent how
    much of the heat budget its input has spent and nothing about a; how much is left still depends on the
    unknown T0, which the estimate (a is proportional to the temperature) narrows.

    ## Rewards
    The reward sums to minus the task's score: per step of the scored window (steps 101..200: a 5 s
    warm-up, then the milling job, which needs a from its start) ``-((a_estimate - a_true)/width(Theta))**2/100``,
    0 before it; at an overheat also ``-1/100`` for every scored step left (the metric counts width(Theta)
    for each). So the episode's return times width(Theta)**2 is minus the mean square error over the scored
    steps, the per-draw score whose RMS over draws is the suite's metric (A/m).

    ## Starting State
    Field 0, M = 0, coil at ``T0 = 278.15 + 40*Q(u)`` K (Q the raised-cosine quantile, u uniform from the
    env's seeded generator), a = 7012*T0/293.15 A/m. The estimator starts from its prior; the observation's
    estimate before the first step is the preset's ``initial_estimate`` (7300 A/m).

    ## Episode End
    ``terminated``: the coil passes 333.15 K (60 C). ``truncated``: 200 steps (10 s at dt = 0.05 s).

    ## Arguments
    ``gymnasium.make(id, reporter="estimator", posterior_nodes=None, heat_state=True, **overrides)``:
    ``reporter``: ``"estimator"`` (default) or ``"agent"`` (the agent-reports track); ``posterior_nodes``: T0
    grid nodes of the estimator (default 64, 24 with a k grid of 9 on the k task); ``heat_state=False`` drops
    ``heat_used`` from the observation (an ablation; the suite plays the default); any
    :class:`~hyst_gym.envs.config.EnvConfig` field on top of the preset. Reset options as
    :class:`~hyst_gym.envs.single.HystEnv` (``initial_temperature`` bypasses the prior).

    ## Version History
    * v0: first version (suite v2): the agent reported a; then the estimator in the loop (the action is the
      field only, the observation holds the estimator's estimate and spread) and the reward that sums to the
      score, with the agent-reports track kept as ``reporter="agent"``; then the coil's heat state
      (``heat_used``) as the observation's last entry on both tracks.
    """

    def __init__(self, task: str = "hyst_gym/HotCalibrate-v0", render_mode=None, reporter: str = "estimator",
                 posterior_nodes: int | None = None, heat_state: bool = True, **overrides):
        spec = _spec(task, "calibrate")
        super().__init__(spec.env_config(**overrides), render_mode=render_mode, **spec.simulator_priors())
        self.task = task
        low, high = self._setup_calibrate(spec, reporter, 1, posterior_nodes, heat_state)
        from gymnasium import spaces

        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        if self.posterior is not None:
            self.action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)

    @property
    def observation_names(self) -> list[str]:
        return list(self.kept_names)

    def reset(self, *, seed=None, options=None):
        observation, info = super().reset(seed=seed, options=options)
        self._restart(np.zeros(1, dtype=np.int64))
        if self.k_prior is not None:
            info["k_true"] = float(self.k_true[0])
        return self._observation(observation[None, :])[0], info

    def step(self, action):
        from .core import action_array

        action = action_array(action, self.action_space.shape)
        sim = self.sim
        _, terminated, truncated = sim.step_views(self._full_action(action[None, :]))
        terminated, truncated = bool(terminated[0]), bool(truncated[0])
        if self.render_mode == "human":
            self.render()
        info = sim.info_of(0)
        reward = self._scored_one(abs(info["a_estimate"] - info["a_true"]), terminated)
        return self._observation(sim.observation())[0], reward, terminated, truncated, info


class HotCalibrateVectorEnv(_Calibrate, IdentificationVectorEnv):
    """Native vector env of the calibration tasks (see :class:`HotCalibrateEnv`; ``reporter``,
    ``posterior_nodes``, ``heat_state`` as there); sub-envs reset automatically restart their estimator."""

    def __init__(self, num_envs: int = 1, task: str = "hyst_gym/HotCalibrate-v0", reporter: str = "estimator",
                 posterior_nodes: int | None = None, heat_state: bool = True, **overrides):
        spec = _spec(task, "calibrate")
        env_args = {key: overrides.pop(key) for key in ENV_KEYWORDS if key in overrides}
        super().__init__(num_envs, spec.env_config(**overrides), **env_args, **spec.simulator_priors())
        self.task = task
        low, high = self._setup_calibrate(spec, reporter, self.num_envs, posterior_nodes, heat_state)
        from gymnasium import spaces
        from gymnasium.vector.utils import batch_space

        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        if self.posterior is not None:
            self.single_action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
            self.action_space = batch_space(self.single_action_space, self.num_envs)

    @property
    def observation_names(self) -> list[str]:
        return list(self.kept_names)

    def reset(self, *, seed=None, options=None):
        observation, info = super().reset(seed=seed, options=options)
        self._restart(self._all)
        return self._observation(observation), info

    def step(self, actions):
        from gymnasium.vector import AutoresetMode

        from .core import action_array

        actions = action_array(actions, (self.num_envs,) + self.single_action_space.shape, "actions")
        next_step = self.autoreset_mode == AutoresetMode.NEXT_STEP
        if self.autoreset_mode == AutoresetMode.DISABLED and self._autoreset.any():  # before the estimator moves
            raise RuntimeError("step: some sub-envs are done and autoreset_mode is DISABLED; reset them first")
        resetting = self._autoreset.copy() if next_step else np.zeros(self.num_envs, dtype=bool)
        full = self._full_action(actions, skip=resetting)
        observation, _, terminated, truncated, info = super().step(full)
        done = terminated | truncated
        final = info.get("final_info") if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any() else None
        source = info if final is None else {key: np.where(done, final[key], info[key])
                                             for key in ("a_estimate", "a_true")}
        reward = self._scored(np.abs(source["a_estimate"] - source["a_true"]), terminated)
        reward[resetting] = 0.0  # the step that reset them (NEXT_STEP): no reward, as SyncVectorEnv
        if final is not None:  # SAME_STEP: the finished sub-envs' last observations, then their restart
            last = info["final_obs"]
            spread = None if self.posterior is None else self._spread()
            heat = self._heat(final["temperature"], self._start_temperature) if self.heat_state else None
            final_obs = np.full(self.num_envs, None, dtype=object)  # one array (or None) per sub-env
            for row, obs in enumerate(last):
                final_obs[row] = None if obs is None else self._row_observation(obs, spread, heat, row)
            info["final_obs"] = final_obs
        restarted = resetting if final is None else done
        if restarted.any():
            self._restart(np.flatnonzero(restarted))
        return self._observation(observation), reward, terminated, truncated, info

    def _row_observation(self, full_row, spread, heat, row):
        observation = full_row[self._keep]  # then the spread (in the loop) and the heat used of the finished episode
        extra = ([] if spread is None else [spread[row]]) + ([] if heat is None else [heat[row]])
        return np.append(observation, np.array(extra, dtype=np.float32))


class HotCalibrateUnknownKEnv(HotCalibrateEnv):
    """``hyst_gym/HotCalibrateUnknownK-v0``: calibrate a with the pinning constant k unknown too.

    ## Description
    The "several unknowns" family. The hot-coil calibration of ``hyst_gym/HotCalibrate-v0`` (coil
    C_th 5 J/K, R_th 4 K/W, start temperature from a raised-cosine prior over 5..45 C, no ambient drift, the
    coil overheats at 60 C) in which the pinning (domain-wall loss) constant k of model (6) is unknown as
    well: each episode draws k uniformly over 320..480 A/m (+-20 % about the Terfenol-D value 400 A/m,
    :data:`K_PRIOR`). k and a both lower M on the initial magnetization curve, so a rising field alone
    confounds them; after a reversal a larger k *raises* M (wider loops) while a larger a still lowers it,
    so only an input that makes reversals and minor loops tells them apart. The agent drives the coil; the
    task's estimator is the grid posterior over (T0, k) (24 x 9 nodes), whose estimate of a marginalizes k.

    The floor is the Van Trees bound of the k-known task computed with a sensitivity envelope taken as the
    largest over five values of k across the prior (``calibration_floor``; sampled, like its random
    histories, not proven between them): knowing k can only help (``[J^-1]_aa >= 1/J_aa``), so it bounds
    every estimate here too, but it ignores the k uncertainty and is therefore looser than a bound with k
    as a nuisance.

    ## Action Space
    ``Box(-1, 1, (1,))``: field command / field_limit (1e5 A/m); the applied field moves towards it by at
    most 2500 A/m per step. With ``reporter="agent"``: (field command, the agent's estimate of a mapped onto
    Theta = [6500, 8100] A/m).

    ## Observation Space
    ``Box(float32)``, normalized, clipped to the bounds (as ``hyst_gym/HotCalibrate-v0``):

    | index | name | min | max | meaning (unit) |
    |---|---|---|---|---|
    | 0 | output | -2 | 2 | y / y(Ms) |
    | 1 | field | -1 | 1 | H / 1e5 A/m |
    | 2 | elapsed | 0 | 1 | step / 200 |
    | 3 | a_estimate | -1 | 1 | the estimator's estimate of a (the one scored), mapped from Theta |
    | 4 | estimate_spread | 0 | 1 | its posterior standard deviation (k marginalized) / width(Theta) |
    | 5 | heat_used | 0 | 11/3 | the coil's temperature rise above its start / 15 K, as ``hyst_gym/HotCalibrate-v0`` |

    With ``reporter="agent"``: ``previous_estimate`` (the agent's last reported estimate) in place of
    ``a_estimate``, no ``estimate_spread``, and ``heat_used`` at index 4. Measurement noise: 1e-4 of the
    output's scale, Gaussian, per step. k does not enter the coil's heating, so ``heat_used`` is the same
    function of the field's history as in ``hyst_gym/HotCalibrate-v0``.

    ## Rewards
    As ``hyst_gym/HotCalibrate-v0``: the reward sums to minus the score,
    ``-((a_estimate - a_true)/width(Theta))**2/100`` per step of steps 101..200, and ``-1/100`` per scored
    step left at an overheat; the return times
    width(Theta)**2 is minus the mean square error over the scored steps (the suite's metric is its RMS over
    draws, A/m).

    ## Starting State
    Field 0, M = 0, coil at ``T0 = 278.15 + 40*Q(u)`` K (Q the raised-cosine quantile), a = 7012*T0/293.15 A/m,
    and ``k = 320 + 160*u'`` A/m, u and u' uniform from the env's seeded generator (u' drawn after the
    simulator's own draws). ``reset`` returns ``info["k_true"]``; the attribute ``k_true`` holds it too.

    ## Episode End
    ``terminated``: the coil passes 333.15 K (60 C). ``truncated``: 200 steps (10 s at dt = 0.05 s).

    ## Arguments
    ``gymnasium.make(id, reporter="estimator", posterior_nodes=None, heat_state=True, **overrides)`` as
    ``hyst_gym/HotCalibrate-v0``. Reset options as :class:`~hyst_gym.envs.single.HystEnv`
    (``initial_temperature`` bypasses the temperature prior) and ``pinning_k`` (A/m, > 0), which bypasses the
    k prior.

    ## Version History
    * v0: first version (suite v2): the agent reported a; then the estimator in the loop and the reward that
      sums to the score, with the agent-reports track kept as ``reporter="agent"``; then the coil's heat state
      (``heat_used``) as the observation's last entry on both tracks.
    """

    def __init__(self, task: str = "hyst_gym/HotCalibrateUnknownK-v0", render_mode=None, **overrides):
        if _spec(task).k_prior is None:
            raise ValueError(f"{task!r} has no prior over k; use HotCalibrateEnv")
        super().__init__(task, render_mode=render_mode, **overrides)


class HotCalibrateUnknownKVectorEnv(HotCalibrateVectorEnv):
    """Native vector env of ``hyst_gym/HotCalibrateUnknownK-v0`` (see :class:`HotCalibrateUnknownKEnv`):
    every reset, the automatic ones included, draws each reset sub-env's k; ``k_true`` holds them."""

    def __init__(self, num_envs: int = 1, task: str = "hyst_gym/HotCalibrateUnknownK-v0", **overrides):
        if _spec(task).k_prior is None:
            raise ValueError(f"{task!r} has no prior over k; use HotCalibrateVectorEnv")
        super().__init__(num_envs, task, **overrides)


# ---------------------------------------------------------------------------- drift jump

JUMP_OPTIONS = ("jump_step", "jump_change")


class _Jump:
    """Shared by the single and the vector drift-jump env: per sub-env a jump step and a change of
    the coil and ambient temperature (K), drawn at reset from the sub-env's episode generator (after
    the simulator's own draws) or given as reset options ``jump_step``, ``jump_change``."""

    def _draw_jumps(self, rows, options):
        sim = self.sim
        n = sim.n
        if not hasattr(self, "jump_step"):
            self.jump_step = np.zeros(n, dtype=np.int64)
            self.jump_change = np.zeros(n)
        for row in rows:
            draws = sim.episode_rngs[row].random(3)
            step = JUMP_WINDOW[0] + int(draws[0] * (JUMP_WINDOW[1] - JUMP_WINDOW[0]))
            change = (JUMP_MAGNITUDE[0] + (JUMP_MAGNITUDE[1] - JUMP_MAGNITUDE[0]) * draws[1]) * (
                1.0 if draws[2] < 0.5 else -1.0)
            if not JUMP_RANGE[0] <= sim.temperature[row] + change <= JUMP_RANGE[1]:
                change = -change
            self.jump_step[row], self.jump_change[row] = step, change
        if "jump_step" in options:
            self.jump_step[rows] = int(options["jump_step"])
        if "jump_change" in options:
            self.jump_change[rows] = float(options["jump_change"])

    def _apply_jumps(self):
        sim = self.sim
        rows = np.flatnonzero(sim.steps == self.jump_step)
        if rows.size:
            sim.shift_temperature(rows, self.jump_change[rows])


def _split_options(options):
    """(simulator options, jump options); a bad jump option is a ValueError naming it."""
    options = dict(options or {})
    jump = {key: options.pop(key) for key in JUMP_OPTIONS if key in options}
    for key, value in jump.items():
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or \
                not np.isfinite(value):
            raise ValueError(f"reset option {key} must be a finite number, got {value!r}")
    if "jump_step" in jump and (jump["jump_step"] < 1 or int(jump["jump_step"]) != jump["jump_step"]):
        raise ValueError(f"reset option jump_step must be an integer >= 1, got {jump['jump_step']!r}")
    return (options or None), jump


class DriftJumpEnv(_Scored, _Jump, ExcitationEnv):
    """``hyst_gym/DriftJump-v0``: a jumps at an unknown time; notice it and re-identify.

    ## Description
    The hot coil of suite v1 (C_th 5 J/K, R_th 4 K/W, start 5..45 C, ambient drift +-0.05 K/s, limit 60 C)
    with a drift *event*: at an unknown step (2..8 s) the actuator's mount changes and the coil and its
    surroundings step by 5..12 K (up or down; the sign is flipped when it would leave 5..50 C), so a
    jumps by 120..290 A/m. The agent drives the field; the built-in min-max estimator identifies a. An
    open-loop input must keep exciting (and heating) for the whole episode to catch the jump; feedback can
    read the estimator's tuning error, idle while it is tuned and excite when it is not.

    ## Action Space
    ``Box(-1, 1, (1,))``: field command / field_limit (1e5 A/m); slew limit 2500 A/m per step.

    ## Observation Space
    As ``hyst_gym/Excitation-v0`` (all normalized):

    | index | name | min | max | meaning (unit) |
    |---|---|---|---|---|
    | 0 | output | -2 | 2 | y / y(Ms) |
    | 1 | field | -1 | 1 | H / 1e5 A/m |
    | 2 | elapsed | 0 | 1 | step / 200 |
    | 3 | a_estimate | -1 | 1 | min-max estimate mapped from Theta = [6500, 8100] A/m |
    | 4 | tuning_error | -1 | 1 | sign*log10(1 + abs(y_eps)/eps)/6 |
    | 5 | curvature_sign | -1 | 1 | sign of d2f/da2 at the estimate |
    | 6 | minmax_gap | 0 | 1 | log1p(nu*)/log1p(2 Ms) |

    ## Rewards
    The reward sums to minus the task's score: ``-|a_estimate - a_true| / width(Theta) / 200`` per step, and at
    an overheat also ``-1/200`` for every step left (the metric counts width(Theta) for each). So the episode's
    return times width(Theta) is minus the suite's per-draw metric, the mean ``|a_estimate - a_true|`` (A/m)
    over the 200 steps (IQM over draws).

    ## Starting State
    Field 0, M = 0, thetahat(0) = 7300 A/m, coil and ambient at T0 uniform in 5..45 C; the jump step and
    change are drawn from the env's seeded generator at reset.

    ## Episode End
    ``terminated``: the coil passes 333.15 K. ``truncated``: 200 steps (10 s).

    ## Arguments
    EnvConfig fields on top of the preset. Reset options: those of ``Excitation-v0`` and ``jump_step``
    (int >= 1), ``jump_change`` (K).

    ## Version History
    * v0: first version (suite v2); then the reward that sums to the score (no soft temperature penalty).
    """

    def __init__(self, task: str = "hyst_gym/DriftJump-v0", render_mode=None, **overrides):
        spec = _spec(task, "jump")
        super().__init__(spec.env_config(**overrides), render_mode=render_mode, **spec.simulator_priors())
        self.task = task
        self._setup_scored(spec, 1, 1)

    def reset(self, *, seed=None, options=None):
        options, jump = _split_options(options)
        observation, info = super().reset(seed=seed, options=options)
        self._draw_jumps(np.zeros(1, dtype=np.int64), jump)
        self._elapsed[:] = 0
        return observation, info

    def step(self, action):
        self._apply_jumps()
        observation, _, terminated, truncated, info = super().step(action)
        return observation, self._scored_one(abs(info["a_estimate"] - info["a_true"]), terminated), terminated, \
            truncated, info


class DriftJumpVectorEnv(_Scored, _Jump, ExcitationVectorEnv):
    """Native vector env of ``hyst_gym/DriftJump-v0`` (see :class:`DriftJumpEnv`); sub-envs that are
    reset automatically (``NEXT_STEP`` or ``SAME_STEP``) draw a new jump, as a single env's reset does."""

    def __init__(self, num_envs: int = 1, task: str = "hyst_gym/DriftJump-v0", **overrides):
        spec = _spec(task, "jump")
        env_args = {key: overrides.pop(key) for key in ENV_KEYWORDS if key in overrides}
        super().__init__(num_envs, spec.env_config(**overrides), **env_args, **spec.simulator_priors())
        self.task = task
        self._setup_scored(spec, 1, self.num_envs)

    def reset(self, *, seed=None, options=None):
        options, jump = _split_options(options)
        observation, info = super().reset(seed=seed, options=options)
        self._draw_jumps(self._all, jump)
        self._elapsed[:] = 0
        return observation, info

    def step(self, actions):
        from gymnasium.vector import AutoresetMode

        self._apply_jumps()
        done_before = self._autoreset.copy()
        observation, _, terminated, truncated, info = super().step(actions)
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            final = info["final_info"]
            error = np.where(done, np.abs(final["a_estimate"] - final["a_true"]),
                             np.abs(info["a_estimate"] - info["a_true"]))
        else:
            error = np.abs(info["a_estimate"] - info["a_true"])
        reward = self._scored(error, terminated)
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            reset_rows = np.flatnonzero(done_before)
            reward[reset_rows] = 0.0  # the step that reset them: no reward, as SyncVectorEnv
        elif self.autoreset_mode == AutoresetMode.SAME_STEP:
            reset_rows = np.flatnonzero(done)
        else:  # DISABLED: the caller resets, and reset() draws new jumps
            reset_rows = np.zeros(0, dtype=np.int64)
        if reset_rows.size:
            self._draw_jumps(reset_rows, {})
            self._elapsed[reset_rows] = 0
        return observation, reward, terminated, truncated, info


__all__ = ["K_PRIOR", "DriftJumpEnv", "DriftJumpVectorEnv", "HotCalibrateEnv", "HotCalibrateUnknownKEnv",
           "HotCalibrateUnknownKVectorEnv", "HotCalibrateVectorEnv", "PinningPrior", "TASKS_V2", "task_config_v2"]


# ---------------------------------------------------------------------------- the floor of the calibration tasks


def output_gain(config) -> float:
    """``G = sum_k |h_k| / scale`` (1/(A/m)): the l1 norm of the normalized measured output's response to a
    unit pulse of M (the transducer's first-order-hold map, summed until it has decayed)."""
    from .core import output_scales

    model = config.transducer.discretize(config.dt)
    scale = output_scales(config, model)[0]
    state = np.zeros(np.shape(model.phi)[0])
    total, previous = 0.0, 1.0  # u_0 = drive_gain*1 (the pulse), u_k = 0 after
    for step in range(100_000):
        u0 = model.drive_gain * previous
        state = model.phi @ state + model.gamma0 * u0 + model.gamma1 * model.drive_gain * (1.0 if step == 0 else 0.0)
        previous = 0.0
        total += abs(state[model.output_index])
        if step > 10 and abs(state).max() < 1e-14 * max(total, 1e-300):
            break
    return total / scale


def bound_setting(config):
    """The :class:`~hyst_gym.estimation.information_bound.BoundSetting` of a calibration task's config."""
    from ..estimation.information_bound import BoundSetting

    t_lo, t_hi = config.initial_temperature_range
    return BoundSetting(config.dt, config.episode_steps, config.field_limit, config.max_field_change,
                        config.output_noise, output_gain(config), float(config.a_of(t_lo)), float(config.a_of(t_hi)))


#: random admissible histories of the sensitivity envelope (and as many again to check it)
ENVELOPE_PATHS = 256
#: values of k (evenly over the task's k prior, ends included) whose envelopes the floor takes the largest of
K_FLOOR_NODES = 5
#: histories per k value on a task with a k prior: with 256, a low-field bin at k = 320 A/m came out 3.7x
#: above the envelope on the check histories, and the check's scaling carries that factor to every field
K_ENVELOPE_PATHS = 4 * ENVELOPE_PATHS


def calibration_floor(task: str, n_paths: int | None = None) -> dict:
    """The Van Trees floor of a calibration task (RMS error over its scored steps and the prior, A/m), with
    the pieces it is made of (``whole_episode``: the same over all steps). ``n_paths``: random histories of
    the envelope (default :data:`ENVELOPE_PATHS`, :data:`K_ENVELOPE_PATHS` per k value on a task with a k
    prior, where the envelope is the largest over :data:`K_FLOOR_NODES` values of k)."""
    from ..estimation.information_bound import SensitivityTable, episode_floor, sensitivity_table

    config = task_config_v2(task)
    setting = bound_setting(config)
    a_top = float(config.a_of(config.temperature_limit))
    k_prior = _spec(task).k_prior
    if n_paths is None:
        n_paths = ENVELOPE_PATHS if k_prior is None else K_ENVELOPE_PATHS
    k_values = [config.hysteresis.k] if k_prior is None else list(np.linspace(k_prior.low, k_prior.high, K_FLOOR_NODES))
    tables = [sensitivity_table(config.hysteresis.replace(k=float(k)), (setting.a_lo, a_top), config.field_limit,
                                config.max_field_change, config.max_field_step, n_paths=n_paths,
                                steps=config.episode_steps) for k in k_values]
    table = tables[0] if len(tables) == 1 else SensitivityTable(
        tables[0].fields, np.max([t.envelope for t in tables], axis=0), max(t.curve_ratio for t in tables),
        max(t.check_ratio for t in tables))
    first = _spec(task).scored_from
    floor = {"value": episode_floor(setting, table, first), "kind": "bound",
             "whole_episode": episode_floor(setting, table),
             "how": f"Van Trees: RMS over steps {first + 1}..{setting.steps} of 1/sqrt(J_prior + I_t), "
                    "I_t <= G^2 sum Phi^2/sigma^2 (slew-reach "
                    "envelope of |dM/da|, thermal limit relaxed); envelope from the initial curve and "
                    f"{n_paths} random admissible histories, checked on {n_paths} independent ones",
             "gain_per_Ms": float(setting.gain * config.hysteresis.Ms), "peak_sensitivity": float(table.envelope[-1]),
             "histories_over_initial_curve": table.curve_ratio, "check_ratio": table.check_ratio}
    if k_prior is not None:
        floor["ignores"] = (f"the uncertainty of k (uniform over {k_prior.low:g}..{k_prior.high:g} A/m): "
                            "the bound is the k-known one (conditional on k, Van Trees on a alone; knowing k can "
                            "only help, [J^-1]_aa >= 1/J_aa), with the sensitivity envelope taken as the largest over "
                            f"k = {', '.join(f'{k:g}' for k in k_values)} A/m (sampled like the histories, not "
                            "proven between them); "
                            "it is looser than a bound with k as a nuisance parameter")
        floor["k_nodes"] = [float(k) for k in k_values]
    return floor
