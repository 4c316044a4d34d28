"""Measure the UMi - Street Canyon twin on the default canyon with street-level sites.

Builds the default config with its BSs moved to street level: 10 m antennas at the street
crossings of a 210 m grid (6 block pitches of the default canyon's 35 m; 16 crossings at
+-105 and +-315 m), the UE served by its 3 nearest sites, ``--points`` points. Then:

1. ``run_compare`` on it (ray tracing against the auto twin, which is UMi there): the traced
   serving-link path loss against the UMi arm's, LoS and NLoS links apart, and the TR 38.901
   table at the traced links' median distances; then again with ``match_pathloss`` (the
   offsets applied, and the benign chain's errors without and with them);
2. the cost of the stochastic arms on that geometry: wall time of
   :func:`~veriloc_rt.propagation.stochastic.stochastic_propagation` per link (every link family
   of a run: BS -> UE, BS -> adversary, adversary -> UE), UMi against UMa, fast fading and
   path loss only, the least of ``--repeats`` runs.

Prints a markdown block (the one ``docs/compare.md`` quotes) and writes it to
``OUT/umi_twin.md``.

Usage (from the repository root)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/umi_twin.py --points 40 --out OUT
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script from a checkout without installing
    sys.path.insert(0, str(ROOT))

from veriloc_rt import __version__  # noqa: E402
from veriloc_rt.config import config_from_dict  # noqa: E402
from veriloc_rt.propagation.stochastic import stochastic_propagation  # noqa: E402
from veriloc_rt.studies.compare import run_compare  # noqa: E402
from veriloc_rt.world.geometry import build_geometry  # noqa: E402

GRID_M = 210.0
SITE_HEIGHT_M = 10.0


def street_sites(extent_m: float, grid_m: float = GRID_M) -> np.ndarray:
    """Street crossings on a ``grid_m`` grid, offset by half a grid from the origin (where the
    drive starts), inside the canyon's extent: [S, 3], m (+-105, +-315 m by default)."""
    k = int(np.floor(extent_m / grid_m))
    ticks = (np.arange(-k, k) + 0.5) * grid_m
    gx, gy = np.meshgrid(ticks, ticks, indexing="ij")
    return np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, SITE_HEIGHT_M)], axis=-1)


def _row(name, q) -> str:
    q = q or {}

    def f(v):
        return "n/a" if v is None else f"{v:.1f}"

    return f"{f(q.get('p50'))} [{f(q.get('p10'))}, {f(q.get('p90'))}]"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    base = config_from_dict({})
    sites = street_sites(base.scene.extent_m)
    csv = out / "street_sites.csv"
    csv.write_text("x,y,z\n" + "".join(f"{x:g},{y:g},{z:g}\n" for x, y, z in sites))
    cfg = config_from_dict({"trajectory": {"num_points": args.points},
                            "topology": {"sites": str(csv), "bs_height_m": SITE_HEIGHT_M}})

    t = time.perf_counter()
    res = run_compare(cfg, out / "compare", workers=1)
    wall = time.perf_counter() - t
    ch, tab, twin = res.channel, res.channel["tr38901_table"], res.twin
    tw = res.models[1]
    lines = [f"veriloc-rt {__version__}; default canyon, {len(sites)} street-level sites "
             f"({SITE_HEIGHT_M:g} m, {GRID_M:g} m grid), {args.points} points, seed {cfg.seed}, "
             f"3.5 GHz. Twin: {tw} ({twin['rule']}; BS {twin['bs_height_m']:g} m, roofs "
             f"{twin['roof_height_m']:g} m). Compare wall time {wall:.0f} s.", "",
             "| serving links | ray tracing | UMi (drawn) | TR 38.901 UMi table |",
             "| --- | --- | --- | --- |"]
    for cond, name in (("all", "all"), ("los", "LoS"), ("nlos", "NLoS")):
        a, b = ch["raytrace"][cond], ch[tw][cond]
        lines.append(f"| {name}: links (with a path) | {a.get('links')} "
                     f"({100 * a.get('links_with_path_share', 0):.0f} %) | {b.get('links')} "
                     f"({100 * b.get('links_with_path_share', 0):.0f} %) | |")
        ref = "" if cond == "all" else (f"{tab[cond]['pathloss_db']:.1f} at "
                                        f"{tab['d_2d_m'][cond]:.0f} m")
        lines.append(f"| {name}: path loss, dB, p50 [p10, p90] | "
                     f"{_row(None, a.get('pathloss_db'))} | {_row(None, b.get('pathloss_db'))} | "
                     f"{ref} |")
    t = time.perf_counter()
    matched = run_compare(cfg, out / "compare-matched", workers=1, match_pathloss=True)
    wall_m = time.perf_counter() - t
    off = matched.twin["pathloss_offset_db"]
    lines += ["", f"With `--match-pathloss` (wall {wall_m:.0f} s, the trace cached): "
              f"{off['los']:+.1f} dB on the twin's LoS links (basis {off['basis']['los']}), "
              f"{off['nlos']:+.1f} dB on its NLoS links (basis {off['basis']['nlos']}). Benign "
              "chain, scenario none:", "",
              "| quantity | ray tracing | UMi | UMi, median path loss matched |",
              "| --- | --- | --- | --- |"]

    def pq(e, key):
        q = e.get(key) or {}
        return ("n/a" if q.get("p50") is None else
                f"{q['p50']:.1f} / {q['p95']:.1f}")

    e_rt, e_tw, e_m = res.errors["raytrace"], res.errors[tw], matched.errors[tw]
    for key, name in (("position_error_m", "DL position error p50 / p95, m"),
                      ("toa_bias_los_m", "ToA bias, LoS links, p50 / p95, m"),
                      ("toa_bias_nlos_m", "ToA bias, NLoS links, p50 / p95, m")):
        lines.append(f"| {name} | {pq(e_rt, key)} | {pq(e_tw, key)} | {pq(e_m, key)} |")
    lines.append(f"| DL fix rate, % | {100 * e_rt['fix_rate']:.1f} | {100 * e_tw['fix_rate']:.1f} | "
                 f"{100 * e_m['fix_rate']:.1f} |")
    hm = [(r.detectors[m]["none"]["correct_decision_rate"].get("HMAC"))
          for r, m in ((res, "raytrace"), (res, tw), (matched, tw))]
    lines.append("| benign HMAC accepted, % | " + " | ".join(
        "n/a" if v is None else f"{100 * v:.1f}" for v in hm) + " |")   # fractions
    lines += ["", "Stochastic arm cost on this geometry (every link family of a run; least of "
              f"{args.repeats}):", "", "| model | mode | links | wall per link, us |",
              "| --- | --- | --- | --- |"]
    geo = build_geometry(cfg, out / "scene")
    for mode in ("fast_fading", "pathloss_only"):
        for model in ("uma", "umi"):
            prop = dataclasses.replace(cfg.propagation, model=model, uma_mode=mode)
            best, links = np.inf, 0
            for _ in range(args.repeats):
                p = stochastic_propagation(geo, prop, cfg.seed)
                best, links = min(best, p.stats["wall_s"]), p.stats["links"]
            lines.append(f"| {model} | {mode} | {links} | {1e6 * best / links:.1f} |")
    text = "\n".join(lines) + "\n"
    (out / "umi_twin.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
