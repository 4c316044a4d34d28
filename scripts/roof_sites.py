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

import numpy as np

from veriloc_rt.cli import ArgumentParser, script_main
from veriloc_rt.world.sites import SitesTool, rooftop_sites, write_sites_csv
from veriloc_rt.world.topology import HexLayout

#: the flags shared with scripts/street_sites.py, and what this one's mean
TOOL = SitesTool(spacing="--isd", spacing_default=200.0,
                 spacing_help="inter-site distance of the hexagonal layout, m",
                 height="--mast", height_default=3.0,
                 height_help="mast height above the roof's highest point there, m",
                 min_height=0.0, canyon="the canyon has no roofs to search")


def roof_sites(args: argparse.Namespace) -> str:
    """Write the sites CSV of parsed ``args``; the line that says what was written.

    :raises InputError: a bad flag, config or scene (:meth:`SitesTool.inputs`), a scene
        without a roof wide enough, too few sites, an ``--out`` that cannot be written
    """
    cfg, scene, region = TOOL.inputs(args)
    layout = HexLayout(args.isd, cfg.topology.bs_height_m, np.zeros(2), 0.0)
    reach = int(math.ceil(region / args.isd)) + 2
    d = np.arange(-reach, reach + 1)
    cells = np.stack(np.meshgrid(d, d, indexing="ij"), -1).reshape(-1, 2)
    xy = layout.cell_bs_positions(cells).reshape(-1, 3)[:, :2]
    _, first = np.unique(np.round(xy * 1000.0).astype(np.int64), axis=0, return_index=True)
    xy = xy[np.sort(first)]
    xy = xy[np.all(np.abs(xy) <= region, axis=1)]
    xy = xy[np.argsort(np.linalg.norm(xy, axis=1), kind="stable")]
    pos = rooftop_sites(scene, xy, args.mast)
    _, first = np.unique(np.round(pos * 1000.0).astype(np.int64), axis=0, return_index=True)
    pos = pos[np.sort(first)]
    TOOL.check_count(len(pos))
    write_sites_csv(args.out, pos)
    return (f"wrote {args.out}: {len(pos)} rooftop sites (hexagonal sites {args.isd:g} m ISD "
            f"within {region:g} m, on the nearest roofs, {args.mast:g} m masts)")


def main(argv: list[str]) -> int:
    args = TOOL.parser(__doc__.splitlines()[0], ArgumentParser).parse_args(argv)
    return script_main(lambda: roof_sites(args))


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
