"""Dask failures under a run as one line naming the flag (issue 37: 'FutureCancelledError ...',
'TimeoutError: No valid workers found', exit 1, no hint); a task's own exception stays as it is."""

import errno

import pytest
from distributed.client import FutureCancelledError
from distributed.comm.core import CommClosedError
from distributed.scheduler import KilledWorker

from veriloc_rt.errors import InputError
from veriloc_rt.sim.executors import dask_failure, named_failures

KEPT = "finished points and realisations are kept in --out: add --resume to continue"


@pytest.mark.parametrize("exc, flag, want", [
    (TimeoutError("No valid workers found"), "--scheduler",
     "--scheduler: the cluster has no workers (Dask: No valid workers found): start some, e.g. "
     "`dask worker tcp://127.0.0.1:8786`, then run again"),
    (FutureCancelledError("k-1", "scheduler-connection-lost"), "--scheduler",
     "--scheduler: the cluster cancelled the run's tasks (Dask: k-1 cancelled for reason: "
     "scheduler-connection-lost.): the scheduler restarted or went away; " + KEPT
     + " once it is back"),
    (CommClosedError("in <TCP>: Stream is closed"), "--workers",
     "--workers: lost the connection to the local Dask cluster (Dask: in <TCP>: Stream is "
     "closed); " + KEPT + " once it is back"),
    (OSError(errno.ECONNREFUSED, "Connection refused"), "--scheduler",
     "--scheduler: lost the connection to the cluster (Dask: [Errno 111] Connection refused); "
     + KEPT + " once it is back"),
], ids=["no-workers", "cancelled", "comm-closed", "refused"])
def test_cluster_failures_are_one_line_naming_the_flag(exc, flag, want):
    err = dask_failure(exc, flag)
    assert isinstance(err, InputError) and str(err) == want
    assert "\n" not in str(err)
    with pytest.raises(InputError) as raised, named_failures(flag):
        raise exc
    assert str(raised.value) == want


def test_a_task_that_killed_its_workers_is_named():
    class Worker:
        address = "tcp://127.0.0.1:4"

    err = dask_failure(KilledWorker("veriloc-realisation-0", Worker(), 3))
    assert str(err).startswith("--scheduler: a task ended the workers that ran it (Dask: ")
    assert str(err).endswith("out of memory? see the workers' logs; " + KEPT)


@pytest.mark.parametrize("exc", [ValueError("a bug"), TimeoutError("the task's own"),
                                 OSError(errno.ENOSPC, "No space left on device", "/x/f.csv"),
                                 InputError("realisation_000/run.json", "is a FIFO")],
                         ids=["bug", "task-timeout", "disk-full", "input"])
def test_a_tasks_own_exception_is_not_a_cluster_failure(exc):
    assert dask_failure(exc) is None
    with pytest.raises(type(exc)) as raised, named_failures():
        raise exc
    assert raised.value is exc
