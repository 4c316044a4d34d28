"""What a resume saves: a full run, the same run killed at 90 % of its time, then resumed.

For each config: a warm-up run (untimed: Dr.Jit's kernel cache and the OS's file cache then
serve every timed run alike); ``veriloc-rt run`` into a new folder with a new (empty)
ray-tracing cache, timed (wall, the command as a user runs it); the same run again into another
folder with another empty cache, killed with SIGKILL where the full run was at ``--kill-at``
of its time (the rows its CSVs held then: a time alone would land elsewhere on a machine whose
load changes from run to run; while no row exists yet, at that time);
then ``--resume`` on it, timed. Prints the three times, the ratio resume / full (wall time of
the command, and the library's own ``run()`` time from ``metrics.json``, which leaves out the
interpreter's start and the imports), the rows each scenario had at the kill, and whether the
resumed folder's result CSVs equal the full run's byte for byte.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_resume.py [--out DIR] [--kill-at 0.9]
        [--only uma ci-tiny] [--points N]

Configs: the built-in default (the ray-traced canyon of ``veriloc-rt run``, 120 points), TR
38.901 UMa (configs/uma-default.json, 60 points) and the ray-traced tiny canyon
(configs/ci-tiny.json, 40 points). A resume costs at least what the full run did after the
kill (10 % of its time) plus the command's fixed start and finish (interpreter, imports,
figures: about 2 s), so the short runs show the fixed part most.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = {"default": (None, 120),
         "uma": (ROOT / "configs" / "uma-default.json", 60),
         "ci-tiny": (ROOT / "configs" / "ci-tiny.json", 40)}


def command(config: Path, out: Path, points: int, *extra: str) -> list[str]:
    return [sys.executable, "-c", "import sys; from veriloc_rt.cli import main; sys.exit(main())",
            "run", str(config), "--out", str(out), "--points", str(points), "--workers", "1",
            *extra]


def env() -> dict:
    return dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")


#: seconds between two looks at a running run's CSVs
POLL_S = 0.05


def total_rows(out: Path) -> int:
    """Rows in the run folder's result CSVs (headers excluded)."""
    n = 0
    for p in out.glob("*_results.csv"):
        try:
            n += max(p.read_bytes().count(b"\n") - 1, 0)
        except FileNotFoundError:   # replaced this instant
            pass
    return n


def timed(cmd: list[str], cwd: Path, out: Path) -> tuple[float, list]:
    """Run ``cmd``: its wall time and its timeline ``[(seconds, total rows), ...]``."""
    t = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=cwd, env=env(), stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True)
    timeline = []
    while p.poll() is None:
        timeline.append((time.perf_counter() - t, total_rows(out)))
        time.sleep(POLL_S)
    dt = time.perf_counter() - t
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr.read()}")
    return dt, timeline


def killed_at(cmd: list[str], cwd: Path, out: Path, rows: int, after_s: float) -> bool:
    """Run ``cmd`` and SIGKILL it once its CSVs hold ``rows`` rows (``rows`` 0: ``after_s``
    seconds in); whether it was still running then."""
    t = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=cwd, env=env(), stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
    while p.poll() is None:
        if (total_rows(out) >= rows) if rows else (time.perf_counter() - t >= after_s):
            p.send_signal(signal.SIGKILL)
            p.wait()
            return True
        time.sleep(POLL_S)
    return False


def with_cache(config: Path | None, cache: Path, dest: Path) -> Path:
    """A copy of ``config`` whose ray-tracing cache is ``cache``."""
    data = json.loads(config.read_text()) if config is not None else {}   # None: the built-in default
    data.setdefault("propagation", {}).setdefault("raytrace", {})["cache_dir"] = str(cache)
    dest.write_text(json.dumps(data))
    return dest


def rows(out: Path) -> str:
    """Rows per scenario CSV, as ``none 54, fbs 0``."""
    found = sorted(out.glob("*_results.csv"), key=lambda p: p.stat().st_mtime)
    return ", ".join(f"{p.name.split('_')[0]} {len(p.read_text().splitlines()) - 1}"
                     for p in found) or "no rows"


def bench(name: str, config: Path, points: int, work: Path, kill_at: float) -> dict:
    warm_cfg = with_cache(config, work / f"{name}-cache-warm", work / f"{name}-warm.json")
    timed(command(warm_cfg, work / f"{name}-warm", points), work, work / f"{name}-warm")
    full_cfg = with_cache(config, work / f"{name}-cache-full", work / f"{name}-full.json")
    part_cfg = with_cache(config, work / f"{name}-cache-part", work / f"{name}-part.json")
    # same config for both folders but the cache: compare configs without it
    full_out, part_out = work / f"{name}-full", work / f"{name}-part"
    t_full, timeline = timed(command(full_cfg, full_out, points), work, full_out)
    target = max((r for t, r in timeline if t <= kill_at * t_full), default=0)
    was_running = killed_at(command(part_cfg, part_out, points), work, part_out, target,
                            kill_at * t_full)
    at_kill = rows(part_out)
    t_resume, _ = timed(command(part_cfg, part_out, points, "--resume"), work, part_out)
    # in-process time of run() (metrics.json): without the interpreter's start and imports
    lib = {k: json.loads((o / "metrics.json").read_text())["timing_s"]["total"]
           for k, o in (("full", full_out), ("resume", part_out))}
    csvs = sorted(p.name for p in full_out.glob("*_results.csv"))
    same = all((full_out / c).read_bytes() == (part_out / c).read_bytes() for c in csvs)
    return {"config": name, "points": points, "full_s": t_full, "killed_at_s": kill_at * t_full,
            "killed_while_running": was_running, "resume_s": t_resume,
            "ratio": t_resume / t_full, "csvs_identical": same, "rows_at_kill": at_kill,
            "run_full_s": lib["full"], "run_resume_s": lib["resume"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="work folder (default: a temporary one)")
    ap.add_argument("--kill-at", type=float, default=0.9, help="share of the full run's time")
    ap.add_argument("--only", nargs="+", choices=sorted(CASES), default=sorted(CASES))
    ap.add_argument("--points", type=int, help="trajectory points (default: 60 UMa, 40 ci-tiny)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.out).resolve() if args.out else Path(tmp)   # the runs start in it
        work.mkdir(parents=True, exist_ok=True)
        print(f"{'config':8s} {'points':>6s} {'full s':>7s} {'kill s':>7s} {'resume s':>8s} "
              f"{'ratio':>6s} | run() {'full s':>6s} {'resume s':>8s} {'ratio':>6s} | "
              "identical CSVs  rows at the kill")
        for name in args.only:
            config, points = CASES[name]
            points = args.points or points
            r = bench(name, config, points, work, args.kill_at)
            flag = "" if r["killed_while_running"] else " (finished before the kill)"
            print(f"{name:8s} {points:6d} {r['full_s']:7.1f} {r['killed_at_s']:7.1f} "
                  f"{r['resume_s']:8.1f} {r['ratio']:6.1%} |       {r['run_full_s']:6.1f} "
                  f"{r['run_resume_s']:8.1f} {r['run_resume_s'] / r['run_full_s']:6.1%} | "
                  f"{str(r['csvs_identical']):14s}  "
                  f"{r['rows_at_kill']}{flag}",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
