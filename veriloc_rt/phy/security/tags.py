"""Authentication tags of a PRS slot: the signed message, HMAC-SHA256 and Ed25519 (paper IV.B).

The message binds the BS identity, the frame/slot counter and the PRS configuration, so a tag
cannot be replayed in another slot or frame, moved to another BS or to another PRS set-up.

Signature scheme: Ed25519 (RFC 8032) rather than ECDSA P-256. Both give 64-byte signatures at the
128-bit security level, but Ed25519 signing is deterministic (no per-signature nonce whose reuse
or bias leaks the key), has one fixed-length encoding (no DER), and verifies faster; its RFC 8032
test vectors pin the implementation. Verification with the BS's public key needs no shared secret.
HMAC tags are compared with :func:`hmac.compare_digest` (constant time).
"""

from __future__ import annotations

import hashlib
import hmac
import struct
from dataclasses import dataclass

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric import ed25519

#: tag length per scheme [bits]: HMAC-SHA256 output, Ed25519 signature
TAG_BITS = {"hmac": 256, "ds": 512}
_MAGIC = b"VLOC-PRS-TAG"
_VERSION = 1
_SCHEME_CODE = {"hmac": 1, "ds": 2}


@dataclass(frozen=True)
class PRSParams:
    """The PRS configuration of one BS that its tag binds."""

    n_id_seq: int
    comb: int
    comb_offset: int
    num_symbols: int
    start_symbol: int
    num_prb: int
    numerology: int
    encrypted: bool


def tag_message(scheme: str, bs_id: int, frame: int, slot: int, prs: PRSParams) -> bytes:
    """The byte string a slot's tag authenticates (big-endian, fixed 34 bytes + magic).

    magic | version u8 | scheme u8 | bs_id u32 | frame u32 | slot u16 | n_id u16 | comb u8 |
    comb_offset u8 | num_symbols u8 | start_symbol u8 | num_prb u16 | numerology u8 | encrypted u8
    """
    if scheme not in _SCHEME_CODE:
        raise ValueError(f"Argument `scheme` must be one of {tuple(_SCHEME_CODE)}, not {scheme!r}")
    return _MAGIC + struct.pack(">BBIIHHBBBBHBB", _VERSION, _SCHEME_CODE[scheme], bs_id, frame, slot,
                                prs.n_id_seq, prs.comb, prs.comb_offset, prs.num_symbols,
                                prs.start_symbol, prs.num_prb, prs.numerology, int(prs.encrypted))


def hmac_tag(key: bytes, message: bytes) -> bytes:
    """HMAC-SHA256 (RFC 2104, FIPS 198-1) of ``message``: 32 bytes."""
    return hmac.new(key, message, hashlib.sha256).digest()


def verify_hmac(key: bytes, message: bytes, tag: bytes) -> bool:
    """Constant-time check of an HMAC-SHA256 tag."""
    return hmac.compare_digest(hmac_tag(key, message), tag)


def sign(key: ed25519.Ed25519PrivateKey, message: bytes) -> bytes:
    """Ed25519 signature (RFC 8032 5.1.6): 64 bytes, deterministic."""
    return key.sign(message)


def verify_signature(key: ed25519.Ed25519PublicKey, message: bytes, signature: bytes) -> bool:
    """Ed25519 verification (RFC 8032 5.1.7) with the BS's public key."""
    try:
        key.verify(signature, message)
    except InvalidSignature:
        return False
    return True


def make_tag(scheme: str, keys, message: bytes) -> bytes:
    """Tag of ``message`` with a BS's :class:`~veriloc_rt.phy.security.keys.BSKeys`."""
    if scheme == "hmac":
        return hmac_tag(keys.hmac_key, message)
    if scheme == "ds":
        if keys.sign_key is None:
            raise ValueError(f"BS {keys.bs_id} has no signing key loaded")
        return sign(keys.sign_key, message)
    raise ValueError(f"Argument `scheme` must be 'hmac' or 'ds', not {scheme!r}")


def check_tag(scheme: str, keys, message: bytes, tag: bytes) -> bool:
    """Verify ``tag`` for ``message``: HMAC with the shared key, DS with the public key."""
    if scheme == "hmac":
        return verify_hmac(keys.hmac_key, message, tag)
    if scheme == "ds":
        return verify_signature(keys.verify_key, message, tag)
    raise ValueError(f"Argument `scheme` must be 'hmac' or 'ds', not {scheme!r}")
