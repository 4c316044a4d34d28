"""The RSTD reference of a fix: slot 0 when heard, else the heard TRP with the strongest peak."""

from types import SimpleNamespace

import numpy as np

from veriloc_rt.phy.chain.receiver import reference_trp


def _timing(detected, snr):
    ests = [SimpleNamespace(detected=d, peak_snr_db=s) for d, s in zip(detected, snr)]
    return SimpleNamespace(detected=np.array(detected), estimates=ests)


def test_reference_is_slot_zero_when_heard():
    assert reference_trp(_timing([True, True, True, True], [9.0, 30.0, 12.0, 11.0])) == 0


def test_reference_falls_back_to_the_strongest_heard():
    # slot 2 is the strongest of all but not heard: slot 3 is the strongest heard
    assert reference_trp(_timing([False, True, False, True], [1.0, 12.0, 40.0, 15.0])) == 3


def test_reference_without_any_heard_is_zero():
    assert reference_trp(_timing([False, False, False], [1.0, 2.0, 3.0])) == 0
