"""OpenStreetMap import, offline: a local extract (``.osm`` XML or ``.osm.pbf``) becomes a scene.

Parsing is left to maintained libraries, which read local files only: ``osmnx`` for OSM XML
(:func:`osmnx.features_from_xml`, no Overpass query, no geocoding) and ``pyrosm`` for PBF
(:class:`pyrosm.OSM` on the file path; its download helpers are never called). Written here is
only what neither does: the height rules, the material mapping, the local metric frame and the
extrusion into closed meshes (here), the Sionna XML and the run's cache
(:mod:`veriloc_rt.world.scene.osm_write`).

* Heights (OSM wiki, Key:height and Key:building:levels): ``height`` in metres unless a unit
  says otherwise (``"12 m"``, ``"40'"``, ``"40 ft"``, ``12'6"``); else ``building:levels`` x the
  storey height (3 m by default, the floor height of TR 38.901 Table 7.2-1, where a UT on floor
  n_fl sits at 3 (n_fl - 1) + 1.5 m); else a stated default height.
* Materials (ITU-R P.2040-3 Table 3, as Sionna RT names them): :data:`MATERIAL_BY_BUILDING` by
  the ``building`` value, :data:`DEFAULT_MATERIAL` for anything else (``yes`` included).
* Frame: a transverse Mercator projection on the WGS84 ellipsoid, scale 1, centred on the
  extract (the middle of the buildings' longitude/latitude box, or of the crop box): x east,
  y north, metres, origin at the centre (the scene convention). Its scale error at distance d
  from the centre is about d^2 / (2 R^2) (Snyder, Map Projections - A Working Manual, USGS PP
  1395, eq. 8-4 to first order): 1.2e-8 at 1 km.
* Footprints (ways and multipolygon relations, holes kept) are triangulated by GEOS's
  constrained Delaunay triangulation (no vertex added) and extruded by trimesh into one closed,
  outward-oriented mesh per polygon.
* Streets: the ways whose ``highway`` value is in :data:`HIGHWAYS` (a car or a pedestrian can
  use them), without tunnels and areas, as an undirected graph of their OSM nodes.
"""

from __future__ import annotations

import functools
import io
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import InputError
from ...inputs import check_path, read_bytes

log = logging.getLogger(__name__)

#: storey height, m: the floor height of TR 38.901 Table 7.2-1 (UT height 3 (n_fl - 1) + 1.5 m)
STOREY_M = 3.0
#: height of a building with neither ``height`` nor ``building:levels``, m (a convention:
#: three or four storeys at :data:`STOREY_M`; set it per city)
DEFAULT_HEIGHT_M = 10.0
#: ``building`` value -> ITU-R P.2040 material (Sionna RT's ITU names)
MATERIAL_BY_BUILDING = {
    **dict.fromkeys(("residential", "house", "apartments", "detached", "semidetached_house",
                     "terrace", "dormitory", "bungalow", "farm"), "brick"),
    **dict.fromkeys(("commercial", "office", "retail", "hotel", "supermarket"), "glass"),
    **dict.fromkeys(("industrial", "warehouse", "hangar", "garage", "garages", "storage_tank"),
                    "metal"),
    **dict.fromkeys(("cabin", "hut", "shed", "barn"), "wood"),
}
#: material of every other ``building`` value (``yes``, public, school, church, ...)
DEFAULT_MATERIAL = "concrete"
#: every material an imported scene can hold (checked against the carrier frequency)
OSM_MATERIALS = tuple(sorted(set(MATERIAL_BY_BUILDING.values()) | {DEFAULT_MATERIAL}))
#: ``highway`` values kept as streets: roads a car can use and ways for pedestrians
#: (OSM wiki, Key:highway); cycleways, bridleways, steps, corridors, construction are left out
HIGHWAYS = ("motorway", "motorway_link", "trunk", "trunk_link", "primary", "primary_link",
            "secondary", "secondary_link", "tertiary", "tertiary_link", "unclassified",
            "residential", "living_street", "service", "road", "pedestrian", "footway", "path",
            "track")
