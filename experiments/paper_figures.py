"""Redraw the paper's Figures 2, 4 and 5 (Nealis & Smith) as PNG files.

    .venv/bin/python -m experiments.paper_figures [--out docs/figures/physics]

* Fig. 2: (a) the Ising anhysteretic curve (2); (b) the total magnetization (6) on a
  +-4e4 A/m loop, with the paper's parameters and, dashed, a visibly hysteretic set
  (k = 4000 A/m, alpha = -0.01) for comparison (see the README on why).
* Fig. 4: tip displacement of the lumped model (13) against the finite-element rod
  (10) linearized about the bias M0, with N = 2 and N = 256 elements, under a common
  M(t) from (6) driven by a 1 Hz, 4e4 A/m sine; a third panel (not in the paper) shows
  the FEM's difference from (13) lumped from the same rod under a step of M.
* Fig. 5: the H-M loop for a = 7012 and a = 6300 A/m (paper parameters), and the same
  pair for the visibly hysteretic set.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

DEFAULT_OUT = pathlib.Path(__file__).resolve().parents[1] / "docs" / "figures" / "physics"
HYSTERETIC = {"k": 4000.0, "alpha": -0.01}


def _loop_field(amplitude=4e4, cycles=2, samples_per_cycle=2000):
    phase = np.linspace(0.0, 2 * np.pi * cycles, cycles * samples_per_cycle + 1)
    return amplitude * np.sin(phase)


def figure_2(out: pathlib.Path, plt) -> pathlib.Path:
    from hyst_gym import simulate_magnetization
    from hyst_gym.physics import HysteresisParams, anhysteretic_magnetization

    p = HysteresisParams()
    field = _loop_field()
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.8))
    h = np.linspace(-4e4, 4e4, 801)
    man, _ = anhysteretic_magnetization(h, p.a, p.Ms, "ising")
    left.plot(h, man, "k")
    left.set(xlabel="applied field H (A/m)", ylabel="anhysteretic magnetization (A/m)", title="(a) Ising (2)")
    last_cycle = slice(field.size // 2, None)
    paper = simulate_magnetization(field)
    visible = simulate_magnetization(field, **HYSTERETIC)
    right.plot(field[last_cycle], paper[last_cycle], "k", label="paper parameters")
    right.plot(field[last_cycle], visible[last_cycle], "C3--", label="k=4000, alpha=-0.01")
    right.set(xlabel="applied field H (A/m)", ylabel="magnetization M (A/m)", title="(b) total magnetization (6)")
    right.legend(fontsize=8, loc="lower right")
    for ax in (left, right):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    path = out / "fig2_magnetization.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def figure_4(out: pathlib.Path, plt) -> pathlib.Path:
    from hyst_gym import simulate_magnetization
    from hyst_gym.physics import DEFAULT_BIAS_MAGNETIZATION, FEMRod, LumpedLinear, RodParams

    rod = RodParams()
    dt = 1e-3
    time = np.arange(3001) * dt
    magnetization = simulate_magnetization(4e4 * np.sin(2 * np.pi * time), time)
    lumped = LumpedLinear().discretize(dt).simulate(magnetization)
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, n in zip(axes[:2], (2, 256)):
        fem = FEMRod(rod, n, DEFAULT_BIAS_MAGNETIZATION).discretize(dt).simulate(magnetization)
        ax.plot(time, fem, "k", label=f"{n} basis elements")
        ax.plot(time, lumped, "C1--", label="lumped model (13)")
        ax.set(xlabel="time (s)", ylabel="tip position (m)",
               title=f"({'ab'[n == 256]}) N = {n}: max diff "
                     f"{np.max(np.abs(fem - lumped)) / np.max(np.abs(lumped)):.1e}")
        ax.legend(fontsize=8, loc="upper right")
        ax.grid(alpha=0.3)
    # Not in the paper: how large the differences get under a step of M (kHz content).
    fine_dt = 5e-6
    fine_time = np.arange(401) * fine_dt
    step = np.r_[0.0, np.full(fine_time.size - 1, 3e5)]
    from_rod = LumpedLinear.from_rod(rod).discretize(fine_dt).simulate(step)
    ax = axes[2]
    for n, style in ((2, "C0"), (256, "k")):
        fem = FEMRod(rod, n, DEFAULT_BIAS_MAGNETIZATION).discretize(fine_dt).simulate(step)
        ax.plot(fine_time * 1e3, (fem - from_rod) * 1e9, style, lw=1, label=f"FEM N = {n}")
    ax.set(xlabel="time (ms)", ylabel="FEM - lumped (13) from the rod (nm)",
           title=f"(c) step of M = 3e5 A/m; x settles at {from_rod[-1] * 1e6:.0f} um")
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path = out / "fig4_lumped_vs_fem.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def figure_5(out: pathlib.Path, plt) -> pathlib.Path:
    from hyst_gym import simulate_magnetization

    field = _loop_field()
    last_cycle = slice(field.size // 2, None)
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.8))
    for ax, (title, extra) in zip(axes, (("(a) paper parameters", {}),
                                         ("(b) k = 4000, alpha = -0.01", HYSTERETIC))):
        for a, style in ((7012.0, "k-"), (6300.0, "C3--")):
            magnetization = simulate_magnetization(field, a=a, **extra)
            ax.plot(field[last_cycle], magnetization[last_cycle], style, label=f"a = {a:.0f} A/m")
        ax.set(xlabel="applied field H (A/m)", ylabel="magnetization M (A/m)", title=title)
        ax.legend(fontsize=8, loc="lower right")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    path = out / "fig5_temperature.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=pathlib.Path, default=DEFAULT_OUT, help="folder for the PNG files")
    args = parser.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    args.out.mkdir(parents=True, exist_ok=True)
    for make in (figure_2, figure_4, figure_5):
        print(f"wrote {make(args.out, plt)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
