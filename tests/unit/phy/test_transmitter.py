"""The transmitter stage: PRS values on the mapped REs, encrypted replicas, tags, waveform."""

import numpy as np
import pytest

from veriloc_rt.config.nr import NRConfig
from veriloc_rt.phy.nr.prs import prs_sequence
from veriloc_rt.phy.transmitter import PRSTransmitter
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.phy.security.encryption import encrypted_prs_sequence
from veriloc_rt.phy.security.keys import public_view, simulated_keys
from veriloc_rt.phy.receiver.tag_verifier import TagVerifier

BS_IDS = (21, 22, 23)


@pytest.fixture(scope="module")
def keys():
    return simulated_keys(BS_IDS, np.random.default_rng(7))


def make(keys, **sec):
    nr = NRConfig()
    security = SecurityConfig(**sec)
    return nr, security, PRSTransmitter(nr, security, BS_IDS, keys)


def test_grid_shape_and_prs_values(keys):
    _, _, tx = make(keys, tag_scheme="none")
    g = tx(frame=3)
    assert g.shape == (3, 10, 14, 624) and g.dtype == np.complex128
    kp = [0, 3, 1, 4, 2, 5] * 2
    for bs in range(3):
        for slot in (0, 9):
            for l in (0, 5, 11):
                k = np.arange((bs + kp[l]) % 6, 624, 6)
                np.testing.assert_array_equal(g[bs, slot, l, k], prs_sequence(bs, slot, l, 104))
        # nothing outside the BS's own PRS REs
        assert np.count_nonzero(g[bs]) == 10 * 12 * 104


def test_encrypted_bs_uses_its_keystream_and_replica_matches(keys):
    _, _, tx = make(keys, encrypted=(False, True, False), tag_scheme="none")
    g = tx(frame=77, slots=[2])
    k = np.arange((1 + 0) % 6, 624, 6)
    enc = encrypted_prs_sequence(keys[22].aes_key, 22, 1, 77, 2, 0, 104)
    np.testing.assert_array_equal(g[1, 0, 0, k], enc)
    np.testing.assert_array_equal(tx.replica(1, 77, [2]), g[1])
    # the standard replica of an encrypted BS is (nearly) uncorrelated with its signal
    std = tx.replica(1, 77, [2], encrypted=False)
    rho = abs(np.vdot(std, g[1])) / np.vdot(g[1], g[1]).real
    assert rho < 5 / np.sqrt(12 * 104)  # 5 sigma of |R|/N for N = 1248 i.i.d. QPSK products


@pytest.mark.parametrize("scheme", ["hmac", "ds"])
def test_tags_verify_noise_free_and_bind_frame_slot_bs(keys, scheme):
    nr, sec, tx = make(keys, tag_scheme=scheme, encrypted=(True, False, False))
    rx = tx(frame=1000, slots=[0, 4]).sum(axis=0)  # all three BSs superposed, flat unit channel
    ver = TagVerifier(nr, sec, BS_IDS, public_view(keys))
    for bs in range(3):
        assert ver(rx[1], bs, frame=1000, slot=4)
        assert not ver(rx[1], bs, frame=1001, slot=4)   # replayed in the next frame
        assert not ver(rx[1], bs, frame=1000, slot=5)   # moved to another slot
    # the tag of BS 0 checked as if it came from BS 1 fails (identity binding)
    rx_swapped = rx[1].copy()
    lay = tx.layout
    sym = lay.symbols[:, None]
    rx_swapped[sym, lay.tag_subcarriers(1)] = rx[1][sym, lay.tag_subcarriers(0)]
    assert not ver(rx_swapped, 1, frame=1000, slot=4)


def test_tags_survive_delay_and_phase_with_estimated_channel(keys):
    nr, sec, tx = make(keys, tag_scheme="hmac")
    rx = tx(frame=5, slots=[3]).sum(axis=0)[0]
    k = np.arange(624)
    h = 0.8 * np.exp(1j * 2.0 - 2j * np.pi * k * 15e3 * 3.1e-6)  # 3.1 us delay, phase 2 rad
    rng = np.random.default_rng(11)
    noise = np.sqrt(0.05 / 2) * (rng.standard_normal(rx.shape) + 1j * rng.standard_normal(rx.shape))
    ver = TagVerifier(nr, sec, BS_IDS, keys)
    for bs in range(3):
        assert ver(rx * h + noise, bs, 5, 3)
    # a pure-noise slot never verifies
    assert not any(ver(noise * 10, bs, 5, 3) for bs in range(3))