#: footprints smaller than this are dropped, m^2 (mapping slivers; no room for a wall pair)
MIN_FOOTPRINT_M2 = 1.0
#: largest extract read, bytes (pyrosm holds the decoded extract in memory)
MAX_OSM_BYTES = 1 << 30
#: OSM stores coordinates as integers of 1e-7 degree: shared nodes have identical values
COORD_DECIMALS = 7
#: version of the written scene (part of the cache key: a change of the rules rebuilds)
FORMAT_VERSION = 1

_FEET_M = 0.3048
_INCH_M = 0.0254
_NUMBER = r"(\d+(?:[.,]\d+)?)"


def parse_height(text) -> float | None:
    """A ``height`` tag in metres (OSM wiki, Key:height: metres by default, units after a space).

    ``"12"``, ``"12.5 m"``, ``"12,5"``, ``"40'"``, ``"40 ft"``, ``"12'6\\""`` ; None for anything
    else or a non-positive value.
    """
    if text is None or (isinstance(text, float) and math.isnan(text)):
        return None
    s = str(text).strip().lower()
    m = re.fullmatch(_NUMBER + r"\s*'\s*(?:" + _NUMBER + r"\s*(?:\"|''))?", s)
    if m:
        value = float(m[1].replace(",", ".")) * _FEET_M + float((m[2] or "0").replace(",", ".")) * _INCH_M
    else:
        m = re.fullmatch(_NUMBER + r"\s*(m|meters?|metres?|ft|feet|foot)?", s)
        if not m:
            return None
        value = float(m[1].replace(",", "."))
        if m[2] in ("ft", "feet", "foot"):
            value *= _FEET_M
    return value if value > 0 else None


def parse_levels(text) -> float | None:
    """A ``building:levels`` tag as a positive number of storeys (the first of ``"3;4"``)."""
    if text is None or (isinstance(text, float) and math.isnan(text)):
        return None
    m = re.match(_NUMBER, str(text).strip())
    if not m:
        return None
    value = float(m[1].replace(",", "."))
    return value if value > 0 else None


def building_height(height_tag, levels_tag, storey_m: float = STOREY_M,
                    default_m: float = DEFAULT_HEIGHT_M) -> tuple[float, str]:
    """(height in m, rule used: ``"height"``, ``"levels"`` or ``"default"``)."""
    h = parse_height(height_tag)
    if h is not None:
        return h, "height"
    n = parse_levels(levels_tag)
    if n is not None:
        return n * storey_m, "levels"
    return default_m, "default"


def building_material(building_tag) -> str:
    """The ITU material of a ``building=*`` value (:data:`MATERIAL_BY_BUILDING`)."""
    return MATERIAL_BY_BUILDING.get(str(building_tag).strip().lower(), DEFAULT_MATERIAL)


def local_crs(lon0_deg: float, lat0_deg: float) -> str:
    """PROJ string of the local transverse Mercator frame centred on (lon0, lat0)."""
    return (f"+proj=tmerc +lat_0={lat0_deg:.9f} +lon_0={lon0_deg:.9f} +k=1 +x_0=0 +y_0=0 "
            "+ellps=WGS84 +units=m +no_defs")


@dataclass(frozen=True, eq=False)
class OsmCity:
    """Buildings and streets of an extract in the local metric frame.

    footprints : [num_buildings] shapely Polygons, m (x east, y north)
    heights : [num_buildings] float64, m
    height_rules : [num_buildings] str (``height``, ``levels`` or ``default``)
    materials : [num_buildings] str (ITU material names)
    osm_ids : [num_buildings] str (``way/123``, ``relation/45``; a multipolygon's parts repeat it)
    street_nodes : [num_nodes, 2] float64, m
    street_edges : [num_edges, 2] int64, indices into ``street_nodes`` (undirected, i < j)
    """

    footprints: list
    heights: np.ndarray
    height_rules: np.ndarray
    materials: np.ndarray
    osm_ids: np.ndarray
    street_nodes: np.ndarray
    street_edges: np.ndarray
    origin_lonlat_deg: tuple[float, float]
    crs: str

    @property
    def num_buildings(self) -> int:
        return len(self.heights)

    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) of the buildings and street nodes, m."""
        import shapely

        b = shapely.total_bounds(np.asarray(self.footprints, dtype=object))
        if len(self.street_nodes):
            lo, hi = self.street_nodes.min(axis=0), self.street_nodes.max(axis=0)
            b = np.array([min(b[0], lo[0]), min(b[1], lo[1]), max(b[2], hi[0]), max(b[3], hi[1])])
        return tuple(float(v) for v in b)

    def to_lonlat(self, xy: np.ndarray) -> np.ndarray:
        """[..., 2] local m -> [..., 2] (lon, lat) degrees (pyproj inverse)."""
        t = _transformer(self.crs, "EPSG:4326")
        xy = np.asarray(xy, dtype=float)
        lon, lat = t.transform(xy[..., 0], xy[..., 1])
        return np.stack([lon, lat], axis=-1)

    def building_meshes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each footprint extruded to its height: [(vertices [n, 3] float64 m, faces [m, 3])]."""
        return [extrude(p, h) for p, h in zip(self.footprints, self.heights)]


