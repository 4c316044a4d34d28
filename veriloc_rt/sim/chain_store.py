"""Chain results kept in the run folder, so that a resumed run recomputes none of them.

The first scenario of a run computes, in the attack window, the chains of the later attack
scenarios too (:meth:`~veriloc_rt.sim.runner.ScenarioRunner.compute_chains`); they, and the
benign chains every scenario shares, are most of a run's work. :class:`ChainStore` appends each
point's results to ``chains.bin`` as soon as they exist, and a resumed run reads them back, so
that only the points no chain was computed for are computed again.

File format: an 8-byte magic, the 32-byte SHA-256 of the run's resolved config (a store of
another config is never read), then records, each a big-endian 8-byte length, the 32-byte
SHA-256 of the payload and the payload. A torn or damaged record ends the file: it and
everything after it are dropped (a kill mid-write tears the last record only).

A payload holds one ``{ChainKey: ChainResult}`` dict without ``pickle`` (loading a pickle runs
code): a JSON tree of the structure, where a dataclass is named by its class, which must be a
dataclass of this package, followed by the arrays' raw bytes (dtype, shape and place in the
tree). Floats go through their exact hex text and arrays as raw bytes, so the results read back
are bit for bit the ones computed, and a resumed run writes the same rows as an uninterrupted
one.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib
import json
import logging
import math
import os
import struct
from pathlib import Path

import numpy as np

from ..config import Config, config_to_dict
from ..fileio import naming
from ..inputs import read_bytes

log = logging.getLogger(__name__)

__all__ = ["ChainStore", "encode", "decode", "config_digest"]

#: the format: 2 since the cache keys are :class:`~veriloc_rt.sim.runner.ChainKey` and the
#: results :class:`veriloc_rt.phy.chain.ChainResult` (a store of format 1 starts anew)
MAGIC = b"VLCHAIN2"
_HEAD = struct.Struct(">Q")
_DIGEST = 32
#: largest store read back, bytes
MAX_STORE_BYTES = 1 << 40
#: the package whose dataclasses a payload may name
_PACKAGE = "veriloc_rt."


def config_digest(cfg: Config) -> bytes:
    """SHA-256 of the resolved config (canonical JSON)."""
    return hashlib.sha256(json.dumps(config_to_dict(cfg), sort_keys=True).encode()).digest()


class _Blob(list):
    """The arrays' raw bytes of one payload, in order, with their running length (the offset
    of the next one: summing the lengths at each array made encoding quadratic in the arrays)."""

    size = 0

    def add(self, data: bytes) -> int:
        """Append ``data``; its offset in the payload's blob."""
        offset = self.size
        self.append(data)
        self.size += len(data)
        return offset


def _enc_array(obj, blob: _Blob):
    a = np.asarray(obj)
    if a.dtype.hasobject:
        raise TypeError("object arrays are not stored")
    fortran = bool(a.flags.f_contiguous and not a.flags.c_contiguous)  # as np.save keeps it
    data = (a.T if fortran else a).tobytes()
    offset = blob.add(data)
    return {"a" if isinstance(obj, np.ndarray) else "s":
            [a.dtype.str, list(a.shape), offset, len(data), fortran]}


def _enc_dataclass(obj, blob: _Blob):
    name, fields = _fields(type(obj))
    return {"c": name, "v": {f: _enc(getattr(obj, f), blob) for f in fields}}


@functools.lru_cache(maxsize=None)
def _fields(cls: type) -> tuple[str, tuple[str, ...]]:
    """A dataclass's stored name and its fields' names (looked up once per class: a store
    holds the same few classes in every record)."""
    return f"{cls.__module__}:{cls.__qualname__}", tuple(f.name for f in dataclasses.fields(cls))


def _same(obj, blob: _Blob):
    return obj


