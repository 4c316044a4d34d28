"""Where the tag decoder's information gate sits against what belief propagation can decode.

Sends random tag words of both codes (HMAC: k = 256, n = 512; DS: 512, 1024) as BPSK through
AWGN at a few SNRs, decodes each with full belief propagation (no gate), and prints per code the
least LLR information (bits per sent bit, ``llr_information``) of a word that decoded, how many
words under a few thresholds decoded, and the normal approximation's success probability of the
best code of that length at a channel capacity equal to the gate
(``DECODE_MIN_INFORMATION`` x the rate).

    .venv/bin/python scripts/ldpc_gate.py [--words 1000] [--seed 11]
"""

from __future__ import annotations

import argparse

import numpy as np

from veriloc_rt.phy.security.coding_bounds import bi_awgn_mu_at_capacity, normal_approximation_bler
from veriloc_rt.phy.security.ldpc import DECODE_MIN_INFORMATION, NRLDPC, llr_information

#: Es/N0 per QPSK symbol, dB: around the rate-1/2 code's threshold, where the words' information
#: spreads across the gate
SNRS_DB = (-1.0, -0.5, 0.0)
THRESHOLDS = (0.35, 0.40, 0.42, 0.45)


def best_code_success(capacity: float, n: int, k: int) -> float:
    """1 - the normal approximation of the best (n, k) code's block error rate on BI-AWGN of
    this capacity."""
    return 1.0 - normal_approximation_bler(bi_awgn_mu_at_capacity(capacity), n, k)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--words", type=int, default=1000, help="words per code and SNR")
    ap.add_argument("--seed", type=int, default=11)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    for k in (256, 512):
        code = NRLDPC(k, 2 * k, min_information=0.0)
        gate = DECODE_MIN_INFORMATION * code.rate
        info, right = [], []
        for snr_db in SNRS_DB:
            sd = np.sqrt(10 ** (-snr_db / 10) / 2)          # per real dimension, unit-energy QPSK
            bits = rng.integers(0, 2, (args.words, k), dtype=np.uint8)
            y = (1 - 2.0 * code.encode(bits)) / np.sqrt(2) + sd * rng.standard_normal((args.words, code.e))
            llr = np.sqrt(2) * y / sd ** 2
            dec, ok = code.decode(llr)
            info.append(llr_information(llr))
            right.append(ok & np.all(dec == bits, axis=1))
        info, right = np.concatenate(info), np.concatenate(right)
        least = f"{info[right].min():.3f}" if right.any() else "none decoded"
        print(f"k = {k}, n = {code.e}: {info.size} words at Es/N0 {SNRS_DB} dB, {int(right.sum())} decoded; "
              f"least information of a decoded word {least} bits (gate {gate:.2f})")
        for t in THRESHOLDS:
            below = info < t
            print(f"  under {t:.2f} bits: {int(below.sum())} words, {int(right[below].sum())} decoded")
        print(f"  best code of this length at capacity {gate:.2f} (normal approximation): success "
              f"{best_code_success(gate, code.e, k):.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
