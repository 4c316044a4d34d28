"""Executors: where the chains of the points ahead are computed.

The detectors carry state from point to point, so they run in order in the engine's process;
the chains of the points ahead are independent (every draw comes from a named stream per
point) and go to an executor: this process (:class:`LocalChains`), forked local processes
(:class:`ForkPool`) or a Dask cluster (:class:`DaskChains`). ``imap(scenario, points)`` yields
``(i, results, timing)`` for every point, in order, with ``results`` for
:meth:`~veriloc_rt.sim.runner.ScenarioRunner.store_chains`; the numbers are the serial run's
whatever the executor. Also the Dask plumbing a Monte Carlo run uses: :func:`connect`,
:func:`local_cluster`, and the one check of ``workers``/``scheduler`` arguments.
"""

from __future__ import annotations

import errno
import logging
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
import uuid
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager

from ..errors import InputError
from .blas import one_blas_thread
from .run_folder import run_keys
from .runner import ScenarioRunner

log = logging.getLogger(__name__)

__all__ = ["LocalChains", "ForkPool", "WorkerLost", "DaskChains", "check_workers",
           "scheduler_client", "init_forked_worker",
           "connect", "probe_scheduler", "local_cluster", "dask_failure", "named_failures",
           "CONNECT_TIMEOUT_S"]


def check_workers(workers, scheduler) -> None:
    """Raise ValueError unless ``workers`` is an integer >= 1, and 1 with a ``scheduler``."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"Argument `workers` must be an integer >= 1, not {workers!r}")
    if scheduler is not None and workers > 1:
        raise ValueError("Argument `workers` must be 1 with `scheduler` (the cluster's workers "
                         f"compute), not {workers!r}")


@contextmanager
def scheduler_client(scheduler):
    """The ``distributed.Client`` of ``scheduler``: connected here (and closed on exit) when it
    is an address, so that a bad address fails before any heavy work; else ``scheduler``
    itself (a connected client, or None)."""
    own = connect(scheduler) if isinstance(scheduler, str) else None
    try:
        yield own if own is not None else scheduler
    finally:
        if own is not None:
            own.close()


#: prctl(2) option: the signal a process gets when its parent dies (linux/prctl.h)
PR_SET_PDEATHSIG = 1

#: the runner a forked worker process uses (set by :class:`ForkPool` before forking)
_WORKER: ScenarioRunner | None = None


def _work(task: tuple[str, int]) -> tuple[int, dict, dict]:
    scenario, i = task
    return _WORKER.worker_chains(scenario, i)


class LocalChains:
    """The chains computed in this process, ahead of the detectors like a pool's (so a point's
    attack scenarios share its serving BSs' signal here too: :meth:`ScenarioRunner.compute_chains`)."""

    def __init__(self, runner: ScenarioRunner):
        self.runner = runner

    def imap(self, scenario: str, points: list[int]):
        for i in points:   # the runner's own timing counts them
            yield i, self.runner.compute_chains(scenario, i), {}

    def close(self) -> None:
        pass

    terminate = close


class WorkerLost(RuntimeError):
    """A chain worker process ended while it computed (killed: out of memory, a signal)."""


class _ForkExecutor(ProcessPoolExecutor):
    """The standard library's process pool, which notices a worker that ended and fails its
    tasks (``BrokenProcessPool``) where ``multiprocessing.Pool`` waits for their results for
    ever; with a way to stop its workers at once."""

    def kill(self) -> None:
        """Stop every worker now (SIGTERM) and drop the tasks not started."""
        for proc in list((self._processes or {}).values()):
            proc.terminate()
        self.shutdown(wait=True, cancel_futures=True)