#: the node of an object by its exact type (the types of almost every node of a record);
#: other types take :func:`_enc_other`'s checks, which give each type the same node
_ENCODERS = {
    type(None): _same, bool: _same, str: _same,
    int: lambda obj, blob: {"i": str(obj)},
    float: lambda obj, blob: {"f": obj.hex()},
    list: lambda obj, blob: [_enc(x, blob) for x in obj],
    tuple: lambda obj, blob: {"t": [_enc(x, blob) for x in obj]},
    dict: lambda obj, blob: {"d": [[_enc(k, blob), _enc(v, blob)] for k, v in obj.items()]},
    np.ndarray: _enc_array,
}


def _enc(obj, blob: _Blob):
    enc = _ENCODERS.get(type(obj))
    if enc is not None:
        return enc(obj, blob)
    return _enc_other(obj, blob)


def _enc_other(obj, blob: _Blob):
    if isinstance(obj, (np.ndarray, np.generic)):   # first: np.float64 is a float, np.str_ a str
        if type(obj) is not np.ndarray and isinstance(obj, np.generic):
            _ENCODERS[type(obj)] = _enc_array   # a NumPy scalar type: the same node next time
        return _enc_array(obj, blob)
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, int):
        return _ENCODERS[int](obj, blob)
    if isinstance(obj, float):
        return _ENCODERS[float](obj, blob)
    if isinstance(obj, list):
        return _ENCODERS[list](obj, blob)
    if isinstance(obj, tuple):
        return _ENCODERS[tuple](obj, blob)
    if isinstance(obj, dict):
        return _ENCODERS[dict](obj, blob)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        _ENCODERS[type(obj)] = _enc_dataclass   # the same node for the class next time
        return _enc_dataclass(obj, blob)
    raise TypeError(f"cannot store a {type(obj).__name__}")


@functools.lru_cache(maxsize=None)
def _dataclass(name: str) -> tuple[type, frozenset]:
    """The dataclass a payload names and its field names (resolved once per name: a store
    names the same few classes in every record)."""
    module, _, qual = name.partition(":")
    if not module.startswith(_PACKAGE):
        raise ValueError(f"class {name!r} is not of this package")
    obj = importlib.import_module(module)
    for part in qual.split("."):
        obj = getattr(obj, part)
    if not (isinstance(obj, type) and dataclasses.is_dataclass(obj)):
        raise ValueError(f"{name!r} is not a dataclass")
    return obj, frozenset(f.name for f in dataclasses.fields(obj))


@functools.lru_cache(maxsize=None)
def _dtype(dtype_str: str) -> np.dtype:
    return np.dtype(dtype_str)


def _array(spec, blob: bytes) -> np.ndarray:
    dtype_str, shape, offset, size, fortran = spec
    dtype = _dtype(dtype_str)
    if dtype.hasobject:
        raise ValueError("object arrays are not stored")
    shape = tuple(int(n) for n in shape)
    if offset < 0 or offset + size > len(blob) or size != dtype.itemsize * math.prod(shape):
        raise ValueError("array outside the record")
    a = np.frombuffer(blob, dtype, count=size // dtype.itemsize if dtype.itemsize else 0,
                      offset=offset)
    a = a.reshape(shape[::-1]).T if fortran else a.reshape(shape)
    return a.copy(order="K")   # writable, its own memory, the stored layout


def _dec(node, blob: bytes):
    if node is None or isinstance(node, (bool, str)):
        return node
    if isinstance(node, list):
        return [_dec(x, blob) for x in node]
    if "c" in node:
        cls, names = _dataclass(node["c"])
        obj = cls.__new__(cls)   # the fields as stored, past __init__/__post_init__
        if node["v"].keys() != names:
            raise ValueError(f"{node['c']}: fields {sorted(node['v'])}, expected {sorted(names)}")
        for k, v in node["v"].items():
            object.__setattr__(obj, k, _dec(v, blob))
        return obj
    (tag, val), = node.items()
    if tag == "i":
        return int(val)
    if tag == "f":
        return float.fromhex(val)
    if tag == "a":
        return _array(val, blob)
    if tag == "s":
        return _array(val, blob)[()]
    if tag == "t":
        return tuple(_dec(x, blob) for x in val)
    if tag == "d":
        return {_dec(k, blob): _dec(v, blob) for k, v in val}
    raise ValueError(f"unknown node {tag!r}")


