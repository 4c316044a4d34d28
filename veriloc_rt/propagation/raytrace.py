"""Ray-traced CIRs for every link a run uses, batched and cached on disk.

Links traced (and nothing else):

* serving BS -> UE, per trajectory point and serving slot (topology.num_trps per point);
* serving BS -> adversary (what a meaconer receives), per point;
* adversary -> UE, per point.

The uplink (UE -> BS) is the reciprocal of the downlink and is never traced. Identical links
(same ends to the millimetre, e.g. the adversary standing where the UE stood) are traced once.

A PathSolver call traces several sources to the union of their targets when every interaction
of its sampled rays is deterministic (line of sight and specular reflections, the default with
the exhaustive edge candidates): a link's paths then depend only on its two ends and the
fidelity, not on what else the call traces. When Sionna draws interactions at random (its
sampled diffraction, diffuse reflection or refraction), it draws them from one seeded sequence
over all of a call's rays, so each call then has one source and its targets
(docs/convergence.md has the measurements).

In ``direction='reciprocal'`` (the default) rays are launched from the street-level end of each
link (UE or adversary) and the result is reversed by reciprocity (reciprocal materials: same
delays, arrival and departure angles swapped, and the 2x2 polarimetric path coefficient
transposed, so any antenna polarization at either end is then applied in the physical
direction; :mod:`~veriloc_rt.propagation.polarization`). In a
canyon the roof edges that carry almost every BS link are a few metres from the UE, so they are
sampled densely by few rays, whereas rays launched from a BS hundreds of metres away must be
counted in millions to hit them.

The cache (``raytrace.cache_dir``) holds one ``.npz`` per PathSolver call, named by a hash of
everything that decides its result, with a checksum over that key and the arrays
(:func:`entry_checksum`). An entry that fails it or holds non-finite values is never used: it
is moved aside into ``quarantine/`` with a warning and the call is traced again
(:func:`read_cache_entry`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import multiprocessing
import os
import signal
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Callable

import numpy as np

from ..config import PropagationConfig, RayTracingConfig
from ..config.fields import to_dict
from ..constants import SPEED_OF_LIGHT
from ..fileio import atomic_output
from ..world.scene.export import scene_digest
from .cir import ADVERSARY_TX, CIR, INTERACTION_NONE, NO_TX, array_response, doppler_shift, ula_element_positions
from .sionna_rt import RawPaths, sampled_diffraction

log = logging.getLogger(__name__)

#: Bump when the cached array layout or the tracing recipe changes (8: entries carry a checksum)
CACHE_VERSION = 10

#: RayTracingConfig fields that do not change what a PathSolver call returns (the cache holds
#: polarimetric paths; antenna polarizations are applied after it)
_NOT_IN_KEY = ("cache_dir", "work_per_call", "polarization")

#: Sources per PathSolver call when the sampled rays draw nothing at random (a bound on the
#: padding of one call's arrays; work_per_call bounds the rest)
MAX_SOURCES_PER_CALL = 150

#: Traced (source, target) pairs per call: Sionna sizes its candidate buffer by
#: max_candidates_per_source x pairs
MAX_PAIRS_PER_CALL = 256

#: Share of a call's traced pairs that must be wanted when the unwanted ones are dropped before
#: refinement (their cost is the visibility tests of the shared rays)
MIN_EFFICIENCY_FILTERED = 1 / 8

#: Uncached links a trace needs before it is spread over several processes: each process
#: imports Sionna RT and loads the scene first, seconds that only a longer job recovers
PARALLEL_MIN_LINKS = 300

Progress = Callable[[int, int], None]


def deterministic_rays(fid: RayTracingConfig) -> bool:
    """Whether Sionna's sampled rays draw no interaction at random: then a link's paths do not
    depend on the other sources of its call."""
    return not (sampled_diffraction(fid) or fid.diffuse_reflection or fid.refraction)


@dataclass(frozen=True, eq=False)
class Propagation:
    """Every link of a run.

    bs_ue : CIR [num_points, num_trps] serving BS -> UE at the UE's ULA (slot 0 is the RSTD reference)
    bs_adv : CIR [num_points, num_trps] the same BSs -> the adversary (single antenna)
    adv_ue : CIR [num_points, 1] adversary -> UE at the UE's ULA
    """

    bs_ue: CIR
    bs_adv: CIR
    adv_ue: CIR
    stats: dict = field(default_factory=dict)


def _key(pos: np.ndarray) -> np.ndarray:
    """Millimetre-rounded integer keys of positions. [n, 3] -> [n, 3] int64"""
    return np.round(np.asarray(pos, dtype=float) * 1000.0).astype(np.int64)


def _unique_rows(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows in order of first appearance -> (first index per unique, inverse)."""
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return first[order], rank[inverse.ravel()]


