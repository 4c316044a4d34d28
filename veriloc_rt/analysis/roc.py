"""ROC of a threshold detector from its statistic on benign and attack points, and its AUC.

Convention (Fawcett 2006, "An introduction to ROC analysis", Pattern Recognit. Lett. 27,
Sec. 2-3): the positive class is the attack. At threshold ``t`` a point is *accepted* (valid)
iff ``stat <= t`` (``accept='<='``, a deviation) or ``stat >= t`` (``'>='``, a share); the
false-alarm rate is ``P_FA = 1 - benign_accept`` (benign points rejected), the detection rate
``P_D = attack_reject`` (attack points rejected). The curve sweeps ``t`` over every observed
value of the pooled statistics (Fawcett's Algorithm 1: one vertex per distinct value, so tied
values move the curve diagonally) plus the end that rejects everything; it runs from (0, 0)
(accept all) to (1, 1) (reject all).

The AUC is the trapezoid area under these vertices (Fawcett Sec. 7, Algorithm 3). With the
diagonal steps at ties it equals the Mann-Whitney probability
``P(attack more suspicious than benign) + P(tie) / 2`` (Hanley & McNeil 1982, Radiology 143),
which the tests check.

A statistic may be ``inf`` on the rejecting side (a rule that rejects whatever the threshold);
it may not be NaN or infinite on the accepting side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RocCurve", "auc", "operating_point", "roc_curve", "detection_at_false_alarm"]


@dataclass(frozen=True, eq=False)
class RocCurve:
    """threshold : [num_vertices] float64, in the statistic's unit (the last one rejects all);
    benign_accept, attack_reject : [num_vertices] float64, fractions in [0, 1], benign_accept
    non-increasing and attack_reject non-decreasing; accept : '<=' or '>='."""

    threshold: np.ndarray
    benign_accept: np.ndarray
    attack_reject: np.ndarray
    accept: str

    @property
    def false_alarm(self) -> np.ndarray:
        """[num_vertices] float64: P_FA = 1 - benign_accept."""
        return 1.0 - self.benign_accept


def _check(stat, name: str, accept: str) -> np.ndarray:
    s = np.asarray(stat, dtype=np.float64)
    if s.ndim != 1 or s.size == 0:
        raise ValueError(f"Argument `{name}` must be a non-empty 1-D array, not shape {s.shape}")
    if np.isnan(s).any():
        raise ValueError(f"Argument `{name}` must not hold NaN")
    if accept not in ("<=", ">="):
        raise ValueError(f"Argument `accept` must be one of '<=', '>=', not {accept!r}")
    bad = -np.inf if accept == "<=" else np.inf
    if (s == bad).any():
        raise ValueError(f"Argument `{name}` must not hold {bad} (it would be accepted at every "
                         "threshold)")
    return s


def _accepted(s: np.ndarray, t, accept: str) -> np.ndarray:
    return (s[None, :] <= np.asarray(t)[:, None]) if accept == "<=" else \
        (s[None, :] >= np.asarray(t)[:, None])


def roc_curve(benign, attack, accept: str) -> RocCurve:
    """The ROC over every observed threshold (module docstring).

    :param benign: [num_benign] float64, the statistic on benign points
    :param attack: [num_attack] float64, the statistic on attack points
    :param accept: '<=' (valid iff stat <= t) or '>=' (valid iff stat >= t)
    """
    b, a = _check(benign, "benign", accept), _check(attack, "attack", accept)
    values = np.unique(np.concatenate([b, a]))          # ascending
    if accept == "<=":
        thr = np.concatenate([values[::-1], [-np.inf]])  # accept all .. reject all
    else:
        thr = np.concatenate([values, [np.inf]])
    # counts by sorted search: O((n + m) log n)
    if accept == "<=":
        nb = np.searchsorted(np.sort(b), thr, side="right")
        na = np.searchsorted(np.sort(a), thr, side="right")
    else:
        nb = b.size - np.searchsorted(np.sort(b), thr, side="left")
        na = a.size - np.searchsorted(np.sort(a), thr, side="left")
    return RocCurve(thr, nb / b.size, 1.0 - na / a.size, accept)


def auc(curve: RocCurve) -> float:
    """Area under the ROC, trapezoid rule over its vertices (Fawcett 2006, Algorithm 3)."""
    fa, pd = curve.false_alarm, curve.attack_reject
    return float(np.sum(np.diff(fa) * (pd[1:] + pd[:-1]) / 2.0))


def operating_point(benign, attack, threshold: float, accept: str) -> tuple[float, float]:
    """(benign_accept, attack_reject) at ``threshold``: the point a detector configured with
    it has on its ROC (a vertex of :func:`roc_curve`)."""
    b, a = _check(benign, "benign", accept), _check(attack, "attack", accept)
    return (float(_accepted(b, [threshold], accept).mean()),
            float(1.0 - _accepted(a, [threshold], accept).mean()))


def detection_at_false_alarm(curve: RocCurve, false_alarm: float) -> tuple[float, float, float]:
    """(threshold, P_FA, P_D) of the vertex with the highest P_D among those with
    ``P_FA <= false_alarm`` (a deterministic test: no randomisation between vertices).
    The first vertex (accept all, P_FA 0) always qualifies."""
    ok = np.flatnonzero(curve.false_alarm <= false_alarm)
    j = ok[np.argmax(curve.attack_reject[ok])]
    return float(curve.threshold[j]), float(curve.false_alarm[j]), float(curve.attack_reject[j])
