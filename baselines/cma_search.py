"""The one CMA-ES loop (pycma) shared by the optimal design and the direct design."""

from __future__ import annotations

import numpy as np


def cma_minimize(loss, x0, step_size: float, bound: float, max_evaluations: int, seed: int):
    """Minimize ``loss(x)`` by CMA-ES within ``[-bound, bound]`` per coordinate.

    Returns ``(x_best, loss_best, evaluations, history)``; ``history`` is the best loss so
    far after each generation. The CMA-ES seed is ``seed + 1`` (pycma treats 0 as "random"),
    so the same arguments give the same search.
    """
    import cma

    options = {"seed": int(seed) + 1, "maxfevals": int(max_evaluations), "verbose": -9, "bounds": [-bound, bound]}
    strategy = cma.CMAEvolutionStrategy(np.asarray(x0, dtype=np.float64), step_size, options)
    history = []
    while not strategy.stop():
        candidates = strategy.ask()
        strategy.tell(candidates, [float(loss(c)) for c in candidates])
        history.append(float(strategy.result.fbest))
    result = strategy.result
    return np.asarray(result.xbest), float(result.fbest), int(result.evaluations), tuple(history)


__all__ = ["cma_minimize"]
