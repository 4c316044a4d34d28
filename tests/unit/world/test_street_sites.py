"""scripts/street_sites.py's choice of street-level sites (``pick_sites``): junctions first,
then, with ``--along``, points along the streets, none closer than the spacing."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from veriloc_rt.world.streets import StreetGraph

ROOT = Path(__file__).resolve().parents[3]


def _script():
    spec = importlib.util.spec_from_file_location("street_sites",
                                                  ROOT / "scripts" / "street_sites.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _tee() -> StreetGraph:
    """A T junction at the origin, three straight 100 m streets (east, west, north)."""
    nodes = np.array([[0.0, 0.0], [100.0, 0.0], [-100.0, 0.0], [0.0, 100.0]])
    edges = np.array([[0, 1], [0, 2], [0, 3]])
    return StreetGraph(nodes, edges, tuple(nodes[list(e)] for e in edges))


def test_tee_by_hand():
    pick = _script().pick_sites
    # junctions only: the one node with three streets
    np.testing.assert_array_equal(pick(_tee(), 40.0), [[0.0, 0.0]])
    # along every 10 m, 40 m apart, by hand: the junction; the points 10-30 m out lie within
    # 40 m of it; 40 m out on each street (east, west, north: the polylines' order at equal
    # distance); 50-70 m lie within 40 m of those; 80 m out on each; 90 m within 40 m of those
    want = [[0, 0], [40, 0], [-40, 0], [0, 40], [80, 0], [-80, 0], [0, 80]]
    np.testing.assert_allclose(pick(_tee(), 40.0, along=10.0), want, atol=1e-9)


def test_grid_sites_are_spaced_on_the_streets_and_fill_them():
    pick = _script().pick_sites
    # a 3 x 3 grid of streets 100 m apart, each edge bent once (two segments)
    g = np.array([-100.0, 0.0, 100.0])
    nodes = np.array([[x, y] for x in g for y in g])
    idx = {tuple(p): i for i, p in enumerate(nodes)}
    edges, lines = [], []
    for (x, y) in nodes:
        for dx, dy in ((100.0, 0.0), (0.0, 100.0)):
            if (x + dx, y + dy) in idx:
                a, b = np.array([x, y]), np.array([x + dx, y + dy])
                mid = (a + b) / 2 + np.array([dy, dx]) * 0.05     # a 5 m kink
                edges.append([idx[(x, y)], idx[(x + dx, y + dy)]])
                lines.append(np.stack([a, mid, b]))
    graph = StreetGraph(nodes, np.array(edges), tuple(lines))
    spacing, step = 45.0, 5.0
    sites = pick(graph, spacing, along=step)
    d = np.linalg.norm(sites[:, None] - sites[None], axis=-1)
    assert np.all(d[~np.eye(len(sites), dtype=bool)] >= spacing)
    # the five junctions (degree >= 3) come first, the centre before the four edge midpoints
    junctions = {(0.0, 0.0), (-100.0, 0.0), (100.0, 0.0), (0.0, -100.0), (0.0, 100.0)}
    assert {tuple(p) for p in sites[:5]} == junctions and tuple(sites[0]) == (0.0, 0.0)

    def on_street(p):   # distance to the nearest segment of any polyline
        best = np.inf
        for line in lines:
            for a, b in zip(line[:-1], line[1:]):
                t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
                best = min(best, np.linalg.norm(p - (a + t * (b - a))))
        return best

    assert max(on_street(p) for p in sites) < 1e-9
    # maximal: every candidate left out lies within the spacing of a site, and every point of
    # the streets (sampled every 1 m) within one step of a candidate (the corners, degree 2,
    # are no candidates: the nearest is one step along a street), so within spacing + step
    samples = []
    for line in lines:
        for a, b in zip(line[:-1], line[1:]):
            n = int(np.ceil(np.linalg.norm(b - a)))
            samples.extend(a + (b - a) * t for t in np.linspace(0.0, 1.0, n + 1))
    near = np.linalg.norm(np.array(samples)[:, None] - sites[None], axis=-1).min(axis=1)
    assert near.max() < spacing + step
