"""Key material of the BSs: generation, key files ("keys files" of VeriLoc) and loading.

One set of files per BS ``<id>`` in a keys directory::

    bs<id>.prs.aes           AES-CTR PRS encryption key: ``aes-128 bs<id> <hex>`` (or aes-256)
    bs<id>.tag.hmac          HMAC-SHA256 tag key: ``hmac-sha256 bs<id> <hex>`` (32 bytes, RFC
                             2104 recommends >= L = 32)
    bs<id>.tag.ed25519.pem   Ed25519 private signing key, PKCS#8 PEM (BS side only)
    bs<id>.tag.ed25519.pub   Ed25519 public key, SubjectPublicKeyInfo PEM (what the UE holds)

The label in front of a symmetric key names its kind and its BS, so an AES file swapped with an
HMAC file of the same length (AES-256), or with another BS's, is refused; a bare hex line (files
of earlier versions) is still read, without that check. The secret keys are written 0600, all
files of a set or none (:func:`generate_keys`), and ``repr(BSKeys)`` shows no key material.

A missing, malformed or wrong-type file raises :class:`~veriloc_rt.errors.InputError` naming it.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from cryptography.exceptions import UnsupportedAlgorithm
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import ed25519

from ...errors import InputError, short_repr
from ...inputs import check_path, read_bytes

log = logging.getLogger(__name__)

HMAC_KEY_BYTES = 32
#: label of an HMAC key file
HMAC_KIND = "hmac-sha256"
#: largest key file read, bytes (a PEM key is ~120 bytes)
MAX_KEY_FILE_BYTES = 64 << 10
_HINT = "generate a set with `veriloc-rt keys --out DIR`"


@dataclass(frozen=True)
class BSKeys:
    """Keys of one BS. ``sign_key`` is None where only the public key is known (UE side)."""

    bs_id: int
    aes_key: bytes = field(repr=False)
    hmac_key: bytes = field(repr=False)
    verify_key: ed25519.Ed25519PublicKey
    sign_key: ed25519.Ed25519PrivateKey | None = field(default=None, repr=False)


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


def _key_line(kind: str, bs_id: int, key: bytes) -> str:
    """One symmetric key file's content: ``<kind> bs<id> <hex>`` (see the module docstring)."""
    return f"{kind} bs{bs_id} {key.hex()}\n"


def generate_keys(out_dir: str | Path, bs_ids: Iterable[int], *, aes_bits: int = 128,
                  rng: np.random.Generator | None = None, overwrite: bool = False) -> list[Path]:
    """Write a key set for ``bs_ids`` into ``out_dir`` (created if needed), all or none.

    Every file is created with its final mode (0600 for the secret keys, 0644 for the public
    key: never readable by others, not even for a moment) under a temporary name, and the files
    are renamed into place only after every one of them is written; a failure removes the
    temporary files and leaves ``out_dir`` as it was.

    :param rng: None (default) draws from the OS CSPRNG; a Generator makes the set reproducible
    :param overwrite: replace existing files instead of refusing
    :return: the files written
    :raises InputError: if a key file exists and ``overwrite`` is False (before writing any)
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(str(out), "exists and is not a folder")
    sets = [make_keys(int(b), aes_bits=aes_bits, rng=rng) for b in bs_ids]
    files: list[tuple[Path, bytes, int]] = []
    for keys in sets:
        paths = key_paths(out, keys.bs_id)
        assert keys.sign_key is not None
        contents = {
            "aes": _key_line(f"aes-{8 * len(keys.aes_key)}", keys.bs_id, keys.aes_key),
            "hmac": _key_line(HMAC_KIND, keys.bs_id, keys.hmac_key),
            "sign": keys.sign_key.private_bytes(serialization.Encoding.PEM,
                                                serialization.PrivateFormat.PKCS8,
                                                serialization.NoEncryption()).decode(),
            "verify": keys.verify_key.public_bytes(serialization.Encoding.PEM,
                                                   serialization.PublicFormat.SubjectPublicKeyInfo).decode(),
        }
        for name, text in contents.items():
            if os.path.lexists(paths[name]) and not overwrite:
                raise InputError(str(paths[name]), "key file exists; refusing to overwrite")
            files.append((paths[name], text.encode("ascii"), 0o644 if name == "verify" else 0o600))
    staged: list[tuple[Path, Path]] = []
    try:
        out.mkdir(parents=True, exist_ok=True)
        for path, data, mode in files:
            tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                         mode)
            staged.append((tmp, path))
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        for tmp, path in staged:
            os.replace(tmp, path)
    except OSError as exc:
        for tmp, _ in staged:
            if os.path.lexists(tmp):
                tmp.unlink()
        raise InputError(str(out), f"cannot write key files ({exc.strerror})") from None
    written = [path for path, _, _ in files]
    log.info("wrote %d key files to %s", len(written), out)
    return written


def _read(path: Path) -> bytes:
    if not os.path.lexists(path):
        raise InputError(str(path), f"missing key file ({_HINT})")
    return read_bytes(path, str(path), "key file", MAX_KEY_FILE_BYTES)


def load_hex_key(path: str | Path, sizes: tuple[int, ...], kinds: tuple[str, ...] = (),
                 bs_id: int | None = None) -> bytes:
    """A symmetric key of one of ``sizes`` bytes: ``<kind> bs<id> <hex>`` or bare hex.

    :param kinds: the labels accepted for this file (``aes-128``, ``hmac-sha256``); a labelled
        file of another kind (an HMAC key in the AES file) is an error
    :param bs_id: the BS the file must be labelled with
    """
    p = Path(path)
    text = _read(p).decode("ascii", errors="replace")
    tokens = text.split()
    if len(tokens) == 3:
        kind, owner, hex_text = tokens
        if kinds and kind not in kinds:
            raise InputError(str(p), f"holds a {short_repr(kind)} key, expected "
                             + " or ".join(kinds) + " (files swapped?)")
        if bs_id is not None and owner != f"bs{bs_id}":
            raise InputError(str(p), f"holds the key of {short_repr(owner)}, expected bs{bs_id}")
    elif len(tokens) == 1:
        kind, hex_text = None, tokens[0]
    else:
        raise InputError(str(p), "malformed key file: expected one line '<kind> bs<id> <hex>' "
                         "or hex digits")
    try:
        key = bytes.fromhex(hex_text)
    except ValueError:
        raise InputError(str(p), "malformed key file: expected hex digits") from None
    if kind is not None and kind.startswith("aes-") and kind[4:].isdigit() \
            and len(key) * 8 != int(kind[4:]):
        raise InputError(str(p), f"labelled {kind} but holds {len(key)} bytes")
    if len(key) not in sizes:
        raise InputError(str(p), f"wrong key size: got {len(key)} bytes, expected "
                         + " or ".join(map(str, sizes)))
    return key


def load_private_key(path: str | Path) -> ed25519.Ed25519PrivateKey:
    """An Ed25519 private key from a PKCS#8 PEM file."""
    p = Path(path)
    data = _read(p)
    try:
        key = serialization.load_pem_private_key(data, password=None)
    except (ValueError, TypeError, UnsupportedAlgorithm) as exc:
        raise InputError(str(p), f"malformed private key file: {str(exc).splitlines()[0]}") from None
    if not isinstance(key, ed25519.Ed25519PrivateKey):
        raise InputError(str(p), f"wrong key type: expected an Ed25519 private key, got {type(key).__name__}")
    return key


