"""Meaconing preserves RSTDs (paper eq.: (t_i + delta) - (t_j + delta) = t_i - t_j) and sets the
transmit power; jamming noise power and band occupancy measured by FFT against the request."""

import math

import numpy as np
import pytest

from veriloc_rt.config.nr import NRConfig
from veriloc_rt.phy.nr.ofdm import OFDM
from veriloc_rt.constants import dbm_to_watt
from veriloc_rt.attacks import (Jammer, Meaconer, fractional_delay, jamming_grid,
                                jamming_iq, meacon, prs_band_hz)
from veriloc_rt.config.attacks import JammingConfig, MeaconingConfig

FS = 30.72e6
N = 8192
#: correlation peaks are refined on a x32 zero-padded spectrum: resolution 1/32 sample (1 ns);
#: half of it plus interpolation ripple -> 1/16 sample
TOL_DELAY_S = 1.0 / (16 * FS)
#: statistical tolerances in standard deviations (seeded, 5 sigma)
SIGMAS = 5.0


def _bandlimited(rng, n=N, frac=0.6):
    spec = np.zeros(n, complex)
    k = np.abs(np.fft.fftfreq(n)) < frac / 2
    spec[k] = rng.standard_normal(k.sum()) + 1j * rng.standard_normal(k.sum())
    return np.fft.ifft(spec)


def _peak_delay(rx, ref, up=32):
    """Delay (s) of ``ref`` inside ``rx`` from the upsampled cross-correlation peak."""
    n = rx.size
    x = np.fft.fft(rx) * np.conj(np.fft.fft(ref))
    big = np.zeros(n * up, complex)
    half = n // 2
    big[:half] = x[:half]
    big[-half:] = x[-half:]
    c = np.abs(np.fft.ifft(big))
    lag = np.argmax(c) / up
    if lag > n / 2:
        lag -= n
    return lag / FS


def test_fractional_delay_matches_analytic_phase_ramp(rng):
    s = _bandlimited(rng)
    s[-300:] = 0  # keep the delayed signal inside the window (no truncation)
    d = 37.3 / FS
    y = fractional_delay(s, d, FS)
    assert _peak_delay(y, s) == pytest.approx(d, abs=TOL_DELAY_S)


def test_meaconing_preserves_rstds_two_path_composite(rng):
    """Composite at the adversary: BS1 and BS2 (each direct path + a weaker echo) + noise."""
    s1, s2 = _bandlimited(rng), _bandlimited(rng)
    s1[-600:] = 0
    s2[-600:] = 0
    t1, t2 = 11.25 / FS, 47.6 / FS
    r = (fractional_delay(s1, t1, FS) + 0.3 * fractional_delay(s1, t1 + 9 / FS, FS)
         + 0.7 * fractional_delay(s2, t2, FS) + 0.2 * fractional_delay(s2, t2 + 14 / FS, FS))
    r += 0.01 * (rng.standard_normal(N) + 1j * rng.standard_normal(N))
    cfg = MeaconingConfig(power_dbm=48.0, processing_delay_s=1e-6)
    tx, gain = Meaconer(cfg)(r, FS)
    # relay output power: the AGC sets dBm on the input; the delay drops only the zero tail
    assert 10 * np.log10(np.mean(np.abs(tx) ** 2) * 1e3) == pytest.approx(48.0, abs=0.05)
    assert gain == pytest.approx(math.sqrt(dbm_to_watt(48.0) / np.mean(np.abs(r) ** 2)))
    # over the air to the UE: a further common delay
    at_ue = fractional_delay(tx, 5.2 / FS, FS)
    d1, d2 = _peak_delay(at_ue, s1), _peak_delay(at_ue, s2)
    assert d1 - d2 == pytest.approx(t1 - t2, abs=TOL_DELAY_S)  # RSTD preserved
    assert d1 == pytest.approx(t1 + 1e-6 + 5.2 / FS, abs=TOL_DELAY_S)  # common delay delta


def test_meaconing_gain_cap_and_inputs(rng):
    r = 1e-6 * _bandlimited(rng)
    tx, g = meacon(r, FS, dbm_to_watt(48.0), 0.0, max_gain_db=60.0)
    assert g == pytest.approx(1e3)
    np.testing.assert_allclose(tx, 1e3 * r, atol=1e-15)
    with pytest.raises(ValueError, match="delay_s"):
        meacon(r, FS, 1.0, -1e-9)


def test_jamming_iq_power_and_band_occupancy(rng):
    nr = NRConfig()
    fs = nr.resolved_sample_rate_hz
    band = prs_band_hz(nr)
    n = 4 * nr.fft_size
    jam = Jammer(nr, JammingConfig(power_dbm=48.0))
    x = jam.iq(n, rng)
    p = dbm_to_watt(48.0)
    spec = np.abs(np.fft.fft(x, norm="ortho")) ** 2
    f = np.fft.fftfreq(n, 1 / fs)
    inband = (f >= band[0]) & (f < band[1])
    n_occ = inband.sum()
    # occupied width = requested: 624 subcarriers of 15 kHz, bins of fs/n
    assert n_occ * fs / n == pytest.approx(band[1] - band[0], rel=1e-9)
    assert spec[~inband].sum() <= 1e-20 * spec.sum()  # nothing outside the band
    # power: sum of n_occ exponential bin powers -> relative std 1/sqrt(n_occ)
    assert abs(np.mean(np.abs(x) ** 2) / p - 1) < SIGMAS / math.sqrt(n_occ)
    # flat inside: half-band powers agree
    lo = inband & (f < 0)
    hi = inband & (f >= 0)
    assert abs(spec[lo].mean() / spec[hi].mean() - 1) < SIGMAS * math.sqrt(2 / (n_occ / 2))


def test_jamming_grid_through_ofdm_gives_requested_power(rng):
    nr = NRConfig()
    p = dbm_to_watt(48.0)
    g = Jammer(nr).grid((4, 14, nr.num_subcarriers), rng)
    assert np.var(g) == pytest.approx(p * nr.fft_size / nr.num_subcarriers, rel=SIGMAS / math.sqrt(g.size))
    x = OFDM(nr).modulate(g)  # unitary OFDM: per-RE variance -> time power
    assert np.mean(np.abs(x) ** 2) == pytest.approx(p, rel=SIGMAS / math.sqrt(g.size))


def test_jamming_reproducible_and_checked():
    a = jamming_iq(256, FS, (-5e6, 5e6), 1.0, np.random.default_rng(3))
    b = jamming_iq(256, FS, (-5e6, 5e6), 1.0, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="band_hz"):
        jamming_iq(256, FS, (-20e6, 5e6), 1.0, np.random.default_rng(3))
    with pytest.raises(TypeError, match="rng"):
        jamming_grid((2, 10), 1.0, 16, rng=3)
