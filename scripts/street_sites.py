"""Street-level candidate sites for a mesh scene: a sites CSV for ``topology.sites``.

Takes the scene's street graph (``streets.json`` beside the XML, or derived from the free space
between the buildings, as the drive generator does), keeps its junctions, and picks them
greedily, nearest the origin first, so that no two sites are closer than ``--spacing`` metres;
each site stands ``--height`` metres above the ground in the street (below the roofs for a
street-level, UMi-like deployment). A junction under an overhang is dropped by the run's own
check (a BS inside a building is an error), so check the file with ``veriloc-rt config check``.

    .venv/bin/python scripts/street_sites.py CONFIG --out SITES.csv [--spacing 200] [--height 10]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from veriloc_rt.config import load_config
from veriloc_rt.world.scene.external import MeshScene
from veriloc_rt.world.streets import scene_streets


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("--out", required=True)
    ap.add_argument("--spacing", type=float, default=200.0)
    ap.add_argument("--height", type=float, default=10.0)
    ap.add_argument("--region", type=float, default=None,
                    help="half-side of the square searched (default: the config's "
                         "trajectory.region_m + 2 x spacing)")
    args = ap.parse_args(argv)
    cfg = load_config(args.config)
    if cfg.scene.is_canyon:
        print("error: scene.source: a mesh scene is needed (the canyon has its own grid)",
              file=sys.stderr)
        return 2
    region = args.region or cfg.trajectory.region_m + 2 * args.spacing
    scene = MeshScene.from_xml(cfg.scene.xml_path)
    graph = scene_streets(scene, region, cfg.trajectory.ue_height_m)
    degree = np.bincount(graph.edges.ravel(), minlength=len(graph.nodes))
    cand = graph.nodes[degree >= 3]
    cand = cand[np.argsort(np.linalg.norm(cand, axis=1))]
    picked: list[np.ndarray] = []
    for p in cand:
        if all(np.linalg.norm(p - q) >= args.spacing for q in picked):
            picked.append(p)
    lines = ["x,y,z"] + [f"{p[0]:.1f},{p[1]:.1f},{args.height:g}" for p in picked]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}: {len(picked)} street-level sites ({len(cand)} junctions within "
          f"{region:g} m, at least {args.spacing:g} m apart, {args.height:g} m high)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
