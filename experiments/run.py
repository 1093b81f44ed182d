"""Run the benchmark's declared experiments and save raw per-seed, per-episode results.

    python -m experiments.run [--profile full|smoke] [--workers N] [--backend local|ray]
                              [--scenarios paper,drift,lumped] [--results DIR] [--force]

Jobs come from :func:`experiments.config.declared_jobs` in two stages (tune / design /
train, then evaluate on the shared held-out draws). Within a stage jobs run in parallel:
``--workers N`` local processes, or ``--backend ray`` (optional extra ``hyst-gym[ray]``;
``--workers`` then sets the CPUs of the local Ray cluster). Both backends call the same
:func:`execute` and write the same files. A job whose output exists is skipped, so an
interrupted run resumes; ``--force`` reruns every job (a training run that reached its
steps is reloaded, not retrained; one saved under other settings than declared must be
moved away first: it is never continued under new settings).

Raw layout under ``--results`` (default ``experiments/results``)::

    raw/tune/<scenario>/<schedule>.json       grid-search scores and winner
    raw/design/<scenario>/<design>.json       CMA-ES design
    raw/train/<scenario>/<config>/seed<k>/    model.zip, config.json, learning_curve.csv
    raw/eval/<scenario>/<agent>/run<k>.csv    one row per held-out episode
    raw/eval/<scenario>/<agent>/run<k>.npz    traces of the first episodes (figures)
    raw/jobs.jsonl                            wall time and env steps of every job run
    raw/run_sessions.jsonl                    wall time of every invocation of this script
    raw/machine.json                          the machine
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import shutil
import sys
import time

import numpy as np

from .config import RL_CONFIGS, SCENARIO_NAMES, Job, declared_jobs

DEFAULT_RESULTS = pathlib.Path(__file__).resolve().parent / "results"
#: seconds an evaluation may predate its model and still count as current (see is_done)
CHECKOUT_SLACK_S = 5.0


def _output_path(job: Job, raw: pathlib.Path) -> pathlib.Path:
    if job.kind == "tune" or job.kind == "design":
        return raw / job.kind / job.scenario / f"{job.agent}.json"
    if job.kind == "train":
        return raw / "train" / job.scenario / job.agent / f"seed{job.run}" / "model.zip"
    return raw / "eval" / job.scenario / job.agent / f"run{job.run}.csv"


def is_done(job: Job, raw: pathlib.Path) -> bool:
    """Whether a job's output exists and is current: a training run has reached its
    timesteps under the declared settings (otherwise it is resumed), a grid search covered
    the current grid, and an evaluation is newer than the model, design or tuning it plays."""
    out = _output_path(job, raw)
    if not out.exists():
        return False
    if job.kind == "train":
        config = out.parent / "config.json"
        # a finished run under other settings is not done: rerunning it gives the resume error
        return (config.exists() and json.loads(config.read_text()).get("trained_steps", 0) >= job.option("timesteps")
                and not _changed_settings(job, out.parent))
    if job.kind == "tune":
        from baselines.schedules import TUNING_GRIDS, grid_points

        # a grid search over another grid (the grid was extended since) is not this job's
        searched = [point["params"] for point in json.loads(out.read_text()).get("grid", [])]
        return searched == grid_points(TUNING_GRIDS[job.agent])
    if job.kind == "eval":
        source = _evaluation_source(job, raw)
        # a git checkout writes both files in the same second in either order; a real
        # retraining or retuning makes the source newer than its old evaluation by far more
        return source is None or (source.exists()
                                  and out.stat().st_mtime >= source.stat().st_mtime - CHECKOUT_SLACK_S)
    return True


def _evaluation_source(job: Job, raw: pathlib.Path):
    """The file an evaluation plays (trained model, design or grid-search winner), or None for fixed agents."""
    from baselines.registry import DESIGN_AGENTS
    from baselines.schedules import TUNING_GRIDS

    scenario = _scenario(job)
    if job.agent in RL_CONFIGS:
        return raw / "train" / scenario.source / job.agent / f"seed{job.run}" / "model.zip"
    if job.agent in DESIGN_AGENTS:
        return raw / "design" / scenario.source / f"{job.agent}.json"
    tuned = raw / "tune" / scenario.source / f"{job.agent}.json"
    if job.agent in TUNING_GRIDS and job.agent != "ramp" and tuned.exists():
        return tuned
    return None


def execute(job: Job, results: str) -> dict:
    """Run one job (in any process) and return its bookkeeping record."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    raw = pathlib.Path(results) / "raw"
    out = _output_path(job, raw)
    out.parent.mkdir(parents=True, exist_ok=True)
    start = time.time()
    steps = {"tune": _tune, "design": _design, "train": _train, "eval": _evaluate}[job.kind](job, raw, out)
    return {"job": job.key, "kind": job.kind, "scenario": job.scenario, "agent": job.agent, "run": job.run,
            "wall_s": round(time.time() - start, 3), "env_steps": int(steps), "pid": os.getpid()}


