"""The experiment runner: raw files, resume, local parallelism, and the Ray backend."""

import csv
import json
import sys

import pytest

from baselines.evaluation import run_episodes
from baselines.registry import make_agent
from baselines.scenarios import HELDOUT_SEEDS, SCENARIOS
from experiments.config import Job, declared_jobs
from experiments.run import run

STAGES = [[Job("tune", "paper", "random", 0, (("episodes", 1),)),
           Job("design", "paper", "optimal_design", 0, (("evaluations", 12),))],
          [Job("eval", "paper", "random", 0, (("episodes", 2),)),
           Job("eval", "paper", "optimal_design", 0, (("episodes", 2),))]]


def _rows(path):
    with path.open() as handle:
        return list(csv.DictReader(handle))


def test_runner_writes_raw_results_resumes_and_matches_direct_evaluation(tmp_path):
    records = run(results=tmp_path, workers=2, stages=STAGES, progress=False)
    assert sorted(r["job"] for r in records) == sorted(j.key for stage in STAGES for j in stage)
    raw = tmp_path / "raw"
    tune = json.loads((raw / "tune" / "paper" / "random.json").read_text())
    assert len(tune["grid"]) == 4 and tune["best"] in [g["params"] for g in tune["grid"]]
    assert min(g["score"] for g in tune["grid"]) == next(g["score"] for g in tune["grid"]
                                                         if g["params"] == tune["best"])
    rows = _rows(raw / "eval" / "paper" / "random" / "run0.csv")
    assert [int(r["seed"]) for r in rows] == list(HELDOUT_SEEDS[:2])
    # the worker's result equals an in-process evaluation of the same tuned agent
    direct, _ = run_episodes(make_agent("random", SCENARIOS["paper"], raw), SCENARIOS["paper"].spec(),
                             HELDOUT_SEEDS[:2])
    assert [float(r["rms_error"]) for r in rows] == pytest.approx([d["rms_error"] for d in direct], rel=1e-12)
    assert sum(r["env_steps"] for r in records if r["kind"] == "eval") == 4 * SCENARIOS["paper"].episode_steps
    jobs_log = (raw / "jobs.jsonl").read_text().splitlines()
    assert len(jobs_log) == 4
    # resume: nothing left to do
    assert run(results=tmp_path, workers=1, stages=STAGES, progress=False) == []


RAY_STAGES = [[Job("design", "paper", "optimal_design", 0, (("evaluations", 12),))]]


def test_ray_backend_without_ray_says_how_to_get_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # makes ``import ray`` fail as if it were absent
    with pytest.raises(ValueError, match=r"pip install 'hyst-gym\[ray\]'"):
        run(results=tmp_path, backend="ray", stages=RAY_STAGES, progress=False)


def test_ray_local_cluster_runs_the_same_jobs_as_local(tmp_path):
    # ray is installed by scripts/setup.sh (extra "ray"), so this runs on a real local Ray cluster
    stages = RAY_STAGES
    ray_records = run(results=tmp_path / "ray", workers=2, backend="ray", stages=stages, progress=False)
    local_records = run(results=tmp_path / "local", workers=1, stages=stages, progress=False)
    assert [r["job"] for r in ray_records] == [r["job"] for r in local_records]
    ray_design = json.loads((tmp_path / "ray/raw/design/paper/optimal_design.json").read_text())
    local_design = json.loads((tmp_path / "local/raw/design/paper/optimal_design.json").read_text())
    assert ray_design["coefficients"] == local_design["coefficients"]


def test_declared_full_profile_meets_the_protocol():
    stages = declared_jobs("full")
    jobs = [j for stage in stages for j in stage]
    for config in ("ppo_stack8", "ppo_stack1", "ppo_lstm", "ppo_info_stack8", "sac_stack8"):
        seeds = {j.run for j in jobs if j.kind == "train" and j.scenario == "paper" and j.agent == config}
        assert len(seeds) >= 5
    evals = [j for j in jobs if j.kind == "eval"]
    assert all(j.option("episodes") >= 50 for j in evals)
    # the direct-search design is searched on the tuning draws of the paper and drift scenarios
    direct = {j.scenario: j for j in jobs if j.kind == "design" and j.agent == "direct_design"}
    assert set(direct) == {"paper", "drift"} and all(j.option("draws") >= 8 for j in direct.values())
    # every RL evaluation comes after its training stage
    train_stage = next(i for i, s in enumerate(stages) if any(j.kind == "train" for j in s))
    assert all(j.kind != "eval" or not j.agent.startswith(("ppo", "sac"))
               for stage in stages[:train_stage + 1] for j in stage)
    # generalization: the paper policies of every seed, and the paper baselines, on the FEM rod
    for scenario in ("paper_fem", "paper_fem_nonlinear"):
        played = {(j.agent, j.run) for j in evals if j.scenario == scenario}
        assert {("ppo_stack8", seed) for seed in range(5)} | {("optimal_design", 0), ("ramp", 0)} <= played
        assert all(j in stages[-1] for j in evals if j.scenario == scenario and j.agent.startswith("ppo"))
    with pytest.raises(ValueError, match="unknown profile"):
        declared_jobs("huge")