class ForkPool:
    """``workers`` forked processes computing :meth:`ScenarioRunner.compute_chains`.

    Forked, so the workers inherit the runner (keys included) without pickling it. A worker
    that ends while it computes (the kernel's out-of-memory killer, a signal) stops the run
    with :class:`WorkerLost` instead of leaving it waiting; the rows and chain results written
    so far are kept (``--resume`` continues).
    """

    def __init__(self, runner: ScenarioRunner, workers: int):
        global _WORKER
        _WORKER = runner
        self.pool = _ForkExecutor(workers, mp_context=mp.get_context("fork"),
                                  initializer=init_forked_worker, initargs=(os.getpid(),))

    def imap(self, scenario: str, points: list[int]):
        try:
            yield from self.pool.map(_work, [(scenario, i) for i in points], chunksize=2)
        except BrokenProcessPool:
            raise WorkerLost("a chain worker process ended while it computed (killed: out of "
                             "memory, or a signal); finished points and chain results are "
                             "kept in --out: add --resume to continue") from None

    def close(self) -> None:
        self.pool.shutdown(wait=True)

    def terminate(self) -> None:
        self.pool.kill()


def init_forked_worker(parent: int) -> None:
    """Workers leave Ctrl-C to the parent, which terminates them and keeps the finished rows;
    and they end with the parent. A killed parent (SIGKILL) cannot terminate them, and a pool
    worker whose parent is gone waits for tasks for ever, holding what it inherited: the run
    folder's lock among them, which would refuse the ``--resume`` that follows. On Linux the
    kernel kills them then (``prctl(PR_SET_PDEATHSIG)``, prctl(2)). SIGTERM (the pool's own
    ``terminate``, or a ``kill`` of the process group) ends them at once, silently: the
    parent's handler, which the fork copied, would raise in them and print a traceback."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
        if os.getppid() != parent:   # the parent died before the request took effect
            os.kill(os.getpid(), signal.SIGKILL)


#: on a Dask worker: the runners of the runs it computes chunks for, by (token, thread id)
_DASK_RUNNERS: dict[tuple[str, int], ScenarioRunner] = {}


_DASK_LOCK = threading.Lock()


def _dask_chunk(token: str, spec: tuple, scenario: str, points: list[int]) -> list[tuple]:
    """A Dask task: the chains of ``points`` (a trajectory chunk).

    The runner is built once per worker thread (a runner is not thread-safe) from
    ``spec = (cfg, geometry, propagation)``; the keys are rebuilt from the config, as the
    Ed25519 key objects do not pickle. BLAS is pinned to one thread first, as the command line
    pins it (:func:`~veriloc_rt.sim.blas.one_blas_thread`): a worker started without that
    computes other last bits, and slower.
    """
    one_blas_thread()
    k = (token, threading.get_ident())
    with _DASK_LOCK:
        runner = _DASK_RUNNERS.get(k)
    if runner is None:
        cfg, geometry, prop = spec
        runner = ScenarioRunner(cfg, geometry, prop, run_keys(cfg, len(geometry.bs_pos)))
        with _DASK_LOCK:
            _DASK_RUNNERS[k] = runner
    return [runner.worker_chains(scenario, i) for i in points]


def _dask_forget(token: str) -> int:
    """On every worker when a run ends: drop its runners (and with them its propagation)."""
    with _DASK_LOCK:
        keys = [k for k in _DASK_RUNNERS if k[0] == token]
        for k in keys:
            del _DASK_RUNNERS[k]
    return len(keys)


class DaskChains:
    """Trajectory chunks as tasks on a Dask cluster (a connected ``distributed.Client``).

    The run's config, geometry and propagation go to every worker once; each chunk of
    ``chunk`` points is one task; at most two chunks per worker thread (plus one) are in
    flight, so results never pile up on the cluster ahead of the detectors.

    :param chunk: points per task (None: about four tasks per worker thread, 1 to 16 points)
    """

    def __init__(self, runner: ScenarioRunner, client, chunk: int | None = None):
        self.client, self.chunk = client, chunk
        self.token = f"veriloc-chains-{uuid.uuid4().hex}"
        self.spec = None
        self.inflight: set = set()
        with named_failures():
            self.threads = max(1, sum(client.nthreads().values()))
            [self.spec] = client.scatter([(runner.cfg, runner.geo, runner.prop)],
                                         broadcast=True, hash=False)
        log.info("Dask: %d worker threads at %s", self.threads, client.scheduler.address)

    def imap(self, scenario: str, points: list[int]):
        size = self.chunk or max(1, min(16, -(-len(points) // (4 * self.threads))))
        chunks = [points[k:k + size] for k in range(0, len(points), size)]
        pending: deque = deque()
        nxt = 0
        while pending or nxt < len(chunks):
            while nxt < len(chunks) and len(pending) < 2 * self.threads + 1:
                f = self.client.submit(_dask_chunk, self.token, self.spec, scenario,
                                       chunks[nxt], key=f"{self.token}-{scenario}-{nxt}",
                                       pure=False)
                pending.append(f)
                self.inflight.add(f)
                nxt += 1
            f = pending.popleft()
            with named_failures():
                out = f.result()
            self.inflight.discard(f)
            yield from out

    def close(self) -> None:
        """Release the run's data on the cluster (the client stays connected). Quiet when the
        cluster is gone (the run's own error says so)."""
        try:
            for f in self.inflight:
                f.cancel()
        except Exception as exc:  # noqa: BLE001 - a scheduler gone cancels nothing
            log.debug("Dask: could not cancel the chunks in flight (%s)", exc)
        self.inflight.clear()
        if self.spec is None:  # closed already
            return
        try:
            self.spec.release()
        except Exception as exc:  # noqa: BLE001
            log.debug("Dask: could not release the run's data (%s)", exc)
        self.spec = None
        try:
            self.client.run(_dask_forget, self.token)
        except Exception as exc:  # noqa: BLE001 - a worker gone by now has nothing to forget
            log.info("Dask: could not clear the workers' runners (%s)", exc)

    terminate = close



#: errno values of a lost connection (the scheduler ended or restarted)
_CONNECTION_LOST = (errno.ECONNREFUSED, errno.ECONNRESET, errno.ECONNABORTED, errno.EPIPE,
                    errno.EHOSTUNREACH, errno.ENETUNREACH, errno.ETIMEDOUT)


def dask_failure(exc: BaseException, flag: str = "--scheduler") -> InputError | None:
    """The one-line error (``<flag>: <problem and hint>``) of a failure of the Dask cluster
    itself: no workers, the run's tasks cancelled (the scheduler restarted or went away), a
    task that killed its workers, a lost connection. None for any other exception (one the
    task itself raised: it is raised as it is).

    :param flag: the option that chose the cluster (``--scheduler``; ``--workers`` for the
        local cluster of a Monte Carlo run)
    """
    from concurrent.futures import CancelledError

    from distributed.comm.core import CommClosedError
    from distributed.scheduler import KilledWorker

    text = " ".join(str(exc).split()) or type(exc).__name__
    kept = "finished points and realisations are kept in --out: add --resume to continue"
    where = ("the cluster" if flag == "--scheduler"
             else "the local Dask cluster")
    if isinstance(exc, TimeoutError) and "No valid workers" in text:
        return InputError(flag, f"{where} has no workers (Dask: {text}): start some, e.g. "
                          "`dask worker tcp://127.0.0.1:8786`, then run again")
    if isinstance(exc, CancelledError):
        return InputError(flag, f"{where} cancelled the run's tasks (Dask: {text}): the "
                          f"scheduler restarted or went away; {kept} once it is back")
    if isinstance(exc, KilledWorker):
        return InputError(flag, f"a task ended the workers that ran it (Dask: {text}): out of "
                          f"memory? see the workers' logs; {kept}")
    if isinstance(exc, CommClosedError) or (
            isinstance(exc, OSError) and exc.filename is None and exc.errno in _CONNECTION_LOST):
        return InputError(flag, f"lost the connection to {where} (Dask: {text}); {kept} once "
                          "it is back")
    return None


@contextmanager
def named_failures(flag: str = "--scheduler"):
    """Raise a Dask cluster's failures in the block as :func:`dask_failure`'s one line."""
    try:
        yield
    except Exception as exc:  # noqa: BLE001 - the cluster's failures named, others raised
        failure = dask_failure(exc, flag)
        if failure is None:
            raise
        raise failure from None


#: seconds to wait for a ``--scheduler`` before giving up
CONNECT_TIMEOUT_S = 10.0


def connect(address: str, timeout_s: float | None = None):
    """A ``distributed.Client`` connected to the scheduler at ``address``.

    :raises InputError: ``--scheduler: cannot connect to <address> (<reason>)`` when no
        scheduler answers within ``timeout_s`` (default :data:`CONNECT_TIMEOUT_S`)
    """
    from distributed import Client
    from distributed.comm import resolve_address

    timeout = CONNECT_TIMEOUT_S if timeout_s is None else timeout_s
    try:
        # a malformed address fails here, before a Client exists (a Client that fails to
        # start hangs for 20 s in its finaliser at exit)
        resolved = resolve_address(address)
        probe_scheduler(resolved, timeout)
        return Client(address, timeout=timeout, set_as_default=False)
    except InputError:
        raise
    # MemoryError: a peer that is no Dask scheduler answered bytes read as a frame length
    except (OSError, TimeoutError, ValueError, TypeError, MemoryError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError("--scheduler", f"cannot connect to {address} ({reason}): is a Dask "
                         "scheduler running there? start one with `dask scheduler --host "
                         "127.0.0.1`") from None


#: largest first message accepted from a scheduler, bytes: its handshake (a small dict of
#: versions and options, well under 1 kB) serialised with Dask's frame header
MAX_HANDSHAKE_BYTES = 1 << 20


def probe_scheduler(address: str, timeout_s: float) -> None:
    """Check that a Dask scheduler listens at ``tcp://`` ``address``, in at most ``timeout_s``.

    A Dask server speaks first: on a new connection it sends its handshake, preceded by the
    message length as a little-endian uint64 (``distributed.comm.tcp.TCP.read``), and Dask's
    client then reads that length with no time limit and allocates it. An HTTP server sends
    nothing until it gets a request (the client waits forever), another server sends text (the
    client allocates exabytes). Here a plain socket reads the first 8 bytes with a deadline and
    checks the length. Other schemes (``tls://``, ``ucx://``) are left to Dask.

    :raises InputError: ``--scheduler: ...`` when nothing or something else answers
    """
    import socket
    import struct

    from distributed.comm import parse_address, parse_host_port

    scheme, loc = parse_address(address)
    if scheme != "tcp":
        return
    host, port = parse_host_port(loc)
    deadline = time.monotonic() + timeout_s
    with socket.create_connection((host, port), timeout=timeout_s) as sock:
        head = b""
        while len(head) < 8:
            sock.settimeout(max(deadline - time.monotonic(), 1e-3))
            try:
                chunk = sock.recv(8 - len(head))
            except (TimeoutError, socket.timeout):
                raise InputError("--scheduler", f"{address} accepted the connection but sent no "
                                 f"Dask handshake within {timeout_s:g} s: not a Dask "
                                 "scheduler") from None
            if not chunk:
                raise InputError("--scheduler", f"{address} closed the connection without a "
                                 "Dask handshake: not a Dask scheduler")
            head += chunk
    (nbytes,) = struct.unpack("<Q", head)
    if not 0 < nbytes <= MAX_HANDSHAKE_BYTES:
        raise InputError("--scheduler", f"{address} answered {head!r}, not a Dask handshake: "
                         "not a Dask scheduler")


#: Dask config of the workers a local cluster starts: without the nanny's default
#: ``MALLOC_TRIM_THRESHOLD_=65536``, which turns off glibc's dynamic mmap threshold and was
#: measured to make the chain 2x slower (every large temporary array mmap'ed afresh)
WORKER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}


@contextmanager
def local_cluster(workers: int):
    """A client of a fresh local cluster on 127.0.0.1: ``workers`` processes with one thread
    each, no dashboard (:data:`WORKER_CONFIG`); closed on exit."""
    import dask
    from distributed import Client, LocalCluster

    # loopback only (a scheduler runs any code a client sends it). The scheduler serves HTTP
    # even without a dashboard, by default on port 8787, with a warning when that is taken
    # (another cluster): a free port on localhost instead. The workers log errors only: a run
    # stopped (Ctrl-C, SIGTERM) cancels their tasks, and each would print a warning about it
    # after the run's own message
    with dask.config.set(WORKER_CONFIG):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None,
                               silence_logs=logging.ERROR,
                               scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
    with cluster, Client(cluster, set_as_default=False) as client:
        try:
            yield client
        except BaseException:
            # closing the cluster while its tasks run: the nanny's warnings that it killed
            # them say nothing the run's own message does not
            logging.getLogger("distributed").setLevel(logging.ERROR)
            raise

