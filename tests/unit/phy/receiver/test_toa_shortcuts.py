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
    different Dopplers) over 10 slots: the estimator with the shortcut (default) and on the
    reference path (``VERILOC_RT_REFERENCE=toa32``, read when the estimator is built) detect
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
        monkeypatch.delenv("VERILOC_RT_REFERENCE", raising=False)
        fast = ToAEstimator(cfg, GUARD)
        assert fast.profile_dtype == np.complex64
        a = fast(cs, nv)
        for named in ("toa32", "all"):
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
