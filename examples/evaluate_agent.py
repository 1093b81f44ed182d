"""Play one episode of a suite task and plot the estimate of a against the truth.

    python examples/evaluate_agent.py --policy ppo_hotcoil.zip --out estimate.png   # a trained PPO policy
    python examples/evaluate_agent.py --out estimate.png                              # a fixed sine input

The truth (``a_true``) lives in ``info`` only; the agent never sees it.
"""
import argparse

import gymnasium
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import hyst_gym  # noqa: E402,F401  (registers the ids)

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--policy",
                    help="a Stable-Baselines3 PPO .zip (default: a 0.5 Hz sine at 60 %% of the field limit)")
parser.add_argument("--seed", type=int, default=0)
parser.add_argument("--out", default="estimate.png")
args = parser.parse_args()

env = gymnasium.make("hyst_gym/HotCoil-v1")
if args.policy:
    from stable_baselines3 import PPO
    model = PPO.load(args.policy, device="cpu")
    act = lambda obs, t: model.predict(obs, deterministic=True)[0]           # noqa: E731
else:
    act = lambda obs, t: np.array([0.6 * np.sin(2 * np.pi * 0.5 * t)], dtype=np.float32)   # noqa: E731

obs, info = env.reset(seed=args.seed)
times, estimate, truth, temperature = [], [], [], []
done = False
while not done:
    obs, reward, terminated, truncated, info = env.step(act(obs, info["time"]))
    times.append(info["time"])
    estimate.append(info["a_estimate"])
    truth.append(info["a_true"])
    temperature.append(info["temperature"] - 273.15)
    done = terminated or truncated
error = np.mean(np.abs(np.subtract(estimate, truth)))
print(f"{len(times)} steps, mean |a_estimate - a_true| = {error:.1f} A/m, overheated: {terminated}")

fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
top.plot(times, truth, label="a true")
top.plot(times, estimate, label="a estimate")
top.set_ylabel("a (A/m)")
top.legend()
bottom.plot(times, temperature)
bottom.set_ylabel("coil (°C)")
bottom.set_xlabel("time (s)")
fig.savefig(args.out, dpi=100)
print(f"wrote {args.out}")
