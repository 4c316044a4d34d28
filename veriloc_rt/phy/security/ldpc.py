"""5G NR LDPC code (base graph 2) for the tag bits: encoding, rate matching, BP decoding.

TS 38.212: base graph 2 (Table 5.3.2-3, shipped as ``data/ldpc_bg2_38212.csv``), lifting size
(5.2.2), encoding (5.3.2), rate matching by bit selection from the circular buffer at redundancy
version 0 (5.4.2.1) and bit interleaving for QPSK (5.4.2.2). Decoding runs belief propagation
(sum-product or normalised min-sum, flooding schedule) with the ``ldpc`` package (Roffe et al.)
on the rows of the lifted parity-check matrix that the transmitted bits touch; the extension rows
whose degree-1 parity bit was never sent carry no information and are left out.

Bit-to-LLR convention: ``llr = log P(b = 0) / P(b = 1)`` (positive means 0).
"""

from __future__ import annotations

import functools
from importlib import resources

import numpy as np
import scipy.sparse as sp

#: base graph 2 dimensions (TS 38.212 5.3.2): 42 rows, 52 columns, 10 systematic columns
BG2_ROWS, BG2_COLS, BG2_KB = 42, 52, 10
#: the set index iLS of each lifting size a * 2^j (TS 38.212 Table 5.3.2-1)
_LIFT_BASES = (2, 3, 5, 7, 9, 11, 13, 15)
#: |LLR| used for known (filler) bits and the clip for others
_LLR_KNOWN = 40.0
#: belief propagation runs only on received words whose LLRs carry at least this share of the
#: k information bits (:func:`llr_information` x e >= share x k); below it the word is returned
#: undecoded (hard decisions, not a codeword). By the converse of the channel coding theorem no
#: code decodes reliably below a share of 1. At 0.8 on BI-AWGN the best code of the tags'
#: lengths would succeed with probability 5e-3 (n = 512) and 7e-5 (n = 1024) by the normal
#: approximation (Polyanskiy, Poor, Verdu 2010); the NR code under 25-iteration BP sits about
#: 1 dB from it, where the approximation gives 3e-6 and 2e-11 (:mod:`.coding_bounds`,
#: tests/unit/phy/security/test_ldpc.py; docs/notes/performance-history.md for the chain's decodes)
DECODE_MIN_INFORMATION = 0.8


def lifting_sizes() -> dict[int, int]:
    """Every lifting size Z of TS 38.212 Table 5.3.2-1 with its set index iLS."""
    out = {}
    for ils, a in enumerate(_LIFT_BASES):
        z = a
        while z <= 384:
            out[z] = ils
            z *= 2
    return dict(sorted(out.items()))


@functools.lru_cache(maxsize=1)
def base_graph_2() -> np.ndarray:
    """BG2 entries: [197, 10] int64 rows (i, j, V_ij for iLS = 0..7), TS 38.212 Table 5.3.2-3."""
    text = resources.files("veriloc_rt").joinpath("data", "ldpc_bg2_38212.csv").read_text()
    rows = [[int(v) for v in line.split(",")] for line in text.splitlines()
            if line.strip() and not line.startswith("#")]
    return np.asarray(rows, dtype=np.int64)


def bg2_kb(k: int) -> int:
    """Number of systematic base columns K_b for base graph 2, TS 38.212 5.2.2."""
    return 10 if k > 640 else 9 if k > 560 else 8 if k > 192 else 6


def lifted_h(z: int, rows: int, cols: int) -> sp.csr_matrix:
    """The first ``rows`` x ``cols`` base blocks of BG2 lifted by ``z`` (P_ij = V_ij mod Z).

    :return: H : [rows z, cols z] uint8 sparse, block (i, j) has H[i z + r, j z + (r + P) mod z] = 1
    """
    ils = lifting_sizes()[z]
    bg = base_graph_2()
    sel = bg[(bg[:, 0] < rows) & (bg[:, 1] < cols)]
    r = np.arange(z)
    ri = (sel[:, 0, None] * z + r).ravel()
    ci = (sel[:, 1, None] * z + (r + sel[:, 2 + ils, None] % z) % z).ravel()
    return sp.csr_matrix((np.ones(ri.size, dtype=np.uint8), (ri, ci)), shape=(rows * z, cols * z))


