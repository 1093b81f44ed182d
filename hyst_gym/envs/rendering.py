"""Rendering of an episode: the H-M loop so far, the output, and a_estimate against a_true.

Uses matplotlib's Agg canvas (no display needed) for ``rgb_array`` frames and PNG files;
``"human"`` mode opens an interactive window when a GUI backend is available.
"""

from __future__ import annotations

import numpy as np

FIGURE_SIZE = (9.0, 3.0)  # inches
DPI = 80


def _columns(history):
    keys = ("time", "field", "magnetization", "output", "a_true", "a_estimate", "temperature")
    if not history:
        return {key: np.zeros(0) for key in keys}
    return {key: np.array([record[key] for record in history]) for key in keys}


def draw_figure(history, config, title: str = "", figure=None):
    """Draw one episode (list of per-step records) on a matplotlib Figure and return it."""
    from matplotlib.figure import Figure
    data = _columns(history)
    if figure is None:
        figure = Figure(figsize=FIGURE_SIZE, dpi=DPI)
    else:
        figure.clear()
    axes = figure.subplots(1, 3)
    loop, out, est = axes
    loop.plot(data["field"] / 1e3, data["magnetization"] / 1e3, lw=1.0, color="tab:blue")
    loop.set_xlabel("H (kA/m)")
    loop.set_ylabel("M (kA/m)")
    loop.set_title("H-M loop")
    loop.set_xlim(-config.field_limit / 1e3, config.field_limit / 1e3)
    loop.set_ylim(-config.hysteresis.Ms / 1e3 * 1.05, config.hysteresis.Ms / 1e3 * 1.05)
    label = "displacement (um)" if config.is_mechanical else "y"
    scale = 1e6 if config.is_mechanical else 1.0
    out.plot(data["time"], data["output"] * scale, lw=1.0, color="tab:green")
    out.set_xlabel("t (s)")
    out.set_ylabel(label)
    out.set_title("output")
    out.set_xlim(0.0, config.episode_duration)
    est.plot(data["time"], data["a_true"], lw=1.5, color="k", label="a_true")
    est.plot(data["time"], data["a_estimate"], lw=1.0, color="tab:red", label="a_estimate")
    est.set_ylim(config.theta_min, config.theta_max)
    est.set_xlim(0.0, config.episode_duration)
    est.set_xlabel("t (s)")
    est.set_ylabel("a (A/m)")
    est.set_title("estimate")
    est.legend(loc="lower right", fontsize=7)
    if title:
        figure.suptitle(title, fontsize=9)
    figure.tight_layout()
    return figure


def figure_to_array(figure) -> np.ndarray:
    """An (H, W, 3) uint8 RGB array of a Figure drawn with the Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def show_human(figure, history, config, title=""):
    """Draw into (or open) an interactive pyplot window; returns the figure to reuse."""
    import matplotlib.pyplot as plt
    if figure is None:
        figure = plt.figure(figsize=FIGURE_SIZE, dpi=DPI)
    draw_figure(history, config, title, figure=figure)
    figure.canvas.draw_idle()
    plt.pause(0.001)
    return figure


def close_figure(figure) -> None:
    import matplotlib.pyplot as plt
    plt.close(figure)


def save_episode_figure(env, path, title: str | None = None) -> str:
    """Save the figure of ``env``'s current episode to a PNG file; returns the path.

    ``env`` is a hyst-gym single env (wrapped or not) made with a ``render_mode`` (so that
    it records its episode).
    """
    import os
    base = getattr(env, "unwrapped", env)
    if not hasattr(base, "sim") or not base.sim.record:
        raise ValueError("save_episode_figure: the env records nothing; make it with render_mode='rgb_array'")
    figure = draw_figure(base.sim.history[0], base.config, title=type(base).__name__ if title is None else title)
    path = os.fspath(path)
    directory = os.path.dirname(path)
    if directory:
        os.makedirs(directory, exist_ok=True)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    FigureCanvasAgg(figure)
    figure.savefig(path, format="png")
    return path


def record_episode(env, policy=None, seed: int | None = None, path=None) -> list[dict]:
    """Run one episode of ``env`` with ``policy(obs) -> action`` (default: the zero
    action) and optionally save its PNG figure to ``path``; returns the episode records."""
    obs, _ = env.reset(seed=seed)
    done = False
    while not done:
        action = np.zeros(env.action_space.shape, dtype=np.float32) if policy is None else policy(obs)
        obs, _, terminated, truncated, _ = env.step(action)
        done = terminated or truncated
    if path is not None:
        save_episode_figure(env, path)
    return getattr(env, "unwrapped", env).episode_history()


__all__ = ["draw_figure", "figure_to_array", "record_episode", "save_episode_figure", "show_human"]


def main(argv=None) -> int:
    """Render the README frame: one default Excitation-v0 episode under a 0.25 Hz sine command.

    ``python -m hyst_gym.envs.rendering [PATH]`` (default docs/figures/envs/excitation_episode.png).
    """
    import sys
    import gymnasium
    argv = sys.argv[1:] if argv is None else argv
    path = argv[0] if argv else "docs/figures/envs/excitation_episode.png"
    env = gymnasium.make("hyst_gym:hyst_gym/Excitation-v0", render_mode="rgb_array")
    dt = env.unwrapped.config.dt
    clock = {"step": 0}

    def sine_command(obs):
        clock["step"] += 1
        return np.array([np.sin(2 * np.pi * 0.25 * clock["step"] * dt)], dtype=np.float32)

    record_episode(env, sine_command, seed=0, path=path)
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
