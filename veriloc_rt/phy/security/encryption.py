"""AES-CTR encryption of the PRS bit stream (paper section IV.A).

``b_PRSenc = b_PRS XOR p`` with ``p`` the AES-CTR keystream, then QPSK (TS 38.211 5.1.3).

Counter-block construction (128 bits, big-endian), one keystream per (BS, frame, slot, symbol)::

    byte  0      domain   0x01 = PRS keystream (other uses of the key must take another value)
    bytes 1..3   bs_id    24 bits
    bytes 4..7   frame    32-bit frame counter (SFN extended by the hyper-frame number)
    bytes 8..9   slot     slot within the frame, 16 bits
    byte  10     symbol   OFDM symbol l within the slot
    bytes 11..15 block    40-bit block counter, starts at 0

CTR mode increments the whole block (NIST SP 800-38A 6.5; ``cryptography`` does the same), so a
keystream of fewer than 2^40 blocks never carries out of the block field: two distinct
(domain, bs_id, frame, slot, symbol) tuples use disjoint sets of counter blocks, and no
(key, counter block) pair repeats across BSs, frames, slots and symbols, even if two BSs shared a
key. The frame counter must not wrap under one key: at 10 ms per frame, 2^32 frames last 497 days,
so keys are rotated well before that. A run of the simulator numbers its points' frames from an
offset drawn from its seed when it uses key files, so runs that share those keys do not share
counter blocks (:func:`veriloc_rt.sim.runner.frame_offset`).
"""

from __future__ import annotations

import numpy as np
from cryptography.hazmat.primitives.ciphers import Cipher, algorithms, modes

from ..nr.prs import prs_bits, qpsk

#: domain byte of the PRS keystream
DOMAIN_PRS = 0x01
#: width of the block counter field [bits]
BLOCK_COUNTER_BITS = 40
_LIMITS = {"bs_id": 2**24, "frame": 2**32, "slot": 2**16, "symbol": 2**8}


def counter_block(bs_id: int, frame: int, slot: int, symbol: int, domain: int = DOMAIN_PRS) -> bytes:
    """Initial 16-byte counter block of one symbol's keystream (layout in the module docstring)."""
    for name, value in (("bs_id", bs_id), ("frame", frame), ("slot", slot), ("symbol", symbol)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"Argument `{name}` must be an integer, not {type(value).__name__}")
        if not 0 <= int(value) < _LIMITS[name]:
            raise ValueError(f"Argument `{name}` must be in [0, {_LIMITS[name] - 1}], not {value}")
    if not 0 <= domain < 256:
        raise ValueError(f"Argument `domain` must be a byte, not {domain}")
    return (bytes([domain]) + int(bs_id).to_bytes(3, "big") + int(frame).to_bytes(4, "big")
            + int(slot).to_bytes(2, "big") + bytes([int(symbol)]) + bytes(5))


def aes_ctr_keystream(key: bytes, initial_block: bytes, num_bytes: int) -> bytes:
    """AES-CTR keystream (encryption of zeros), NIST SP 800-38A 6.5.

    :param key: 16 or 32 bytes (AES-128 / AES-256)
    :param initial_block: the first counter block, 16 bytes
    """
    if len(key) not in (16, 32):
        raise ValueError(f"Argument `key` must be 16 or 32 bytes, not {len(key)}")
    if num_bytes > 16 * 2**BLOCK_COUNTER_BITS:
        raise ValueError("keystream longer than the block counter field")
    enc = Cipher(algorithms.AES(key), modes.CTR(initial_block)).encryptor()
    return enc.update(bytes(num_bytes)) + enc.finalize()


