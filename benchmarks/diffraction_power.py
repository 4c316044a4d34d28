"""Serving-link power on a config's canyon with Sionna's and with veriloc-rt's diffraction.

Traces the serving BS -> UE links of the config's trajectory twice (diffraction_coefficient
'sionna' and 'utd', everything else as configured) and prints each one's coverage and median
(p10 / p90) path gain at the first ULA element, and the per-link change.

    .venv/bin/python benchmarks/diffraction_power.py [CONFIG] [--points N] [--cache DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import harness
import numpy as np

from veriloc_rt.config import load_config


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?")
    ap.add_argument("--points", type=int, default=None)
    ap.add_argument("--cache", default=None, help="ray-tracing cache folder (default: none)")
    args = ap.parse_args()
    cfg = load_config(args.config)
    if args.points:
        cfg = cfg.replace(trajectory=dataclasses.replace(cfg.trajectory, num_points=args.points))
    gain = {}
    with harness.geometry(cfg) as geo:
        for coef in ("sionna", "utd"):
            rtc = dataclasses.replace(cfg.propagation.raytrace, diffraction_coefficient=coef)
            c = cfg.replace(propagation=dataclasses.replace(cfg.propagation, raytrace=rtc))
            prop, dt = harness.timed_trace(geo, c, adversary=False, cache_dir=args.cache)
            pw = np.sum(np.abs(prop.bs_ue.gains[:, :, 0, :]) ** 2, axis=-1).ravel()
            g = 10 * np.log10(np.where(pw > 0, pw, np.nan))
            gain[coef] = g
            print(f"{coef:6s}: {len(pw)} links, {dt:.1f} s, with a path {np.mean(pw > 0) * 100:.1f} %, "
                  f"path gain median {np.nanmedian(g):.1f} dB (p10 {np.nanpercentile(g, 10):.1f}, "
                  f"p90 {np.nanpercentile(g, 90):.1f})")
    d = gain["utd"] - gain["sionna"]
    print(f"utd - sionna per link: median {np.nanmedian(d):+.2f} dB, p10 {np.nanpercentile(d, 10):+.2f}, "
          f"p90 {np.nanpercentile(d, 90):+.2f}, more than 3 dB apart {np.nanmean(np.abs(d) > 3) * 100:.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
