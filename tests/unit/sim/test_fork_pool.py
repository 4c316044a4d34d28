"""ForkPool (veriloc_rt/sim/executors.py): the chains of the points in order, and a worker that
ends while it computes stops the run with WorkerLost instead of a wait for ever."""

import os
import signal
import time

import pytest

from veriloc_rt.sim.executors import ForkPool, WorkerLost


class _Runner:
    """What ForkPool's workers call: the point's number squared, or the worker killed at
    ``die_at`` (what the kernel's out-of-memory killer does)."""

    def __init__(self, die_at: int | None = None):
        self.die_at = die_at

    def worker_chains(self, scenario: str, i: int):
        if i == self.die_at:
            os.kill(os.getpid(), signal.SIGKILL)
        return i, {scenario: i * i}, {"chain": 0.0}


def test_the_points_come_back_in_order_from_the_workers():
    pool = ForkPool(_Runner(), 2)
    try:
        got = list(pool.imap("none", list(range(9))))
    finally:
        pool.close()
    assert [i for i, _, _ in got] == list(range(9))
    assert [r["none"] for _, r, _ in got] == [i * i for i in range(9)]


def test_a_killed_worker_stops_the_run_with_worker_lost_not_a_hang():
    pool = ForkPool(_Runner(die_at=5), 2)
    t = time.perf_counter()
    got = []
    with pytest.raises(WorkerLost, match="ended while it computed.*--resume"):
        for item in pool.imap("none", list(range(40))):
            got.append(item[0])
    pool.terminate()
    assert time.perf_counter() - t < 30   # not the wait for ever of multiprocessing.Pool
    assert got == list(range(len(got))) and len(got) <= 5   # those before it, in order
