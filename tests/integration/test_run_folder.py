"""The run folder as issue #19 found it: nothing lost, one run at a time, resume that keeps
the finished work (the chains included) and works after a stop anywhere.

Reference for every resume: the same config run without interruption; the resumed folder's
result CSVs must equal its byte for byte (the CSVs store floats exactly, so equal bytes mean
equal numbers) and the metrics of every scenario must be equal.
"""

from __future__ import annotations

import json
import os
import platform
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import veriloc_rt

from veriloc_rt.config import config_from_dict
from veriloc_rt.sim import engine
from veriloc_rt.sim.engine import run
from veriloc_rt.sim.run_folder import CHAIN_FILE, OWNER_FILE, locked
from veriloc_rt.sim.runner import ScenarioRunner

from .test_cli import ROOT

UMA = {"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
       "trajectory": {"num_points": 6}, "seed": 5,
       "run": {"scenarios": ["none", "fbs", "jamming"]}}


def snapshot(folder) -> dict:
    """Every file under ``folder`` (but the lock) -> its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.startswith(".veriloc-run")}


def assert_same_results(cfg, got, want) -> None:
    for s in cfg.run.scenarios:
        assert (got / f"{s}_results.csv").read_bytes() == (want / f"{s}_results.csv").read_bytes(), s
    m_got = json.loads((got / "metrics.json").read_text())["scenarios"]
    assert m_got == json.loads((want / "metrics.json").read_text())["scenarios"]
    assert json.loads((got / "run.json").read_text())["status"] == "complete"


def cli(*args, cwd=None):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "veriloc_rt.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd or ROOT, env=env)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The reference: UMA run without interruption."""
    cfg = config_from_dict(UMA)
    out = tmp_path_factory.mktemp("full") / "run"
    run(cfg, out)
    return cfg, out


class Stop(KeyboardInterrupt):
    """Ctrl-C, raised by a progress callback at a chosen point."""


def stop_at(scenario: str, done: int):
    def progress(label, d, total):
        if label == scenario and d >= done:
            raise Stop
    return progress


def count_chains(monkeypatch) -> list:
    """Every ScenarioRunner.compute_chains call from now on, as (scenario, point)."""
    calls: list = []
    original = ScenarioRunner.compute_chains

    def counted(self, scenario, i):
        calls.append((scenario, i))
        return original(self, scenario, i)

    monkeypatch.setattr(ScenarioRunner, "compute_chains", counted)
    return calls


# -- data loss ------------------------------------------------------------------------------

def test_a_run_of_another_config_leaves_the_folder_untouched(tmp_path):
    """Issue #19 data loss (1): it truncated the CSVs and replaced run.json."""
    data = dict(UMA, run={"scenarios": ["none", "fbs"]}, trajectory={"num_points": 3})
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(data))
    out = tmp_path / "o"
    run(config_from_dict(data), out)
    before = snapshot(out)
    r = cli("run", cfg, "--out", out, "--seed", "9", "--workers", "1")
    assert r.returncode == 2
    assert r.stderr == (f"error: --out {out}: holds a run of another config (or --points/--seed): "
                        "use a new --out, the same config with --resume to continue it, or "
                        "--force to replace it\n")
    assert snapshot(out) == before
    # --force replaces it
    r = cli("run", cfg, "--out", out, "--seed", "9", "--workers", "1", "--force")
    assert r.returncode == 0, r.stderr
    assert json.loads((out / "run.json").read_text())["seed"] == 9


def test_a_folder_of_other_files_needs_force_and_keeps_them(tmp_path):
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(dict(UMA, run={"scenarios": ["none"]}, trajectory={"num_points": 3})))
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes")
    r = cli("run", cfg, "--out", out, "--workers", "1")
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 1
    assert "holds no veriloc-rt run" in r.stderr
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == ["notes.txt"]
    assert cli("run", cfg, "--out", out, "--workers", "1", "--force").returncode == 0
    assert (out / "notes.txt").read_text() == "my notes" and (out / "none_results.csv").exists()


# -- the lock -------------------------------------------------------------------------------

def test_a_run_on_a_locked_folder_exits_2_and_changes_nothing(tmp_path):
    """Issue #19 data loss (2): two runs on one folder both exited 0 with mixed files."""
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(dict(UMA, run={"scenarios": ["none"]}, trajectory={"num_points": 3})))
    out = tmp_path / "o"
    with locked(out):
        before = snapshot(out)
        r = cli("run", cfg, "--out", out, "--workers", "1")
        assert r.returncode == 2
        assert r.stderr == (f"error: --out {out}: locked by another run (pid {os.getpid()} on "
                            f"{platform.node()})\n")
        assert snapshot(out) == before


