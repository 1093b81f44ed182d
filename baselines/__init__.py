"""Baseline agents: schedules, estimator-policies, optimal design, greedy information, RL.

Every agent has ``reset(seed)``, ``act(observation) -> action`` and SB3's
``predict(observation, state, episode_start, deterministic)`` (:mod:`baselines.agents`).

* :mod:`baselines.schedules` -- H(t) as pure functions of time, the common limits
  (:class:`~baselines.schedules.ExcitationLimits`, :func:`~baselines.schedules.apply_limits`)
  and the documented tuning grids;
* :mod:`baselines.optimal_design` -- CMA-ES multisine maximizing Fisher information about a
  (:mod:`baselines.information`);
* :mod:`baselines.greedy` -- receding-horizon information-maximizing input;
* :mod:`baselines.estimator_agents` -- min-max / gradient / multiple-model estimators as
  agents of ``Estimation-v0``;
* :mod:`baselines.rl` -- trained PPO/SAC policies with frame stacking, RecurrentPPO with an LSTM;
* :mod:`baselines.registry` -- any of them by name; :mod:`baselines.scenarios` -- the
  benchmark's scenarios and seed sets; :mod:`baselines.evaluation` -- the metrics;
* ``hyst-gym train`` (:mod:`baselines.train`) and ``hyst-gym evaluate`` (:mod:`baselines.evaluate`).
"""
