"""Writing an imported OpenStreetMap city as a Sionna scene, and the run's cached import.

``scene.xml`` (one PLY per building material, a ground plane), ``scene.json`` (the frame and
provenance) and ``streets.json`` (the street graph), every file written atomically. The rules
(heights, materials, frame, extrusion) are in :mod:`veriloc_rt.world.scene.osm`.
"""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path

import numpy as np

from ...fileio import atomic_files, atomic_write_text, json_text
from ...inputs import check_path, read_bytes
from .export import SCENE_FILE, write_ply
from .osm import (DEFAULT_HEIGHT_M, FORMAT_VERSION, HIGHWAYS, MAX_OSM_BYTES, STOREY_M, OsmCity,
                  check_kind, read_osm)

log = logging.getLogger(__name__)

#: the ground plane extends this far beyond the buildings and streets, m
GROUND_MARGIN_M = 20.0


def write_osm_scene(city: OsmCity, out_dir, *, ground_material: str = "medium_dry_ground",
                    thickness_m: float = 0.3, meta: dict | None = None) -> Path:
    """Write ``scene.xml`` (one PLY per building material, a ground plane), ``scene.json`` (frame
    and provenance) and ``streets.json`` (the street graph) into ``out_dir``.

    :returns: path of the XML file, loadable with ``sionna.rt.load_scene``
    """
    out = Path(out_dir)
    (out / "meshes").mkdir(parents=True, exist_ok=True)
    meshes = city.building_meshes()
    mats = sorted(set(city.materials.tolist()))
    lines = ['<scene version="2.1.0">', ""]
    for mat in mats + ["ground"]:
        itu = ground_material if mat == "ground" else mat
        lines += [f'\t<bsdf type="itu-radio-material" id="{mat}_material">',
                  f'\t\t<string name="type" value="{itu}"/>',
                  f'\t\t<float name="thickness" value="{thickness_m:.6g}"/>', "\t</bsdf>"]
    lines.append("")
    for mat in mats:
        sel = [m for m, name in zip(meshes, city.materials) if name == mat]
        offs = np.cumsum([0] + [len(v) for v, _ in sel])
        v = np.concatenate([v for v, _ in sel])
        f = np.concatenate([f + o for (_, f), o in zip(sel, offs[:-1])])
        write_ply(out / "meshes" / f"buildings_{mat}.ply", v, f)
    x0, y0, x1, y1 = city.extent()
    g = GROUND_MARGIN_M
    gv = np.array([[x0 - g, y0 - g, 0.0], [x1 + g, y0 - g, 0.0], [x1 + g, y1 + g, 0.0],
                   [x0 - g, y1 + g, 0.0]])
    write_ply(out / "meshes" / "ground.ply", gv, np.array([[0, 1, 2], [0, 2, 3]]))
    for name, mat in [(f"buildings_{m}", m) for m in mats] + [("ground", "ground")]:
        lines += [f'\t<shape type="ply" id="mesh-{name}">',
                  f'\t\t<string name="filename" value="meshes/{name}.ply"/>',
                  '\t\t<boolean name="face_normals" value="true"/>',
                  f'\t\t<ref id="{mat}_material" name="bsdf"/>', "\t</shape>"]
    lines += ["</scene>", ""]
    streets = {"nodes": np.round(city.street_nodes, 4).tolist(),
               "edges": city.street_edges.tolist()}
    atomic_write_text(out / "streets.json",
                      json_text(streets, indent=None, separators=(",", ":")) + "\n")
    info = {"format_version": FORMAT_VERSION, "crs": city.crs,
            "origin_lonlat_deg": list(city.origin_lonlat_deg),
            "frame": "x east, y north, z up, m; transverse Mercator centred on origin_lonlat_deg",
            "num_buildings": city.num_buildings,
            "height_rules": {r: int(np.sum(city.height_rules == r))
                             for r in ("height", "levels", "default")},
            "materials": {m: int(np.sum(city.materials == m)) for m in mats},
            "ground_material": ground_material, "thickness_m": thickness_m,
            "ground_xy_m": [x0 - g, y0 - g, x1 + g, y1 + g],
            "num_street_nodes": len(city.street_nodes),
            "num_street_edges": len(city.street_edges), "highways": list(HIGHWAYS),
            **(meta or {})}
    atomic_write_text(out / "scene.json", json_text(info) + "\n")
    xml = out / SCENE_FILE
    atomic_write_text(xml, "\n".join(lines))
    return xml


def osm_scene(path, out_dir, *, field: str = "scene.osm", bbox_deg=None, radius_m: float = 0.0,
              storey_m: float = STOREY_M, default_height_m: float = DEFAULT_HEIGHT_M,
              ground_material: str = "medium_dry_ground",
              thickness_m: float = 0.3) -> tuple[Path, OsmCity | None]:
    """Import ``path`` into ``out_dir``, or reuse the scene already there when it was built from
    the same extract (SHA-256) with the same settings.

    :returns: the XML path and the city (None when reused)
    """
    p = check_path(path, field)
    check_kind(p, field)
    digest = hashlib.sha256(read_bytes(p, field, "OpenStreetMap extract", MAX_OSM_BYTES)).hexdigest()
    meta = {"source": str(p), "source_sha256": digest,
            "bbox_deg": list(bbox_deg) if bbox_deg is not None else None,
            "radius_m": radius_m, "storey_m": storey_m, "default_height_m": default_height_m}
    out = Path(out_dir)
    xml = out / SCENE_FILE
    try:
        old = json.loads((out / "scene.json").read_text())
    except (OSError, ValueError):
        old = None
    keys = list(meta) + ["format_version", "ground_material", "thickness_m"]
    now = {**meta, "format_version": FORMAT_VERSION, "ground_material": ground_material,
           "thickness_m": thickness_m}
    if (isinstance(old, dict) and xml.exists()
            and all(old.get(k) == now[k] for k in keys if k != "source")):
        log.info("OSM scene reused from %s", out)
        return xml, None
    city = read_osm(p, field, bbox_deg=bbox_deg, radius_m=radius_m, storey_m=storey_m,
                    default_height_m=default_height_m)
    # the old index goes first and the new one comes after every other file: a stop in
    # between leaves no scene.xml, so nothing half-written is reused
    xml.unlink(missing_ok=True)
    with atomic_files(out) as tmp:
        new = write_osm_scene(city, tmp, ground_material=ground_material,
                              thickness_m=thickness_m, meta=meta)
        index = new.read_text()
        new.unlink()
    atomic_write_text(xml, index)
    return xml, city
