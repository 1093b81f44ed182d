"""Train PPO (Stable-Baselines3) on a benchmark suite task and save the policy.

    python examples/train_ppo_suite_task.py --timesteps 100000 --out ppo_hotcoil.zip

Needs the ``rl`` extra. The task is ``hyst_gym/HotCoil-v1``: drive a hot coil's field so that the
built-in estimator identifies ``a`` before the coil overheats.
"""
import argparse

from stable_baselines3 import PPO

from hyst_gym.envs import make_sb3_vec_env

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--timesteps", type=int, default=100_000, help="environment steps to train (default 100,000)")
parser.add_argument("--out", default="ppo_hotcoil.zip", help="where to save the policy")
args = parser.parse_args()

env = make_sb3_vec_env("hyst_gym/HotCoil-v1", num_envs=8, seed=0)      # native vector env, no subprocesses
model = PPO("MlpPolicy", env, n_steps=128, batch_size=256, seed=0, device="cpu", verbose=0)
model.learn(total_timesteps=args.timesteps, progress_bar=False)
model.save(args.out)
print(f"trained {args.timesteps} steps; saved {args.out}")