def plan_calls(src_id: np.ndarray, dst_id: np.ndarray, per_pair_work: int,
               work_per_call: int, max_sources: int = MAX_SOURCES_PER_CALL,
               min_efficiency: float = 0.25,
               max_pairs: int = MAX_PAIRS_PER_CALL) -> list[np.ndarray]:
    """Split links (in the given order) into PathSolver calls.

    A call traces every one of its sources to every one of its targets, so its work is
    ``per_pair_work * num_sources * num_targets``. Links are added while that stays within
    ``work_per_call``, the call has at most ``max_sources`` sources and ``max_pairs`` traced
    pairs (Sionna sizes its candidate buffer by them) and at least
    ``min_efficiency`` of the traced pairs are wanted: consecutive UE points with the same serving
    BSs (or one BS and many UEs) share a call, while point-to-point links go in small calls of at
    most 1/min_efficiency links. :class:`LinkTracer` uses ``max_sources=1`` (one source and its
    targets per call) where the rays draw interactions at random (the module docstring says why).

    :returns: list of index arrays into the links
    """
    calls, cur, srcs, dsts = [], [], set(), set()
    for i, (s, d) in enumerate(zip(src_id.tolist(), dst_id.tolist())):
        ns, nd = len(srcs | {s}), len(dsts | {d})
        if cur and (per_pair_work * ns * nd > work_per_call or ns > max_sources
                    or ns * nd > max_pairs or (len(cur) + 1) < min_efficiency * ns * nd):
            calls.append(np.array(cur))
            cur, srcs, dsts = [], set(), set()
        cur.append(i)
        srcs.add(s)
        dsts.add(d)
    if cur:
        calls.append(np.array(cur))
    return calls


