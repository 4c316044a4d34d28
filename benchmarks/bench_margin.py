"""Scene crop margin against per-link received power (a benchmark, not a test).

Traces a config's links (serving BS -> UE and adversary -> UE, at evenly spaced points of its
drive) once per crop margin (``scene.margin_m``) with the config's own fidelity, and compares
each link's received power and strongest path with those of the largest margin given (make it
the canyon's half-side, ``scene.extent_m``, to compare with the whole canyon). Prints one table
row per margin: buildings kept, tracing seconds (indicative: one trace, kernels compiled by the
first margin), the share of links more than 3 dB and 1 dB off, the p90 of the absolute
deviation, the share of links whose strongest reference path is found. Usage:

    python benchmarks/bench_margin.py [CONFIG] [--margins 150,200,300,450] [--points 120]
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace

import harness
import numpy as np

from veriloc_rt.config import Config, load_config
from veriloc_rt.propagation import link_metrics as lm


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?", help="config file (default: the built-in defaults)")
    ap.add_argument("--margins", default="150,200,300,450", help="m, comma-separated, largest last")
    ap.add_argument("--points", type=int, default=120, help="points evaluated (evenly spaced)")
    args = ap.parse_args()
    cfg = load_config(args.config) if args.config else Config()
    margins = [float(m) for m in args.margins.split(",")]
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for m in margins:
            c = replace(cfg, scene=replace(cfg.scene, margin_m=m))
            with harness.geometry(c, f"{tmp}/margin_{m:g}") as geo:
                n = geo.num_points
                sel = np.unique(np.linspace(0, n - 1, min(args.points, n)).round().astype(int))
                prop, dt = harness.timed_trace(geo, c, sel)
            runs[m] = (prop, sel, dt, geo.scene.num_buildings)
            print(f"margin {m:g} m: {geo.scene.num_buildings} buildings traced in "
                  f"{runs[m][2]:.1f} s", flush=True)
    ref = runs[margins[-1]][0]
    print(f"\nagainst the {margins[-1]:g} m margin\n")
    print("| margin m | buildings | trace s | links | serving links > 3 dB off % | > 1 dB off % "
          "| p90 abs dev. dB | strongest path found % | adversary -> UE links > 1 dB off % |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for m in margins:
        prop, sel, dt, nb = runs[m]
        d, p, pa = harness.power_deviation(prop, ref, sel)
        print(f"| {m:g} | {nb} | {dt:.1f} | {p.size} | {100 * np.mean(p > 3):.1f} | "
              f"{100 * np.mean(p > 1):.1f} | {lm.quantile(p, 90):.2f} | "
              f"{100 * np.nanmean(d['strongest_found']):.0f} | {100 * np.mean(pa > 1):.1f} |")


if __name__ == "__main__":
    main()
