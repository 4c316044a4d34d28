"""Each detector's decision statistic: its CSV column, direction, unit and configured threshold.

Every detector decides by comparing one number per point with its configured threshold, and the
verdict *is* that comparison (each detector computes the verdict from the statistic, one code
path): valid iff ``stat <= threshold`` (ABSA, Handshake, Tracking: a deviation) or
``stat >= threshold`` (HMAC, DigSig: a verified share). Sweeping the threshold over the observed
statistics gives the detector's ROC (:mod:`veriloc_rt.report.roc`). Rules that reject or accept
whatever the threshold (a missing fix, an undetected BS) give ``inf`` or the statistic's
accepting end (0 for a deviation, 1 for a share); the detectors' module docstrings say which.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.detectors import DetectorsConfig
from .outcomes import DETECTORS
from .tracking import nis_gate

__all__ = ["ACCEPT_AT_MOST", "ACCEPT_AT_LEAST", "STATISTICS", "STAT_COLUMNS", "Statistic",
           "accepts", "configured_thresholds"]

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


def configured_thresholds(cfg: DetectorsConfig) -> dict[str, float]:
    """``{detector: threshold}`` in each statistic's unit (Tracking: the NIS gate)."""
    return {"HMAC": cfg.hmac.min_valid_fraction, "DigSig": cfg.digsig.min_valid_fraction,
            "ABSA": cfg.absa.threshold_deg, "Handshake": cfg.handshake.threshold_m,
            "Tracking": nis_gate(cfg.tracking.gate_probability)}


def accepts(stat, threshold: float, accept: str) -> np.ndarray:
    """[...] bool: valid at ``threshold``. stat : [...] float64 in the statistic's unit."""
    s = np.asarray(stat, dtype=np.float64)
    if accept == ACCEPT_AT_MOST:
        return s <= threshold
    if accept == ACCEPT_AT_LEAST:
        return s >= threshold
    raise ValueError(f"Argument `accept` must be one of '<=', '>=', not {accept!r}")