class LinkTracer:
    """Traces arbitrary (source, target) position pairs with one fidelity, using the cache.

    :param scene_xml: scene to load (lazily, on the first cache miss)
    :param cache_dir: folder for cached calls (None: no cache)
    """

    def __init__(self, scene_xml: str | Path, fc: float, fid: RayTracingConfig, seed: int,
                 cache_dir: str | Path | None):
        self.scene_xml = Path(scene_xml)
        self.fc = fc
        self.fid = fid
        self.seed = seed
        self.cache_dir = Path(cache_dir) / "raytrace" if cache_dir else None
        self._tracer = None
        self._base_key = None
        self.stats = {"calls": 0, "cache_hits": 0, "links_traced": 0, "trace_s": 0.0}

    def sionna_tracer(self):
        """The :class:`~veriloc_rt.propagation.sionna_rt.SionnaTracer`, created (scene loaded)
        on the first call; a benchmark calls it first to keep scene loading out of its timing."""
        if self._tracer is None:
            from .sionna_rt import SionnaTracer
            self._tracer = SionnaTracer(self.scene_xml, self.fc, self.seed,
                                        self.fid.diffraction_coefficient)
        return self._tracer

    def call_key(self, src: np.ndarray, dst: np.ndarray, pairs: np.ndarray) -> str:
        """Cache key of one PathSolver call: a hash of the cache version, the scene's digest,
        the carrier, every fidelity field that changes the traced paths, the seed, the Sionna
        RT / Mitsuba / Dr.Jit versions, the ray count (``rays_per_source``, hashed once more
        after the rest, as the keys of earlier versions did) and the call's positions and
        pairs.

        :param src, dst: [num_src, 3], [num_dst, 3] float64, m
        :param pairs: [num_links, 2] int (source, target) indices
        :returns: 32 hexadecimal digits
        """
        if self._base_key is None:
            fid = {k: v for k, v in to_dict(self.fid).items() if k not in _NOT_IN_KEY}
            versions = {p: metadata.version(p) for p in ("sionna-rt", "mitsuba", "drjit")}
            self._base_key = json.dumps({"v": CACHE_VERSION, "scene": scene_digest(self.scene_xml),
                                         "fc": self.fc, "fid": fid, "seed": self.seed,
                                         "versions": versions}, sort_keys=True)
        h = hashlib.sha256(self._base_key.encode())
        h.update(str(self.fid.rays_per_source).encode())
        for a in (_key(src), _key(dst), pairs.astype(np.int64)):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()[:32]

    def trace(self, src: np.ndarray, dst: np.ndarray, progress: Progress | None = None,
              workers: int = 1, reduce: Reducer | None = None) -> RawPaths:
        """Paths from ``src[i]`` (Sionna source) to ``dst[i]`` (Sionna target) for every i,
        ``fid.rays_per_source`` rays per source.

        :param src, dst: [num_links, 3] float64, m
        :param workers: processes tracing the calls the cache does not hold, when they hold at
            least PARALLEL_MIN_LINKS links (each call's result depends only on its own inputs,
            so the result is the same for any number)
        :param reduce: applied to the links' paths chunk by chunk of links
            (:func:`reduced_rows`) instead of to all of them at once: what a run keeps of a link
            (its strongest paths) is then all that is held for every link
        :returns: RawPaths with one row per link, in Sionna's source -> target orientation
        """
        if len(src) == 0:   # nothing to trace (e.g. an adversary that is never active)
            empty = RawPaths.empty(0, max(self.fid.max_depth, 1))
            return empty if reduce is None else reduce(empty, np.arange(0))
        src_first, src_id = _unique_rows(_key(src))
        dst_first, dst_id = _unique_rows(_key(dst))
        pair_keys = np.stack([src_id, dst_id], axis=1)
        pair_first, pair_inv = _unique_rows(pair_keys)
        u_src, u_dst = src_id[pair_first], dst_id[pair_first]
        order = np.lexsort((u_dst, u_src))
        per_pair = max(self.fid.max_depth, 1) * self.fid.rays_per_source
        # one source per call where Sionna draws interactions at random (module docstring);
        # otherwise unwanted pairs cost little (their candidates are dropped before they are
        # refined), so point-to-point links share calls too
        batched = deterministic_rays(self.fid)
        calls = plan_calls(u_src[order], u_dst[order], per_pair, self.fid.work_per_call,
                           max_sources=MAX_SOURCES_PER_CALL if batched else 1,
                           min_efficiency=MIN_EFFICIENCY_FILTERED if batched else 0.25)
        results: list[RawPaths | None] = [None] * len(pair_first)
        done = 0
        total = len(pair_first)

        def finish(links: np.ndarray, raw: RawPaths) -> None:
            nonlocal done
            for j, li in enumerate(links):
                results[li] = _row(raw, j)
            done += len(links)
            if progress:
                progress(round(done * len(src) / total), len(src))

        todo = []
        for call in calls:
            links = order[call]
            cs, cs_inv = np.unique(u_src[links], return_inverse=True)
            cd, cd_inv = np.unique(u_dst[links], return_inverse=True)
            pairs = np.stack([cs_inv.ravel(), cd_inv.ravel()], axis=1)
            s_pos, d_pos = src[src_first[cs]], dst[dst_first[cd]]
            key = self.call_key(s_pos, d_pos, pairs) if self.cache_dir else None
            cached = self._cached(key, len(pairs))
            if cached is not None:
                finish(links, cached)
            else:
                todo.append((links, s_pos, d_pos, pairs, key))
        procs = min(workers, len(todo)) \
            if sum(len(t[3]) for t in todo) >= PARALLEL_MIN_LINKS else 1
        self.stats["processes"] = max(procs, self.stats.get("processes", 1))
        jobs = [(s_pos, d_pos, pairs) for _, s_pos, d_pos, pairs, _ in todo]
        computed = (_trace_in_processes(self, jobs, procs) if procs > 1
                    else ((k, *self._compute(*job)) for k, job in enumerate(jobs)))
        for k, raw, seconds in computed:
            links, _, _, pairs, key = todo[k]
            self.stats["trace_s"] += seconds
            self.stats["calls"] += 1
            self.stats["links_traced"] += len(pairs)
            if key:
                write_cache_entry(self.cache_dir / f"{key}.npz", key, raw)
            finish(links, raw)
        if reduce is not None:
            return reduced_rows(results, pair_inv, reduce)
        merged = RawPaths.concat(results) if results else None
        return _take(merged, pair_inv)

    def _cached(self, key: str | None, num_links: int) -> RawPaths | None:
        """The cache's result of a call (None: no cache, or not in it)."""
        if not key:
            return None
        cached = read_cache_entry(self.cache_dir / f"{key}.npz", key, num_links)
        if cached is not None:
            self.stats["cache_hits"] += 1
        return cached

    def _compute(self, s_pos: np.ndarray, d_pos: np.ndarray,
                 pairs: np.ndarray) -> tuple[RawPaths, float]:
        """One PathSolver call, traced here. -> (paths, seconds)"""
        t0 = time.perf_counter()
        tracer = self.sionna_tracer()
        tracer.max_paths_per_src = min(self.fid.max_candidates_per_source * len(d_pos), 10**6)
        raw = tracer.trace(s_pos, d_pos, self.fid, pairs=pairs)
        return raw, time.perf_counter() - t0


