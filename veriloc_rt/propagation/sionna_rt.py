"""Thin, batched wrapper around Sionna RT's PathSolver.

It knows nothing of trajectories: it traces (one transmitter, many receivers) groups and
returns raw per-link paths in float64 / complex128, with invalid paths masked. Both ends are one
isotropic dual-polarised element ('VH': theta-hat and phi-hat ports), so every path carries its
2x2 polarimetric coefficient and any single-port polarization is applied afterwards
(:mod:`~veriloc_rt.propagation.polarization`); the UE's ULA is applied afterwards from the arrival
angles (the synthetic-array model). One trace serves any array and any polarization.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..backend import import_sionna
from ..config import RayTracingConfig
from .polarization import apply_materials, project
from .street_paths import aligned, duplicates

log = logging.getLogger(__name__)

#: Source counts up to this are padded to a power of two, larger ones to a multiple of
#: SOURCE_STEP_LARGE (:func:`padded_source_count`)
SOURCE_POW2_MAX = 128
SOURCE_STEP_LARGE = 64

#: Dummy sources stand this many scene-diagonals below the scene's lowest point: the scene
#: then fills a cone of ~1/(2 x this) rad around their zenith, so almost none of their rays
#: meets it (their cost) and what they trace is dropped anyway (:meth:`SionnaTracer.trace`)
DUMMY_SOURCE_DISTANCE = 100.0


def padded_source_count(n: int) -> int:
    """The source count a PathSolver call of ``n`` real sources is padded to: the next power
    of two up to SOURCE_POW2_MAX, then the next multiple of SOURCE_STEP_LARGE. At most
    2n - 1 (the dummies' hash tables and buffers: memory) and one of a few values, so that
    Dr.Jit compiles the kernels whose code holds the source count once per value, not once
    per drive."""
    if n < 1:
        raise ValueError(f"`n` must be >= 1, not {n}")
    if n <= SOURCE_POW2_MAX:
        return 1 << (n - 1).bit_length()
    return -(-n // SOURCE_STEP_LARGE) * SOURCE_STEP_LARGE


def pad_sources(src: np.ndarray, dummy: np.ndarray) -> np.ndarray:
    """``src`` [n, 3] m followed by copies of ``dummy`` [3] m up to
    :func:`padded_source_count` rows: the real sources keep their indices."""
    src = np.atleast_2d(np.asarray(src, np.float64))
    extra = padded_source_count(len(src)) - len(src)
    return np.concatenate([src, np.broadcast_to(np.asarray(dummy, np.float64), (extra, 3))])


def dummy_source_position(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Where dummy sources stand for a scene whose bounding box is ``lo``..``hi`` [3] m:
    below its centre, DUMMY_SOURCE_DISTANCE diagonals (at least 1 m each) below its lowest
    point. -> [3] float64, m"""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    diag = max(float(np.linalg.norm(hi - lo)), 1.0)
    c = (lo + hi) / 2
    return np.array([c[0], c[1], lo[2] - DUMMY_SOURCE_DISTANCE * diag])


@dataclass(frozen=True, eq=False)
class RawPaths:
    """Paths of ``num_links`` links, padded to ``num_paths``.

    tau : [num_links, num_paths] float64, s
    a : [num_links, num_paths, num_rx_ports, num_tx_ports] complex128, path coefficient per
        (receive port, transmit port): 2x2 polarimetric (theta-hat, phi-hat) as traced, 1x1
        after :meth:`project`
    theta_r, phi_r, theta_t, phi_t : [num_links, num_paths] float64, rad
    interactions : [num_links, num_paths, max_depth] uint8;  valid : [num_links, num_paths] bool
    """

    tau: np.ndarray
    a: np.ndarray
    theta_r: np.ndarray
    phi_r: np.ndarray
    theta_t: np.ndarray
    phi_t: np.ndarray
    interactions: np.ndarray
    valid: np.ndarray

    FIELDS = ("tau", "a", "theta_r", "phi_r", "theta_t", "phi_t", "interactions", "valid")

    @property
    def num_links(self) -> int:
        return self.tau.shape[0]

    def project(self, rx: str, tx: str) -> "RawPaths":
        """Single-port coefficients (``a`` becomes [..., 1, 1]) for polarizations ``rx``, ``tx``.

        As Sionna RT does for a path whose coefficient is zero for every antenna pair, a path
        the two ports do not couple at all (exactly 0) is dropped.
        """
        a = project(self.a, rx, tx)
        valid = self.valid & (a != 0)
        return replace(self, a=np.where(valid, a, 0.0)[..., None, None], valid=valid,
                       tau=np.where(valid, self.tau, -1.0))

    def keep_strongest(self, max_paths: int) -> "RawPaths":
        """At most ``max_paths`` paths per link (the strongest: power summed over the port
        pairs), then sorted by delay."""
        power = np.where(self.valid, np.sum(np.abs(self.a) ** 2, axis=(2, 3)), -1.0)
        n = min(max_paths, self.tau.shape[1])
        top = np.argsort(-power, axis=1, kind="stable")[:, :n]
        tau_top = np.take_along_axis(np.where(self.valid, self.tau, np.inf), top, axis=1)
        order = np.take_along_axis(top, np.argsort(tau_top, axis=1, kind="stable"), axis=1)
        pick = {f: np.take_along_axis(getattr(self, f), order.reshape(
            order.shape + (1,) * (getattr(self, f).ndim - 2)), axis=1) for f in self.FIELDS}
        return RawPaths(**pick)

    @classmethod
    def empty(cls, num_links: int, max_depth: int,
              num_ports: tuple[int, int] = (2, 2)) -> "RawPaths":
        """``num_links`` links without a path (one invalid padding path each)."""
        z = np.zeros((num_links, 1))
        return cls(tau=np.full((num_links, 1), -1.0),
                   a=np.zeros((num_links, 1) + tuple(num_ports), np.complex128), theta_r=z.copy(),
                   phi_r=z.copy(), theta_t=z.copy(), phi_t=z.copy(),
                   interactions=np.zeros((num_links, 1, max_depth), np.uint8),
                   valid=np.zeros((num_links, 1), bool))

    def merge(self, other: "RawPaths") -> "RawPaths":
        """The paths of both (same links), each distinct path once
        (:func:`.street_paths.duplicates`), in the order self, other."""
        both = {f: np.concatenate([getattr(self, f), getattr(other, f)], axis=1)
                if f != "interactions" else None for f in self.FIELDS}
        depth = max(self.interactions.shape[2], other.interactions.shape[2])
        both["interactions"] = np.concatenate(
            [np.pad(x.interactions, [(0, 0), (0, 0), (0, depth - x.interactions.shape[2])])
             for x in (self, other)], axis=1)
        angles = np.stack([both[f] for f in ("theta_r", "phi_r", "theta_t", "phi_t")], axis=-1)
        dup = duplicates(both["tau"], angles, both["interactions"], both["valid"])
        keep = both["valid"] & ~dup
        order = np.argsort(~keep, axis=1, kind="stable")[:, :max(int(keep.sum(1).max()), 1)]
        out = {}
        for f in self.FIELDS:
            x = np.take_along_axis(both[f], order.reshape(order.shape + (1,) * (both[f].ndim - 2)),
                                   axis=1)
            out[f] = x
        v = np.take_along_axis(keep, order, axis=1)
        out["valid"] = v
        out["tau"] = np.where(v, out["tau"], -1.0)
        out["a"] = np.where(v[..., None, None], out["a"], 0.0)
        for f in ("theta_r", "phi_r", "theta_t", "phi_t"):      # as _extract pads
            out[f] = np.where(v, out[f], 0.0)
        out["interactions"] = np.where(v[..., None], out["interactions"], 0).astype(np.uint8)
        return RawPaths(**out)

    @staticmethod
    def concat(parts: list["RawPaths"]) -> "RawPaths":
        width = max(p.tau.shape[1] for p in parts)
        depth = max(p.interactions.shape[2] for p in parts)
        out = {}
        for f in RawPaths.FIELDS:
            arrs = []
            for p in parts:
                x = getattr(p, f)
                pad = [(0, 0), (0, width - x.shape[1])] + [(0, 0)] * (x.ndim - 2)
                if f == "interactions":
                    pad[2] = (0, depth - x.shape[2])
                arrs.append(np.pad(x, pad))
            out[f] = np.concatenate(arrs, axis=0)
        out["tau"] = np.where(out["valid"], out["tau"], -1.0)
        return RawPaths(**out)

    def to_npz(self) -> dict[str, np.ndarray]:
        return {f: getattr(self, f) for f in self.FIELDS}

    @classmethod
    def from_npz(cls, data) -> "RawPaths":
        return cls(**{f: np.asarray(data[f]) for f in cls.FIELDS})


class SionnaTracer:
    """Loads a scene once and traces (tx, [rx...]) groups with fixed fidelity.

    A call with ``pairs`` traces its sources padded with dummy sources
    (:func:`padded_source_count`; :attr:`pad_sources`), which leaves every real pair's paths
    the same to the bit: the dummies come after the real sources (whose indices, rays and
    sampler lanes are unchanged); in Sionna's candidate generator each source has its own
    hash-table region, its own path budget and its own share of the candidate buffer, so the
    dummies' rays cannot displace a real source's candidates; and the dummies' pairs are not
    wanted, so their candidates are dropped before the image method (:class:`.WantedLinks`)
    or never enumerated (:class:`.StreetCandidateGenerator`). The sampled rays' candidate
    generator is Sionna's deterministic one with the target count handed to Dr.Jit as data
    (:mod:`.sb_opaque`). With both, a call's kernels depend on its padded source count and on
    whether it has one target or several, not on a drive's own counts (docs/performance.md,
    "Cold start").

    :param scene_xml: Mitsuba XML scene
    :param frequency: carrier frequency [Hz]
    :param seed: PathSolver seed (deterministic candidate generation)
    :param diffraction_coefficient: 'utd' gives every object a material whose diffraction is
        the Kouyoumjian-Pathak / Luebbers UTD (:mod:`.utd_material`); 'sionna' keeps Sionna's
    """

    def __init__(self, scene_xml: str | Path, frequency: float, seed: int,
                 diffraction_coefficient: str = "utd"):
        self._rt = rt = import_sionna()
        self.scene = rt.load_scene(str(scene_xml), merge_shapes=True)
        if diffraction_coefficient == "utd":
            # deferred: the module subclasses Sionna's materials, importable only after
            # import_sionna() has selected the Mitsuba variant
            from .utd_material import use_utd_materials
            use_utd_materials(self.scene)
        elif diffraction_coefficient != "sionna":
            raise ValueError("`diffraction_coefficient` must be 'utd' or 'sionna', "
                             f"not {diffraction_coefficient!r}")
        self.scene.frequency = frequency
        self.scene.tx_array, self.scene.rx_array = polarimetric_arrays(rt)
        #: (receive, transmit) ports of a path coefficient
        self.ports = (len(self.scene.rx_array.antenna_pattern.patterns),
                      len(self.scene.tx_array.antenna_pattern.patterns))
        self._materials = None   # the MaterialsConfig last applied to the scene
        self.solver = rt.PathSolver(deterministic=True)
        # deferred: the module needs the Mitsuba variant import_sionna() selected
        from .sb_opaque import OpaqueSBDeterministicCandidateGenerator
        from .street_solver import WantedLinks
        # Sionna's PathSolver has no public hook for the candidate generator: its attribute
        # is wrapped (pinned Sionna RT version, tests/unit/propagation), around Sionna's
        # deterministic generator with the target count opaque to Dr.Jit (sb_opaque)
        self._wanted = WantedLinks(OpaqueSBDeterministicCandidateGenerator())
        self.solver._candidate_generator = self._wanted
        self._edge_solvers: dict = {}   # (plane distance, target reflections) -> (solver, gen.)
        # deferred, as above: the image method and field calculator of Sionna's PathSolver
        from sionna.rt.path_solvers.field_calculator import FieldCalculator
        from sionna.rt.path_solvers.image_method import ImageMethod
        self._stages = (ImageMethod(), FieldCalculator())
        self.seed = int(seed) % (2**31 - 1)
        self.max_paths_per_src = 10**6
        self.last_num_edge_candidates = 0
        #: pad the sources of a call with ``pairs`` (False: the call's own source count)
        self.pad_sources = True
        #: sources of the last PathSolver call, dummies included
        self.last_num_sources = 0
        bbox = self.scene.mi_scene.bbox()
        self._dummy = dummy_source_position(np.array(bbox.min, np.float64).ravel(),
                                            np.array(bbox.max, np.float64).ravel())

    @property
    def candidate_generator(self):
        """Sionna RT candidate generator of the sampled rays (before :class:`.WantedLinks`
        drops the unwanted pairs): Sionna's deterministic one with the target count opaque
        (:mod:`.sb_opaque`); settable (tests compare it with Sionna's own)."""
        return self._wanted.generator

    @candidate_generator.setter
    def candidate_generator(self, generator) -> None:
        self._wanted.generator = generator

    def _edge_solver(self, fid: RayTracingConfig):
        """(PathSolver, its candidate generator): the exhaustive edge-diffraction candidates."""
        key = (fid.candidate_plane_distance_m, fid.candidate_target_reflections)
        if key not in self._edge_solvers:
            # deferred: the module needs the Mitsuba variant import_sionna() selected
            from .street_solver import StreetCandidateGenerator
            solver = self._rt.PathSolver()
            # Sionna's PathSolver has no public hook for the candidate generator: its
            # attribute is replaced (pinned Sionna RT version, tests/unit/propagation)
            generator = StreetCandidateGenerator(self.scene.mi_scene, *key)
            solver._candidate_generator = generator
            self._edge_solvers[key] = (solver, generator)
        return self._edge_solvers[key]

    def trace(self, tx_pos: np.ndarray, rx_pos: np.ndarray, fid: RayTracingConfig,
              pairs: np.ndarray | None = None) -> RawPaths:
        """Trace every transmitter to every receiver in one PathSolver call, launching
        ``fid.rays_per_source`` rays per source.

        :param tx_pos: [num_tx, 3] float64, m; rx_pos: [num_rx, 3] float64, m
        :param pairs: [num_links, 2] int (tx, rx) indices to return; default all tx x rx pairs
            in row-major (tx, rx) order (then the sources are not padded)
        :returns: one row per returned pair
        """
        scene = self.scene
        if fid.materials != self._materials:
            apply_materials(scene, fid.materials)
            self._materials = fid.materials
        tx_pos = np.atleast_2d(tx_pos)
        rx_pos = np.atleast_2d(rx_pos)
        num_tx = len(tx_pos)
        if pairs is not None and self.pad_sources:
            tx_pos = pad_sources(tx_pos, self._dummy)
        self.last_num_sources = len(tx_pos)
        enumerated = fid.edge_candidates != "sampled" and fid.diffraction and fid.max_depth >= 1
        self._wanted.links = pairs
        buf = solve_buffer(self._wanted, self._stages, scene, tx_pos, rx_pos,
                           max_depth=fid.max_depth,
                           max_num_paths_per_src=self.max_paths_per_src,
                           samples_per_src=fid.rays_per_source, los=fid.los,
                           specular_reflection=fid.specular_reflection,
                           diffuse_reflection=fid.diffuse_reflection,
                           refraction=fid.refraction, diffraction=sampled_diffraction(fid),
                           seed=self.seed)
        raw = _extract(buf, num_tx, len(rx_pos), pairs, self.ports, fid.max_depth)
        if enumerated:
            _, generator = self._edge_solver(fid)
            generator.links = pairs
            buf = solve_buffer(generator, self._stages, scene, tx_pos, rx_pos,
                               max_depth=fid.max_depth,
                               max_num_paths_per_src=10**9, samples_per_src=fid.rays_per_source,
                               los=False, specular_reflection=True, diffuse_reflection=False,
                               refraction=False, diffraction=True, seed=self.seed)
            self.last_num_edge_candidates = generator.last_num_candidates
            raw = raw.merge(_extract(buf, num_tx, len(rx_pos), pairs, self.ports,
                                     fid.max_depth))
        return raw


def solve_buffer(generator, stages: tuple, scene, src: np.ndarray, tgt: np.ndarray, *,
                 max_depth: int,
                 max_num_paths_per_src: int, samples_per_src: int, los: bool,
                 specular_reflection: bool, diffuse_reflection: bool, refraction: bool,
                 diffraction: bool, seed: int):
    """The steps of Sionna RT's ``PathSolver.__call__`` with the candidate ``generator`` and
    ``stages`` (its ImageMethod and FieldCalculator) (synthetic arrays, devices with
    Sionna's default orientation, no edge diffraction, lit region on) from sources ``src``
    to targets ``tgt`` ([n, 3] m) up to its paths buffer, without building its ``Paths``.

    The positions go to Dr.Jit as arrays: Sionna's ``Scene.sources`` writes each device's
    position into its array with a kernel that holds the position (and the device's index)
    as literals, one new kernel per position.

    ``Paths`` scatters the buffer into [rx, tx, path] tensors with index arithmetic on Python
    integers (the call's transmitter and receiver counts and its largest path count per link),
    which Dr.Jit compiles in as literals: one new kernel for almost every call, and again for
    every new drive (docs/performance.md, "Cold start"). :func:`_extract` does that
    scattering in NumPy instead, on the same float32 values.

    :returns: Sionna's PathsBuffer with the valid paths only
    """
    import drjit as dr   # deferred, as Sionna RT (import_sionna selects the Mitsuba variant)
    import mitsuba as mi
    if scene.tx_array is None or scene.rx_array is None:
        raise ValueError("the scene's tx_array and rx_array must be set")
    # float32 as Sionna's device positions; read by the kernels of the caller's _extract too
    keep = [aligned(c, np.float32) for c in (*np.asarray(src).T, *np.asarray(tgt).T)]
    src_pos = mi.Point3f(*(mi.Float(c) for c in keep[:3]))
    tgt_pos = mi.Point3f(*(mi.Float(c) for c in keep[3:]))
    src_ori = dr.zeros(mi.Point3f, len(src))
    tgt_ori = dr.zeros(mi.Point3f, len(tgt))
    dr.make_opaque(src_pos, tgt_pos, src_ori, tgt_ori)
    # the stages in the order of Sionna's PathSolver.__call__ (pinned Sionna RT version)
    image_method, field_calculator = stages
    buf = generator(
        mi_scene=scene.mi_scene, src_positions=src_pos, tgt_positions=tgt_pos,
        samples_per_src=samples_per_src, max_num_paths_per_src=max_num_paths_per_src,
        max_depth=max_depth, los=los, specular_reflection=specular_reflection,
        diffuse_reflection=diffuse_reflection, refraction=refraction, diffraction=diffraction,
        edge_diffraction=False, seed=seed)
    buf.schedule()
    dr.eval()
    buf.shrink()
    buf.detach_geometry()
    buf = image_method(scene=scene.mi_scene, paths=buf, src_positions=src_pos,
                       tgt_positions=tgt_pos, diffraction=diffraction, diffraction_lit_region=True)
    buf = field_calculator(
        wavelength=scene.wavelength, paths=buf, samples_per_src=samples_per_src,
        diffraction=diffraction, src_positions=src_pos, tgt_positions=tgt_pos,
        src_orientations=src_ori, tgt_orientations=tgt_ori,
        src_antenna_patterns=scene.tx_array.antenna_pattern.patterns,
        tgt_antenna_patterns=scene.rx_array.antenna_pattern.patterns)
    buf.discard_invalid()
    buf.keep_alive = keep   # Dr.Jit may alias the arrays; the buffer's kernels read them
    return buf


def sampled_diffraction(fid: RayTracingConfig) -> bool:
    """Whether Sionna's own rays sample diffraction (its random draws) under ``fid``."""
    return fid.diffraction and fid.edge_candidates != "exhaustive"


def polarimetric_arrays(rt) -> tuple:
    """(tx_array, rx_array): one isotropic element with a theta-hat and a phi-hat port each
    (Sionna 'VH' = slant angles 0 and pi/2 under TR 38.901 polarization model-2)."""
    return tuple(rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="VH")
                 for _ in range(2))


