"""Reward ablation: dense error reward, information increment, band time.

    python -m experiments.ablation_reward [--timesteps 50000] [--seeds 10] [--workers 2]
                                          [--arms dense,information,band] [--force]

Every arm is the committed ``ppo_stack8`` configuration in the ``paper`` scenario (PPO,
8 stacked frames, :data:`baselines.train.DEFAULT_HYPERPARAMS`, 8 sub-envs, training seeds
0..k-1) trained by the same :func:`baselines.train.train`; they differ only in its
``reward`` argument:

* ``dense`` -- the environment's own ``-|a_estimate - a_true|/width(Theta)`` (uses the truth);
* ``information`` -- :class:`baselines.rewards.InformationRewardVecEnv`, the per-step
  increment of the Fisher information about a at the estimate (uses no truth);
* ``band`` -- :class:`baselines.rewards.BandRewardVecEnv`, -1 per step outside the 0.1 %
  settle band: the benchmark's metric itself as the reward (uses the truth).

All arms are (re)trained here at the same budget so that they share the code and the
environment version, then evaluated by :func:`baselines.evaluation.run_episodes` on the
benchmark's 50 held-out draws (:data:`baselines.scenarios.HELDOUT_SEEDS`).

Writes (under ``experiments/results/``)::

    raw/ablation_reward/train/<arm>/seed<k>/   model.zip, config.json, learning_curve.csv
    raw/ablation_reward/eval/<arm>/run<k>.csv  one row per held-out episode
    ablation_reward.json                       IQM + 95 % stratified-bootstrap CI per arm and
                                               metric, P(arm better than dense)

TensorBoard logs and checkpoints are deleted after training (they are not results).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import pathlib
import platform
import shutil
import sys
import time

import numpy as np

from baselines.rewards import REWARDS

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
RAW = RESULTS / "raw" / "ablation_reward"
SUMMARY = RESULTS / "ablation_reward.json"
ARMS = REWARDS  # one arm per training reward of baselines/train.py
SCENARIO = "paper"
CONFIG = "ppo_stack8"
METRICS = ("settle_time_s", "integrated_error", "rms_error", "final_error")
EVAL_EVERY, EVAL_EPISODES = 5_000, 4  # as the committed full profile's learning curves


def train_and_evaluate(arm: str, seed: int, timesteps: int, raw: str) -> dict:
    """Train one (arm, seed) run and evaluate it on the held-out draws (any process)."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import baselines.train as training
    from baselines.evaluate import write_episodes_csv
    from baselines.evaluation import run_episodes
    from baselines.rl import PolicyAgent
    from baselines.scenarios import HELDOUT_SEEDS, SCENARIOS
    from experiments.config import RL_CONFIGS

    config = RL_CONFIGS[CONFIG]
    scenario = SCENARIOS[SCENARIO]
    folder = pathlib.Path(raw) / "train" / arm / f"seed{seed}"
    start = time.time()
    training.train(config.algo, scenario.spec(), timesteps, seed, folder, n_envs=8, n_stack=config.n_stack,
                   checkpoint_every=0, eval_every=EVAL_EVERY, eval_episodes=EVAL_EPISODES,
                   hyperparams=dict(config.hyperparams), resume=False, progress=False, scenario=SCENARIO,
                   reward=arm)
    train_wall = time.time() - start
    shutil.rmtree(folder / "tb", ignore_errors=True)
    shutil.rmtree(folder / "checkpoints", ignore_errors=True)
    saved = json.loads((folder / "config.json").read_text())
    agent = PolicyAgent.load(folder, name=f"{CONFIG}_{arm}")
    records, _ = run_episodes(agent, scenario.spec(), HELDOUT_SEEDS)
    write_episodes_csv(pathlib.Path(raw) / "eval" / arm / f"run{seed}.csv", records,
                       {"scenario": SCENARIO, "agent": f"{CONFIG}_{arm}", "run": seed, "reward": arm})
    return {"arm": arm, "seed": seed, "env_steps": int(saved["trained_steps"]), "train_wall_s": round(train_wall, 1),
            "wall_s": round(time.time() - start, 1)}


def _read_metric(arm, metric, raw=RAW, censored=True):
    from baselines.survival import censor

    rows = []
    for path in sorted((raw / "eval" / arm).glob("run*.csv")):
        with path.open() as handle:
            records = list(csv.DictReader(handle))
        values = np.array([float(r[metric]) for r in records])
        if metric == "settle_time_s" and censored:  # never settled: censored at the episode length, not dropped
            values = censor(values, max(float(r["episode_time_s"]) for r in records))[0]
        rows.append(values)
    return np.array(rows)


