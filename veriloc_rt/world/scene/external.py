"""Arbitrary triangle-mesh scenes (Mitsuba XML, Sionna's bundled scenes): loading, the checks
of their frame and units, ground and building shapes, geometry queries, cropping.

A scene's shapes are split into the *ground*, the large flat shape(s) at the bottom, and the
*buildings*, every other shape: anything standing on the ground is an obstacle for the UE and a
candidate roof for a BS. Sionna's bundled city scenes name their ground ``ground`` or ``Plane``
but some name none; the split therefore goes by shape, not by name.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ...errors import InputError
from ...fileio import atomic_write_text
from .export import SCENE_FILE, read_ply, scene_bsdfs, scene_shapes, write_ply

log = logging.getLogger(__name__)

#: a face is horizontal when its normal is within this angle of the vertical, degrees
HORIZONTAL_TOL_DEG = 5.0
#: the ground is flat: its shapes span at most this height, m (terrain is not supported)
GROUND_FLAT_M = 0.5
#: ground shapes start at most this far above the scene's lowest point, m
GROUND_BOTTOM_M = 0.5
#: the ground shapes together cover at least this share of the scene's x-y bounding box
GROUND_MIN_SHARE = 0.25
#: the ground lies at z = 0 within this tolerance, m: heights (UE, BS) are measured from z = 0
GROUND_Z_TOL_M = 0.5
#: a building rises at least this far above the ground, m (lower shapes still trace and block)
MIN_BUILDING_M = 2.0
#: a scene in metres spans at least / at most this much horizontally, m (a city quarter in
#: kilometres spans ~1, in millimetres ~1e6)
MIN_EXTENT_M, MAX_EXTENT_M = 20.0, 50e3
#: largest building height accepted, m (taller: another unit; the tallest building is 828 m)
MAX_BUILDING_M = 1000.0


@dataclass(frozen=True, eq=False)
class MeshShape:
    """One shape of a scene.

    triangles : [num_triangles, 3, 3] float64, m
    """

    name: str
    bsdf: str
    triangles: np.ndarray

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        flat = self.triangles.reshape(-1, 3)
        return flat.min(axis=0), flat.max(axis=0)


@dataclass(frozen=True, eq=False)
class MeshScene:
    """A checked mesh scene: flat ground at z = 0 and buildings standing on it.

    ground_xy : (x_min, y_min, x_max, y_max) of the ground, m
    """

    xml: Path
    ground: tuple[MeshShape, ...]
    buildings: tuple[MeshShape, ...]
    bsdfs: dict
    ground_xy: tuple[float, float, float, float]

    @classmethod
    def from_xml(cls, xml_path: str | Path, field: str = "scene.source") -> "MeshScene":
        """Load every shape, split ground from buildings and check the frame and units.

        :raises InputError: one line for a file that is not a readable XML scene, a scene without
            flat ground or without buildings, in another unit than metres or not holding the
            origin
        """
        xml_path = Path(xml_path)
        shapes = []
        for name, path, bsdf in scene_shapes(xml_path, field):
            v, f = read_ply(path)
            shapes.append(MeshShape(name, bsdf, v[f]))
        return cls.from_shapes(xml_path, shapes, scene_bsdfs(xml_path, field), field)

    @classmethod
    def from_shapes(cls, xml_path: Path, shapes: list[MeshShape], bsdfs: dict,
                    field: str = "scene.source") -> "MeshScene":
        where = str(xml_path)
        lo = np.min([s.bounds[0] for s in shapes], axis=0)
        hi = np.max([s.bounds[1] for s in shapes], axis=0)
        span = float(max(hi[0] - lo[0], hi[1] - lo[1]))
        if not MIN_EXTENT_M <= span <= MAX_EXTENT_M:
            raise InputError(field, f"{where}: spans {span:.4g} horizontally, expected "
                             f"{MIN_EXTENT_M:g} to {MAX_EXTENT_M:g} m (is it in metres?)")
        box_area = float((hi[0] - lo[0]) * (hi[1] - lo[1]))
        is_ground = [_flat_bottom_share(s, lo[2], box_area) for s in shapes]
        ground = tuple(s for s, share in zip(shapes, is_ground) if share is not None)
        if not ground or sum(is_ground[i] or 0.0 for i in range(len(shapes))) < GROUND_MIN_SHARE:
            bottom = max(shapes, key=lambda s: _projected_area(s.triangles))
            b_lo, b_hi = bottom.bounds
            raise InputError(field, f"{where}: no flat ground (a near-horizontal shape at the "
                             f"bottom covering {GROUND_MIN_SHARE:.0%} of the scene); the largest "
                             f"shape {bottom.name!r:.60} spans z {b_lo[2]:.4g} to {b_hi[2]:.4g} m")
        ground_z = float(np.mean([g.bounds[0][2] for g in ground]))
        if abs(ground_z) > GROUND_Z_TOL_M:
            raise InputError(field, f"{where}: the ground lies at z = {ground_z:.4g} m, expected "
                             "0 (heights are measured from z = 0: translate the scene)")
        buildings = tuple(s for s, share in zip(shapes, is_ground) if share is None)
        tall = [s for s in buildings if s.bounds[1][2] - ground_z >= MIN_BUILDING_M]
        if not tall:
            raise InputError(field, f"{where}: no buildings (no shape besides the ground rises "
                             f"{MIN_BUILDING_M:g} m above it)")
        top = max(s.bounds[1][2] for s in tall) - ground_z
        if top > MAX_BUILDING_M:
            raise InputError(field, f"{where}: a building {top:.4g} high, expected at most "
                             f"{MAX_BUILDING_M:g} m (is it in metres?)")
        g_lo = np.min([g.bounds[0] for g in ground], axis=0)
        g_hi = np.max([g.bounds[1] for g in ground], axis=0)
        if not (g_lo[0] < 0.0 < g_hi[0] and g_lo[1] < 0.0 < g_hi[1]):
            raise InputError(field, f"{where}: the ground spans x {g_lo[0]:.4g} to "
                             f"{g_hi[0]:.4g} m, y {g_lo[1]:.4g} to {g_hi[1]:.4g} m and does not "
                             "hold the origin (the drive region and the layout are centred on "
                             "it: translate the scene)")
        ground_xy = (float(g_lo[0]), float(g_lo[1]), float(g_hi[0]), float(g_hi[1]))
        return cls(Path(xml_path), ground, buildings, dict(bsdfs), ground_xy)

    # --- geometry queries -----------------------------------------------------------------
    @property
    def triangles(self) -> np.ndarray:
        """Every triangle, ground first: [num_triangles, 3, 3] float64, m."""
        return np.concatenate([s.triangles for s in self.ground + self.buildings], axis=0)

    @property
    def building_triangles(self) -> np.ndarray:
        """[num_triangles, 3, 3] float64, m"""
        if not self.buildings:
            return np.zeros((0, 3, 3))
        return np.concatenate([s.triangles for s in self.buildings], axis=0)

    @property
    def num_buildings(self) -> int:
        """Number of building shapes (a Sionna scene splits a building by material)."""
        return len(self.buildings)

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box (min [3], max [3]) in m."""
        flat = self.triangles.reshape(-1, 3)
        return flat.min(axis=0), flat.max(axis=0)

    def inside_extent(self, xy: np.ndarray) -> np.ndarray:
        """Points whose x, y lie on the ground. [..., 2] -> [...] bool"""
        x0, y0, x1, y1 = self.ground_xy
        xy = np.asarray(xy, dtype=float)
        return (xy[..., 0] >= x0) & (xy[..., 0] <= x1) & (xy[..., 1] >= y0) & (xy[..., 1] <= y1)

    def inside_building(self, xyz: np.ndarray) -> np.ndarray:
        """Points under a building surface: an odd number of building surfaces straight above
        (a roof without a floor counts once: Sionna's city scenes have no floors).

        :param xyz: [num_points, 3] float64, m
        :returns: [num_points] bool
        """
        return _crossings_above(self.building_triangles, xyz) % 2 == 1

    def crop(self, points_xy: np.ndarray, margin: float) -> "MeshScene":
        """Keep only the building shapes whose bounding box lies within ``margin`` of any point.

        :param points_xy: [num_points, 2] float64, m
        """
        pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        keep = []
        for s in self.buildings:
            lo, hi = s.bounds
            d = np.hypot(np.maximum(np.maximum(lo[0] - pts[:, 0], 0.0), pts[:, 0] - hi[0]),
                         np.maximum(np.maximum(lo[1] - pts[:, 1], 0.0), pts[:, 1] - hi[1]))
            if np.any(d <= margin):
                keep.append(s)
        return replace(self, buildings=tuple(keep))

    def write(self, out_dir: str | Path, ground_bounds: tuple[float, float, float, float]) -> Path:
        """Write the scene as ``scene.xml`` with one PLY per material of the buildings
        (``meshes/buildings-<k>.ply``) and a ground rectangle at z = 0 over ``ground_bounds``
        with the ground's material; the materials are copied verbatim.

        :returns: path of the XML file
        """
        out = Path(out_dir)
        (out / "meshes").mkdir(parents=True, exist_ok=True)
        by_bsdf: dict[str, list[np.ndarray]] = {}
        for s in self.buildings:
            by_bsdf.setdefault(s.bsdf, []).append(s.triangles)
        shapes = []
        for k, (bsdf, tris) in enumerate(sorted(by_bsdf.items())):
            # shared vertices merged: Sionna RT finds a wedge only where two faces share an edge
            v, f = np.unique(np.concatenate(tris).reshape(-1, 3), axis=0, return_inverse=True)
            write_ply(out / "meshes" / f"buildings-{k}.ply", v, f.reshape(-1, 3))
            shapes.append((f"buildings-{k}", bsdf))
        x0, y0, x1, y1 = ground_bounds
        gv = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
        write_ply(out / "meshes" / "ground.ply", gv, np.array([[0, 1, 2], [0, 2, 3]]))
        shapes.append(("ground", self.ground[0].bsdf))
        used = sorted({b for _, b in shapes if b})
        lines = ['<scene version="2.1.0">', ""] + [f"\t{self.bsdfs[b]}" for b in used
                                                  if b in self.bsdfs] + [""]
        for name, bsdf in shapes:
            lines += [f'\t<shape type="ply" id="mesh-{name}">',
                      f'\t\t<string name="filename" value="meshes/{name}.ply"/>',
                      '\t\t<boolean name="face_normals" value="true"/>']
            if bsdf:
                lines.append(f'\t\t<ref id="{bsdf}" name="bsdf"/>')
            lines.append("\t</shape>")
        lines += ["</scene>", ""]
        xml = out / SCENE_FILE
        atomic_write_text(xml, "\n".join(lines))
        return xml


