"""One class per task kind: what the benchmark does differently on an excitation, a calibration and a
drift-jump task (the metric, the statistic over draws, the agents' estimator, the draws recorded, the
floor and the kind's own agents). ``task_kind(task_id)`` picks the class from the task's
:class:`~hyst_gym.envs.task_spec.TaskSpec`.
"""

from __future__ import annotations

import numpy as np

from experiments.suite import common


class TaskKind:
    """A task the suite plays: ``id``, ``spec`` (its TaskSpec), ``config`` (its EnvConfig). The metric of a
    draw is the mean over the scored steps of ``|a_estimate - a_true| ** power`` (width(Theta) per step after
    an overheat)."""

    statistic_name = "iqm"
    power = 1
    #: sub-envs per batched play of the design family
    batch_size = 4096
    #: the family's feedback rules tuned and reported (name, design-name prefix)
    feedback_picks = (("thermostat", "thermostat_"), ("proportional", "proportional_"),
                      ("identify_then_idle", "gate_"))
    #: the estimator-swap agents (context) this kind plays under the tuned open-loop input
    context_estimators = ("gradient", "multiple_model")
    metric_words = ("mean |a_estimate - a_true| over the 200 steps, A/m (width(Theta) per step after an overheat), "
                    "IQM over draws")

    def __init__(self, task_id: str):
        from hyst_gym.envs.tasks import task_spec

        self.id = task_id
        self.spec = task_spec(task_id)
        self.config = self.spec.env_config()

    def metric(self, errors: np.ndarray) -> np.ndarray:
        """Per-draw metric from the (steps, draws) absolute errors."""
        first = self.spec.scored_from
        return np.sum(errors[first:] ** self.power, axis=0) / (errors.shape[0] - first)

    def statistic(self, scores) -> float:
        """The statistic over draws (and runs) of a (runs, draws) metric matrix: the IQM."""
        from baselines.stats import iqm

        return iqm(scores)

    def draws(self, env) -> dict:
        """What the reset drew per sub-env (recorded in the JSON)."""
        sim = env.sim
        return {"temperature": sim.temperature.copy(), "drift_rate": sim.drift_rate.copy()}

    def replicate_options(self, draws: dict, j: int) -> dict:
        """Reset options that repeat draw ``j``'s plant truth (the oracle's noise replicate)."""
        return {"initial_temperature": float(draws["temperature"][j]),
                "ambient_drift_rate": float(draws["drift_rate"][j])}

    def family(self):
        """The design family this kind tunes its feedback rules and open-loop input from."""
        return common.design_family()

    def field_agent(self, designs):
        """A DesignBank reading the estimate column of the task's observation."""
        import gymnasium

        import hyst_gym  # noqa: F401
        from baselines.suite_agents import DesignBank

        names = gymnasium.make(self.id).unwrapped.observation_names
        column = "a_estimate" if "a_estimate" in names else "previous_estimate"
        return DesignBank(designs, self.config, names.index(column))

    def design_agent(self, designs):
        """The agent that plays ``designs`` (one per sub-env, or one everywhere) on the task."""
        return self.field_agent(designs)

    def reference_agents(self, tuning, heldout, log=print) -> tuple:
        """The kind's simple references ({name: (kind, held-out scores)}, {name: tuned choice}); none here."""
        return {}, {}

    def context_agents(self, tuned_open_loop, heldout) -> dict:
        """Agents reported for context (kind ``estimator``): the env's estimator swapped, under the tuned input."""
        return {name: ("estimator", common.play(self.design_agent([tuned_open_loop]), self, heldout,
                                                overrides={"estimator": name})[0])
                for name in self.context_estimators}


class ExciteTask(TaskKind):
    """Suite v1's excitation tasks: the built-in min-max estimator identifies a; floor: the replicate oracle."""


class JumpTask(TaskKind):
    """The drift-jump task: a jumps at a drawn step; the min-max estimator must be re-excited."""

    def draws(self, env) -> dict:
        return {**super().draws(env), "jump_step": env.jump_step.copy(), "jump_change": env.jump_change.copy()}

    def replicate_options(self, draws: dict, j: int) -> dict:
        return {**super().replicate_options(draws, j), "jump_step": int(draws["jump_step"][j]),
                "jump_change": float(draws["jump_change"][j])}


