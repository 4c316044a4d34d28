"""trace(): link bookkeeping, CIR assembly, cache, and Doppler against Sionna's own."""

import numpy as np
import pytest

from veriloc_rt.config import config_from_dict
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.propagation.cir import ADVERSARY_TX, NO_TX, doppler_shift
from veriloc_rt.propagation.raytrace import MAX_SOURCES_PER_CALL, plan_calls, trace
from veriloc_rt.propagation.sionna_rt import (dummy_source_position, pad_sources,
                                             padded_source_count)
from veriloc_rt.world.geometry import build_geometry

from .rt_scenes import ground, write_test_scene

TINY = {"seed": 3,
        "scene": {"extent_m": 140.0, "margin_m": 30.0},
        "trajectory": {"num_points": 14, "region_m": 70.0},
        "propagation": {"raytrace": {"rays_per_source": 3000, "max_depth": 2}}}


def test_plan_calls_bounds_work_and_targets():
    src = np.repeat(np.arange(10), 3)
    dst = np.tile(np.arange(3), 10)
    calls = plan_calls(src, dst, per_pair_work=10, work_per_call=300)  # <= 30 pairs per call
    assert sum(len(c) for c in calls) == 30
    for c in calls:
        assert len(set(src[c])) * len(set(dst[c])) * 10 <= 300
    # point-to-point links: a call of n links traces n x n pairs; efficiency >= 1/4 -> n <= 4
    calls = plan_calls(np.arange(10), np.arange(10), 1, 10**9, min_efficiency=0.25)
    assert [len(c) for c in calls] == [4, 4, 2]
    # one source (a BS, forward mode) to many targets: all pairs wanted, one call
    calls = plan_calls(np.zeros(50, int), np.arange(50), 1, 10**9)
    assert len(calls) == 1
    # Sionna's candidate buffer grows with the traced pairs: at most max_pairs of them a call
    calls = plan_calls(np.repeat(np.arange(40), 3), np.tile(np.arange(3), 40), 1, 10**9,
                       max_pairs=30)
    assert [len(c) for c in calls] == [30, 30, 30, 30]



