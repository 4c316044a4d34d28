"""The ToA search's shortcut ``toa32`` (:mod:`veriloc_rt.phy.shortcuts`): the zero-padded delay
profiles transformed in single precision.

Reference values: the profile's power from the DFT written out in double precision, and the
estimator's reference path (``VERILOC_RT_REFERENCE=toa32``) on the same cross-spectra.
"""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.config.channel import ReceiverConfig
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.phy.channel import Links, add_noise, apply_frequency
from veriloc_rt.phy.receiver.sync import frequency_cross_spectra
from veriloc_rt.phy.receiver.toa import ToAEstimator
from veriloc_rt.phy.transmitter import PRSTransmitter

GUARD = 0.25e-6
#: single-precision transforms: rounding of 2^-24 relative per operation, grown by the
#: transforms' log2(L) ~ 10 stages and the chirp-z's two transforms: 1e-5 of the peak bounds it
#: with a margin of ~10 (the same bound as test_toa.py's C64_RTOL)
C64_RTOL = 1e-5
#: the ToA with and without the shortcut, s: the profiles only choose the grid cell (16 ns) the
#: double-precision sub-sample refinement starts from, so the same cell gives the same ToA up
#: to double precision's rounding of the refinement (1e-15 s is 1e-9 of a cell)
TOA_ABS_S = 1e-15
#: the peak SNR with and without it, dB: the peak's power rounded to ~1e-6 relative in single
#: precision is 4e-6 dB; 1e-4 dB leaves a margin of 25
SNR_ABS_DB = 1e-4


def test_profile_power_in_single_precision_equals_the_explicit_dft():
    """lag_power of double-precision spectra with ``dtype=complex64`` (the shortcut's call) on
    the chain's grid (624 bins zero-padded to 4096, lags -16..737, the chirp-z path; and the
    whole-grid path on lags that wrap), windowed or not, against the DFT written out in double
    precision: within C64_RTOL of the peak."""
    rng = np.random.default_rng(5)
    k_n, n = 624, 4096
    pos = np.arange(k_n)
    idx = pos - 312
    g = rng.standard_normal((5, k_n)) + 1j * rng.standard_normal((5, k_n))
    win = np.cos(np.pi * np.linspace(-0.49, 0.49, k_n)) ** 2
    for lags in (np.arange(-16, 738), np.arange(-16, 128), np.arange(-900, 3000)):
        dft = np.exp(2j * np.pi * np.outer(lags, pos) / n)                       # [L, K]
        for w in (None, win):
            gw = g if w is None else g * w
            want = np.sum(np.abs(dft @ gw.T) ** 2, axis=1)
            got = ToAEstimator.lag_power(g, idx, lags, n, w, np.dtype(np.complex64))
            assert got.dtype == np.float64 and got.shape == want.shape
            np.testing.assert_allclose(got, want, rtol=0, atol=C64_RTOL * want.max())
            # and not the double-precision result: the shortcut does change the rounding
            exact = ToAEstimator.lag_power(g, idx, lags, n, w)
            assert not np.array_equal(got, exact)


@pytest.mark.parametrize("method", ["first_path", "strongest"])
def test_estimates_with_and_without_toa32_agree(monkeypatch, method):
    """A noisy two-path link (an early path 8 dB under the strong one, 250 ns before it, with
    different Dopplers) over 10 slots: the estimator with the shortcut alone (the other ToA
    shortcuts named in VERILOC_RT_REFERENCE) and on the reference path (``toa32`` named too,
    or ``all``; read when the estimator is built) detect
    alike, give the same Doppler, the same ToA within TOA_ABS_S and the peak SNR within
    SNR_ABS_DB; the reference path is the double-precision transform."""
    nr = NRConfig(slots_per_frame=10)
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="none"), (1, 2, 3))
    slots = range(10)
    rep = tx.replica(0, 0, slots)
    links = Links(np.array([[2.0e-6, 2.25e-6]]), np.array([[[10 ** (-8 / 20), np.exp(1j)]]]),
                  np.array([[90.0, -40.0]]), np.ones((1, 2), bool))
    cfg = ReceiverConfig(toa_method=method, doppler_max_hz=150.0)
    nv = 0.25
    for seed in range(4):
        rng = np.random.default_rng(seed)
        y = add_noise(apply_frequency(links, rep[None], np.ones(1), tx.ofdm, slots, 1.75e-6), nv, rng)
        cs = frequency_cross_spectra(y, rep, tx.ofdm, slots)
        monkeypatch.setenv("VERILOC_RT_REFERENCE", "dofherk,spectra32")   # toa32 alone
        fast = ToAEstimator(cfg, GUARD)
        assert fast.profile_dtype == np.complex64
        a = fast(cs, nv)
        for named in ("toa32,dofherk,spectra32", "all"):
            monkeypatch.setenv("VERILOC_RT_REFERENCE", named)
            ref = ToAEstimator(cfg, GUARD)
            assert ref.profile_dtype is None
            b = ref(cs, nv)
            assert a.detected and b.detected
            assert a.doppler_hz == b.doppler_hz
            assert a.toa_s == pytest.approx(b.toa_s, abs=TOA_ABS_S)
            assert a.peak_snr_db == pytest.approx(b.peak_snr_db, abs=SNR_ABS_DB)
            np.testing.assert_allclose(a.snapshots, b.snapshots, rtol=1e-6)


