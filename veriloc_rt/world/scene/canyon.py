"""Procedural urban canyon: a Manhattan grid of closed building boxes over a ground plane.

Street centre lines run along ``x = k * pitch`` and ``y = k * pitch`` (``pitch = block + street``),
so the origin is an intersection. Block ``(i, j)`` covers
``[i*pitch + w/2, (i+1)*pitch - w/2] x [j*pitch + w/2, (j+1)*pitch - w/2]`` (w: street width).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...config import SceneConfig
from ...errors import bad_value


@dataclass(frozen=True, eq=False)
class UrbanCanyon:
    """A Manhattan grid of buildings.

    footprints : [num_buildings, 4] float64, m (x_min, y_min, x_max, y_max)
    heights : [num_buildings] float64, m
    """

    footprints: np.ndarray
    heights: np.ndarray
    street_width: float
    block_size: float
    extent: float
    building_material: str = "concrete"
    ground_material: str = "medium_dry_ground"
    material_thickness: float = 0.3

    @property
    def pitch(self) -> float:
        """Distance between parallel street centre lines [m]."""
        return self.block_size + self.street_width

    @property
    def num_buildings(self) -> int:
        return len(self.heights)

    def inside_building(self, xy: np.ndarray, clearance: float = 0.0) -> np.ndarray:
        """Whether points lie inside a block footprint grown by ``clearance``.

        This is analytic (the grid is infinite in principle), so it also covers cropped blocks.

        :param xy: [..., 2] float64, m
        :returns: [...] bool
        """
        xy = np.asarray(xy, dtype=float)
        half = self.street_width / 2.0 - clearance
        # offset from the nearest street centre line, per axis
        off = np.abs(xy - self.pitch * np.round(xy / self.pitch))
        in_extent = np.all(np.abs(xy) <= self.extent, axis=-1)
        return np.all(off > half, axis=-1) & in_extent

    def inside_extent(self, xy: np.ndarray) -> np.ndarray:
        """Whether points lie in the area the grid covers. [..., 2] -> [...] bool"""
        return np.all(np.abs(np.asarray(xy, dtype=float)) <= self.extent, axis=-1)

    def crop(self, points_xy: np.ndarray, margin: float) -> "UrbanCanyon":
        """Keep only the buildings whose footprint lies within ``margin`` of any point.

        :param points_xy: [num_points, 2] float64, m (BS positions and a densified trajectory)
        """
        pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        keep = np.zeros(self.num_buildings, dtype=bool)
        fp = self.footprints
        for start in range(0, len(pts), 2048):
            p = pts[start:start + 2048]
            dx = np.maximum(np.maximum(fp[None, :, 0] - p[:, None, 0], 0.0),
                            p[:, None, 0] - fp[None, :, 2])
            dy = np.maximum(np.maximum(fp[None, :, 1] - p[:, None, 1], 0.0),
                            p[:, None, 1] - fp[None, :, 3])
            keep |= np.any(dx * dx + dy * dy <= margin * margin, axis=0)
        return replace(self, footprints=fp[keep], heights=self.heights[keep])

    def box_meshes(self) -> tuple[np.ndarray, np.ndarray]:
        """All buildings as closed boxes (8 vertices, 12 outward-facing triangles each).

        :returns: vertices [8*num_buildings, 3] float64, m; faces [12*num_buildings, 3] int64
        """
        n = self.num_buildings
        x0, y0, x1, y1 = (self.footprints[:, i] for i in range(4))
        z0, z1 = np.zeros(n), self.heights
        corners = np.stack([
            np.stack([x0, y0, z0], -1), np.stack([x1, y0, z0], -1),
            np.stack([x1, y1, z0], -1), np.stack([x0, y1, z0], -1),
            np.stack([x0, y0, z1], -1), np.stack([x1, y0, z1], -1),
            np.stack([x1, y1, z1], -1), np.stack([x0, y1, z1], -1),
        ], axis=1)  # [n, 8, 3]
        # counter-clockwise seen from outside -> normals point outwards
        quad_faces = np.array([
            [0, 2, 1], [0, 3, 2],  # bottom (-z)
            [4, 5, 6], [4, 6, 7],  # top (+z)
            [0, 1, 5], [0, 5, 4],  # south (-y)
            [1, 2, 6], [1, 6, 5],  # east (+x)
            [2, 3, 7], [2, 7, 6],  # north (+y)
            [3, 0, 4], [3, 4, 7],  # west (-x)
        ])
        faces = quad_faces[None, :, :] + 8 * np.arange(n)[:, None, None]
        return corners.reshape(-1, 3), faces.reshape(-1, 3)

    def ground_mesh(self, bounds_xy: tuple[float, float, float, float]) -> tuple[np.ndarray, np.ndarray]:
        """A ground rectangle at z = 0 (normal +z) covering ``(x_min, y_min, x_max, y_max)``."""
        x0, y0, x1, y1 = bounds_xy
        v = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
        return v, np.array([[0, 1, 2], [0, 2, 3]])

    def street_nodes(self, half_side: float) -> np.ndarray:
        """Intersections of street centre lines inside ``|x|, |y| <= half_side``.

        :returns: [num_nodes, 2] float64, m
        """
        k = int(math.floor(min(half_side, self.extent) / self.pitch))
        ticks = np.arange(-k, k + 1) * self.pitch
        gx, gy = np.meshgrid(ticks, ticks, indexing="ij")
        return np.stack([gx.ravel(), gy.ravel()], axis=-1)


def urban_canyon(cfg: SceneConfig | None = None, rng: np.random.Generator | None = None,
                 field: str = "scene") -> UrbanCanyon:
    """Build the full Manhattan grid described by ``cfg`` (crop it with :meth:`UrbanCanyon.crop`).

    Heights are ``building_height_m + U(-jitter, +jitter)`` drawn from ``rng`` in a fixed block
    order, so the same seed gives the same city whatever is later cropped.

    :raises InputError: for inconsistent parameters (jitter as large as the height)
    """
    cfg = cfg or SceneConfig()
    if cfg.height_jitter_m >= cfg.building_height_m:
        raise bad_value(f"{field}.height_jitter_m", cfg.height_jitter_m,
                        f"a value < building_height_m ({cfg.building_height_m})")
    pitch = cfg.block_size_m + cfg.street_width_m
    half_w = cfg.street_width_m / 2.0
    kmax = int(math.floor(cfg.extent_m / pitch))
    if kmax < 1:
        raise bad_value(f"{field}.extent_m", cfg.extent_m,
                        f"a value >= one block pitch ({pitch} m)")
    idx = np.arange(-kmax, kmax)  # block i spans [i*pitch, (i+1)*pitch]
    ii, jj = np.meshgrid(idx, idx, indexing="ij")
    ii, jj = ii.ravel(), jj.ravel()
    footprints = np.stack([ii * pitch + half_w, jj * pitch + half_w,
                           (ii + 1) * pitch - half_w, (jj + 1) * pitch - half_w], axis=-1)
    heights = np.full(len(ii), cfg.building_height_m)
    if cfg.height_jitter_m > 0:
        if rng is None:
            raise ValueError("`rng` is required when height_jitter_m > 0")
        heights = heights + rng.uniform(-cfg.height_jitter_m, cfg.height_jitter_m, len(ii))
    return UrbanCanyon(footprints=footprints.astype(float), heights=heights,
                       street_width=cfg.street_width_m, block_size=cfg.block_size_m,
                       extent=kmax * pitch, building_material=cfg.building_material,
                       ground_material=cfg.ground_material,
                       material_thickness=cfg.material_thickness_m)