def test_rl_configs_are_trainable_and_a_changed_config_is_not_done(tmp_path):
    from baselines.rewards import REWARDS
    from baselines.rl import ALGORITHMS, RECURRENT_ALGORITHMS
    from baselines.train import DEFAULT_HYPERPARAMS
    from experiments.config import RL_CONFIGS
    from experiments.run import is_done

    for name, config in RL_CONFIGS.items():
        assert config.algo in ALGORITHMS and config.reward in REWARDS and config.n_stack >= 1, name
        assert config.algo not in RECURRENT_ALGORITHMS or config.n_stack == 1, name
        assert set(dict(config.hyperparams)) <= set(DEFAULT_HYPERPARAMS[config.algo]), name
    # a finished ppo_stack8 run saved before the reward was recorded (dense): done under its
    # own config, not done under a config with another reward or other hyperparameters
    folder = tmp_path / "raw" / "train" / "paper" / "ppo_stack8" / "seed0"
    folder.mkdir(parents=True)
    (folder / "model.zip").write_bytes(b"")
    saved = {"algo": "ppo", "n_stack": 8, "hyperparams": dict(DEFAULT_HYPERPARAMS["ppo"]), "trained_steps": 100}
    (folder / "config.json").write_text(json.dumps(saved))
    job = Job("train", "paper", "ppo_stack8", 0, (("timesteps", 100),))
    assert is_done(job, tmp_path / "raw")
    assert not is_done(Job("train", "paper", "ppo_stack8", 0, (("timesteps", 200),)), tmp_path / "raw")
    (folder / "config.json").write_text(json.dumps({**saved, "reward": "information"}))
    assert not is_done(job, tmp_path / "raw")


def test_a_grid_search_over_an_old_grid_and_stale_evaluations_are_not_done(tmp_path):
    import os

    from baselines.schedules import TUNING_GRIDS, grid_points
    from experiments.run import is_done

    raw = tmp_path / "raw"
    tuned = raw / "tune" / "paper" / "sine.json"
    tuned.parent.mkdir(parents=True)
    current = [{"params": p, "score": 1.0} for p in grid_points(TUNING_GRIDS["sine"])]
    tune = Job("tune", "paper", "sine", 0, (("episodes", 2),))
    tuned.write_text(json.dumps({"grid": current[:-1], "best": current[0]["params"]}))
    assert not is_done(tune, raw)  # the grid has a point this search never scored
    tuned.write_text(json.dumps({"grid": current, "best": current[0]["params"]}))
    assert is_done(tune, raw)
    evaluation = raw / "eval" / "paper" / "sine" / "run0.csv"
    evaluation.parent.mkdir(parents=True)
    evaluation.write_text("seed\n")
    played = Job("eval", "paper", "sine", 0, (("episodes", 2),))
    old = tuned.stat().st_mtime - 3600
    os.utime(evaluation, (old, old))
    assert not is_done(played, raw)  # it played the previous winner
    os.utime(evaluation, None)
    assert is_done(played, raw)
    # a redesigned input makes its evaluations stale the same way
    design = raw / "design" / "paper" / "optimal_design.json"
    design.parent.mkdir(parents=True)
    design.write_text("{}")
    designed = raw / "eval" / "paper" / "optimal_design" / "run0.csv"
    designed.parent.mkdir(parents=True)
    designed.write_text("seed\n")
    os.utime(designed, (old, old))
    assert not is_done(Job("eval", "paper", "optimal_design", 0, (("episodes", 2),)), raw)
    # the paper's ramp plays no tuning: its evaluation is current whenever it exists
    ramp = raw / "eval" / "paper" / "ramp" / "run0.csv"
    ramp.parent.mkdir(parents=True)
    ramp.write_text("seed\n")
    assert is_done(Job("eval", "paper", "ramp", 0, (("episodes", 2),)), raw)
