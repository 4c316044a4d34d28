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
pickled (a geometry: 50-250 kB), through a queue that does not wait for the process. If the
process is killed, the wait raises :class:`FigureError` instead of waiting for ever.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import pickle
import sys
from multiprocessing.connection import wait as wait_for
from typing import Callable

from .executors import init_forked_worker

log = logging.getLogger(__name__)

__all__ = ["Figures", "FigureError"]


class FigureError(RuntimeError):
    """The figures' process ended before it drew what it was given, or a figure's error could
    not be passed back as it was."""


def _draw_loop(parent: int, jobs, results) -> None:
    """The figures' process: each job from ``jobs`` drawn in turn, its outcome (None, or the
    error it raised) sent back on ``results``; a None job ends it."""
    init_forked_worker(parent)
    while True:
        job = jobs.get()
        if job is None:
            break
        fn, args, kwargs = job
        err = None
        try:
            fn(*args, **kwargs)
        except Exception as exc:   # passed back: the engine raises it at the wait
            err = exc
        try:
            data = pickle.dumps(err)
        except Exception:   # an error that does not pickle: its text
            data = pickle.dumps(FigureError(f"{type(err).__name__}: {err}"))
        results.send_bytes(data)
    results.close()


class Figures:
    """Figures drawn by one forked process (``parallel``; started at the first figure), in
    the order given, or in this process (not ``parallel``: a run in one process draws them
    where it runs).

    Use as a context manager: leaving it waits for the figures (and raises the first error
    one met), or, on an error, stops the process with what it has not drawn. A process that
    ends before it has drawn what it was given (killed) is an error at the wait, not a hang.
    """

    def __init__(self, parallel: bool):
        self.parallel = bool(parallel)
        self._proc = None
        self._jobs = None      # the jobs' queue (put without waiting for the process)
        self._results = None   # the receiving end of the outcomes' pipe
        self._pending: list[str] = []   # what the figures given and not yet waited for draw

    @property
    def pid(self) -> int | None:
        """The figures' process id (None: not started, or ended)."""
        return None if self._proc is None else self._proc.pid

    def submit(self, fn: Callable, *args, **kwargs) -> None:
        """Draw ``fn(*args, **kwargs)``: in the figures' process, or here (not ``parallel``)."""
        if not self.parallel:
            fn(*args, **kwargs)
            return
        if self._proc is None:
            self._start()
        self._jobs.put((fn, args, kwargs))
        self._pending.append(getattr(fn, "__name__", repr(fn)))

    def _start(self) -> None:
        ctx = mp.get_context("fork")
        # a forked process inherits the unflushed output and would write it again
        sys.stdout.flush()
        sys.stderr.flush()
        self._jobs = ctx.Queue()
        self._results, send = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_draw_loop, args=(os.getpid(), self._jobs, send),
                                 name="veriloc-figures", daemon=True)
        self._proc.start()
        send.close()

    def wait(self) -> None:
        """Wait for every figure given; raise the first error one met (FigureError when the
        process ended first)."""
        first = None
        while self._pending:
            name = self._pending.pop(0)
            # its outcome, or the process's end, whichever comes first (the outcomes come in
            # the order given; a pipe whose writer has ended reads as EOF)
            wait_for([self._results, self._proc.sentinel])
            got = self._results.poll()
            if got:
                try:
                    err = pickle.loads(self._results.recv_bytes())
                except EOFError:
                    got = False
            if not got:
                self._proc.join()
                err = FigureError(f"the figures' process ended (exit code "
                                  f"{self._proc.exitcode}) before it drew {name}")
                self._pending.clear()
            if err is not None and first is None:
                first = err
            elif err is not None:
                log.warning("figure %s failed too: %s", name, err)
        if first is not None:
            raise first

    def close(self) -> None:
        """Wait for the figures (:meth:`wait`), then end their process."""
        try:
            self.wait()
        finally:
            if self._proc is not None:
                if self._proc.is_alive():
                    self._jobs.put(None)
                    self._proc.join()
                self._release()

    def terminate(self) -> None:
        """Stop the figures' process now: the figures not yet drawn are not."""
        self._pending.clear()
        if self._proc is not None:
            self._proc.terminate()
            self._proc.join()
            self._release()

    def _release(self) -> None:
        self._jobs.close()
        self._jobs.cancel_join_thread()   # nothing left to feed a process that has ended
        self._results.close()
        self._proc = self._jobs = self._results = None

    def __enter__(self) -> "Figures":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:   # the run's own error is the one to see
            self.terminate()
