"""A run's detection analysis: each detector's ROC and AUC per attack, the uninformative flag,
and the fused decisions (k-of-n vote, Neyman-Pearson fusion), from the rows the run wrote.

Points (the same as ``correct_decision_rate``, so the configured threshold's operating point
reproduces it exactly): *benign* = the ``none`` scenario's points with a fix (a DoS point is no
false alarm, as in the paper); *attack* = an attack scenario's attack-window points. The ROC math
is :mod:`.roc`, the fusion's :mod:`.fusion`.

* single detectors: the ROC of their statistic (:mod:`veriloc_rt.detectors.statistics`) over
  every benign and attack point, with the configured threshold's operating point; the five,
  then in a run with more than three TRPs the ``Integrity`` test and ``AuthShare`` (their
  statistics in every row), which also enter the vote and the NP fusion;
* ``uninformative``: a detector whose benign acceptance at its threshold is below
  ``detectors.min_benign_accept``; its attack rejections are not detections (it rejects
  everything);
* ``KofN``: the number of rejecting detectors, valid iff ``<= k - 1`` (``detectors.fusion.k``),
  over every point (nothing is fitted);
* ``NPFusion``: the trajectory's blocks split in three (:func:`.fusion.split_by_index` with the
  named stream ``"fusion-split"``); the naive-Bayes likelihood-ratio score fitted on the first
  third (the three attacks pooled as the alternative: the defender does not know which attack
  comes), its threshold at ``detectors.fusion.false_alarm`` on the second third's benign
  scores, its ROC and operating point on the last third (the *test* points) only. ``fusion.test`` compares it, on those same test
  points, with every single detector and the vote at their best threshold for that false-alarm
  rate (chosen on the test points: an oracle in the single detectors' favour).

Intervals (:mod:`.intervals`): every share (``benign_accept``, ``attack_reject``,
``false_alarm``) has a sibling ``<key>_ci95``, Clopper-Pearson over the points it counts; each
decision's ``auc`` and ``pd_at_false_alarm`` (its detection rate at the best vertex with false
alarm <= ``detectors.fusion.false_alarm``, that false alarm in ``false_alarm_at_pd``) have a
percentile bootstrap over the points (stream ``("bootstrap", decision, attack)`` of the seed).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import zlib

import numpy as np

from ..config import Config
from ..detectors.outcomes import DETECTORS, TRP_DETECTORS
from ..detectors.statistics import STATISTICS, TRP_STATISTICS, accepts, configured_thresholds
from ..rng import stream
from .fusion import CALIBRATE, FIT, TEST, NaiveBayesLR, kofn_votes, np_threshold, split_by_index
from .intervals import binomial_ci, bootstrap_roc_ci, ci_suffix
from .roc import RocCurve, auc, detection_at_false_alarm, operating_point, roc_curve

log = logging.getLogger(__name__)

__all__ = ["FUSED", "ROC_COLUMNS", "DetectionAnalysis", "analyse_detection"]

#: the fused decisions' names, after :data:`DETECTORS` in every table
FUSED = ("KofN", "NPFusion")
#: the attacks' numbers in the named bootstrap streams
_ATTACK = {"fbs": 1, "meaconing": 2, "jamming": 3}


def _attack_index(name: str) -> int:
    """The bootstrap stream's index of an attack scenario: the built-ins' fixed ones, a
    registered threat's from its name (CRC-32, above the built-ins'), so any name has one."""
    return _ATTACK.get(name, 4 + zlib.crc32(name.encode()))
#: roc.csv columns
ROC_COLUMNS = ("detector", "attack", "threshold", "benign_accept", "attack_reject")


@dataclass
class _Points:
    """One scenario's selected points: index [n] int64; stats [n, d] float64; valid [n, d]
    bool (the verdicts of the run's d detectors, :data:`DETECTORS` then the
    :data:`TRP_DETECTORS` when present)."""

    index: np.ndarray
    stats: np.ndarray
    valid: np.ndarray

    @classmethod
    def of(cls, rows: list, keep, names: tuple) -> "_Points":
        sel = [r for r in rows if keep(r)]
        return cls(np.array([r.index for r in sel], dtype=np.int64),
                   np.array([[r.stats[d] for d in names] for r in sel],
                            dtype=np.float64).reshape(-1, len(names)),
                   np.array([[r.verdicts[d] for d in names] for r in sel],
                            dtype=bool).reshape(-1, len(names)))

    def take(self, mask: np.ndarray) -> "_Points":
        return _Points(self.index[mask], self.stats[mask], self.valid[mask])


@dataclass
class DetectionAnalysis:
    """metrics : the ``roc`` block of metrics.json; curves : {(name, attack): RocCurve};
    operating : {(name, attack): (threshold, benign_accept, attack_reject)};
    uninformative : the detectors flagged."""

    metrics: dict
    curves: dict = field(default_factory=dict)
    operating: dict = field(default_factory=dict)
    uninformative: list = field(default_factory=list)

    def roc_rows(self) -> list[tuple]:
        """roc.csv rows (:data:`ROC_COLUMNS`), every curve's vertices."""
        out = []
        for (name, attack), c in self.curves.items():
            out += [(name, attack, float(t), float(b), float(a))
                    for t, b, a in zip(c.threshold, c.benign_accept, c.attack_reject)]
        return out


