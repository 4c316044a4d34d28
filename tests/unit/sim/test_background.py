"""The figures' process (veriloc_rt/sim/background.py): the same files as drawn in place, in
the order given, errors raised where drawing in place would have raised them."""

import os
import time
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.fileio import atomic_write_text
from veriloc_rt.sim.background import FigureError, Figures


def _draw(path: Path, seed: int) -> None:
    import matplotlib.pyplot as plt

    from veriloc_rt.fileio import atomic_output

    x = np.random.default_rng(seed).normal(size=50)
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot(x, label=f"seed {seed}")
    ax.legend()
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)


def _record(path: Path, text: str) -> None:
    """Append a line after a pause (the order test: a slow first job must still come first)."""
    time.sleep(0.05)
    with open(path, "a") as fh:
        fh.write(f"{text} {os.getpid()}\n")


def _fail(message: str) -> None:
    raise ValueError(message)


def test_a_figure_drawn_in_its_process_equals_the_one_drawn_in_place(tmp_path):
    with Figures(parallel=True) as figs:
        figs.submit(_draw, tmp_path / "child.png", 3)
    Figures(parallel=False).submit(_draw, tmp_path / "here.png", 3)
    # Agg's rendering depends on the data and settings alone: the same bytes
    assert (tmp_path / "child.png").read_bytes() == (tmp_path / "here.png").read_bytes()


def test_figures_are_drawn_in_the_order_given_by_one_process(tmp_path):
    log = tmp_path / "order.txt"
    with Figures(parallel=True) as figs:
        for k in range(4):
            figs.submit(_record, log, f"job{k}")
    lines = [ln.split() for ln in log.read_text().splitlines()]
    assert [name for name, _ in lines] == ["job0", "job1", "job2", "job3"]
    pids = {pid for _, pid in lines}
    assert len(pids) == 1 and pids != {str(os.getpid())}   # one process, not this one


def test_not_parallel_draws_here(tmp_path):
    log = tmp_path / "here.txt"
    Figures(parallel=False).submit(_record, log, "job")
    assert log.read_text().split() == ["job", str(os.getpid())]


def test_an_error_is_raised_at_the_wait_and_the_other_figures_are_drawn(tmp_path):
    figs = Figures(parallel=True)
    figs.submit(_fail, "first broken")
    figs.submit(atomic_write_text, tmp_path / "after.txt", "drawn")
    figs.submit(_fail, "second broken")
    with pytest.raises(ValueError, match="first broken"):
        figs.close()
    assert (tmp_path / "after.txt").read_text() == "drawn"


def test_leaving_on_an_error_stops_the_process_and_keeps_the_runs_error(tmp_path):
    with pytest.raises(KeyError, match="the run's"):
        with Figures(parallel=True) as figs:
            figs.submit(time.sleep, 30)
            figs.submit(atomic_write_text, tmp_path / "never.txt", "drawn")
            t = time.perf_counter()
            raise KeyError("the run's")
    assert time.perf_counter() - t < 10   # not waited for the 30 s figure
    assert not (tmp_path / "never.txt").exists()


def test_a_killed_process_is_an_error_at_the_wait_not_a_hang(tmp_path):
    figs = Figures(parallel=True)
    figs.submit(atomic_write_text, tmp_path / "first.txt", "drawn")
    figs.submit(time.sleep, 30)
    figs.submit(atomic_write_text, tmp_path / "never.txt", "drawn")
    deadline = time.perf_counter() + 20
    while not (tmp_path / "first.txt").exists() and time.perf_counter() < deadline:
        time.sleep(0.01)
    time.sleep(0.2)   # into the 30 s job
    os.kill(figs.pid, 9)
    t = time.perf_counter()
    with pytest.raises(FigureError, match="exit code -9.*before it drew sleep"):
        figs.close()
    assert time.perf_counter() - t < 10
    assert (tmp_path / "first.txt").read_text() == "drawn"
    assert not (tmp_path / "never.txt").exists()