def encode(obj) -> bytes:
    """``obj`` (None, bool, int, float, str, NumPy arrays and scalars, lists, tuples, dicts and
    dataclasses of this package, nested) as bytes, without pickle: the length of a JSON tree
    (8 bytes, big-endian), the tree, then the arrays' raw bytes, which the tree locates."""
    blob = _Blob()
    tree = json.dumps(_enc(obj, blob), separators=(",", ":")).encode()
    return b"".join([_HEAD.pack(len(tree)), tree, *blob])


def decode(data: bytes):
    """The object :func:`encode` wrote. Raises ValueError (or KeyError, TypeError) on bad data."""
    (size,) = _HEAD.unpack_from(data, 0)
    start = _HEAD.size + size
    if start > len(data):
        raise ValueError("tree outside the record")
    return _dec(json.loads(data[_HEAD.size:start]), memoryview(data)[start:])


class ChainStore:
    """The chain results of one run folder (module docstring), opened for appending.

    :param path: the store's file (``out/chains.bin``)
    :param digest: :func:`config_digest` of the run's config
    :param resume: read the results already stored (when the file is of this config) and append
        after them; else start an empty store
    """

    def __init__(self, path: str | Path, digest: bytes, resume: bool):
        self.path = Path(path)
        self.digest = digest
        self.loaded: list[dict] = []
        end = self._read() if resume else 0
        with naming(self.path):
            if end:
                self._fh = open(self.path, "r+b")
                self._fh.truncate(end)       # drop a torn or damaged tail
                self._fh.seek(end)
            else:
                self._fh = open(self.path, "wb")
                self._fh.write(MAGIC + digest)
                self._fh.flush()

    def _read(self) -> int:
        """Fill :attr:`loaded`; the offset after the last good record (0: nothing usable)."""
        if not os.path.lexists(self.path):
            return 0
        # non-blocking: a FIFO in its place is an error, not a wait for a writer
        data = read_bytes(self.path, str(self.path), "chain store", MAX_STORE_BYTES)
        head = len(MAGIC) + _DIGEST
        if data[:len(MAGIC)] != MAGIC or data[len(MAGIC):head] != self.digest:
            if data:
                log.warning("%s: not a chain store of this config; starting a new one", self.path)
            return 0
        pos = head
        while pos < len(data):
            rec = pos + _HEAD.size + _DIGEST
            if rec > len(data):
                break
            (size,) = _HEAD.unpack_from(data, pos)
            payload = data[rec:rec + size]
            if len(payload) < size or hashlib.sha256(payload).digest() != data[pos + _HEAD.size:rec]:
                break
            try:
                self.loaded.append(decode(payload))
            except (ValueError, KeyError, TypeError, OSError, AttributeError, ImportError) as exc:
                log.warning("%s: record at byte %d unreadable (%s)", self.path, pos, exc)
                break
            pos = rec + size
        if pos < len(data):
            log.warning("%s: %d bytes after the last complete record dropped (an interrupted "
                        "write); their chains are computed again", self.path, len(data) - pos)
        return pos

    def append(self, results: dict) -> None:
        """Store one point's ``{cache key: ChainResult}`` (flushed at once)."""
        if not results:
            return
        payload = encode(results)
        with naming(self.path):   # a full disk: the torn record is dropped when resumed
            self._fh.write(_HEAD.pack(len(payload)) + hashlib.sha256(payload).digest() + payload)
            self._fh.flush()

    def close(self) -> None:
        """Close the file; what a failed write left unflushed is dropped (a torn record is
        dropped when the store is read)."""
        try:
            self._fh.close()
        except OSError:
            if not self._fh.closed:
                raise

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
