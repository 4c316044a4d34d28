"""Channel statistics of ``veriloc-rt compare`` against hand-worked cases and TR 38.901."""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.studies.compare import channel_statistics, uma_reference_statistics
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.propagation.cir import CIR


def _cir(delays, powers, az, zen, los, rx=(0.0, 0.0, 1.5), tx=(100.0, 0.0, 1.5)):
    n = len(delays)
    shape = (1, 1, n)
    g = np.sqrt(np.asarray(powers, float)).astype(complex).reshape(1, 1, 1, n)
    return CIR(delays=np.asarray(delays, float).reshape(shape), gains=g,
               aoa_az=np.asarray(az, float).reshape(shape), aoa_zen=np.asarray(zen, float).reshape(shape),
               aod_az=np.zeros(shape), aod_zen=np.full(shape, np.pi / 2), doppler=np.zeros(shape),
               interactions=np.zeros(shape + (1,), np.uint8), valid=np.ones(shape, bool),
               tx_index=np.zeros((1, 1), np.int64), tx_pos=np.asarray(tx, float).reshape(1, 1, 3),
               rx_pos=np.asarray(rx, float).reshape(1, 3), los=np.array([[los]]),
               carrier_frequency=3.5e9)


def test_two_equal_paths_delay_and_angle_spread():
    # two equal-power paths 100 ns apart: rms delay spread 50 ns; at azimuths +-30 deg the
    # circular spread is sqrt(-2 ln cos 30 deg) rad = 30.5 deg (TR 38.901 A.1)
    d0 = 100.0 / SPEED_OF_LIGHT
    c = _cir([d0, d0 + 100e-9], [1.0, 1.0], np.deg2rad([30.0, -30.0]), [np.pi / 2] * 2, los=True)
    s = channel_statistics(c)
    assert s["ds_ns"]["p50"] == pytest.approx(50.0, rel=1e-9)
    want = np.degrees(np.sqrt(-2 * np.log(np.cos(np.deg2rad(30.0)))))
    assert s["asa_deg"]["p50"] == pytest.approx(want, rel=1e-9)
    assert s["zsa_deg"]["p50"] == pytest.approx(0.0, abs=1e-5)
    # the path at the straight-line delay against the other: K = 0 dB
    assert s["k_db"]["p50"] == pytest.approx(0.0, abs=1e-9)
    assert s["los_pct"] == 100.0 and s["paths_per_link_mean"] == 2.0


def test_k_factor_ten_to_one():
    d0 = 100.0 / SPEED_OF_LIGHT
    c = _cir([d0, d0 + 50e-9], [10.0, 1.0], [0.0, 1.0], [np.pi / 2] * 2, los=True)
    assert channel_statistics(c)["k_db"]["p50"] == pytest.approx(10.0, abs=1e-9)


def test_nlos_link_has_no_k_factor():
    d0 = 100.0 / SPEED_OF_LIGHT
    c = _cir([d0 + 10e-9, d0 + 50e-9], [1.0, 1.0], [0.0, 1.0], [np.pi / 2] * 2, los=False)
    s = channel_statistics(c)
    assert s["los_pct"] == 0.0 and s["k_db"]["p50"] is None


def test_uma_reference_medians_from_table_7_5_6():
    # at 3.5 GHz the frequency-dependent entries use fc = 6 GHz (Table 7.5-6 note 6):
    # NLoS lgDS = -6.28 - 0.204 lg 6 -> 364 ns; LoS lgDS = -6.955 - 0.0963 lg 6 -> 93.3 ns;
    # NLoS lgASA = 2.08 - 0.27 lg 6 -> 74.1 deg; NLoS lgZSA = 1.512 - 0.3236 lg 6 -> 18.2 deg;
    # LoS ASA 10^1.81 = 64.6 deg, ZSA 10^0.95 = 8.9 deg, K 9 dB
    t = uma_reference_statistics(3.5e9)
    lg6 = np.log10(6.0)
    assert t["nlos"]["ds_ns"] == pytest.approx(10 ** (-6.28 - 0.204 * lg6) * 1e9, rel=1e-12)
    assert t["nlos"]["ds_ns"] == pytest.approx(364.0, abs=1.0)
    assert t["los"]["ds_ns"] == pytest.approx(93.3, abs=0.1)
    assert t["nlos"]["asa_deg"] == pytest.approx(74.1, abs=0.1)
    assert t["nlos"]["zsa_deg"] == pytest.approx(18.2, abs=0.1)
    assert t["los"]["asa_deg"] == pytest.approx(64.6, abs=0.1)
    assert t["los"]["zsa_deg"] == pytest.approx(8.9, abs=0.1)
    assert t["los"]["k_db"] == 9.0 and t["nlos"]["k_db"] is None
