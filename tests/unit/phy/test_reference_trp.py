"""The RSTD reference of a fix: slot 0 when heard, else the heard TRP with the strongest peak."""

import numpy as np

from veriloc_rt.phy.chain.receiver import reference_trp


def _timing(detected, snr):
    return np.array(detected), np.array(snr)


def test_reference_is_slot_zero_when_heard():
    assert reference_trp(*_timing([True, True, True, True], [9.0, 30.0, 12.0, 11.0])) == 0


def test_reference_falls_back_to_the_strongest_heard():
    # slot 2 is the strongest of all but not heard: slot 3 is the strongest heard
    assert reference_trp(*_timing([False, True, False, True], [1.0, 12.0, 40.0, 15.0])) == 3


def test_reference_without_any_heard_is_zero():
    assert reference_trp(*_timing([False, False, False], [1.0, 2.0, 3.0])) == 0


def test_range_std_is_the_crlb_plus_the_floor():
    from veriloc_rt.phy.chain.receiver import range_std

    b = 624 * 15e3                        # 52 PRB at 15 kHz
    snr_db = np.array([10.0, 30.0])
    snr = 10 ** (snr_db / 10) - 1
    # var(tau) = 1 / (8 pi^2 beta^2 SNR), beta^2 = B^2 / 12, range = c tau
    want = np.sqrt((299_792_458.0 ** 2) / (8 * np.pi**2 * (b**2 / 12) * snr) + 3.0**2)
    np.testing.assert_allclose(range_std(snr_db, b, 3.0), want, rtol=1e-12)
