"""DL positioning reference signal: Gold sequence, c_init, r(m) and the comb mapping.

TS 38.211 clause 5.2.1 (pseudo-random sequence), 7.4.1.7.2 (PRS sequence) and 7.4.1.7.3 (mapping
to physical resources). The mapping assumes the PRS resource starts at point A (``m`` counts from
subcarrier 0 of the grid, NStartGrid = RBOffset = 0), normal cyclic prefix and ``beta_PRS = 1``.
"""

from __future__ import annotations

import functools
from importlib import resources

import numpy as np

from ...config.nr import COMB_SIZES, NUM_SYMBOLS, SYMBOLS_PER_SLOT

#: Nc of TS 38.211 5.2.1: the Gold sequence discards the first 1600 outputs
GOLD_NC = 1600
_MAX_C_INIT = 2**31


def _check_int(name: str, value: object, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"Argument `{name}` must be an integer, not {type(value).__name__}")
    if not lo <= int(value) <= hi:
        raise ValueError(f"Argument `{name}` must be in [{lo}, {hi}], not {value}")
    return int(value)


def _lfsr(state: np.ndarray, taps: tuple[int, ...], total: int) -> np.ndarray:
    """Run x(n+31) = sum_t x(n+t) mod 2 for n = 0..total-32, 28 outputs per numpy step."""
    x = np.zeros(total, dtype=np.uint8)
    x[:31] = state
    n = 0
    while n + 31 < total:
        step = min(28, total - 31 - n)  # x(n+31) needs x(n+3) at most, so 28 at a time are ready
        acc = np.zeros(step, dtype=np.uint8)
        for t in taps:
            acc ^= x[n + t:n + t + step]
        x[n + 31:n + 31 + step] = acc
        n += step
    return x


@functools.lru_cache(maxsize=8)
def _x1(total: int) -> np.ndarray:
    init = np.zeros(31, dtype=np.uint8)
    init[0] = 1
    out = _lfsr(init, (0, 3), total)
    out.setflags(write=False)
    return out


@functools.lru_cache(maxsize=4)
def _x2_basis(total: int) -> np.ndarray:
    """[31, total] uint8: the x2 m-sequence started from each unit initial state e_i."""
    out = np.empty((31, total), dtype=np.uint8)
    for i in range(31):
        init = np.zeros(31, dtype=np.uint8)
        init[i] = 1
        out[i] = _lfsr(init, (0, 1, 2, 3), total)
    out.setflags(write=False)
    return out


