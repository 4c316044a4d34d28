"""``--scheduler`` on a real cluster: ``dask scheduler`` and two ``dask worker`` processes.

Nothing of the cluster runs in the test process (unlike ``LocalCluster``): the workers are
started as a user starts them (:func:`~veriloc_rt.sim.process_cluster.process_cluster`), with
``--no-nanny``, their own working directory, ``PYTHONPATH`` on this checkout and without the
``OPENBLAS_NUM_THREADS=1`` that the command line and ``conftest.py`` set for themselves. The
independent reference is the same command run serially (``--workers 1``): every file it writes
must come out byte for byte the same, but for the fields named in :data:`TIMING_FIELDS`.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from veriloc_rt.sim.process_cluster import process_cluster

from .test_cli import ROOT

#: real Dask clusters of separate processes, ~1.5 min: CI's second step (-m heavy)
pytestmark = pytest.mark.heavy

#: small UMa run (path loss only, no tracing), as in test_montecarlo.py: 8 points, attack
#: window points 2..5; 2 realisations for the Monte Carlo
SMALL = {"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
         "trajectory": {"num_points": 8}, "seed": 5,
         "run": {"scenarios": ["none", "fbs"], "digsig": "shared", "evaluate_encrypted": False}}
REALISATIONS = 2
#: seconds a run may take before the test fails (about 10 s each on an idle 2-core machine)
RUN_TIMEOUT_S = 300.0

#: the fields that measure time or say where a run ran, per file name: removed before the
#: comparison. ``timing_s`` of metrics.json and run.json: stage times and wall time;
#: ``resources``: ``workers``, ``scheduler``, peak memory; ``raytrace_stats.wall_s`` of
#: propagation_summary.json: the wall time of the propagation draw.
TIMING_FIELDS = {"metrics.json": [("timing_s",), ("resources",)],
                 "run.json": [("timing_s",), ("resources",)],
                 "propagation_summary.json": [("raytrace_stats", "wall_s")]}
#: the placeholder of a run folder's absolute path, which run.json records (``scene_xml``)
OUT = "<out>"


def _without_timing(path: Path, out: Path) -> bytes:
    """The file's bytes; a JSON file of :data:`TIMING_FIELDS` re-serialised without them (as
    the package writes JSON: ``indent=2``) and with ``out``'s absolute path as :data:`OUT`."""
    data = path.read_bytes()
    if path.name not in TIMING_FIELDS:
        return data
    doc = json.loads(data)
    for keys in TIMING_FIELDS[path.name]:
        node = doc
        for k in keys[:-1]:
            node = node[k]
        assert keys[-1] in node, (path, keys)   # the field exists: the list is not stale
        del node[keys[-1]]
    return json.dumps(doc, indent=2).replace(str(out.resolve()), OUT).encode()


