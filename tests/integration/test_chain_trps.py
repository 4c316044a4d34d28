"""The chain with nine TRPs in three slot groups (comb 6 with tags): on exact single-path links
(built here from the geometry) it recovers every ToA, the position and every TRP's tag."""

from __future__ import annotations

import numpy as np

from veriloc_rt.config import config_from_dict
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.phy.chain import PositioningChain
from veriloc_rt.phy.security.keys import simulated_keys
from veriloc_rt.propagation.cir import CIR, array_response, ula_element_positions

FC = 3.5e9
#: noiseless bounds as tests/integration/test_chain.py: ToA within 0.1 sample, fix within 0.5 m
TOA_SAMPLES = 0.1
POSITION_M = 0.5


def ring(n: int) -> np.ndarray:
    """n TRPs on two rings around the origin (250 m and 600 m), 25 m high."""
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False) + 0.3
    r = np.where(np.arange(n) % 2, 600.0, 250.0)
    return np.stack([r * np.cos(ang), r * np.sin(ang), np.full(n, 25.0)], -1)


def exact_cir(bs: np.ndarray, ue: np.ndarray, amp: float = 1e-6) -> CIR:
    n = len(bs)
    d = bs - ue[None, :]
    dist = np.linalg.norm(d, axis=1)
    az, zen = np.arctan2(d[:, 1], d[:, 0]), np.arccos(d[:, 2] / dist)
    ep = ula_element_positions(5, 0.5 * SPEED_OF_LIGHT / FC, 0.0)
    gains = amp * array_response(az[:, None], zen[:, None], ep, SPEED_OF_LIGHT / FC)
    z = np.zeros((1, n, 1))
    return CIR(delays=(dist / SPEED_OF_LIGHT)[None, :, None], gains=gains[None].astype(complex),
               aoa_az=az[None, :, None], aoa_zen=zen[None, :, None], aod_az=z, aod_zen=z,
               doppler=np.zeros((1, n, 1)), interactions=np.zeros((1, n, 1, 1), np.uint8),
               valid=np.ones((1, n, 1), bool), tx_index=np.arange(n)[None], tx_pos=bs[None],
               rx_pos=ue[None], los=np.ones((1, n), bool), carrier_frequency=FC)


def test_nine_trps_in_slot_groups_noiseless():
    cfg = config_from_dict({"topology": {"num_trps": 9}, "channel": {"noise": False,
                                                                   "power_control": False},
                            "security": {"encrypted": [True, False]}})
    assert cfg.nr.slot_plan(True)[1] == 2            # three groups of two slots
    bs = ring(9)
    ue = np.array([37.0, -21.0, 1.5])
    chain = PositioningChain(cfg.nr, cfg.security, cfg.channel, cfg.receiver,
                             cfg.propagation.ue_array, FC, simulated_keys(range(9),
                                                                          np.random.default_rng(0)))
    cir = exact_cir(bs, ue)
    res = chain(cir, 0, np.random.default_rng(1))
    assert res.detected.all()
    err = np.abs(res.toa_s - cir.delays[0, :, 0]) * chain.ofdm.sample_rate_hz
    np.testing.assert_array_less(err, TOA_SAMPLES)
    assert res.position.ok and res.position.num_bs == 9
    assert np.linalg.norm(res.position.position[:2] - ue[:2]) < POSITION_M
    assert res.tags_checked and res.tags_valid.all()
