"""Ray-tracing settings against a reference trace, link by link (a benchmark, not a test).

Traces every link of a config's drive (serving BS -> UE, adversary -> UE) once per setting (a
``propagation.raytrace`` field set to a value, e.g. ``candidate_plane_distance_m=30``) and
compares each link's received power with the reference config's trace of the same drive (read
from its propagation cache when it is there: the reference is usually expensive). Prints per
setting the tracing time (warm: the first setting also compiles the kernels, so list the
cheapest setting twice to see it) and the share of links more than 1 and 3 dB off. Usage:

    python scripts/bench_candidates.py REFERENCE.json [--config CONFIG] SETTING [SETTING ...]

The default run's reference of docs/performance.md is the default config with
``rays_per_source`` 1e6 and ``edge_candidates`` 'both' at the whole canyon's crop (450 m).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import fields, replace

import numpy as np

from veriloc_rt.config import Config, load_config
from veriloc_rt.propagation import link_metrics as lm
from veriloc_rt.propagation.raytrace import trace
from veriloc_rt.world.geometry import build_geometry


def patched(cfg: Config, setting: str) -> Config:
    """``cfg`` with ``name=value`` set in ``propagation.raytrace`` ('default': unchanged)."""
    if setting == "default":
        return cfg
    name, value = setting.split("=", 1)
    fid = cfg.propagation.raytrace
    kind = {f.name: type(getattr(fid, f.name)) for f in fields(fid)}[name]
    fid = replace(fid, **{name: kind(value)})
    return replace(cfg, propagation=replace(cfg.propagation, raytrace=fid))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reference", help="the reference config (same drive and scene as --config)")
    ap.add_argument("settings", nargs="+", help="name=value of propagation.raytrace, or 'default'")
    ap.add_argument("--config", help="the config whose settings are varied (default: the "
                    "reference's scene and drive with the built-in fidelity defaults)")
    args = ap.parse_args()
    ref_cfg = load_config(args.reference)
    base = load_config(args.config) if args.config else replace(
        ref_cfg, propagation=replace(ref_cfg.propagation, raytrace=Config().propagation.raytrace))
    geo = build_geometry(ref_cfg, "bench-candidates-scene")
    sel = np.arange(geo.num_points)
    t = time.perf_counter()
    ref = trace(geo, ref_cfg.propagation, ref_cfg.seed)
    print(f"reference: {time.perf_counter() - t:.1f} s ({ref.stats['cache_hits']} cache hits)")
    print("| setting | trace s | serving links > 1 dB off % | > 3 dB off % | p90 abs dev. dB "
          "| adversary -> UE links > 1 dB off % |")
    print("| --- | --- | --- | --- | --- | --- |")
    for s in args.settings:
        c = patched(base, s)
        t = time.perf_counter()
        prop = trace(geo, c.propagation, c.seed, cache_dir=None)
        dt = time.perf_counter() - t
        d = lm.link_deviation(lm.cir_link_arrays(prop.bs_ue, sel), lm.cir_link_arrays(ref.bs_ue, sel))
        p = np.abs(d["power_dev_db"])
        a = lm.link_deviation(lm.cir_link_arrays(prop.adv_ue, sel), lm.cir_link_arrays(ref.adv_ue, sel))
        pa = np.abs(a["power_dev_db"])
        print(f"| {s} | {dt:.1f} | {100 * np.mean(p > 1):.1f} | {100 * np.mean(p > 3):.1f} | "
              f"{lm.quantile(p, 90):.2f} | {100 * np.mean(pa > 1):.1f} |", flush=True)


if __name__ == "__main__":
    main()
