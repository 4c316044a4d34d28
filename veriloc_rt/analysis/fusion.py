"""Fused decisions over the five detectors: k-of-n voting, Neyman-Pearson likelihood-ratio test.

**k-of-n voting** (Varshney 1997, "Distributed Detection and Data Fusion", Sec. 3.3, the
counting rule): the fused point is rejected iff at least ``k`` of the ``n`` detectors reject it.
As a statistic: the number of rejecting detectors, valid iff ``votes <= k - 1``; sweeping k from
n + 1 down to 0 gives its ROC (k = 1: any detector rejects; k = n: all do).

**Neyman-Pearson fusion** of the detectors' statistics. By the Neyman-Pearson lemma the most
powerful test at false-alarm rate alpha thresholds the likelihood ratio
``L(s) = p(s | attack) / p(s | benign)`` (Neyman & Pearson 1933; Kay 1998, "Fundamentals of
Statistical Signal Processing, Vol. II", Theorem 3.1). The densities are unknown, so the score
is a *naive-Bayes* estimate of ``log L``: the sum over detectors of
``log p_1(s_j) - log p_0(s_j)``, each factor a histogram of that detector's statistic on the
fitting points (bin edges at the pooled quantiles, a separate bin for ``inf``, add-one-half
(Jeffreys) smoothing of the counts). For a binary statistic this is the Chair-Varshney fusion
rule (Chair & Varshney 1986, IEEE Trans. AES 22(1)). The detectors are not independent, so the
score is not the true likelihood ratio and the test is not the most powerful one; but its
threshold is the empirical (1 - alpha) quantile of the scores of *held-out benign* points (the
smallest threshold whose share of those scores above it is at most alpha, no randomisation),
so the false-alarm rate is held whatever the model error: the model only costs detection power.
This is the sample-splitting construction of Neyman-Pearson classification (Tong, Feng & Li
2018, "Neyman-Pearson classification algorithms and NP receiver operating characteristics",
Sci. Adv. 4: the class-0 scores that set the threshold are not those the score was fitted on;
on its own fitting points the score is optimistic and the false alarm would be far above
alpha on small runs).

Fitting, calibrating and evaluating on the same points would overstate the rates, so the points
are split by trajectory index into three parts (:func:`split_by_index`): :data:`FIT` (the
histograms), :data:`CALIBRATE` (the threshold, benign points only) and :data:`TEST` (the ROC,
AUC and operating point).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CALIBRATE", "FIT", "NaiveBayesLR", "TEST", "kofn_votes", "np_threshold",
           "split_by_index"]

#: the parts of :func:`split_by_index`: the score's fitting, the threshold's calibration, the
#: evaluation
FIT, CALIBRATE, TEST = 0, 1, 2

#: histogram bins per statistic (at most; ties merge quantile edges)
NUM_BINS = 12
#: additive smoothing of the histogram counts (Jeffreys prior: 1/2 per bin)
SMOOTHING = 0.5


def kofn_votes(valid) -> np.ndarray:
    """[num_points] int64: detectors that reject each point. valid : [num_points, n] bool."""
    v = np.asarray(valid, dtype=bool)
    if v.ndim != 2:
        raise ValueError(f"Argument `valid` must have shape [num_points, n], not {v.shape}")
    return (~v).sum(axis=1).astype(np.int64)


def split_by_index(num_points: int, rng: np.random.Generator, block: int,
                   num_parts: int = 3) -> np.ndarray:
    """[num_points] int64, each index's part in ``0 .. num_parts - 1`` (:data:`FIT`,
    :data:`CALIBRATE`, :data:`TEST`): consecutive blocks of ``block`` indices (neighbouring
    points share the tracker's state and the channel, so a block keeps them in one part), the
    blocks in a random order dealt to the parts in turn (part sizes differ by at most a block)."""
    if num_points < 1 or block < 1 or num_parts < 1:
        raise ValueError(f"Arguments `num_points` {num_points}, `block` {block} and "
                         f"`num_parts` {num_parts} must be >= 1")
    num_blocks = -(-num_points // block)
    part = np.empty(num_blocks, np.int64)
    part[rng.permutation(num_blocks)] = np.arange(num_blocks) % num_parts
    return part[np.arange(num_points) // block]


@dataclass(frozen=True, eq=False)
class _Histogram:
    edges: np.ndarray       # [num_edges] float64, finite, ascending
    log_ratio: np.ndarray   # [num_edges + 2] float64: bins below/between/above edges, then inf

    def bin(self, x: np.ndarray) -> np.ndarray:
        idx = np.searchsorted(self.edges, x, side="right")
        return np.where(np.isposinf(x), self.edges.size + 1, idx)


class NaiveBayesLR:
    """Naive-Bayes log-likelihood-ratio score of the detectors' statistics (module docstring).

    :param benign: [num_benign, num_stats] float64, the statistics on benign training points
    :param attack: [num_attack, num_stats] float64, the same on attack training points
    """

    def __init__(self, benign, attack):
        b, a = np.asarray(benign, dtype=np.float64), np.asarray(attack, dtype=np.float64)
        if b.ndim != 2 or a.ndim != 2 or b.shape[1] != a.shape[1] or not (b.size and a.size):
            raise ValueError(f"Arguments `benign` {b.shape} and `attack` {a.shape} must be "
                             "non-empty [num_points, num_stats] with the same num_stats")
        if np.isnan(b).any() or np.isnan(a).any() or np.isneginf(b).any() or np.isneginf(a).any():
            raise ValueError("Arguments `benign` and `attack` must not hold NaN or -inf")
        self.histograms = [self._fit(b[:, j], a[:, j]) for j in range(b.shape[1])]

    @staticmethod
    def _fit(b: np.ndarray, a: np.ndarray) -> _Histogram:
        pooled = np.concatenate([b, a])
        finite = pooled[np.isfinite(pooled)]
        q = np.linspace(0.0, 1.0, NUM_BINS + 1)[1:-1]
        edges = np.unique(np.quantile(finite, q)) if finite.size else np.zeros(0)
        h = _Histogram(edges, np.zeros(edges.size + 2))
        nbins = edges.size + 2
        c0 = np.bincount(h.bin(b), minlength=nbins) + SMOOTHING
        c1 = np.bincount(h.bin(a), minlength=nbins) + SMOOTHING
        return _Histogram(edges, np.log(c1 / c1.sum()) - np.log(c0 / c0.sum()))

    def score(self, stats) -> np.ndarray:
        """[num_points] float64: estimated log L (large: attack-like). stats : [num_points,
        num_stats] float64."""
        s = np.asarray(stats, dtype=np.float64)
        if s.ndim != 2 or s.shape[1] != len(self.histograms):
            raise ValueError(f"Argument `stats` must have shape [num_points, "
                             f"{len(self.histograms)}], not {s.shape}")
        return np.sum([h.log_ratio[h.bin(s[:, j])] for j, h in enumerate(self.histograms)],
                      axis=0)


def np_threshold(benign_score, false_alarm: float) -> float:
    """The smallest threshold tau over the benign scores with ``mean(score > tau) <= alpha``
    (reject iff score > tau; valid iff score <= tau). benign_score : [num_benign] float64."""
    s = np.sort(np.asarray(benign_score, dtype=np.float64))
    if s.ndim != 1 or s.size == 0 or not 0.0 <= false_alarm < 1.0:
        raise ValueError("Arguments `benign_score` must be non-empty 1-D and `false_alarm` in "
                         f"[0, 1), not {s.shape}, {false_alarm!r}")
    values = np.unique(s)
    above = s.size - np.searchsorted(s, values, side="right")   # count of score > value
    ok = np.flatnonzero(above <= false_alarm * s.size)
    return float(values[ok[0]])
