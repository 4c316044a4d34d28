"""Tiny analytic scenes for ray-tracing tests, written with the package's own PLY writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from veriloc_rt.world.scene.canyon import UrbanCanyon
from veriloc_rt.world.scene.export import write_ply

#: slab thickness making ITU materials behave as half-spaces: 2 m of concrete or ground
#: attenuates the internally reflected wave by > 35 dB (alpha ~ 10-14 Np/m at 3.5 GHz)
THICK = 2.0


def write_test_scene(folder: Path, meshes: dict) -> Path:
    """meshes: name -> (vertices, faces, ITU material name)."""
    folder = Path(folder)
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    lines = ['<scene version="2.1.0">']
    for name, (v, f, mat) in meshes.items():
        write_ply(folder / "meshes" / f"{name}.ply", v, f)
        lines += [f'<bsdf type="itu-radio-material" id="{name}_material">'
                  f'<string name="type" value="{mat}"/>'
                  f'<float name="thickness" value="{THICK}"/></bsdf>',
                  f'<shape type="ply" id="mesh-{name}">'
                  f'<string name="filename" value="meshes/{name}.ply"/>'
                  '<boolean name="face_normals" value="true"/>'
                  f'<ref id="{name}_material" name="bsdf"/></shape>']
    lines.append("</scene>")
    (folder / "scene.xml").write_text("\n".join(lines))
    return folder / "scene.xml"


def ground(half: float = 300.0):
    v = np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0.0]])
    return v, np.array([[0, 1, 2], [0, 2, 3]]), "medium_dry_ground"


def boxes(footprints, heights, material="concrete"):
    c = UrbanCanyon(np.asarray(footprints, float), np.asarray(heights, float), 5.0, 30.0, 1e4)
    v, f = c.box_meshes()
    return v, f, material
