"""HMAC/DS tag verdicts, ABSA angle wrapping and thresholds, DL-UL handshake boundary."""

import math

import numpy as np
import pytest

from veriloc_rt.config.fields import from_dict
from veriloc_rt.config.detectors import ABSAConfig, HandshakeConfig, TagDetectorConfig
from veriloc_rt.detectors import (ABSADetector, HandshakeDetector, TagDetector, angle_difference,
                                  geometric_azimuth, wrap_angle)
from veriloc_rt.errors import InputError

#: boundary probes sit this far either side of a threshold (well above float round-off)
EPS_DEG = 1e-6
EPS_M = 1e-6


# --- tags -------------------------------------------------------------------------------------

def test_tags_all_verified_is_valid():
    assert TagDetector()(np.array([True, True, True])).valid


def test_tags_one_forged_bs_is_invalid():
    v = TagDetector()(np.array([True, False, True]))
    assert not v.valid and list(v.verified) == [True, False, True]


def test_tags_undetected_policy():
    tv, det = np.array([True, False, True]), np.array([True, False, True])
    assert not TagDetector()(tv, det).valid  # default: undetected serving BS -> invalid (jamming)
    assert TagDetector(TagDetectorConfig(undetected="ignore"))(tv, det).valid
    none = np.zeros(3, bool)
    assert not TagDetector(TagDetectorConfig(undetected="ignore"))(tv, none).valid  # 0 verified


def test_tags_slot_fraction():
    slots = np.array([[1, 1, 0, 1], [1, 0, 0, 1], [1, 1, 1, 1]], dtype=bool)  # BS1: 2 of 4
    assert TagDetector()(slots).valid  # majority rule, 0.5 inclusive
    assert not TagDetector(TagDetectorConfig(min_valid_fraction=1.0))(slots).valid
    unchecked = np.array([[1.0, np.nan], [np.nan, np.nan], [1.0, 1.0]])
    v = TagDetector()(unchecked)
    assert not v.valid and list(v.verified) == [True, False, True]  # no checked slot: unverified


def test_tags_bad_shape():
    with pytest.raises(ValueError, match="detected"):
        TagDetector()(np.ones(3, bool), np.ones(2, bool))


# --- ABSA -------------------------------------------------------------------------------------

def test_wrap_and_difference_across_zero():
    assert math.degrees(angle_difference(math.radians(359.0), math.radians(1.0))) == pytest.approx(2.0)
    assert math.degrees(angle_difference(math.radians(-179.0), math.radians(179.0))) == pytest.approx(2.0)
    assert wrap_angle(np.pi) == pytest.approx(np.pi) and wrap_angle(-np.pi) == pytest.approx(np.pi)
    assert wrap_angle(3 * np.pi / 2) == pytest.approx(-np.pi / 2)


def test_geometric_azimuth_convention():
    bs = np.array([[10.0, 0.0, 25.0], [0.0, 10.0, 25.0], [-10.0, 0.0, 25.0]])
    np.testing.assert_allclose(geometric_azimuth(bs, [0, 0, 1.5]), [0, np.pi / 2, np.pi])


@pytest.mark.parametrize("true_deg", [0.0, 350.0, 179.5])
def test_absa_threshold_boundary_wrapped(true_deg):
    """Estimate at reference +- (20 deg -+ eps) around the wrap points."""
    det = ABSADetector()
    bs = np.array([[math.cos(math.radians(true_deg)), math.sin(math.radians(true_deg))]]) * 300.0
    for sign in (+1, -1):
        inside = math.radians(true_deg + sign * (20.0 - EPS_DEG))
        outside = math.radians(true_deg + sign * (20.0 + EPS_DEG))
        assert det([inside], bs, reference_position=[0.0, 0.0]).valid
        assert not det([outside], bs, reference_position=[0.0, 0.0]).valid


def test_absa_meaconing_geometry_flags_adversary_direction():
    """Meaconed signals all arrive from the adversary: 2 of 3 BSs are > 20 deg off."""
    bs = np.array([[250.0, 0.0, 25.0], [-125.0, 216.5, 25.0], [-125.0, -216.5, 25.0]])
    ue, adv = np.array([0.0, 0.0, 1.5]), np.array([-40.0, 5.0, 1.5])
    az_adv = math.atan2(adv[1] - ue[1], adv[0] - ue[0])
    v = ABSADetector()(np.full(3, az_adv), bs, reference_position=ue)
    assert not v.valid
    legit = ABSADetector()(geometric_azimuth(bs, ue) + math.radians(5.0), bs, reference_position=ue)
    assert legit.valid


def test_absa_reference_modes_and_missing():
    bs = np.array([[100.0, 0.0], [0.0, 100.0]])
    scene = np.array([math.radians(30.0), np.nan])  # NLOS strongest path of BS 0 at 30 deg
    est = np.array([math.radians(32.0), math.radians(91.0)])
    assert not ABSADetector()(est, bs, reference_position=[0, 0]).valid  # geometry: 32 vs 0
    mixed = ABSADetector(ABSAConfig(reference="scene_or_geometry"))
    assert mixed(est, bs, [0, 0], scene).valid
    only_scene = ABSADetector(ABSAConfig(reference="scene"))
    v = only_scene(est, bs, None, scene)
    assert v.valid and np.isnan(v.error[1])  # BS 1 unchecked
    nan_est = np.array([math.radians(1.0), np.nan])
    assert not ABSADetector()(nan_est, bs, [0, 0]).valid  # missing AoA -> invalid (default)
    assert ABSADetector(ABSAConfig(missing_estimate="ignore"))(nan_est, bs, [0, 0]).valid
    assert not ABSADetector()(est, bs, None).valid  # nothing checkable: unchecked_verdict False


def test_absa_config_range():
    with pytest.raises(InputError, match="threshold_deg"):
        from_dict(ABSAConfig, {"threshold_deg": 200})


# --- DL-UL handshake --------------------------------------------------------------------------

def test_handshake_boundary_20m():
    det = HandshakeDetector()
    d = np.array([3.0, 4.0]) / 5.0
    assert det([0.0, 0.0], d * (20.0 - EPS_M)).valid
    assert det([0.0, 0.0], d * 20.0).valid  # inclusive
    assert not det([0.0, 0.0], d * (20.0 + EPS_M)).valid
    assert det([0.0, 0.0], d * 12.0).distance_m == pytest.approx(12.0)


def test_handshake_failures():
    det = HandshakeDetector()
    assert not det(None, [1.0, 2.0]).valid
    assert not det([np.nan, 0.0], [1.0, 2.0]).valid
    assert not det([1.0, 2.0], None).valid
    assert HandshakeDetector(HandshakeConfig(ul_failure="valid"))([1.0, 2.0], None).valid


def test_handshake_horizontal_vs_3d():
    dl, ul = [0.0, 0.0, 1.5], [0.0, 15.0, 30.0]
    assert HandshakeDetector()(dl, ul).valid
    assert not HandshakeDetector(HandshakeConfig(horizontal=False))(dl, ul).valid