#: ``dofherk`` against the eigenvalue definition and the reference's products: the same sums of
#: ~10^4 float64 products in another order, relative rounding ~1e-16 sqrt(n) per entry; 1e-12
#: leaves a margin of ~1e2 (the test of the reference itself uses 1e-10 against eigvalsh)
HERK_RTOL = 1e-12


def test_spatial_dof_by_the_hermitian_update_equals_the_eigenvalue_definition():
    """spatial_dof(..., hermitian=True) (zherk, one triangle) against 2 (sum lambda)^2 /
    sum lambda^2 over the eigenvalues of the sample covariance (eigvalsh of the products written
    out), for white, mixed and rank-1 fields, one block or several pooled (the chain's comb
    groups), and tr R against sum |x|^2; within HERK_RTOL; the reference path's value is the
    products' (``hermitian=False``)."""
    from veriloc_rt.phy.receiver.toa import spatial_covariance_stats, spatial_dof

    rng = np.random.default_rng(3)
    for mix in (np.eye(5), rng.standard_normal((5, 5)), np.outer(np.arange(1, 6), np.ones(5))):
        x = mix @ (rng.standard_normal((5, 3000)) + 1j * rng.standard_normal((5, 3000)))
        lam = np.clip(np.linalg.eigvalsh(x @ x.conj().T), 0.0, None)
        want = float(np.clip(2.0 * lam.sum() ** 2 / np.sum(lam ** 2), 2.0, 10.0))
        parts = [np.ascontiguousarray(x[:, i:i + 500]) for i in range(0, 3000, 500)]
        for blocks in (x, parts):
            tr, dof = spatial_covariance_stats(blocks, True)
            assert dof == pytest.approx(want, rel=HERK_RTOL)
            assert tr == pytest.approx(float(np.sum(np.abs(x) ** 2)), rel=HERK_RTOL)
            assert spatial_dof(blocks, True) == dof
            assert spatial_dof(blocks, False) == pytest.approx(dof, rel=HERK_RTOL)
    assert spatial_dof(np.zeros((5, 10), complex), True) == 10.0
    assert spatial_dof(np.ones((1, 10), complex), True) == 2.0


def test_noise_estimates_by_the_hermitian_update_and_the_switch(monkeypatch):
    """noise_estimates(..., hermitian=True): the mean power of the free symbols (tr R over their
    count) and their dof against the reference's values (``_mean_power`` and the products)
    within HERK_RTOL; TimingStage and ToAEstimator take the path from VERILOC_RT_REFERENCE when
    built (``dofherk`` or ``all``: the reference)."""
    from veriloc_rt.config.channel import ChannelConfig
    from veriloc_rt.phy.chain.receiver import TimingStage
    from veriloc_rt.phy.nr.ofdm import OFDM
    from veriloc_rt.phy.receiver.sync import noise_estimates

    rng = np.random.default_rng(8)
    grid = rng.standard_normal((5, 3, 14, 48)) + 1j * rng.standard_normal((5, 3, 14, 48))
    grid[:, :, :, :24] *= 3.0                             # not white: the dof is below 2 A
    busy = tuple(range(3, 14))
    nv_ref, dof_ref = noise_estimates(grid, busy)
    nv, dof = noise_estimates(grid, busy, True)
    free = grid[:, :, :3, :]
    assert nv == pytest.approx(float(np.mean(np.abs(free) ** 2)), rel=HERK_RTOL)
    assert nv == pytest.approx(nv_ref, rel=HERK_RTOL)
    assert dof == pytest.approx(dof_ref, rel=HERK_RTOL) and dof < 10.0
    ofdm = OFDM(NRConfig(slots_per_frame=2))
    for env, fast in ((None, True), ("toa32", True), ("dofherk", False), ("all", False)):
        if env is None:
            monkeypatch.delenv("VERILOC_RT_REFERENCE", raising=False)
        else:
            monkeypatch.setenv("VERILOC_RT_REFERENCE", env)
        est = ToAEstimator(ReceiverConfig(), GUARD)
        assert est.hermitian is fast
        stage = TimingStage(est, ofdm, range(2), ChannelConfig(), 12e-6, busy, 1.0)
        assert stage.hermitian is fast


