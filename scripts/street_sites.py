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

import numpy as np

from veriloc_rt.cli import ArgumentParser, script_main
from veriloc_rt.config.world import MIN_ANTENNA_HEIGHT_M
from veriloc_rt.errors import InputError
from veriloc_rt.world.sites import SitesTool, write_sites_csv
from veriloc_rt.world.streets import scene_streets

#: the flags shared with scripts/roof_sites.py, and what this one's mean
TOOL = SitesTool(spacing="--spacing", spacing_default=200.0,
                 spacing_help="least distance between two sites, m",
                 height="--height", height_default=10.0,
                 height_help="antenna height above the ground, m",
                 min_height=MIN_ANTENNA_HEIGHT_M, canyon="the canyon has its own grid")


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


def street_sites(args: argparse.Namespace) -> str:
    """Write the sites CSV of parsed ``args``; the line that says what was written.

    :raises InputError: a bad flag, config or scene (:meth:`SitesTool.inputs`), too few sites,
        an ``--out`` that cannot be written
    """
    if args.along is not None and not (np.isfinite(args.along) and args.along > 0):
        raise InputError("--along", f"got {args.along:g}, expected a step > 0 m")
    cfg, scene, region = TOOL.inputs(args)
    graph = scene_streets(scene, region, cfg.trajectory.ue_height_m)
    picked = pick_sites(graph, args.spacing, args.along)
    TOOL.check_count(len(picked))
    write_sites_csv(args.out, np.column_stack([picked, np.full(len(picked), args.height)]),
                    z_format="g")
    return (f"wrote {args.out}: {len(picked)} street-level sites (junctions"
            + (f" and points every {args.along:g} m along the streets" if args.along else "")
            + f" within {region:g} m, at least {args.spacing:g} m apart, {args.height:g} m high)")


def main(argv: list[str]) -> int:
    ap = TOOL.parser(__doc__.splitlines()[0], ArgumentParser)
    ap.add_argument("--along", type=float, default=None,
                    help="also points every STEP m along the streets, after the junctions")
    args = ap.parse_args(argv)
    return script_main(lambda: street_sites(args))


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
