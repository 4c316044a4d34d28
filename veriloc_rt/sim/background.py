"""A run's figures drawn in a process of their own while the run goes on.

A run's figures (the scene's top view, each scenario's time series and map, the summary plots
and the ROC) cost the engine's process 2-4 s of CPU. Drawn in place they hold up what follows
them: after the first scenario, whose chains cover every later one, the engine's detector
passes and its figures run on one core while the other idles, and a short run spends a third
of its time drawing. :class:`Figures` hands them to one forked process instead, which draws
them in the order given while the engine goes on; :meth:`Figures.wait` waits for them before
the run ends and raises the first error one met, as drawing in place would have raised it.

One process for all of a run's figures, not one per figure: the plots keep their figures from
one scenario to the next (:mod:`veriloc_rt.report.plots`) and matplotlib its fonts and caches
from the first drawing on, which a process per figure would build again each time (measured:
a scenario's figures 0.7 s of CPU in a fresh process, 0.3 s in one that drew the last
scenario's). A figure's file is written atomically (:func:`~veriloc_rt.fileio.atomic_output`):
a stopped run leaves no half-written one, and a resumed run draws again those it does not find.
The process is forked, like the chain workers, and leaves Ctrl-C to the engine and ends with
it (:func:`~veriloc_rt.sim.executors.init_forked_worker`); a figure's arguments reach it
pickled (a geometry: 50-250 kB).
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import sys
from typing import Callable

from .executors import init_forked_worker

log = logging.getLogger(__name__)

__all__ = ["Figures"]


class Figures:
    """Figures drawn by one forked process (``parallel``; started at the first figure), in
    the order given, or in this process (not ``parallel``: a run in one process draws them
    where it runs).

    Use as a context manager: leaving it waits for the figures (and raises the first error
    one met), or, on an error, stops the process with what it has not drawn.
    """

    def __init__(self, parallel: bool):
        self.parallel = bool(parallel)
        self._pool = None
        self._pending: list = []   # (AsyncResult, what it draws)

    def submit(self, fn: Callable, *args, **kwargs) -> None:
        """Draw ``fn(*args, **kwargs)``: in the figures' process, or here (not ``parallel``)."""
        if not self.parallel:
            fn(*args, **kwargs)
            return
        if self._pool is None:
            # a forked process inherits the unflushed output and would write it again
            sys.stdout.flush()
            sys.stderr.flush()
            self._pool = mp.get_context("fork").Pool(1, initializer=init_forked_worker,
                                                     initargs=(os.getpid(),))
        name = getattr(fn, "__name__", repr(fn))
        self._pending.append((self._pool.apply_async(fn, args, kwargs), name))

    def wait(self) -> None:
        """Wait for every figure given; raise the first error one met."""
        first = None
        while self._pending:
            res, name = self._pending.pop(0)
            try:
                res.get()
            except Exception as exc:
                if first is None:
                    first = exc
                else:
                    log.warning("figure %s failed too: %s", name, exc)
        if first is not None:
            raise first

    def close(self) -> None:
        """Wait for the figures (:meth:`wait`), then end their process."""
        try:
            self.wait()
        finally:
            if self._pool is not None:
                self._pool.close()
                self._pool.join()
                self._pool = None

    def terminate(self) -> None:
        """Stop the figures' process now: the figures not yet drawn are not."""
        self._pending.clear()
        if self._pool is not None:
            self._pool.terminate()
            self._pool = None

    def __enter__(self) -> "Figures":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:   # the run's own error is the one to see
            self.terminate()