def gold_sequence(c_init: int, length: int) -> np.ndarray:
    """Length-31 Gold sequence c(n), TS 38.211 clause 5.2.1.

    :param c_init: initialisation of the second m-sequence, ``0 <= c_init < 2**31``
    :param length: number of output bits M_PN
    :return: c : [length] uint8, bits 0/1
    """
    c_init = _check_int("c_init", c_init, 0, _MAX_C_INIT - 1)
    length = _check_int("length", length, 0, 2**26)
    total = GOLD_NC + length + 31
    # x1 is the same for every c_init, and x2 is linear over GF(2) in its initial state: x2 is
    # the XOR of the basis sequences of the set bits of c_init. Both are cached per total length
    # (rounded up to reuse entries), so a sequence costs one XOR-reduction instead of an LFSR run.
    padded = -(-total // 4096) * 4096
    bits = ((c_init >> np.arange(31)) & 1).astype(bool)
    x1 = _x1(padded)[GOLD_NC:GOLD_NC + length]
    basis = _x2_basis(padded)[bits, GOLD_NC:GOLD_NC + length]
    return x1 ^ np.bitwise_xor.reduce(basis, axis=0) if basis.shape[0] else x1.copy()


def prs_c_init(n_id_seq: int, slot: int, symbol: int, symbols_per_slot: int = SYMBOLS_PER_SLOT) -> int:
    """PRS scrambling initialisation, TS 38.211 clause 7.4.1.7.2.

    c_init = (2^22 floor(n_ID/1024) + 2^10 (N_symb^slot n_s,f + l + 1)(2 (n_ID mod 1024) + 1)
    + (n_ID mod 1024)) mod 2^31.

    :param n_id_seq: dl-PRS-SequenceId, 0..4095
    :param slot: slot number within the frame n_s,f^mu, 0..159 (mu <= 4)
    :param symbol: OFDM symbol index l within the slot
    :param symbols_per_slot: N_symb^slot (14 for normal CP, 12 extended)
    """
    n_id = _check_int("n_id_seq", n_id_seq, 0, 4095)
    slot = _check_int("slot", slot, 0, 10 * 2**6 - 1)
    symbols_per_slot = _check_int("symbols_per_slot", symbols_per_slot, 12, 14)
    symbol = _check_int("symbol", symbol, 0, symbols_per_slot - 1)
    lo = n_id % 1024
    raw = (2**22 * (n_id // 1024) + 2**10 * (symbols_per_slot * slot + symbol + 1) * (2 * lo + 1) + lo)
    return raw % _MAX_C_INIT


def qpsk(bits: np.ndarray) -> np.ndarray:
    """QPSK of TS 38.211 5.1.3: pairs (b(2i), b(2i+1)) -> ((1-2b(2i)) + j(1-2b(2i+1)))/sqrt(2).

    :param bits: [..., 2 n] uint8, 0/1
    :return: symbols : [..., n] complex128, unit energy
    """
    b = np.asarray(bits, dtype=np.float64)
    if b.shape[-1] % 2:
        raise ValueError(f"Argument `bits` must have an even last axis, not {b.shape[-1]}")
    s = (1.0 - 2.0 * b) / np.sqrt(2.0)
    return s[..., 0::2] + 1j * s[..., 1::2]


def prs_bits(n_id_seq: int, slot: int, symbol: int, length: int) -> np.ndarray:
    """The PRS bit stream b_PRS = c(0..2 length - 1) of one symbol (before QPSK).

    The sequence does not depend on the frame (c_init has no frame number), so it is cached.

    :return: bits : [2 length] uint8, read-only
    """
    return _prs_bits(int(n_id_seq), int(slot), int(symbol), int(length))


@functools.lru_cache(maxsize=16384)
def _prs_bits(n_id_seq: int, slot: int, symbol: int, length: int) -> np.ndarray:
    out = gold_sequence(prs_c_init(n_id_seq, slot, symbol), 2 * length)
    out.setflags(write=False)
    return out


def prs_sequence(n_id_seq: int, slot: int, symbol: int, length: int) -> np.ndarray:
    """PRS sequence r(m), m = 0..length-1, TS 38.211 clause 7.4.1.7.2 (normal CP).

    :return: r : [length] complex128, unit-energy QPSK
    """
    return qpsk(prs_bits(n_id_seq, slot, symbol, length))


@functools.lru_cache(maxsize=1)
def _kprime_table() -> dict[int, tuple[int, ...]]:
    text = resources.files("veriloc_rt").joinpath("data", "prs_kprime_38211.csv").read_text()
    table = {}
    for line in text.splitlines():
        if line.strip() and not line.startswith("#"):
            vals = [int(v) for v in line.split(",")]
            table[vals[0]] = tuple(vals[1:])
    return table


def check_comb(comb: int, num_symbols: int) -> None:
    """Raise ValueError unless (K_comb, L_PRS) is an allowed pair (L >= K and L mod K = 0)."""
    if comb not in COMB_SIZES:
        raise ValueError(f"Argument `comb` must be one of {COMB_SIZES}, not {comb}")
    if num_symbols not in NUM_SYMBOLS:
        raise ValueError(f"Argument `num_symbols` must be one of {NUM_SYMBOLS}, not {num_symbols}")
    if num_symbols < comb or num_symbols % comb:
        raise ValueError(f"comb {comb} needs a number of symbols that is a multiple of {comb}, "
                         f"not {num_symbols} (TS 38.211 7.4.1.7.3)")


def k_prime(comb: int, num_symbols: int) -> np.ndarray:
    """Per-symbol frequency offsets k', TS 38.211 Table 7.4.1.7.3-1.

    :return: k_prime : [num_symbols] int64, subcarriers, indexed by l - l_start
    """
    check_comb(comb, num_symbols)
    return np.asarray(_kprime_table()[comb][:num_symbols], dtype=np.int64)


def prs_subcarriers(comb: int, num_symbols: int, k_offset: int, num_subcarriers: int) -> np.ndarray:
    """Subcarriers k = m K_comb + ((k_offset + k') mod K_comb) of every PRS symbol, clause 7.4.1.7.3.

    :param num_subcarriers: grid width 12 N_PRB; must be a multiple of ``comb``
    :return: k : [num_symbols, num_subcarriers // comb] int64, subcarrier index, row l - l_start
    """
    kp = k_prime(comb, num_symbols)
    k_offset = _check_int("k_offset", k_offset, 0, comb - 1)
    if num_subcarriers % comb:
        raise ValueError(f"Argument `num_subcarriers` must be a multiple of comb {comb}")
    m = np.arange(num_subcarriers // comb)
    return m[None, :] * comb + ((k_offset + kp[:, None]) % comb)