def test_call_source_counts_are_bucketed():
    """Dr.Jit compiles a PathSolver call's source count into its kernels, so a call is padded
    to one of a few counts (docs/performance.md, "Cold start"): another drive's calls, with
    other counts, then reuse the kernels. The counts listed here are the ladder itself
    (powers of two to 128, then multiples of 64); at most 2n - 1 sources (memory)."""
    n = np.arange(1, MAX_SOURCES_PER_CALL + 1)
    padded = np.array([padded_source_count(int(k)) for k in n])
    assert sorted(set(padded.tolist())) == [1, 2, 4, 8, 16, 32, 64, 128, 192]
    assert np.all(padded >= n) and np.all(padded <= 2 * n - 1)
    assert padded_source_count(200) == 256 and padded_source_count(257) == 320
    with pytest.raises(ValueError, match="`n`"):
        padded_source_count(0)
    # the calls of two drives of 3 serving links a point, with their own source counts,
    # are padded to counts of the ladder: 11 and 14 sources are traced as 16
    src = np.repeat(np.arange(30), 3)
    dst = (np.repeat(np.arange(30), 3) // 7 + np.tile(np.arange(3), 30))
    counts = [len(set(src[c].tolist())) for c in plan_calls(src, dst, 1, 10**9, max_pairs=45)]
    assert len(set(counts)) > 1
    assert {padded_source_count(k) for k in counts} <= {1, 2, 4, 8, 16, 32, 64, 128, 192}


def test_pad_sources_appends_dummies_far_below_the_scene():
    """The real sources keep their rows (their indices in the call's pairs); the dummies stand
    DUMMY_SOURCE_DISTANCE scene diagonals below the scene."""
    rng = np.random.default_rng(0)
    src = rng.uniform(-100, 100, (5, 3))
    lo, hi = np.array([-300.0, -300.0, 0.0]), np.array([300.0, 300.0, 40.0])
    dummy = dummy_source_position(lo, hi)
    diag = np.sqrt(600.0 ** 2 + 600.0 ** 2 + 40.0 ** 2)
    assert np.allclose(dummy, [0.0, 0.0, -100.0 * diag])
    out = pad_sources(src, dummy)
    assert out.shape == (8, 3)
    assert np.array_equal(out[:5], src) and np.array_equal(out[5:], np.tile(dummy, (3, 1)))
    assert pad_sources(src[:4], dummy).shape == (4, 3)

@pytest.mark.raytrace
def test_trace_tiny_canyon_and_cache(tmp_path):
    cfg = config_from_dict(TINY)
    geo = build_geometry(cfg, tmp_path / "scene")
    active = np.zeros(geo.num_points, bool)
    active[5:] = True
    first = trace(geo, cfg.propagation, cfg.seed, cache_dir=tmp_path / "cache",
                  adversary_points=active)
    P = geo.num_points
    assert first.bs_ue.delays.shape[:2] == (P, 3) and first.bs_ue.num_ant == 5
    assert first.bs_adv.num_ant == 1 and first.adv_ue.num_ant == 5
    assert np.array_equal(first.bs_ue.tx_index, geo.serving)
    assert np.all(first.adv_ue.tx_index[:5] == NO_TX) and np.all(first.adv_ue.tx_index[5:] == ADVERSARY_TX)
    assert not first.adv_ue.valid[:5].any() and not first.bs_adv.valid[:5].any()
    assert first.bs_ue.has_path().mean() > 0.5
    # delays are absolute: no path arrives before the straight line allows (float32: 1 ps)
    cir = first.bs_ue
    excess = np.where(cir.valid, cir.delays - cir.geometric_delay()[..., None], 0.0)
    assert excess.min() >= -1e-12
    # a LoS adversary link's first path is the straight line
    a = first.adv_ue
    los = a.los[:, 0]
    assert los.any()
    assert np.allclose(a.first_path_delay()[los, 0], a.geometric_delay()[los, 0], atol=1e-12)
    assert first.stats["calls"] > 0
    again = trace(geo, cfg.propagation, cfg.seed, cache_dir=tmp_path / "cache",
                  adversary_points=active)
    assert again.stats["calls"] == 0 and again.stats["cache_hits"] == first.stats["calls"]
    for name in ("bs_ue", "bs_adv", "adv_ue"):
        x, y = getattr(first, name), getattr(again, name)
        for f in ("delays", "gains", "doppler", "valid", "aoa_az"):
            assert np.array_equal(getattr(x, f), getattr(y, f))


@pytest.mark.raytrace
@pytest.mark.parametrize("edge_candidates", ["exhaustive", "both"])
def test_a_links_paths_do_not_depend_on_the_other_links_traced(tmp_path, edge_candidates):
    """A UE's links traced with the whole drive's (many sources a PathSolver call, the
    default's deterministic rays) or alone are bit-identical, and so are the links of a run that
    traces the adversary at every point or only at some (point-to-point links sharing calls,
    the unwanted pairs' candidates dropped before refinement); with Sionna's sampled diffraction
    ('both') each call has one source, and the same holds."""
    from veriloc_rt.propagation.raytrace import LinkTracer, trace_links

    cfg = config_from_dict(TINY | {"propagation": {"raytrace": TINY["propagation"]["raytrace"]
                                                   | {"edge_candidates": edge_candidates}}})
    geo = build_geometry(cfg, tmp_path / "scene")
    fid = cfg.propagation.raytrace
    tracer = LinkTracer(geo.scene_xml, cfg.propagation.carrier_frequency_hz, fid, cfg.seed, None)
    tx = geo.bs_pos[geo.serving].reshape(-1, 3)
    rx = np.repeat(geo.ue.pos, 3, axis=0)
    every = trace_links(tracer, tx, rx, True)
    sources = len(np.unique(geo.ue.pos.round(3), axis=0))
    if edge_candidates == "exhaustive":   # batched: the test compares batched with alone
        assert tracer.stats["calls"] < sources / 2
    else:
        assert tracer.stats["calls"] == sources
    for i in (0, geo.num_points // 2, geo.num_points - 1):
        alone = trace_links(tracer, tx[3 * i:3 * i + 3], rx[3 * i:3 * i + 3], True)
        for j in range(3):   # the valid paths (the padding follows the longest link traced)
            v, w = every.valid[3 * i + j], alone.valid[j]
            assert v.sum() == w.sum() > 0, (i, j)
            for f in ("tau", "a", "phi_r", "theta_r"):
                assert np.array_equal(getattr(every, f)[3 * i + j][v], getattr(alone, f)[j][w]), (i, j, f)
    some = np.zeros(geo.num_points, bool)
    some[geo.num_points // 2:] = True
    full = trace(geo, cfg.propagation, cfg.seed, cache_dir=None)
    part = trace(geo, cfg.propagation, cfg.seed, cache_dir=None, adversary_points=some)
    for name, rows in (("bs_ue", slice(None)), ("bs_adv", some), ("adv_ue", some)):
        x, y = getattr(full, name), getattr(part, name)
        for f in ("delays", "gains", "valid", "aoa_az"):
            assert np.array_equal(getattr(x, f)[rows], getattr(y, f)[rows]), (name, f)


@pytest.mark.raytrace
def test_tracing_in_processes_gives_the_serial_result(tmp_path, monkeypatch):
    """Calls spread over two spawned tracing processes: every array and every cache entry is
    bit-identical to the serial trace's (each call's result depends only on its inputs), and
    the calls are the same ones."""
    import veriloc_rt.propagation.raytrace as rtmod

    # the schema's smallest calls: 16 pairs (max_depth x rays = 6000 each), so there are several
    fid = TINY["propagation"]["raytrace"]
    cfg = config_from_dict(TINY | {"propagation": {"raytrace": fid | {"work_per_call": 100_000}}})
    geo = build_geometry(cfg, tmp_path / "scene")
    serial = trace(geo, cfg.propagation, cfg.seed, cache_dir=tmp_path / "c1")
    monkeypatch.setattr(rtmod, "PARALLEL_MIN_LINKS", 0)   # the tiny job is spread too
    par = trace(geo, cfg.propagation, cfg.seed, cache_dir=tmp_path / "c2", workers=2)
    assert serial.stats["processes"] == 1 and par.stats["processes"] == 2
    assert par.stats["calls"] == serial.stats["calls"] > 1
    for name in ("bs_ue", "bs_adv", "adv_ue"):
        x, y = getattr(serial, name), getattr(par, name)
        for f in ("delays", "gains", "doppler", "valid", "aoa_az", "interactions"):
            assert np.array_equal(getattr(x, f), getattr(y, f)), (name, f)
    entries = sorted(p.name for p in (tmp_path / "c1" / "raytrace").glob("*.npz"))
    assert entries == sorted(p.name for p in (tmp_path / "c2" / "raytrace").glob("*.npz"))
    for e in entries:
        a, b = (np.load(tmp_path / c / "raytrace" / e) for c in ("c1", "c2"))
        with a, b:
            assert all(np.array_equal(a[k], b[k]) for k in a.files)


@pytest.mark.raytrace
def test_doppler_matches_sionna(tmp_path):
    """Our Doppler from arrival/departure angles and velocities vs Sionna's own (moving tx and
    rx over ground: LoS and reflection). Sionna's is float32: 1e-3 Hz at ~50 Hz shifts."""
    from veriloc_rt.backend import import_sionna

    rt = import_sionna()
    xml = write_test_scene(tmp_path, {"ground": ground()})
    scene = rt.load_scene(str(xml))
    scene.frequency = 3.5e9
    for side in ("tx_array", "rx_array"):
        setattr(scene, side, rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V"))
    v_tx, v_rx = np.array([3.0, -1.0, 0.0]), np.array([-8.0, 5.0, 0.0])
    scene.add(rt.Transmitter("tx", position=[0.0, 0.0, 20.0], velocity=v_tx.tolist()))
    scene.add(rt.Receiver("rx", position=[60.0, 25.0, 1.5], velocity=v_rx.tolist()))
    paths = rt.PathSolver(deterministic=True)(scene, max_depth=1, samples_per_src=100_000)
    valid = np.asarray(paths.valid).reshape(-1)
    get = lambda x: np.asarray(x, dtype=float).reshape(-1)[valid][None, None, :]
    ours = doppler_shift(get(paths.phi_r), get(paths.theta_r), get(paths.phi_t),
                         get(paths.theta_t), v_rx[None], v_tx[None, None], SPEED_OF_LIGHT / 3.5e9)
    theirs = get(paths.doppler)
    assert valid.sum() == 2
    assert np.allclose(ours, theirs, atol=1e-3 + 1e-5 * np.abs(theirs).max())


@pytest.mark.raytrace
def test_trace_with_adversary_never_active(tmp_path):
    """No active adversary point (a run of the 'none' scenario only, the fidelity bench): the
    adversary links are empty rather than an error (was: AttributeError on None.tau)."""
    cfg = config_from_dict(dict(TINY, trajectory={"num_points": 3, "region_m": 70.0}))
    geo = build_geometry(cfg, tmp_path / "scene")
    prop = trace(geo, cfg.propagation, cfg.seed, cache_dir=None,
                 adversary_points=np.zeros(geo.num_points, bool))
    assert np.all(prop.adv_ue.tx_index == NO_TX) and not prop.adv_ue.valid.any()
    assert not prop.bs_adv.valid.any()
    assert prop.bs_ue.delays.shape[:2] == (3, 3) and prop.stats["adversary_links"] == 0
    # a subset of points (the fidelity bench): their serving links as in the full trace, the
    # other points' links without a path
    some = np.array([True, False, True])
    part = trace(geo, cfg.propagation, cfg.seed, cache_dir=None,
                 adversary_points=np.zeros(geo.num_points, bool), ue_points=some)
    assert part.stats["links"] == 6 and not part.bs_ue.valid[~some].any()
    for f in ("delays", "gains", "valid", "aoa_az"):
        assert np.array_equal(getattr(part.bs_ue, f)[some], getattr(prop.bs_ue, f)[some]), f


@pytest.mark.raytrace
def test_no_path_anywhere_gives_a_usable_cir(tmp_path):
    """With every interaction switched off but LoS, in a canyon whose BSs are all hidden, no
    link has a path: the CIR keeps one invalid path slot per link (was: zero slots, and the
    chain failed on an empty minimum) and the chain reports a service failure."""
    from veriloc_rt.sim.run_folder import run_keys
    from veriloc_rt.studies.diagnostics import benign_chain

    cfg = config_from_dict(dict(TINY, trajectory={"num_points": 3, "region_m": 70.0},
                                propagation={"raytrace": {"rays_per_source": 1000, "max_depth": 1,
                                                          "specular_reflection": False,
                                                          "diffraction": False}}))
    geo = build_geometry(cfg, tmp_path / "scene")
    prop = trace(geo, cfg.propagation, cfg.seed, cache_dir=None,
                 adversary_points=np.zeros(geo.num_points, bool))
    cir = prop.bs_ue
    if cir.valid.any():
        pytest.skip("a BS is in line of sight in this draw")
    assert cir.delays.shape == (3, 3, 1) and np.all(cir.delays == -1.0)
    b = benign_chain(cfg, geo, cir, run_keys(cfg, len(geo.bs_pos)), np.arange(3))
    assert not np.isfinite(b.pos).any() and not b.decisions[:, 0].any()


def _random_rows(rng, n: int, depth: int) -> list:
    """``n`` single-link RawPaths as calls return them: float32 angles, 2x2 ports, each its own
    width (1-40 path slots), some slots invalid (tau -1, zeros), some paths coupling only H to H
    (a V-V projection drops them and keeps their angles), interactions up to ``depth``."""
    from veriloc_rt.propagation.sionna_rt import RawPaths

    rows = []
    for _ in range(n):
        w = int(rng.integers(1, 41))
        valid = rng.random((1, w)) < 0.7
        tau = np.where(valid, rng.random((1, w)) * 1e-6, -1.0)
        a = (rng.normal(size=(1, w, 2, 2)) + 1j * rng.normal(size=(1, w, 2, 2))) * valid[..., None, None]
        hh = rng.random(w) < 0.3             # paths a V-V link does not couple: dropped, angles kept
        a[0, hh, 0, :] = 0
        a[0, hh, :, 0] = 0
        ang = {f: np.where(valid, rng.random((1, w)), 0.0).astype(np.float32)
               for f in ("theta_r", "phi_r", "theta_t", "phi_t")}
        inter = (rng.integers(0, 4, (1, w, depth)) * valid[..., None]).astype(np.uint8)
        rows.append(RawPaths(tau=tau, a=a.astype(np.complex64), interactions=inter, valid=valid, **ang))
    return rows


@pytest.mark.parametrize("chunk", [1, 7, 64, 1000])
def test_reduced_rows_equal_the_reduction_of_all_rows_bit_for_bit(chunk):
    """The links' paths reduced chunk by chunk (what a run keeps: each set's ports, its strongest
    paths) are the reduction of all of them at once, field for field and bit for bit: a chunk
    is laid out as the whole (width, depth, types), the reduction works row by row. Reference:
    the whole laid out by ``RawPaths.concat`` and taken by index, as before the chunks."""
    from veriloc_rt.propagation.raytrace import reduced_rows
    from veriloc_rt.propagation.sionna_rt import RawPaths

    rng = np.random.default_rng(5)
    rows = _random_rows(rng, 60, depth=4)
    index = rng.integers(0, 60, 150)                  # links sharing a traced pair, any order
    ports = (("V", "V"), ("H", "+45"), ("-45", "V"))

    def keep(part, idx):                              # a different reduction per third of the links
        g = np.minimum(idx // 50, 2)
        out = [part.project(*ports[k]).keep_strongest(8) for k in range(3)]
        return RawPaths(**{f: np.concatenate([getattr(out[g[i]], f)[i:i + 1] for i in range(len(idx))])
                           if len(idx) else getattr(out[0], f) for f in RawPaths.FIELDS})

    whole = RawPaths.concat(rows)
    whole = RawPaths(**{f: getattr(whole, f)[index] for f in RawPaths.FIELDS})
    ref = keep(whole, np.arange(len(index)))
    got = reduced_rows(rows, index, keep, chunk=chunk)
    for f in RawPaths.FIELDS:
        x, y = getattr(ref, f), getattr(got, f)
        assert x.dtype == y.dtype and x.shape == y.shape, f
        assert np.array_equal(x, y), f
