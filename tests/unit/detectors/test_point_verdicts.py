"""The one per-point evaluation of the stateless detectors (a run's and the diagnostics'), with
the ABSA reference position as its parameter."""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.config import ArrayConfig
from veriloc_rt.config.channel import ChannelConfig, ReceiverConfig
from veriloc_rt.config.detectors import DetectorsConfig
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.constants import SPEED_OF_LIGHT as C
from veriloc_rt.detectors import PointDetectors, point_verdicts
from veriloc_rt.detectors.absa import angle_difference, geometric_azimuth
from veriloc_rt.phy.chain import PositioningChain
from veriloc_rt.phy.security.keys import simulated_keys
from veriloc_rt.propagation.cir import CIR, array_response, ula_element_positions

FC = 3.5e9
BS = np.array([[0.0, 289.0, 25.0], [-250.3, -144.5, 25.0], [250.3, -144.5, 25.0]])
UE = np.array([37.0, -21.0, 1.5])


@pytest.fixture(scope="module")
def result():
    """A noiseless chain result on one line-of-sight path per BS (AoA = geometry)."""
    d = BS - UE
    dist = np.linalg.norm(d, axis=1)
    az, zen = np.arctan2(d[:, 1], d[:, 0]), np.arccos(d[:, 2] / dist)
    ep = ula_element_positions(5, 0.5 * C / FC, 0.0)
    gains = 1e-6 * array_response(az[:, None], zen[:, None], ep, C / FC)
    z = np.zeros((1, 3, 1))
    cir = CIR(delays=(dist / C)[None, :, None], gains=gains[None].astype(complex), aoa_az=az[None, :, None],
              aoa_zen=zen[None, :, None], aod_az=z, aod_zen=z, doppler=z.copy(),
              interactions=np.zeros((1, 3, 1, 1), np.uint8), valid=np.ones((1, 3, 1), bool),
              tx_index=np.array([[0, 1, 2]]), tx_pos=BS[None], rx_pos=UE[None],
              los=np.ones((1, 3), bool), carrier_frequency=FC)
    chain = PositioningChain(NRConfig(slots_per_frame=2), SecurityConfig(tag_scheme="hmac"),
                             ChannelConfig(noise=False), ReceiverConfig(), ArrayConfig(), FC,
                             simulated_keys((0, 1, 2), np.random.default_rng(0)))
    return chain(cir, 0, np.random.default_rng(1))


def test_every_verdict_valid_at_the_true_position(result):
    det = PointDetectors.from_config(DetectorsConfig())
    v = point_verdicts(det, result, BS, UE, ds=result)
    assert v == {"HMAC": True, "DigSig": True, "ABSA": True, "Handshake": True}
    assert list(point_verdicts(det, result, BS, UE)) == ["HMAC", "ABSA", "Handshake"]   # no DS


def test_absa_follows_the_reference_position(result):
    """The reference is a parameter: from a position whose azimuth to some BS differs from the
    true one by more than the 20 degree threshold (computed here from the geometry), ABSA fails;
    from no position at all no BS is checked and the unchecked verdict (invalid) applies."""
    det = PointDetectors.from_config(DetectorsConfig())
    far = UE + np.array([0.0, 200.0, 0.0])
    shift = angle_difference(geometric_azimuth(BS, far), geometric_azimuth(BS, UE))
    assert np.degrees(shift.max()) > det.absa.absa.config.threshold_deg
    assert not point_verdicts(det, result, BS, far)["ABSA"]
    assert not point_verdicts(det, result, BS, None)["ABSA"]
