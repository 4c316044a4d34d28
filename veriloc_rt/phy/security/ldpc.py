"""5G NR LDPC code (base graph 2) for the tag bits: encoding, rate matching, BP decoding.

TS 38.212: base graph 2 (Table 5.3.2-3, shipped as ``data/ldpc_bg2_38212.csv``), lifting size
(5.2.2), encoding (5.3.2), rate matching by bit selection from the circular buffer at redundancy
version 0 (5.4.2.1) and bit interleaving for QPSK (5.4.2.2). Decoding runs belief propagation
(sum-product or normalised min-sum, flooding schedule) with the ``ldpc`` package (Roffe et al.)
on the rows of the lifted parity-check matrix that the transmitted bits touch; the extension rows
whose degree-1 parity bit was never sent carry no information and are left out. Words that are
already codewords on their sent bits are not handed to the package: its output for them is
known (:meth:`NRLDPC.decode`).

Bit-to-LLR convention: ``llr = log P(b = 0) / P(b = 1)`` (positive means 0).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
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
        # parity = M s mod 2 over the k information bits (the fillers are 0), as float32
        # products (BLAS; exact: the sums are integers <= k <= 3840 < 2^24); NumPy's integer
        # matrix product has no BLAS and took 25x as long
        encode_matrix = (hp_inv.astype(np.float64) @ hs.astype(np.float64)) % 2.0
        self._encode_info = np.ascontiguousarray(encode_matrix[:, :k].T, dtype=np.float32)
        self._skip = _codeword_skip(self.h, self.positions, self.k, self.k_full)
        self._positions64 = np.ascontiguousarray(self.positions, dtype=np.int64)

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
        s = np.zeros(bits.shape[:-1] + (self.n,), dtype=np.uint8)
        s[..., :self.k] = bits
        s[..., self.k_full:] = (bits.astype(np.float32) @ self._encode_info) % 2
        return s

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
        :data:`DECODE_MIN_INFORMATION`). A word whose hard decisions on the sent bits are a
        codeword's, every sent bit's LLR clear of 0, gets that codeword without running BP:
        the package would return it, converged, from its first iteration
        (:func:`_already_codewords`; the output is the same).

        :param llr: [..., e] float64, log P(0)/P(1) per transmitted bit
        :return: bits : [..., k] uint8 and ok : [...] bool (all parity checks satisfied)
        """
        llr = np.asarray(llr, dtype=np.float64)
        if llr.shape[-1] != self.e:
            raise ValueError(f"Argument `llr` must have {self.e} values on its last axis, not {llr.shape[-1]}")
        flat = llr.reshape(-1, self.e)
        w = flat.shape[0]
        bits = np.zeros((w, self.k), dtype=np.uint8)
        ok = np.zeros(w, dtype=bool)
        decodable = llr_information(flat) * self.e >= self.min_information * self.k
        total, hard, done, cw_done = self.prepare(flat)
        done &= decodable
        bits[done] = cw_done[done, :self.k]
        ok[done] = True
        for i in range(w):
            if not decodable[i]:
                bits[i] = hard[i, :self.k]
                continue
            if done[i]:
                continue
            # a list: the package copies it element by element, 20x faster from a list
            self._decoder.update_channel_probs((1.0 / (1.0 + np.exp(np.abs(total[i])))).tolist())
            cw = np.asarray(self._decoder.decode(hard[i]), dtype=np.uint8)
            bits[i] = cw[:self.k]
            ok[i] = bool(self._decoder.converge)
        return bits.reshape(llr.shape[:-1] + (self.k,)), ok.reshape(llr.shape[:-1])

    def prepare(self, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What :meth:`decode` starts from, for received words ``flat`` [W, e] float64: each
        word's LLR per codeword bit ``total`` [W, n] float64 (the copies of a bit added in the
        order of the sent bits, the fillers known, clipped to +-40), its hard decisions ``hard``
        [W, n] uint8, and the codeword skip (:func:`_already_codewords`): ``clean`` [W] bool and
        ``cw`` [W, n] uint8, the codeword meaningful where ``clean``. One compiled pass
        (:func:`~veriloc_rt.phy.security.ldpc_kernels.word_totals`), the bits of
        :meth:`prepare_reference` (tests/unit/phy/security/test_ldpc_kernels.py)."""
        from .ldpc_kernels import word_totals

        flat = np.ascontiguousarray(flat, dtype=np.float64)
        w, sk = flat.shape[0], self._skip
        total = np.empty((w, self.n))
        hard = np.empty((w, self.n), dtype=np.uint8)
        cw = np.empty((w, self.n), dtype=np.uint8)
        clean = np.empty(w, dtype=bool)
        word_totals(flat, self._positions64, self.k, self.k_full, _LLR_KNOWN, sk.indptr,
                    sk.indices, sk.sent, sk.unsent, sk.single, sk.min_llr, total, hard, cw, clean)
        return total, hard, clean, cw

    def prepare_reference(self, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`prepare` in NumPy (its reference: the code it replaced)."""
        w = flat.shape[0]
        # every word's LLR per codeword bit in one call: the copies of a bit added in the order
        # of the sent bits (bincount adds as np.add.at does: the same sums), words set apart
        idx = (self.positions[None, :] + self.n * np.arange(w)[:, None]).ravel()
        total = np.bincount(idx, weights=np.nan_to_num(flat).ravel(),
                            minlength=w * self.n).reshape(w, self.n)
        total[:, self.k:self.k_full] = _LLR_KNOWN
        total = np.clip(total, -_LLR_KNOWN, _LLR_KNOWN)
        hard = (total < 0).astype(np.uint8)
        clean, cw = _already_codewords(self._skip, total, hard)
        return total, hard, clean, cw


