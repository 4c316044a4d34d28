"""Rooftop candidate sites for a mesh scene: a sites CSV for ``topology.sites``.

Takes the BS sites of the hexagonal layout (``--isd`` metres between cell centres, unrotated,
a cell centred at the origin: every cell vertex within ``--region`` of the origin), moves each
to the nearest roof as ``topology.placement`` 'rooftop' does (``veriloc_rt.world.sites``:
at least 2 m inside the building's outline, ``--mast`` metres above its highest point there)
and drops duplicates (two sites moved onto the same roof point). With
``"selection": "traced_power"`` each point then measures the strongest of these roofs, to be
compared with the street-level candidates of ``scripts/street_sites.py``.

    .venv/bin/python scripts/roof_sites.py CONFIG --out SITES.csv [--isd 200] [--mast 3]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from veriloc_rt.config import load_config
from veriloc_rt.errors import InputError
from veriloc_rt.world.scene.external import MeshScene
from veriloc_rt.world.sites import rooftop_sites
from veriloc_rt.world.topology import HexLayout


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("--out", required=True)
    ap.add_argument("--isd", type=float, default=200.0)
    ap.add_argument("--mast", type=float, default=3.0)
    ap.add_argument("--region", type=float, default=None,
                    help="half-side of the square covered (default: the config's "
                         "trajectory.region_m + 2 x isd)")
    args = ap.parse_args(argv)
    cfg = load_config(args.config)
    if cfg.scene.is_canyon:
        print("error: scene.source: a mesh scene is needed (the canyon has no roofs to search)",
              file=sys.stderr)
        return 2
    region = args.region or cfg.trajectory.region_m + 2 * args.isd
    layout = HexLayout(args.isd, cfg.topology.bs_height_m, np.zeros(2), 0.0)
    reach = int(math.ceil(region / args.isd)) + 2
    d = np.arange(-reach, reach + 1)
    cells = np.stack(np.meshgrid(d, d, indexing="ij"), -1).reshape(-1, 2)
    xy = layout.cell_bs_positions(cells).reshape(-1, 3)[:, :2]
    _, first = np.unique(np.round(xy * 1000.0).astype(np.int64), axis=0, return_index=True)
    xy = xy[np.sort(first)]
    xy = xy[np.all(np.abs(xy) <= region, axis=1)]
    xy = xy[np.argsort(np.linalg.norm(xy, axis=1), kind="stable")]
    scene = MeshScene.from_xml(cfg.scene.xml_path)
    try:
        pos = rooftop_sites(scene, xy, args.mast)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    _, first = np.unique(np.round(pos * 1000.0).astype(np.int64), axis=0, return_index=True)
    pos = pos[np.sort(first)]
    lines = ["x,y,z"] + [f"{p[0]:.1f},{p[1]:.1f},{p[2]:.1f}" for p in pos]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}: {len(pos)} rooftop sites (hexagonal sites {args.isd:g} m ISD "
          f"within {region:g} m, on the nearest roofs, {args.mast:g} m masts)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
