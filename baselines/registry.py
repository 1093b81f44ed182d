"""Build any benchmark agent by name.

Names (the keys of ``experiments/results/summary.json``):

* schedules: ``ramp`` (the paper's, untuned), ``ramp_tuned``, ``sine``, ``chirp``, ``prbs``,
  ``multisine`` (Schroeder phases), ``random`` -- the tuned ones read their grid-search
  winner from ``artifacts/tune/<scenario>/<name>.json``;
* ``optimal_design`` (CMA-ES at the nominal a) and ``optimal_design_prior`` (averaged over
  the temperature prior), and ``direct_design`` (CMA-ES on the simulated settle time or RMS
  error itself, :mod:`baselines.direct_design`), read from
  ``artifacts/design/<scenario>/<name>.json``;
* ``greedy_info`` -- the receding-horizon information-maximizing input;
* estimators as agents on ``Estimation-v0``: ``minmax``, ``gradient``, ``multiple_model``;
* a path to a trained model (folder with ``model.zip`` + ``config.json``).
"""

from __future__ import annotations

import json
import pathlib

from hyst_gym.estimation import ESTIMATORS

from .agents import ScheduleAgent
from .schedules import TUNING_GRIDS, make_schedule

SCHEDULE_AGENTS = ("ramp", "ramp_tuned", "sine", "chirp", "prbs", "multisine", "random")
DESIGN_AGENTS = ("optimal_design", "optimal_design_prior", "direct_design")
ESTIMATOR_AGENTS = tuple(ESTIMATORS)  # the estimation layer's registry, in its order
ADAPTIVE_AGENTS = ("greedy_info",)
ALL_NAMED_AGENTS = SCHEDULE_AGENTS + DESIGN_AGENTS + ADAPTIVE_AGENTS + ESTIMATOR_AGENTS


def default_schedule_params(name: str) -> dict:
    """The first grid point (``ramp``: the paper's setting)."""
    from .schedules import grid_points

    return grid_points(TUNING_GRIDS[name])[0]


def make_agent(name: str, scenario, artifacts=None):
    """Agent ``name`` for ``scenario`` (a :class:`~baselines.scenarios.Scenario`)."""
    artifacts = pathlib.Path(artifacts) if artifacts is not None else None
    if name in SCHEDULE_AGENTS:
        if name == "ramp":  # the paper's input: never tuned
            params = default_schedule_params(name)
        else:
            # A tuned schedule never falls back to its untuned grid point: that played
            # silently different numbers under the same name (5.80 s against 2.98 s for sine).
            if artifacts is None:
                raise OSError(f"agent {name!r} needs its tuned settings: pass the artifacts folder "
                              "(evaluate --artifacts; default: the checkout's experiments/results/raw)")
            tuned = artifacts / "tune" / scenario.source / f"{name}.json"
            if not tuned.exists():
                raise OSError(f"agent {name!r} needs its tuned settings: missing {tuned} "
                              "(run the 'tune' stage of experiments/run.py first)")
            params = json.loads(tuned.read_text())["best"]
        return ScheduleAgent(make_schedule(name, **params), scenario.limits, scenario.episode_steps, name=name)
    if name in DESIGN_AGENTS:
        from .optimal_design import MultisineDesign

        path = artifacts / "design" / scenario.source / f"{name}.json" if artifacts else None
        if path is None or not path.exists():
            raise OSError(f"agent {name!r} needs its design: run the 'design' job first (missing {path})")
        data = json.loads(path.read_text())
        if name == "direct_design":
            from .direct_design import KnotSchedule

            design = KnotSchedule(tuple(data["knots"]), data["episode_s"], data["field_max"])
        else:
            design = MultisineDesign(tuple(data["coefficients"]), data["period"], data["field_max"])
        return ScheduleAgent(design, scenario.limits, scenario.episode_steps, name=name)
    if name == "greedy_info":
        from .greedy import GreedyInformationAgent
        from .observation import estimate_reader

        return GreedyInformationAgent(scenario.limits, scenario.theta, scenario.nominal_a,
                                      estimate_of=estimate_reader(scenario))
    if name in ESTIMATOR_AGENTS:
        from .estimator_agents import EstimatorAgent

        return EstimatorAgent(name, scenario)
    path = pathlib.Path(name)
    if path.exists():
        from .rl import PolicyAgent

        return PolicyAgent.load(path)
    raise ValueError(f"unknown agent {name!r}: not one of {', '.join(ALL_NAMED_AGENTS)} and not a model path")


__all__ = ["SCHEDULE_AGENTS", "DESIGN_AGENTS", "ESTIMATOR_AGENTS", "ADAPTIVE_AGENTS", "ALL_NAMED_AGENTS",
           "make_agent", "default_schedule_params"]