def summarize(raw=RAW, budget=None) -> dict:
    """Summary of the raw CSVs: per arm and metric ``{"iqm", "ci95", "n", "runs"}``, the
    success rate, and P(arm better than dense) with its interval for the other arms."""
    from baselines.stats import probability_of_improvement, probability_of_improvement_ci, summarize as stat

    out = {"scenario": SCENARIO, "config": CONFIG, "arms": {}, "probability_of_improvement": {}}
    scores = {}
    for arm in ARMS:
        out["arms"][arm] = {}
        for metric in METRICS:
            matrix = _read_metric(arm, metric, raw)
            if matrix.size == 0:
                continue
            scores[arm, metric] = matrix
            out["arms"][arm][metric] = {**stat(matrix), "runs": int(matrix.shape[0])}
        settle = _read_metric(arm, "settle_time_s", raw, censored=False)
        if settle.size:
            out["arms"][arm]["success_rate"] = float(np.mean(np.isfinite(settle)))
    for arm in ARMS[1:]:
        for metric in METRICS:
            if (arm, metric) in scores and ("dense", metric) in scores:
                x, y = scores[arm, metric], scores["dense", metric]
                out["probability_of_improvement"].setdefault(arm, {})[metric] = {
                    "over_dense": probability_of_improvement(x, y), "ci95": list(probability_of_improvement_ci(x, y))}
    if budget:
        out.update(budget)
    return out


def main(argv=None) -> int:
    from tqdm.auto import tqdm

    parser = argparse.ArgumentParser(prog="python -m experiments.ablation_reward", description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=50_000, help="env steps per run (committed ppo_stack8: 50000)")
    parser.add_argument("--seeds", type=int, default=10, help="training seeds 0..N-1 per arm (committed: 10)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--arms", default=",".join(ARMS))
    parser.add_argument("--force", action="store_true", help="retrain runs whose evaluation CSV exists")
    args = parser.parse_args(argv)
    arms = [a for a in args.arms.split(",") if a]
    if set(arms) - set(ARMS) or args.timesteps <= 0 or args.seeds <= 0 or args.workers <= 0:
        parser.error(f"--arms must be some of {ARMS}; --timesteps, --seeds, --workers > 0")
    jobs = [(arm, seed) for seed in range(args.seeds) for arm in arms
            if args.force or not (RAW / "eval" / arm / f"run{seed}.csv").exists()]
    start, records = time.time(), []
    bar = tqdm(total=len(jobs), unit="run", desc="ablation")
    if args.workers == 1:
        for job in jobs:
            records.append(train_and_evaluate(*job, args.timesteps, str(RAW)))
            bar.update()
    else:
        import concurrent.futures
        import multiprocessing

        context = multiprocessing.get_context("spawn")  # torch and numba threads do not survive fork
        with concurrent.futures.ProcessPoolExecutor(args.workers, mp_context=context) as pool:
            futures = [pool.submit(train_and_evaluate, *job, args.timesteps, str(RAW)) for job in jobs]
            for future in concurrent.futures.as_completed(futures):
                records.append(future.result())
                bar.set_postfix_str(f"{records[-1]['arm']} seed {records[-1]['seed']}", refresh=False)
                bar.update()
    bar.close()
    RAW.mkdir(parents=True, exist_ok=True)
    if records:
        with (RAW / "runs.jsonl").open("a") as handle:
            for record in records:
                handle.write(json.dumps(record) + "\n")
    runs = [json.loads(line) for line in (RAW / "runs.jsonl").read_text().splitlines() if line.strip()]
    budget = {"timesteps_per_run": args.timesteps, "training_seeds": args.seeds, "heldout_draws": 50,
              "env_steps_total": int(sum(r["env_steps"] for r in runs)),
              "train_wall_s_total": round(sum(r["train_wall_s"] for r in runs), 1),
              "worker_wall_s_total": round(sum(r["wall_s"] for r in runs), 1), "workers": args.workers,
              "machine": f"{platform.platform()}, {os.cpu_count()} CPUs (shared, loaded)",
              "command": "python -m experiments.ablation_reward "
                         + " ".join(argv if argv is not None else sys.argv[1:])}
    summary = summarize(RAW, budget)
    SUMMARY.write_text(json.dumps(summary, indent=2) + "\n")
    for arm, metrics in summary["arms"].items():
        if "settle_time_s" in metrics:
            m = metrics["settle_time_s"]
            print(f"[ablation] {arm:12s} settle IQM {m['iqm']:.2f} s [{m['ci95'][0]:.2f}, {m['ci95'][1]:.2f}], "
                  f"success {metrics['success_rate']:.0%}, runs {m['runs']}")
    print(f"[ablation] wrote {SUMMARY} ({time.time() - start:.0f} s wall)")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