def llr_information(llr: np.ndarray) -> np.ndarray:
    """Mean mutual information per bit that LLRs carry about their bits, bits (0 to 1):
    1 - mean H_b(1 / (1 + e^|L|)), the LLR-only estimate for consistent LLRs (Land, Hoeher,
    Gligorevic, ITG SCC 2004; no knowledge of the sent bits needed).

    :param llr: [..., e] float64
    :return: [...] float64
    """
    a = np.abs(np.nan_to_num(np.asarray(llr, dtype=np.float64)))
    u = np.exp(-a)                                   # H_b(p) = (log(1 + u) + a u / (1 + u)) / ln 2
    h = (np.log1p(u) + a * u / (1.0 + u)) / np.log(2.0)
    return 1.0 - h.mean(axis=-1)


def _gf2_inverse(a: np.ndarray) -> np.ndarray:
    """Inverse of a square GF(2) matrix by Gauss-Jordan elimination."""
    n = a.shape[0]
    m = np.concatenate([a.astype(bool), np.eye(n, dtype=bool)], axis=1)
    for col in range(n):
        piv = col + np.flatnonzero(m[col:, col])
        if piv.size == 0:
            raise ValueError("parity part of H is singular")
        if piv[0] != col:
            m[[col, piv[0]]] = m[[piv[0], col]]
        rows = np.flatnonzero(m[:, col])
        rows = rows[rows != col]
        m[rows] ^= m[col]
    return m[:, n:].astype(np.uint8)