def _scenario(job):
    from baselines.scenarios import SCENARIOS

    return SCENARIOS[job.scenario]


def _censored_settle(records, scenario):
    from baselines.survival import censor

    return censor([r["settle_time_s"] for r in records], scenario.episode_s)[0]


def _score(records, scenario):
    """Tuning criterion: IQM settle time (censored) in fixed-a scenarios, IQM RMS error in drift."""
    from baselines.stats import iqm

    if scenario.name == "drift":
        return iqm([r["rms_error"] for r in records])
    return iqm(_censored_settle(records, scenario)) + 1e-6 * iqm([r["integrated_error"] for r in records])


def _tune(job, raw, out):
    from baselines.agents import ScheduleAgent
    from baselines.evaluation import run_episodes
    from baselines.scenarios import TUNING_SEEDS
    from baselines.schedules import TUNING_GRIDS, grid_points, make_schedule

    scenario = _scenario(job)
    seeds = TUNING_SEEDS[:job.option("episodes", 10)]
    grid, steps = [], 0
    for params in grid_points(TUNING_GRIDS[job.agent]):
        agent = ScheduleAgent(make_schedule(job.agent, **params), scenario.limits, scenario.episode_steps)
        records, _ = run_episodes(agent, scenario.spec(), seeds)
        steps += sum(r["steps"] for r in records)
        grid.append({"params": params, "score": _score(records, scenario)})
    best = min(grid, key=lambda g: g["score"])
    out.write_text(json.dumps({"schedule": job.agent, "scenario": job.scenario, "seeds": list(seeds),
                               "criterion": "iqm rms_error" if scenario.name == "drift" else "iqm settle_time_s",
                               "grid": grid, "best": best["params"]}, indent=2))
    return steps


def _design(job, raw, out):
    from baselines.optimal_design import design_input

    scenario = _scenario(job)
    if job.agent == "direct_design":
        return _direct_design(job, scenario, out)
    a_values = scenario.prior_a if job.agent.endswith("_prior") else (scenario.nominal_a,)
    period = min(scenario.episode_s, 6.0)
    result = design_input(scenario.limits, a_values, period=period, max_evaluations=job.option("evaluations", 400),
                          seed=job.run)
    out.write_text(json.dumps({"design": job.agent, "scenario": job.scenario, "a_values": list(a_values),
                               "coefficients": list(result.design.coefficients), "period": period,
                               "field_max": scenario.limits.field_max, "log_information": result.log_information,
                               "evaluations": result.evaluations, "history": list(result.history)}, indent=2))
    return 0


