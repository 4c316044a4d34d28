"""Ray-tracing settings against a reference trace, link by link (a benchmark, not a test).

Traces every link of a config's drive (serving BS -> UE, adversary -> UE) once per setting (a
``propagation.raytrace`` field set to a value, e.g. ``candidate_plane_distance_m=30``) and
compares each link's received power with the reference config's trace of the same drive (read
from its propagation cache when it is there: the reference is usually expensive). Prints per
setting the tracing time (warm: the first setting also compiles the kernels, so list the
cheapest setting twice to see it) and the share of links more than 1 and 3 dB off. Usage:

    python benchmarks/bench_candidates.py REFERENCE.json [--config CONFIG] SETTING [SETTING ...]

The default run's reference of docs/performance.md is the default config with
``rays_per_source`` 1e6 and ``edge_candidates`` 'both' at the whole canyon's crop (450 m).
"""

from __future__ import annotations

import argparse
from dataclasses import fields, replace

import harness
import numpy as np

from veriloc_rt.config import Config, load_config
from veriloc_rt.propagation import link_metrics as lm


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
    with harness.geometry(ref_cfg) as geo:   # the cache keys on the scene files, not their folder
        compare(geo, ref_cfg, base, args.settings)


def compare(geo, ref_cfg: Config, base: Config, settings: list[str]) -> None:
    """Trace each setting on ``geo`` and print its row against the reference's trace."""
    sel = np.arange(geo.num_points)
    ref, dt = harness.timed_trace(geo, ref_cfg, cache_dir="default")   # the reference's cache
    print(f"reference: {dt:.1f} s ({ref.stats['cache_hits']} cache hits)")
    print("| setting | trace s | serving links > 1 dB off % | > 3 dB off % | p90 abs dev. dB "
          "| adversary -> UE links > 1 dB off % |")
    print("| --- | --- | --- | --- | --- | --- |")
    for s in settings:
        prop, dt = harness.timed_trace(geo, patched(base, s))
        _, p, pa = harness.power_deviation(prop, ref, sel)
        print(f"| {s} | {dt:.1f} | {100 * np.mean(p > 1):.1f} | {100 * np.mean(p > 3):.1f} | "
              f"{lm.quantile(p, 90):.2f} | {100 * np.mean(pa > 1):.1f} |", flush=True)


if __name__ == "__main__":
    main()
