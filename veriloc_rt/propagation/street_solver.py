"""Sionna RT side of :mod:`.street_paths`: a candidate generator for Sionna's PathSolver.

:class:`StreetCandidateGenerator` has the call signature of Sionna RT's shoot-and-bounce
candidate generators and returns a PathsBuffer of the deterministic street candidates; the
PathSolver then runs its own image method and field calculator on them, exactly as on the
candidates of its ray launcher. Import this module only after
:func:`veriloc_rt.backend.import_sionna` (it needs the Mitsuba variant selected).
"""

from __future__ import annotations

import logging

import drjit as dr
import mitsuba as mi
import numpy as np
from sionna.rt.constants import InteractionType
from sionna.rt.path_solvers.paths_buffer import PathsBuffer
from sionna.rt.utils.wedges import wedge_geometry

from .street_paths import (DIFFRACTION, REFLECTION, Candidates, SceneGeometry, aligned,
                           street_candidates, wanted_pairs)

log = logging.getLogger(__name__)

#: A pre-filter segment is tested for occlusion this far from its ends (its end points lie
#: on surfaces; Sionna's image method tests the exact segments afterwards), m
SEGMENT_END_MARGIN_M = 0.01

_KIND = np.zeros(3, np.uint32)
_KIND[REFLECTION] = InteractionType.SPECULAR
_KIND[DIFFRACTION] = InteractionType.DIFFRACTION


def scene_geometry(mi_scene) -> SceneGeometry:
    """Planes and wedges of every mesh of a Mitsuba scene."""
    meshes = []
    for sh in mi_scene.shapes():
        if not sh.is_mesh():
            continue
        ptr = int(np.asarray(dr.reinterpret_array(mi.UInt, mi.ShapePtr(sh)))[0])
        v = np.asarray(sh.vertex_positions_buffer(), np.float64).reshape(-1, 3)
        f = np.asarray(sh.faces_buffer(), np.int64).reshape(-1, 3)
        meshes.append((ptr, v, f))
    return SceneGeometry.from_meshes(meshes)


