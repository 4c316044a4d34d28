"""Mitsuba XML + PLY export of a canyon, and reading meshes back from any Sionna XML scene.

PLY files are read by trimesh and written here, in the bytes trimesh's binary writer gives (its
header, float32 vertices, uchar-counted int32 triangles): deterministic, so the same canyon always
gives byte-identical files, which the propagation cache hashes (:func:`scene_digest`); writing
them here spares a run trimesh's import (a third of a second, paid again by every resume). Every
file is written atomically (:mod:`veriloc_rt.fileio`).
"""

from __future__ import annotations

import hashlib
import io
import struct
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ...errors import InputError
from ...fileio import atomic_write_bytes, atomic_write_text
from ...inputs import check_path, read_bytes
from .canyon import UrbanCanyon

SCENE_FILE = "scene.xml"
#: largest scene XML read, bytes
MAX_XML_BYTES = 16 << 20
#: largest mesh file read, bytes (the paper-size canyon's buildings are ~1 MB)
MAX_MESH_BYTES = 1 << 30


#: the header of trimesh's binary PLY writer (``trimesh.exchange.ply.export_ply``), comment
#: included: the files stay byte-identical to those it wrote, and so do the cache keys
_PLY_HEADER = ("ply\nformat binary_little_endian 1.0\ncomment https://github.com/mikedh/trimesh\n"
               "element vertex {nv}\nproperty float x\nproperty float y\nproperty float z\n"
               "element face {nf}\nproperty list uchar int vertex_indices\nend_header\n")
#: one binary PLY triangle: its vertex count (3) and three vertex indices
_PLY_FACE = np.dtype([("count", "<u1"), ("index", "<i4", (3,))])


def ply_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A triangle mesh as a binary little-endian PLY file (PLY format 1.0: header, then the
    vertex and face elements in the order the header declares them).

    :param vertices: [num_vertices, 3] float, m (stored as float32)
    :param faces: [num_faces, 3] int, vertex indices (stored as int32)
    """
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces).reshape(-1, 3)
    packed = np.empty(len(f), dtype=_PLY_FACE)
    packed["count"] = 3
    packed["index"] = f
    head = _PLY_HEADER.format(nv=len(v), nf=len(f)).encode("ascii")
    return head + v.astype("<f4").tobytes() + packed.tobytes()


def write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Write a triangle mesh as a binary little-endian PLY (:func:`ply_bytes`), atomically.

    :param vertices: [num_vertices, 3] float, m (stored as float32)
    :param faces: [num_faces, 3] int, vertex indices (stored as int32)
    """
    atomic_write_bytes(path, ply_bytes(vertices, faces))


