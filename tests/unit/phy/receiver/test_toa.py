"""ToA, Doppler and hearability of the receiver front ends + ToAEstimator.

Reference values are independent: the true delay of a synthetic path, the Cramer-Rao bound
recomputed from the PRS RE frequencies (standards-and-limits.md section 2:
var >= 1 / (8 pi^2 beta^2 SNR_tot)), and the post-correlation SNR |alpha|^2 sum|X|^2 / sigma^2.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from veriloc_rt.phy.channel import (Links, add_noise, apply_frequency, apply_time,
                                    subcarrier_frequencies, timing_reference)
from veriloc_rt.config.channel import ReceiverConfig
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.phy.transmitter import PRSTransmitter
from veriloc_rt.phy.receiver.sync import (block_index, frequency_cross_spectra, noise_variance,
                                          time_cross_spectra)
from veriloc_rt.phy.receiver.toa import CrossSpectra, ToAEstimator, ZoomPlan, fft_length, zoom_plan
from veriloc_rt.config.security import SecurityConfig

GUARD = 0.25e-6
#: Noiseless ToA: the issue's bound, 0.1 sample at the simulated rate
TOA_SAMPLES = 0.1
#: RMSE / CRB at high SNR: the strongest-peak rule is the ML estimator (efficient above the
#: threshold); 80 trials give the RMSE a relative std of 1/sqrt(160) = 8%, so [0.8, 1.35] is
#: about 3 sigma around 1 plus 10% for the jointly estimated Doppler
CRB_RATIO = (0.8, 1.35)


def _setup(rate=None, slots=10):
    nr = NRConfig(sample_rate_hz=rate, slots_per_frame=slots)
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="none"), (1, 2, 3))
    return nr, tx


def _links(delays, doppler, gains=None):
    d = np.asarray(delays, float)[:, None]
    g = np.exp(1j * np.array([0.3, 1.1, 2.0]))[: d.shape[0], None, None] if gains is None else gains
    return Links(d, g * np.ones((d.shape[0], 1, 1)), np.asarray(doppler, float)[:, None],
                 np.ones(d.shape, bool))


@pytest.mark.parametrize("rate", [15.36e6, 122.88e6])
@pytest.mark.parametrize("domain", ["frequency", "time"])
def test_noiseless_single_path_toa_below_a_tenth_of_a_sample(rate, domain):
    nr, tx = _setup(rate, slots=4)
    slots = range(4)
    tau = np.array([3.0123e-6, 2.5e-6, 4.4567e-6])
    links = _links(tau, [120.0, -60.0, 0.0])
    t0 = timing_reference(links, GUARD)
    est = ToAEstimator(ReceiverConfig(), GUARD)
    ofdm = tx.ofdm
    if domain == "frequency":
        y = apply_frequency(links, tx(0, slots), np.ones(3), ofdm, slots, t0)
    else:
        wave = tx.waveform(0, slots)
        y = apply_time(links, wave, np.ones(3), ofdm.sample_rate_hz, t0, wave.shape[1] + 2000)
    for bs in range(3):
        rep = tx.replica(bs, 0, slots)
        cs = (frequency_cross_spectra(y, rep, ofdm, slots) if domain == "frequency" else
              time_cross_spectra(y, rep, ofdm, slots, GUARD, 12e-6))
        e = est(cs, 0.0)
        assert e.detected
        assert abs(e.toa_s - (tau[bs] - t0)) * ofdm.sample_rate_hz < TOA_SAMPLES
        # Doppler: 4 slots = 4 ms; noiseless residual-phase refinement is exact to < 1 Hz
        assert e.doppler_hz == pytest.approx([120.0, -60.0, 0.0][bs], abs=1.0)


def _crb_std(replica, freqs, snr_re):
    p = np.abs(replica) ** 2                                    # [S, 14, K]
    w = p.sum(axis=(0, 1))
    mean = np.sum(freqs * w) / w.sum()
    beta2 = np.sum(freqs ** 2 * w) / w.sum() - mean ** 2
    snr_tot = snr_re * p.sum()
    return 1.0 / np.sqrt(8 * np.pi ** 2 * beta2 * snr_tot), np.sqrt(beta2)


def test_toa_rmse_follows_the_cramer_rao_bound():
    nr, tx = _setup(slots=2)
    slots = range(2)
    ofdm = tx.ofdm
    rep = tx.replica(0, 0, slots)
    grids = rep[None]
    cfg = ReceiverConfig(toa_method="strongest")
    est = ToAEstimator(cfg, GUARD)
    rng = np.random.default_rng(2024)
    freqs = subcarrier_frequencies(ofdm)
    ratios = []
    for snr_re_db in (-5.0, 5.0, 15.0):
        snr = 10 ** (snr_re_db / 10)
        crb, beta = _crb_std(rep, freqs, snr)
        errs = []
        for _ in range(80):
            tau = 2e-6 + rng.uniform(0, 1e-6)
            links = _links([tau], [rng.uniform(-50, 50)], gains=np.exp(2j * np.pi * rng.random()) * np.ones((1, 1, 1)))
            t0 = 1e-6
            y = add_noise(apply_frequency(links, grids, np.ones(1), ofdm, slots, t0), 1.0 / snr, rng)
            e = est(frequency_cross_spectra(y, rep, ofdm, slots), 1.0 / snr)
            errs.append(e.toa_s - (tau - t0))
        rmse = np.sqrt(np.mean(np.square(errs)))
        ratios.append(rmse / crb)
    assert beta == pytest.approx(2.70e6, rel=0.01)  # standards-and-limits.md: beta = 2.702 MHz
    for r in ratios:
        assert CRB_RATIO[0] < r < CRB_RATIO[1], ratios


def test_peak_snr_is_the_post_correlation_snr():
    nr, tx = _setup(slots=2)
    slots = range(2)
    ofdm = tx.ofdm
    rep = tx.replica(0, 0, slots)
    rng = np.random.default_rng(5)
    snr_re = 10 ** (-5 / 10)
    links = _links([2.2e-6], [0.0])
    y = add_noise(apply_frequency(links, rep[None], np.ones(1), ofdm, slots, 2e-6), 1 / snr_re, rng)
    e = ToAEstimator(ReceiverConfig(), GUARD)(frequency_cross_spectra(y, rep, ofdm, slots), 1 / snr_re)
    expect = 10 * np.log10(1 + snr_re * np.sum(np.abs(rep) ** 2))  # |alpha|^2 N_RE / sigma^2 + noise
    # one noisy realisation at SNR_tot = 29 dB: the peak amplitude has a relative std of
    # 1/sqrt(2 SNR_tot) = 2.5% (0.2 dB); 1 dB also covers the upward bias of the max over cells
    assert e.peak_snr_db == pytest.approx(expect, abs=1.0)


def test_first_path_finds_a_weaker_earlier_path_that_strongest_misses():
    nr, tx = _setup(slots=2)
    slots = range(2)
    ofdm = tx.ofdm
    rep = tx.replica(0, 0, slots)
    # early path 8 dB weaker, 250 ns (75 m, > the 107 ns resolution) before the strong one
    links = Links(np.array([[2.0e-6, 2.25e-6]]), np.array([[[10 ** (-8 / 20), np.exp(1j)]]]),
                  np.zeros((1, 2)), np.ones((1, 2), bool))
    t0 = 1.75e-6
    rng = np.random.default_rng(9)
    nv = 0.25  # SNR per RE: strong path 6 dB, weak one -2 dB (post-correlation 40 and 32 dB)
    y = add_noise(apply_frequency(links, rep[None], np.ones(1), ofdm, slots, t0), nv, rng)
    cs = frequency_cross_spectra(y, rep, ofdm, slots)
    fp = ToAEstimator(ReceiverConfig(), GUARD)(cs, nv)
    st = ToAEstimator(ReceiverConfig(toa_method="strongest"), GUARD)(cs, nv)
    # measured over 60 noise draws at 6 dB less SNR: first path std 5.7 ns (the Hann window and
    # the strong path's leakage roughly double the CRB std), strongest 0.74 ns. Here, 6 dB
    # better: ~2.9 and ~0.4 ns; bounds 12 ns (4 sigma, 3.6 m, far from the 250 ns alternative)
    # and 3 ns
    assert fp.toa_s == pytest.approx(0.25e-6, abs=12e-9)
    assert st.toa_s == pytest.approx(0.50e-6, abs=3e-9)
    # the transmitter's mask of the replica in place of comparing its values: the same spectra,
    # bit for bit, and the same estimate
    given = frequency_cross_spectra(y, rep, ofdm, slots, tx.occupied(slots)[1][0])
    for (b1, k1, p1), (b2, k2, p2) in zip(cs.parts, given.parts):
        np.testing.assert_array_equal(b1, b2)
        np.testing.assert_array_equal(k1, k2)
        np.testing.assert_array_equal(p1.view(np.int64), p2.view(np.int64))
    # |X|^2 of every block's bins, written on the occupied ones only: the dense formula's values
    dense = np.abs(rep[block_index(rep)]) ** 2
    np.testing.assert_array_equal(cs.ref_power, dense)
    np.testing.assert_array_equal(given.ref_power, dense)
    assert ToAEstimator(ReceiverConfig(), GUARD)(given, nv).toa_s == fp.toa_s


#: noise-only searches and the false detections allowed: detection_false_alarm = 1e-3 per
#: search, so 150 draws expect 0.15; 3 or more has probability < 1e-3 (Poisson)
NOISE_DRAWS = 150
MAX_FALSE = 2


def test_hearability_threshold():
    nr, tx = _setup(slots=2)
    slots = range(2)
    ofdm = tx.ofdm
    rep = tx.replica(0, 0, slots)
    rng = np.random.default_rng(11)
    est = ToAEstimator(ReceiverConfig(), GUARD)
    false = 0
    for _ in range(NOISE_DRAWS):
        noise_only = add_noise(np.zeros((1, 2, 14, nr.num_subcarriers), complex), 1.0, rng)
        nv = noise_variance(noise_only, nr.prs_symbols)
        assert nv == pytest.approx(1.0, rel=0.12)   # 2 x 2 x 624 free REs: std 2%, 6 sigma
        quiet = est(frequency_cross_spectra(noise_only, rep, ofdm, slots), nv)
        false += quiet.detected
        assert quiet.detected or np.isnan(quiet.toa_s)
    assert false <= MAX_FALSE
    strict = dataclasses.replace(ReceiverConfig(), hearability_db=40.0)
    links = _links([2.2e-6], [0.0])
    y = add_noise(apply_frequency(links, rep[None], np.ones(1), ofdm, slots, 2e-6), 10.0, rng)
    cs = frequency_cross_spectra(y, rep, ofdm, slots)
    # post-correlation SNR = 2496 REs at -10 dB = 24 dB: heard at 8 dB, not at 40 dB
    assert est(cs, 10.0).detected
    assert not ToAEstimator(strict, GUARD)(cs, 10.0).detected


def test_comb_parts_hold_only_the_occupied_bins_and_match_the_dense_products():
    """frequency_cross_spectra keeps the replica's REs only (CrossSpectra.parts: the blocks
    grouped by comb pattern, 6 groups of N_sc / 6 bins for comb 6, TS 38.211's k' pattern over
    12 symbols). Second method: the same quantities from the dense spectra (CrossSpectra.dense
    handed over as ``spectra``): Doppler spectra (tolerance: their single precision, 1e-6
    relative), block combination, per-block correlation and spatial dof (double, 1e-12)."""
    nr, tx = _setup(slots=2)
    slots = range(2)
    rng = np.random.default_rng(3)
    rep = tx.replica(1, 0, slots)
    y = add_noise(np.zeros((5,) + rep.shape), 1.0, rng) + 3.0 * rep[None]
    cs = frequency_cross_spectra(y, rep, tx.ofdm, slots)
    assert cs.spectra is None and len(cs.parts) == nr.comb
    assert all(bins.size == nr.num_subcarriers // nr.comb for _, bins, _ in cs.parts)
    assert sorted(np.concatenate([b for b, _, _ in cs.parts])) == list(range(cs.ref_power.shape[0]))
    dense = dataclasses.replace(cs, spectra=cs.dense, parts=None)
    assert len(dense.occupied) == nr.comb            # the same groups, found from ref_power
    nus = np.arange(-400.0, 401.0, 25.0)
    tc = cs.block_times - cs.block_times.mean()
    flat = dataclasses.replace(cs, spectra=cs.dense, parts=None, ref_power=np.ones_like(cs.ref_power))
    assert flat.occupied is None                     # every bin occupied: the dense product
    d_ref = ToAEstimator.doppler_spectra(flat, nus, tc)
    np.testing.assert_allclose(ToAEstimator.doppler_spectra(cs, nus, tc), d_ref,
                               atol=1e-6 * np.abs(d_ref).max())
    w = np.exp(1j * rng.uniform(0, 2 * np.pi, tc.size))
    np.testing.assert_allclose(cs.combine(w), flat.combine(w), rtol=1e-12, atol=1e-12 * np.abs(flat.combine(w)).max())
    np.testing.assert_allclose(cs.at_delay(1.3e-6), flat.at_delay(1.3e-6), rtol=1e-12, atol=1e-12)
    from veriloc_rt.phy.receiver.toa import spatial_dof

    occupied = np.concatenate([q.reshape(5, -1) for _, _, q in cs.parts], axis=1)
    assert spatial_dof(occupied) == pytest.approx(spatial_dof(cs.dense.reshape(5, -1)), rel=1e-12)
    # the parts pooled without concatenating
    assert spatial_dof([q.reshape(5, -1) for _, _, q in cs.parts]) == pytest.approx(
        spatial_dof(occupied), rel=1e-12)


def test_spatial_dof_equals_the_eigenvalue_definition():
    """spatial_dof = 2 (sum lambda)^2 / sum lambda^2 over the eigenvalues of the sample spatial
    covariance (Satterthwaite), computed here with an eigendecomposition; trace and Frobenius
    norm give the same up to rounding (1e-10)."""
    from veriloc_rt.phy.receiver.toa import spatial_dof

    rng = np.random.default_rng(7)
    for mix in (np.eye(5), rng.standard_normal((5, 5)), np.outer(np.arange(1, 6), np.ones(5))):
        x = mix @ (rng.standard_normal((5, 3000)) + 1j * rng.standard_normal((5, 3000)))
        lam = np.clip(np.linalg.eigvalsh(x @ x.conj().T / x.shape[1]), 0.0, None)
        ref = float(np.clip(2.0 * lam.sum() ** 2 / np.sum(lam ** 2), 2.0, 10.0))
        assert spatial_dof(x) == pytest.approx(ref, rel=1e-10)
    assert spatial_dof(np.zeros((5, 10), complex)) == 10.0


@pytest.mark.parametrize("contiguous", [True, False])
def test_profile_power_equals_the_explicit_dft(contiguous):
    """ToAEstimator.lag_power: sum_a |sum_k g_ak e^{j 2 pi k l / n}|^2 on the searched lags (one
    wrapped run of the FFT's output, or any lags through the gather), against the DFT written
    out (second method; tolerance: double-precision FFT rounding, 1e-9 relative)."""
    rng = np.random.default_rng(5)
    pos = np.arange(40) if contiguous else np.sort(rng.choice(64, 40, replace=False))
    idx = pos + 7                           # bins need not start at 0: a common phase ramp
    g = rng.standard_normal((3, 4, 40)) + 1j * rng.standard_normal((3, 4, 40))
    n = 256
    lags = np.arange(-9, 120) if contiguous else np.array([-9, -2, 0, 5, 77, 130])
    got = ToAEstimator.lag_power(g, idx, lags, n)
    dft = np.exp(2j * np.pi * np.outer(lags, pos) / n)                       # [L, K]
    want = np.sum(np.abs(np.einsum("lk,vak->val", dft, g)) ** 2, axis=1)     # [V, L]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * want.max())


def test_frequency_cross_spectra_are_the_per_re_products_in_block_order():
    """Block b = (slot, symbol) in row-major order of the replica's non-zero symbols; S = Y X*
    per RE (written out RE by RE: second method; exact)."""
    nr, tx = _setup(slots=2)
    slots = range(2)
    rng = np.random.default_rng(2)
    rep = tx.replica(0, 0, slots)
    y = add_noise(np.zeros((2,) + rep.shape), 1.0, rng)
    for r in (rep, np.where(np.arange(14)[None, :, None] == 3, 0, rep)):   # a rectangle, a gap
        cs = frequency_cross_spectra(y, r, tx.ofdm, slots)
        blocks = [(s, l) for s in range(2) for l in range(14) if np.any(r[s, l] != 0)]
        want = np.stack([y[:, s, l] * np.conj(r[s, l]) for s, l in blocks], axis=1)
        np.testing.assert_array_equal(cs.dense, want)
        np.testing.assert_array_equal(cs.ref_power, np.abs(np.stack([r[s, l] for s, l in blocks])) ** 2)


def test_cross_spectra_of_a_kept_replica_are_those_of_a_fresh_copy():
    """A read-only replica (the transmitter's kept array: one object for every frame of a
    standard PRS) has its conj(X) and |X|^2 kept from call to call: the spectra are bit for bit
    those of a writable copy, whose terms are never kept (changing the copy changes the next
    call's result), and the kept terms are read-only."""
    nr, tx = _setup(slots=2)
    slots = range(2)
    kept = tx.replica(1, 0, slots, copy=False)
    assert not kept.flags.writeable and tx.replica(1, 5, slots, copy=False) is kept
    fresh = tx.replica(1, 0, slots)
    assert fresh.flags.writeable and fresh is not kept
    rng = np.random.default_rng(4)
    y = add_noise(np.zeros((2,) + kept.shape), 1.0, rng)
    for _ in range(2):
        a = frequency_cross_spectra(y, kept, tx.ofdm, slots)
        b = frequency_cross_spectra(y, fresh, tx.ofdm, slots)
        np.testing.assert_array_equal(a.dense, b.dense)
        np.testing.assert_array_equal(a.ref_power, b.ref_power)
    assert not a.ref_power.flags.writeable
    fresh[fresh != 0] *= 1j                     # S = Y conj(j X) = -j Y conj(X)
    c = frequency_cross_spectra(y, fresh, tx.ofdm, slots)
    np.testing.assert_allclose(c.dense, -1j * a.dense, rtol=1e-12)   # (rounding of the products)
    assert np.abs(c.dense - a.dense).max() > 0.1 * np.abs(a.dense).max()


#: the searches with the map cut and with the whole window may differ by the transforms'
#: rounding only: ToA within 1e-12 s (3e-4 m), Doppler within 1e-3 Hz (the map's single-precision
#: parabola), detections equal
CUT_TOA_S, CUT_DOPPLER_HZ = 1e-12, 1e-3


def test_first_path_map_cut_finds_what_the_whole_window_finds(monkeypatch):
    """The first-path map covers the lags up to the scan's last strong cell plus a margin, not
    the whole search window (:meth:`ToAEstimator.map_lags`). Reference: the same search with the
    whole window (the reach threshold lowered until every lag counts). Channels: a relay's copy
    of the link 7.5 us late, Doppler 250 Hz, 1 to 3 dB weaker than the direct path (a strong
    cell of the scan far past its strongest, which the map must cover: where nothing crosses the
    thresholds the search falls back on the map's strongest cell), then random multipath spread
    over the window; each with noise. And the cut does cover less than the window here."""
    from veriloc_rt.phy.receiver import toa

    nr, tx = _setup(slots=10)
    slots = range(10)
    ofdm = tx.ofdm
    rep = tx.replica(0, 0, slots)
    rng = np.random.default_rng(21)
    t0 = 1.75e-6
    cases = [(np.array([2.0e-6, 9.5e-6]), np.array([0.0, 250.0]), np.array([1.0, 10 ** (-db / 20)]))
             for db in (1.0, 2.0, 3.0)]
    for _ in range(6):
        n = int(rng.integers(2, 6))
        cases.append((2.0e-6 + np.sort(rng.uniform(0, 9e-6, n)), rng.uniform(-250, 250, n),
                      10 ** (-rng.uniform(0, 12, n) / 20)))
    cut_lags = []
    orig = ToAEstimator.map_lags
    monkeypatch.setattr(ToAEstimator, "map_lags",
                        staticmethod(lambda *a: cut_lags.append(orig(*a)) or cut_lags[-1]))
    for delays, doppler, amp in cases:
        gains = (amp * np.exp(1j * rng.uniform(0, 2 * np.pi, amp.size)))[None, None, :]
        links = Links(delays[None, :], gains, doppler[None, :], np.ones((1, delays.size), bool))
        nv = 0.5
        y = add_noise(apply_frequency(links, rep[None], np.ones(1), ofdm, slots, t0), nv, rng)
        cs = frequency_cross_spectra(y, rep, ofdm, slots)
        est = ToAEstimator(ReceiverConfig(), GUARD)
        cut = est(cs, nv)
        with monkeypatch.context() as m:
            m.setattr(toa, "FIRST_PATH_MAP_REACH_DB", 1e6)
            whole = est(cs, nv)
        assert cut.detected and whole.detected
        assert cut.toa_s == pytest.approx(whole.toa_s, abs=CUT_TOA_S)
        assert cut.doppler_hz == pytest.approx(whole.doppler_hz, abs=CUT_DOPPLER_HZ)
        assert cut.toa_s == pytest.approx(delays[0] - t0, abs=20e-9)   # the direct path
    # the lag grid: the 624 bins on a 1024-point grid, zero padded 4x; from -GUARD to the window
    rx = ReceiverConfig()
    step = 1.0 / (rx.upsample * 1024 * nr.subcarrier_spacing_hz)
    first = -int(np.ceil(GUARD / step))
    n_lags = int(np.ceil(rx.search_window_s / step)) + 1 - first
    for k in range(3):   # the relay cases: the map reaches past the relay's copy
        assert (first + cut_lags[2 * k]) * step > cases[k][0][1] - t0
    assert len(cut_lags) == 2 * len(cases) and cut_lags[-1] == n_lags   # the last: whole window
    assert min(cut_lags[0::2]) < n_lags


def test_profile_power_does_not_depend_on_the_previous_call():
    """lag_power keeps its zero-padded buffer from call to call: a call after a larger one with
    scattered bins (which leaves the whole buffer written) gives bit for bit what the same
    call gave first (the padding is zeroed again), and the explicit DFT (tolerance as above)."""
    rng = np.random.default_rng(8)
    g = rng.standard_normal((2, 3, 30)) + 1j * rng.standard_normal((2, 3, 30))
    idx, lags, n = np.arange(30), np.arange(-5, 60), 128
    first = ToAEstimator.lag_power(g, idx, lags, n)
    big = rng.standard_normal((4, 5, 50)) + 1j * rng.standard_normal((4, 5, 50))
    ToAEstimator.lag_power(big, np.sort(rng.choice(200, 50, replace=False)), np.arange(-9, 90), 256)
    ToAEstimator.lag_power(big.astype(np.complex64), np.arange(50), np.arange(-9, 90), 512)
    again = ToAEstimator.lag_power(g, idx, lags, n)
    np.testing.assert_array_equal(again, first)
    dft = np.exp(2j * np.pi * np.outer(lags, idx) / n)
    want = np.sum(np.abs(np.einsum("lk,vak->val", dft, g)) ** 2, axis=1)
    np.testing.assert_allclose(again, want, rtol=1e-9, atol=1e-9 * want.max())


#: single-precision transforms: float32 rounding over a few thousand terms, relative to the peak
C64_RTOL = 1e-5


@pytest.mark.parametrize("contiguous", [True, False])
def test_profile_power_on_the_chain_grid_equals_the_explicit_dft(contiguous):
    """On the chain's grid (624 bins zero-padded to 4096, the lags -16..737 of the search window)
    lag_power evaluates the window alone by the chirp-z transform; against the DFT written out
    (second method), windowed or not, in double precision (tolerance as above) and in single
    precision (C64_RTOL of the peak), twice (the work arrays are reused)."""
    rng = np.random.default_rng(11)
    k_n, n = 624, 4096
    pos = np.arange(k_n) if contiguous else np.sort(rng.choice(700, k_n, replace=False))
    idx = pos - 312
    lags = np.arange(-16, 738)
    assert zoom_plan(pos, -16, lags.size, n, np.dtype(np.complex128)) is not None
    g = rng.standard_normal((3, 5, k_n)) + 1j * rng.standard_normal((3, 5, k_n))
    win = np.cos(np.pi * np.linspace(-0.49, 0.49, k_n)) ** 2
    dft = np.exp(2j * np.pi * np.outer(lags, pos) / n)                       # [L, K]
    for w in (None, win):
        gw = g if w is None else g * w
        want = np.sum(np.abs(np.einsum("lk,vak->val", dft, gw)) ** 2, axis=1)
        for _ in range(2):
            got = ToAEstimator.lag_power(g, idx, lags, n, w)
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * want.max())
            got32 = ToAEstimator.lag_power(g.astype(np.complex64), idx, lags, n,
                                           None if w is None else w.astype(np.float32))
            np.testing.assert_allclose(got32, want, rtol=0, atol=C64_RTOL * want.max())


def _five_smooth(n: int) -> bool:
    for p in (2, 3, 5):
        while n % p == 0:
            n //= p
    return n == 1


def test_chirp_z_length_is_the_smallest_five_smooth_one_above_the_convolution():
    """fft_length(n): the smallest 2^a 3^b 5^c >= n, against a brute-force search (exact);
    on the chain's grid (P = 624 bins, M = 755 lags: n = 1378) 2^5 3^2 5 = 1440."""
    for n in range(1, 2500):
        want = next(m for m in range(n, 2 * n + 2) if _five_smooth(m))
        assert fft_length(n) == want
    assert fft_length(624 + 755 - 1) == 1440


@pytest.mark.parametrize("extra", [0, 31, None])
def test_chirp_z_gives_the_dft_at_any_length_above_the_linear_convolution(extra):
    """ZoomPlan's FFTs of length L compute a linear convolution of P + M - 1 outputs, so every
    L >= P + M - 1 gives the zero-padded DFT written out (second method; tolerance: double
    precision, 1e-9 relative as above): the bound itself (extra = 0), a prime length above it
    (P + M - 1 + 31 = 1409) and the default fft_length (None); below the bound the plan is
    refused (the convolution would wrap)."""
    rng = np.random.default_rng(12)
    pos, l0, m, n = np.arange(624), -16, 755, 4096
    lags = l0 + np.arange(m)
    size = None if extra is None else 624 + m - 1 + extra
    plan = ZoomPlan(pos, l0, m, n, np.dtype(np.complex128), size)
    assert plan.size == (1440 if extra is None else size)
    g = rng.standard_normal((2, 5, 624)) + 1j * rng.standard_normal((2, 5, 624))
    win = np.cos(np.pi * np.linspace(-0.49, 0.49, 624)) ** 2
    dft = np.exp(2j * np.pi * np.outer(lags, pos) / n)                        # [M, K]
    for w in (None, win):
        gw = g if w is None else g * w
        want = np.sum(np.abs(np.einsum("lk,vak->val", dft, gw)) ** 2, axis=1)
        np.testing.assert_allclose(plan.power(g, w), want, rtol=1e-9, atol=1e-9 * want.max())
    with pytest.raises(ValueError, match="below P \\+ M - 1"):
        ZoomPlan(pos, l0, m, n, np.dtype(np.complex128), 624 + m - 2)


def test_doppler_spectra_add_up_groups_whose_bins_overlap():
    """Blocks whose occupancy differs but overlaps (all bins, the even bins, two bins in three)
    form groups sharing bins: the Doppler spectra add the groups' products there (they were
    overwritten by the last group). Second method: the dense product over every block and bin
    (ref_power all ones: one group); tolerance: single precision, 1e-6 of the largest entry as
    above. The block combination is checked the same way in double precision (1e-12)."""
    rng = np.random.default_rng(21)
    a_n, b_n, k_n = 2, 4, 12
    ref = np.ones((b_n, k_n))
    ref[1, 1::2] = 0
    ref[3, ::3] = 0
    spectra = (rng.standard_normal((a_n, b_n, k_n)) + 1j * rng.standard_normal((a_n, b_n, k_n))) * (ref > 0)
    cs = CrossSpectra(spectra, np.arange(k_n) * 15e3, 15e3, np.arange(b_n) * 1e-3, ref, k_n * 15e3)
    assert len(cs.groups) == 3 and cs.bins_overlap
    flat = dataclasses.replace(cs, ref_power=np.ones_like(ref))
    assert len(flat.groups) == 1 and not flat.bins_overlap
    nus = np.arange(-50.0, 51.0, 25.0)
    tc = cs.block_times - cs.block_times.mean()
    want = ToAEstimator.doppler_spectra(flat, nus, tc)
    np.testing.assert_allclose(ToAEstimator.doppler_spectra(cs, nus, tc), want, rtol=0,
                               atol=1e-6 * np.abs(want).max())
    w = np.exp(1j * rng.uniform(0, 2 * np.pi, b_n))
    np.testing.assert_allclose(cs.combine(w), flat.combine(w), rtol=0, atol=1e-12 * np.abs(flat.combine(w)).max())


#: noise-only searches at a design detection_false_alarm of FA_DESIGN: the rate must not depend
#: on the Doppler step (the same noise maximum, sampled finer) and must be the design value up to
#: the cell count's approximation (a factor FA_FACTOR: measured 0.088-0.12 at 0.1 on 1000 draws
#: with 1 and 5 antennas, 1 and 10 slots). FA_DRAWS draws give the rate a binomial std of 0.02;
#: counting the scan's hypotheses gave 0.18 at 50 Hz and 0.03 at 6.25 Hz (10 slots, 400 draws:
#: docs/notes/performance-history.md) and fails this test
FA_DESIGN, FA_FACTOR, FA_DRAWS = 0.1, 2.0, 240
#: the two steps see the same noise: their rates differ only where a maximum straddles the
#: threshold (measured 0.003 apart on 1000 draws); 0.04 is 2 binomial std of one rate
FA_STEP_DIFF = 0.04


def test_noise_only_false_alarms_are_the_design_rate_at_every_doppler_step():
    nr, tx = _setup(slots=4)
    slots = range(4)
    rep = tx.replica(0, 0, slots)
    rng = np.random.default_rng(23)
    steps = (50.0, 6.25)
    ests = [ToAEstimator(dataclasses.replace(ReceiverConfig(), hearability_db=0.0, doppler_max_hz=300.0,
                                             doppler_step_hz=s, detection_false_alarm=FA_DESIGN), GUARD)
            for s in steps]
    assert ests[1].hypotheses.size == 8 * (ests[0].hypotheses.size - 1) + 1
    false = np.zeros(len(steps))
    for _ in range(FA_DRAWS):
        y = add_noise(np.zeros((5, 4, 14, nr.num_subcarriers), complex), 1.0, rng, major_axis=1)
        cs = frequency_cross_spectra(y, rep, tx.ofdm, slots)
        nv = noise_variance(y, nr.prs_symbols)
        false += [e(cs, nv).detected for e in ests]
    rate = false / FA_DRAWS
    assert abs(rate[0] - rate[1]) <= FA_STEP_DIFF
    assert np.all((rate >= FA_DESIGN / FA_FACTOR) & (rate <= FA_DESIGN * FA_FACTOR))
