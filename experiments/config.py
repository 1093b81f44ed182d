"""The declared list of experiment configurations.

:func:`declared_jobs` returns the jobs of a *profile* in dependency stages: stage 0
tunes the schedules, designs the optimal inputs and trains the RL policies; stage 1
evaluates every agent on the shared held-out draws (baselines run beside the training,
RL policies after it). Profiles:

* ``full`` -- the committed run (``experiments/results/``), 10 training seeds per RL
  config, sized for about 1 h on 2 CPU cores;
* ``smoke`` -- the same pipeline at toy size, for the tests and a quick check.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from baselines.registry import DESIGN_AGENTS, ESTIMATOR_AGENTS, SCHEDULE_AGENTS
from baselines.scenarios import SCENARIOS


@dataclass(frozen=True)
class Job:
    """One unit of work. ``kind`` is ``tune``, ``design``, ``train`` or ``eval``.

    ``agent`` is a baseline name, or ``<algo>_<variant>`` for RL (``ppo_stack8``); ``run``
    is the training seed (0 for deterministic baselines); ``options`` holds sizes.
    """

    kind: str
    scenario: str
    agent: str
    run: int = 0
    options: tuple = field(default_factory=tuple)

    @property
    def key(self) -> str:
        return f"{self.kind}/{self.scenario}/{self.agent}/run{self.run}"

    def option(self, name, default=None):
        return dict(self.options).get(name, default)


@dataclass(frozen=True)
class RLConfig:
    """One RL configuration: ``algo`` (:data:`baselines.rl.ALGORITHMS`), ``n_stack`` frames
    of history, the training ``reward`` (:data:`baselines.rewards.REWARDS`), and
    ``hyperparams`` overriding :data:`baselines.train.DEFAULT_HYPERPARAMS` as (name, value) pairs."""

    algo: str
    n_stack: int
    reward: str = "dense"
    hyperparams: tuple = ()


#: RL configurations by name. ``stack8``: 8 frames of history; ``stack1`` (no history) and
#: ``lstm`` (a recurrent policy, one frame) are the history ablation; ``info``: trained on
#: the Fisher-information increment instead of the dense error (uses no truth), for 300k
#: steps (its validation settle time stopped improving from about there in a probe of two
#: seeds run to 1M steps, not part of the committed results).
#: RecurrentPPO's minibatch is 2048 steps: at 256 it trains about 4x slower (measured) for
#: the same steps.
RL_CONFIGS = {
    "ppo_stack8": RLConfig("ppo", 8),
    "ppo_stack1": RLConfig("ppo", 1),
    "ppo_lstm": RLConfig("recurrent_ppo", 1, hyperparams=(("batch_size", 2048),)),
    "ppo_info_stack8": RLConfig("ppo", 8, reward="information"),
    "ppo_lstm_info": RLConfig("recurrent_ppo", 1, reward="information", hyperparams=(("batch_size", 2048),)),
    "sac_stack8": RLConfig("sac", 8),
}

PROFILES = {
    # timesteps and eval_every: per algorithm, or per config name where it differs
    "full": {"rl_seeds": 10, "timesteps": {"ppo": 50_000, "sac": 50_000, "recurrent_ppo": 50_000,
                                          "ppo_info_stack8": 300_000, "ppo_lstm_info": 300_000},
             "episodes": 50, "tuning_episodes": 3, "design_evaluations": 300, "direct_evaluations": 400,
             "tuning_draws_direct": 8, "rl_scenarios": ("paper", "drift"),
             "drift_timesteps": {"ppo": 50_000, "ppo_info_stack8": 300_000},
             "eval_every": {"ppo": 5_000, "sac": 5_000, "recurrent_ppo": 5_000, "ppo_info_stack8": 25_000,
                            "ppo_lstm_info": 25_000},
             "eval_episodes": 4, "rl_configs": ("ppo_stack8", "ppo_stack1", "ppo_lstm", "ppo_info_stack8",
                                                "ppo_lstm_info", "sac_stack8"),
             "drift_rl_configs": ("ppo_stack8", "ppo_info_stack8"), "generalization": True},
    "smoke": {"rl_seeds": 1, "timesteps": {"ppo": 512, "sac": 300}, "episodes": 3, "tuning_episodes": 2,
              "design_evaluations": 30, "direct_evaluations": 12, "tuning_draws_direct": 2,
              "rl_scenarios": ("paper",), "drift_timesteps": {"ppo": 512, "sac": 300},
              "eval_every": {"ppo": 256, "sac": 0}, "eval_episodes": 2, "rl_configs": ("ppo_stack8",),
              "drift_rl_configs": (), "generalization": False},
}

SCENARIO_NAMES = ("paper", "drift", "lumped")
#: Agents run in the lumped scenario (its plant is slow to simulate, so the set is reduced;
#: RL is trained in the paper and drift scenarios only).
LUMPED_AGENTS = ("ramp", "sine", "optimal_design", "minmax", "multiple_model")
#: Generalization: evaluation-only scenarios and the agents run
#: there; each plays the artifacts of its ``Scenario.trained_in`` (drift or paper).
GENERALIZATION = {"drift_hot": ("sine", "ppo_stack8", "ppo_info_stack8"),
                  "drift_noisy": ("sine", "ppo_stack8", "ppo_info_stack8"),
                  "paper_fem": ("ramp", "sine", "optimal_design", "ppo_stack8", "ppo_info_stack8"),
                  "paper_fem_nonlinear": ("ramp", "sine", "optimal_design", "ppo_stack8")}


def _per_config(sizes: dict, config: str, algo: str):
    """A profile size given per config name where it differs, else per algorithm."""
    return sizes[config] if config in sizes else sizes[algo]


def declared_jobs(profile: str = "full", scenarios=SCENARIO_NAMES):
    """Stages (lists of :class:`Job`) of ``profile``, restricted to ``scenarios``:
    [tuning and designs], [RL training and baseline evaluations], [RL evaluations]."""
    try:
        p = PROFILES[profile]
    except KeyError:
        raise ValueError(f"unknown profile {profile!r}; expected one of {sorted(PROFILES)}") from None
    prep, evals = [], []
    for scenario in scenarios:
        sizes = (("episodes", p["tuning_episodes"]),)
        keep = (lambda name: name in LUMPED_AGENTS) if scenario == "lumped" else (lambda name: True)
        for name in filter(keep, SCHEDULE_AGENTS):
            if name != "ramp":
                prep.append(Job("tune", scenario, name, 0, sizes))
            evals.append(Job("eval", scenario, name, 0, (("episodes", p["episodes"]),)))
        for name in filter(keep, DESIGN_AGENTS):
            design_sizes = ((("evaluations", p["direct_evaluations"]), ("draws", p["tuning_draws_direct"]))
                            if name == "direct_design" else (("evaluations", p["design_evaluations"]),))
            prep.append(Job("design", scenario, name, 0, design_sizes))
            evals.append(Job("eval", scenario, name, 0, (("episodes", p["episodes"]),)))
        for name in filter(keep, ("greedy_info",) + ESTIMATOR_AGENTS):
            evals.append(Job("eval", scenario, name, 0, (("episodes", p["episodes"]),)))
        if scenario in p["rl_scenarios"]:
            configs = p["rl_configs"] if scenario == "paper" else p["drift_rl_configs"]
            steps = p["timesteps"] if scenario == "paper" else p["drift_timesteps"]
            for config in configs:
                algo = RL_CONFIGS[config].algo
                for seed in range(p["rl_seeds"]):
                    prep.append(Job("train", scenario, config, seed,
                                    (("timesteps", _per_config(steps, config, algo)),
                                     ("eval_every", _per_config(p["eval_every"], config, algo)),
                                     ("eval_episodes", p["eval_episodes"]))))
                    evals.append(Job("eval", scenario, config, seed, (("episodes", p["episodes"]),)))
    for scenario, agents in GENERALIZATION.items():
        source = SCENARIOS[scenario].trained_in
        if source not in scenarios or not p.get("generalization", True):
            continue
        trained = p["rl_configs"] if source == "paper" else p["drift_rl_configs"]
        if source not in p["rl_scenarios"]:
            trained = ()
        for agent in agents:
            if agent in RL_CONFIGS:
                evals += [Job("eval", scenario, agent, seed, (("episodes", p["episodes"]),))
                          for seed in range(p["rl_seeds"]) if agent in trained]
            else:
                evals.append(Job("eval", scenario, agent, 0, (("episodes", p["episodes"]),)))
    train = [j for j in prep if j.kind == "train"]
    baseline_evals = [j for j in evals if j.agent not in RL_CONFIGS]
    rl_evals = [j for j in evals if j.agent in RL_CONFIGS]
    return [[j for j in prep if j.kind != "train"], train + baseline_evals, rl_evals]


__all__ = ["Job", "RLConfig", "RL_CONFIGS", "PROFILES", "SCENARIO_NAMES", "declared_jobs"]