def keystream_bits(key: bytes, bs_id: int, frame: int, slot: int, symbol: int, num_bits: int) -> np.ndarray:
    """The keystream p of one PRS symbol, bits MSB first.

    :return: p : [num_bits] uint8, 0/1
    """
    block = counter_block(bs_id, frame, slot, symbol)
    stream = aes_ctr_keystream(key, block, -(-num_bits // 8))
    return np.unpackbits(np.frombuffer(stream, dtype=np.uint8))[:num_bits]


def _counter_heads(bs_id: int, frame: int, slot_symbols) -> np.ndarray:
    """The first 11 bytes of :func:`counter_block` of each (slot, symbol) pair: [num_pairs, 11]
    uint8 (the same bytes, built as one array instead of one ``bytes`` per symbol)."""
    head = np.frombuffer(counter_block(bs_id, frame, 0, 0)[:8], dtype=np.uint8)   # checks bs_id, frame
    pairs = []
    for pair in slot_symbols:
        for v in pair:
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise TypeError(f"slot and symbol must be integers, not {type(v).__name__}")
        pairs.append(pair)
    ss = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    for name, col in (("slot", ss[:, 0]), ("symbol", ss[:, 1])):
        bad = (col < 0) | (col >= _LIMITS[name])
        if np.any(bad):
            raise ValueError(f"Argument `{name}` must be in [0, {_LIMITS[name] - 1}], not {int(col[bad][0])}")
    out = np.empty((ss.shape[0], 11), dtype=np.uint8)
    out[:, :8] = head
    out[:, 8] = ss[:, 0] >> 8
    out[:, 9] = ss[:, 0] & 0xFF
    out[:, 10] = ss[:, 1]
    return out


def keystream_bits_many(key: bytes, bs_id: int, frame: int, slot_symbols, num_bits: int) -> np.ndarray:
    """:func:`keystream_bits` of several (slot, symbol) pairs of one frame, in one AES call.

    CTR mode's keystream block j is AES_K(counter block + j); every symbol's stream is far
    shorter than 2^40 blocks, so its blocks are its initial counter block with j in the block
    field, and the counter blocks of all symbols are encrypted together (ECB over the list).

    :param slot_symbols: sequence of (slot, symbol)
    :return: p : [num_pairs, num_bits] uint8, 0/1 (row i equals keystream_bits(..., *slot_symbols[i], num_bits))
    """
    if len(key) not in (16, 32):
        raise ValueError(f"Argument `key` must be 16 or 32 bytes, not {len(key)}")
    nb = -(-num_bits // 128)
    heads = _counter_heads(bs_id, frame, slot_symbols)
    blocks = np.zeros((heads.shape[0], nb, 16), dtype=np.uint8)
    blocks[:, :, :11] = heads[:, None, :]
    j = np.arange(nb, dtype=np.uint64)
    for b in range(5):   # the 40-bit block counter, big-endian in bytes 11..15
        blocks[:, :, 15 - b] = ((j >> np.uint64(8 * b)) & np.uint64(0xFF)).astype(np.uint8)[None, :]
    enc = Cipher(algorithms.AES(key), modes.ECB()).encryptor()
    stream = np.frombuffer(enc.update(blocks.tobytes()) + enc.finalize(), dtype=np.uint8)
    return np.unpackbits(stream.reshape(heads.shape[0], nb * 16), axis=1)[:, :num_bits]


def encrypted_prs_bits(key: bytes, bs_id: int, n_id_seq: int, frame: int, slot: int, symbol: int,
                       length: int) -> np.ndarray:
    """b_PRSenc = b_PRS XOR p for ``length`` PRS symbols.

    :return: bits : [2 length] uint8
    """
    return prs_bits(n_id_seq, slot, symbol, length) ^ keystream_bits(key, bs_id, frame, slot, symbol,
                                                                     2 * length)


def encrypted_prs_sequence(key: bytes, bs_id: int, n_id_seq: int, frame: int, slot: int, symbol: int,
                           length: int) -> np.ndarray:
    """Encrypted PRS s_PRSenc(m), m = 0..length-1: QPSK of :func:`encrypted_prs_bits`.

    :return: s : [length] complex128, unit-energy QPSK
    """
    return qpsk(encrypted_prs_bits(key, bs_id, n_id_seq, frame, slot, symbol, length))