#: the references' settings tuned on the tuning draws: ramp-and-hold peaks (A/m), bang-hold margins (K)
RAMP_HOLD_PEAKS = (4.0e4, 6.0e4, 8.0e4, 1.0e5)
BANG_HOLD_MARGINS = (1.0, 2.0, 5.0)


class CalibrateTask(TaskKind):
    """The calibration tasks: the agent designs the field and the task's env runs its estimator (the grid
    posterior, :class:`hyst_gym.envs.posterior.GridPosterior`) in the loop, so every agent plays with the same
    estimator; metric: the mean square error over the scored steps, RMS over draws; floor: a Van Trees bound."""

    statistic_name = "rms"
    power = 2
    batch_size = 512  # the calibration agents run 64 node simulators per sub-env
    feedback_picks = (("thermostat", "thermostat_"), ("proportional", "proportional_"))
    context_estimators = ()
    metric_words = ("RMS of a_estimate - a_true over steps 101..200 (the job after a 5 s warm-up) and the draws, "
                    "A/m (width(Theta) per step after an overheat)")

    def statistic(self, scores) -> float:
        return float(np.sqrt(np.mean(scores)))

    def draws(self, env) -> dict:
        draws = super().draws(env)
        if self.spec.k_prior is not None:
            draws["k"] = env.k_true
        return draws

    def family(self):
        """Without the designs that read the truth or the min-max estimator's tuning error (there is none)."""
        return [d for d in common.design_family() if not d.truth and d.gate is None]

    def reference_agents(self, tuning, heldout, log=print) -> tuple:
        """The worst-case-safe ramp-and-hold (open loop, its peak tuned) and the bang-hold rule (feedback, its
        margin tuned) of :mod:`baselines.references`, each best of its settings on the tuning draws."""
        import gymnasium

        import hyst_gym  # noqa: F401
        from baselines.references import BangHold, ramp_hold
        from baselines.suite_agents import Design

        names = gymnasium.make(self.id).unwrapped.observation_names
        column, spread = names.index("a_estimate"), names.index("estimate_spread")
        ramps = {}
        for peak in RAMP_HOLD_PEAKS:
            try:
                ramps[f"ramp_hold_{peak:g}"] = self.design_agent([Design(f"ramp_hold_{peak:g}",
                                                                         ramp_hold(self.config, peak))])
            except ValueError as error:  # a peak the hottest start cannot afford at all is not a candidate
                log(f"[suite v2] {self.id}: ramp_hold skips {peak:g} A/m: {error}")
        candidates = {"ramp_hold": ("open_loop", ramps),
                      "bang_hold": ("feedback", {f"bang_hold_{margin:g}": BangHold(self.config, column, margin,
                                                                                      spread_index=spread)
                                                 for margin in BANG_HOLD_MARGINS})}
        agents, tuned = {}, {}
        for name, (kind, options) in candidates.items():
            scores = {label: self.statistic(common.play(agent, self, tuning)[0][None, :])
                      for label, agent in options.items()}
            best = min(scores, key=scores.get)
            agents[name] = (kind, common.play(options[best], self, heldout)[0])
            tuned[name] = best
        log(f"[suite v2] {self.id}: references {tuned}")
        return agents, tuned

    def k_known_sibling(self) -> CalibrateTask | None:
        """The task with the same plant, limits and sensors but k known, for a task with a k prior (else None)."""
        from hyst_gym.envs.tasks import TASKS

        if self.spec.k_prior is None:
            return None
        return task_kind(next(other.id for other in TASKS.values() if other.kind == "calibrate"
                              and other.config == self.spec.config
                              and other.sensors_hidden == self.spec.sensors_hidden))


#: TaskSpec kind -> the class that plays it
KIND_CLASSES = {"excite": ExciteTask, "jump": JumpTask, "calibrate": CalibrateTask,
                "calibrate_unknown_k": CalibrateTask}


def task_kind(task_id: str) -> TaskKind:
    """The :class:`TaskKind` of a registered task id."""
    from hyst_gym.envs.tasks import task_spec

    return KIND_CLASSES[task_spec(task_id).kind](task_id)