#: The LinkTracer of a tracing process (:func:`_trace_in_processes`)
_PROCESS_TRACER: LinkTracer | None = None


def _start_tracing_process(scene_xml: str, fc: float, fid: RayTracingConfig, seed: int,
                           threads: int) -> None:
    """Initializer of a tracing process: its own tracer (no cache: the parent writes it), its
    share of the cores for Dr.Jit, and Ctrl-C left to the parent (which terminates it)."""
    global _PROCESS_TRACER
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from ..backend import import_sionna
    import_sionna()
    import drjit as dr
    dr.set_thread_count(threads)
    _PROCESS_TRACER = LinkTracer(scene_xml, fc, fid, seed, cache_dir=None)


def _trace_job(job: tuple) -> tuple:
    k, args = job
    return (k, *_PROCESS_TRACER._compute(*args))


def _trace_in_processes(tracer: LinkTracer, jobs: list[tuple], procs: int):
    """Yield (job index, paths, seconds) of PathSolver calls ``jobs`` (their
    :meth:`LinkTracer._compute` arguments), traced by ``procs`` new processes, as they finish.

    The processes are spawned, not forked (a fork would copy Dr.Jit's threads and LLVM state),
    each loads the scene once; they are terminated if the caller stops (Ctrl-C, an error).
    """
    threads = max(1, (os.cpu_count() or 1) // procs)
    log.info("ray tracing: %d calls in %d processes", len(jobs), procs)
    pool = multiprocessing.get_context("spawn").Pool(
        procs, initializer=_start_tracing_process,
        initargs=(str(tracer.scene_xml), tracer.fc, tracer.fid, tracer.seed, threads))
    try:
        yield from pool.imap_unordered(_trace_job, list(enumerate(jobs)))
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()


def entry_checksum(key: str, arrays: dict[str, np.ndarray]) -> np.ndarray:
    """SHA-256 of a cache entry: its key (so an entry copied under another key fails) and
    every :attr:`RawPaths.FIELDS` array's dtype, shape and bytes. -> [32] uint8"""
    h = hashlib.sha256(key.encode())
    for f in RawPaths.FIELDS:
        a = np.ascontiguousarray(arrays[f])
        h.update(f"{f}:{a.dtype.str}:{a.shape}".encode())
        h.update(a.tobytes())
    return np.frombuffer(h.digest(), np.uint8)


def write_cache_entry(path: Path, key: str, raw: RawPaths) -> None:
    """Store ``raw`` with its :func:`entry_checksum`, atomically; a cache that cannot be
    written costs the next run a trace, not this one: a warning."""
    arrays = raw.to_npz()
    try:
        with atomic_output(path) as tmp:
            np.savez(tmp, checksum=entry_checksum(key, arrays), **arrays)
    except OSError as exc:
        log.warning("ray-tracing cache: cannot write %s (%s); continuing without it", path, exc)


def _verified(data, key: str, num_links: int) -> RawPaths | str:
    """A loaded cache entry's paths, or what is wrong with it."""
    missing = [f for f in (*RawPaths.FIELDS, "checksum") if f not in data.files]
    if missing:
        return f"missing {', '.join(missing)}"
    arrays = {f: data[f] for f in RawPaths.FIELDS}
    if not np.array_equal(data["checksum"], entry_checksum(key, arrays)):
        return "checksum mismatch"
    raw = RawPaths.from_npz(arrays)
    if raw.num_links != num_links:
        return f"{raw.num_links} links, expected {num_links}"
    v = raw.valid
    if not (all(np.all(np.isfinite(x[v])) for x in (raw.tau, raw.a, raw.theta_r, raw.phi_r,
                                                       raw.theta_t, raw.phi_t))
            and np.all(raw.tau[v] >= 0)):
        return "non-finite or negative values in valid paths"
    return raw


def read_cache_entry(path: Path, key: str, num_links: int) -> RawPaths | None:
    """The verified cache entry at ``path`` (None: none, or damaged).

    A damaged entry (unreadable, truncated, a checksum that does not match its content and key,
    the wrong number of links, NaNs or negative delays in valid paths) is moved aside into
    ``quarantine/`` next to it, with a warning, and the caller traces the call again.
    """
    if not path.is_file():
        return None
    try:
        with open(path, "rb") as fh:   # closed here whatever np.load makes of it
            data = np.load(fh, allow_pickle=False)
            if not hasattr(data, "files"):
                found = "not an .npz archive"
            else:
                with data:
                    found = _verified(data, key, num_links)
    except Exception as exc:  # noqa: BLE001 - any damage (zip, zlib, header, EOF) is a miss
        found = f"unreadable: {type(exc).__name__}: {exc}"
    if isinstance(found, RawPaths):
        return found
    problem = found
    quarantine = path.parent / "quarantine"
    dest = quarantine / f"{path.stem}.{int(time.time())}.{os.getpid()}.npz"
    try:
        quarantine.mkdir(exist_ok=True)
        os.replace(path, dest)
        where = f"moved to {dest}"
    except OSError as exc:
        where = f"could not be moved aside ({exc})"
    log.warning("ray-tracing cache: %s is damaged (%s); %s, tracing the call again",
                path, problem, where)
    return None


#: a function of (the paths of some links, those links' row indices) -> what is kept of them
Reducer = Callable[[RawPaths, np.ndarray], RawPaths]
#: links whose paths :func:`reduced_rows` lays out at once
REDUCE_CHUNK_LINKS = 512


def reduced_rows(rows: list[RawPaths], index: np.ndarray, reduce: Reducer,
                 chunk: int = REDUCE_CHUNK_LINKS) -> RawPaths:
    """``reduce`` of ``RawPaths.concat([rows[i] for i in index])`` taken chunk by chunk of
    ``chunk`` links and the reduced chunks concatenated: the same rows as ``reduce`` of the
    whole when ``reduce`` works row by row, since every chunk is laid out as the whole would be
    (padded to the widest row's paths and the deepest row's interactions, the rows' types). The
    whole held several gigabytes on 1200 points of 6 TRPs (links of up to 2154 paths, of
    which a CIR keeps 32).
    """
    depth = max((r.interactions.shape[2] for r in rows), default=1)
    width = max((r.tau.shape[1] for r in rows), default=1)
    like = rows[0] if rows else RawPaths.empty(0, depth)
    layout = {f: np.zeros((0, width) + getattr(like, f).shape[2:], getattr(like, f).dtype)
              for f in RawPaths.FIELDS}                 # no row: the width and the types
    layout = RawPaths(**dict(layout, interactions=np.zeros((0, width, depth), np.uint8)))
    parts = []
    for start in range(0, len(index), chunk):
        idx = np.asarray(index[start:start + chunk])
        part = RawPaths.concat([layout] + [rows[i] for i in idx])
        parts.append(reduce(part, np.arange(start, start + len(idx))))
    if not parts:
        return reduce(layout, np.arange(0))
    return RawPaths.concat(parts)


def _row(raw: RawPaths, j: int) -> RawPaths:
    return RawPaths(**{f: getattr(raw, f)[j:j + 1] for f in RawPaths.FIELDS})


def _scatter(raw: RawPaths, idx: np.ndarray, n: int) -> RawPaths:
    """Rows of ``raw`` placed at ``idx`` of ``n`` rows; the other rows hold no path."""
    out = {}
    for f in RawPaths.FIELDS:
        x = getattr(raw, f)
        full = np.zeros((n,) + x.shape[1:], dtype=x.dtype)
        if f == "tau":
            full[:] = -1.0
        full[idx] = x
        out[f] = full
    return RawPaths(**out)


def _slots(points: np.ndarray, t: int) -> np.ndarray:
    """Rows of the ``t`` serving links of each of ``points`` in a [num_points * t] array."""
    return np.repeat(points, t) * t + np.tile(np.arange(t), len(points))


def _take(raw: RawPaths, idx: np.ndarray) -> RawPaths:
    return RawPaths(**{f: getattr(raw, f)[idx] for f in RawPaths.FIELDS})


def trace_links(tracer: LinkTracer, tx: np.ndarray, rx: np.ndarray, reciprocal: bool,
                progress: Progress | None = None, workers: int = 1,
                reduce: Reducer | None = None) -> RawPaths:
    """Physical tx -> rx links; with ``reciprocal`` the rays start at the receiver (the
    tracer's ``fid.rays_per_source`` rays per source).

    :returns: RawPaths in the physical orientation: ``theta_r/phi_r`` at the receiver,
        ``theta_t/phi_t`` at the transmitter, ``a`` indexed (receiver port, transmitter port)
        (reversed paths: the transposed polarimetric matrix, Lorentz reciprocity)
    """
    if reduce is None:
        return tracer.trace(tx, rx, progress, workers) if not reciprocal \
            else _physical(tracer.trace(rx, tx, progress, workers))
    if not reciprocal:
        return tracer.trace(tx, rx, progress, workers, reduce=reduce)
    return tracer.trace(rx, tx, progress, workers,
                        reduce=lambda part, rows: reduce(_physical(part), rows))


def _physical(rev: RawPaths) -> RawPaths:
    """Paths traced from the receiver, in the physical orientation (:func:`trace_links`)."""
    return RawPaths(tau=rev.tau, a=np.swapaxes(rev.a, 2, 3), theta_r=rev.theta_t, phi_r=rev.phi_t,
                    theta_t=rev.theta_r, phi_t=rev.phi_r,
                    interactions=_reverse_interactions(rev.interactions), valid=rev.valid)


def _reverse_interactions(inter: np.ndarray) -> np.ndarray:
    """Reverse each path's interaction sequence (its used prefix). [..., depth] uint8"""
    depth = inter.shape[-1]
    k = np.count_nonzero(inter != INTERACTION_NONE, axis=-1)[..., None]
    j = np.arange(depth)
    src = np.where(j < k, k - 1 - j, j)
    return np.take_along_axis(inter, src, axis=-1)


def build_cir(raw: RawPaths, shape: tuple[int, int], tx_index: np.ndarray, tx_pos: np.ndarray,
              rx_pos: np.ndarray, v_tx: np.ndarray, v_rx: np.ndarray, fc: float,
              element_pos: np.ndarray | None, max_paths: int) -> CIR:
    """Physical-orientation raw links (row-major over ``shape`` = (points, slots)) -> CIR.

    :param raw: single-port links (:meth:`RawPaths.project`)
    :param element_pos: [num_ant, 3] receive array element offsets (None: one antenna)
    :param v_tx: [P, T, 3] m/s; v_rx: [P, 3] m/s
    """
    if raw.a.shape[2:] != (1, 1):
        raise ValueError(f"build_cir needs single-port paths (RawPaths.project), not ports "
                         f"{raw.a.shape[2:]}")
    raw = raw.keep_strongest(max_paths)
    P, T = shape
    if raw.tau.shape[1] == 0:   # no link has a path (e.g. no diffraction in a deep canyon):
        raw = RawPaths.empty(raw.num_links, max(raw.interactions.shape[-1], 1), (1, 1))  # one slot
    n = raw.tau.shape[1]

    def g(x):
        return x.reshape((P, T) + x.shape[1:])

    tau, a, valid = g(raw.tau), g(raw.a[..., 0, 0]), g(raw.valid)
    aoa_az, aoa_zen, aod_az, aod_zen = g(raw.phi_r), g(raw.theta_r), g(raw.phi_t), g(raw.theta_t)
    lam = SPEED_OF_LIGHT / fc
    if element_pos is None:
        gains = a[:, :, None, :]
    else:
        gains = a[:, :, None, :] * array_response(aoa_az, aoa_zen, element_pos, lam)
    gains = np.where(valid[:, :, None, :], gains, 0.0)
    dop = np.where(valid, doppler_shift(aoa_az, aoa_zen, aod_az, aod_zen, v_rx, v_tx, lam), 0.0)
    inter = g(raw.interactions)
    los = np.any(valid & np.all(inter == INTERACTION_NONE, axis=-1), axis=-1)
    return CIR(delays=np.where(valid, tau, -1.0), gains=gains.astype(np.complex128),
               aoa_az=aoa_az, aoa_zen=aoa_zen, aod_az=aod_az, aod_zen=aod_zen, doppler=dop,
               interactions=inter, valid=valid, tx_index=np.asarray(tx_index, dtype=np.int64),
               tx_pos=tx_pos, rx_pos=rx_pos, los=los, carrier_frequency=fc,
               meta={"model": "raytrace", "num_paths_kept": n})


def trace(geometry, cfg: PropagationConfig, seed: int, progress: Progress | None = None,
          cache_dir: str | Path | None = "default",
          adversary_points: np.ndarray | None = None,
          ue_points: np.ndarray | None = None, workers: int = 1) -> Propagation:
    """Ray-trace every link of ``geometry`` (a :class:`~veriloc_rt.world.geometry.Geometry`).

    :param adversary_points: [num_points] bool, points at which the adversary transmits or
        listens (default: all); adversary links elsewhere are left empty (``NO_TX``)
    :param ue_points: [num_points] bool, points whose serving BS -> UE links are traced
        (default: all); the others are left without a path (a study of a subset of points)

    :param cache_dir: "default" uses ``cfg.raytrace.cache_dir``; None disables the cache
    :param progress: called as ``progress(links_done, links_total)``
    :param workers: tracing processes for a long job (:meth:`LinkTracer.trace`)
    """
    fid = cfg.raytrace
    if cache_dir == "default":
        cache_dir = fid.cache_dir or None
    fc = cfg.carrier_frequency_hz
    ue, adv, serving, bs_pos = geometry.ue, geometry.adversary, geometry.serving, geometry.bs_pos
    P = ue.num_points
    tracer = LinkTracer(geometry.scene_xml, fc, fid, seed, cache_dir)
    recip = fid.direction == "reciprocal"
    lam = SPEED_OF_LIGHT / fc
    arr = cfg.ue_array
    elem = ula_element_positions(arr.num_elements, arr.spacing_wavelengths * lam,
                                 np.deg2rad(arr.axis_azimuth_deg))
    bs_tx = bs_pos[serving]                      # [P, T, 3], T TRPs per point
    T = serving.shape[1]
    zeros_v = np.zeros(bs_tx.shape)
    # one planning pass over all links so progress covers the whole job
    active = np.ones(P, bool) if adversary_points is None else np.asarray(adversary_points, bool)
    if active.shape != (P,):
        raise ValueError(f"`adversary_points` must have shape ({P},), not {active.shape}")
    act = np.flatnonzero(active)
    ue_on = np.ones(P, bool) if ue_points is None else np.asarray(ue_points, bool)
    if ue_on.shape != (P,):
        raise ValueError(f"`ue_points` must have shape ({P},), not {ue_on.shape}")
    on = np.flatnonzero(ue_on)
    # every link in one pass: a source's calls hold all its targets (the adversary stands where
    # the UE stood, so its BS links share the UE's sources)
    k, n, m = T * len(on), T * P, T * len(act)
    tx_links = np.concatenate([bs_tx[on].reshape(-1, 3), bs_tx[act].reshape(-1, 3), adv.pos[act]])
    rx_links = np.concatenate([np.repeat(ue.pos[on], T, axis=0),
                               np.repeat(adv.pos[act], T, axis=0), ue.pos[act]])
    total = len(tx_links)
    cb = (lambda done, _n: progress(done, total)) if progress else None
    t0 = time.perf_counter()
    # antenna polarizations in the physical direction (receiver port, transmitter port)
    pol = fid.polarization
    bs_p, ue_p, adv_p = pol.bs, pol.ue, pol.adversary_polarization()
    mp = fid.max_paths_per_link
    # what a CIR keeps of a link (its ports' coefficient, its strongest paths), taken chunk by
    # chunk of links as they are laid out (the three sets of links have their own ports)
    ends = np.array([k, k + m])
    ports = ((ue_p, bs_p), (adv_p, bs_p), (ue_p, adv_p))

    def keep(part: RawPaths, rows: np.ndarray) -> RawPaths:
        group = np.searchsorted(ends, rows, side="right")
        kept = [_take(part, np.flatnonzero(group == g)).project(*ports[g]).keep_strongest(mp)
                for g in range(3) if np.any(group == g)]
        if not kept:
            return part.project(ue_p, bs_p).keep_strongest(mp)
        return _take(RawPaths.concat(kept), np.argsort(np.argsort(group, kind="stable")))

    raw = trace_links(tracer, tx_links, rx_links, recip, cb, workers, keep)
    raw_bs_ue = _scatter(_take(raw, np.arange(k)), _slots(on, T), n)
    raw_bs_adv = _scatter(_take(raw, np.arange(k, k + m)), _slots(act, T), n)
    raw_adv = _scatter(_take(raw, np.arange(k + m, total)), act, P)
    adv_slot = np.where(active[:, None], serving, NO_TX)
    bs_ue = build_cir(raw_bs_ue, (P, T), serving, bs_tx, ue.pos, zeros_v, ue.vel, fc, elem, mp)
    bs_adv = build_cir(raw_bs_adv, (P, T), adv_slot, bs_tx, adv.pos, zeros_v, adv.vel, fc, None, mp)
    adv_ue = build_cir(raw_adv, (P, 1), np.where(active, ADVERSARY_TX, NO_TX)[:, None],
                       adv.pos[:, None, :], ue.pos, adv.vel[:, None, :], ue.vel, fc, elem, mp)
    stats = dict(tracer.stats, wall_s=time.perf_counter() - t0, links=total, bs_links=n + m,
                 adversary_links=len(act))
    log.info("ray tracing: %d links, %d calls (%d from cache), %.1f s tracing",
             stats["links"], stats["calls"], stats["cache_hits"], stats["trace_s"])
    return Propagation(bs_ue=bs_ue, bs_adv=bs_adv, adv_ue=adv_ue, stats=stats)
