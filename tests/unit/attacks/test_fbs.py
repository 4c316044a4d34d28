"""FBS spoofing: replica delays reproduce the target's RSTDs; replica grids carry no valid tag."""

import numpy as np
import pytest

from veriloc_rt.constants import SPEED_OF_LIGHT as C
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.phy.nr.grid import ReLayout
from veriloc_rt.phy.transmitter import PRSTransmitter
from veriloc_rt.phy.receiver.multilateration import multilaterate
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.attacks import (FalseBaseStation, fbs_delays, fbs_delays_absolute,
                                spoofer_replicas, target_position)
from veriloc_rt.config.attacks import FBSConfig

#: RSTDs are ~1e-6 s; float64 differences of such values are exact to ~1e-21 s, 1e-15 s
#: (0.3 um) leaves room for the distance arithmetic
TOL_RSTD_S = 1e-15
#: multilateration stops at xtol 1e-12 on exact RSTDs; 1 mm flags any real mismatch
TOL_FIX_M = 1e-3

BS = np.array([[250.0, 0.0, 25.0], [-125.0, 216.5, 25.0], [-125.0, -216.5, 25.0]])
UE = np.array([20.0, -35.0, 1.5])


def _toa_at_ue(delays, adversary, ue):
    """Independent recomputation: replica i leaves the adversary at d_i, travels |a - ue|."""
    return delays + np.linalg.norm(np.asarray(adversary) - ue) / C


def _rstd_from_distances(bs, p):
    d = np.linalg.norm(bs - p, axis=1)
    return (d - d[0]) / C


@pytest.mark.parametrize("adv_offset", [(-60.0, 10.0, 0.0), (400.0, 300.0, 0.0), (3.0, 0.0, 0.0)])
def test_delays_reproduce_target_rstds_exactly(adv_offset):
    adv = UE + np.array(adv_offset)
    ue_est = UE + np.array([4.0, -3.0, 0.0])  # the adversary's estimate is 5 m off
    plan = FalseBaseStation(FBSConfig(target_offset_m=100.0, target_bearing_deg=30.0))(BS, adv, ue_est)
    assert np.all(plan.delays >= 0)
    expect_target = ue_est + 100.0 * np.array([np.cos(np.pi / 6), np.sin(np.pi / 6), 0.0])
    np.testing.assert_allclose(plan.target, expect_target, atol=1e-12)
    toa = _toa_at_ue(plan.delays, adv, UE)  # measured at the TRUE UE position
    np.testing.assert_allclose(toa - toa[0], _rstd_from_distances(BS, plan.target), rtol=0,
                               atol=TOL_RSTD_S)


def test_nonnegative_delays_equal_absolute_up_to_common_offset():
    adv = UE + np.array([600.0, 0.0, 0.0])  # far adversary: absolute delays go negative
    t = target_position(UE, 100.0, 0.0)
    d_abs = fbs_delays_absolute(BS, t, adv, UE)
    assert d_abs.min() < 0
    d = fbs_delays(BS, t, adv, UE)
    assert d.min() == pytest.approx(0.0, abs=1e-18) and np.all(d >= 0)
    shift = d - d_abs
    np.testing.assert_allclose(shift, shift[0], rtol=0, atol=TOL_RSTD_S)
    # absolute delays: replica i reaches the UE when BS i's signal would reach the target
    np.testing.assert_allclose(_toa_at_ue(d_abs, adv, UE), np.linalg.norm(BS - t, axis=1) / C,
                               rtol=0, atol=TOL_RSTD_S)
    # without adversary/UE: earliest replica at 0
    d_rel = fbs_delays(BS, t)
    np.testing.assert_allclose(d_rel - d_rel.min(), d_rel, atol=0)
    np.testing.assert_allclose(d_rel - d_rel[0], _rstd_from_distances(BS, t), atol=TOL_RSTD_S)


def test_multilateration_of_spoofed_rstds_lands_on_target():
    adv = UE + np.array([-50.0, 20.0, 0.0])
    plan = FalseBaseStation()(BS, adv, UE)
    toa = _toa_at_ue(plan.delays, adv, UE)
    fix = multilaterate(BS, toa - toa[0], ue_height_m=UE[2])
    assert fix.ok
    assert np.linalg.norm(fix.position[:2] - plan.target[:2]) < TOL_FIX_M
    assert np.linalg.norm(fix.position[:2] - UE[:2]) == pytest.approx(100.0, abs=TOL_FIX_M)


def test_spoofer_replicas_standard_prs_and_forged_tags(rng):
    nr = NRConfig()
    legit = PRSTransmitter(nr, SecurityConfig(tag_scheme="none"), [10, 11, 12])
    layout = ReLayout.from_config(nr, True)
    reps = spoofer_replicas(nr, 7, [(0, 1e-6), (2, 0.0)], rng, slots=[0, 3])
    assert [(b, d) for b, d, _ in reps] == [(0, 1e-6), (2, 0.0)]
    for bs, _, grid in reps:
        prs_mask = layout.prs_mask(bs)
        tag_mask = layout.tag_mask(bs)
        ref = legit.replica(bs, 7, [0, 3], encrypted=False)
        np.testing.assert_array_equal(grid[:, prs_mask], ref[:, prs_mask])  # standard PRS
        tags = grid[:, tag_mask]
        np.testing.assert_allclose(np.abs(tags), 1.0)  # unit-energy QPSK
        assert set(np.round(tags.real * np.sqrt(2)).ravel()) == {-1.0, 1.0}
        assert np.all(grid[:, ~(prs_mask | tag_mask)] == 0)
    empty = spoofer_replicas(nr, 7, [(1, 0.0)], rng, slots=[0], tag_fill="none")[0][2]
    assert np.all(empty[:, layout.tag_mask(1)] == 0)