def load_public_key(path: str | Path) -> ed25519.Ed25519PublicKey:
    """An Ed25519 public key from a SubjectPublicKeyInfo PEM file."""
    p = Path(path)
    data = _read(p)
    try:
        key = serialization.load_pem_public_key(data)
    except (ValueError, TypeError, UnsupportedAlgorithm) as exc:
        raise InputError(str(p), f"malformed public key file: {str(exc).splitlines()[0]}") from None
    if not isinstance(key, ed25519.Ed25519PublicKey):
        raise InputError(str(p), f"wrong key type: expected an Ed25519 public key, got {type(key).__name__}")
    return key


def load_keys(keys_dir: str | Path, bs_ids: Iterable[int], *, private: bool = True,
              aes_bits: int | None = None) -> dict[int, BSKeys]:
    """Load the key set of ``bs_ids`` from ``keys_dir``.

    :param private: also load the signing keys (BS side); False loads what a UE holds
    :param aes_bits: the AES key size the run uses (``security.aes_key_bits``); None: 128 or 256
    :raises InputError: naming the first missing, malformed or wrong-type file
    """
    d = check_path(keys_dir, "security.keys_dir")
    if not d.is_dir():
        raise InputError(str(d), f"keys directory does not exist ({_HINT})")
    out: dict[int, BSKeys] = {}
    for bs_id in bs_ids:
        paths = key_paths(d, int(bs_id))
        aes = load_hex_key(paths["aes"], (16, 32), ("aes-128", "aes-256"), int(bs_id))
        if aes_bits is not None and 8 * len(aes) != aes_bits:
            raise InputError(str(paths["aes"]), f"a {8 * len(aes)}-bit AES key, but "
                             f"security.aes_key_bits is {aes_bits}")
        mac = load_hex_key(paths["hmac"], (HMAC_KEY_BYTES,), (HMAC_KIND,), int(bs_id))
        pub = load_public_key(paths["verify"])
        sk = load_private_key(paths["sign"]) if private else None
        if sk is not None and sk.public_key().public_bytes_raw() != pub.public_bytes_raw():
            raise InputError(str(paths["verify"]), f"public key does not match {paths['sign'].name}")
        out[int(bs_id)] = BSKeys(int(bs_id), aes, mac, pub, sk)
    return out


def public_view(keys: Mapping[int, BSKeys]) -> dict[int, BSKeys]:
    """The same key set without the signing keys (what a UE is given)."""
    return {b: BSKeys(k.bs_id, k.aes_key, k.hmac_key, k.verify_key, None) for b, k in keys.items()}
