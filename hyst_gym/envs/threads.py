"""The threads a batched step runs its blocks of sub-envs in (the grid posterior's node plants, an Identification
step's plants and model bank): compiled kernels that release the GIL, one block per thread, a row's numbers
depending on its row alone, so that the split changes no number."""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

#: the rows (node plants, bank models) of a step from which it runs in :func:`step_threads` threads (blocks of
#: sub-envs; below it, the threads' hand-over costs more than the second core gains)
SPLIT_MIN_NODES = 4096
#: the most threads a step uses (the machine this package is measured on has 2 cores)
MAX_STEP_THREADS = 2


def step_threads() -> int:
    """Threads a step uses: the CPUs this process may run on, at most :data:`MAX_STEP_THREADS`."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # no sched_getaffinity (macOS, Windows)
        cpus = os.cpu_count() or 1
    return max(1, min(MAX_STEP_THREADS, cpus))


def block_edges(n: int, threads: int) -> list:
    """The (first, stop) sub-envs of ``threads`` blocks of ``n`` sub-envs, as equal as whole sub-envs make them."""
    edges = [n * b // threads for b in range(threads + 1)]
    return list(zip(edges[:-1], edges[1:]))


class WorkerThreads:
    """``workers`` threads that run the other blocks of a step while the calling thread runs the first; made on the
    first threaded step and made again in a forked child, whose copy of a pool has no threads."""

    def __init__(self, workers: int, name: str):
        self.workers = max(1, int(workers))
        self.name = name
        self._pool, self._pool_pid, self._lock = None, None, threading.Lock()

    def pool(self) -> ThreadPoolExecutor:
        with self._lock:
            if self._pool is None or self._pool_pid != os.getpid():
                self._pool = ThreadPoolExecutor(max_workers=self.workers, thread_name_prefix=self.name)
                self._pool_pid = os.getpid()
            return self._pool

    def run(self, function, calls) -> None:
        """``function(*call)`` for every call of ``calls``: the first in this thread, the others in the workers at
        the same time; returns once all have finished (raising the first one's error, if any)."""
        others = [self.pool().submit(function, *call) for call in calls[1:]]
        function(*calls[0])
        for other in others:
            other.result()


__all__ = ["MAX_STEP_THREADS", "SPLIT_MIN_NODES", "WorkerThreads", "block_edges", "step_threads"]
