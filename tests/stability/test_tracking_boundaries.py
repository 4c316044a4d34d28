"""Where the Kalman tracking detector fails after long coasting.

Coasting (no fused measurement: DoS or rejection) only predicts: the position variance grows
as ``a + 2 k dt c + k^2 dt^2 b + q dt^4 k (4 k^2 - 1) / 12`` after k predictions from a
posterior [[a, c], [c, b]] per axis (DWNA, closed form derived in
tests/unit/detectors/test_tracking.py), the gate is the chi-square(2) 85 % point
gamma = -2 ln 0.15 = 3.7942, and recovery needs M = 2 of the last N = 2 recovery epochs to
pass. Every boundary below is predicted from those three facts and found exactly (noise-free
measurements, default config: q = (1 m/s^2)^2, R = (5 m)^2, dt = 1 s). Boundaries found:

* **manoeuvre during an outage** (the UE accelerates at a during a DoS of k epochs and keeps
  accelerating): the CV prediction misses by a k^2 / 2 while the variance grows as q k^3 / 3,
  so the NIS at resumption grows ~ 3 a^2 k / (4 q): the track is recovered after outages of up
  to 90 / 28 / 10 / 4 epochs for a = 0.25 / 0.5 / 1 / 2 m/s^2, and never after one epoch more
  (every later epoch invalid: a DoS turned into a permanent track loss). A target that does not
  manoeuvre is recovered after any outage (tested up to 200 epochs), always at the second
  resumed epoch (the M-of-N cost).
* **constant-offset spoof vs covariance inflation**: an offset D is held off while
  D^2 > gamma (P_xx + R) and re-accepted at the second consecutive pass: after 10 / 18 / 29 / 48
  epochs for D = 50 / 100 / 200 / 400 m (~ D^0.75 here, D^(2/3) asymptotically).
"""

import numpy as np
import pytest

from veriloc_rt.detectors.tracking import KalmanTracker
from veriloc_rt.config.detectors import TrackingConfig

CFG = TrackingConfig()
GAMMA = -2.0 * np.log(1.0 - CFG.gate_probability)
R = CFG.meas_std_m ** 2
Q = CFG.accel_std_mps2 ** 2
DT = CFG.dt_s
#: epochs of clean constant-velocity track before the outage / attack
LEAD = 40
VX = 8.0


def _coasted_var(p0, k, axis):
    """Position variance after k DWNA predictions from posterior p0 (closed form)."""
    a, b, c = p0[axis, axis], p0[axis + 2, axis + 2], p0[axis, axis + 2]
    return a + 2 * k * DT * c + k**2 * DT**2 * b + Q * DT**4 * k * (4 * k**2 - 1) / 12


def _lead_in():
    trk = KalmanTracker(CFG)
    for i in range(LEAD):
        assert trk(np.array([VX * i, 0.0])).valid
    return trk, trk.P.copy()


def _outage(accel, k, after=30):
    """Valid flags of the epochs after an outage of k epochs; the UE accelerates (in y) at
    ``accel`` from the first outage epoch on."""
    trk, _ = _lead_in()
    out = []
    for i in range(LEAD, LEAD + k + after):
        t = i - LEAD
        z = np.array([VX * i, 0.5 * accel * t**2])
        v = trk(None if i < LEAD + k else z)
        assert np.all(np.isfinite(v.position)) and np.all(np.isfinite(v.covariance))
        out.append(v.valid)
    return out[k:]


def _largest_recoverable_outage(accel, p0):
    """Re-acceptance needs both resumed epochs k and k + 1 to pass (2-of-2 over the recovery
    epochs; the outage epochs count as failures). The second, worse one: offset a (k + 1)^2 / 2
    against a prediction k + 2 steps from the last update."""
    def nis_second(k):
        return (0.5 * accel * (k + 1) ** 2) ** 2 / (_coasted_var(p0, k + 2, 1) + R)
    k = 1
    while nis_second(k + 1) <= GAMMA:
        k += 1
    return k


@pytest.mark.parametrize("accel, expect", [(0.25, 90), (0.5, 28), (1.0, 10), (2.0, 4)])
def test_manoeuvre_during_outage_loses_the_track_beyond_the_predicted_length(accel, expect):
    _, p0 = _lead_in()
    k_max = _largest_recoverable_outage(accel, p0)
    assert k_max == expect
    # the asymptote 4 gamma q / (3 a^2) ignores R and the initial P: it under-predicts
    assert k_max >= 4 * GAMMA * Q / (3 * accel**2)
    # works at k_max: first resumed epoch invalid (1 of 2), second re-accepted
    assert _outage(accel, k_max)[:2] == [False, True]
    # fails one epoch later: never re-accepted (the NIS keeps growing while coasting)
    assert not any(_outage(accel, k_max + 1))


@pytest.mark.parametrize("k", [1, 10, 60, 200])
def test_no_manoeuvre_is_recovered_after_any_outage(k):
    assert _outage(0.0, k, after=5) == [False, True, True, True, True]


def _reacceptance_epoch(offset_m, p0):
    """Attack epoch j = 0 is rejected in tracking mode (recovery starts after it); j >= 1 are
    recovery epochs with NIS D^2 / (P_xx(j + 1) + R); accepted at the first j >= 2 passing
    after a pass."""
    passes = [offset_m**2 / (_coasted_var(p0, j + 1, 0) + R) <= GAMMA for j in range(400)]
    assert not passes[0]
    return next(j for j in range(2, 400) if passes[j] and passes[j - 1])


@pytest.mark.parametrize("offset_m, expect", [(50.0, 10), (100.0, 18), (200.0, 29), (400.0, 48)])
def test_constant_offset_spoof_is_held_off_until_the_gate_inflates(offset_m, expect):
    trk, p0 = _lead_in()
    j_acc = _reacceptance_epoch(offset_m, p0)
    assert j_acc == expect
    valid = []
    for j in range(j_acc + 3):
        i = LEAD + j
        valid.append(trk(np.array([VX * i + offset_m, 0.0])).valid)
    # held off exactly until j_acc, then fused (and tracked: the spoof is now the track)
    assert valid == [False] * j_acc + [True] * 3
