"""Key material of the BSs: generation, key files ("keys files" of VeriLoc) and loading.

One set of files per BS ``<id>`` in a keys directory::

    bs<id>.prs.aes           AES-CTR PRS encryption key: ``aes-128 bs<id> <hex>`` (or aes-256)
    bs<id>.tag.hmac          HMAC-SHA256 tag key: ``hmac-sha256 bs<id> <hex>`` (32 bytes, RFC
                             2104 recommends >= L = 32)
    bs<id>.tag.ed25519.pem   Ed25519 private signing key, PKCS#8 PEM (BS side only)
    bs<id>.tag.ed25519.pub   Ed25519 public key, SubjectPublicKeyInfo PEM (what the UE holds)

The label in front of a symmetric key names its kind and its BS, so an AES file swapped with an
HMAC file of the same length (AES-256), or with another BS's, is refused; a bare hex line (files
of earlier versions) is still read, without that check. A set is written all files or none, in
a folder of mode 0700 it creates, each file 0600 (:func:`generate_keys`), and ``repr(BSKeys)``
shows no key material. Loading refuses a world-writable key file (or folder) and warns about
secret key material others may read; a byte-order mark in front of a file's text is dropped.

A missing, malformed or wrong-type file raises :class:`~veriloc_rt.errors.InputError` naming it.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import secrets
import shutil
import stat
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from cryptography.exceptions import UnsupportedAlgorithm
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import ed25519

from ...errors import InputError, short_repr
from ...fileio import TMP_MARK, exchange_folders
from ...inputs import check_path, decode_text, read_bytes

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


#: the names of key files (:func:`key_paths`)
_KEY_NAME = re.compile(r"bs[0-9]+\.(prs\.aes|tag\.hmac|tag\.ed25519\.pem|tag\.ed25519\.pub)")
def _link_or_copy(src: str, dst: str) -> None:
    """``dst`` the same file as ``src`` (a hard link), or a copy where links are refused; never
    over an existing ``dst`` (:class:`FileExistsError`)."""
    try:
        os.link(src, dst, follow_symlinks=False)
    except FileExistsError:
        raise
    except OSError:
        if os.path.islink(src):
            os.symlink(os.readlink(src), dst)
            return
        fd = os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                     stat.S_IMODE(os.stat(src).st_mode))
        with os.fdopen(fd, "wb") as fh, open(src, "rb") as source:
            shutil.copyfileobj(source, fh)


def _write_new(path: Path, data: bytes) -> None:
    """Create ``path`` 0600 (never readable by others, not even for a moment) with ``data``,
    synced to disk."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                 0o600)
    with os.fdopen(fd, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


def generate_keys(out_dir: str | Path, bs_ids: Iterable[int], *, aes_bits: int = 128,
                  rng: np.random.Generator | None = None, overwrite: bool = False) -> list[Path]:
    """Write a key set for ``bs_ids`` into ``out_dir``, all or none.

    Every file is created 0600 in a temporary folder next to ``out_dir`` (mode 0700) and synced;
    only then does the set take its place, in one step:

    * ``out_dir`` missing: the temporary folder is renamed to it (so it is created 0700);
    * ``out_dir`` holding none of the set's files: each file is linked into it, those already
      placed removed again if one fails;
    * ``overwrite`` and ``out_dir`` holding some of them: the temporary folder gets the files
      of ``out_dir`` the set does not replace (hard links), then the two folders are swapped
      at once (:func:`~veriloc_rt.fileio.exchange_folders`) and the old one removed.
      ``out_dir`` must then hold key files only (the swap replaces the folder as a whole).

    A failure before that step removes the temporary folder and leaves ``out_dir`` as it was:
    its old keys complete.

    :param rng: None (default) draws from the OS CSPRNG; a Generator makes the set reproducible
    :param overwrite: replace existing files instead of refusing
    :return: the files written
    :raises InputError: ``<out_dir>: ...`` (not a folder, holds other files with
        ``overwrite``, cannot be written), ``<file>: key file exists ...`` (before writing any)
    """
    out = Path(os.path.abspath(out_dir))
    if os.path.lexists(out) and not out.is_dir():
        raise InputError(str(out), "is not a folder")
    if out.parent == out:
        raise InputError(str(out), "the root folder cannot hold a key set: give a folder of "
                         "its own")
    sets = [make_keys(int(b), aes_bits=aes_bits, rng=rng) for b in bs_ids]
    files: list[tuple[Path, bytes]] = []
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
            files.append((paths[name], text.encode("ascii")))
    names = {path.name for path, _ in files}
    existing = sorted(os.listdir(out)) if out.is_dir() else []
    replace = any(n in names for n in existing)
    if replace:
        others = [n for n in existing if n not in names and not _KEY_NAME.fullmatch(n)]
        if others:
            raise InputError(str(out), f"holds {short_repr(others[0])}, not a key file: keys "
                             "--force replaces the key folder as a whole, so it must hold key "
                             "files only; move the other files out, or use a new --out")
    stage = out.with_name(f".{out.name}{TMP_MARK}{os.getpid()}-{secrets.token_hex(4)}")
    placed: list[Path] = []
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        os.mkdir(stage, 0o700)
        os.chmod(stage, 0o700)      # whatever the umask
        for path, data in files:
            _write_new(stage / path.name, data)
        if not existing and not out.exists():
            os.rename(stage, out)
        elif not replace:
            for path, _ in files:
                _link_or_copy(str(stage / path.name), str(path))
                placed.append(path)
        else:
            for n in existing:
                if n not in names:
                    _link_or_copy(str(out / n), str(stage / n))
            exchange_folders(stage, out)
    except OSError as exc:
        for path in placed:
            path.unlink(missing_ok=True)
        shutil.rmtree(stage, ignore_errors=True)
        raise InputError(str(out), f"cannot write key files ({exc.strerror or exc}); nothing "
                         "was changed there") from None
    shutil.rmtree(stage, ignore_errors=True)   # the staging folder, or the old keys
    written = [path for path, _ in files]
    log.info("wrote %d key files to %s", len(written), out)
    return written


#: mode bits of a file that others may read or write
_GROUP_OTHER = stat.S_IRWXG | stat.S_IRWXO


def _check_mode(path: Path, secret: bool) -> None:
    """Refuse key material anyone may replace (world-writable: the file, or its folder without
    the sticky bit); warn about secret key material others may read."""
    try:
        st = os.stat(path)
        folder = os.stat(path.parent)
    except OSError:
        return
    if st.st_mode & stat.S_IWOTH:
        raise InputError(str(path), f"key file is world-writable (mode "
                         f"{stat.S_IMODE(st.st_mode):04o}): anyone on this machine could "
                         f"replace the key; `chmod 600 {path}`")
    if folder.st_mode & stat.S_IWOTH and not folder.st_mode & stat.S_ISVTX:
        raise InputError(str(path), f"its folder is world-writable (mode "
                         f"{stat.S_IMODE(folder.st_mode):04o}): anyone on this machine could "
                         f"replace the key; `chmod 700 {path.parent}`")
    if secret and st.st_mode & _GROUP_OTHER:
        log.warning("%s: secret key material readable or writable by others (mode %04o): "
                    "`chmod 600 %s`", path, stat.S_IMODE(st.st_mode), path)


def _read(path: Path, secret: bool = True) -> bytes:
    if not os.path.lexists(path):
        raise InputError(str(path), f"missing key file ({_HINT})")
    data = read_bytes(path, str(path), "key file", MAX_KEY_FILE_BYTES)
    _check_mode(path, secret)
    return data


def _text(path: Path, data: bytes) -> str:
    """A key file's text: UTF-8, a byte-order mark (an editor's) dropped."""
    return decode_text(data, str(path), "key file")


def load_hex_key(path: str | Path, sizes: tuple[int, ...], kinds: tuple[str, ...] = (),
                 bs_id: int | None = None) -> bytes:
    """A symmetric key of one of ``sizes`` bytes: ``<kind> bs<id> <hex>`` or bare hex.

    :param kinds: the labels accepted for this file (``aes-128``, ``hmac-sha256``); a labelled
        file of another kind (an HMAC key in the AES file) is an error
    :param bs_id: the BS the file must be labelled with
    """
    p = Path(path)
    text = _text(p, _read(p))
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
    data = _text(p, _read(p)).encode()
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
    data = _text(p, _read(p, secret=False)).encode()
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
        problem = ("is a symbolic link loop" if d.is_symlink() and not d.exists()
                   and _loops(d) else "is not a folder" if d.exists()
                   else "keys directory does not exist")
        raise InputError(str(d), f"{problem} ({_HINT})")
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


def _loops(path: Path) -> bool:
    try:
        os.stat(path)
    except OSError as exc:
        return exc.errno == errno.ELOOP
    return False


def public_view(keys: Mapping[int, BSKeys]) -> dict[int, BSKeys]:
    """The same key set without the signing keys (what a UE is given)."""
    return {b: BSKeys(k.bs_id, k.aes_key, k.hmac_key, k.verify_key, None) for b, k in keys.items()}