def _direct_design(job, scenario, out):
    """CMA-ES on the tuning criterion itself (the schedules' grid-search score, tuning draws)."""
    from baselines.agents import ScheduleAgent
    from baselines.direct_design import search_direct_design
    from baselines.evaluation import run_episodes
    from baselines.scenarios import TUNING_SEEDS

    seeds = TUNING_SEEDS[:job.option("draws", 8)]
    steps = []

    def score(schedule):
        records, _ = run_episodes(ScheduleAgent(schedule, scenario.limits, scenario.episode_steps), scenario.spec(),
                                  seeds)
        steps.append(sum(r["steps"] for r in records))
        return _score(records, scenario)

    result = search_direct_design(score, scenario.limits, scenario.episode_s, n_knots=job.option("knots", 16),
                                  max_evaluations=job.option("evaluations", 400), seed=job.run)
    out.write_text(json.dumps({"design": job.agent, "scenario": job.scenario, "seeds": list(seeds),
                               "criterion": "iqm rms_error" if scenario.name == "drift" else "iqm settle_time_s",
                               "knots": list(result.schedule.knots), "episode_s": result.schedule.episode_s,
                               "field_max": result.schedule.field_max, "score": result.score,
                               "evaluations": result.evaluations, "history": list(result.history)}, indent=2))
    return int(sum(steps))


def _changed_settings(job, folder):
    from baselines.train import DEFAULT_HYPERPARAMS, changed_settings

    config = RL_CONFIGS[job.agent]
    return changed_settings(folder, config.algo, config.n_stack, config.reward,
                            {**DEFAULT_HYPERPARAMS[config.algo], **dict(config.hyperparams)})


