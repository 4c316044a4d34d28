"""A Dask cluster of separate processes on this machine, as a user starts one by hand.

:func:`process_cluster` starts ``dask scheduler`` on 127.0.0.1 (a free port chosen by the
operating system, read back from its ``--scheduler-file``: no port is guessed, so none can
collide) and ``workers`` ``dask worker`` processes connected to it, one thread each, and
yields the scheduler's address for ``--scheduler``. Unlike ``LocalCluster``
(:func:`~veriloc_rt.sim.executors.local_cluster`) nothing of the cluster runs in this process
and the workers inherit nothing of it but the environment given: what a run on a real cluster
meets (its own working directory, its own BLAS set-up, every argument serialised).

The processes run ``python -m distributed.cli.dask_scheduler`` / ``dask_worker`` (what the
``dask scheduler`` and ``dask worker`` commands run) with this interpreter, through a short
bootstrap that asks Linux to end them when this process dies (``prctl(PR_SET_PDEATHSIG)``,
prctl(2)), so that a killed caller leaves no cluster behind; on exit they are terminated.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import tempfile
import time
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Iterator

log = logging.getLogger(__name__)

__all__ = ["process_cluster", "START_TIMEOUT_S", "STOP_TIMEOUT_S"]

#: seconds to wait for the scheduler's address and for every worker to register
START_TIMEOUT_S = 60.0
#: seconds a process gets to end after SIGTERM before it is killed
STOP_TIMEOUT_S = 10.0

#: runs ``sys.argv[2]`` as ``__main__`` with the arguments after it, after asking the kernel
#: to send SIGTERM when the parent (pid ``sys.argv[1]``) dies; a parent gone already (before
#: the request took effect) ends it at once. prctl option 1 is PR_SET_PDEATHSIG.
_BOOTSTRAP = """\
import os, runpy, signal, sys
if sys.platform.startswith("linux"):
    import ctypes
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)
    if os.getppid() != int(sys.argv[1]):
        sys.exit(1)
module = sys.argv[2]
sys.argv = [module, *sys.argv[3:]]
runpy.run_module(module, run_name="__main__", alter_sys=True)
"""


def _start(module: str, args: list[str], log_path: Path, env: dict | None,
           cwd: Path | None) -> subprocess.Popen:
    with open(log_path, "wb") as fh:
        return subprocess.Popen([sys.executable, "-c", _BOOTSTRAP, str(os.getpid()), module,
                                 *args], stdout=fh, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, env=env, cwd=cwd)


def _stop(procs: list[subprocess.Popen]) -> None:
    """SIGTERM to every process at once, then wait; SIGKILL to those still there after
    :data:`STOP_TIMEOUT_S`."""
    for proc in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
    deadline = time.monotonic() + STOP_TIMEOUT_S
    for proc in procs:
        try:
            proc.wait(max(deadline - time.monotonic(), 0.0))
        except subprocess.TimeoutExpired:
            log.warning("Dask process %d ignored SIGTERM for %g s: killed", proc.pid,
                        STOP_TIMEOUT_S)
            proc.kill()
            proc.wait()


def _tail(path: Path, lines: int = 20) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return ""


def _address(scheduler: subprocess.Popen, file: Path, log_path: Path, timeout_s: float) -> str:
    """The scheduler's address, from its scheduler file once written."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if scheduler.poll() is not None:
            raise RuntimeError(f"dask scheduler exited with code {scheduler.returncode}:\n"
                               f"{_tail(log_path)}")
        try:
            return json.loads(file.read_text())["address"]
        except (OSError, ValueError, KeyError):   # not there yet, or being written
            time.sleep(0.05)
    raise RuntimeError(f"dask scheduler gave no address within {timeout_s:g} s:\n"
                       f"{_tail(log_path)}")


def _wait_for_workers(address: str, workers: list[subprocess.Popen], logs: list[Path],
                      timeout_s: float) -> None:
    from distributed import Client

    deadline = time.monotonic() + timeout_s
    with Client(address, timeout=timeout_s, set_as_default=False) as client:
        while len(client.nthreads()) < len(workers):
            for proc, path in zip(workers, logs):
                if proc.poll() is not None:
                    raise RuntimeError(f"dask worker exited with code {proc.returncode}:\n"
                                       f"{_tail(path)}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"{len(workers)} dask workers did not all register within "
                                   f"{timeout_s:g} s")
            time.sleep(0.1)


@contextmanager
def process_cluster(workers: int, *, nanny: bool = False, env: dict | None = None,
                    cwd: str | Path | None = None, log_dir: str | Path | None = None,
                    timeout_s: float = START_TIMEOUT_S) -> Iterator[str]:
    """A scheduler and ``workers`` one-thread workers as processes -> the scheduler's address.

    :param nanny: start each worker under a nanny (``dask worker``'s default; the nanny sets
        the worker's environment from Dask's ``distributed.nanny.pre-spawn-environ``)
    :param env: the processes' environment (None: this process's)
    :param cwd: their working directory (None: this process's)
    :param log_dir: where their logs, the scheduler file and the workers' scratch folders go
        (None: a temporary folder, removed on exit)
    :raises RuntimeError: a process exits early, or the cluster is not up within ``timeout_s``
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"Argument `workers` must be an integer >= 1, not {workers!r}")
    with ExitStack() as stack:
        if log_dir is None:
            folder = Path(stack.enter_context(tempfile.TemporaryDirectory(
                prefix="veriloc-dask-")))
        else:
            folder = Path(log_dir)
            folder.mkdir(parents=True, exist_ok=True)
        procs: list[subprocess.Popen] = []
        # last in, first out: the workers stop, then the scheduler, then the folder goes
        stack.callback(lambda: (_stop(procs[1:]), _stop(procs[:1])))
        file = folder / "scheduler.json"
        file.unlink(missing_ok=True)
        # the scheduler serves HTTP even without the dashboard, by default on port 8787: port 0
        procs.append(_start("distributed.cli.dask_scheduler",
                            ["--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                             "--dashboard-address", "127.0.0.1:0", "--scheduler-file", str(file)],
                            folder / "scheduler.log", env, cwd))
        logs = [folder / f"worker-{k}.log" for k in range(workers)]
        # started at once: a worker reads the scheduler's address from the file when it exists
        for k in range(workers):
            procs.append(_start("distributed.cli.dask_worker", [
                "--scheduler-file", str(file), "--nthreads", "1",
                "--nanny" if nanny else "--no-nanny", "--host", "127.0.0.1", "--no-dashboard",
                "--dashboard-address", "127.0.0.1:0", "--name", f"worker-{k}",
                "--memory-limit", "0", "--local-directory", str(folder / f"worker-{k}"),
                "--death-timeout", f"{timeout_s:g}"], logs[k], env, cwd))
        address = _address(procs[0], file, folder / "scheduler.log", timeout_s)
        _wait_for_workers(address, procs[1:], logs, timeout_s)
        log.info("Dask cluster of %d worker processes at %s (logs in %s)", workers, address,
                 folder)
        yield address
