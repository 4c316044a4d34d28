"""The chain store: results read back bit for bit, damage detected, nothing but data loaded."""

import dataclasses
import json
import logging
import struct

import numpy as np
import pytest

from veriloc_rt.config import config_from_dict
from veriloc_rt.sim.chain_store import ChainStore, config_digest, decode, encode
from veriloc_rt.sim.engine import compute_propagation
from veriloc_rt.sim.run_folder import run_keys
from veriloc_rt.sim.runner import ScenarioRunner
from veriloc_rt.world.geometry import build_geometry

CFG = {"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
       "trajectory": {"num_points": 4}, "seed": 5}


def same(a, b, where="") -> None:
    """Equal bit for bit and of the same types, all the way down (NaNs included)."""
    assert type(a) is type(b), f"{where}: {type(a)} vs {type(b)}"
    if isinstance(a, (np.ndarray, np.generic)):
        assert a.dtype == b.dtype and a.shape == b.shape, where
        assert np.asarray(a).tobytes() == np.asarray(b).tobytes(), where
    elif isinstance(a, float):
        assert a.hex() == b.hex(), where
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{where}[{k}]")
    elif isinstance(a, dict):
        assert list(a) == list(b), where
        for k in a:
            same(a[k], b[k], f"{where}[{k!r}]")
    elif dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    else:
        assert a == b, where


@pytest.fixture(scope="module")
def chain_results(tmp_path_factory):
    """Real chain results: a benign point and an attack point (all four scenarios)."""
    cfg = config_from_dict(CFG)
    geo = build_geometry(cfg, tmp_path_factory.mktemp("scene"))
    runner = ScenarioRunner(cfg, geo, compute_propagation(cfg, geo), run_keys(cfg, len(geo.bs_pos)))
    window = cfg.run.attack_points(geo.num_points)
    i = int(np.flatnonzero(window)[0])
    return cfg, runner.compute_chains("none", i)


def test_chain_results_read_back_bit_for_bit(chain_results):
    _, results = chain_results
    assert any(k.scenario is not None for k in results) and any(k.scenario is None for k in results)
    same(decode(encode(results)), results)
    # the corner values JSON would lose: NaN, infinities, -0.0, big integers, numpy scalars
    odd = {("x", 1): [float("nan"), float("-inf"), -0.0, 10**30, np.float32(1.5), np.bool_(True),
                      (None, "s", False), np.asfortranarray(np.arange(6.0).reshape(2, 3)),
                      np.arange(12, dtype=">i4").reshape(3, 4)[:, ::2], np.zeros((0, 3))]}
    back = decode(encode(odd))
    same(back, odd)
    assert back[("x", 1)][7].flags.f_contiguous      # the stored layout, as np.save keeps it


def test_a_store_reads_back_what_was_appended_and_drops_a_torn_tail(tmp_path, chain_results, caplog):
    cfg, results = chain_results
    digest = config_digest(cfg)
    path = tmp_path / "chains.bin"
    with ChainStore(path, digest, resume=False) as store:
        for _ in range(3):
            store.append(results)
    size = path.stat().st_size
    with ChainStore(path, digest, resume=True) as store:
        assert len(store.loaded) == 3
        same(store.loaded[2], results)
    # a kill mid-write: the last record torn
    with open(path, "r+b") as fh:
        fh.truncate(size - 10)
    with caplog.at_level(logging.WARNING), ChainStore(path, digest, resume=True) as store:
        assert len(store.loaded) == 2
        store.append(results)             # continues after the last complete record
    assert "dropped" in caplog.text
    with ChainStore(path, digest, resume=True) as store:
        assert len(store.loaded) == 3


def test_a_damaged_record_ends_the_store(tmp_path, chain_results):
    cfg, results = chain_results
    digest = config_digest(cfg)
    path = tmp_path / "chains.bin"
    with ChainStore(path, digest, resume=False) as store:
        store.append(results)
        first_end = store.path.stat().st_size
        store.append(results)
        store.append(results)
    data = bytearray(path.read_bytes())
    data[first_end + 100] ^= 0x01        # one bit of the second record's payload
    path.write_bytes(bytes(data))
    with ChainStore(path, digest, resume=True) as store:
        assert len(store.loaded) == 1     # the checksum stops it; later records are not trusted


def test_a_store_of_another_config_is_not_read(tmp_path, chain_results):
    cfg, results = chain_results
    path = tmp_path / "chains.bin"
    with ChainStore(path, config_digest(cfg), resume=False) as store:
        store.append(results)
    other = config_digest(cfg.replace(seed=cfg.seed + 1))
    with ChainStore(path, other, resume=True) as store:
        assert store.loaded == []
    with ChainStore(path, other, resume=True) as store:   # and it was started afresh
        assert store.loaded == []


def test_a_payload_cannot_name_a_class_outside_the_package():
    # what a planted payload would do to run code: construct os.system or a foreign class
    for name in ("os:system", "subprocess:Popen", "veriloc_rt.fileio:atomic_output"):
        tree = json.dumps({"c": name, "v": {}}).encode()
        with pytest.raises(ValueError):
            decode(struct.pack(">Q", len(tree)) + tree)
    with pytest.raises(TypeError):
        encode(np.array([object()], dtype=object))
    # nor an object array, nor bytes outside the record
    for spec in (["|O", [1], 0, 8, False], ["<f8", [4], 0, 32, False]):
        tree = json.dumps({"a": spec}).encode()
        with pytest.raises(ValueError):
            decode(struct.pack(">Q", len(tree)) + tree + bytes(8))
