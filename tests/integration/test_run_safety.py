"""Issue 37, the run half: runs that stop cleanly (SIGTERM like Ctrl-C, a killed run's owner
file seen as stale), finished results never replaced without --force, no hang on a file that
is not a regular one in --out, every failure one line naming its file or flag.

The command line runs as a subprocess of the installed entry point where the case is about
signals or hangs (a regression then fails on the subprocess's timeout instead of hanging the
suite). Reference for every resume: the same config run without interruption; the CSVs must be
equal byte for byte (they store floats exactly).

The config is the tiny UMa one of the issue with ``adversary_lag_points`` 1 and 12 points: with
those the run logs no warning before its scenarios (the issue's 8 points and lag 2 warn that the
adversary starts behind the trajectory), so a failure's stderr is exactly its one line.
"""

from __future__ import annotations

import errno
import json
import os
import platform
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import pytest

from veriloc_rt import cli as cli_module
from veriloc_rt.config import config_from_dict
from veriloc_rt.errors import InputError
from veriloc_rt.report import results as results_module
from veriloc_rt.live.state import RunFolderState
from veriloc_rt.sim.run_folder import (LOCK_FILE, OWNER_FILE, RUN_FILES, check_fresh,
                                       check_resume, locked)

#: the installed command (the virtualenv's entry point, beside this interpreter)
ENTRY = Path(sys.executable).parent / "veriloc-rt"
#: seconds a refused command may take: start-up (imports) on a loaded 2-core machine is 2-5 s;
#: a hang (the issue: for ever) fails here
QUICK_S = 60
#: seconds a whole tiny run may take on that machine (measured 11 s unloaded)
RUN_S = 300

TINY = {"propagation": {"model": "uma"},
        "trajectory": {"num_points": 12, "adversary_lag_points": 1},
        "run": {"scenarios": ["none", "fbs"], "evaluate_encrypted": False, "digsig": "shared"}}
#: long enough for a signal to land while the chains run (about 0.3 s a point here)
LONGER = {**TINY, "trajectory": {"num_points": 30, "adversary_lag_points": 1}}
MESSAGE = ("interrupted; finished ray-tracing batches are kept in the cache, finished points and "
           "chain results in --out: add --resume to continue")