def test_waveform_demodulates_to_grid(keys):
    nr, _, tx = make(keys, tag_scheme="hmac")
    x = tx.waveform(frame=2, slots=[0, 1])
    assert x.shape == (3, tx.ofdm.num_samples([0, 1]))
    np.testing.assert_allclose(tx.ofdm.demodulate(x, [0, 1]), tx(2, [0, 1]), atol=1e-12)


def test_missing_keys_is_an_error():
    with pytest.raises(ValueError, match="no keys"):
        PRSTransmitter(NRConfig(), SecurityConfig(tag_scheme="hmac"), BS_IDS, None)


def test_tag_channel_noise_estimate_is_scale_free(keys):
    """The received grid is in physical units (per-RE noise ~1e-13 W at a UE): the estimated
    noise variance must scale with the grid's power (a receiver does not depend on the unit),
    and match the variance injected. Tolerance 15 %: ~1200 second differences of the pilots
    (std of a variance estimate ~ sqrt(2 / 1200) ~ 4 %, more with their overlap)."""
    from veriloc_rt.phy.receiver.tag_verifier import estimate_tag_channel

    nr, sec, tx = make(keys, tag_scheme="hmac")
    rx = tx(frame=5, slots=[3]).sum(axis=0)[0]
    k = np.arange(624)
    h = 0.8 * np.exp(1j * 2.0 - 2j * np.pi * k * 15e3 * 1.3e-6)
    rng = np.random.default_rng(12)
    var = 0.4   # per-RE SNR -2 dB, where an under-weighted LLR loses the tag
    noise = np.sqrt(var / 2) * (rng.standard_normal(rx.shape) + 1j * rng.standard_normal(rx.shape))
    y = rx * h + noise
    ver = TagVerifier(nr, sec, BS_IDS, keys)
    lay = tx.layout
    for bs in range(3):
        rep = tx.replica(bs, 5, [3])[0]
        _, nv1 = estimate_tag_channel(y, lay, bs, rep)
        assert abs(nv1 / var - 1) < 0.15
        for c in (1e-7, 1e3):   # a received amplitude of 0.1 uV (W ~ 1e-14) and a large one
            _, nv = estimate_tag_channel(c * y, lay, bs, rep)
            assert nv / c**2 == pytest.approx(nv1, rel=1e-9)
            assert ver(c * y, bs, 5, 3) == ver(y, bs, 5, 3)


@pytest.mark.parametrize("sec", [dict(tag_scheme="none"), dict(tag_scheme="hmac", tag_fill="repeat"),
                                 dict(tag_scheme="ds", tag_fill="single", encrypted=(True, False, True))])
def test_occupied_masks_are_the_grids_and_replicas_nonzero_res_in_every_frame(keys, sec):
    # the receivers read these masks instead of comparing the grids' values: they must be the
    # values' own nonzero pattern, exactly, whatever the frame (PRS encrypted or not, tags
    # repeated over every tag RE or sent once), and per requested slots
    _, _, tx = make(keys, **sec)
    for frame, slots in ((0, None), (4_000_000_000, [3, 7])):
        grids_occ, reps_occ = tx.occupied(slots)
        np.testing.assert_array_equal(grids_occ, tx(frame, slots) != 0)
        for bs in range(3):
            np.testing.assert_array_equal(reps_occ[bs], tx.replica(bs, frame, slots) != 0)
            np.testing.assert_array_equal(reps_occ[bs], tx.replica(bs, frame, slots, not sec.get("encrypted", (False,) * 3)[bs]) != 0)
        assert not grids_occ.flags.writeable and not any(r.flags.writeable for r in reps_occ)
    # single fill leaves tag REs empty, so the grid's mask is not the layout's
    if sec.get("tag_fill") == "single":
        assert np.count_nonzero(tx.occupied()[0][0]) < 2 * np.count_nonzero(tx.occupied()[1][0])
