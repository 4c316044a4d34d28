"""OFDM round trip at every supported sample rate, CP lengths of TS 38.211 5.3.1, tone frequency."""

import numpy as np
import pytest

from veriloc_rt.errors import InputError
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.phy.nr.ofdm import OFDM

#: round trip tolerance: two unitary FFTs of length <= 8192 in float64 (error ~ 1e-15 * log2 N)
ROUND_TRIP_ATOL = 1e-12


@pytest.mark.parametrize("mu,fs", [(0, 15.36e6), (0, 30.72e6), (0, 61.44e6), (0, 122.88e6),
                                   (1, 30.72e6), (1, 61.44e6), (1, 122.88e6)])
def test_round_trip(mu, fs):
    cfg = NRConfig(numerology=mu, sample_rate_hz=fs)
    ofdm = OFDM(cfg)
    rng = np.random.default_rng(3)
    grid = rng.standard_normal((2, 2, 14, 624)) + 1j * rng.standard_normal((2, 2, 14, 624))
    x = ofdm.modulate(grid, [4, 5])
    assert x.shape == (2, ofdm.num_samples([4, 5]))
    np.testing.assert_allclose(ofdm.demodulate(x, [4, 5]), grid, atol=ROUND_TRIP_ATOL)
    # Parseval (unitary transforms): useful-part energy equals grid energy
    assert np.isclose(np.sum(np.abs(ofdm.demodulate(x, [4, 5])) ** 2), np.sum(np.abs(grid) ** 2))


def test_default_rate_is_smallest_holding_the_band():
    assert NRConfig().resolved_sample_rate_hz == 15.36e6
    assert NRConfig(numerology=1).resolved_sample_rate_hz == 30.72e6
    assert NRConfig(num_prb=100).resolved_sample_rate_hz == 30.72e6  # 1200 subcarriers > 1024


def test_cp_lengths_and_frame_length_at_reference_rate():
    # standards-and-limits.md 1a: at 122.88 MHz, 15 kHz: N_FFT 8192, CP 576, 640 for l = 0 and 7,
    # a 10 ms frame is 1 228 800 samples
    ofdm = OFDM(NRConfig(sample_rate_hz=122.88e6))
    cp = ofdm.cp_lengths(0)
    assert ofdm.fft_size == 8192
    assert cp[0] == cp[7] == 640 and set(cp[[1, 2, 3, 4, 5, 6, 8, 9, 10, 11, 12, 13]]) == {576}
    assert ofdm.num_samples(range(10)) == 1_228_800
    # mu = 1 at 61.44 MHz (N_FFT 2048, one sample = kappa/2 Tc): 0.5 ms slots, long CP only on
    # symbol 0 of each slot (l = 0 and 14 of the subframe), 144 + 16 kappa / (kappa/2) = 176 samples
    o1 = OFDM(NRConfig(numerology=1, sample_rate_hz=61.44e6))
    assert o1.cp_lengths(0)[0] == o1.cp_lengths(1)[0] == 144 + 32
    assert set(o1.cp_lengths(0)[1:]) == {144}
    assert o1.num_samples(range(20)) == 614_400


def test_single_subcarrier_is_a_tone_at_its_frequency():
    cfg = NRConfig(sample_rate_hz=30.72e6)
    ofdm = OFDM(cfg)
    grid = np.zeros((1, 14, 624), dtype=complex)
    k = 400
    grid[0, 3, k] = 1.0
    x = ofdm.modulate(grid)
    start = ofdm.symbol_starts([0])[0, 3]
    seg = x[start:start + ofdm.cp_lengths(0)[3] + ofdm.fft_size]
    n = np.arange(seg.size) - ofdm.cp_lengths(0)[3]
    f = (k - 312) * 15e3  # subcarrier 312 sits at DC
    expected = np.exp(2j * np.pi * f * n / 30.72e6) / np.sqrt(ofdm.fft_size)
    np.testing.assert_allclose(seg, expected, atol=1e-12)


@pytest.mark.parametrize("fs", [10e6, 7.68e6, 20e6])
def test_sample_rate_that_cannot_hold_the_band_is_rejected(fs):
    with pytest.raises(InputError, match="sample_rate_hz"):
        NRConfig(sample_rate_hz=fs)
