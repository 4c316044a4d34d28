"""Timing a ray trace: the one place ``veriloc-rt bench`` and the benchmarks (``benchmarks/``)
time :func:`~veriloc_rt.propagation.raytrace.trace`."""

from __future__ import annotations

import time

import numpy as np

from ..config import Config
from ..propagation.raytrace import Propagation, trace

__all__ = ["timed_trace"]


def timed_trace(geometry, cfg: Config, points=None, adversary: bool = True, repeats: int = 1,
                cache_dir=None) -> tuple[Propagation, float]:
    """(propagation, wall seconds) of ``trace`` of ``cfg`` on ``geometry`` with only the links
    of ``points`` (indices; None: every point) and, when ``adversary`` is False, no adversary
    links: the fastest of ``repeats`` identical traces (the first of a setting also compiles its
    Dr.Jit kernels and, in a new process, starts the LLVM back end; the trace is deterministic,
    so every repeat gives the same paths). ``cache_dir``: as ``trace``'s (None: no cache)."""
    on = np.zeros(geometry.num_points, dtype=bool)
    on[np.arange(geometry.num_points) if points is None else np.asarray(points, dtype=int)] = True
    best, prop = np.inf, None
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        prop = trace(geometry, cfg.propagation, cfg.seed, cache_dir=cache_dir,
                     adversary_points=on if adversary else np.zeros_like(on), ue_points=on)
        best = min(best, time.perf_counter() - t)
    return prop, best
