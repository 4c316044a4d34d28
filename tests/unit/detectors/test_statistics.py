"""Each detector's statistic reproduces its verdict exactly (detectors.statistics), and the
verdicts are those of the rules the detectors' docstrings state, re-implemented here from the
text on random inputs (tags, ABSA, handshake) and random tracks with gaps and jumps (tracking:
the M-of-N rule replayed from the epochs' NIS and modes)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from veriloc_rt.config import config_from_dict
from veriloc_rt.config.detectors import (ABSAConfig, HandshakeConfig, TagDetectorConfig,
                                         TrackingConfig)
from veriloc_rt.detectors import ABSADetector, HandshakeDetector, KalmanTracker, TagDetector
from veriloc_rt.detectors.absa import angle_difference
from veriloc_rt.detectors.statistics import (STAT_COLUMNS, STATISTICS, accepts,
                                             configured_thresholds)

CASES = 400


def _tag_rule(tv, det, cfg):
    """The docstring's rule: every detected BS verified (share of checked slots >= f), the
    undetected rule, at least min_verified_bs verified."""
    verified = []
    for row, d in zip(tv, det):
        checked = [x for x in row if not math.isnan(x)]
        share = sum(checked) / len(checked) if checked else 0.0
        verified.append(bool(d and checked and share >= cfg.min_valid_fraction))
    ok = all(v for v, d in zip(verified, det) if d)
    if cfg.undetected == "invalid" and not all(det):
        ok = False
    return ok and sum(verified) >= cfg.min_verified_bs


def test_tag_statistic_gives_the_rule():
    rng = np.random.default_rng(1)
    for _ in range(CASES):
        frac = float(rng.choice([0.1, 0.3, 0.5, 2 / 3, 0.7, 1.0]))
        cfg = TagDetectorConfig(min_valid_fraction=frac,
                                undetected=str(rng.choice(["invalid", "ignore"])),
                                min_verified_bs=int(rng.integers(0, 4)))
        nbs, nslots = int(rng.integers(1, 4)), int(rng.integers(1, 11))
        tv = (rng.random((nbs, nslots)) < rng.random()).astype(float)
        tv[rng.random((nbs, nslots)) < 0.2] = np.nan
        det = rng.random(nbs) < 0.85
        v = TagDetector(cfg)(tv, det)
        assert v.valid == (v.stat >= cfg.min_valid_fraction) == _tag_rule(tv, det, cfg)
        assert 0.0 <= v.stat <= 1.0


def test_absa_statistic_gives_the_rule():
    rng = np.random.default_rng(2)
    bs = np.array([[100.0, 0.0], [-50.0, 90.0], [-50.0, -90.0]])
    for _ in range(CASES):
        cfg = ABSAConfig(threshold_deg=float(rng.choice([5.0, 20.0, 45.0])),
                         missing_estimate=str(rng.choice(["invalid", "ignore"])),
                         unchecked_verdict=bool(rng.random() < 0.5))
        ue = rng.normal(0, 20, 2) if rng.random() < 0.9 else None
        ref = ABSADetector(cfg).reference_azimuth(bs, ue)
        az = ref + np.radians(rng.normal(0, cfg.threshold_deg, 3)) if ue is not None \
            else rng.uniform(-np.pi, np.pi, 3)
        az[rng.random(3) < 0.15] = np.nan
        v = ABSADetector(cfg)(az, bs, reference_position=ue)
        checked = np.isfinite(az) & np.isfinite(ref)
        dev = np.degrees(angle_difference(az[checked], ref[checked]))
        want = bool(np.all(dev <= cfg.threshold_deg)) if checked.any() else cfg.unchecked_verdict
        if cfg.missing_estimate == "invalid" and np.isnan(az).any():
            want = False
        assert v.valid == (v.stat <= cfg.threshold_deg) == want


def test_absa_exact_threshold_difference_is_accepted():
    """A deviation of exactly the threshold passes although the wrap costs a few ulp."""
    bs = np.array([[100.0, 0.0]])
    ref = ABSADetector().reference_azimuth(bs, np.zeros(2))
    v = ABSADetector()(ref + math.radians(20.0), bs, reference_position=np.zeros(2))
    assert v.valid and v.stat == 20.0


def test_handshake_statistic_gives_the_rule():
    rng = np.random.default_rng(3)
    for _ in range(CASES):
        cfg = HandshakeConfig(threshold_m=20.0, ul_failure=str(rng.choice(["invalid", "valid"])))
        dl = rng.normal(0, 15, 2) if rng.random() < 0.9 else None
        ul = rng.normal(0, 15, 2) if rng.random() < 0.9 else None
        v = HandshakeDetector(cfg)(dl, ul)
        if dl is None:
            want = False
        elif ul is None:
            want = cfg.ul_failure == "valid"
        else:
            want = float(np.hypot(*(dl - ul))) <= 20.0
        assert v.valid == (v.stat <= 20.0) == want


@pytest.mark.parametrize("m,n", [(2, 2), (1, 3), (2, 3), (3, 5)])
def test_tracking_statistic_gives_the_m_of_n_rule(m, n):
    rng = np.random.default_rng(10 * m + n)
    tr = KalmanTracker(TrackingConfig(accept_m=m, window_n=n, accel_std_mps2=1.0))
    gate = tr.gate
    mode, window = "init", []
    pos = np.zeros(2)
    seen = set()
    for k in range(600):
        pos = pos + np.array([5.0, 2.0])
        z = pos + rng.normal(0, 5, 2)
        if rng.random() < 0.08:
            z = z + rng.choice([30.0, 150.0]) * rng.standard_normal(2)   # a spoofed jump
        if rng.random() < 0.05:
            z = None                                                    # DoS
        v = tr(z)
        passed = z is not None and v.nis <= gate
        if mode == "init":
            want = z is not None
        elif mode == "tracking":
            want, window = passed, []
        else:
            window = (window + [passed])[-n:]
            want = passed and sum(window) >= m
        assert v.valid == (v.stat <= gate) == want, k
        seen.add((mode, want))
        mode = v.mode
    assert {("tracking", False), ("recovery", True), ("recovery", False)} <= seen


def test_statistics_table_matches_the_config():
    cfg = config_from_dict({})
    thr = configured_thresholds(cfg.detectors)
    assert thr["HMAC"] == 0.5 and thr["ABSA"] == 20.0 and thr["Handshake"] == 20.0
    assert thr["Tracking"] == pytest.approx(3.7942, abs=1e-4)   # chi-square(2) 85 % point
    assert STAT_COLUMNS == ("hmac_stat", "digsig_stat", "absa_stat", "handshake_stat",
                            "tracking_stat")
    assert accepts([0.4, 0.5], 0.5, STATISTICS["HMAC"].accept).tolist() == [False, True]
    assert accepts([20.0, 20.1], 20.0, STATISTICS["ABSA"].accept).tolist() == [True, False]