@dataclass(frozen=True, eq=False)
class _Skip:
    """What :func:`_already_codewords` needs of a code: h [m, n] int32 CSR, its parity checks;
    sent [n] bool, the codeword bits with an LLR of their own (sent, or known fillers);
    unsent [u] int64, the others (punctured); single [u] int64, for each of them a check whose
    other bits are all sent; min_llr : float, the least |LLR| of a sent bit that keeps every
    message of the first iteration from such a check nonzero (inf: never skip, the code lacks
    a single check for some unsent bit)."""

    h: sp.csr_matrix
    sent: np.ndarray
    unsent: np.ndarray
    single: np.ndarray
    min_llr: float

    @functools.cached_property
    def indptr(self) -> np.ndarray:
        """[m + 1] int64, h's row pointers (the compiled pass's)."""
        return np.ascontiguousarray(self.h.indptr, dtype=np.int64)

    @functools.cached_property
    def indices(self) -> np.ndarray:
        """[nnz] int64, h's column indices (the compiled pass's)."""
        return np.ascontiguousarray(self.h.indices, dtype=np.int64)


def _codeword_skip(h: sp.csr_matrix, positions: np.ndarray, k: int, k_full: int) -> _Skip:
    """When belief propagation provably returns a word without running it (see
    :func:`_already_codewords`), for the code of parity checks ``h`` whose sent bits are
    ``positions`` (fillers at k..k_full - 1)."""
    h = sp.csr_matrix(h, dtype=np.int32)
    n = h.shape[1]
    sent = np.zeros(n, dtype=bool)
    sent[positions] = True
    sent[k:k_full] = True
    unsent = np.flatnonzero(~sent)
    unsent_in_row = h @ (~sent).astype(np.int32)                      # [m]
    hc = h.tocsc()
    single = np.zeros(unsent.size, dtype=np.int64)
    for j, col in enumerate(unsent):
        rows = hc.indices[hc.indptr[col]:hc.indptr[col + 1]]
        rows = rows[unsent_in_row[rows] == 1]
        if rows.size == 0:
            return _Skip(h, sent, unsent, single, np.inf)
        single[j] = rows[0]
    # sum-product: a check's message to a bit is +-log((1 + t) / (1 - t)), t the product of
    # tanh(L / 2) over its other d - 1 bits; with every |L| >= min_llr, t >= 1e-12 and the
    # message is nonzero in float64 (min-sum: 0.75 min |L| > 0 for any min_llr > 0)
    d = int(np.diff(h.indptr).max())
    return _Skip(h, sent, unsent, single, float(2.0 * np.arctanh(1e-12 ** (1.0 / max(d - 1, 1)))))


def _already_codewords(skip: _Skip, total: np.ndarray, hard: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The words that belief propagation (the ``ldpc`` package, received-vector input) would
    return in its first iteration, converged, and what it returns for them: ``(clean [W] bool,
    codeword [W, n] uint8)``, the codeword meaningful where ``clean``. A word is clean when its
    hard decisions ``hard`` [W, n] on the sent bits are those of a codeword (its unsent bits
    then follow from the single checks) and its LLRs ``total`` [W, n] put every sent bit at
    least ``skip.min_llr`` from 0.

    The package decodes the error pattern e of ``hard`` (H e = s, s = H hard) from error
    probabilities p = 1 / (1 + e^|L|), initial messages log((1 - p) / p) > 0 on the sent bits
    and 0 on the unsent ones (hard decision 0). In the first iteration, a check with an unsent
    bit sends its other bits a message of magnitude 0 (a factor tanh(0) in the product, or the
    minimum 0 in min-sum); a check with only sent bits has s_i = 0 (the hard decisions are a
    codeword's there) and sends positive messages; so every sent bit's belief stays positive
    (e = 0 there). An unsent bit j receives from each single check i a nonzero message of sign
    (-1)^(s_i) (all other messages nonnegative), and s_i = c_j, the codeword's bit, for each of
    them; from checks with another unsent bit, messages of magnitude 0. Its belief has the sign
    of c_j: e = c on the unsent bits, which satisfies H e = s; the package stops, converged,
    and returns hard XOR e = c (tests/unit/phy/security/test_ldpc.py compares both on many
    words)."""
    w = total.shape[0]
    if not np.isfinite(skip.min_llr):
        return np.zeros(w, dtype=bool), hard
    s = (skip.h @ hard.T.astype(np.int32)) % 2                       # [m, W]
    cw = hard.copy()
    cw[:, skip.unsent] = s[skip.single].T
    clean = ~np.any((skip.h @ cw.T.astype(np.int32)) % 2, axis=0)
    strong = np.all(np.abs(total[:, skip.sent]) >= skip.min_llr, axis=1)
    return clean & strong, cw