def test_spoofer_tags_are_random_between_draws():
    nr = NRConfig()
    a = spoofer_replicas(nr, 0, [(0, 0.0)], np.random.default_rng(1), slots=[0])[0][2]
    b = spoofer_replicas(nr, 0, [(0, 0.0)], np.random.default_rng(2), slots=[0])[0][2]
    mask = ReLayout.from_config(nr, True).tag_mask(0)
    assert np.mean(a[:, mask] != b[:, mask]) > 0.5  # 3/4 of QPSK symbols differ on average


def test_bad_inputs(rng):
    with pytest.raises(ValueError, match="target"):
        fbs_delays(BS, [0.0, 0.0])
    with pytest.raises(ValueError, match="go together"):
        fbs_delays(BS, UE, adversary=UE)
    with pytest.raises(ValueError, match="delay"):
        spoofer_replicas(NRConfig(), 0, [(0, -1e-9)], rng, slots=[0])
    with pytest.raises(TypeError, match="rng"):
        spoofer_replicas(NRConfig(), 0, [(0, 0.0)], 5, slots=[0])


def test_spoofed_grid_fails_hmac_verification_legit_passes(rng):
    """Grid level, no channel: the UE sees legit + 10x stronger spoofer replica on BS 0's REs.
    The legit grid alone verifies; overshadowed by random-QPSK tags it does not."""
    from veriloc_rt.phy.security.keys import simulated_keys
    from veriloc_rt.phy.receiver.tag_verifier import TagVerifier

    nr = NRConfig(slots_per_frame=1)
    sec = SecurityConfig(tag_scheme="hmac")
    keys = simulated_keys([10, 11, 12], rng)
    legit = PRSTransmitter(nr, sec, [10, 11, 12], keys)(frame=3, slots=[0])[0, 0]
    verify = TagVerifier(nr, sec, [10, 11, 12], keys)
    assert verify(legit, 0, 3, 0)
    spoof = spoofer_replicas(nr, 3, [(0, 0.0)], rng, slots=[0])[0][2][0]
    assert not verify(legit + 10.0 * spoof, 0, 3, 0)


@pytest.mark.parametrize("bias_s", [2e-6, -0.5e-6])
def test_bias_mode_adds_the_bias_to_the_spoofed_bs_only(bias_s):
    """Mode 'bias': replica 1 reaches the UE exactly bias_s after BS 1's own signal, so RSTD 1 is
    the true one plus the bias (independent: distances), RSTD 2 is untouched (BS 2 not spoofed)."""
    adv = UE + np.array([-40.0, 15.0, 0.0])
    plan = FalseBaseStation(FBSConfig(mode="bias", bias_s=bias_s), spoofed=[1])(BS, adv, UE)
    assert [i for i, _ in plan.replicas] == [1]
    assert np.all(np.isnan(plan.target))
    toa_spoofed = _toa_at_ue(plan.delays[1], adv, UE)
    dist = np.linalg.norm(BS - UE, axis=1)
    # the adversary (43 m from the UE) is nearer than every BS by more than |bias|: no shift
    np.testing.assert_array_equal(plan.delays, fbs_delays_absolute(BS, UE, adv, UE) + bias_s)
    assert np.all(plan.delays >= 0)
    assert toa_spoofed - dist[1] / C == pytest.approx(bias_s, abs=TOL_RSTD_S)
    rstd = np.array([0.0, toa_spoofed - dist[0] / C, (dist[2] - dist[0]) / C])
    truth = _rstd_from_distances(BS, UE)
    np.testing.assert_allclose(rstd - truth, [0.0, bias_s, 0.0], rtol=0, atol=TOL_RSTD_S)


def test_bias_mode_shifts_all_replicas_when_one_would_be_early():
    """A bias earlier than the adversary's head start (-1 us against BS 0, 250 m away, with the
    adversary 150 m from the UE) would need a negative delay: every replica moves later by the
    same amount, so the spoofed replicas keep their relative bias."""
    adv = UE + np.array([150.0, 0.0, 0.0])
    plan = FalseBaseStation(FBSConfig(mode="bias", bias_s=-1e-6), spoofed=[1])(BS, adv, UE)
    d_abs = fbs_delays_absolute(BS, UE, adv, UE) - 1e-6
    assert d_abs.min() < 0 and plan.delays.min() == pytest.approx(0.0, abs=1e-18)
    np.testing.assert_allclose(plan.delays - d_abs, -d_abs.min(), rtol=0, atol=TOL_RSTD_S)


def test_bias_of_one_ISD_mostly_breaks_the_geometry():
    """A 2 us (600 m) bias on one BS of a 500 m-ISD triangle: the hyperbolas with the biased
    range difference exceed the BS baseline from most positions inside the triangle (no fix, a
    DoS), the rest land far off. Independent check: |c rstd| < baseline is necessary for a fix."""
    bias_m = 2e-6 * C
    rng = np.random.default_rng(3)
    xy = rng.uniform(-150, 150, size=(200, 2))
    ok = off = 0
    base = np.linalg.norm(BS[1] - BS[0])
    for p in xy:
        ue = np.array([p[0], p[1], 1.5])
        d = np.linalg.norm(BS - ue, axis=1)
        r = (d - d[0]) / C
        r[1] += bias_m / C
        fix = multilaterate(BS, r, ue_height_m=1.5)
        if abs(r[1] * C) >= base:
            assert not fix.ok  # no hyperbola: must be a service failure
        if fix.ok:
            ok += 1
            off += np.linalg.norm(fix.position[:2] - p) > 15.0
    assert off == ok  # no fix near the UE: a biased RSTD never yields a success
    assert ok < 0.5 * len(xy)
