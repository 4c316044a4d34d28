"""95 % confidence intervals of a run's shares, AUCs and detection rates (``*_ci95`` keys).

* Shares (``outcomes``, ``correct_decision_rate``, ``benign_accept``, ``attack_reject``, ...):
  the exact binomial (Clopper-Pearson) interval of ``k`` of ``n`` points,
  ``scipy.stats.binomtest(k, n).proportion_ci(0.95, method="exact")``: ``lo`` the 2.5 %
  quantile of Beta(k, n - k + 1) (0 when k = 0), ``hi`` the 97.5 % quantile of
  Beta(k + 1, n - k) (1 when k = n) (Clopper & Pearson 1934, Biometrika 26). It treats the
  points as independent trials; points of one drive are correlated in time, so the interval is
  the sampling error of the evaluated points, not of the scenario (an ensemble over
  realisations, ``run.realisations``, gives the spread between drives and layouts).
* The AUC and the detection rate at the target false alarm (``detectors.fusion.false_alarm``):
  a percentile bootstrap (Efron & Tibshirani 1993, "An Introduction to the Bootstrap",
  Sec. 13.3) over the points of one run (benign and attack points resampled separately, with
  replacement, :data:`BOOTSTRAP_RESAMPLES` times) with the named stream ``"bootstrap"`` of the
  run seed; over the realisations of a Monte Carlo (the mean of the realisations' values,
  realisations resampled, stream ``"bootstrap-realisations"``).
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["CI_LEVEL", "CI_SUFFIX", "BOOTSTRAP_RESAMPLES", "binomial_ci", "bootstrap_roc_ci",
           "bootstrap_mean_ci", "ci_suffix", "resampled_auc_pd"]

#: confidence level of every ``*_ci95`` interval
CI_LEVEL = 0.95
#: bootstrap resamples: the 2.5 % and 97.5 % percentiles of 1000 draws move by about
#: 0.02 x (the interval's width) from one seed to another (Efron & Tibshirani Sec. 19.3)
BOOTSTRAP_RESAMPLES = 1000
#: the sibling key of a value's interval: ``key + CI_SUFFIX``
CI_SUFFIX = "_ci95"


def ci_suffix(key: str) -> str:
    """The key of ``key``'s interval."""
    return key + CI_SUFFIX


def binomial_ci(k: int, n: int, level: float = CI_LEVEL) -> list[float] | None:
    """Clopper-Pearson interval ``[lo, hi]`` of ``k`` successes in ``n`` trials; None for
    ``n == 0`` (no points: no share)."""
    if n <= 0:
        return None
    return list(_clopper_pearson(int(k), int(n), float(level)))


@functools.lru_cache(maxsize=4096)
def _clopper_pearson(k: int, n: int, level: float) -> tuple[float, float]:
    """:func:`binomial_ci`'s bounds, each (k, n, level) computed once (SciPy finds them by
    root finding, ~4 ms a call; a run's shares repeat many counts: 0 of n, n of n)."""
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(confidence_level=level, method="exact")
    return float(ci.low), float(ci.high)


def _percentiles(x: np.ndarray, level: float) -> list[float] | None:
    x = x[np.isfinite(x)]
    if not x.size:
        return None
    a = (1.0 - level) / 2.0
    lo, hi = np.quantile(x, [a, 1.0 - a])
    return [float(lo), float(hi)]


def resampled_auc_pd(benign, attack, accept: str, false_alarm: float, ib: np.ndarray,
                     ia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """AUC and detection rate at false alarm <= ``false_alarm`` of each resample: row ``r`` of
    ``ib`` [R, num_benign] and ``ia`` [R, num_attack] (indices into ``benign`` and
    ``attack``). The same numbers as :func:`~.roc.roc_curve`, :func:`~.roc.auc` and
    :func:`~.roc.detection_at_false_alarm` on each resample, from point counts per distinct
    value, all resamples at once: the AUC is the Mann-Whitney probability that an attack
    point is more suspicious plus half the ties (Fawcett 2006, Sec. 7); the detection rate
    is the one at the lowest-false-alarm-qualifying threshold (the curve's vertex with the
    highest detection among those at false alarm <= ``false_alarm``).

    :returns: (auc [R], pd [R]) float64
    """
    b = np.asarray(benign, dtype=np.float64)
    a = np.asarray(attack, dtype=np.float64)
    if accept == ">=":   # valid iff stat >= t: the same curve as -stat with '<='
        b, a = -b, -a
    elif accept != "<=":
        raise ValueError(f"Argument `accept` must be one of '<=', '>=', not {accept!r}")
    values, inv = np.unique(np.concatenate([b, a]), return_inverse=True)
    u = values.size
    r = ib.shape[0]
    rows = np.arange(r)[:, None] * u
    cb = np.bincount((rows + inv[: b.size][ib]).ravel(), minlength=r * u).reshape(r, u)
    ca = np.bincount((rows + inv[b.size:][ia]).ravel(), minlength=r * u).reshape(r, u)
    nb, na = ib.shape[1], ia.shape[1]
    below = np.cumsum(cb, axis=1) - cb          # benign points strictly below each value
    aucs = ((ca * (below + 0.5 * cb)).sum(axis=1) / (nb * na)).astype(np.float64)
    # a threshold at value k accepts the points <= it: false alarm 1 - CB_k / nb, detection
    # 1 - CA_k / na, both non-increasing in k; the best qualifying one is the first k with
    # CB_k >= (1 - false_alarm) nb (the accept-all end, k = u - 1, always qualifies)
    cum_b, cum_a = np.cumsum(cb, axis=1), np.cumsum(ca, axis=1)
    ok = (1.0 - cum_b / nb) <= false_alarm
    k0 = np.argmax(ok, axis=1)
    pds = 1.0 - cum_a[np.arange(r), k0] / na
    return aucs, pds


def bootstrap_roc_ci(benign, attack, accept: str, false_alarm: float, rng: np.random.Generator,
                     resamples: int = BOOTSTRAP_RESAMPLES, level: float = CI_LEVEL
                     ) -> tuple[list[float] | None, list[float] | None]:
    """Percentile-bootstrap intervals of (AUC, detection rate at false alarm <=
    ``false_alarm``) of a statistic on ``benign`` and ``attack`` points (:mod:`.roc`'s
    conventions), the two sets resampled separately with replacement
    (:func:`resampled_auc_pd`)."""
    nb, na = np.size(benign), np.size(attack)
    ib = rng.integers(0, nb, (resamples, nb))
    ia = rng.integers(0, na, (resamples, na))
    aucs, pds = resampled_auc_pd(benign, attack, accept, false_alarm, ib, ia)
    return _percentiles(aucs, level), _percentiles(pds, level)


def bootstrap_mean_ci(values, rng: np.random.Generator, resamples: int = BOOTSTRAP_RESAMPLES,
                      level: float = CI_LEVEL) -> list[float] | None:
    """Percentile-bootstrap interval of the mean of ``values`` (None entries left out), the
    values resampled with replacement; None without a value."""
    x = np.array([float(v) for v in values if v is not None], dtype=np.float64)
    if not x.size:
        return None
    means = x[rng.integers(0, x.size, (resamples, x.size))].mean(axis=1)
    return _percentiles(means, level)
