"""Key material of the BSs: generation, key files ("keys files" of VeriLoc) and loading.

One set of files per BS ``<id>`` in a keys directory::

    bs<id>.prs.aes           AES-CTR PRS encryption key, hex (16 or 32 bytes)
    bs<id>.tag.hmac          HMAC-SHA256 tag key, hex (32 bytes, RFC 2104 recommends >= L = 32)
    bs<id>.tag.ed25519.pem   Ed25519 private signing key, PKCS#8 PEM (BS side only)
    bs<id>.tag.ed25519.pub   Ed25519 public key, SubjectPublicKeyInfo PEM (what the UE holds)

A missing, malformed or wrong-type file raises :class:`~veriloc_rt.errors.InputError` naming it.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import ed25519

from ...errors import InputError

log = logging.getLogger(__name__)

HMAC_KEY_BYTES = 32
_HINT = "generate a set with `veriloc-rt keys --out DIR`"


@dataclass(frozen=True)
class BSKeys:
    """Keys of one BS. ``sign_key`` is None where only the public key is known (UE side)."""

    bs_id: int
    aes_key: bytes
    hmac_key: bytes
    verify_key: ed25519.Ed25519PublicKey
    sign_key: ed25519.Ed25519PrivateKey | None = None


def key_paths(keys_dir: str | Path, bs_id: int) -> dict[str, Path]:
    """The four key files of BS ``bs_id``."""
    d = Path(keys_dir)
    return {"aes": d / f"bs{bs_id}.prs.aes", "hmac": d / f"bs{bs_id}.tag.hmac",
            "sign": d / f"bs{bs_id}.tag.ed25519.pem", "verify": d / f"bs{bs_id}.tag.ed25519.pub"}


def _random_bytes(n: int, rng: np.random.Generator | None) -> bytes:
    return os.urandom(n) if rng is None else rng.bytes(n)


def make_keys(bs_id: int, *, aes_bits: int = 128, rng: np.random.Generator | None = None) -> BSKeys:
    """Fresh keys for one BS: from the OS CSPRNG, or from ``rng`` (reproducible simulation only)."""
    if aes_bits not in (128, 256):
        raise ValueError(f"Argument `aes_bits` must be 128 or 256, not {aes_bits}")
    aes = _random_bytes(aes_bits // 8, rng)
    mac = _random_bytes(HMAC_KEY_BYTES, rng)
    sk = ed25519.Ed25519PrivateKey.from_private_bytes(_random_bytes(32, rng))
    return BSKeys(int(bs_id), aes, mac, sk.public_key(), sk)


def simulated_keys(bs_ids: Iterable[int], rng: np.random.Generator, *, aes_bits: int = 128) -> dict[int, BSKeys]:
    """Keys for a run without key files, drawn from ``rng`` (never for real deployments)."""
    return {int(b): make_keys(int(b), aes_bits=aes_bits, rng=rng) for b in bs_ids}


def generate_keys(out_dir: str | Path, bs_ids: Iterable[int], *, aes_bits: int = 128,
                  rng: np.random.Generator | None = None, overwrite: bool = False) -> list[Path]:
    """Write a key set for ``bs_ids`` into ``out_dir`` (created if needed).

    :param rng: None (default) draws from the OS CSPRNG; a Generator makes the set reproducible
    :param overwrite: replace existing files instead of refusing
    :return: the files written
    :raises InputError: if a key file exists and ``overwrite`` is False
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for bs_id in bs_ids:
        keys = make_keys(int(bs_id), aes_bits=aes_bits, rng=rng)
        paths = key_paths(out, keys.bs_id)
        for p in paths.values():
            if p.exists() and not overwrite:
                raise InputError(str(p), "key file exists; refusing to overwrite")
        assert keys.sign_key is not None
        contents = {
            "aes": keys.aes_key.hex() + "\n",
            "hmac": keys.hmac_key.hex() + "\n",
            "sign": keys.sign_key.private_bytes(serialization.Encoding.PEM,
                                                serialization.PrivateFormat.PKCS8,
                                                serialization.NoEncryption()).decode(),
            "verify": keys.verify_key.public_bytes(serialization.Encoding.PEM,
                                                   serialization.PublicFormat.SubjectPublicKeyInfo).decode(),
        }
        for name, text in contents.items():
            p = paths[name]
            p.write_text(text)
            if name in ("aes", "hmac", "sign"):
                p.chmod(0o600)
            written.append(p)
    log.info("wrote %d key files to %s", len(written), out)
    return written


