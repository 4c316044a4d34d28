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
    assert s["los_share"] == 1.0 and s["paths_per_link_mean"] == 2.0


def test_k_factor_ten_to_one():
    d0 = 100.0 / SPEED_OF_LIGHT
    c = _cir([d0, d0 + 50e-9], [10.0, 1.0], [0.0, 1.0], [np.pi / 2] * 2, los=True)
    assert channel_statistics(c)["k_db"]["p50"] == pytest.approx(10.0, abs=1e-9)


def test_nlos_link_has_no_k_factor():
    d0 = 100.0 / SPEED_OF_LIGHT
    c = _cir([d0 + 10e-9, d0 + 50e-9], [1.0, 1.0], [0.0, 1.0], [np.pi / 2] * 2, los=False)
    s = channel_statistics(c)
    assert s["los_share"] == 0.0 and s["k_db"]["p50"] is None


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


def _links(powers_db, los):
    """One single-path link per entry (points axis), path power 10^(-PL/10)."""
    p = len(powers_db)
    shape = (p, 1, 1)
    g = (10 ** (-np.asarray(powers_db, float) / 20)).astype(complex).reshape(p, 1, 1, 1)
    d0 = 100.0 / SPEED_OF_LIGHT
    return CIR(delays=np.full(shape, d0), gains=g, aoa_az=np.zeros(shape),
               aoa_zen=np.full(shape, np.pi / 2), aod_az=np.zeros(shape),
               aod_zen=np.full(shape, np.pi / 2), doppler=np.zeros(shape),
               interactions=np.zeros(shape + (1,), np.uint8), valid=np.ones(shape, bool),
               tx_index=np.zeros((p, 1), np.int64), tx_pos=np.tile([100.0, 0.0, 10.0], (p, 1, 1)),
               rx_pos=np.tile([0.0, 0.0, 1.5], (p, 1)), los=np.asarray(los).reshape(p, 1),
               carrier_frequency=3.5e9)


def test_pathloss_statistics_and_offsets_per_los_state():
    """Traced LoS 70/80 dB, NLoS 100/110/120 dB; twin LoS 60 dB, NLoS 90/130 dB: medians 75 / 110
    against 60 / 110 -> offsets +15 (LoS), 0 (NLoS); all links 100 vs 90 -> +10."""
    from veriloc_rt.studies.compare import pathloss_offsets

    traced = _links([70, 80, 100, 110, 120], [True, True, False, False, False])
    twin = _links([60, 90, 130], [True, False, False])
    assert channel_statistics(traced, traced.los)["pathloss_db"]["p50"] == pytest.approx(75.0)
    assert channel_statistics(traced, ~traced.los)["pathloss_db"]["p50"] == pytest.approx(110.0)
    off = pathloss_offsets(traced, twin)
    assert off["los"] == pytest.approx(15.0) and off["nlos"] == pytest.approx(0.0)
    assert off["all"] == pytest.approx(10.0) and off["basis"] == {"los": "los", "nlos": "nlos"}
    # a state the twin never drew falls back on the all-links offset
    off = pathloss_offsets(traced, _links([90, 130], [False, False]))
    assert off["basis"]["los"] == "all" and off["los"] == off["all"] == pytest.approx(-10.0)


def test_umi_reference_from_tables():
    """UMi at 3.5 GHz (lg(1 + 3.5) = 0.65321): LoS lgDS -7.14 - 0.24 x 0.65321 -> 50.5 ns,
    NLoS lgDS -6.83 - 0.24 x 0.65321 -> 103.1 ns; path loss Table 7.4.1-1 at 100 m, 10 m BS."""
    from veriloc_rt.propagation.umi import umi_pathloss_db
    from veriloc_rt.studies.compare import reference_statistics

    t = reference_statistics("umi", 3.5e9, 100.0)
    assert t["h_bs_m"] == 10.0
    assert t["los"]["ds_ns"] == pytest.approx(50.5, abs=0.05)
    assert t["nlos"]["ds_ns"] == pytest.approx(103.1, abs=0.05)
    assert t["los"]["pathloss_db"] == pytest.approx(umi_pathloss_db(100.0, 10.0, 1.5, 3.5e9, True))
    assert t["nlos"]["pathloss_db"] == pytest.approx(umi_pathloss_db(100.0, 10.0, 1.5, 3.5e9,
                                                                     False))
    assert t["los"]["k_db"] == 9.0 and t["nlos"]["k_db"] is None
