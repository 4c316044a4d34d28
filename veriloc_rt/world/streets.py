"""Street graphs of mesh scenes: read from ``streets.json`` beside the scene XML, or derived from
the free space at UE height between the buildings.

``streets.json`` (written by the OpenStreetMap import, or by hand), in the scene's metric frame::

    {"nodes": [[x_m, y_m], ...], "edges": [[i, j], ...]}

edges are undirected, indices into ``nodes``, each a straight street segment.

Derivation: the buildings are rasterised at :data:`GRID_M` (:mod:`.scene.raster`); the cells
at least the clearance plus the discretisation margins away from any blocked cell (Euclidean
distance transform, ``scipy.ndimage``) form the drivable area; its skeleton (Zhang-Suen
thinning) becomes a graph (``networkx``) whose chains between junctions and ends are the edges,
simplified (Douglas-Peucker, ``shapely``) within a tolerance the margins include. Short dead-end
spurs (skeleton artefacts at corners) are pruned; the largest connected part is kept.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..inputs import parse_json, read_text
from .scene.external import MeshScene
from .scene.raster import rasterize

log = logging.getLogger(__name__)

STREETS_FILE = "streets.json"
#: largest streets.json read, bytes
MAX_STREETS_BYTES = 64 << 20
#: raster resolution of the derived graph, m
GRID_M = 1.0
#: clearance of a derived street centre line from every wall, m (the trajectory keeps >= this)
CLEARANCE_M = 1.0
#: Douglas-Peucker tolerance of the derived edges, m
SIMPLIFY_M = 0.5
#: dead ends shorter than this are skeleton artefacts and pruned, m
SPUR_M = 15.0


@dataclass(frozen=True, eq=False)
class StreetGraph:
    """An undirected street graph.

    nodes : [num_nodes, 2] float64, m; edges : [num_edges, 2] int64 (node indices)
    polylines : per edge, [num_vertices, 2] float64, m, from ``nodes[i]`` to ``nodes[j]``
    """

    nodes: np.ndarray
    edges: np.ndarray
    polylines: tuple

    @property
    def length(self) -> float:
        """Total street length, m."""
        return float(sum(np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in self.polylines))

    def neighbours(self) -> list[list[tuple[int, int]]]:
        """Per node, its (edge index, other node) pairs."""
        out: list[list[tuple[int, int]]] = [[] for _ in range(len(self.nodes))]
        for e, (i, j) in enumerate(self.edges):
            out[i].append((e, int(j)))
            out[j].append((e, int(i)))
        return out

    def within(self, half_side: float) -> "StreetGraph":
        """The edges lying entirely in the square ``|x|, |y| <= half_side``, largest connected part."""
        keep = [e for e, p in enumerate(self.polylines) if np.all(np.abs(p) <= half_side)]
        return _largest_part(self.nodes, self.edges[keep], [self.polylines[e] for e in keep])


def load_streets(path: str | Path, field: str = "scene.source") -> StreetGraph:
    """Read ``streets.json``; one-line errors naming the file for anything unusable."""
    name = str(path)
    data = parse_json(read_text(path, field, "street graph", MAX_STREETS_BYTES), name)
    if not isinstance(data, dict) or set(data) != {"nodes", "edges"}:
        raise InputError(name, 'expected an object {"nodes": [[x_m, y_m], ...], '
                         '"edges": [[i, j], ...]}')
    try:
        nodes = np.array(data["nodes"], dtype=float)
        edges = np.array(data["edges"], dtype=np.int64)
    except (TypeError, ValueError):
        raise InputError(name, "nodes must be [x_m, y_m] number pairs and edges [i, j] integer "
                         "pairs") from None
    if nodes.ndim != 2 or nodes.shape[1] != 2 or not len(nodes):
        raise InputError(name, f"nodes of shape {nodes.shape}, expected [num_nodes, 2]")
    if not np.all(np.isfinite(nodes)):
        raise InputError(name, f"node {int(np.argmax(~np.isfinite(nodes).all(1)))} is not finite")
    if edges.ndim != 2 or edges.shape[1] != 2 or not len(edges):
        raise InputError(name, f"edges of shape {edges.shape}, expected [num_edges, 2]")
    bad = (edges < 0).any(1) | (edges >= len(nodes)).any(1) | (edges[:, 0] == edges[:, 1])
    if bad.any():
        k = int(np.argmax(bad))
        raise InputError(name, f"edge {k} {edges[k].tolist()} must join two different nodes "
                         f"0..{len(nodes) - 1}")
    polylines = tuple(nodes[[i, j]] for i, j in edges)
    return StreetGraph(nodes, edges, polylines)


def scene_streets(scene: MeshScene, region_m: float, ue_height: float) -> StreetGraph:
    """The street graph of ``scene`` inside ``|x|, |y| <= region_m``: ``streets.json`` beside
    its XML when there is one, else derived (:func:`derive_streets`)."""
    path = scene.xml.parent / STREETS_FILE
    if path.is_file():
        graph = load_streets(path).within(region_m)
        log.info("street graph: %s, %d edges in the region", path, len(graph.edges))
        return graph
    return derive_streets(scene, region_m, ue_height)


def derive_streets(scene: MeshScene, region_m: float, ue_height: float,
                   clearance: float = CLEARANCE_M) -> StreetGraph:
    """Street centre lines from the free space at ``ue_height`` between the buildings.

    Every point of every edge keeps at least ``clearance`` from the blocked cells' walls: a free
    cell centre at distance ``d`` (transform to blocked cell centres) is at least
    ``d - res/sqrt(2) - res/4`` from a wall (the wall lies in the blocked cell, sampled every
    res/4); an edge between skeleton cells adds at most ``res/sqrt(2)``, the simplification
    :data:`SIMPLIFY_M`.
    """
    import networkx as nx
    from scipy import ndimage

    res = GRID_M
    x0, y0, x1, y1 = scene.ground_xy
    bounds = (max(x0, -region_m), max(y0, -region_m), min(x1, region_m), min(y1, region_m))
    grid = rasterize(scene.building_triangles, bounds, res, ue_height)
    free = ~grid.blocked
    # the ground's edge is a wall too
    free[[0, -1], :] = False
    free[:, [0, -1]] = False
    dist = ndimage.distance_transform_edt(free) * res
    need = clearance + 2.0 * res / math.sqrt(2.0) + res / 4.0 + SIMPLIFY_M
    skel = _thin(dist >= need)
    g = _pixel_graph(skel)
    nodes, edges, polylines = _chains(g, grid)
    graph = _largest_part(nodes, edges, polylines)
    graph = _prune(graph)
    if not len(graph.edges):
        raise InputError("trajectory.region_m", f"no street in the scene within {region_m:g} m "
                         f"of the origin is {2 * need:.1f} m wide or more (the derived street "
                         f"graph keeps {clearance:g} m from walls): a larger region, or a "
                         f"{STREETS_FILE} beside the scene")
    log.info("street graph derived: %d nodes, %d edges, %.0f m of streets", len(graph.nodes),
             len(graph.edges), graph.length)
    return graph


def _thin(img: np.ndarray) -> np.ndarray:
    """Zhang-Suen thinning of a binary image to a one-pixel-wide 8-connected skeleton
    (T. Y. Zhang and C. Y. Suen, "A fast parallel algorithm for thinning digital patterns",
    Commun. ACM 27(3), 1984, pp. 236-239)."""
    im = np.pad(img.astype(np.uint8), 1)
    while True:
        changed = False
        for step in (0, 1):
            p = im
            n = [np.roll(np.roll(p, -dy, 0), -dx, 1) for dy, dx in
                 ((-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1), (-1, -1))]
            # P2..P9 clockwise from north (rows are the first axis)
            b = sum(n)
            a = sum(((n[k] == 0) & (n[(k + 1) % 8] == 1)).astype(np.uint8) for k in range(8))
            p2, p4, p6, p8 = n[0], n[2], n[4], n[6]
            if step == 0:
                c = (p2 * p4 * p6 == 0) & (p4 * p6 * p8 == 0)
            else:
                c = (p2 * p4 * p8 == 0) & (p2 * p6 * p8 == 0)
            rm = (p == 1) & (b >= 2) & (b <= 6) & (a == 1) & c
            if rm.any():
                im = im.copy()
                im[rm] = 0
                changed = True
        if not changed:
            return im[1:-1, 1:-1].astype(bool)


def _pixel_graph(skel: np.ndarray):
    """8-connected graph of skeleton cells; a diagonal link only where no orthogonal path of
    two links joins the same cells (keeps junctions free of small triangles)."""
    import networkx as nx

    g = nx.Graph()
    ii, jj = np.nonzero(skel)
    on = set(zip(ii.tolist(), jj.tolist()))
    g.add_nodes_from(on)
    for i, j in on:
        for di, dj in ((1, 0), (0, 1)):
            if (i + di, j + dj) in on:
                g.add_edge((i, j), (i + di, j + dj))
        for di, dj in ((1, 1), (1, -1)):
            q = (i + di, j + dj)
            if q in on and (i + di, j) not in on and (i, j + dj) not in on:
                g.add_edge((i, j), q)
    return g


def _chains(g, grid) -> tuple[np.ndarray, np.ndarray, list]:
    """Contract chains of degree-2 cells into edges between junctions and ends."""
    from shapely.geometry import LineString

    key = {n for n in g.nodes if g.degree(n) != 2}
    for comp in _components(g):  # closed loops without a junction: one cell becomes a node
        if not key.intersection(comp):
            key.add(min(comp))
    index = {n: k for k, n in enumerate(sorted(key))}
    nodes = grid.centres(np.array(sorted(key), dtype=np.int64).reshape(-1, 2))
    edges, polylines, seen = [], [], set()
    for start in sorted(key):
        for nb in sorted(g.neighbors(start)):
            if (start, nb) in seen:
                continue
            path = [start, nb]
            while path[-1] not in key:
                nxt = [q for q in g.neighbors(path[-1]) if q != path[-2]]
                path.append(nxt[0])
            seen.add((path[-1], path[-2]))
            seen.add((start, nb))
            if path[-1] == start and len(path) < 4:
                continue
            xy = grid.centres(np.array(path, dtype=np.int64))
            line = np.asarray(LineString(xy).simplify(SIMPLIFY_M).coords) if len(xy) > 2 else xy
            edges.append((index[start], index[path[-1]]))
            polylines.append(line)
    return nodes, np.array(edges, dtype=np.int64).reshape(-1, 2), polylines


def _components(g) -> list:
    import networkx as nx
    return [set(c) for c in nx.connected_components(g)]


def _largest_part(nodes: np.ndarray, edges: np.ndarray, polylines: list) -> StreetGraph:
    """The connected part of the graph with the most street length, nodes renumbered."""
    import networkx as nx

    g = nx.MultiGraph()
    for e, (i, j) in enumerate(edges):
        g.add_edge(int(i), int(j), key=e,
                   length=float(np.linalg.norm(np.diff(polylines[e], axis=0), axis=1).sum()))
    if not g.number_of_edges():
        return StreetGraph(np.zeros((0, 2)), np.zeros((0, 2), np.int64), ())
    best = max(nx.connected_components(g),
               key=lambda c: sum(d["length"] for *_, d in g.subgraph(c).edges(data=True)))
    keep = sorted(best)
    renum = {n: k for k, n in enumerate(keep)}
    sel = [e for e, (i, _) in enumerate(edges) if int(i) in renum]
    return StreetGraph(np.asarray(nodes)[keep],
                       np.array([[renum[int(edges[e, 0])], renum[int(edges[e, 1])]] for e in sel],
                                dtype=np.int64).reshape(-1, 2),
                       tuple(polylines[e] for e in sel))


def _prune(graph: StreetGraph) -> StreetGraph:
    """Drop dead-end edges shorter than :data:`SPUR_M` (repeatedly), then merge the chains the
    removals leave at degree-2 nodes."""
    nodes, edges, polys = graph.nodes, graph.edges, list(graph.polylines)
    for _ in range(3):
        deg = np.bincount(edges.ravel(), minlength=len(nodes))
        lengths = np.array([np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in polys])
        spur = ((deg[edges[:, 0]] == 1) ^ (deg[edges[:, 1]] == 1)) & (lengths < SPUR_M)
        if not spur.any() or spur.all():
            break
        edges = edges[~spur]
        polys = [p for p, s in zip(polys, spur) if not s]
    nodes, edges, polys = _merge_degree2(nodes, edges, polys)
    return _largest_part(nodes, edges, polys)


def _merge_degree2(nodes, edges, polys):
    """Join the two edges at every node of degree 2 into one (unless that closes a loop)."""
    edges = [tuple(map(int, e)) for e in edges]
    polys = list(polys)
    skip: set[int] = set()
    while True:
        deg = np.bincount(np.array(edges, dtype=np.int64).ravel(), minlength=len(nodes))
        cand = [int(n) for n in np.flatnonzero(deg == 2) if int(n) not in skip]
        if not cand:
            return nodes, np.array(edges, dtype=np.int64).reshape(-1, 2), polys
        n = cand[0]
        at = [k for k, e in enumerate(edges) if n in e]
        if len(at) != 2:          # a self-loop at n
            skip.add(n)
            continue
        e1, e2 = at
        a = edges[e1][0] if edges[e1][1] == n else edges[e1][1]
        b = edges[e2][1] if edges[e2][0] == n else edges[e2][0]
        if a == b:                # merging would make a self-loop: keep this node
            skip.add(n)
            continue
        p1 = polys[e1] if edges[e1][1] == n else polys[e1][::-1]
        p2 = polys[e2] if edges[e2][0] == n else polys[e2][::-1]
        keep = [k for k in range(len(edges)) if k not in (e1, e2)]
        edges = [edges[k] for k in keep] + [(a, b)]
        polys = [polys[k] for k in keep] + [np.concatenate([p1, p2[1:]])]