def _read(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise InputError(str(path), f"missing key file ({_HINT})") from None
    except OSError as exc:
        raise InputError(str(path), f"cannot read key file: {exc.strerror}") from None


def load_hex_key(path: str | Path, sizes: tuple[int, ...]) -> bytes:
    """A hex-encoded symmetric key of one of ``sizes`` bytes."""
    p = Path(path)
    text = _read(p).decode("ascii", errors="replace").strip()
    try:
        key = bytes.fromhex(text)
    except ValueError:
        raise InputError(str(p), "malformed key file: expected one line of hex digits") from None
    if len(key) not in sizes:
        raise InputError(str(p), f"wrong key size: got {len(key)} bytes, expected "
                         + " or ".join(map(str, sizes)))
    return key


def load_private_key(path: str | Path) -> ed25519.Ed25519PrivateKey:
    """An Ed25519 private key from a PKCS#8 PEM file."""
    p = Path(path)
    try:
        key = serialization.load_pem_private_key(_read(p), password=None)
    except (ValueError, TypeError) as exc:
        raise InputError(str(p), f"malformed private key file: {str(exc).splitlines()[0]}") from None
    if not isinstance(key, ed25519.Ed25519PrivateKey):
        raise InputError(str(p), f"wrong key type: expected an Ed25519 private key, got {type(key).__name__}")
    return key


def load_public_key(path: str | Path) -> ed25519.Ed25519PublicKey:
    """An Ed25519 public key from a SubjectPublicKeyInfo PEM file."""
    p = Path(path)
    try:
        key = serialization.load_pem_public_key(_read(p))
    except (ValueError, TypeError) as exc:
        raise InputError(str(p), f"malformed public key file: {str(exc).splitlines()[0]}") from None
    if not isinstance(key, ed25519.Ed25519PublicKey):
        raise InputError(str(p), f"wrong key type: expected an Ed25519 public key, got {type(key).__name__}")
    return key


def load_keys(keys_dir: str | Path, bs_ids: Iterable[int], *, private: bool = True) -> dict[int, BSKeys]:
    """Load the key set of ``bs_ids`` from ``keys_dir``.

    :param private: also load the signing keys (BS side); False loads what a UE holds
    :raises InputError: naming the first missing, malformed or wrong-type file
    """
    d = Path(keys_dir)
    if not d.is_dir():
        raise InputError(str(d), f"keys directory does not exist ({_HINT})")
    out: dict[int, BSKeys] = {}
    for bs_id in bs_ids:
        paths = key_paths(d, int(bs_id))
        aes = load_hex_key(paths["aes"], (16, 32))
        mac = load_hex_key(paths["hmac"], (HMAC_KEY_BYTES,))
        pub = load_public_key(paths["verify"])
        sk = load_private_key(paths["sign"]) if private else None
        if sk is not None and sk.public_key().public_bytes_raw() != pub.public_bytes_raw():
            raise InputError(str(paths["verify"]), f"public key does not match {paths['sign'].name}")
        out[int(bs_id)] = BSKeys(int(bs_id), aes, mac, pub, sk)
    return out


def public_view(keys: Mapping[int, BSKeys]) -> dict[int, BSKeys]:
    """The same key set without the signing keys (what a UE is given)."""
    return {b: BSKeys(k.bs_id, k.aes_key, k.hmac_key, k.verify_key, None) for b, k in keys.items()}
