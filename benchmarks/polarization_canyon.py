#!/usr/bin/env python3
"""Measure: per-link received power of the default canyon for antenna polarizations, surface
scattering and depolarization (docs/polarization.md).

One setting per process (``--setting``), tracing the serving BS -> UE links of the first
``--points`` trajectory points of the default config (reciprocal, no cache); every polarization
pair is projected from the same polarimetric trace. Writes per-link path gains to a JSON file;
``--summary`` prints the markdown tables from several such files.

    .venv/bin/python benchmarks/polarization_canyon.py --setting smooth --out smooth.json
    .venv/bin/python benchmarks/polarization_canyon.py --summary smooth.json rough_diffuse.json
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

import harness
import numpy as np

#: (BS port, UE port): the BS transmits, the UE receives
PAIRS = [("V", "V"), ("H", "H"), ("V", "H"), ("H", "V"), ("+45", "+45"), ("+45", "-45"),
         ("+45", "V"), ("+45", "H")]

#: name -> (materials overrides, diffuse_reflection, single-port 'V' arrays)
SETTINGS = {
    "smooth": ({}, False, False),
    "smooth_single_port": ({}, False, True),
    "rough_specular": ({"scattering_coefficient": 0.3}, False, False),
    "rough_diffuse": ({"scattering_coefficient": 0.3}, True, False),
    "rough_diffuse_no_xpd": ({"scattering_coefficient": 0.3, "xpr_db": 100.0}, True, False),
    "rough_diffuse_single_port": ({"scattering_coefficient": 0.3}, True, True),
}


def measure(setting: str, points: int, rays: int | None, out: str) -> None:
    from veriloc_rt.backend import import_sionna
    from veriloc_rt.config import config_from_dict
    from veriloc_rt.propagation.cir import INTERACTION_DIFFRACTION, INTERACTION_DIFFUSE

    materials, diffuse, single = SETTINGS[setting]
    rt_cfg = {"diffuse_reflection": diffuse, "materials": materials}
    if rays:
        rt_cfg["rays_per_source"] = rays
    cfg = config_from_dict({"trajectory": {"num_points": points},
                            "propagation": {"raytrace": rt_cfg}})
    fid = cfg.propagation.raytrace
    with harness.geometry(cfg) as geo:
        tracer = harness.loaded_tracer(geo.scene_xml, cfg)
        sionna = tracer.sionna_tracer()
        if single:   # the pre-polarimetric tracer: one 'V' port at each end (cost reference)
            rt = import_sionna()
            sionna.scene.tx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso",
                                                   polarization="V")
            sionna.scene.rx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso",
                                                   polarization="V")
        tx, rx = harness.serving_links(geo)
        raw, dt = harness.timed_links(tracer, tx, rx, replace(fid, direction="reciprocal"))
    res = {"setting": setting, "points": points, "links": len(tx), "rays": fid.rays_per_source,
           "unique_links": tracer.stats["links_traced"], "trace_s": dt,
           "s_per_link": dt / max(tracer.stats["links_traced"], 1),
           "paths_per_link_mean": float(raw.valid.sum(1).mean()), "gain": {}}
    for bs, ue in ([("V", "V")] if single else PAIRS):
        p = raw if single else raw.project(ue, bs)
        a = np.where(p.valid, p.a[..., 0, 0], 0.0)
        kept = p.keep_strongest(fid.max_paths_per_link)
        ak = np.where(kept.valid, kept.a[..., 0, 0], 0.0)
        pw = np.abs(a) ** 2
        res["gain"][f"{bs}/{ue}"] = {"all": pw.sum(1).tolist(),
                                     "kept": (np.abs(ak) ** 2).sum(1).tolist()}
        for kind, code in (("diffracted", INTERACTION_DIFFRACTION),
                           ("diffuse", INTERACTION_DIFFUSE)):
            has = np.any(p.interactions == code, axis=-1)
            res["gain"][f"{bs}/{ue}"][kind] = np.where(has, pw, 0.0).sum(1).tolist()
    with open(out, "w") as fh:
        json.dump(res, fh)
    print(f"{setting}: {res['unique_links']} links traced in {dt:.1f} s "
          f"({res['s_per_link']:.3f} s/link), {res['paths_per_link_mean']:.0f} paths/link")


def _db(x):
    x = np.asarray(x, float)
    return 10 * np.log10(np.where(x > 0, x, np.nan))


def label(r: dict) -> str:
    return f"{r['setting']} ({r['points']} pts, {r['rays'] // 1000}k rays)"


def summary(files: list[str]) -> None:
    runs = [json.load(open(f)) for f in files]
    def reference(r):   # smooth V/V of the same links (first such file given)
        base = next((b for b in runs if b["setting"] == "smooth" and b["points"] == r["points"]), r)
        return _db(base["gain"]["V/V"]["all"])
    print("| setting | BS/UE | median dB | p10 dB | p90 dB | vs smooth V/V, median (p10 / p90) dB "
          "| 32 kept: median dB | via diffraction, median % | diffuse, median % |")
    print("|---|---|---|---|---|---|---|---|---|")
    q = np.nanpercentile
    for r in runs:
        ref = reference(r)
        for pair, g in r["gain"].items():
            x, k = _db(g["all"]), _db(g["kept"])
            d = x - ref
            both = np.isfinite(d)
            tot = np.asarray(g["all"])
            share = {kind: 100 * np.median(np.asarray(g[kind])[tot > 0] / tot[tot > 0])
                     for kind in ("diffracted", "diffuse")}
            print(f"| {label(r)} | {pair} | {q(x, 50):.1f} | {q(x, 10):.1f} | {q(x, 90):.1f} "
                  f"| {np.median(d[both]):+.1f} ({q(d[both], 10):+.1f} / {q(d[both], 90):+.1f}) "
                  f"| {q(k, 50):.1f} | {share['diffracted']:.0f} | {share['diffuse']:.0f} |")
    print()
    print("| setting | rays/source | links traced | trace s | s/link | paths/link (mean) |")
    print("|---|---|---|---|---|---|")
    for r in runs:
        print(f"| {label(r)} | {r['rays']} | {r['unique_links']} | {r['trace_s']:.1f} | "
              f"{r['s_per_link']:.3f} | {r['paths_per_link_mean']:.0f} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--setting", choices=tuple(SETTINGS))
    ap.add_argument("--points", type=int, default=20)
    ap.add_argument("--rays", type=int, help="rays per source (default: the config's)")
    ap.add_argument("--out", help="JSON file of the setting's per-link gains")
    ap.add_argument("--summary", nargs="+", help="JSON files to tabulate")
    args = ap.parse_args()
    if args.summary:
        summary(args.summary)
        return 0
    if not (args.setting and args.out):
        ap.error("give --setting and --out, or --summary")
    measure(args.setting, args.points, args.rays, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
