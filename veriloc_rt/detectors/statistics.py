"""Each detector's decision statistic: its CSV column, direction, unit and configured threshold.

Every detector decides by comparing one number per point with its configured threshold, and the
verdict *is* that comparison (each detector computes the verdict from the statistic, one code
path): valid iff ``stat <= threshold`` (ABSA, Handshake, Tracking: a deviation) or
``stat >= threshold`` (HMAC, DigSig: a verified share). Sweeping the threshold over the observed
statistics gives the detector's ROC (:mod:`veriloc_rt.analysis.roc`). Rules that reject or accept
whatever the threshold (a missing fix, an undetected BS) give ``inf`` or the statistic's
accepting end (0 for a deviation, 1 for a share); the detectors' module docstrings say which.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


from ..config.detectors import DetectorsConfig
from .outcomes import DETECTORS, TRP_DETECTORS
from .tracking import nis_gate

__all__ = ["ACCEPT_AT_MOST", "ACCEPT_AT_LEAST", "STATISTICS", "STAT_COLUMNS", "Statistic",
           "TRP_STATISTICS", "TRP_STAT_COLUMNS", "accepts", "auth_share_verdict",
           "configured_thresholds", "integrity_verdict"]

#: valid iff stat <= threshold
ACCEPT_AT_MOST = "<="
#: valid iff stat >= threshold
ACCEPT_AT_LEAST = ">="


@dataclass(frozen=True)
class Statistic:
    """detector : its name (:data:`DETECTORS`); column : the results CSV column; accept :
    :data:`ACCEPT_AT_MOST` or :data:`ACCEPT_AT_LEAST`; unit : its unit ('' dimensionless);
    threshold_field : the config field (under ``detectors.``) its threshold comes from;
    doc : what it is."""

    detector: str
    column: str
    accept: str
    unit: str
    threshold_field: str
    doc: str


STATISTICS = {s.detector: s for s in (
    Statistic("HMAC", "hmac_stat", ACCEPT_AT_LEAST, "", "hmac.min_valid_fraction",
              "HMAC tags: the weakest counted serving BS's share of checked slots whose tag "
              "verified; 0 when an undetected BS or too few detected BSs reject the point"),
    Statistic("DigSig", "digsig_stat", ACCEPT_AT_LEAST, "", "digsig.min_valid_fraction",
              "the same for the Ed25519 signature tags"),
    Statistic("ABSA", "absa_stat", ACCEPT_AT_MOST, "deg", "absa.threshold_deg",
              "largest |AoA - reference azimuth| over the checked BSs, deg (1e-9 deg "
              "resolution); inf when a missing AoA or no checked BS rejects the point"),
    Statistic("Handshake", "handshake_stat", ACCEPT_AT_MOST, "m", "handshake.threshold_m",
              "distance between the DL and the UL fix, m; inf when a missing fix rejects the "
              "point"),
    Statistic("Tracking", "tracking_stat", ACCEPT_AT_MOST, "", "tracking.gate_probability",
              "Kalman NIS of the DL fix against the prediction (in recovery: the larger of it "
              "and the window's M-th smallest NIS); inf without a fix, 0 for the fix that "
              "starts the track; threshold: the chi-square(2) gate of "
              "`detectors.tracking.gate_probability`"),
)}
assert tuple(STATISTICS) == DETECTORS

#: the statistics' results CSV columns, in :data:`DETECTORS` order
STAT_COLUMNS = tuple(STATISTICS[d].column for d in DETECTORS)

#: the statistics of :data:`TRP_DETECTORS` (runs with more than three TRPs)
TRP_STATISTICS = {s.detector: s for s in (
    Statistic("Integrity", "integrity_stat", ACCEPT_AT_MOST, "", "receiver.integrity_false_alarm",
              "-log10 of the p-value of the weighted fix's first chi-square(N - 3) integrity "
              "test, before any exclusion (0 when the fix has no redundancy, inf without a "
              "fix); threshold: -log10 of the test's size `receiver.integrity_false_alarm` "
              "(the field is the receiver's, not under `detectors.`)"),
    Statistic("AuthShare", "authshare_stat", ACCEPT_AT_LEAST, "", "min_auth_share",
              "share of the DL fix's TRPs whose tags verified (per-anchor authentication); 0 "
              "without a fix or without checked tags"),
)}
assert tuple(TRP_STATISTICS) == TRP_DETECTORS

#: their results CSV columns, in :data:`TRP_DETECTORS` order
TRP_STAT_COLUMNS = tuple(TRP_STATISTICS[d].column for d in TRP_DETECTORS)


def configured_thresholds(cfg: DetectorsConfig,
                          integrity_false_alarm: float | None = None) -> dict[str, float]:
    """``{detector: threshold}`` in each statistic's unit (Tracking: the NIS gate); with
    ``integrity_false_alarm`` (``receiver.integrity_false_alarm``) also the
    :data:`TRP_DETECTORS`' (Integrity: -log10 of the test's size)."""
    out = {"HMAC": cfg.hmac.min_valid_fraction, "DigSig": cfg.digsig.min_valid_fraction,
           "ABSA": cfg.absa.threshold_deg, "Handshake": cfg.handshake.threshold_m,
           "Tracking": nis_gate(cfg.tracking.gate_probability)}
    if integrity_false_alarm is not None:
        out["Integrity"] = float(-np.log10(integrity_false_alarm))
        out["AuthShare"] = cfg.min_auth_share
    return out


def integrity_verdict(fix, false_alarm: float) -> tuple[bool, float]:
    """(valid, statistic) of the Integrity detector for a DL fix
    (:class:`~veriloc_rt.phy.receiver.multilateration.MultilaterationResult`): the statistic is
    -log10 of the p-value of its first chi-square test (``test_chi2`` with ``test_dof`` degrees
    of freedom, before any exclusion), so that valid iff no fault was detected, i.e.
    p >= ``false_alarm``; ``inf`` (invalid) without a fix; 0 (valid) for a fix with no
    redundancy (no test)."""
    if not fix.ok:
        return False, float("inf")
    if fix.test_dof <= 0:
        return True, 0.0
    # imported here: scipy.stats is a chain-only package (a resume that computes no chain
    # does not load it; tests/unit/test_lazy_imports.py)
    from scipy.stats import chi2

    stat = float(-chi2.logsf(fix.test_chi2, fix.test_dof) / np.log(10.0))
    stat = max(stat, 0.0)       # logsf(0) is -0.0 up to rounding
    return bool(accepts(stat, -np.log10(false_alarm), ACCEPT_AT_MOST)), stat


def auth_share_verdict(share: float, min_share: float) -> tuple[bool, float]:
    """(valid, statistic) of the AuthShare detector: the share of the fix's TRPs whose tags
    verified (NaN without a fix or tags: 0), valid iff at least ``min_share``."""
    stat = 0.0 if not np.isfinite(share) else float(share)
    return bool(accepts(stat, min_share, ACCEPT_AT_LEAST)), stat


def accepts(stat, threshold: float, accept: str) -> np.ndarray:
    """[...] bool: valid at ``threshold``. stat : [...] float64 in the statistic's unit."""
    s = np.asarray(stat, dtype=np.float64)
    if accept == ACCEPT_AT_MOST:
        return s <= threshold
    if accept == ACCEPT_AT_LEAST:
        return s >= threshold
    raise ValueError(f"Argument `accept` must be one of '<=', '>=', not {accept!r}")
