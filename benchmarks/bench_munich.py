"""Tracing cost per link and link coverage on Munich beside the procedural canyon (a benchmark,
not a test).

For each config (default: ``configs/munich.json`` and the built-in canyon default) builds the
run's geometry with ``--points`` trajectory points, traces every link of the run (serving BS ->
UE, serving BS -> adversary, adversary -> UE; no cache) at the config's fidelity, and prints a
markdown table: scene size after the crop, links, tracing seconds (scene loading and kernel
compilation excluded: one warm-up link is traced first), milliseconds per link, and the share
of links with at least one path (coverage). Usage:

    python benchmarks/bench_munich.py [--points N] [CONFIG ...]   ('default': the built-in config)
"""

from __future__ import annotations

import argparse
import time

import harness
import numpy as np

from veriloc_rt.config import load_config, with_overrides
from veriloc_rt.propagation.cir import NO_TX


def bench(path: str, points: int) -> dict:
    cfg = with_overrides(load_config(None if path == "default" else path), points=points)
    t = time.perf_counter()
    with harness.geometry(cfg) as geo:
        geo_s = time.perf_counter() - t
        t = time.perf_counter()
        warm = harness.loaded_tracer(geo.scene_xml, cfg)
        harness.timed_links(warm, geo.bs_pos[:1], geo.ue.pos[:1])   # load + compile
        warm_s = time.perf_counter() - t
        prop, _ = harness.timed_trace(geo, cfg)
    s = prop.stats
    cov = {name: float(np.mean(c.has_path()[c.tx_index != NO_TX])) * 100.0
           for name, c in (("bs_ue", prop.bs_ue), ("bs_adv", prop.bs_adv), ("adv_ue", prop.adv_ue))}
    return {"config": path, "scene": cfg.scene.source, "triangles": len(geo.scene.triangles)
            if hasattr(geo.scene, "triangles") else int(geo.scene.box_meshes()[1].shape[0]),
            "bs": len(geo.bs_pos), "bs_z": geo.bs_pos[:, 2], "links": s["links"],
            "trace_s": s["trace_s"], "ms_per_link": 1e3 * s["trace_s"] / max(s["links"], 1),
            "geometry_s": geo_s, "warmup_s": warm_s, **cov}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("configs", nargs="*", default=["configs/munich.json", "default"])
    ap.add_argument("--points", type=int, default=20)
    args = ap.parse_args()
    print("| config | scene | triangles | BSs (heights m) | links | trace s | ms per link "
          "| BS->UE with a path % | BS->adversary % | adversary->UE % | geometry s "
          "| load + first link s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for path in args.configs:
        r = bench(path, args.points)
        heights = ", ".join(f"{z:.0f}" for z in r["bs_z"])
        print(f"| {r['config']} | {r['scene']} | {r['triangles']} | {r['bs']} ({heights}) "
              f"| {r['links']} | {r['trace_s']:.1f} | {r['ms_per_link']:.0f} | {r['bs_ue']:.1f} "
              f"| {r['bs_adv']:.1f} | {r['adv_ue']:.1f} | {r['geometry_s']:.1f} "
              f"| {r['warmup_s']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
