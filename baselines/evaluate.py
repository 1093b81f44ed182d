"""``hyst-gym evaluate``: run one agent on seeded episodes and write per-episode CSV.

``--agent`` is a baseline name (see :mod:`baselines.registry`) or the folder/zip of a
trained policy. Episodes use the benchmark's held-out seeds (the first ``--episodes``
of them) unless ``--seed`` gives another start, so results are comparable across agents.
Writes ``episodes.csv`` (one row per episode, :data:`~baselines.evaluation.METRICS`)
and prints the IQM of the settle time and of the RMS error.
"""

from __future__ import annotations

import csv
import pathlib

import numpy as np

from hyst_gym.envs.registration import ENV_IDS

from .evaluation import run_episodes
from .registry import ALL_NAMED_AGENTS, ESTIMATOR_AGENTS, make_agent
from .rl import PolicyAgent
from .scenarios import ESTIMATION_ID, EXCITATION_ID, HELDOUT_SEEDS, SCENARIOS


def configure_parser(parser):
    parser.add_argument("--agent", required=True,
                        help=f"baseline name ({', '.join(ALL_NAMED_AGENTS)}) or the folder/zip of a trained model")
    parser.add_argument("--env", choices=sorted(ENV_IDS), default=None,
                        help=f"environment id (default {EXCITATION_ID}; {ESTIMATION_ID} for estimator agents)")
    parser.add_argument("--scenario", choices=sorted(SCENARIOS), default="paper",
                        help="environment settings (default: the paper's case)")
    parser.add_argument("--episodes", type=int, default=50,
                        help=f"episodes to run (> 0; default 50, the {len(HELDOUT_SEEDS)} held-out draws)")
    parser.add_argument("--seed", type=int, default=None,
                        help="first seed, >= 0; episode i uses seed + i (default: the held-out set)")
    parser.add_argument("--artifacts", default=str(COMMITTED_ARTIFACTS),
                        help="folder with tuned schedules and designs (default: the committed "
                             "experiments/results/raw of this checkout, from any working directory)")
    parser.add_argument("--out", required=True, help="output folder (episodes.csv is written into it)")


#: the committed tuning and design results beside the package (present in a source checkout)
COMMITTED_ARTIFACTS = pathlib.Path(__file__).resolve().parents[1] / "experiments" / "results" / "raw"


def write_episodes_csv(path, records, extra=None):
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [{**(extra or {}), **r} for r in records]
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


def _check_policy_fits(agent: PolicyAgent, spec, label: str, path: str) -> None:
    """A policy trained elsewhere is refused in our words, before SB3 finds the mismatch."""
    env = spec.make()
    try:
        agent.check_env(label, int(np.prod(env.observation_space.shape)), int(np.prod(env.action_space.shape)))
    except ValueError as error:
        raise ValueError(f"--agent {path}: {error}") from None
    finally:
        env.close()


def main(args) -> int:
    from baselines.stats import iqm
    from baselines.survival import censor

    if args.episodes <= 0:
        raise ValueError(f"--episodes must be > 0, got {args.episodes}")
    if args.seed is not None and args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    if not pathlib.Path(args.artifacts).is_dir():
        raise ValueError(f"--artifacts {args.artifacts}: no such folder")
    scenario = SCENARIOS[args.scenario]
    env_id = args.env or (ESTIMATION_ID if args.agent in ESTIMATOR_AGENTS else EXCITATION_ID)
    agent = make_agent(args.agent, scenario, args.artifacts)
    if isinstance(agent, PolicyAgent):
        _check_policy_fits(agent, scenario.spec(env_id), f"{env_id} ({scenario.name})", args.agent)
    if args.seed is None:
        seeds = list(HELDOUT_SEEDS[:args.episodes])
        if args.episodes > len(HELDOUT_SEEDS):
            seeds += list(range(HELDOUT_SEEDS[-1] + 1, HELDOUT_SEEDS[0] + args.episodes))
    else:
        seeds = list(range(args.seed, args.seed + args.episodes))
    records, _ = run_episodes(agent, scenario.spec(env_id), seeds)
    path = write_episodes_csv(pathlib.Path(args.out) / "episodes.csv", records,
                              {"agent": getattr(agent, "name", args.agent), "scenario": scenario.name, "env": env_id})
    settle, observed = censor([r["settle_time_s"] for r in records], scenario.episode_s)
    print(f"[evaluate] {args.agent} on {env_id} ({scenario.name}), {len(records)} episodes: "
          f"settle-time IQM {iqm(settle):.3f} s (settled {observed.mean():.0%}), "
          f"RMS-error IQM {iqm([r['rms_error'] for r in records]):.2f} A/m")
    print(f"[evaluate] wrote {path}")
    return 0


__all__ = ["configure_parser", "main", "write_episodes_csv"]
