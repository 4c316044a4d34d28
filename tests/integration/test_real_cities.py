"""Mesh scenes end to end: bad scenes are one-line errors (exit 2) from ``config check``, and a
short ray-traced run on a cropped part of a scene bundled with Sionna RT finishes."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.world.scene.export import read_ply, write_ply

from .test_bad_inputs import MINI, assert_one_line, check, run_cli

ROOT = Path(__file__).resolve().parents[2]


def mini(tmp_path: Path) -> Path:
    dst = tmp_path / "mini"
    shutil.copytree(MINI, dst)
    return dst


def scene_config(scene: Path, **extra) -> dict:
    return {"seed": 7, "scene": {"source": str(scene / "scene.xml")},
            "trajectory": {"num_points": 12, "region_m": 60.0}, **extra}


def drop_shape(scene: Path, shape_id: str) -> None:
    xml = scene / "scene.xml"
    text = xml.read_text()
    start = text.index(f'<shape type="ply" id="{shape_id}">')
    end = text.index("</shape>", start) + len("</shape>")
    xml.write_text(text[:start] + text[end:])


def transform_meshes(scene: Path, scale: float = 1.0, shift=(0.0, 0.0, 0.0)) -> None:
    for ply in (scene / "meshes").glob("*.ply"):
        v, f = read_ply(ply)
        write_ply(ply, v * scale + np.asarray(shift), f)


def test_scene_without_buildings(tmp_path):
    scene = mini(tmp_path)
    drop_shape(scene, "mesh-buildings")
    line = assert_one_line(*check(tmp_path, scene_config(scene))[::2], "scene.source")
    assert "no buildings" in line


def test_scene_without_ground(tmp_path):
    scene = mini(tmp_path)
    drop_shape(scene, "mesh-ground")
    line = assert_one_line(*check(tmp_path, scene_config(scene))[::2], "scene.source")
    assert "no flat ground" in line


def test_scene_that_is_not_xml(tmp_path):
    scene = mini(tmp_path)
    (scene / "scene.xml").write_bytes(b"ply\nformat binary_little_endian 1.0\n\x00\x01")
    line = assert_one_line(*check(tmp_path, scene_config(scene))[::2], "scene.source")
    assert "not valid XML" in line


def test_scene_in_kilometres(tmp_path):
    scene = mini(tmp_path)
    transform_meshes(scene, scale=1e-3)
    line = assert_one_line(*check(tmp_path, scene_config(scene))[::2], "scene.source")
    assert "(is it in metres?)" in line


def test_scene_far_from_the_origin(tmp_path):
    scene = mini(tmp_path)
    transform_meshes(scene, shift=(5000.0, 0.0, 0.0))
    line = assert_one_line(*check(tmp_path, scene_config(scene))[::2], "scene.source")
    assert "does not hold the origin" in line


def test_unknown_bundled_scene(tmp_path):
    line = assert_one_line(*check(tmp_path, {"scene": {"source": "sionna:atlantis"}})[::2],
                           "scene.source")
    assert "munich" in line   # the message lists the bundled scenes


def test_streets_too_narrow_for_the_derived_graph(tmp_path):
    # the mini canyon's streets are 5 m wide: no centre line keeps the clearance from both walls
    line = assert_one_line(*check(tmp_path, scene_config(mini(tmp_path)))[::2],
                           "trajectory.region_m")
    assert "no street" in line


def test_streets_json_through_a_building(tmp_path):
    scene = mini(tmp_path)
    # the street x = 0 of the mini canyon (pitch 35 m), then straight through the block east
    (scene / "streets.json").write_text(json.dumps(
        {"nodes": [[0.0, -50.0], [0.0, 0.0], [0.0, 17.5], [30.0, 17.5]],
         "edges": [[0, 1], [1, 2], [2, 3]]}))
    data = scene_config(scene, trajectory={"num_points": 30, "region_m": 60.0,
                                           "turn_probability": 1.0})
    line = assert_one_line(*check(tmp_path, data)[::2], "trajectory")
    assert "inside a building" in line


def _sites_config(tmp_path, rows: str) -> tuple[dict, object]:
    """A small canyon config whose BSs come from a sites CSV of ``rows`` (and that CSV's path)."""
    sites = tmp_path / "sites.csv"
    sites.write_text("x,y,z\n" + rows)
    return ({"seed": 3, "scene": {"extent_m": 140.0, "margin_m": 30.0},
             "topology": {"sites": str(sites)}, "trajectory": {"num_points": 12, "region_m": 70.0}},
            sites)


def test_sites_csv_with_a_bad_row(tmp_path):
    data, sites = _sites_config(tmp_path, "0,0,30\n50,x,30\n0,50,30\n")
    line = assert_one_line(*check(tmp_path, data)[::2], f"{sites}:3")
    assert "non-numeric" in line


def test_site_inside_a_building(tmp_path):
    # (17.5, 17.5) is the centre of a 30 m block of the canyon (pitch 35 m), 15 m high
    data, sites = _sites_config(tmp_path, "0,0,30\n17.5,17.5,10\n0,50,30\n")
    line = assert_one_line(*check(tmp_path, data)[::2], str(sites))
    assert "site 2 at (17.5, 17.5, 10.0) m is inside a building" in line


@pytest.mark.raytrace
def test_short_traced_run_on_a_cropped_bundled_scene(tmp_path):
    """etoile, cropped to 40 m around a 4-point drive and its rooftop BSs: every scenario runs
    and the serving links find paths."""
    cfg = {"seed": 2, "scene": {"source": "sionna:etoile", "margin_m": 40.0},
           "topology": {"isd_m": 120.0},
           "trajectory": {"num_points": 4, "region_m": 60.0, "adversary_lag_points": 1},
           "propagation": {"raytrace": {"rays_per_source": 2000, "edge_candidates": "sampled"}}}
    f = tmp_path / "c.json"
    f.write_text(json.dumps(cfg))
    code, out, err = run_cli("run", f, "--out", tmp_path / "r")
    assert code == 0, err
    r = tmp_path / "r"
    metrics = json.loads((r / "metrics.json").read_text())
    assert set(metrics["scenarios"]) == {"none", "fbs", "meaconing", "jamming"}
    for name in ("none", "fbs", "meaconing", "jamming"):
        assert (r / f"{name}_results.csv").read_text().count("\n") == 1 + 4   # header + points
    s = json.loads((r / "propagation_summary.json").read_text())
    assert s["num_points"] == 4 and s["num_buildings"] > 0
    assert s["bs_to_ue"]["links_with_path_share"] > 0
    assert (r / "scene" / "scene.xml").is_file()
    assert (r / "scene_top_view.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bs_reaching_no_point_warns(caplog):
    import logging

    from veriloc_rt.sim.checks import warn_silent_bs

    serving = np.array([[0, 1, 2], [0, 1, 3], [0, 4, 3]])
    has_path = np.array([[True, False, False], [True, False, True], [True, True, False]])
    # BS 1 serves points 0 and 1, no path at either; BS 2 serves point 0 only, no path;
    # BS 3 has a path at point 1, BS 4 at point 2
    with caplog.at_level(logging.WARNING):
        assert warn_silent_bs(has_path, serving) == [1, 2]
    assert caplog.records[0].getMessage().startswith("BS 1, 2 reach the UE at none of the points")
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert warn_silent_bs(np.ones((3, 3), bool), serving) == []
    assert not caplog.records
