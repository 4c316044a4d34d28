"""Procedural canyon: closed meshes, free streets, crop margin, byte-identical export."""

import hashlib

import numpy as np
import pytest
import trimesh

from veriloc_rt.config import SceneConfig
from veriloc_rt.errors import InputError
from veriloc_rt.world.scene.canyon import urban_canyon
from veriloc_rt.world.scene.export import (ply_bytes, read_ply, scene_bounds, write_ply,
                                           write_scene)


def small(**kw):
    return SceneConfig(**{"extent_m": 120.0, **kw})


def test_every_building_is_a_closed_box_of_the_right_volume():
    c = urban_canyon(small(height_jitter_m=3.0), np.random.default_rng(1))
    v, f = c.box_meshes()
    for b in range(c.num_buildings):
        m = trimesh.Trimesh(v[8 * b:8 * b + 8], f[12 * b:12 * b + 12] - 8 * b, process=False)
        assert m.is_watertight and m.is_winding_consistent
        fp = c.footprints[b]
        expect = (fp[2] - fp[0]) * (fp[3] - fp[1]) * c.heights[b]
        # outward normals give a positive signed volume equal to footprint x height
        assert m.volume == pytest.approx(expect, rel=1e-12)


def test_buildings_leave_streets_free():
    cfg = small()
    c = urban_canyon(cfg)
    # street strips: |x - k*pitch| < w/2. No footprint may intersect any strip.
    fp = c.footprints
    for axis in (0, 1):
        lo, hi = fp[:, axis], fp[:, axis + 2]
        k = np.round(lo / c.pitch)
        gap_lo = lo - k * c.pitch          # distance of the block edge from the street centre
        assert np.all(gap_lo >= cfg.street_width_m / 2 - 1e-9)
        assert np.allclose(hi - lo, cfg.block_size_m)
    # dense random points on centre lines are never inside a building
    rng = np.random.default_rng(0)
    t = rng.uniform(-c.extent, c.extent, 5000)
    k = rng.integers(-3, 4, 5000) * c.pitch
    pts = np.concatenate([np.stack([t, k], 1), np.stack([k, t], 1)])
    assert not c.inside_building(pts).any()


def test_inside_building_matches_footprints():
    c = urban_canyon(small())
    rng = np.random.default_rng(3)
    pts = rng.uniform(-c.extent, c.extent, (20000, 2))
    fp = c.footprints
    brute = ((pts[:, None, 0] > fp[:, 0]) & (pts[:, None, 0] < fp[:, 2])
             & (pts[:, None, 1] > fp[:, 1]) & (pts[:, None, 1] < fp[:, 3])).any(1)
    assert np.array_equal(c.inside_building(pts), brute)


def test_crop_keeps_exactly_the_buildings_within_margin():
    c = urban_canyon(small())
    pts = np.array([[0.0, 0.0], [70.0, -35.0]])
    margin = 25.0
    kept = c.crop(pts, margin)
    fp = c.footprints
    dx = np.maximum(np.maximum(fp[None, :, 0] - pts[:, None, 0], 0), pts[:, None, 0] - fp[None, :, 2])
    dy = np.maximum(np.maximum(fp[None, :, 1] - pts[:, None, 1], 0), pts[:, None, 1] - fp[None, :, 3])
    expect = (np.hypot(dx, dy) <= margin).any(0)
    assert kept.num_buildings == expect.sum() > 0
    assert np.array_equal(kept.footprints, fp[expect])


def _digest(folder):
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(p.name.encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def test_same_seed_gives_byte_identical_files(tmp_path):
    digests = []
    for run, seed in enumerate((5, 5, 6)):
        c = urban_canyon(small(height_jitter_m=4.0), np.random.default_rng(seed))
        out = tmp_path / str(run)
        write_scene(c, out, scene_bounds(c, np.zeros((1, 2)), 10.0))
        digests.append(_digest(out))
    assert digests[0] == digests[1]
    assert digests[0] != digests[2]


def test_ply_round_trip(tmp_path):
    c = urban_canyon(small())
    write_scene(c, tmp_path, scene_bounds(c, np.zeros((1, 2)), 10.0))
    v, f = read_ply(tmp_path / "meshes" / "buildings.ply")
    v0, f0 = c.box_meshes()
    assert np.allclose(v, v0, atol=1e-4) and np.array_equal(f, f0)


def test_ply_bytes_are_trimesh_writers_bytes():
    """The PLY writer gives the bytes trimesh's binary writer gives (the independent oracle:
    the files the propagation cache hashed before the writer moved here), for the canyon's
    buildings and ground and for a random mesh with float32 vertices and int64 faces."""
    c = urban_canyon(small(height_jitter_m=3.0), np.random.default_rng(3))
    rng = np.random.default_rng(4)
    meshes = [c.box_meshes(), c.ground_mesh(scene_bounds(c, np.zeros((1, 2)), 10.0)),
              ((rng.normal(size=(50, 3)) * 1e3).astype(np.float32),
               rng.integers(0, 50, size=(80, 3)).astype(np.int64))]
    for v, f in meshes:
        ref = trimesh.Trimesh(vertices=v, faces=f, process=False, validate=False)
        assert ply_bytes(v, f) == ref.export(file_type="ply", encoding="binary")


def test_ascii_and_binary_ply_read_the_same_mesh(tmp_path):
    """trimesh reads both encodings; the binary file is the package's writer's."""
    v0 = np.array([[0, 0, 0], [1.5, 0, 0], [0, 2.25, 0], [0, 0, 3.0]])
    f0 = np.array([[0, 1, 2], [0, 1, 3], [1, 2, 3]])
    write_ply(tmp_path / "b.ply", v0, f0)
    (tmp_path / "a.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n"
        + "".join(" ".join(map(str, r)) + "\n" for r in v0)
        + "".join("3 " + " ".join(map(str, r)) + "\n" for r in f0))
    for name in ("a.ply", "b.ply"):
        v, f = read_ply(tmp_path / name)
        assert np.array_equal(v, v0) and np.array_equal(f, f0), name   # all exact in float32


def test_bad_parameters_are_input_errors():
    with pytest.raises(InputError, match="scene.height_jitter_m"):
        urban_canyon(small(height_jitter_m=15.0), np.random.default_rng(0))
    with pytest.raises(InputError, match="scene.extent_m"):
        urban_canyon(SceneConfig(extent_m=20.0, block_size_m=30.0))