def _entry(curve: RocCurve, threshold: float, benign, attack, alpha: float,
           rng: np.random.Generator) -> dict:
    """One decision's entry under ``roc.attacks.<attack>``: AUC, operating point at
    ``threshold``, detection rate at false alarm <= ``alpha`` (the best vertex), each with its
    95 % interval (:mod:`.intervals`: binomial for the operating point's shares, bootstrap over
    the points from ``rng`` for the AUC and the detection rate)."""
    b, a = np.asarray(benign), np.asarray(attack)
    ba, ar = operating_point(b, a, threshold, curve.accept)
    _, fa, pd = detection_at_false_alarm(curve, alpha)
    auc_ci, pd_ci = bootstrap_roc_ci(b, a, curve.accept, alpha, rng)
    return {"auc": auc(curve), ci_suffix("auc"): auc_ci, "threshold": threshold,
            "benign_accept": ba,
            ci_suffix("benign_accept"): binomial_ci(round(ba * b.size), b.size),
            "attack_reject": ar,
            ci_suffix("attack_reject"): binomial_ci(round(ar * a.size), a.size),
            "pd_at_false_alarm": pd, ci_suffix("pd_at_false_alarm"): pd_ci,
            "false_alarm_at_pd": fa}


def analyse_detection(rows: dict, cfg: Config) -> DetectionAnalysis | None:
    """The analysis of a run's rows ``{scenario: [PointRow]}``; None without a ``none``
    scenario, without benign fixes or attack points, or without statistics in the rows."""
    attacks = [s for s in rows if s != "none" and rows[s]]
    every = [r for s in rows for r in rows[s]]
    if "none" not in rows or not attacks or any(not set(DETECTORS) <= set(r.stats)
                                                  for r in every):
        return None
    # the TRP detectors (runs with more than three TRPs) when every row has them
    dets = DETECTORS + tuple(d for d in TRP_DETECTORS
                             if all(d in r.stats and d in r.verdicts for r in every))
    benign = _Points.of(rows["none"], lambda r: r.outcome != "service_failure", dets)
    attack = {s: _Points.of(rows[s], lambda r: r.attack, dets) for s in attacks}
    attacks = [s for s in attacks if attack[s].index.size]
    if not benign.index.size or not attacks:
        return None
    det = cfg.detectors
    thr = configured_thresholds(det, cfg.receiver.integrity_false_alarm)
    stat_of = {**STATISTICS, **TRP_STATISTICS}
    k = det.fusion.k
    res = DetectionAnalysis({})
    # -- single detectors and the vote, over every point ----------------------------------
    names = {d: (benign.stats[:, j], {s: attack[s].stats[:, j] for s in attacks},
                 stat_of[d].accept, thr[d]) for j, d in enumerate(dets)}
    names["KofN"] = (kofn_votes(benign.valid), {s: kofn_votes(attack[s].valid) for s in attacks},
                     "<=", float(k - 1))
    summary: dict = {}
    alpha = det.fusion.false_alarm
    for j, (name, (b, a_by, acc, t)) in enumerate(names.items()):
        n_ok = int(accepts(b, t, acc).sum())
        ba = n_ok / b.size
        summary[name] = {"statistic": stat_of[name].column if name in stat_of else "votes",
                         "accept": acc, "threshold": t, "benign_accept": ba,
                         ci_suffix("benign_accept"): binomial_ci(n_ok, b.size),
                         "uninformative": ba < det.min_benign_accept}
        if ba < det.min_benign_accept:
            res.uninformative.append(name)
        for s in attacks:
            c = roc_curve(b, a_by[s], acc)
            res.curves[(name, s)] = c
            e = _entry(c, t, b, a_by[s], alpha, stream(cfg.seed, "bootstrap", j, _attack_index(s)))
            res.operating[(name, s)] = (t, e["benign_accept"], e["attack_reject"])
            res.metrics.setdefault("attacks", {}).setdefault(s, {})[name] = e
    # -- Neyman-Pearson fusion: fit, calibrate and evaluate on three parts of the blocks -------
    n = max(r.index for r in every) + 1
    part = split_by_index(n, stream(cfg.seed, "fusion-split"), det.fusion.split_block)
    fusion: dict = {"k": k, "false_alarm": det.fusion.false_alarm,
                    "split_block": det.fusion.split_block,
                    "fit_indices": int((part == FIT).sum()),
                    "calibration_indices": int((part == CALIBRATE).sum()),
                    "test_indices": int((part == TEST).sum())}
    b_fit, b_cal, b_te = (benign.take(part[benign.index] == p) for p in (FIT, CALIBRATE, TEST))
    a_fit = np.concatenate([attack[s].stats[part[attack[s].index] == FIT] for s in attacks])
    a_te = {s: attack[s].take(part[attack[s].index] == TEST) for s in attacks}
    sizes = [b_fit.index.size, a_fit.size, b_cal.index.size, b_te.index.size,
             *(p.index.size for p in a_te.values())]
    if all(sizes):
        model = NaiveBayesLR(b_fit.stats, a_fit)
        s_cal = model.score(b_cal.stats)
        tau = np_threshold(s_cal, det.fusion.false_alarm)
        fusion["np_threshold"] = tau
        fusion["np_calibration_false_alarm"] = float((s_cal > tau).mean())
        fusion["np_fit_false_alarm"] = float((model.score(b_fit.stats) > tau).mean())
        sb = model.score(b_te.stats)
        n_ok = int((sb <= tau).sum())
        summary["NPFusion"] = {"statistic": "naive-Bayes log-likelihood ratio", "accept": "<=",
                               "threshold": tau, "benign_accept": n_ok / sb.size,
                               ci_suffix("benign_accept"): binomial_ci(n_ok, sb.size),
                               "uninformative": False, "evaluated_on": "test indices"}
        test: dict = {}
        for s in attacks:
            sa = model.score(a_te[s].stats)
            c = roc_curve(sb, sa, "<=")
            res.curves[("NPFusion", s)] = c
            e = _entry(c, tau, sb, sa, alpha,
                       stream(cfg.seed, "bootstrap", len(names), _attack_index(s)))
            res.operating[("NPFusion", s)] = (tau, e["benign_accept"], e["attack_reject"])
            res.metrics["attacks"][s]["NPFusion"] = e
            test[s] = _test_comparison(b_te, a_te[s], sb, sa, tau, det.fusion.false_alarm, dets)
        fusion["test"] = test
    else:
        log.warning("NP fusion skipped: a part of the split has no benign or no attack point")
    res.metrics = {"benign_points": int(benign.index.size),
                   "min_benign_accept": det.min_benign_accept, "detectors": summary,
                   "uninformative": list(res.uninformative),
                   "attacks": res.metrics.get("attacks", {}), "fusion": fusion}
    return res


