"""Simulate hysteresis loops with the physics layer: major and minor loops of model (6).

    python examples/simulate_loops.py --out loops.png
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import hyst_gym  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default="loops.png")
args = parser.parse_args()

fig, axis = plt.subplots(figsize=(6, 4.5))
phase = np.linspace(0.0, 4 * np.pi, 4001)                  # two periods: the first settles the loop
for amplitude in (2.5e4, 5e4, 1e5):                         # A/m
    field = amplitude * np.sin(phase)
    magnetization = hyst_gym.simulate_magnetization(field, a=5000, k=1500, c=0.3)   # A/m, from M = 0
    last = phase >= 2 * np.pi
    axis.plot(field[last] / 1e3, magnetization[last] / 1e3, label=f"{amplitude / 1e3:.0f} kA/m")
    width = np.ptp(magnetization[last]) / 1e3
    print(f"amplitude {amplitude / 1e3:5.0f} kA/m: M spans {width:7.1f} kA/m")
axis.set_xlabel("H (kA/m)")
axis.set_ylabel("M (kA/m)")
axis.legend(title="peak field")
fig.savefig(args.out, dpi=100)
print(f"wrote {args.out}")
