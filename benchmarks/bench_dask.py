"""Scaling of ``--scheduler`` on a real Dask cluster: 1 and 2 workers (a benchmark, not a test).

Runs a fixed UMa Monte Carlo (``configs/paper-uma.json`` with ``--realisations`` realisations
of ``--points`` points, one task per realisation) serially (``--workers 1``, no Dask) and then
on a cluster of separate ``dask scheduler`` and ``dask worker`` processes (one thread each;
:func:`veriloc_rt.sim.process_cluster.process_cluster`) of 1 and of 2 workers, each command in
its own process, and the same config as a single run of ``realisations x points`` points in
trajectory chunks (``run.realisations = 1``). Prints one table:

* ``wall s``: the command's wall time (process start to exit: imports, plots and all);
* ``speedup``: the serial command's wall time over this one's (same mode);
* ``tasks``: the run's tasks in the scheduler's task stream, ``compute s`` the sum of their
  compute times there (``startstops``, action ``compute``: on the worker, argument
  deserialisation and result serialisation excluded);
* ``overhead/task s``: ``(workers x span - compute) / tasks``, the worker time per task not
  spent computing: start-up of a task, transfers, waiting for the client, and idle workers at
  the end (the load imbalance of few tasks). ``span``: the Monte Carlo's own wall time
  (``timing_s.total``: from before the first task to the last result), for chunks the time
  the scenarios took (``timing_s.scenario_*``: the tasks run then; geometry, propagation and
  plots run on the client alone and are left out).

Each Dask run's result files are checked against the serial ones (the CSVs byte for byte).
Usage (19 minutes on the loaded 2-core machine of docs/notes/performance-history.md):

    python benchmarks/bench_dask.py [--out bench-dask] [--realisations 4] [--points 60] [--nanny]
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import harness

from veriloc_rt.sim.process_cluster import process_cluster

ROOT = harness.ROOT

CONFIG = ROOT / "configs" / "paper-uma.json"
#: key prefixes of the tasks each mode submits (veriloc_rt.sim.montecarlo, .executors)
TASK_PREFIX = {"montecarlo": "veriloc-realisation-", "chunks": "veriloc-chains-"}


def run_cli(cfg: dict, out: Path, *extra: str) -> tuple[float, dict]:
    """``veriloc-rt run`` in its own process -> (wall s, metrics.json timing_s)."""
    wall, metrics = harness.run_cli(cfg, out, *extra)
    return wall, metrics["timing_s"]


def csvs(folder: Path) -> dict:
    """Every result CSV under ``folder`` -> its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*.csv"))}


def span_s(mode: str, timing: dict) -> float:
    if mode == "montecarlo":
        return float(timing["total"])
    return sum(v for k, v in timing.items() if k.startswith("scenario_"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="bench-dask")
    ap.add_argument("--realisations", type=int, default=4)
    ap.add_argument("--points", type=int, default=60)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--nanny", action="store_true", help="start the workers under a nanny "
                    "(dask worker's default) instead of --no-nanny")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    out = Path(args.out).resolve()
    base = json.loads(CONFIG.read_text())
    base["trajectory"]["num_points"] = args.points
    configs = {"montecarlo": {**base, "run": {**base["run"], "realisations": args.realisations}},
               "chunks": {**base, "trajectory": {**base["trajectory"],
                                                 "num_points": args.points * args.realisations}}}
    rows = []
    serial = {}
    for mode, cfg in configs.items():
        wall, timing = run_cli(cfg, out / f"{mode}-serial", "--workers", "1")
        serial[mode] = wall
        rows.append({"mode": mode, "workers": "serial", "wall_s": wall, "speedup": 1.0,
                     "tasks": None, "compute_s": None, "overhead_s": None,
                     "span_s": span_s(mode, timing)})
        print(f"{mode} serial: {wall:.1f} s", file=sys.stderr, flush=True)
    from distributed import Client

    for n in args.workers:
        with process_cluster(n, nanny=args.nanny, log_dir=out / f"cluster-{n}") as address, \
                Client(address, set_as_default=False) as client:
            client.get_task_stream(count=1)   # starts the scheduler's task-stream recording
            for mode, cfg in configs.items():
                t0 = time.time()
                wall, timing = run_cli(cfg, out / f"{mode}-{n}", "--scheduler", address)
                stream = [t for t in client.get_task_stream(start=t0)
                          if str(t["key"]).startswith(TASK_PREFIX[mode])]
                compute = sum(s["stop"] - s["start"] for t in stream for s in t["startstops"]
                              if s["action"] == "compute")
                span = span_s(mode, timing)
                same = csvs(out / f"{mode}-{n}") == csvs(out / f"{mode}-serial")
                if not same:
                    raise SystemExit(f"error: {mode} on {n} workers wrote other CSVs than the "
                                     "serial run")
                rows.append({"mode": mode, "workers": n, "wall_s": wall,
                             "speedup": serial[mode] / wall, "tasks": len(stream),
                             "compute_s": compute, "span_s": span,
                             "overhead_s": (n * span - compute) / max(len(stream), 1)})
                print(f"{mode} on {n} workers: {wall:.1f} s", file=sys.stderr, flush=True)
    (out / "bench_dask.json").write_text(json.dumps(rows, indent=2))
    print(f"UMa ({CONFIG.name}), {args.realisations} realisations x {args.points} points "
          f"(Monte Carlo: one task per realisation) and one run of "
          f"{args.realisations * args.points} points in trajectory chunks; workers: "
          f"{'nanny' if args.nanny else '--no-nanny'}, --nthreads 1")
    print("| mode | workers | wall s | speedup | tasks | compute s | span s | overhead/task s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        opt = (lambda k, f: "-" if r[k] is None else format(r[k], f))
        print(f"| {r['mode']} | {r['workers']} | {r['wall_s']:.1f} | {r['speedup']:.2f} | "
              f"{opt('tasks', 'd')} | {opt('compute_s', '.1f')} | {r['span_s']:.1f} | "
              f"{opt('overhead_s', '.2f')} |")
    print(f"wrote {out}/bench_dask.json; every Dask run's CSVs equal the serial run's")
    return 0


if __name__ == "__main__":
    sys.exit(main())