def read_ply(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh (PLY, or any format trimesh reads) and check it.

    :returns: vertices [num_vertices, 3] float64, m; faces [num_faces, 3] int64
    :raises InputError: naming the file when it is not a regular file, cannot be parsed (an
        ASCII PLY: has not as many rows as its header declares), has no triangle, a non-finite
        vertex or a face index outside the vertex list
    """
    import trimesh   # on use: its import takes a third of a second; most commands read no mesh

    name = str(path)
    data = read_bytes(path, name, "mesh file", MAX_MESH_BYTES)
    try:
        kind = Path(path).suffix.lstrip(".").lower()
        if kind == "ply":   # trimesh's PLY parser alone: 5x faster than trimesh.load's scene
            from trimesh.exchange.ply import load_ply   # graph (2367 files of sionna:munich)

            kw = load_ply(io.BytesIO(data))
            vertices = np.asarray(kw["vertices"], dtype=float).reshape(-1, 3)
            faces = np.asarray(kw.get("faces", np.zeros((0, 3))), dtype=np.int64)
        else:
            mesh = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh", process=False)
            vertices = np.asarray(mesh.vertices, dtype=float).reshape(-1, 3)
            faces = np.asarray(mesh.faces, dtype=np.int64)
    except Exception as exc:  # noqa: BLE001 - a third-party parser on user bytes: any failure
        reason = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise InputError(name, f"not a readable triangle mesh ({reason})") from None
    _check_ascii_ply_rows(data, name)
    if faces.ndim != 2 or faces.shape[0] == 0 or faces.shape[1] != 3:
        raise InputError(name, f"no triangles (faces of shape {faces.shape})")
    if not np.all(np.isfinite(vertices)):
        k = int(np.argmax(~np.all(np.isfinite(vertices), axis=1)))
        raise InputError(name, f"vertex {k} is not finite ({vertices[k].tolist()})")
    if faces.min() < 0 or faces.max() >= len(vertices):
        k = int(np.argmax((faces < 0).any(axis=1) | (faces >= len(vertices)).any(axis=1)))
        raise InputError(name, f"face {k} indexes vertex {faces[k].tolist()}, but the mesh has "
                         f"{len(vertices)} vertices")
    return vertices, faces


def _check_ascii_ply_rows(data: bytes, name: str) -> None:
    """An ASCII PLY must have as many data rows as its header declares elements.

    trimesh reads ASCII rows in order without counting them: a file cut short loses its last
    faces, and one missing a vertex row takes the first face row as a vertex, both silently
    (binary files it checks: their length must match the header).
    """
    head, sep, body = data.partition(b"end_header")
    lines = [ln.split() for ln in head.decode("ascii", "replace").splitlines()]
    if not (data.startswith(b"ply") and sep and ["format", "ascii"] in [ln[:2] for ln in lines]):
        return
    declared = sum(int(ln[2]) for ln in lines
                   if len(ln) == 3 and ln[0] == "element" and ln[2].isdigit())
    rows = sum(1 for ln in body.splitlines() if ln.strip())
    if rows != declared:
        raise InputError(name, f"{rows} data rows, but the PLY header declares {declared} "
                         "elements (vertices and faces)")


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
    atomic_write_text(xml, "\n".join(lines))
    return xml


def scene_mesh_files(xml_path: str | Path, field: str = "scene.source") -> list[Path]:
    """PLY/OBJ files an XML scene references (paths resolved against the XML's folder).

    :raises InputError: if the file is missing, not XML, or references missing meshes
    """
    return [path for _, path, _ in scene_shapes(xml_path, field)]


def scene_shapes(xml_path: str | Path, field: str = "scene.source") -> list[tuple[str, Path, str]]:
    """The mesh shapes of an XML scene: (shape id, mesh file, id of the material it refers to,
    "" for none), in document order; mesh paths are resolved against the XML's folder.

    :raises InputError: if the file is missing, not XML, or references missing meshes
    """
    root = _scene_root(xml_path, field)
    xml_path = Path(xml_path)
    folder = xml_path.parent.resolve()
    shapes = []
    for k, shape in enumerate(root.iter("shape")):
        bsdf = next((r.get("id", "") for r in shape.iter("ref")), "")
        for s in shape.iter("string"):
            if s.get("name") == "filename":
                ref = check_path(s.get("value", ""), field)
                p = (xml_path.parent / ref).resolve()
                if not p.is_relative_to(folder):
                    raise InputError(field, f"{str(xml_path)!r} references mesh {str(p)!r} "
                                     "outside the scene's folder")
                if not p.exists():  # anything but a regular file: read_ply says so
                    raise InputError(field, f"{str(xml_path)!r} references missing mesh {str(p)!r}")
                shapes.append((shape.get("id") or f"shape-{k}", p, bsdf))
    if not shapes:
        raise InputError(field, f"{str(xml_path)!r} has no mesh shapes")
    return shapes


def scene_bsdfs(xml_path: str | Path, field: str = "scene.source") -> dict[str, str]:
    """The top-level material definitions of an XML scene: id -> the ``<bsdf>`` element as XML
    text (copied verbatim into a cropped scene)."""
    root = _scene_root(xml_path, field)
    return {b.get("id"): ET.tostring(b, encoding="unicode").strip()
            for b in root.findall("bsdf") if b.get("id")}


def scene_itu_materials(xml_path: str | Path, field: str = "scene.source") -> list[str]:
    """The ITU material types (``<bsdf type="itu-radio-material">``'s ``type``) an XML scene
    uses, in the order they appear."""
    out = []
    for bsdf in _scene_root(xml_path, field).iter("bsdf"):
        if bsdf.get("type") == "itu-radio-material":
            for s in bsdf.iter("string"):
                if s.get("name") == "type":
                    out.append(s.get("value", ""))
    return out


def _scene_root(xml_path: str | Path, field: str) -> ET.Element:
    data = read_bytes(xml_path, field, "scene file", MAX_XML_BYTES)
    try:
        return ET.fromstring(data)
    except ET.ParseError as exc:
        raise InputError(field, f"{str(xml_path)!r} is not valid XML ({exc})") from None


def scene_digest(xml_path: str | Path) -> str:
    """SHA-256 over the XML and every mesh it references (the cache key of a scene)."""
    h = hashlib.sha256()
    xml_path = Path(xml_path)
    h.update(xml_path.read_bytes())
    for p in scene_mesh_files(xml_path):
        h.update(struct.pack("<Q", p.stat().st_size))
        h.update(p.read_bytes())
    return h.hexdigest()
