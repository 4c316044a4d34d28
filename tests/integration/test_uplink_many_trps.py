"""The UL fix with more than three TRPs uses the DL's fit (weighted, chi-square test, fault
exclusion), not the three-TRP unweighted fit with its rms residual check.

An analytic CIR (one path per link; built here from the geometry alone): six TRPs around the
UE, TRP 4's single path late by BIAS_M (a pure NLoS range bias), noiseless. The weighted fit must
exclude TRP 4 in both directions and land within POSITION_M of the UE; the unweighted fit of the
three-TRP rule sees an rms residual over receiver.max_residual_m and gives no fix.
"""

from __future__ import annotations

import numpy as np

from veriloc_rt.config import config_from_dict
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.phy.chain import PositioningChain
from veriloc_rt.propagation.cir import CIR, array_response

FC = 3.5e9
#: a range bias far above the fit's range stds (the shipped overbound of the default
#: range_error_model: 31-35 m at high SNR), so the chi-square test flags it
BIAS_M = 400.0
#: noiseless fix from five unbiased TRPs: the PRS's delay resolution at 10 MHz is a few m; the
#: peak interpolation brings the ToAs within a fraction of it
POSITION_M = 3.0


def _cir(ue, bs, bad):
    d = bs - ue[None, :]
    dist = np.linalg.norm(d, axis=1)
    az, zen = np.arctan2(d[:, 1], d[:, 0]), np.arccos(d[:, 2] / dist)
    n = len(bs)
    delays = dist / SPEED_OF_LIGHT
    delays[bad] += BIAS_M / SPEED_OF_LIGHT
    ep = np.stack([np.arange(5) * 0.5 * SPEED_OF_LIGHT / FC, np.zeros(5), np.zeros(5)], axis=1)
    ep -= ep.mean(axis=0)
    gains = 1e-6 * array_response(az[:, None], zen[:, None], ep, SPEED_OF_LIGHT / FC)
    z = np.zeros((1, n, 1))
    return CIR(delays=delays[None, :, None], gains=gains[None].astype(complex),
               aoa_az=az[None, :, None], aoa_zen=zen[None, :, None], aod_az=z, aod_zen=z,
               doppler=z.copy(), interactions=np.zeros((1, n, 1, 1), np.uint8),
               valid=np.ones((1, n, 1), bool), tx_index=np.arange(n)[None], tx_pos=bs[None],
               rx_pos=ue[None], los=np.ones((1, n), bool), carrier_frequency=FC)


def test_uplink_fix_excludes_the_biased_trp_like_the_downlink():
    cfg = config_from_dict({"topology": {"num_trps": 6}, "security": {"tag_scheme": "none"},
                            "channel": {"noise": False}})
    ang = np.deg2rad(np.arange(6) * 60.0 + 10.0)
    bs = np.stack([300 * np.cos(ang), 300 * np.sin(ang), np.full(6, 25.0)], axis=1)
    ue = np.array([20.0, -35.0, 1.5])
    chain = PositioningChain.from_config(cfg, max_doppler_hz=10.0)
    res = chain(_cir(ue, bs, bad=4), 0, np.random.default_rng(0))
    for fix in (res.position, res.uplink.position):
        assert fix.ok, fix.status
        assert 4 in fix.excluded and 4 not in fix.used
        assert np.linalg.norm(fix.position[:2] - ue[:2]) < POSITION_M
    # the three-TRP rule on the same uplink ToAs: no fix (rms residual check)
    alone = chain.uplink.positioner
    from veriloc_rt.phy.channel import Links
    up = alone(Links.uplink_from_cir(_cir(ue, bs, bad=4), 0, chain.element_pos), bs, 1.5,
               np.random.default_rng(0))
    assert not up.position.ok
