"""Mesh scenes (Sionna's bundled cities): ground and buildings, derived street graphs, drives
on them, rooftop BSs. Every geometric claim is checked against the mesh with trimesh (its
plane section and ray casting), independently of the project's own raster and parity tests."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from veriloc_rt.config import Config, TopologyConfig, TrajectoryConfig
from veriloc_rt.config.world import bundled_scene_xml
from veriloc_rt.errors import InputError
from veriloc_rt.world.scene.external import MeshScene
from veriloc_rt.world.sites import load_sites, nearest_serving, rooftop_sites
from veriloc_rt.world.streets import CLEARANCE_M, derive_streets, load_streets, scene_streets
from veriloc_rt.world.trajectory import follower, generate_graph_trajectory

#: the path is checked every this many metres of arc length (the drive's kinematic step)
SAMPLE_M = 0.25
#: float32 PLY vertices (Sionna's scenes) carry ~1e-5 m; heights compared to this
HEIGHT_TOL_M = 1e-4


@pytest.fixture(scope="module")
def etoile() -> MeshScene:
    return MeshScene.from_xml(bundled_scene_xml("etoile"))


@pytest.fixture(scope="module")
def street_canyon() -> MeshScene:
    return MeshScene.from_xml(bundled_scene_xml("simple_street_canyon"))


def _trimesh(scene: MeshScene):
    import trimesh
    t = scene.building_triangles.reshape(-1, 3)
    return trimesh.Trimesh(vertices=t, faces=np.arange(len(t)).reshape(-1, 3), process=False)


def ray_hits_z(tris: np.ndarray, origins: np.ndarray, direction: np.ndarray) -> list:
    """Möller-Trumbore ray-triangle intersection (T. Möller and B. Trumbore, "Fast, minimum
    storage ray-triangle intersection", J. Graphics Tools 2(1), 1997): per origin, the z of
    every triangle the ray ``origin + t * direction`` (t > 0) hits."""
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    e1, e2, p, det, v0 = e1[ok], e2[ok], p[ok], det[ok], tris[ok, 0]
    out = []
    for o in origins:
        s = o - v0
        u = np.einsum("ij,ij->i", s, p) / det
        q = np.cross(s, e1)
        v = (q @ direction) / det
        t = np.einsum("ij,ij->i", e2, q) / det
        hit = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        out.append(o[2] + t[hit] * direction[2])
    return out


def wall_distance(scene: MeshScene, xyz: np.ndarray) -> np.ndarray:
    """Independent check: horizontal distance, m, from each point to the buildings' cut at its
    height (trimesh.intersections.mesh_plane, shapely)."""
    import shapely
    import trimesh

    z = float(xyz[0, 2])
    assert np.all(xyz[:, 2] == z)
    seg = trimesh.intersections.mesh_plane(_trimesh(scene), [0, 0, 1], [0, 0, z])
    walls = shapely.multilinestrings([shapely.linestrings(s[:, :2]) for s in seg])
    return shapely.distance(shapely.points(xyz[:, :2]), walls)


def inside_buildings(scene: MeshScene, xyz: np.ndarray) -> np.ndarray:
    """Independent check: an odd number of building faces a vertical ray up crosses
    (:func:`ray_hits_z`)."""
    # a ray up only meets faces whose footprint holds the point: test near ones only
    tris = scene.building_triangles
    inside = np.zeros(len(xyz), dtype=bool)
    lo, hi = tris[:, :, :2].min(axis=1), tris[:, :, :2].max(axis=1)
    for k, o in enumerate(xyz):
        near = np.all((lo <= o[:2] + 1e-9) & (hi >= o[:2] - 1e-9), axis=1)
        inside[k] = len(ray_hits_z(tris[near], o[None], np.array([0.0, 0.0, 1.0]))[0]) % 2 == 1
    return inside


def test_bundled_city_scenes_split_into_ground_and_buildings(etoile, street_canyon):
    # etoile's ground is the shape "Plane", simple_street_canyon's "floor" (read off the XMLs)
    assert [s.name for s in etoile.ground] == ["mesh-Plane"]
    assert [s.name for s in street_canyon.ground] == ["mesh-floor"]
    assert street_canyon.num_buildings == 6   # building_1 .. building_6
    lo, hi = street_canyon.bounds
    assert hi[2] == pytest.approx(50.9, abs=0.05)   # its tallest building (PLY vertices)


@pytest.mark.parametrize("name", ["etoile", "simple_street_canyon"])
def test_derived_drive_keeps_out_of_buildings_and_1m_from_walls(name, etoile, street_canyon):
    scene = {"etoile": etoile, "simple_street_canyon": street_canyon}[name]
    cfg = TrajectoryConfig(num_points=300, region_m=200.0 if name == "etoile" else 90.0,
                           turn_probability=0.6)
    graph = derive_streets(scene, cfg.region_m, cfg.ue_height_m)
    ue = generate_graph_trajectory(cfg, graph, np.random.default_rng(5))
    adv = follower(ue, cfg.adversary_lag_points, cfg.adversary_min_separation_m)
    # the whole covered path, not only the samples, and the adversary's points
    s = np.arange(min(adv.s.min(), ue.s.min()), ue.s.max(), SAMPLE_M)
    samples = ue.at_arclength(s)
    pts = np.concatenate([samples, ue.pos, adv.pos])
    pts[:, 2] = cfg.ue_height_m
    dist = wall_distance(scene, pts)
    assert dist.min() >= CLEARANCE_M, dist.min()
    # points >= 1 m from every wall are either all outside or deep inside a building: the
    # parity test on every 4th sample (1 m apart) and every trajectory point settles which
    few = np.concatenate([samples[::4], ue.pos, adv.pos])
    few[:, 2] = cfg.ue_height_m
    assert not inside_buildings(scene, few).any()
    assert ue.s[-1] - ue.s[0] > 100.0          # it drives somewhere (300 s)


def test_drive_keeps_the_generator_kinematics(etoile):
    cfg = TrajectoryConfig(num_points=400, region_m=200.0)
    graph = derive_streets(etoile, cfg.region_m, cfg.ue_height_m)
    ue = generate_graph_trajectory(cfg, graph, np.random.default_rng(2))
    speed = np.linalg.norm(np.diff(ue.pos, axis=0), axis=1) / cfg.dt_s
    # chord speeds never exceed the top cruise speed (chords are shorter than arcs)
    assert speed.max() <= cfg.max_speed_mps + 1e-9
    # arc length never decreases: the drive only goes forward along its route
    assert np.all(np.diff(ue.s) >= 0)
    # same seed, same drive; another seed, another drive
    again = generate_graph_trajectory(cfg, graph, np.random.default_rng(2))
    other = generate_graph_trajectory(cfg, graph, np.random.default_rng(3))
    assert np.array_equal(ue.pos, again.pos) and not np.array_equal(ue.pos, other.pos)


def test_streets_json_beside_the_scene_is_the_graph(tmp_path, street_canyon):
    # the street between the two rows of buildings of simple_street_canyon runs along y ~ -4
    # (building_4 ends at y = 9.6, building_6 starts at y = -8.6: read off the PLYs)
    streets = {"nodes": [[-80.0, 0.5], [0.0, 0.5], [80.0, 0.5]], "edges": [[0, 1], [1, 2]]}
    (tmp_path / "streets.json").write_text(json.dumps(streets))
    scene = replace(street_canyon, xml=tmp_path / "scene.xml")
    graph = scene_streets(scene, 90.0, 1.5)
    assert np.array_equal(graph.nodes, np.array(streets["nodes"]))
    cfg = TrajectoryConfig(num_points=60, region_m=90.0)
    ue = generate_graph_trajectory(cfg, graph, np.random.default_rng(0))
    assert np.allclose(ue.pos[:, 1], 0.5) and np.all(np.abs(ue.pos[:, 0]) <= 80.0 + 1e-9)


@pytest.mark.parametrize("text, problem", [
    ('{"nodes": [[0, 0]], "edges": [[0, 0]]}', "must join two different nodes"),
    ('{"nodes": [[0, 0], [1, 1]], "edges": [[0, 2]]}', "must join two different nodes"),
    ('{"nodes": [[0, 0], [1, "a"]], "edges": [[0, 1]]}', "number pairs"),
    ('{"nodes": [], "edges": []}', "expected [num_nodes, 2]"),
    ('{"nodes": [[0, 0], [1, 1]]}', "expected an object"),
])
def test_bad_streets_json_is_one_line(tmp_path, text, problem):
    f = tmp_path / "streets.json"
    f.write_text(text)
    with pytest.raises(InputError) as exc:
        load_streets(f)
    assert problem in str(exc.value) and "\n" not in str(exc.value)


def test_rooftop_bs_stands_mast_height_above_its_roof(etoile):
    mast = TopologyConfig().mast_height_m
    want = np.array([[0.0, 0.0], [150.0, -80.0], [-200.0, 120.0], [300.0, 250.0]])
    bs = rooftop_sites(etoile, want, mast)
    tris = etoile.building_triangles
    up = ray_hits_z(tris, bs, np.array([0.0, 0.0, 1.0]))
    down = ray_hits_z(tris, bs, np.array([0.0, 0.0, -1.0]))
    for k in range(len(bs)):
        assert len(up[k]) == 0                # nothing above the antenna: not inside
        roof = down[k].max()                  # the roof straight below
        assert bs[k, 2] - roof == pytest.approx(mast, abs=HEIGHT_TOL_M)
        assert roof > 2.0                     # a building's roof, not the ground
    # the checker of the drive test sees a building under each roof
    assert inside_buildings(etoile, np.column_stack([bs[:, :2], np.full(len(bs), 1.5)])).all()


def test_sites_csv_and_nearest_serving(tmp_path):
    f = tmp_path / "sites.csv"
    f.write_text("x,y,z,azimuth_deg\n0,0,20,90\n100,0,20,0\n0,100,20,0\n300,300,20,45\n")
    sites, az = load_sites(f)
    assert sites.shape == (4, 3) and az[0] == pytest.approx(np.pi / 2)
    xy = np.array([[10.0, 10.0], [280.0, 290.0]])
    bs, serving, used = nearest_serving(sites, xy)
    # point 0: site 1 (14.1 m), then sites 2 and 3 (both 90.6 m: file order); point 1: site 4
    # (22.4 m), site 3 (338.4 m), site 2 (341.2 m); ids in order of first use
    assert used.tolist() == [0, 1, 2, 3]
    assert serving.tolist() == [[0, 1, 2], [3, 2, 1]]
    assert np.array_equal(bs, sites)


@pytest.mark.parametrize("body, where, problem", [
    ("x,y\n0,0\n", "", "header"),
    ("x,y,z\n0,0,20\n1,1\n2,2,20\n", ":3", "2 columns, expected 3"),
    ("x,y,z\n0,0,20\n1,abc,20\n2,2,20\n", ":3", "non-numeric"),
    ("x,y,z\n0,0,20\n1,1,nan\n2,2,20\n", ":3", "non-finite"),
    ("x,y,z\n0,0,20\n1,1,0.5\n2,2,20\n", ":3", "BS height above"),
    ("x,y,z,azimuth_deg\n0,0,20,0\n1,1,20,400\n2,2,20,0\n", ":3", "-360 to 360"),
    ("x,y,z\n0,0,20\n1,1,20\n", "", "2 sites, expected at least 3"),
    ("x,y,z\n0,0,20\n1,1,20\n0,0,20\n", "", "same position"),
])
def test_bad_sites_csv_is_one_line(tmp_path, body, where, problem):
    f = tmp_path / "sites.csv"
    f.write_text(body)
    with pytest.raises(InputError) as exc:
        load_sites(f)
    assert exc.value.field == f"{f}{where}" and problem in exc.value.problem


def test_rooftop_placement_refused_on_the_canyon():
    from veriloc_rt.config import config_from_dict
    with pytest.raises(InputError) as exc:
        config_from_dict({"topology": {"placement": "rooftop"}})
    assert exc.value.field == "topology.placement"
    assert Config().topology.placement == "auto"


def test_written_crop_keeps_shared_edges(tmp_path, street_canyon):
    """The cropped scene merges each material's buildings into one PLY with the vertices shared
    (Sionna RT finds wedges, hence diffraction, only on edges two faces share): the six closed
    boxes of simple_street_canyon stay closed (watertight: every edge in exactly two faces)."""
    import trimesh

    from veriloc_rt.world.scene.export import read_ply, scene_shapes

    xml = street_canyon.write(tmp_path, street_canyon.ground_xy)
    shapes = scene_shapes(xml)
    assert shapes[-1][0] == "mesh-ground"
    nv = nf = 0
    for _, path, _ in shapes[:-1]:       # one PLY per building material
        v, f = read_ply(path)
        assert trimesh.Trimesh(vertices=v, faces=f, process=False).is_watertight
        nv, nf = nv + len(v), nf + len(f)
    assert (nv, nf) == (6 * 8, 6 * 12)   # 6 boxes: 8 corners, 12 triangles each
    again = MeshScene.from_xml(xml)
    assert len(again.building_triangles) == 6 * 12