def test_two_runs_at_once_one_is_refused(tmp_path):
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(dict(UMA, run={"scenarios": ["none", "jamming"]})))
    out = tmp_path / "o"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    first = subprocess.Popen([sys.executable, "-m", "veriloc_rt.cli", "run", str(cfg), "--out",
                              str(out), "--workers", "1"], cwd=ROOT, env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not (out / OWNER_FILE).exists():
            assert first.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        second = cli("run", cfg, "--out", out, "--workers", "1")
        assert second.returncode == 2
        assert second.stderr.startswith(f"error: --out {out}: locked by another run (pid "
                                        f"{first.pid} on ")
    finally:
        _, err = first.communicate(timeout=120)
    assert first.returncode == 0, err
    assert json.loads((out / "run.json").read_text())["status"] == "complete"


# -- resume ---------------------------------------------------------------------------------

def test_resume_after_a_stop_during_propagation(tmp_path, monkeypatch, uninterrupted):
    """Issue #19: Ctrl-C during ray tracing said 'add --resume', then --resume refused it
    ('no run.json'). The stop is raised where the links are computed (ray tracing or UMa)."""
    cfg, full = uninterrupted
    out = tmp_path / "o"

    def stopped(*a, **k):
        raise Stop

    monkeypatch.setattr(engine, "compute_propagation", stopped)
    with pytest.raises(Stop):
        run(cfg, out)
    assert json.loads((out / "run.json").read_text())["status"] == "stopped"
    monkeypatch.undo()
    run(cfg, out, resume=True)
    assert_same_results(cfg, out, full)


def test_resume_in_an_attack_scenario_computes_no_chain(tmp_path, monkeypatch, uninterrupted):
    """Issue #19: the attack scenarios' chains computed during 'none' were lost. 'none'
    computes every chain of the run (the benign ones and, in the attack window, those of the
    later attack scenarios), so a stop in 'fbs' leaves nothing to compute."""
    cfg, full = uninterrupted
    out = tmp_path / "o"
    with pytest.raises(Stop):
        run(cfg, out, progress=stop_at("fbs", 5))
    assert len((out / "fbs_results.csv").read_text().splitlines()) == 1 + 5
    calls = count_chains(monkeypatch)
    run(cfg, out, resume=True)
    assert calls == []
    assert_same_results(cfg, out, full)


def test_resume_in_none_computes_only_the_points_left(tmp_path, monkeypatch, uninterrupted):
    cfg, full = uninterrupted
    n = cfg.trajectory.num_points
    out = tmp_path / "o"
    with pytest.raises(Stop):
        run(cfg, out, progress=stop_at("none", 4))
    k = len((out / "none_results.csv").read_text().splitlines()) - 1
    assert 0 < k < n
    calls = count_chains(monkeypatch)
    run(cfg, out, resume=True)
    assert calls == [("none", i) for i in range(k, n)]
    assert_same_results(cfg, out, full)


def test_resume_with_a_damaged_chain_store_recomputes_what_it_lost(tmp_path, monkeypatch,
                                                                    uninterrupted):
    cfg, full = uninterrupted
    out = tmp_path / "o"
    with pytest.raises(Stop):
        run(cfg, out, progress=stop_at("fbs", 2))
    data = bytearray((out / CHAIN_FILE).read_bytes())
    data[len(data) // 2] ^= 0xFF
    (out / CHAIN_FILE).write_bytes(bytes(data))
    calls = count_chains(monkeypatch)
    run(cfg, out, resume=True)
    assert len(calls) > 0
    assert_same_results(cfg, out, full)


# -- a run killed at random points ----------------------------------------------------------

def killed_and_resumed(tmp_path, cfg_file, kills, seed: int, workers: int, sig) -> None:
    """Run the config uninterrupted; then, per kill, a fresh run killed with ``sig`` at a
    seeded random moment (a share of the uninterrupted run's time) and resumed (or, killed
    before run.json existed, run again): the result files must equal the uninterrupted ones."""
    cfg = config_from_dict(json.loads(cfg_file.read_text()))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    base = [sys.executable, "-m", "veriloc_rt.cli", "run", str(cfg_file), "--workers", str(workers)]
    t = time.monotonic()
    full = tmp_path / "full"
    r = subprocess.run(base + ["--out", str(full)], cwd=tmp_path, env=env, capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    t_full = time.monotonic() - t
    rng = np.random.default_rng(seed)
    resumed = 0
    for k in range(kills):
        out = tmp_path / f"killed{k}"
        p = subprocess.Popen(base + ["--out", str(out)], cwd=tmp_path, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            p.wait(timeout=rng.uniform(0.3, 0.95) * t_full)
        except subprocess.TimeoutExpired:
            p.send_signal(sig)
            p.wait(timeout=60)
            # Ctrl-C and SIGTERM (issue 37) stop it alike: 128 + the signal, 'stopped' (0: it
            # had just finished; -sig: it was still importing, before the handlers exist)
            if sig != signal.SIGKILL and p.returncode not in (0, -sig):
                assert p.returncode == 128 + sig
                assert not (out / OWNER_FILE).exists()
                if (out / "run.json").exists():
                    assert json.loads((out / "run.json").read_text())["status"] == "stopped"
        r = subprocess.run(base + ["--out", str(out), "--resume"], cwd=tmp_path, env=env,
                           capture_output=True, text=True)
        if r.returncode == 2 and "nothing to resume" in r.stderr:
            r = subprocess.run(base + ["--out", str(out)], cwd=tmp_path, env=env,
                               capture_output=True, text=True)
        else:
            resumed += 1
        assert r.returncode == 0, r.stderr
        assert_same_results(cfg, out, full)
    assert resumed > 0


def test_killed_runs_resume_to_the_same_bytes_fast(tmp_path):
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(dict(UMA, run={"scenarios": ["none", "fbs"],
                                             "evaluate_encrypted": False})))
    killed_and_resumed(tmp_path, cfg, kills=1, seed=19, workers=1, sig=signal.SIGKILL)


@pytest.mark.slow
@pytest.mark.parametrize("sig, workers", [(signal.SIGKILL, 2), (signal.SIGINT, 2),
                                          (signal.SIGTERM, 2)],
                         ids=["SIGKILL", "SIGINT", "SIGTERM"])
def test_killed_runs_resume_to_the_same_bytes(tmp_path, sig, workers):
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(dict(UMA, trajectory={"num_points": 12},
                                   run={"scenarios": ["none", "fbs", "meaconing", "jamming"]})))
    killed_and_resumed(tmp_path, cfg, kills=4, seed=int(sig), workers=workers, sig=sig)


@pytest.mark.slow
@pytest.mark.raytrace
def test_killed_ray_traced_runs_resume_to_the_same_bytes(tmp_path):
    """The tiny canyon, the cache shared (the uninterrupted run fills it first, so that every
    run uses the same traced paths: Sionna RT is not bit-exact from one trace to the next)."""
    data = json.loads((ROOT / "configs" / "ci-tiny.json").read_text())
    data["trajectory"]["num_points"] = 10
    data["propagation"]["raytrace"]["cache_dir"] = str(tmp_path / "cache")
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(data))
    killed_and_resumed(tmp_path, cfg, kills=3, seed=7, workers=2, sig=signal.SIGKILL)


@pytest.mark.slow
@pytest.mark.raytrace
def test_ctrl_c_during_ray_tracing_then_resume_reuses_the_traced_calls(tmp_path):
    """Issue #19: Ctrl-C while tracing said 'add --resume', then --resume refused ('no
    run.json'). Now the resumed run finds every call traced before the stop in the cache (one
    hit each) and traces only the others: hits + calls = the calls of the whole plan."""
    data = json.loads((ROOT / "configs" / "ci-tiny.json").read_text())
    data["trajectory"]["num_points"] = 10
    # the least work a PathSolver call may take: the 50 links go in several calls
    data["propagation"]["raytrace"].update(cache_dir=str(tmp_path / "cache"), work_per_call=100_000)
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(data))
    out = tmp_path / "o"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    base = [sys.executable, "-m", "veriloc_rt.cli", "run", str(cfg), "--workers", "1"]
    p = subprocess.Popen(base + ["--out", str(out)], cwd=tmp_path, env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    entries = tmp_path / "cache" / "raytrace"
    deadline = time.monotonic() + 300
    while p.poll() is None and not any(entries.glob("*.npz")):
        assert time.monotonic() < deadline
        time.sleep(0.02)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=300)
    assert p.returncode == 130, err
    assert "add --resume" in err
    assert json.loads((out / "run.json").read_text())["status"] == "stopped"
    traced_before = len(list(entries.glob("*.npz")))
    r = subprocess.run(base + ["--out", str(out), "--resume"], cwd=tmp_path, env=env,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    stats = json.loads((out / "propagation_summary.json").read_text())["raytrace_stats"]
    assert stats["cache_hits"] == traced_before
    assert stats["cache_hits"] > 0 and stats["calls"] > 0    # stopped while tracing
    # the whole plan, traced once more from the now complete cache: all hits
    r = subprocess.run(base + ["--out", str(tmp_path / "again")], cwd=tmp_path, env=env,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    again = json.loads((tmp_path / "again" / "propagation_summary.json").read_text())
    assert again["raytrace_stats"]["calls"] == 0
    assert again["raytrace_stats"]["cache_hits"] == stats["cache_hits"] + stats["calls"]


def test_relative_out_gives_an_absolute_scene_path_and_run_json_a_relative_one(tmp_path,
                                                                                monkeypatch):
    """Regression (a real Dask cluster, issue #22): with a relative ``out_dir``, the geometry a
    cluster's workers receive held a path relative to the caller's working directory; it is
    absolute now. run.json records it relative to the run folder (issue #40: the folder can be
    moved), with the package's git revision when the package is a git checkout."""
    monkeypatch.chdir(tmp_path)
    cfg = config_from_dict({**UMA, "trajectory": {"num_points": 2},
                            "run": {"scenarios": ["none"]}})
    res = run(cfg, "rel")
    want = tmp_path.resolve() / "rel" / "scene" / "scene.xml"
    info = json.loads((tmp_path / "rel" / "run.json").read_text())
    assert info["scene_xml"] == "scene/scene.xml"
    assert info["versions"]["veriloc-rt"] == veriloc_rt.__version__
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                          text=True).stdout.strip()
    assert info["git_revision"].removesuffix("-dirty") == head
    assert info["resources"]["workers"] == 1
    assert res.geometry.scene_xml == want and res.out_dir == tmp_path.resolve() / "rel"
