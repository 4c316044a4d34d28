"""The receiver's work on several TRPs at once gives each TRP's values bit for bit.

The batched paths (:func:`frequency_cross_spectra_many`, :func:`noise_estimates`, the tag
check on the channel of the tag REs alone) exist for speed only: each is checked against the
one-TRP path it replaces and against the formula itself (S = Y X* on the replica's REs; the
mean |Y|^2 of the free symbols), with no tolerance where the same floating-point operations
run (bit equality), and 1e-12 relative where the formula is evaluated in another order.
"""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.config.nr import NRConfig
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.phy.channel import add_noise
from veriloc_rt.phy.receiver.sync import (frequency_cross_spectra, frequency_cross_spectra_many,
                                          noise_dof, noise_estimates, noise_variance)
from veriloc_rt.phy.receiver.tag_verifier import TagVerifier, estimate_tag_channel
from veriloc_rt.phy.receiver.toa import spatial_dof
from veriloc_rt.phy.security.keys import simulated_keys
from veriloc_rt.phy.transmitter import PRSTransmitter

BS_IDS = (21, 22, 23)


def _bits(a: np.ndarray) -> bytes:
    return np.ascontiguousarray(a).tobytes()


@pytest.fixture(scope="module")
def scene():
    """Three TRPs' comb-6 PRS (mapping of TS 38.211 7.4.1.7.3: the same 12 symbols, the
    config's comb offsets 0, 1, 2) through different gains, plus noise, on a 4-antenna grid of
    2 slots."""
    nr = NRConfig(slots_per_frame=2)
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="none"), BS_IDS)
    slots = range(2)
    reps = [tx.replica(b, 0, slots) for b in range(3)]
    rng = np.random.default_rng(5)
    gains = np.array([1.0, 0.5j, -0.25])[:, None, None, None, None]
    y = add_noise(np.zeros((4,) + reps[0].shape, complex), 1.0, rng) + (gains * np.array(reps)[:, None]).sum(0)
    return nr, tx, slots, reps, y


def test_cross_spectra_of_several_replicas_are_each_replicas_own(scene):
    nr, tx, slots, reps, y = scene
    many = frequency_cross_spectra_many(y, reps, tx.ofdm, slots)
    occ = [tx.occupied(slots)[1][b] for b in range(3)]
    given = frequency_cross_spectra_many(y, reps, tx.ofdm, slots, occ)
    # the premise of the shared pass: every TRP's groups read the same sets of blocks
    block_sets = [sorted(tuple(bl) for bl, _, _ in cs.parts) for cs in many]
    assert block_sets[0] == block_sets[1] == block_sets[2]
    # ... each on other bins (its own comb offset in each symbol)
    bins_of = [{tuple(bl): tuple(k) for bl, k, _ in cs.parts} for cs in many]
    assert all(len({b[blk] for b in bins_of}) == 3 for blk in bins_of[0])
    for b, rep in enumerate(reps):
        one = frequency_cross_spectra(y, rep, tx.ofdm, slots)
        for cs in (many[b], given[b]):
            assert len(cs.parts) == len(one.parts) == nr.comb
            for (b1, k1, p1), (b2, k2, p2) in zip(one.parts, cs.parts):
                np.testing.assert_array_equal(b1, b2)
                np.testing.assert_array_equal(k1, k2)
                assert p2.flags.c_contiguous and _bits(p1) == _bits(p2)
            assert _bits(cs.ref_power) == _bits(one.ref_power)
            assert _bits(cs.block_times) == _bits(one.block_times)
            # the formula: S = Y X* (the same product on the replica's REs: exactly equal;
            # 0 elsewhere, where Y 0* may be a signed zero)
            s_idx, l_idx = np.nonzero(np.any(rep != 0, axis=-1))
            direct = y[:, s_idx, l_idx, :] * np.conj(rep[s_idx, l_idx])[None]
            np.testing.assert_array_equal(cs.dense, direct)


def test_cross_spectra_many_checks_its_arguments(scene):
    _, tx, slots, reps, y = scene
    with pytest.raises(ValueError, match="one entry per replica"):
        frequency_cross_spectra_many(y, reps, tx.ofdm, slots, [None])
    with pytest.raises(ValueError, match="rx_grid"):
        frequency_cross_spectra_many(y[0], reps, tx.ofdm, slots)


def test_noise_estimates_are_the_two_estimators_values(scene):
    nr, _, _, _, y = scene
    nv, dof = noise_estimates(y, nr.prs_symbols)
    assert nv == noise_variance(y, nr.prs_symbols)
    assert dof == noise_dof(y, nr.prs_symbols)
    free = [s for s in range(14) if s not in nr.prs_symbols]
    # the definitions, summed in another order: 1e-12 relative (float64 rounding over 10^4 terms)
    assert nv == pytest.approx(float(np.mean(np.abs(y[..., free, :]) ** 2)), rel=1e-12)
    assert dof == pytest.approx(spatial_dof(y[..., free, :].reshape(4, -1)), rel=1e-12)
    # every symbol busy: no estimate (NaN) and the independent-antenna dof 2 A
    nv0, dof0 = noise_estimates(y, range(14))
    assert np.isnan(nv0) and dof0 == 8.0


def test_tag_check_on_the_tag_res_channel_is_the_full_grids():
    """The tag check given the channel on the tag REs alone decides as with that channel
    written into a full grid (the chain's old route), for a slot that verifies and one that
    does not."""
    keys = simulated_keys(BS_IDS, np.random.default_rng(7))
    nr, sec = NRConfig(), SecurityConfig(tag_scheme="hmac")
    tx = PRSTransmitter(nr, sec, BS_IDS, keys)
    ver = TagVerifier(nr, sec, BS_IDS, keys)
    lay = tx.layout
    rx = tx(frame=5, slots=[3]).sum(axis=0)[0]
    rng = np.random.default_rng(11)
    noise = np.sqrt(0.05 / 2) * (rng.standard_normal(rx.shape) + 1j * rng.standard_normal(rx.shape))
    for y, verifies in ((rx + noise, True), (10 * noise, False)):
        for bs in range(3):
            rep = tx.replica(bs, 5, [3])[0]
            h_t, nv = estimate_tag_channel(y, lay, bs, rep)
            full = np.zeros_like(y)
            full[lay.symbols[:, None], lay.tag_subcarriers(bs)] = h_t
            a = ver.check(y, bs, 5, 3, channel=full, noise_var=nv)
            b = ver.check(y, bs, 5, 3, noise_var=nv, tag_channel=h_t)
            assert a == b
            assert b.valid == verifies
    with pytest.raises(ValueError, match="needs `noise_var`"):
        ver.check(rx, 0, 5, 3, tag_channel=h_t)
    with pytest.raises(ValueError, match="shape"):
        ver.check(rx, 0, 5, 3, noise_var=1.0, tag_channel=h_t[:, :3])
