"""Geometry queries on an arbitrary triangle-mesh scene (external Sionna XML scenes)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .export import read_ply, scene_mesh_files


@dataclass(frozen=True, eq=False)
class MeshScene:
    """All triangles of a scene.

    triangles : [num_triangles, 3, 3] float64, m
    """

    triangles: np.ndarray

    @classmethod
    def from_xml(cls, xml_path: str | Path, field: str = "scene.source") -> "MeshScene":
        tris = []
        for p in scene_mesh_files(xml_path, field):
            v, f = read_ply(p)
            tris.append(v[f])
        return cls(np.concatenate(tris, axis=0))

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box (min [3], max [3]) in m."""
        flat = self.triangles.reshape(-1, 3)
        return flat.min(axis=0), flat.max(axis=0)

    def inside_extent(self, xy: np.ndarray) -> np.ndarray:
        """Points whose x, y lie within the scene's bounding box. [..., 2] -> [...] bool"""
        lo, hi = self.bounds
        xy = np.asarray(xy, dtype=float)
        return np.all((xy >= lo[:2]) & (xy <= hi[:2]), axis=-1)

    def inside_building(self, xyz: np.ndarray) -> np.ndarray:
        """Points enclosed by closed meshes: odd number of surfaces crossed straight above.

        :param xyz: [num_points, 3] float64, m
        :returns: [num_points] bool
        """
        pts = np.asarray(xyz, dtype=float).reshape(-1, 3)
        a, b, c = self.triangles[:, 0], self.triangles[:, 1], self.triangles[:, 2]
        # 2-D barycentric set-up; vertical faces (zero projected area) never cross a vertical ray
        det = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
        ok = np.abs(det) > 1e-12
        a, b, c, det = a[ok], b[ok], c[ok], det[ok]
        out = np.zeros(len(pts), dtype=bool)
        for start in range(0, len(pts), 256):
            p = pts[start:start + 256, None, :]
            l1 = ((b[:, 1] - c[:, 1]) * (p[..., 0] - c[:, 0])
                  + (c[:, 0] - b[:, 0]) * (p[..., 1] - c[:, 1])) / det
            l2 = ((c[:, 1] - a[:, 1]) * (p[..., 0] - c[:, 0])
                  + (a[:, 0] - c[:, 0]) * (p[..., 1] - c[:, 1])) / det
            l3 = 1.0 - l1 - l2
            inside = (l1 >= 0) & (l2 >= 0) & (l3 > 0)
            z = l1 * a[:, 2] + l2 * b[:, 2] + l3 * c[:, 2]
            crossings = np.count_nonzero(inside & (z > p[..., 2]), axis=-1)
            out[start:start + 256] = crossings % 2 == 1
        return out
