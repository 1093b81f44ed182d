"""Baseline agents: schedules, estimator-policies, optimal design, RL."""