class NRLDPC:
    """Rate-matched 5G NR LDPC code, base graph 2, for ``k`` information bits into ``e`` bits.

    :param k: information bits K' (<= 3840 for BG2)
    :param e: transmitted bits E (even, for QPSK); default 2k, rate 1/2
    :param iterations: BP iterations (paper: 25)
    :param method: 'sum_product' or 'min_sum' (normalised, factor 0.75)
    :param min_information: BP runs only on words whose LLRs carry at least this share of the k
        information bits (:data:`DECODE_MIN_INFORMATION`; 0: on every word)
    """

    def __init__(self, k: int, e: int | None = None, iterations: int = 25, method: str = "sum_product",
                 min_information: float = DECODE_MIN_INFORMATION):
        if not 1 <= k <= 3840:
            raise ValueError(f"Argument `k` must be in [1, 3840] for base graph 2, not {k}")
        e = 2 * k if e is None else int(e)
        if e < k or e % 2:
            raise ValueError(f"Argument `e` must be even and >= k = {k}, not {e}")
        if method not in ("sum_product", "min_sum"):
            raise ValueError(f"Argument `method` must be 'sum_product' or 'min_sum', not {method!r}")
        if not 0.0 <= min_information <= 1.0:
            raise ValueError(f"Argument `min_information` must be in [0, 1], not {min_information}")
        self.k, self.e, self.iterations, self.method = k, e, iterations, method
        self.min_information = float(min_information)
        kb = bg2_kb(k)
        self.z = min(z for z in lifting_sizes() if kb * z >= k)
        self.k_full = BG2_KB * self.z           # K = 10 Z, fillers at k..K-1
        n_cb = (BG2_COLS - 2) * self.z          # N = 50 Z = N_cb (no limited-buffer rate matching)
        d_idx = 2 * self.z + np.arange(n_cb)    # d_k = c_{k + 2Z}
        d_idx = d_idx[(d_idx < k) | (d_idx >= self.k_full)]  # skip <NULL> filler bits
        e_idx = d_idx[np.arange(e) % d_idx.size]  # circular buffer from k0 = 0 (rv 0)
        # bit interleaving for Q_m = 2 (5.4.2.2): f[i + 2 j] = e[i E/2 + j]
        self.positions = e_idx.reshape(2, e // 2).T.ravel()  # [e] codeword index of each sent bit
        cols = max(int(self.positions.max()) // self.z + 1, BG2_KB + 4)
        self.rows = cols - BG2_KB
        self.h = lifted_h(self.z, self.rows, cols)
        self.n = cols * self.z
        hs = self.h[:, :self.k_full].toarray()
        hp_inv = _gf2_inverse(self.h[:, self.k_full:].toarray())
        # parity = M s mod 2, as float64 products (BLAS; exact: the sums are integers <= the
        # parity length); NumPy's integer matrix product has no BLAS and took 25x as long
        self._encode_matrix = (hp_inv.astype(np.float64) @ hs.astype(np.float64)) % 2.0

    @functools.cached_property
    def _decoder(self):
        """The belief-propagation decoder (the ``ldpc`` package), built on the first decode:
        importing that package loads its quantum-code decoders too (about half a second), which
        a run that decodes nothing (a resume past its last point, a run without tags) skips."""
        from ldpc import BpDecoder

        return BpDecoder(
            self.h, error_channel=np.full(self.n, 0.1), max_iter=self.iterations,
            bp_method="product_sum" if self.method == "sum_product" else "minimum_sum",
            ms_scaling_factor=0.75 if self.method == "min_sum" else 1.0,
            schedule="parallel", input_vector_type="received_vector")

    @property
    def rate(self) -> float:
        return self.k / self.e

    def codeword(self, bits: np.ndarray) -> np.ndarray:
        """Lifted codeword c of the decoded graph (systematic part with zero fillers, then parity).

        :param bits: [..., k] uint8
        :return: c : [..., n] uint8
        """
        bits = np.asarray(bits, dtype=np.uint8)
        if bits.shape[-1] != self.k:
            raise ValueError(f"Argument `bits` must have {self.k} bits on its last axis, not {bits.shape[-1]}")
        s = np.zeros(bits.shape[:-1] + (self.k_full,), dtype=np.float64)
        s[..., :self.k] = bits
        parity = (s @ self._encode_matrix.T) % 2
        return np.concatenate([s, parity], axis=-1).astype(np.uint8)

    def encode(self, bits: np.ndarray) -> np.ndarray:
        """Encode, rate-match and interleave.

        :param bits: [..., k] uint8
        :return: f : [..., e] uint8, the transmitted bits in QPSK order
        """
        return self.codeword(bits)[..., self.positions]

    def decode(self, llr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """BP-decode received LLRs of the transmitted bits.

        A word whose LLRs carry less than ``min_information`` x k bits is not decoded: its bits
        are the hard decisions and ``ok`` is False (BP would spend every iteration on it; see
        :data:`DECODE_MIN_INFORMATION`).

        :param llr: [..., e] float64, log P(0)/P(1) per transmitted bit
        :return: bits : [..., k] uint8 and ok : [...] bool (all parity checks satisfied)
        """
        llr = np.asarray(llr, dtype=np.float64)
        if llr.shape[-1] != self.e:
            raise ValueError(f"Argument `llr` must have {self.e} values on its last axis, not {llr.shape[-1]}")
        flat = llr.reshape(-1, self.e)
        bits = np.zeros((flat.shape[0], self.k), dtype=np.uint8)
        ok = np.zeros(flat.shape[0], dtype=bool)
        decodable = llr_information(flat) * self.e >= self.min_information * self.k
        for i, row in enumerate(flat):
            total = np.zeros(self.n)
            np.add.at(total, self.positions, np.nan_to_num(row))
            total[self.k:self.k_full] = _LLR_KNOWN
            total = np.clip(total, -_LLR_KNOWN, _LLR_KNOWN)
            hard = (total < 0).astype(np.uint8)
            if not decodable[i]:
                bits[i] = hard[:self.k]
                continue
            self._decoder.update_channel_probs(1.0 / (1.0 + np.exp(np.abs(total))))
            cw = np.asarray(self._decoder.decode(hard), dtype=np.uint8)
            bits[i] = cw[:self.k]
            ok[i] = bool(self._decoder.converge)
        return bits.reshape(llr.shape[:-1] + (self.k,)), ok.reshape(llr.shape[:-1])
