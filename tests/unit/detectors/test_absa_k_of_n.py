"""ABSA with a k-of-N rule (detectors.absa.min_pass) for many TRPs."""

import math

import numpy as np
import pytest

from veriloc_rt.config.detectors import ABSAConfig
from veriloc_rt.detectors.absa import ABSADetector

UE = np.array([10.0, -5.0])


def trps(n):
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([300 * np.cos(ang), 300 * np.sin(ang), np.full(n, 25.0)], -1)


def true_az(bs):
    return np.arctan2(bs[:, 1] - UE[1], bs[:, 0] - UE[0])


@pytest.mark.parametrize("k, valid", [(0, False), (6, True), (7, True), (8, False)])
def test_k_of_n(k, valid):
    bs = trps(9)
    off = np.deg2rad([1, 2, 3, 4, 5, 6, 7, 30, 50])     # two TRPs beyond 20 deg
    v = ABSADetector(ABSAConfig(min_pass=k))(true_az(bs) + off, bs, UE)
    assert v.valid is valid
    if k:
        # the statistic is the k-th smallest deviation: valid iff it is within 20 deg
        assert v.stat == pytest.approx(np.sort([1, 2, 3, 4, 5, 6, 7, 30, 50])[k - 1], abs=1e-6)
    else:
        assert v.stat == pytest.approx(50.0, abs=1e-6)       # the paper's rule: the largest


def test_meaconing_collapses_every_arrival_to_one_direction():
    """A relay makes all N arrivals come from it: with more TRPs fewer can pass by chance."""
    bs = trps(9)
    relay = np.arctan2(-40.0 - UE[1], 25.0 - UE[0])
    v = ABSADetector(ABSAConfig(min_pass=5))(np.full(9, relay), bs, UE)
    assert not v.valid and np.sum(v.passed) < 5


def test_missing_estimates_do_not_pass():
    bs = trps(5)
    az = true_az(bs)
    az[[1, 3]] = np.nan
    v = ABSADetector(ABSAConfig(min_pass=3))(az, bs, UE)
    assert v.valid and int(v.passed.sum()) == 3
    assert ABSADetector(ABSAConfig(min_pass=4))(az, bs, UE).stat == math.inf
