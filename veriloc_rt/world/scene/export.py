"""Mitsuba XML + PLY export of a canyon, and reading meshes back from any Sionna XML scene.

The PLY writer is our own (binary little-endian, fixed header) so the same canyon always gives
byte-identical files; this is what the propagation cache hashes.
"""

from __future__ import annotations

import hashlib
import struct
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ...errors import InputError
from .canyon import UrbanCanyon

SCENE_FILE = "scene.xml"


def write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Binary little-endian PLY: float32 vertices, uint8-counted int32 triangle lists.

    :param vertices: [num_vertices, 3] float, m; faces: [num_faces, 3] int
    """
    v = np.ascontiguousarray(vertices, dtype="<f4")
    f = np.empty(len(faces), dtype=[("n", "u1"), ("idx", "<i4", (3,))])
    f["n"] = 3
    f["idx"] = faces
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(v.tobytes())
        fh.write(f.tobytes())


def read_ply(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh PLY (any encoding trimesh reads). -> vertices, faces"""
    import trimesh

    mesh = trimesh.load(str(path), force="mesh", process=False)
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)


def scene_bounds(canyon: UrbanCanyon, points_xy: np.ndarray, pad: float) -> tuple[float, ...]:
    """Ground rectangle covering the buildings and the given points, grown by ``pad``."""
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    xs = [pts[:, 0]] + ([canyon.footprints[:, 0], canyon.footprints[:, 2]]
                        if canyon.num_buildings else [])
    ys = [pts[:, 1]] + ([canyon.footprints[:, 1], canyon.footprints[:, 3]]
                        if canyon.num_buildings else [])
    x, y = np.concatenate(xs), np.concatenate(ys)
    return (float(x.min() - pad), float(y.min() - pad), float(x.max() + pad), float(y.max() + pad))


def write_scene(canyon: UrbanCanyon, out_dir: str | Path,
                ground_bounds: tuple[float, float, float, float]) -> Path:
    """Write ``scene.xml`` with ``meshes/buildings.ply`` and ``meshes/ground.ply``.

    :returns: path of the XML file, loadable with ``sionna.rt.load_scene``
    """
    out = Path(out_dir)
    (out / "meshes").mkdir(parents=True, exist_ok=True)
    shapes = []
    if canyon.num_buildings:
        v, f = canyon.box_meshes()
        write_ply(out / "meshes" / "buildings.ply", v, f)
        shapes.append(("buildings", "buildings_material"))
    gv, gf = canyon.ground_mesh(ground_bounds)
    write_ply(out / "meshes" / "ground.ply", gv, gf)
    shapes.append(("ground", "ground_material"))
    t = f"{canyon.material_thickness:.6g}"
    lines = ['<scene version="2.1.0">', "",
             '\t<bsdf type="itu-radio-material" id="buildings_material">',
             f'\t\t<string name="type" value="{canyon.building_material}"/>',
             f'\t\t<float name="thickness" value="{t}"/>', "\t</bsdf>",
             '\t<bsdf type="itu-radio-material" id="ground_material">',
             f'\t\t<string name="type" value="{canyon.ground_material}"/>',
             f'\t\t<float name="thickness" value="{t}"/>', "\t</bsdf>", ""]
    for name, mat in shapes:
        lines += [f'\t<shape type="ply" id="mesh-{name}">',
                  f'\t\t<string name="filename" value="meshes/{name}.ply"/>',
                  '\t\t<boolean name="face_normals" value="true"/>',
                  f'\t\t<ref id="{mat}" name="bsdf"/>', "\t</shape>"]
    lines += ["</scene>", ""]
    xml = out / SCENE_FILE
    xml.write_text("\n".join(lines))
    return xml


def scene_mesh_files(xml_path: str | Path, field: str = "scene.source") -> list[Path]:
    """PLY/OBJ files an XML scene references (paths resolved against the XML's folder).

    :raises InputError: if the file is missing, not XML, or references missing meshes
    """
    xml_path = Path(xml_path)
    if not xml_path.is_file():
        raise InputError(field, f"scene file {str(xml_path)!r} does not exist")
    try:
        root = ET.parse(xml_path).getroot()
    except ET.ParseError as exc:
        raise InputError(field, f"{str(xml_path)!r} is not valid XML ({exc})") from None
    files = []
    for shape in root.iter("shape"):
        for s in shape.iter("string"):
            if s.get("name") == "filename":
                p = (xml_path.parent / s.get("value", "")).resolve()
                if not p.is_file():
                    raise InputError(field, f"{str(xml_path)!r} references missing mesh {str(p)!r}")
                files.append(p)
    if not files:
        raise InputError(field, f"{str(xml_path)!r} has no mesh shapes")
    return files


def scene_digest(xml_path: str | Path) -> str:
    """SHA-256 over the XML and every mesh it references (the cache key of a scene)."""
    h = hashlib.sha256()
    xml_path = Path(xml_path)
    h.update(xml_path.read_bytes())
    for p in scene_mesh_files(xml_path):
        h.update(struct.pack("<Q", p.stat().st_size))
        h.update(p.read_bytes())
    return h.hexdigest()