def _normals(tris: np.ndarray) -> np.ndarray:
    return np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])


def _projected_area(tris: np.ndarray) -> float:
    return float(0.5 * np.abs(_normals(tris)[:, 2]).sum())


def _flat_bottom_share(shape: MeshShape, scene_z_min: float, box_area: float) -> float | None:
    """Share of the scene's bounding box a flat shape at the bottom covers (None: the shape is
    not flat, not at the bottom or not mostly horizontal)."""
    lo, hi = shape.bounds
    if hi[2] - lo[2] > GROUND_FLAT_M or lo[2] - scene_z_min > GROUND_BOTTOM_M:
        return None
    n = _normals(shape.triangles)
    area = 0.5 * np.linalg.norm(n, axis=1)
    horiz = np.abs(n[:, 2]) >= 2.0 * area * np.cos(np.deg2rad(HORIZONTAL_TOL_DEG))
    if area.sum() <= 0 or area[horiz].sum() < 0.99 * area.sum():
        return None
    share = float(area[horiz].sum() / box_area) if box_area > 0 else 0.0
    return share if share >= 0.01 else None


def _crossings_above(tris: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Number of triangles a vertical ray up from each point crosses (half-open barycentric
    test, so a ray through a shared edge counts once). [num_points, 3] -> [num_points] int"""
    pts = np.asarray(xyz, dtype=float).reshape(-1, 3)
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    det = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
    ok = np.abs(det) > 1e-12   # vertical faces never cross a vertical ray
    a, b, c, det = a[ok], b[ok], c[ok], det[ok]
    out = np.zeros(len(pts), dtype=np.int64)
    chunk = max(1, int(4e6 // max(len(det), 1)))   # bounds the [chunk, num_triangles] temporaries
    for start in range(0, len(pts), chunk):
        p = pts[start:start + chunk, None, :]
        l1 = ((b[:, 1] - c[:, 1]) * (p[..., 0] - c[:, 0])
              + (c[:, 0] - b[:, 0]) * (p[..., 1] - c[:, 1])) / det
        l2 = ((c[:, 1] - a[:, 1]) * (p[..., 0] - c[:, 0])
              + (a[:, 0] - c[:, 0]) * (p[..., 1] - c[:, 1])) / det
        l3 = 1.0 - l1 - l2
        inside = (l1 >= 0) & (l2 >= 0) & (l3 > 0)
        z = l1 * a[:, 2] + l2 * b[:, 2] + l3 * c[:, 2]
        out[start:start + chunk] = np.count_nonzero(inside & (z > p[..., 2]), axis=-1)
    return out
