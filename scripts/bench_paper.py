"""Wall time, stage breakdown and peak memory of the paper evaluation (a benchmark, not a test).

Runs ``veriloc-rt run`` on the paper's UMa config once and on the ray-traced config twice, the
first time with an empty propagation cache (cold) and then with it filled (warm), each in its
own process, and prints one table from the runs' ``metrics.json`` (``timing_s``) against the
issue's targets: UMa <= 60 s, ray tracing <= 300 s cold / <= 60 s warm, peak memory <= 4 GiB,
then the ray tracer's cost per link of the cold run (its ``propagation_summary.json``).
Stage times other than tracing are CPU seconds summed over the chain workers, so with 2 workers
they add up to about twice the wall time they take. Usage (about half an hour on 2 cores):

    python scripts/bench_paper.py [--out bench-paper] [--points 1200] [--workers 2]
                                  [--only uma|raytrace]
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = {"uma": ROOT / "configs" / "paper-uma.json", "raytrace": ROOT / "configs" / "paper-raytrace.json"}
#: seconds, from the issue
TARGETS = {"uma": 60.0, "raytrace cold": 300.0, "raytrace warm": 60.0}
MEMORY_TARGET_MIB = 4 * 1024
#: receiver stages of the chain (veriloc_rt.phy.chain.STAGES minus waveform and channel)
RECEIVER = ("toa", "position", "aoa", "tags", "uplink")


def run_one(name: str, cfg: dict, out: Path, workers: int) -> dict:
    """One ``veriloc-rt run`` in its own process; its timing_s plus the measured wall time."""
    out.mkdir(parents=True, exist_ok=True)
    cfg_path = out / "config.json"
    cfg_path.write_text(json.dumps(cfg, indent=2))
    t = time.perf_counter()
    # -I: nothing imported from the current folder; --force: the bench owns this folder, and a
    # rerun into it replaces the previous bench's run
    proc = subprocess.run([sys.executable, "-I", "-m", "veriloc_rt.cli", "run", "--out",
                           str(out / "run"), "--workers", str(workers), "--force", "--",
                           str(cfg_path)],
                          capture_output=True, text=True)
    wall = time.perf_counter() - t
    (out / "stdout.txt").write_text(proc.stdout)
    (out / "stderr.txt").write_text(proc.stderr)
    if proc.returncode != 0:
        raise SystemExit(f"error: {name} run failed (exit {proc.returncode}); see {out}/stderr.txt")
    metrics = json.loads((out / "run" / "metrics.json").read_text())
    timing = {**metrics["timing_s"], **metrics.get("resources", {})}
    timing["wall"] = wall
    summary = out / "run" / "propagation_summary.json"
    stats = json.loads(summary.read_text()).get("raytrace_stats") if summary.exists() else None
    if stats:
        timing["raytrace_stats"] = stats
    return timing


def tracing_line(name: str, t: dict) -> str | None:
    """The ray tracer's cost per link of a run that traced (None: it traced nothing)."""
    st = t.get("raytrace_stats") or {}
    n = int(st.get("links_traced", 0))
    if n == 0:
        return None
    return (f"{name}: {n} distinct links traced of the run's {st['links']}, {st['wall_s']:.0f} s wall "
            f"({1e3 * st['wall_s'] / n:.1f} ms a link), {st['trace_s']:.0f} s of solver calls in "
            f"{st.get('processes', 1)} processes ({1e3 * st['trace_s'] / n:.1f} ms a link in a process)")


def peak_mib(t: dict) -> float:
    """Peak RSS of a run, MiB: its largest process (forked workers share the main one's pages)."""
    return max(t.get("peak_rss_main_mib", 0.0), t.get("peak_rss_worker_mib", 0.0))


def row(name: str, t: dict) -> str:
    rec = sum(t.get(f"{k}_total", 0.0) for k in RECEIVER)
    mem = peak_mib(t)
    target = TARGETS[name]
    stages = {"tracing": t.get("propagation", 0.0), "waveform": t.get("waveform_total", 0.0),
              "channel": t.get("channel_total", 0.0), "receiver": rec,
              "adversary": t.get("adversary_total", 0.0), "detectors": t.get("detectors_total", 0.0)}
    # wall share of each stage: tracing runs alone, the rest are CPU seconds over the workers
    workers = max(int(t.get("workers", 1)), 1)
    wall_share = {k: (v if k == "tracing" else v / workers) for k, v in stages.items()}
    worst = max(wall_share, key=wall_share.get)
    verdict = "met" if t["wall"] <= target else f"missed ({t['wall'] / target:.1f}x; {worst})"
    return (f"| {name} | {t['wall']:.0f} | " + " | ".join(f"{v:.0f}" for v in stages.values())
            + f" | {mem / 1024:.2f} | {target:.0f} s: {verdict} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="bench-paper")
    ap.add_argument("--points", type=int, default=1200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--only", choices=("uma", "raytrace"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    results = {}
    for model, path in CONFIGS.items():
        if args.only and model != args.only:
            continue
        cfg = json.loads(path.read_text())
        cfg.setdefault("trajectory", {})["num_points"] = args.points
        if model == "uma":
            results["uma"] = run_one("uma", cfg, out / "uma", args.workers)
            continue
        cache = out / "raytrace-cache"
        shutil.rmtree(cache, ignore_errors=True)
        cfg.setdefault("propagation", {}).setdefault("raytrace", {})["cache_dir"] = str(cache.resolve())
        for name in ("raytrace cold", "raytrace warm"):
            results[name] = run_one(name, cfg, out / name.replace(" ", "-"), args.workers)
    print(f"{args.points} points x 4 scenarios, --workers {args.workers}; stage columns: tracing "
          f"wall s, the others CPU s summed over workers")
    print("| run | wall s | tracing | waveform | channel | receiver | adversary | detectors | "
          "peak GiB | target |")
    print("| --- |" + " --- |" * 9)
    for name, t in results.items():
        print(row(name, t))
    for name, t in results.items():
        line = tracing_line(name, t)
        if line:
            print(line)
    (out / "bench_paper.json").write_text(json.dumps(results, indent=2))
    mem = max(peak_mib(t) for t in results.values())
    print(f"peak memory {mem / 1024:.2f} GiB (target {MEMORY_TARGET_MIB / 1024:.0f} GiB: "
          f"{'met' if mem <= MEMORY_TARGET_MIB else 'missed'}); wrote {out}/bench_paper.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