def veriloc(*args, cwd: Path, timeout: float = RUN_S) -> subprocess.CompletedProcess:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    return subprocess.run([str(ENTRY), *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=timeout)


def start(*args, cwd: Path) -> subprocess.Popen:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    return subprocess.Popen([str(ENTRY), *map(str, args)], cwd=cwd, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def snapshot(folder: Path) -> dict:
    """Every regular file under ``folder`` -> its bytes (special files by their type)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_symlink() or not p.is_file():
            out[str(p.relative_to(folder))] = "special"
        else:
            out[str(p.relative_to(folder))] = p.read_bytes()
    return out


def same_csvs(got: Path, want: Path, cfg: dict) -> None:
    for s in cfg["run"]["scenarios"]:
        assert (got / f"{s}_results.csv").read_bytes() == (want / f"{s}_results.csv").read_bytes(), s
    assert json.loads((got / "run.json").read_text())["status"] == "complete"


def rows(path: Path) -> int:
    return max(0, len(path.read_bytes().splitlines()) - 1) if path.exists() else 0


def wait_rows(p: subprocess.Popen, csv: Path | Callable[[], int], n: int,
              timeout: float = RUN_S) -> None:
    """Wait until ``csv`` (a results CSV, or a function counting rows) holds ``n`` rows while
    ``p`` runs."""
    count = csv if callable(csv) else (lambda: rows(csv))
    deadline = time.monotonic() + timeout
    while count() < n:
        assert p.poll() is None, p.communicate()[1]
        assert time.monotonic() < deadline
        time.sleep(0.05)


def sigterm_after(p: subprocess.Popen, csv: Path | Callable[[], int], n: int,
                  progress: tuple[str, ...]) -> str:
    """SIGTERM ``p`` once ``n`` rows exist (:func:`wait_rows`); check it exits with 128 + 15
    and prints exactly the stop message besides its progress lines (those starting with
    ``progress``); return its stderr."""
    try:
        wait_rows(p, csv, n)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=QUICK_S)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert p.returncode == 128 + signal.SIGTERM, err
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip()
             and not ln.startswith(progress)]
    assert lines == [MESSAGE]
    return err


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """The configs and their uninterrupted runs (through the command, 2 workers)."""
    root = tmp_path_factory.mktemp("safety")
    out = {}
    for name, data in (("tiny", TINY), ("longer", LONGER)):
        cfg = root / f"{name}.json"
        cfg.write_text(json.dumps(data))
        full = root / f"{name}-full"
        r = veriloc("run", cfg, "--out", full, "--workers", "2", cwd=root)
        assert r.returncode == 0, r.stderr
        out[name] = (cfg, full)
    return out


# -- no hang: a FIFO at a file the run reads or writes -------------------------------------

ROLE = {LOCK_FILE: "a run's lock", OWNER_FILE: "a run's lock"}


@pytest.mark.parametrize("resume", [False, True], ids=["run", "resume"])
@pytest.mark.parametrize("name", ["run.json", "none_results.csv", "fbs_results.csv",
                                  "metrics.json", "chains.bin", LOCK_FILE, OWNER_FILE])
def test_a_fifo_in_the_run_folder_is_exit_2_within_seconds(tmp_path, made, name, resume):
    """Issue 37: a FIFO at run.json, a results CSV or chains.bin hung run and --resume for
    ever. Now the command refuses it before reading anything: exit 2, one line naming it."""
    cfg, full = made["tiny"]
    out = tmp_path / "o"
    shutil.copytree(full, out)
    (out / name).unlink(missing_ok=True)
    os.mkfifo(out / name)
    before = snapshot(out)
    t = time.monotonic()
    r = veriloc("run", cfg, "--out", out, "--workers", "1", *(["--resume"] if resume else []),
                cwd=tmp_path, timeout=QUICK_S)
    elapsed = time.monotonic() - t
    assert r.returncode == 2, r.stderr
    role = ROLE.get(name, "a run reads and replaces it")
    assert r.stderr == (f"error: {out / name}: is a FIFO (named pipe), not a regular file "
                        f"({role}): remove it, or use another --out\n")
    assert snapshot(out) == before
    assert elapsed < QUICK_S


@pytest.mark.parametrize("special", ["fifo", "device", "folder", "loop"])
def test_every_run_file_that_is_not_regular_is_refused_before_it_is_read(tmp_path, special):
    """Every file of RUN_FILES (and the lock's), for a new run (even with --force) and a
    resumed one: the checks stat, they never open, so none of them can block."""
    cfg = config_from_dict(TINY)
    kinds = {"fifo": "a FIFO (named pipe)", "device": "a character device",
             "folder": "a folder", "loop": "a symbolic link loop"}
    for name in (*RUN_FILES, LOCK_FILE, OWNER_FILE):
        out = tmp_path / f"{special}-{name}"
        out.mkdir()
        path = out / name
        if special == "fifo":
            os.mkfifo(path)
        elif special == "device":
            path.symlink_to("/dev/zero")
        elif special == "folder":
            path.mkdir()
        else:
            path.symlink_to(path)
        for check in (lambda: check_fresh(out, cfg), lambda: check_fresh(out, cfg, force=True),
                      lambda: check_resume(out, cfg)):
            with pytest.raises(InputError) as err:
                check()
            assert err.value.field == str(path), name
            assert err.value.problem.startswith(f"is {kinds[special]}, not a regular file"), name


# -- runs that stop cleanly ----------------------------------------------------------------

@pytest.mark.heavy   # 20-90 s of runs: CI's second step
def test_sigterm_stops_a_run_like_ctrl_c_and_resume_gives_the_same_bytes(tmp_path, made):
    """Issue 37: SIGTERM ended a run silently (rc 143), left the owner file and 'running'.
    Now: the Ctrl-C message, exit 143, status 'stopped', no owner file, no traceback from the
    forked chain workers; --resume then ends with the uninterrupted run's bytes."""
    cfg, full = made["longer"]
    out = tmp_path / "o"
    p = start("run", cfg, "--out", out, "--workers", "2", cwd=tmp_path)
    err = sigterm_after(p, out / "none_results.csv", 3, ("none ",))
    assert "Traceback" not in err
    info = json.loads((out / "run.json").read_text())
    assert info["status"] == "stopped"
    assert not (out / OWNER_FILE).exists()
    assert 3 <= rows(out / "none_results.csv") < LONGER["trajectory"]["num_points"]
    assert RunFolderState(out).state()["status"] == "stopped"
    r = veriloc("run", cfg, "--out", out, "--workers", "2", "--resume", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    same_csvs(out, full, LONGER)


@pytest.mark.heavy   # 20-90 s of runs: CI's second step
def test_a_killed_runs_owner_file_is_stale_stopped_and_blocks_nothing(tmp_path, made):
    """Issue 37: after a kill the live view showed 'running' for ever. A SIGKILLed run leaves
    'running' and its owner file naming a process that is gone: the live view says
    'stopped', and --resume goes ahead (to the uninterrupted bytes)."""
    cfg, full = made["longer"]
    out = tmp_path / "o"
    p = start("run", cfg, "--out", out, "--workers", "1", cwd=tmp_path)
    try:
        wait_rows(p, out / "none_results.csv", 2)
    finally:
        p.kill()
        p.communicate(timeout=QUICK_S)
    assert (out / OWNER_FILE).read_text() == f"pid {p.pid} on {platform.node()}\n"
    assert json.loads((out / "run.json").read_text())["status"] == "running"
    assert RunFolderState(out).state()["status"] == "stopped"
    # the same owner file naming a live process (this one): running
    (out / OWNER_FILE).write_text(f"pid {os.getpid()} on {platform.node()}\n")
    assert RunFolderState(out).state()["status"] == "running"
    (out / OWNER_FILE).write_text(f"pid {p.pid} on {platform.node()}\n")
    r = veriloc("run", cfg, "--out", out, "--workers", "1", "--resume", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert not (out / OWNER_FILE).exists()
    same_csvs(out, full, LONGER)


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


@pytest.mark.parametrize("owner, says", [
    ("dead", "pid {pid} on {host}, which has ended; a process it started still holds the lock: "
             "`fuser {lock}` lists the processes holding it"),
    (None, "no .veriloc-run.owner names it; `fuser {lock}` lists the processes holding it"),
    (b"\xff\xfe", "its .veriloc-run.owner cannot be read: owner file is not UTF-8 text (byte "
                  "0xff at offset 0); `fuser {lock}` lists the processes holding it"),
    ("other", "pid 7 on elsewhere"),
], ids=["dead-pid", "missing", "unreadable", "other-host"])
def test_the_locked_message_names_what_the_owner_file_knows(tmp_path, owner, says):
    """Issue 37: 'locked by another run (unknown)'."""
    out = tmp_path / "o"
    pid = _dead_pid()
    with locked(out):
        path = out / OWNER_FILE
        if owner == "dead":
            path.write_text(f"pid {pid} on {platform.node()}\n")
        elif owner is None:
            path.unlink()
        elif owner == "other":
            path.write_text("pid 7 on elsewhere\n")
        else:
            path.write_bytes(owner)
        with pytest.raises(InputError) as err:
            with locked(out):
                pass
    want = says.format(pid=pid, host=platform.node(), lock=out / LOCK_FILE)
    assert str(err.value) == f"--out {out}: locked by another run ({want})"


# -- finished results are never replaced without --force -----------------------------------

@pytest.mark.heavy   # 20-90 s of runs: CI's second step
def test_a_same_config_rerun_into_a_complete_folder_is_refused(tmp_path, made):
    """Issue 37: a same-config rerun replaced a finished run's results (killed at 5 rows, it
    left 5 rows of a complete run). Refused now, the folder unchanged; --force replaces."""
    cfg, full = made["tiny"]
    out = tmp_path / "o"
    shutil.copytree(full, out)
    before = snapshot(out)
    r = veriloc("run", cfg, "--out", out, "--workers", "1", cwd=tmp_path, timeout=QUICK_S)
    assert r.returncode == 2
    assert r.stderr == (f"error: --out {out}: holds a complete run of this config: its results "
                        "are kept; use a new --out, or --force to replace them\n")
    assert snapshot(out) == before
    r = veriloc("run", cfg, "--out", out, "--workers", "1", "--force", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    same_csvs(out, full, TINY)


@pytest.mark.heavy   # 20-90 s of runs: CI's second step
def test_an_unfinished_run_with_points_needs_resume_or_force(tmp_path, made):
    """The choice for an unfinished folder: its finished points are kept too (--resume
    continues them, --force starts over); one that finished no point is started over."""
    cfg, full = made["tiny"]
    out = tmp_path / "o"
    shutil.copytree(full, out)
    info = json.loads((out / "run.json").read_text())
    info["status"] = "stopped"
    (out / "run.json").write_text(json.dumps(info))
    lines = (out / "fbs_results.csv").read_bytes().splitlines(keepends=True)
    (out / "fbs_results.csv").write_bytes(b"".join(lines[:4]))
    (out / "none_results.csv").unlink()
    before = snapshot(out)
    r = veriloc("run", cfg, "--out", out, "--workers", "1", cwd=tmp_path, timeout=QUICK_S)
    assert r.returncode == 2
    assert r.stderr == (f"error: --out {out}: holds an unfinished run of this config with 3 "
                        "finished points: add --resume to continue it, or --force to start it "
                        "over\n")
    assert snapshot(out) == before
    (out / "fbs_results.csv").unlink()
    r = veriloc("run", cfg, "--out", out, "--workers", "1", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    same_csvs(out, full, TINY)


# -- every failure named --------------------------------------------------------------------

class FullDisk:
    """A text file whose writes fail with ENOSPC (as write(2) reports it: no file name) after
    ``ok`` of them."""

    def __init__(self, fh, ok: int):
        self.fh, self.ok = fh, ok

    def write(self, text):
        if self.ok <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.ok -= 1
        return self.fh.write(text)

    def __getattr__(self, name):
        return getattr(self.fh, name)


@pytest.mark.heavy   # 20-90 s of runs: CI's second step
def test_a_full_disk_names_the_file_and_keeps_every_finished_point(tmp_path, made, monkeypatch,
                                                                     capsys):
    """Issue 37: 'error: OSError: [Errno 28] ...' named no file. The results CSV's appends
    fail after 4 rows (the writer opens it for appending): one line naming it, exit 1, the 4
    rows and the status 'stopped' kept, --resume then ends with the uninterrupted bytes."""
    cfg, full = made["tiny"]
    out = tmp_path / "o"
    real_open = open

    def opener(path, mode="r", *a, **k):
        fh = real_open(path, mode, *a, **k)
        return FullDisk(fh, 4) if mode == "a" and str(path).endswith("none_results.csv") else fh

    monkeypatch.setattr(results_module, "open", opener, raising=False)
    code = cli_module.main(["run", str(cfg), "--out", str(out), "--workers", "1"])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]
    assert code == 1
    assert err == [f"error: {out.resolve() / 'none_results.csv'}: no space left on device; "
                   "finished points are kept in --out: free space, then add --resume"]
    assert rows(out / "none_results.csv") == 4
    assert json.loads((out / "run.json").read_text())["status"] == "stopped"
    assert not (out / OWNER_FILE).exists()
    monkeypatch.undo()
    r = veriloc("run", cfg, "--out", out, "--workers", "1", "--resume", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    same_csvs(out, full, TINY)


def _stopped_copy(full: Path, out: Path, keep: int) -> None:
    """``full`` as a run stopped after ``keep`` points of 'none' (status 'stopped')."""
    shutil.copytree(full, out)
    info = json.loads((out / "run.json").read_text())
    info["status"] = "stopped"
    (out / "run.json").write_text(json.dumps(info))
    lines = (out / "none_results.csv").read_bytes().splitlines(keepends=True)
    (out / "none_results.csv").write_bytes(b"".join(lines[:1 + keep]))
    (out / "fbs_results.csv").unlink()


@pytest.mark.parametrize("damage, problem", [
    (lambda b: b[:200] + b"\xff" + b[201:],
     "results file is not UTF-8 text (byte 0xff at offset 200)"),
    (lambda b: b.replace(b"\n0.0,", b"\nabc,", 1),
     "not a results CSV of this run (line 2: could not convert string to float: 'abc'): "
     "delete it to compute its points again with --resume, or use --force or a new --out"),
    (lambda b: b"x,y\n1,2\n",
     "not a results CSV of this run (header ['x', 'y'] is not the results CSV's): delete it to "
     "compute its points again with --resume, or use --force or a new --out"),
], ids=["not-utf8", "bad-number", "other-header"])
def test_a_damaged_results_csv_on_resume_is_one_line_naming_it(tmp_path, made, damage, problem):
    """Issue 37: 'error: UnicodeDecodeError ...', exit 1, no file named."""
    cfg, full = made["tiny"]
    out = tmp_path / "o"
    _stopped_copy(full, out, 5)
    csv = out / "none_results.csv"
    csv.write_bytes(damage(csv.read_bytes()))
    r = veriloc("run", cfg, "--out", out, "--workers", "1", "--resume", cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr == f"error: {csv}: {problem}\n"


@pytest.mark.parametrize("content, problem", [
    (b'{"config": \xff}', "run file is not UTF-8 text (byte 0xff at offset 11)"),
    (b"[1, 2]", "holds no run config: not a veriloc-rt run.json"),
    (b'{"config": {', "not valid JSON (Expecting property name enclosed in double quotes: "
                     "line 1 column 13 (char 12)): not a veriloc-rt run.json, or a damaged one"),
], ids=["not-utf8", "a-list", "torn"])
def test_a_damaged_run_json_on_resume_is_one_line_naming_it(tmp_path, made, content, problem):
    cfg, full = made["tiny"]
    out = tmp_path / "o"
    _stopped_copy(full, out, 5)
    (out / "run.json").write_bytes(content)
    r = veriloc("run", cfg, "--out", out, "--workers", "1", "--resume", cwd=tmp_path,
                timeout=QUICK_S)
    assert r.returncode == 2
    assert r.stderr == f"error: {out / 'run.json'}: {problem}\n"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_scheduler_that_refuses_the_connection_is_one_line(tmp_path, made):
    cfg, _ = made["tiny"]
    port = _free_port()
    r = veriloc("run", cfg, "--out", tmp_path / "o", "--scheduler", f"tcp://127.0.0.1:{port}",
                cwd=tmp_path, timeout=QUICK_S)
    assert r.returncode == 2
    assert r.stderr == (f"error: --scheduler: cannot connect to tcp://127.0.0.1:{port} ([Errno "
                        "111] Connection refused): is a Dask scheduler running there? start one "
                        "with `dask scheduler --host 127.0.0.1`\n")
    assert not (tmp_path / "o").exists()


@pytest.mark.heavy   # 20-90 s of runs: CI's second step
def test_a_scheduler_without_workers_is_one_line_and_the_run_resumable(tmp_path, made):
    """Issue 37: 'TimeoutError: No valid workers found', exit 1, no hint."""
    cfg, _ = made["tiny"]
    out = tmp_path / "o"
    file = tmp_path / "scheduler.json"
    # a scheduler as `dask scheduler` starts one, on loopback, without a worker
    sched = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host",
                              "127.0.0.1", "--port", "0", "--no-dashboard",
                              "--dashboard-address", "127.0.0.1:0", "--scheduler-file",
                              str(file)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + QUICK_S
        address = None
        while address is None:
            assert sched.poll() is None and time.monotonic() < deadline
            try:
                address = json.loads(file.read_text())["address"]
            except (OSError, ValueError, KeyError):   # not (completely) written yet
                time.sleep(0.1)
        assert address.startswith("tcp://127.0.0.1:")
        r = veriloc("run", cfg, "--out", out, "--scheduler", address, cwd=tmp_path)
    finally:
        sched.terminate()
        sched.wait(timeout=QUICK_S)
    assert r.returncode == 2
    assert r.stderr == ("error: --scheduler: the cluster has no workers (Dask: No valid workers "
                        "found): start some, e.g. `dask worker tcp://127.0.0.1:8786`, then run "
                        "again\n")
    assert json.loads((out / "run.json").read_text())["status"] == "stopped"


@pytest.mark.heavy   # 20-90 s of runs: CI's second step
def test_sigterm_stops_a_monte_carlo_on_a_local_cluster_quietly_and_resumably(tmp_path):
    """The Dask workers of a local cluster: SIGTERM to the command prints its one message, no
    traceback and no warning of the cluster's shutdown; --resume then gives the uninterrupted
    Monte Carlo's montecarlo.csv byte for byte."""
    data = {**LONGER, "run": {**LONGER["run"], "realisations": 2}}
    cfg = tmp_path / "mc.json"
    cfg.write_text(json.dumps(data))
    full = tmp_path / "full"
    r = veriloc("run", cfg, "--out", full, "--workers", "2", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "o"
    p = start("run", cfg, "--out", out, "--workers", "2", cwd=tmp_path)
    sigterm_after(p, lambda: sum(rows(f) for f in out.glob("realisation_*/none_results.csv")), 3,
                  ("Monte Carlo", "realisations"))
    assert json.loads((out / "run.json").read_text())["status"] == "stopped"
    assert not (out / OWNER_FILE).exists()
    r = veriloc("run", cfg, "--out", out, "--workers", "2", "--resume", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (out / "montecarlo.csv").read_bytes() == (full / "montecarlo.csv").read_bytes()
    for k in range(2):
        same_csvs(out / f"realisation_{k:03d}", full / f"realisation_{k:03d}", LONGER)