def _train(job, raw, out):
    from baselines.train import train

    config = RL_CONFIGS[job.agent]
    scenario = _scenario(job)
    folder = out.parent
    timesteps = job.option("timesteps")
    hyperparams = dict(config.hyperparams)
    # resumes a run cut short; refuses (one-line error) a run saved under other settings
    train(config.algo, scenario.spec(), timesteps, job.run, folder, n_envs=8, n_stack=config.n_stack,
          checkpoint_every=max(timesteps // 2, 1), eval_every=job.option("eval_every", 0),
          eval_episodes=job.option("eval_episodes", 8), hyperparams=hyperparams, resume=True,
          progress=False, scenario=job.scenario, reward=config.reward)
    shutil.rmtree(folder / "checkpoints", ignore_errors=True)  # model.zip is the final state
    return timesteps


def _evaluate(job, raw, out):
    from baselines.evaluate import write_episodes_csv
    from baselines.evaluation import run_episodes
    from baselines.registry import ESTIMATOR_AGENTS, make_agent
    from baselines.rl import PolicyAgent
    from baselines.scenarios import ESTIMATION_ID, EXCITATION_ID, HELDOUT_SEEDS, SCENARIOS
    from baselines.transfer import adapt_agent

    scenario = _scenario(job)
    if job.agent in RL_CONFIGS:
        agent = PolicyAgent.load(raw / "train" / scenario.source / job.agent / f"seed{job.run}", name=job.agent)
        agent = adapt_agent(agent, SCENARIOS[scenario.source], scenario)  # e.g. y -> tip displacement on the rod
    else:
        agent = make_agent(job.agent, scenario, raw)
    env_id = ESTIMATION_ID if job.agent in ESTIMATOR_AGENTS else EXCITATION_ID
    seeds = HELDOUT_SEEDS[:job.option("episodes", 50)]
    records, traces = run_episodes(agent, scenario.spec(env_id), seeds, keep_traces=3)
    write_episodes_csv(out, records, {"scenario": job.scenario, "agent": job.agent, "run": job.run, "env": env_id})
    np.savez_compressed(out.with_suffix(".npz"), **{f"{k}_{i}": np.asarray(v, dtype=np.float32)
                                                     for i, t in enumerate(traces) for k, v in t.items()})
    return sum(r["steps"] for r in records)


def run_stage(jobs, results, workers=1, backend="local", progress=True):
    """Run independent jobs; returns their records (skipped jobs are not rerun)."""
    from tqdm.auto import tqdm

    if not jobs:
        return []
    if backend == "ray":
        return _run_ray(jobs, results, workers)
    if backend != "local":
        raise ValueError(f"unknown backend {backend!r}; expected 'local' or 'ray'")
    records = []
    bar = tqdm(total=len(jobs), unit="job", disable=not progress, desc="jobs")
    if workers <= 1:
        for job in jobs:
            records.append(execute(job, str(results)))
            bar.set_postfix_str(job.key, refresh=False)
            bar.update()
    else:
        import concurrent.futures
        import multiprocessing

        context = multiprocessing.get_context("spawn")  # torch and numba threads do not survive fork
        with concurrent.futures.ProcessPoolExecutor(workers, mp_context=context) as pool:
            futures = {pool.submit(execute, job, str(results)): job for job in jobs}
            for future in concurrent.futures.as_completed(futures):
                records.append(future.result())
                bar.set_postfix_str(futures[future].key, refresh=False)
                bar.update()
    bar.close()
    return records


def _run_ray(jobs, results, workers):
    try:
        import ray
    except ImportError:
        raise ValueError("--backend ray needs Ray, an optional extra: pip install 'hyst-gym[ray]'") from None
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(num_cpus=max(int(workers), 1), include_dashboard=False, log_to_driver=False,
                 runtime_env={"env_vars": {"OMP_NUM_THREADS": "1"}})
    try:
        remote = ray.remote(num_cpus=1)(execute)
        return ray.get([remote.remote(job, str(results)) for job in jobs])
    finally:
        if started_here:
            ray.shutdown()


def run(profile="full", results=DEFAULT_RESULTS, workers=1, backend="local", scenarios=SCENARIO_NAMES,
        force=False, progress=True, stages=None):
    """Run the declared stages of ``profile`` (or the given ``stages``); returns the job records."""
    results = pathlib.Path(results)
    raw = results / "raw"
    raw.mkdir(parents=True, exist_ok=True)
    (raw / "machine.json").write_text(json.dumps(
        {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
         "cpu_count": os.cpu_count(), "python": sys.version.split()[0], "workers": workers, "backend": backend,
         "profile": profile}, indent=2))
    all_records, start = [], time.time()
    for stage in (declared_jobs(profile, scenarios) if stages is None else stages):
        todo = [j for j in stage if force or not is_done(j, raw)]
        # training first (longest), then paper/drift before generalization, so that the pool
        # stays busy and the main results come first
        todo.sort(key=lambda j: (j.kind != "train", j.kind != "tune", j.scenario.startswith("drift_"), j.key))
        records = run_stage(todo, results, workers, backend, progress)
        with (raw / "jobs.jsonl").open("a") as handle:
            for record in records:
                handle.write(json.dumps(record) + "\n")
        all_records += records
    if all_records:
        with (raw / "run_sessions.jsonl").open("a") as handle:
            handle.write(json.dumps({"wall_s": round(time.time() - start, 1), "jobs_run": len(all_records),
                                     "workers": workers, "backend": backend, "profile": profile}) + "\n")
    return all_records


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.run", description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="full", help="full (committed results) or smoke")
    parser.add_argument("--workers", type=int, default=1, help="parallel local processes (or Ray CPUs)")
    parser.add_argument("--backend", default="local", choices=("local", "ray"))
    parser.add_argument("--scenarios", default=",".join(SCENARIO_NAMES))
    parser.add_argument("--results", default=str(DEFAULT_RESULTS))
    parser.add_argument("--force", action="store_true", help="rerun jobs whose output exists")
    args = parser.parse_args(argv)
    scenarios = tuple(s for s in args.scenarios.split(",") if s)
    unknown = set(scenarios) - set(SCENARIO_NAMES)
    if unknown:
        parser.error(f"unknown scenario(s) {sorted(unknown)}; expected some of {SCENARIO_NAMES}")
    if args.workers < 1:
        parser.error(f"--workers must be >= 1, got {args.workers}")
    start = time.time()
    try:
        records = run(args.profile, args.results, args.workers, args.backend, scenarios, args.force)
    except ValueError as error:
        parser.exit(2, f"experiments.run: error: {error}\n")
    print(f"[run] {len(records)} jobs, {sum(r['env_steps'] for r in records):,} env steps, "
          f"{time.time() - start:.0f} s wall")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
