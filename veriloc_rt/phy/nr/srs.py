"""Uplink SRS-like reference signal from the UE, for the downlink-uplink handshake.

TS 38.211 6.4.1.4 with a documented simplification: one antenna port, no group or sequence
hopping (u = n_ID^SRS mod 30, v = 0), and any bandwidth that is a multiple of 4 PRBs instead of
the C_SRS table 6.4.1.4.3-1. The sequence is the low-PAPR sequence r^(alpha, 0)_{u,0} of 5.2.2
for lengths >= 36 (Zadoff-Chu of prime length N_ZC, cyclically extended), with cyclic shift
alpha = 2 pi n_cs / n_cs_max, mapped to every K_TC-th subcarrier from offset k_TC (6.4.1.4.3).
"""

from __future__ import annotations

import numpy as np

from .prs import SYMBOLS_PER_SLOT

#: transmission comb sizes K_TC and the number of cyclic shifts n_cs_max of each, 38.211 6.4.1.4.2
SRS_COMBS = {2: 8, 4: 12, 8: 6}


def _largest_prime_below(n: int) -> int:
    for p in range(n - 1, 1, -1):
        if all(p % d for d in range(2, int(p**0.5) + 1)):
            return p
    raise ValueError(f"no prime below {n}")


def srs_sequence(n_id: int, length: int, cyclic_shift: int = 0, comb: int = 4) -> np.ndarray:
    """Low-PAPR SRS sequence, TS 38.211 5.2.2.1 (length >= 36) and 6.4.1.4.2.

    x_q(m) = exp(-j pi q m (m + 1) / N_ZC), q = floor(qbar + 1/2) + v (-1)^floor(2 qbar),
    qbar = N_ZC (u + 1) / 31; r(n) = exp(j alpha n) x_q(n mod N_ZC).

    :param n_id: n_ID^SRS, 0..1023
    :param length: M_sc,b^SRS (>= 36)
    :param cyclic_shift: n_SRS^cs, 0..n_cs_max-1
    :return: r : [length] complex128, unit modulus
    """
    if comb not in SRS_COMBS:
        raise ValueError(f"Argument `comb` must be one of {tuple(SRS_COMBS)}, not {comb}")
    if not 0 <= n_id <= 1023:
        raise ValueError(f"Argument `n_id` must be in [0, 1023], not {n_id}")
    if length < 36:
        raise ValueError(f"Argument `length` must be >= 36, not {length}")
    n_cs_max = SRS_COMBS[comb]
    if not 0 <= cyclic_shift < n_cs_max:
        raise ValueError(f"Argument `cyclic_shift` must be in [0, {n_cs_max - 1}], not {cyclic_shift}")
    u, v = n_id % 30, 0
    n_zc = _largest_prime_below(length)  # largest prime N_ZC < M_ZC
    qbar = n_zc * (u + 1) / 31
    q = int(np.floor(qbar + 0.5)) + v * (-1) ** int(np.floor(2 * qbar))
    m = np.arange(n_zc)
    x = np.exp(-1j * np.pi * q * m * (m + 1) / n_zc)
    n = np.arange(length)
    alpha = 2 * np.pi * cyclic_shift / n_cs_max
    return np.exp(1j * alpha * n) * x[n % n_zc]


def srs_grid(num_prb: int, n_id: int, comb: int = 4, comb_offset: int = 0,
             symbols: tuple[int, ...] = (13,), cyclic_shift: int = 0) -> np.ndarray:
    """One slot of the UE's SRS-like signal over ``num_prb`` PRBs (from subcarrier 0).

    :param symbols: OFDM symbols carrying it (SRS sits in the last 6 symbols of the slot)
    :return: grid : [14, 12 num_prb] complex128, unit-energy REs on the comb, 0 elsewhere
    """
    if num_prb % 4:
        raise ValueError(f"Argument `num_prb` must be a multiple of 4, not {num_prb}")
    if not 0 <= comb_offset < comb:
        raise ValueError(f"Argument `comb_offset` must be in [0, {comb - 1}], not {comb_offset}")
    n_sc = 12 * num_prb
    length = n_sc // comb
    r = srs_sequence(n_id, length, cyclic_shift, comb)
    grid = np.zeros((SYMBOLS_PER_SLOT, n_sc), dtype=np.complex128)
    for l in symbols:
        if not 0 <= l < SYMBOLS_PER_SLOT:
            raise ValueError(f"Argument `symbols` must lie in 0..13, not {l}")
        grid[l, comb_offset::comb] = r
    return grid