@functools.lru_cache(maxsize=8)
def _transformer(src: str, dst: str):
    """pyproj Transformer src -> dst in (lon, lat) / (x, y) order, built once per pair."""
    from pyproj import Transformer

    return Transformer.from_crs(src, dst, always_xy=True)


def extrude(polygon, height: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward-oriented prism over ``polygon`` (holes kept) from z = 0 to ``height``.

    GEOS's constrained Delaunay triangulation (``shapely.constrained_delaunay_triangles``) keeps
    the ring vertices exactly, so the caps share their boundary edges with the walls that
    ``trimesh.creation.extrude_triangulation`` builds along every ring.

    :returns: vertices [num_vertices, 3] float64, m; faces [num_faces, 3] int64
    """
    import shapely
    import trimesh

    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(polygon))
    coords = shapely.get_coordinates(shapely.get_exterior_ring(tris)).reshape(-1, 4, 2)[:, :3]
    verts, inv = np.unique(coords.reshape(-1, 2), axis=0, return_inverse=True)
    faces = inv.reshape(-1, 3)
    mesh = trimesh.creation.extrude_triangulation(verts, faces, height)
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)


# -- reading ----------------------------------------------------------------------------------

def check_kind(path: Path, field: str) -> str:
    """``"pbf"`` or ``"xml"`` by the file name; InputError for any other extension."""
    name = path.name.lower()
    if name.endswith(".pbf"):
        return "pbf"
    if name.endswith(".osm") or name.endswith(".osm.xml"):
        return "xml"
    raise InputError(field, f"{str(path)!r}: unknown extension, expected an OpenStreetMap "
                     "extract ending in .osm (XML) or .osm.pbf")


def _check_content(data: bytes, kind: str, path: Path, field: str) -> None:
    if not data.strip():
        raise InputError(field, f"{str(path)!r} is empty")
    if kind == "pbf":
        # a PBF file opens with a BlobHeader whose type is "OSMHeader" (OSM wiki, PBF Format)
        if b"OSMHeader" not in data[:64]:
            raise InputError(field, f"{str(path)!r} is not an OSM PBF file (no OSMHeader blob)")
        return
    import xml.etree.ElementTree as ET

    try:
        _event, root = next(ET.iterparse(io.BytesIO(data), events=("start",)))
    except (ET.ParseError, StopIteration) as exc:
        raise InputError(field, f"{str(path)!r} is not OSM XML ({exc})") from None
    if root.tag != "osm":
        raise InputError(field, f"{str(path)!r} is not OSM XML (root element <{root.tag:.40}>, "
                         "expected <osm>)")


def _read_pbf(path: Path, field: str):
    import pyrosm

    try:
        osm = pyrosm.OSM(str(path))     # the crop is applied afterwards, as for XML
        buildings = osm.get_buildings()
        ways = osm.get_data_by_custom_criteria(custom_filter={"highway": list(HIGHWAYS)},
                                               filter_type="keep", keep_nodes=False,
                                               keep_relations=False)
    except Exception as exc:  # noqa: BLE001 - a third-party parser on user bytes: any failure
        reason = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise InputError(field, f"{str(path)!r} is not a readable OSM PBF file ({reason})") from None
    ids = ([f"{t}/{i}" for t, i in zip(buildings["osm_type"], buildings["id"])]
           if buildings is not None else [])
    return buildings, ids, ways


def _read_xml(path: Path, field: str):
    import osmnx as ox

    ox.settings.use_cache = False        # no response cache: nothing is fetched
    ox.settings.log_file = False

    def features(tags):
        try:
            return ox.features_from_xml(path, tags=tags)
        except Exception as exc:  # noqa: BLE001 - a third-party parser on user bytes
            # osmnx's documented "no feature matches the tags" (its error class lives in a
            # private module, so it is recognised by name)
            if type(exc).__name__ == "InsufficientResponseError":
                return None
            reason = " ".join(str(exc).split())[:120] or type(exc).__name__
            raise InputError(field, f"{str(path)!r} is not readable OSM XML ({reason})") from None

    buildings = features({"building": True})
    ids = [f"{t}/{i}" for t, i in buildings.index] if buildings is not None else []
    return buildings, ids, features({"highway": list(HIGHWAYS)})


def _column(gdf, name: str) -> list:
    """A tag column as a list (None per row when no feature carries the tag)."""
    if gdf is None:
        return []
    return list(gdf[name]) if name in gdf.columns else [None] * len(gdf)


def _present(v) -> bool:
    return v is not None and not (isinstance(v, float) and math.isnan(v)) and str(v) != ""


def read_osm(path, field: str = "scene.osm", *, bbox_deg=None, radius_m: float = 0.0,
             storey_m: float = STOREY_M, default_height_m: float = DEFAULT_HEIGHT_M) -> OsmCity:
    """Read an extract's buildings and streets into the local metric frame.

    :param bbox_deg: (lon_min, lat_min, lon_max, lat_max): keep the buildings that intersect it
        and the street segments inside it; the frame is centred on it
    :param radius_m: > 0: keep the buildings within this distance of the frame's origin and the
        street segments inside that circle
    :raises InputError: naming ``field`` for a missing, empty, corrupted or non-OSM file, an
        unknown extension, an extract (or crop) without buildings
    """
    import shapely

    p = check_path(path, field)
    kind = check_kind(p, field)
    data = read_bytes(p, field, "OpenStreetMap extract", MAX_OSM_BYTES)
    _check_content(data, kind, p, field)
    if bbox_deg is not None:
        bbox_deg = tuple(float(v) for v in bbox_deg)
    if kind == "pbf":
        buildings, ids, ways = _read_pbf(p, field)
    else:
        buildings, ids, ways = _read_xml(p, field)
    crop = "" if bbox_deg is None and radius_m <= 0 else " inside the crop"
    if buildings is None or len(buildings) == 0:
        raise InputError(field, f"{str(p)!r} has no buildings (no way or relation tagged "
                         "building=*)")
    geoms = np.asarray(buildings.geometry.values, dtype=object)
    keep = np.array([g is not None and g.geom_type in ("Polygon", "MultiPolygon") for g in geoms])
    keep &= np.array([str(b).lower() != "no" for b in _column(buildings, "building")], dtype=bool)
    if bbox_deg is not None:
        keep &= shapely.intersects(geoms, shapely.box(*bbox_deg))
    if not keep.any():
        raise InputError(field, f"{str(p)!r} has no building footprints{crop}")
    if bbox_deg is not None:
        lon0, lat0 = (bbox_deg[0] + bbox_deg[2]) / 2, (bbox_deg[1] + bbox_deg[3]) / 2
    else:
        b = shapely.total_bounds(geoms[keep])
        lon0, lat0 = (b[0] + b[2]) / 2, (b[1] + b[3]) / 2
    lon0, lat0 = round(float(lon0), 9), round(float(lat0), 9)
    crs = local_crs(lon0, lat0)
    fwd = _transformer("EPSG:4326", crs)

    def project(geom):
        return shapely.transform(geom, lambda c: np.stack(fwd.transform(c[:, 0], c[:, 1]), -1))

    heights_t, levels_t = _column(buildings, "height"), _column(buildings, "building:levels")
    kinds = _column(buildings, "building")
    origin = shapely.Point(0.0, 0.0)
    polys, hs, rules, mats, oid = [], [], [], [], []
    dropped = 0
    for k in np.flatnonzero(keep):
        g = project(shapely.make_valid(geoms[k]))
        if radius_m > 0 and g.distance(origin) > radius_m:
            continue
        h, rule = building_height(heights_t[k], levels_t[k], storey_m, default_height_m)
        for part in shapely.get_parts(shapely.get_parts(g)):
            if part.geom_type != "Polygon":
                continue
            part = shapely.remove_repeated_points(shapely.geometry.polygon.orient(part), 1e-3)
            if part.is_empty or part.area < MIN_FOOTPRINT_M2:
                dropped += 1
                continue
            polys.append(part)
            hs.append(h)
            rules.append(rule)
            mats.append(building_material(kinds[k]))
            oid.append(ids[k])
    if not polys:
        raise InputError(field, f"{str(p)!r} has no building footprints{crop}")
    if dropped:
        log.info("OSM: %d footprint parts under %g m^2 dropped", dropped, MIN_FOOTPRINT_M2)
    nodes, edges = _street_graph(ways, fwd, bbox_deg, radius_m)
    return OsmCity(footprints=polys, heights=np.asarray(hs, dtype=float),
                   height_rules=np.asarray(rules), materials=np.asarray(mats),
                   osm_ids=np.asarray(oid), street_nodes=nodes, street_edges=edges,
                   origin_lonlat_deg=(lon0, lat0), crs=crs)


def street_lines(ways) -> list[np.ndarray]:
    """The (lon, lat) node sequences of the street ways: [[num_nodes_of_way, 2] float64, deg].

    Kept: ``highway`` in :data:`HIGHWAYS`, not ``area=yes``, no ``tunnel`` (other than ``no``).
    A closed way read as a polygon (a roundabout) contributes its ring.
    """
    import shapely

    if ways is None or len(ways) == 0:
        return []
    hw, area, tunnel = _column(ways, "highway"), _column(ways, "area"), _column(ways, "tunnel")
    out = []
    for g, h, a, t in zip(ways.geometry.values, hw, area, tunnel):
        if g is None or str(h) not in HIGHWAYS or str(a).lower() == "yes":
            continue
        if _present(t) and str(t).lower() != "no":
            continue
        for part in shapely.get_parts(g):
            if part.geom_type == "Polygon":
                part = part.exterior
            if part.geom_type in ("LineString", "LinearRing") and len(part.coords) >= 2:
                out.append(np.asarray(part.coords, dtype=float)[:, :2])
    return out


def _street_graph(ways, fwd, bbox_deg, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    lines = street_lines(ways)
    if not lines:
        return np.zeros((0, 2)), np.zeros((0, 2), dtype=np.int64)
    allc = np.round(np.concatenate(lines), COORD_DECIMALS)
    uniq, inv = np.unique(allc, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    starts = np.cumsum([0] + [len(ln) for ln in lines])
    pairs = np.concatenate([np.stack([inv[a:b - 1], inv[a + 1:b]], -1)
                            for a, b in zip(starts[:-1], starts[1:])])
    x, y = fwd.transform(uniq[:, 0], uniq[:, 1])
    xy = np.stack([x, y], -1)
    inside = np.ones(len(uniq), dtype=bool)
    if bbox_deg is not None:
        inside &= ((uniq[:, 0] >= bbox_deg[0]) & (uniq[:, 0] <= bbox_deg[2])
                   & (uniq[:, 1] >= bbox_deg[1]) & (uniq[:, 1] <= bbox_deg[3]))
    if radius_m > 0:
        inside &= np.hypot(xy[:, 0], xy[:, 1]) <= radius_m
    pairs = pairs[inside[pairs].all(axis=1) & (pairs[:, 0] != pairs[:, 1])]
    pairs = np.unique(np.sort(pairs, axis=1), axis=0)
    used, new = np.unique(pairs, return_inverse=True)
    return xy[used], new.reshape(-1, 2).astype(np.int64)