class StreetCandidateGenerator:
    """Deterministic [R...] D [R...] candidates (:func:`.street_paths.street_candidates`).

    :param mi_scene: the Mitsuba scene the solver will trace (its meshes are read once)
    :param plane_distance: m;  max_target_reflections (see
        :func:`.street_paths.street_candidates`)
    """

    def __init__(self, mi_scene, plane_distance: float, max_target_reflections: int):
        self.geo = scene_geometry(mi_scene)
        self.mi_scene = mi_scene
        self.plane_distance = plane_distance
        self.max_target_reflections = max_target_reflections
        self.last_num_candidates = 0
        #: [n, 2] int (source, target) pairs the next call enumerates (None: every pair)
        self.links: np.ndarray | None = None

    def __call__(self, mi_scene, src_positions, tgt_positions, samples_per_src,
                 max_num_paths_per_src, max_depth, los, specular_reflection, diffuse_reflection,
                 refraction, diffraction, edge_diffraction, seed, **_):
        src = _points(src_positions)
        tgt = _points(tgt_positions)
        depth = max(int(max_depth), 1)
        c = street_candidates(self.geo, src, tgt, depth, self.plane_distance,
                              self.max_target_reflections, self._visible, links=self.links) \
            if diffraction and max_depth >= 1 else None
        num = len(c) if c is not None else 0
        if num == 1:
            # a one-lane pointer array is dispatched wrongly by Dr.Jit (measured: the wedge
            # lookup read another mesh); the copy is dropped by RawPaths.merge
            c = Candidates(**{f: np.concatenate([getattr(c, f)] * 2) for f in Candidates.FIELDS})
            num = 2
        self.last_num_candidates = num
        buf = PathsBuffer(num, max_depth, diffraction)
        if num == 0:
            return buf
        # Dr.Jit may alias a contiguous NumPy array instead of copying it: keep every array
        # handed over alive until the solver is done with the buffer
        self._alive = arrs = [aligned(x) for x in (
            _KIND[c.kind], c.shape, c.prim, c.vertex[..., 0], c.vertex[..., 1],
            c.vertex[..., 2], np.ones(c.kind.shape), c.src.astype(np.uint32),
            c.tgt.astype(np.uint32))]
        buf._interaction_types = mi.TensorXu(arrs[0])
        buf._shapes = mi.TensorXu(arrs[1])
        buf._primitives = mi.TensorXu(arrs[2])
        buf._vertices_x = mi.TensorXf(arrs[3])
        buf._vertices_y = mi.TensorXf(arrs[4])
        buf._vertices_z = mi.TensorXf(arrs[5])
        buf._probs = mi.TensorXf(arrs[6])
        buf._src_indices = mi.UInt(arrs[7])
        buf._tgt_indices = mi.UInt(arrs[8])
        g = self.geo
        f0 = c.face0
        w_arrs = [aligned(x, np.uint32) for x in (
            g.edge_shape[c.wedge], g.edge_prim[c.wedge, f0], g.edge_local[c.wedge, f0])]
        self._alive += w_arrs
        wedges = wedge_geometry(dr.reinterpret_array(mi.MeshPtr, mi.UInt(w_arrs[0])),
                                mi.UInt(w_arrs[1]), mi.UInt(w_arrs[2]))
        dr.eval(wedges)
        # Sionna's 0-face is the one the incident ray comes from (ImageMethod checks
        # dot(-k, n0) > 0): keep the face chosen above even if wedge_geometry reoriented it
        n0 = _points(wedges.n0)
        flip = np.einsum("ij,ij->i", n0, g.edge_n[c.wedge, f0]) < 0
        if flip.any():
            flip = aligned(flip)
            self._alive.append(flip)
            wedges.swap_faces(mi.Bool(flip))
        dr.eval(wedges)
        buf._diffracting_wedges = wedges
        buf._paths_counter = mi.UInt(num)
        buf.schedule()
        dr.eval()
        return buf

    def _visible(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Whether the segments a-b [n, 3] m meet no surface away from their ends (False where
        an end is not finite). -> [n] bool"""
        # a NaN or an infinity in a row makes its sum non-finite (coordinates are far below
        # the float64 overflow), at a fraction of the cost of np.isfinite(...).all(axis=1)
        with np.errstate(invalid="ignore", over="ignore"):       # inf - inf: NaN, not finite
            finite = np.isfinite(a[:, 0] + a[:, 1] + a[:, 2] + b[:, 0] + b[:, 1] + b[:, 2])
        if not finite.any():
            return finite
        if not finite.all():
            a, b = np.where(finite[:, None], a, 0.0), np.where(finite[:, None], b, 1.0)
        d = b - a
        # np.linalg.norm(d, axis=1) term by term, in its order (the same float64 bits), faster
        length = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
        u = d / np.where(length > 0, length, 1.0)[:, None]
        o = a + SEGMENT_END_MARGIN_M * u
        # one array per coordinate: a [3, n] array would be read with the stride n compiled in,
        # one kernel per segment count (docs/performance.md, "Cold start")
        arrs = [aligned(x, np.float32) for x in (*o.T, *u.T,
                                                  np.maximum(length - 2 * SEGMENT_END_MARGIN_M, 0))]
        ray = mi.Ray3f(mi.Point3f(*(mi.Float(x) for x in arrs[:3])),
                       mi.Vector3f(*(mi.Float(x) for x in arrs[3:6])))
        ray.maxt = mi.Float(arrs[6])
        hit = np.asarray(self.mi_scene.ray_test(ray), bool)
        del arrs   # read by ray_test, which has run
        return finite & ~hit & (length > 2 * SEGMENT_END_MARGIN_M)


class WantedLinks:
    """Wraps a Sionna candidate generator and drops the candidates of (source, target) pairs
    that are not wanted before the PathSolver refines them: a call can then hold many
    point-to-point links (its rays are shared; only the wanted pairs' candidates go on to the
    image method and the field calculator).

    :param generator: a Sionna RT candidate generator (e.g. the PathSolver's own)
    """

    def __init__(self, generator):
        self.generator = generator
        #: [n, 2] int (source, target) pairs the next call keeps (None: every pair)
        self.links: np.ndarray | None = None

    def __call__(self, mi_scene, src_positions, tgt_positions, **kwargs):
        buf = self.generator(mi_scene=mi_scene, src_positions=src_positions,
                             tgt_positions=tgt_positions, **kwargs)
        if self.links is None:
            return buf
        buf.schedule()
        dr.eval()
        buf.shrink()
        wanted = wanted_pairs(self.links, dr.width(src_positions), dr.width(tgt_positions))
        src = np.asarray(buf.source_indices, np.int64)
        tgt = np.asarray(buf.target_indices, np.int64)
        keep = aligned(np.flatnonzero(wanted[src, tgt]), np.uint32)
        self._alive = keep      # Dr.Jit may alias the array (see StreetCandidateGenerator)
        buf = buf.gather(mi.UInt(keep))
        return buf


def _points(p) -> np.ndarray:
    """Dr.Jit 3-vector array -> [n, 3] float64, read one coordinate at a time: Dr.Jit writes a
    whole 3-vector array into NumPy's [3, n] layout with a kernel that has n compiled in (one
    kernel per array size; docs/performance.md, "Cold start")."""
    dr.eval(p)
    return np.stack([np.asarray(c, np.float64) for c in (p.x, p.y, p.z)], axis=1)
