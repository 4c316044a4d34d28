"""What a binary code of a given length can do on the binary-input AWGN channel: the reference
the tag decoder is checked against (``tests/unit/phy/security/test_ldpc.py``).

The channel is described by the mean ``mu`` of its consistent LLRs, L ~ N(mu, 2 mu) for a sent 0
(BPSK at Es/N0 = mu / 4 per real dimension). With i = log2(1 + e^-L), its capacity is 1 - E[i]
and its dispersion E[i^2] - E[i]^2; the normal approximation of Polyanskiy, Poor and Verdu
(IEEE Trans. IT 2010, with the 1/2 log n term) gives the block error rate of the best (n, k)
code: Q((n C - k + log2(n) / 2) / sqrt(n V)).
"""

from __future__ import annotations

import numpy as np
from scipy import integrate, optimize, stats

__all__ = ["bi_awgn_info_moments", "bi_awgn_mu_at_capacity", "normal_approximation_bler"]


def bi_awgn_info_moments(mu: float) -> tuple[float, float]:
    """E[i] and E[i^2] of i = log2(1 + e^-L), L ~ N(mu, 2 mu) (numerical integration over
    +-12 standard deviations)."""
    sd = np.sqrt(2 * mu)
    lim = (mu - 12 * sd, mu + 12 * sd)
    info = lambda x: np.log2(1 + np.exp(-x))  # noqa: E731
    return (integrate.quad(lambda x: info(x) * stats.norm.pdf(x, mu, sd), *lim)[0],
            integrate.quad(lambda x: info(x) ** 2 * stats.norm.pdf(x, mu, sd), *lim)[0])


def bi_awgn_mu_at_capacity(capacity: float) -> float:
    """The LLR mean at which the channel's capacity is ``capacity`` bits (0 < capacity < 1)."""
    return float(optimize.brentq(lambda m: 1 - bi_awgn_info_moments(m)[0] - capacity, 0.01, 50.0))


def normal_approximation_bler(mu: float, n: int, k: int) -> float:
    """Block error rate of the best (n, k) code on the channel of LLR mean ``mu``."""
    m1, m2 = bi_awgn_info_moments(mu)
    return float(stats.norm.sf((n * (1 - m1) - k + 0.5 * np.log2(n)) / np.sqrt(n * (m2 - m1 ** 2))))
