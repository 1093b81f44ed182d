"""``hyst-gym demo``: the end-to-end demo of the pipeline (the README's main job).

Stage 1 (physics): simulate the domain-wall model on the paper's and on a visibly
hysteretic parameter set and plot the loops. Later stages are appended by the
benchmark work (paper example, baselines, PPO, comparison table).
"""

from __future__ import annotations

import pathlib

import numpy as np


def configure_parser(parser):
    parser.add_argument("--out", default="demo_out", help="folder for figures and tables (default: demo_out)")


def physics_stage(out: pathlib.Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hyst_gym import simulate_magnetization

    time = np.linspace(0.0, 2.0, 4001)
    field = 1e5 * np.sin(2 * np.pi * time) * np.minimum(1.0, 0.5 + time / 2)
    fig, ax = plt.subplots(figsize=(5, 4))
    for label, params in (("paper (k=400, alpha=-0.1)", {}),
                          ("hysteretic (k=4000, alpha=-0.01)", {"k": 4000.0, "alpha": -0.01})):
        magnetization = simulate_magnetization(field, time, **params)
        ax.plot(field, magnetization, label=label)
    ax.set(xlabel="field H (A/m)", ylabel="magnetization M (A/m)", title="Domain-wall model (6)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "loops.png", dpi=120)
    plt.close(fig)
    print(f"[physics] wrote {out / 'loops.png'}")


def main(args) -> int:
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    physics_stage(out)
    return 0
