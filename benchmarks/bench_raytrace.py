#!/usr/bin/env python3
"""Benchmark: ray-tracing cost and coverage of the serving BS -> UE links on the default scene.

For each (direction, rays per source) setting it traces the serving links of the first
``--points`` trajectory points of the default config (no cache), in a fresh process so that
peak memory is per setting, and prints seconds per link, the share of links with at least one
valid path, peak RSS, and the deviation of first-path delay and power from the reference
setting (reciprocal, most rays). Forward tracing is not the reference: launched from a BS
hundreds of metres away, even 1e6 rays miss the earliest roof-edge diffraction of a third of the
links (their first path comes out tens of metres late; 1e7 rays close the gap).

    .venv/bin/python benchmarks/bench_raytrace.py                # 300 points, default sweep
    .venv/bin/python benchmarks/bench_raytrace.py --points 1200  # the full default trajectory
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import harness
import numpy as np

from veriloc_rt.config import RayTracingConfig
from veriloc_rt.constants import SPEED_OF_LIGHT

SWEEP = [("forward", 100_000), ("forward", 300_000), ("forward", 1_000_000),
         ("reciprocal", 3_000), ("reciprocal", 10_000), ("reciprocal", 30_000),
         ("reciprocal", 100_000), ("reciprocal", 300_000)]


def one(direction: str, rays: int, points: int, depth: int, out: Path,
        candidates: int = 2000) -> None:
    """Trace in this process and save first-path delay/power per link to ``out``."""
    from veriloc_rt.config import config_from_dict

    cfg = config_from_dict({"trajectory": {"num_points": points},
                            "propagation": {"raytrace": {"direction": direction,
                                                         "rays_per_source": rays,
                                                         "max_depth": depth,
                                                         "max_candidates_per_source": candidates}}})
    with harness.geometry(cfg) as geo:
        tracer = harness.loaded_tracer(geo.scene_xml, cfg)
        raw, dt = harness.timed_links(tracer, *harness.serving_links(geo))
    pol = cfg.propagation.raytrace.polarization
    raw = raw.project(pol.ue, pol.bs)
    a = raw.a[..., 0, 0]
    tau = np.where(raw.valid, raw.tau, np.inf)
    first = tau.argmin(axis=1)
    has = raw.valid.any(axis=1)
    rows = np.arange(len(tau))
    np.savez(out, tau=raw.tau, a=a, valid=raw.valid, inter=raw.interactions, first_tau=np.where(has, tau[rows, first], np.nan),
             first_pow=np.where(has, np.abs(a[rows, first]) ** 2, np.nan),
             total_pow=(np.abs(a) ** 2 * raw.valid).sum(1), has=has, seconds=dt,
             calls=tracer.stats["calls"], unique=tracer.stats["links_traced"],
             maxrss_gib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=300)
    ap.add_argument("--depth", type=int, default=RayTracingConfig().max_depth,
                    help="max_depth (default: the config's)")
    ap.add_argument("--only", help="settings, comma separated, e.g. reciprocal:10000,forward:1e6")
    ap.add_argument("--keep", help="folder to keep each setting's per-link results (.npz)")
    ap.add_argument("--candidates", type=int, default=2000,
                    help="raytrace.max_candidates_per_source (default 2000)")
    ap.add_argument("--one", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        one(args.one[0], int(args.one[1]), args.points, args.depth, Path(args.one[2]),
            args.candidates)
        return 0
    sweep = SWEEP if not args.only else [(o.split(":")[0], int(float(o.split(":")[1])))
                                         for o in args.only.split(",")]
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for direction, rays in sweep:
            f = Path(args.keep or tmp) / f"{direction}_{rays}.npz"
            f.parent.mkdir(parents=True, exist_ok=True)
            subprocess.run([sys.executable, __file__, "--points", str(args.points), "--depth",
                            str(args.depth), "--candidates", str(args.candidates), "--one",
                            direction, str(rays), str(f)], check=True)
            with np.load(f) as d:
                results[(direction, rays)] = {k: d[k] for k in d.files}
    recips = [r for d, r in results if d == "reciprocal"]
    ref_key = ("reciprocal", max(recips)) if recips else max(results, key=lambda k: k[1])
    ref = results[ref_key]
    n_links = len(ref["has"])
    print(f"default scene, {args.points} points, {n_links} serving BS->UE links, max_depth "
          f"{args.depth}, diffraction on; reference = {ref_key[0]} {ref_key[1]:.0e} rays")
    print(f"{'direction':>10} {'rays/src':>9} {'s/link':>7} {'links w/ path':>13} "
          f"{'peak GiB':>8} {'calls':>5} {'tau1 within 1 m':>15} {'|dtau1| p95 m':>13} {'dP1 p50 dB':>10} "
          f"{'dPtot p50 dB':>12}")
    table = []
    for (direction, rays), r in results.items():
        both = r["has"] & ref["has"]
        dtau = np.abs(r["first_tau"][both] - ref["first_tau"][both]) * SPEED_OF_LIGHT
        dp1 = 10 * np.log10(r["first_pow"][both] / ref["first_pow"][both])
        dpt = 10 * np.log10(r["total_pow"][both] / ref["total_pow"][both])
        row = {"direction": direction, "rays_per_source": int(rays),
               "s_per_link": float(r["seconds"]) / n_links,
               "links_with_path_pct": 100.0 * float(r["has"].mean()),
               "peak_rss_gib": float(r["maxrss_gib"]), "calls": int(r["calls"]),
               "first_path_within_1m_pct": 100.0 * float((dtau <= 1.0).mean()) if both.any() else None,
               "first_path_delay_dev_m_p95": float(np.percentile(dtau, 95)) if both.any() else None,
               "first_path_power_dev_db_p50": float(np.median(dp1)) if both.any() else None,
               "total_power_dev_db_p50": float(np.median(dpt)) if both.any() else None}
        table.append(row)
        print(f"{direction:>10} {rays:>9.0e} {row['s_per_link']:>7.4f} "
              f"{row['links_with_path_pct']:>12.1f}% {row['peak_rss_gib']:>8.2f} "
              f"{row['calls']:>5d} {row['first_path_within_1m_pct'] or 0:>14.1f}% "
              f"{row['first_path_delay_dev_m_p95'] or 0:>13.2f} "
              f"{row['first_path_power_dev_db_p50'] or 0:>10.2f} "
              f"{row['total_power_dev_db_p50'] or 0:>12.2f}")
    print(json.dumps(table))
    return 0


if __name__ == "__main__":
    sys.exit(main())