def assert_same_run_files(serial: Path, dask: Path) -> int:
    """Every file of ``serial`` is in ``dask`` and vice versa, with the same bytes (but for
    :data:`TIMING_FIELDS`) -> the number of files compared."""
    names = sorted(p.relative_to(serial) for p in serial.rglob("*") if p.is_file())
    assert names == sorted(p.relative_to(dask) for p in dask.rglob("*") if p.is_file())
    for name in names:
        a, b = _without_timing(serial / name, serial), _without_timing(dask / name, dask)
        if a != b:
            i = next((i for i, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
            raise AssertionError(f"{name} differs at byte {i}: {a[i - 80:i + 40]!r} != "
                                 f"{b[i - 80:i + 40]!r}")
    return len(names)


MC = {**SMALL, "run": {**SMALL["run"], "realisations": REALISATIONS}}


def _start(where: Path, config: dict, out: str, *extra) -> subprocess.Popen:
    """``veriloc-rt run <out>.json --out <out> ...`` started in ``where``, with paths relative
    to it (the workers' working directory is elsewhere); its output goes to ``<out>.log``."""
    (where / f"{out}.json").write_text(json.dumps(config))
    with open(where / f"{out}.log", "wb") as log:
        proc = subprocess.Popen([sys.executable, "-m", "veriloc_rt.cli", "run", f"{out}.json",
                                 "--out", out, *extra], cwd=where, stdout=log,
                                stderr=subprocess.STDOUT)
    proc.log = where / f"{out}.log"
    return proc


def _finish(proc: subprocess.Popen) -> None:
    """Wait for a run of :func:`_start`: exit 0, and no warning in its output."""
    proc.wait(timeout=RUN_TIMEOUT_S)
    text = proc.log.read_text()
    assert proc.returncode == 0, text
    assert "Warning" not in text, text


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The references, started first so that they run while the cluster starts: the Monte
    Carlo in ``mc_serial/``, the single run in ``one_serial/`` -> the folder and the processes
    (killed when the module ends, if still running)."""
    where = tmp_path_factory.mktemp("client")
    procs = [_start(where, MC, "mc_serial", "--workers", "1"),
             _start(where, SMALL, "one_serial", "--workers", "1")]
    yield where, procs
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """The scheduler's address and the workers' working directory; the processes are stopped
    when the module's tests are done, passed or failed (the context manager's exit)."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    cwd = tmp_path_factory.mktemp("worker-cwd")
    with process_cluster(2, env=env, cwd=cwd,
                         log_dir=tmp_path_factory.mktemp("dask-logs")) as address:
        yield address, cwd


def test_real_cluster_gives_the_serial_files(serial, cluster):
    """(a) a Monte Carlo of 2 realisations (one task each) and (b) a single run in trajectory
    chunks, through ``--scheduler``: the serial run's files. Regression: workers without
    one-thread BLAS computed other last bits in the uplink's least-squares fits (chains.bin
    differed) and took ~20x longer in the ToA search."""
    where, refs = serial
    address, worker_cwd = cluster
    _finish(_start(where, MC, "mc_dask", "--scheduler", address))
    _finish(_start(where, SMALL, "one_dask", "--scheduler", address))
    for proc in refs:
        _finish(proc)
    files = assert_same_run_files(where / "mc_serial", where / "mc_dask")
    # the Monte Carlo's lock, 3 JSON/CSV files and 2 plots; per realisation its lock, 8
    # JSON/CSV files (roc.csv and the two scenarios' links CSVs among them), chains.bin, 8 plots
    # (roc.png) and 3 scene files (XML, 2 PLY)
    assert files == 6 + REALISATIONS * 21
    timing = json.loads((where / "mc_dask" / "metrics.json").read_text())["resources"]
    assert timing["scheduler"] == address and timing["workers"] == 2

    assert assert_same_run_files(where / "one_serial", where / "one_dask") == 21
    timing = json.loads((where / "one_dask" / "metrics.json").read_text())["resources"]
    assert timing["scheduler"] == address and timing["workers"] == 2
    # the workers wrote nothing where they run: every file went to the client's --out
    assert not any(worker_cwd.iterdir())


@pytest.mark.raytrace
def test_ray_traced_realisations_use_the_clients_cache(cluster, tmp_path):
    """Regression: the realisations of a ray-traced Monte Carlo resolved the relative
    ``propagation.raytrace.cache_dir`` on the workers, so each traced into a cache of its own
    working directory; they use the client's (the serial run's) now."""
    address, worker_cwd = cluster
    tiny = json.loads((ROOT / "configs" / "ci-tiny.json").read_text())
    cfg = {**tiny, "trajectory": {**tiny["trajectory"], "num_points": 2},
           "run": {"scenarios": ["none"], "realisations": 2}}
    _finish(_start(tmp_path, cfg, "mc_traced", "--scheduler", address))
    cache = tmp_path / ".veriloc-cache" / "raytrace"   # the config's default, relative
    # one PathSolver call per realisation (2 points, one batch), none found in the cache
    calls = [json.loads((tmp_path / "mc_traced" / f"realisation_00{r}" /
                         "propagation_summary.json").read_text())["raytrace_stats"]["calls"]
             for r in range(2)]
    assert len(list(cache.glob("*.npz"))) == sum(calls) > 0
    assert not any(worker_cwd.iterdir())