#: ``spectra32``: sums of 20-120 products of complex64-rounded spectra (relative rounding
#: 2^-24 = 6e-8 per product and addition) against the double-precision sums: 1e-5 of the
#: largest entry bounds the error with a margin of ~10 (C64_RTOL's bound)
S32_RTOL = C64_RTOL


def test_single_precision_combinations_equal_the_double_precision_sums(monkeypatch):
    """The scan's single-precision copies (``doppler_spectra``'s ``keep``) combined over the
    blocks and over the bins (SingleSpectra) against the sums written out in double precision
    on the dense spectra (sum_b w_b S_abk; sum_k S_abk e^{j2pi f_k tau}), for a comb-6 PRS (six
    groups of blocks) and a dense replica (one group): within S32_RTOL of the largest entry;
    results in complex128. The estimator reads the switch when built (``spectra32``, ``all``:
    the double-precision spectra), and both paths give the same detection and a ToA within
    TOA_ABS_S x 1e3 (the combinations' rounding reaches the refinement through the combined
    spectra: 1e-12 s is 0.3 mm)."""
    from veriloc_rt.phy.receiver.toa import SingleSpectra

    nr = NRConfig(slots_per_frame=4)
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="none"), (1, 2, 3))
    slots = range(4)
    rep = tx.replica(0, 0, slots)
    rng = np.random.default_rng(12)
    links = Links(np.array([[2.0e-6]]), np.array([[[1.0]]]), np.array([[60.0]]), np.ones((1, 1), bool))
    y = add_noise(apply_frequency(links, rep[None], np.ones(1), tx.ofdm, slots, 1.75e-6), 0.5, rng)
    dense_rep = np.where(rep != 0, rep, 1.0 + 0j)                # every RE occupied: one group
    for replica in (rep, dense_rep):
        cs = frequency_cross_spectra(y, replica, tx.ofdm, slots)
        tc = cs.block_times - cs.block_times.mean()
        keep = []
        ToAEstimator.doppler_spectra(cs, np.array([-50.0, 0.0, 50.0]), tc, None, keep)
        assert len(keep) == len(cs.groups)
        single = SingleSpectra(cs, keep)
        w = np.exp(-2j * np.pi * 37.0 * tc)
        want = np.einsum("b,abk->ak", w, cs.dense)
        got = single.combine(w)
        assert got.dtype == np.complex128
        np.testing.assert_allclose(got, want, rtol=0, atol=S32_RTOL * np.abs(want).max())
        tau = 0.31e-6
        want = np.einsum("abk,k->ab", cs.dense, np.exp(2j * np.pi * cs.freqs * tau))
        got = single.at_delay(tau)
        assert got.dtype == np.complex128
        np.testing.assert_allclose(got, want, rtol=0, atol=S32_RTOL * np.abs(want).max())
        assert not np.array_equal(got, cs.at_delay(tau))
    cfg = ReceiverConfig(doppler_max_hz=150.0)
    cs = frequency_cross_spectra(y, rep, tx.ofdm, slots)
    monkeypatch.setenv("VERILOC_RT_REFERENCE", "toa32,dofherk")             # spectra32 alone
    fast = ToAEstimator(cfg, GUARD)
    assert fast.single_spectra
    a = fast(cs, 0.5)
    for named in ("toa32,dofherk,spectra32", "all"):
        monkeypatch.setenv("VERILOC_RT_REFERENCE", named)
        ref = ToAEstimator(cfg, GUARD)
        assert not ref.single_spectra
        b = ref(cs, 0.5)
        assert a.detected and b.detected
        assert a.toa_s == pytest.approx(b.toa_s, abs=1e3 * TOA_ABS_S)
        assert a.doppler_hz == pytest.approx(b.doppler_hz, abs=1e-3)