def _test_comparison(b_te: _Points, a_te: _Points, sb, sa, tau: float, alpha: float,
                     dets: tuple = DETECTORS) -> dict:
    """On the test points of one attack: each decision's AUC and its detection rate at
    false-alarm rate <= alpha (the NP fusion at its calibrated threshold ``tau``; the others at
    their best vertex on these points, an oracle in their favour), and ``best_single``: the
    single detector with the highest such detection rate (then the highest AUC)."""
    out: dict = {}
    stat_of = {**STATISTICS, **TRP_STATISTICS}
    for j, d in enumerate(dets):
        c = roc_curve(b_te.stats[:, j], a_te.stats[:, j], stat_of[d].accept)
        t, fa, pd = detection_at_false_alarm(c, alpha)
        out[d] = {"auc": auc(c), "threshold": t, "false_alarm": fa, "attack_reject": pd}
    c = roc_curve(kofn_votes(b_te.valid), kofn_votes(a_te.valid), "<=")
    t, fa, pd = detection_at_false_alarm(c, alpha)
    out["KofN"] = {"auc": auc(c), "threshold": t, "false_alarm": fa, "attack_reject": pd}
    out["NPFusion"] = {"auc": auc(roc_curve(sb, sa, "<=")), "threshold": tau,
                       "false_alarm": float((sb > tau).mean()),
                       "attack_reject": float((sa > tau).mean())}
    nb, na = b_te.index.size, a_te.index.size
    for e in out.values():   # Clopper-Pearson intervals of the shares on these points
        e[ci_suffix("false_alarm")] = binomial_ci(round(e["false_alarm"] * nb), nb)
        e[ci_suffix("attack_reject")] = binomial_ci(round(e["attack_reject"] * na), na)
    out["best_single"] = max(dets, key=lambda d: (out[d]["attack_reject"], out[d]["auc"]))
    return out
