"""Compiled kernel of :meth:`~veriloc_rt.phy.security.ldpc.NRLDPC.decode`'s own work around
belief propagation (:mod:`~veriloc_rt.phy.jit`): each word's LLR per codeword bit, its hard
decisions and the codeword skip (``ldpc._already_codewords``, the NumPy reference), in one pass
instead of a dozen NumPy calls and two sparse products per decode.

Exact: the LLRs of a bit's copies are added in the order of the sent bits from 0.0 (as
``np.bincount`` adds them), NaN and infinities mapped as ``np.nan_to_num`` maps them, the clip
is ``np.clip``'s (NaN stays NaN), and the rest is integer and boolean arithmetic; so it replaces
the NumPy code outright (tests/unit/phy/security/test_ldpc_kernels.py compares both).
"""

from __future__ import annotations

from ..jit import kernel

__all__ = ["word_totals"]


@kernel
def word_totals(flat, positions, k, k_full, known, indptr, indices, sent, unsent, single,
                min_llr, total, hard, cw, clean):
    """Fill ``total``, ``hard``, ``cw`` and ``clean`` for the received words ``flat``.

    total[w, c] = clip(sum of nan_to_num(flat[w, j]) over j with positions[j] = c, in j's
    order, from 0.0; ``known`` on the fillers k..k_full - 1; clipped to +-known);
    hard = total < 0; cw = hard with each unsent bit u set to the parity of the hard decisions
    on its single check ``single[u]``; clean[w]: cw satisfies every check of the CSR matrix
    (``indptr``, ``indices``) and every ``sent`` bit has |total| >= min_llr (never when
    min_llr is infinite).

    :param flat: [W, e] float64; positions: [e] int64; sent: [n] bool; unsent, single: [u]
        int64; total: [W, n] float64; hard, cw: [W, n] uint8; clean: [W] bool (outputs)
    """
    n = total.shape[1]
    m = indptr.size - 1
    big = 1.7976931348623157e308
    for w in range(flat.shape[0]):
        for c in range(n):
            total[w, c] = 0.0
        for j in range(flat.shape[1]):
            x = flat[w, j]
            if x != x:
                x = 0.0
            elif x > big:
                x = big
            elif x < -big:
                x = -big
            total[w, positions[j]] += x
        for c in range(k, k_full):
            total[w, c] = known
        for c in range(n):
            x = total[w, c]
            if x < -known:
                x = -known
            elif x > known:
                x = known
            total[w, c] = x
            hard[w, c] = 1 if x < 0.0 else 0
            cw[w, c] = hard[w, c]
        ok = min_llr <= big
        if ok:
            for c in range(n):
                if sent[c] and not abs(total[w, c]) >= min_llr:
                    ok = False
                    break
        if ok:
            for i in range(unsent.size):
                r = single[i]
                s = 0
                for p in range(indptr[r], indptr[r + 1]):
                    s ^= hard[w, indices[p]]
                cw[w, unsent[i]] = s
            for r in range(m):
                s = 0
                for p in range(indptr[r], indptr[r + 1]):
                    s ^= cw[w, indices[p]]
                if s:
                    ok = False
                    break
        clean[w] = ok
