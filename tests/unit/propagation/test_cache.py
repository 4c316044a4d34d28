"""The ray-tracing cache as issue #19 found it: a truncated, bit-flipped or swapped entry
crashed every later run (BadZipFile, EOFError, IndexError), and another valid entry or NaNs
copied over one were used silently. Now each is quarantined and the call traced again.

Reference: the paths the same LinkTracer traced into the empty cache. A re-trace of a call
repeats the same rays on the same scene; Sionna RT computes in float32, so the re-traced
values are compared within float32 resolution (:data:`RETRACE_RTOL`)."""

from __future__ import annotations

import logging
import shutil

import numpy as np
import pytest

from veriloc_rt.config import RayTracingConfig
from veriloc_rt.propagation.raytrace import LinkTracer, entry_checksum, read_cache_entry
from veriloc_rt.propagation.sionna_rt import RawPaths

from .rt_scenes import boxes, ground, write_test_scene

pytestmark = pytest.mark.raytrace

#: relative tolerance between a call traced twice: a few float32 ulps (2**-23 ~ 1.2e-7)
RETRACE_RTOL = 1e-6
FC = 3.5e9
RAYS = 2000
#: two calls: a BS to two UEs, and another BS to one of them
CALLS = {"a": (np.array([[0.0, 0.0, 25.0]] * 2), np.array([[90.0, 10.0, 1.5], [140.0, -30.0, 1.5]])),
         "b": (np.array([[-80.0, 40.0, 25.0]]), np.array([[90.0, 10.0, 1.5]]))}


@pytest.fixture(scope="module")
def traced(tmp_path_factory):
    """A tracer, a cache holding the two calls, and their paths."""
    root = tmp_path_factory.mktemp("cache")
    xml = write_test_scene(root / "scene", {"ground": ground(),
                                            "block": boxes([[30, -20, 60, 0]], [20.0])})
    fid = RayTracingConfig(max_depth=1, diffraction=False, refraction=False, rays_per_source=RAYS)
    tracer = LinkTracer(xml, FC, fid, 1, root / "pristine")
    ref = {k: tracer.trace(s, d) for k, (s, d) in CALLS.items()}
    files = sorted((root / "pristine" / "raytrace").glob("*.npz"))
    assert tracer.stats["calls"] == 2 and len(files) == 2
    return tracer, root / "pristine", ref


def truncate(f, other):
    data = f.read_bytes()
    f.write_bytes(data[:len(data) // 2])


def flip_bit(f, other):
    """One bit of the path gains' bytes (a flip in the archive's padding changes nothing)."""
    data = bytearray(f.read_bytes())
    with np.load(f) as z:
        a = z["a"].tobytes()
    at = data.find(a)
    assert at > 0
    data[at + len(a) // 2] ^= 0x10
    f.write_bytes(bytes(data))


def swap(f, other):
    shutil.copyfile(other, f)


def nans_checksummed(f, other):
    """NaNs in every valid path, with a checksum that matches them (a poisoned but consistent
    entry: only the values give it away)."""
    with np.load(f) as z:
        arrays = {k: z[k].copy() for k in RawPaths.FIELDS}
    arrays["tau"][arrays["valid"]] = np.nan
    arrays["a"][arrays["valid"]] = np.nan
    np.savez(f, checksum=entry_checksum(f.stem, arrays), **arrays)


def nans(f, other):
    with np.load(f) as z:
        arrays = {k: z[k].copy() for k in (*RawPaths.FIELDS, "checksum")}
    arrays["tau"][:] = np.nan
    np.savez(f, **arrays)


@pytest.mark.parametrize("damage", [truncate, flip_bit, swap, nans, nans_checksummed],
                         ids=lambda f: f.__name__)
def test_a_damaged_entry_is_quarantined_and_traced_again(traced, tmp_path, caplog, damage):
    tracer, pristine, ref = traced
    cache = tmp_path / "cache"
    shutil.copytree(pristine, cache)
    tracer.cache_dir = cache / "raytrace"
    target, other = (cache / "raytrace" / f"{k}.npz" for k in _names(cache))
    damage(target, other)
    calls, hits = tracer.stats["calls"], tracer.stats["cache_hits"]
    s, d = CALLS["a"]
    with caplog.at_level(logging.WARNING):
        got = tracer.trace(s, d)
    assert tracer.stats["calls"] == calls + 1 and tracer.stats["cache_hits"] == hits
    assert "is damaged" in caplog.text and target.name in caplog.text
    assert len(list((cache / "raytrace" / "quarantine").iterdir())) == 1
    want = ref["a"]
    assert np.array_equal(got.valid, want.valid)
    np.testing.assert_allclose(got.tau[got.valid], want.tau[want.valid], rtol=RETRACE_RTOL)
    np.testing.assert_allclose(np.abs(got.a), np.abs(want.a), rtol=RETRACE_RTOL, atol=0)
    # the re-traced entry replaced it: the next look-up is a hit again
    again = tracer.trace(s, d)
    assert tracer.stats["calls"] == calls + 1 and tracer.stats["cache_hits"] == hits + 1
    assert np.array_equal(again.tau, got.tau)


def _names(cache) -> tuple[str, str]:
    """Cache keys of call 'a' and call 'b' (told apart by their number of links)."""
    by_links = {}
    for f in (cache / "raytrace").glob("*.npz"):
        with np.load(f) as z:
            by_links[z["tau"].shape[0]] = f.stem
    return by_links[len(CALLS["a"][1])], by_links[len(CALLS["b"][1])]


def test_an_intact_entry_reads_back_exactly(traced):
    tracer, pristine, ref = traced
    key_a, _ = _names(pristine)
    got = read_cache_entry(pristine / "raytrace" / f"{key_a}.npz", key_a, len(CALLS["a"][1]))
    for f in RawPaths.FIELDS:
        assert np.array_equal(getattr(got, f), getattr(ref["a"], f))
