"""The tracker with a per-fix measurement covariance (detectors.tracking.measurement_noise)."""

import numpy as np
import pytest

from veriloc_rt.config import config_from_dict
from veriloc_rt.config.detectors import TrackingConfig
from veriloc_rt.detectors.tracking import MIN_R_M2, KalmanTracker
from veriloc_rt.errors import InputError


def test_r_equal_to_the_fixed_one_changes_nothing():
    cfg = TrackingConfig(meas_std_m=4.0)
    a, b = KalmanTracker(cfg), KalmanTracker(cfg)
    rng = np.random.default_rng(3)
    for k in range(20):
        z = np.array([2.0 * k, 1.0]) + rng.normal(0, 3, 2)
        va, vb = a(z), b(z, None, 16.0 * np.eye(2))
        assert va.stat == vb.stat and np.array_equal(va.covariance, vb.covariance)


def test_update_with_a_given_r_is_the_kalman_update():
    cfg = TrackingConfig(meas_std_m=5.0, gate_probability=0.999999)
    t = KalmanTracker(cfg)
    r0 = np.array([[9.0, 2.0], [2.0, 4.0]])
    t(np.array([0.0, 0.0]), None, r0)
    x0, p0 = t.x.copy(), t.P.copy()
    np.testing.assert_allclose(np.diag(p0)[:2], [9.0, 4.0])
    r = np.array([[1.0, 0.3], [0.3, 2.0]])
    z = np.array([1.0, -0.5])
    v = t(z, 1.0, r)
    # the textbook update written out: predict with F, Q; K = P H^T (H P H^T + R)^-1
    f = np.eye(4)
    f[0, 2] = f[1, 3] = 1.0
    # DWNA, dt = 1 (Bar-Shalom 6.3.3), state order x, y, vx, vy
    q = cfg.accel_std_mps2**2 * np.kron([[0.25, 0.5], [0.5, 1.0]], np.eye(2))
    xp, pp = f @ x0, f @ p0 @ f.T + q
    h = np.hstack([np.eye(2), np.zeros((2, 2))])
    s = h @ pp @ h.T + r
    k = pp @ h.T @ np.linalg.inv(s)
    nu = z - xp[:2]
    assert v.nis == pytest.approx(float(nu @ np.linalg.solve(s, nu)))
    np.testing.assert_allclose(t.x, xp + k @ nu, atol=1e-12)


def test_tiny_covariances_are_floored():
    t = KalmanTracker(TrackingConfig())
    t(np.zeros(2), None, np.diag([1e-9, 1e-9]))
    np.testing.assert_allclose(np.diag(t.P)[:2], [MIN_R_M2, MIN_R_M2])


def test_fix_covariance_needs_the_weighted_fit():
    with pytest.raises(InputError) as e:
        config_from_dict({"detectors": {"tracking": {"measurement_noise": "fix_covariance"}}})
    assert e.value.field == "detectors.tracking.measurement_noise"
    cfg = config_from_dict({"detectors": {"tracking": {"measurement_noise": "fix_covariance"}},
                            "receiver": {"fix_weighting": "snr"}})
    assert cfg.weighted_fix and cfg.trp_outputs
    assert not config_from_dict({}).trp_outputs


def test_auto_takes_the_fix_covariance_exactly_when_the_fix_is_weighted():
    from veriloc_rt.detectors.registry import Tracking
    cases = [({}, "fixed"),                                            # 3 TRPs: unweighted fit
             ({"topology": {"num_trps": 4}}, "fix_covariance"),        # auto weighting, > 3
             ({"topology": {"num_trps": 9}, "receiver": {"fix_weighting": "equal"}}, "fixed"),
             ({"receiver": {"fix_weighting": "snr"}}, "fix_covariance"),
             ({"topology": {"num_trps": 9},
               "detectors": {"tracking": {"measurement_noise": "fixed"}}}, "fixed")]
    for data, want in cases:
        cfg = config_from_dict(data)
        assert cfg.tracking_measurement_noise == want, data
        assert Tracking.from_config(cfg).cfg.tracking.measurement_noise == want, data
