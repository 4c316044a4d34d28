"""Tag bits <-> tag REs: LDPC rate 1/2, QPSK, repetition over the slot's tag REs, and back to LLRs.

Transmit: tag (HMAC 256 bits or Ed25519 512 bits) -> 5G NR LDPC BG2 at rate 1/2 (E = 2 K) ->
QPSK (TS 38.211 5.1.3) -> the slot's tag REs in (symbol, subcarrier) order. With fill 'repeat'
the E/2 symbols are repeated cyclically over all tag REs (the paper's figure fills every empty RE
of the BS's tag comb); the receiver adds the LLRs of the copies (maximum-ratio combining).
"""

from __future__ import annotations

import functools

import numpy as np

from ..nr.prs import qpsk
from .ldpc import NRLDPC
from .tags import TAG_BITS


@functools.lru_cache(maxsize=16)
def ldpc_code(k: int, iterations: int, method: str) -> NRLDPC:
    """Shared rate-1/2 code for ``k`` tag bits (building one costs a GF(2) inversion)."""
    return NRLDPC(k, 2 * k, iterations=iterations, method=method)


def qpsk_llr(y: np.ndarray, h: np.ndarray, noise_var: float | np.ndarray) -> np.ndarray:
    """Exact per-bit LLRs of unit-energy QPSK through ``y = h x + n``, n ~ CN(0, noise_var).

    LLR(b0) = 2 sqrt(2) Re(h* y) / noise_var, LLR(b1) = 2 sqrt(2) Im(h* y) / noise_var.

    :param y: [n] complex, received REs
    :param h: [n] complex, channel per RE
    :return: llr : [2 n] float64, log P(0)/P(1), interleaved (b0, b1) per symbol
    """
    z = np.conj(h) * y * (2.0 * np.sqrt(2.0) / noise_var)
    out = np.empty(2 * z.size)
    out[0::2] = z.real
    out[1::2] = z.imag
    return out


class TagModem:
    """Maps a tag of one scheme onto ``num_res`` REs and decodes it back.

    :param scheme: 'hmac' or 'ds'
    :param num_res: tag REs per slot
    :param fill: 'repeat' or 'single'
    """

    def __init__(self, scheme: str, num_res: int, fill: str = "repeat", iterations: int = 25,
                 method: str = "sum_product"):
        if scheme not in TAG_BITS:
            raise ValueError(f"Argument `scheme` must be one of {tuple(TAG_BITS)}, not {scheme!r}")
        if fill not in ("repeat", "single"):
            raise ValueError(f"Argument `fill` must be 'repeat' or 'single', not {fill!r}")
        self.scheme, self.num_res, self.fill = scheme, int(num_res), fill
        self.code = ldpc_code(TAG_BITS[scheme], iterations, method)
        self.num_symbols = self.code.e // 2
        if self.num_res < self.num_symbols:
            raise ValueError(f"{self.num_res} tag REs per slot cannot hold a {scheme} tag "
                             f"({self.num_symbols} QPSK symbols); widen the band or add symbols")
        used = self.num_res if fill == "repeat" else self.num_symbols
        self.copy_index = np.arange(used) % self.num_symbols  # which codeword symbol each RE carries
        #: [2 used] int64, the codeword bit of each LLR of the used REs (b0, b1 per RE)
        self.bit_index = (2 * self.copy_index[:, None] + np.arange(2)).ravel()

    def modulate(self, tag: bytes) -> np.ndarray:
        """:return: x : [num_res] complex128, unit-energy QPSK on used REs, 0 on unused ones"""
        return self.modulate_many([tag])[0]

    def modulate_many(self, tags) -> np.ndarray:
        """:meth:`modulate` of several tags at once (one encoding product for all).

        :param tags: sequence of bytes
        :return: x : [len(tags), num_res] complex128
        """
        for tag in tags:
            if len(tag) * 8 != self.code.k:
                raise ValueError(f"Argument `tag` must be {self.code.k // 8} bytes, not {len(tag)}")
        bits = np.unpackbits(np.frombuffer(b"".join(tags), dtype=np.uint8)).reshape(len(tags), self.code.k)
        sym = qpsk(self.code.encode(bits))                                    # [N, e / 2]
        out = np.zeros((len(tags), self.num_res), dtype=np.complex128)
        out[:, :self.copy_index.size] = sym[:, self.copy_index]
        return out

    def demodulate(self, y: np.ndarray, h: np.ndarray, noise_var: float | np.ndarray) -> tuple[bytes, bool]:
        """LLRs, combining of the copies, LDPC decoding.

        :param y: [num_res] complex, received tag REs
        :param h: [num_res] complex, channel estimate on them
        :param noise_var: noise variance per RE (scalar or [num_res])
        :return: (tag bytes, all parity checks satisfied)
        """
        n = self.copy_index.size
        nv = np.broadcast_to(np.asarray(noise_var, dtype=np.float64), (self.num_res,))[:n]
        llr = qpsk_llr(np.asarray(y)[:n], np.asarray(h)[:n], np.maximum(nv, 1e-30))
        # the copies' LLRs summed per codeword bit in the REs' order (bincount adds as
        # np.add.at does, into 0: the same sums)
        combined = np.bincount(self.bit_index, weights=llr, minlength=self.code.e)
        bits, ok = self.code.decode(combined)
        return np.packbits(bits).tobytes(), bool(ok)
