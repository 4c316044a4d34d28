"""The scene folder a geometry build writes: each file complete or as it was (issue #19)."""

from __future__ import annotations

from pathlib import Path

import pytest

from veriloc_rt.config import config_from_dict
from veriloc_rt.world import geometry
from veriloc_rt.world.geometry import build_geometry

#: a small canyon (as configs/ci-tiny.json): builds in well under a second
TINY = {"scene": {"extent_m": 140.0, "margin_m": 30.0},
        "trajectory": {"num_points": 6, "region_m": 70.0}}


def _files(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def test_a_stop_while_writing_the_scene_leaves_the_old_scene(tmp_path, monkeypatch):
    scene = tmp_path / "scene"
    build_geometry(config_from_dict(dict(TINY, seed=1)), scene)
    old = _files(scene)
    assert set(old) == {"scene.xml", "meshes/buildings.ply", "meshes/ground.ply"}
    real = geometry.write_scene

    def stopped(canyon, out_dir, bounds):   # every file written, then Ctrl-C before placing
        real(canyon, out_dir, bounds)
        raise KeyboardInterrupt

    monkeypatch.setattr(geometry, "write_scene", stopped)
    with pytest.raises(KeyboardInterrupt):
        build_geometry(config_from_dict(dict(TINY, seed=2)), scene)
    assert _files(scene) == old   # no half-written file, no stray temporary folder


def test_the_scene_folder_gets_exactly_what_write_scene_writes(tmp_path, monkeypatch):
    scene = tmp_path / "scene"
    build_geometry(config_from_dict(dict(TINY, seed=1)), scene)
    old = _files(scene)
    direct = tmp_path / "direct"
    real = geometry.write_scene

    def also_direct(canyon, out_dir, bounds):
        real(canyon, direct, bounds)
        return real(canyon, out_dir, bounds)

    monkeypatch.setattr(geometry, "write_scene", also_direct)
    geo = build_geometry(config_from_dict(dict(TINY, seed=2)), scene)
    assert geo.scene_xml == scene / "scene.xml"
    new = _files(scene)
    assert new == _files(direct)           # the seed-2 scene, byte for byte, replaced seed 1's
    assert new != old                      # (the two seeds' canyons differ)
