"""The run's Doppler scan: the largest Doppler the UE receives (sim.runner.channel_doppler_hz)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from veriloc_rt.config import Config
from veriloc_rt.propagation.cir import CIR
from veriloc_rt.propagation.raytrace import Propagation
from veriloc_rt.sim.runner import channel_doppler_hz


def cir(doppler, valid=None) -> CIR:
    """Links with the given per-path Doppler [P, T, N] Hz (other fields arbitrary, valid)."""
    d = np.asarray(doppler, dtype=float)
    p, t, n = d.shape
    z = np.zeros((p, t, n))
    return CIR(delays=z + 1e-6, gains=np.ones((p, t, 1, n), complex), aoa_az=z, aoa_zen=z + 1.0,
               aod_az=z, aod_zen=z + 1.0, doppler=d, interactions=np.zeros((p, t, n, 1), np.uint8),
               valid=np.ones((p, t, n), bool) if valid is None else np.asarray(valid, dtype=bool),
               tx_index=np.tile(np.arange(t), (p, 1)), tx_pos=np.zeros((p, t, 3)),
               rx_pos=np.ones((p, 3)), los=np.zeros((p, t), bool), carrier_frequency=3.5e9)


# two points, three BSs, two paths; the -500 Hz path is invalid and must not count
BS_UE = cir([[[100.0, -60.0], [10.0, 0.0], [-5.0, 5.0]], [[20.0, 30.0], [-95.0, 1.0], [0.0, -500.0]]],
            valid=[[[1, 1], [1, 1], [1, 1]], [[1, 1], [1, 1], [1, 0]]])
# the relay's receive Doppler per point: point 0 in [-90, 80], point 1 in [-10, 40]
BS_ADV = cir([[[80.0, -90.0], [0.0, 0.0], [0.0, 0.0]], [[40.0, -10.0], [0.0, 0.0], [0.0, 0.0]]])
# the adversary -> UE Doppler per point: point 0 in [-20, 50], point 1 in [-70, 60]
ADV_UE = cir([[[50.0, -20.0]], [[60.0, -70.0]]])


@pytest.mark.parametrize("scenarios,expected_hz", [
    (("none",), 100.0),                   # |100| is the largest valid BS -> UE Doppler
    (("none", "fbs"), 100.0),             # the adversary's own paths reach 70 Hz
    (("none", "jamming"), 100.0),
    # relayed: per point the extreme sums, 80 + 50 = 130 and -(-90 - 20) = 110 at point 0,
    # 40 + 60 = 100 and -(-10 - 70) = 80 at point 1 (not max|rx| + max|tx| = 90 + 70 = 160)
    (("none", "meaconing"), 130.0),
])
def test_the_fastest_doppler_the_ue_receives(scenarios, expected_hz):
    cfg = Config()
    cfg = dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, scenarios=scenarios))
    assert channel_doppler_hz(cfg, Propagation(BS_UE, BS_ADV, ADV_UE)) == expected_hz


def test_max_doppler_of_a_cir_without_valid_paths_is_zero():
    assert cir([[[300.0]]], valid=[[[False]]]).max_doppler_hz() == 0.0
