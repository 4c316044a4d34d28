"""Example plug-in scene source: one building on flat ground (docs/extending.md, "A new scene
source").

The ground is a square of side ``2 * GROUND_HALF_M`` at z = 0 centred on the origin; the building
a box of footprint ``SIDE_M`` x ``SIDE_M`` centred at ``CENTRE_XY`` with the height the config
gives after the name (``scene.source = "one_building:<height in m>"``; ``"one_building"``:
``DEFAULT_HEIGHT_M``). Its materials are the config's ``scene.building_material`` and
``scene.ground_material`` (the base class checks those against the carrier before a ray-traced
run). Register it by importing this module.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from veriloc_rt.errors import bad_value
from veriloc_rt.world.scene.external import MeshScene, MeshShape
from veriloc_rt.world.sources import SCENE_SOURCE_REGISTRY, SceneSource

#: half-side of the square ground, m (holds the default hexagonal layout's BSs)
GROUND_HALF_M = 1000.0
#: footprint side of the building, m, and its centre (x, y), m
SIDE_M = 40.0
CENTRE_XY = (60.0, 20.0)
#: height without an argument, m
DEFAULT_HEIGHT_M = 30.0


def box_triangles(x0: float, y0: float, x1: float, y1: float, h: float) -> np.ndarray:
    """The 12 triangles of the closed box [x0, x1] x [y0, y1] x [0, h]: [12, 3, 3], m."""
    v = np.array([[x, y, z] for z in (0.0, h) for y in (y0, y1) for x in (x0, x1)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return np.array([v[[a, b, c]] for a, b, c, d in quads for a, b, c in ((a, b, c), (a, c, d))])


def material_xml(bsdf_id: str, itu_type: str, thickness_m: float) -> str:
    """One ``<bsdf>`` element of an ITU material, as Sionna RT's scenes write it."""
    return (f'<bsdf type="itu-radio-material" id="{bsdf_id}"><string name="type" '
            f'value="{itu_type}"/><float name="thickness" value="{thickness_m:.6g}"/></bsdf>')


@SCENE_SOURCE_REGISTRY.register("one_building")
class OneBuilding(SceneSource):
    """A single box building on a flat square ground."""

    def load(self, cfg, scene_dir: Path) -> MeshScene:
        sc = cfg.scene
        try:
            height = float(sc.source_arg) if sc.source_arg else DEFAULT_HEIGHT_M
        except ValueError:
            height = float("nan")
        if not 2.0 <= height <= 500.0:
            raise bad_value("scene.source", sc.source, "'one_building' or "
                            "'one_building:<height>' with a height of 2 to 500 m")
        g = GROUND_HALF_M
        ground = np.array([[[-g, -g, 0.0], [g, -g, 0.0], [g, g, 0.0]],
                           [[-g, -g, 0.0], [g, g, 0.0], [-g, g, 0.0]]])
        cx, cy = CENTRE_XY
        s = SIDE_M / 2.0
        shapes = [MeshShape("ground", "ground_material", ground),
                  MeshShape("building", "building_material",
                            box_triangles(cx - s, cy - s, cx + s, cy + s, height))]
        bsdfs = {"ground_material": material_xml("ground_material", sc.ground_material,
                                                 sc.material_thickness_m),
                 "building_material": material_xml("building_material", sc.building_material,
                                                   sc.material_thickness_m)}
        # nothing is written here: build_geometry writes the cropped scene into scene_dir
        return MeshScene.from_shapes(Path(scene_dir) / "one_building.xml", shapes, bsdfs)