def _extract(buf, num_tx: int, num_rx: int, pairs: np.ndarray | None,
             ports: tuple[int, int], max_depth: int) -> RawPaths:
    """Sionna paths buffer (valid paths, :func:`solve_buffer`) -> float64 arrays
    [num_links, num_paths, ...] in (tx, rx) pair order; num_paths is the largest path count of
    a (tx, rx) pair, the shorter rows padded with invalid paths (as Sionna's ``Paths``)."""
    # deferred, as Sionna RT (import_sionna selects the Mitsuba variant)
    import drjit as dr
    from sionna.rt.utils import theta_phi_from_unit_vec
    n = int(buf.buffer_size)
    depth = max(1, max_depth)   # Sionna's interaction depth axis (PathsBuffer)
    if n:
        src = np.asarray(buf.source_indices, np.int64)
        tgt = np.asarray(buf.target_indices, np.int64)
        link = tgt * num_tx + src                         # Sionna's (rx, tx) order
        order = np.argsort(link, kind="stable")
        counts = np.bincount(link, minlength=num_rx * num_tx)
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        rank = np.empty(n, np.int64)
        rank[order] = np.arange(n) - first[link[order]]
        num_paths = int(counts.max())
    else:
        link = rank = np.zeros(0, np.int64)
        num_paths = 0
    shape = (num_rx * num_tx, num_paths)

    def scatter(values, fill, dtype=np.float64, extra=()):
        out = np.full(shape + extra, fill, dtype)
        if n:
            out[link, rank] = values
        return out.reshape((num_rx, num_tx, num_paths) + extra)

    def f32(x):
        return np.asarray(x, np.float32).astype(np.float64)

    if n:
        # Sionna's Paths: a [rx pattern, tx pattern] of Complex2f; angles from the unit vectors
        a_val = np.stack([np.stack([f32(dr.real(v)) + 1j * f32(dr.imag(v)) for v in row], -1)
                          for row in buf.a], -2)       # [n, rx ports, tx ports]
        theta_t, phi_t = theta_phi_from_unit_vec(buf.k_tx)
        theta_r, phi_r = theta_phi_from_unit_vec(buf.k_rx)
        vals = {k: f32(v) for k, v in (("tau", buf.tau), ("theta_t", theta_t),
                                       ("phi_t", phi_t), ("theta_r", theta_r),
                                       ("phi_r", phi_r))}
        inter_val = np.asarray(buf.interaction_types, np.uint8).reshape(n, depth)
    else:
        a_val, inter_val = 0.0, 0
        vals = dict.fromkeys(("tau", "theta_t", "phi_t", "theta_r", "phi_r"), 0.0)
    tau = scatter(vals["tau"], -1.0)
    a = scatter(a_val, 0.0, np.complex128, tuple(ports))    # [R, T, N, rx ports, tx ports]
    valid = scatter(True, False, bool)
    th_t, ph_t = scatter(vals["theta_t"], 0.0), scatter(vals["phi_t"], 0.0)
    th_r, ph_r = scatter(vals["theta_r"], 0.0), scatter(vals["phi_r"], 0.0)
    inter = scatter(inter_val, 0, np.uint8, (depth,))      # [R, T, N, D]
    if pairs is None:
        t_idx, r_idx = np.meshgrid(np.arange(num_tx), np.arange(num_rx), indexing="ij")
        t_idx, r_idx = t_idx.ravel(), r_idx.ravel()
    else:
        t_idx, r_idx = pairs[:, 0], pairs[:, 1]

    def pick(x):
        return x[r_idx, t_idx]

    v = pick(valid)
    raw = RawPaths(tau=np.where(v, pick(tau), -1.0), a=np.where(v[..., None, None], pick(a), 0.0),
                   theta_r=np.where(v, pick(th_r), 0.0), phi_r=np.where(v, pick(ph_r), 0.0),
                   theta_t=np.where(v, pick(th_t), 0.0), phi_t=np.where(v, pick(ph_t), 0.0),
                   interactions=np.where(v[..., None], pick(inter), 0).astype(np.uint8),
                   valid=v)
    return canonical_order(raw)


def canonical_order(raw: RawPaths) -> RawPaths:
    """The paths of each link in one order that depends on the paths only: valid first, then
    by delay, angles, interaction sequence and coefficient.

    Sionna RT numbers a link's paths with atomic counters (``dr.scatter_inc`` in
    ``Paths``), so with several threads the order it returns varies from call to call.
    """
    ports = int(np.prod(raw.a.shape[2:]))
    keys = [np.abs(raw.a).reshape(raw.a.shape[:2] + (ports,))[..., k] for k in range(ports)][::-1]
    keys += [raw.interactions[..., k] for k in range(raw.interactions.shape[2])][::-1]
    keys += [raw.phi_t, raw.theta_t, raw.phi_r, raw.theta_r, raw.tau, ~raw.valid]
    order = np.lexsort(keys, axis=-1)
    return RawPaths(**{f: np.take_along_axis(getattr(raw, f), order.reshape(
        order.shape + (1,) * (getattr(raw, f).ndim - 2)), axis=1) for f in RawPaths.FIELDS})
