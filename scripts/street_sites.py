"""Street-level candidate sites for a mesh scene: a sites CSV for ``topology.sites``.

Takes the scene's street graph (``streets.json`` beside the XML, or derived from the free space
between the buildings, as the drive generator does), keeps its junctions, and picks them
greedily, nearest the origin first, so that no two sites are closer than ``--spacing`` metres;
each site stands ``--height`` metres above the ground in the street (below the roofs for a
street-level, UMi-like deployment). With ``--along STEP`` the streets between the junctions
are filled too: points every STEP metres along each street (its polyline), picked after the
junctions by the same rule (no two sites closer than the spacing), as small cells on lamp
posts would be. A site under an overhang is refused by the run's own check (a BS inside a
building is an error), so check the file with ``veriloc-rt config check``.

    .venv/bin/python scripts/street_sites.py CONFIG --out SITES.csv [--spacing 200] [--height 10]
        [--along STEP]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from veriloc_rt.config import load_config
from veriloc_rt.world.scene.external import MeshScene
from veriloc_rt.world.streets import scene_streets


def pick_sites(graph, spacing: float, along: float | None = None) -> np.ndarray:
    """Street-level sites of a street graph (``nodes`` [n, 2], ``edges`` [m, 2], ``polylines``):
    its junctions (three or more edges), nearest the origin first, then, with ``along``, points
    every ``along`` metres along each polyline (its ends excluded: they are nodes), nearest the
    origin first; each kept when no site already kept lies closer than ``spacing``.

    :returns: [num_sites, 2] float64, m, in the order kept
    """
    degree = np.bincount(np.asarray(graph.edges).ravel(), minlength=len(graph.nodes))
    cand = np.asarray(graph.nodes)[degree >= 3]
    cand = cand[np.argsort(np.linalg.norm(cand, axis=1))]
    if along:
        pts = []
        for line in graph.polylines:
            seg = np.diff(line, axis=0)
            s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(seg, axis=1))])
            at = np.arange(along, s[-1], along)
            pts.append(np.stack([np.interp(at, s, line[:, 0]), np.interp(at, s, line[:, 1])],
                                axis=1))
        extra = np.concatenate(pts) if pts else np.zeros((0, 2))
        extra = extra[np.argsort(np.linalg.norm(extra, axis=1), kind="stable")]
        cand = np.concatenate([cand, extra])
    picked: list[np.ndarray] = []
    for p in cand:
        if all(np.linalg.norm(p - q) >= spacing for q in picked):
            picked.append(p)
    return np.array(picked).reshape(-1, 2)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("--out", required=True)
    ap.add_argument("--spacing", type=float, default=200.0)
    ap.add_argument("--height", type=float, default=10.0)
    ap.add_argument("--along", type=float, default=None,
                    help="also points every STEP m along the streets, after the junctions")
    ap.add_argument("--region", type=float, default=None,
                    help="half-side of the square searched (default: the config's "
                         "trajectory.region_m + 2 x spacing)")
    args = ap.parse_args(argv)
    if args.along is not None and not args.along > 0:
        print("error: --along: a step > 0 m is needed", file=sys.stderr)
        return 2
    cfg = load_config(args.config)
    if cfg.scene.is_canyon:
        print("error: scene.source: a mesh scene is needed (the canyon has its own grid)",
              file=sys.stderr)
        return 2
    region = args.region or cfg.trajectory.region_m + 2 * args.spacing
    scene = MeshScene.from_xml(cfg.scene.xml_path)
    graph = scene_streets(scene, region, cfg.trajectory.ue_height_m)
    picked = pick_sites(graph, args.spacing, args.along)
    lines = ["x,y,z"] + [f"{p[0]:.1f},{p[1]:.1f},{args.height:g}" for p in picked]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}: {len(picked)} street-level sites (junctions"
          + (f" and points every {args.along:g} m along the streets" if args.along else "")
          + f" within {region:g} m, at least {args.spacing:g} m apart, {args.height:g} m high)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
