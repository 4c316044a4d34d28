"""Noise sources alone: the variance they add against the configured receiver noise, and the
shared grid's identity across domains and slot counts."""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.config.channel import ChannelConfig
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.phy.channel import receiver_noise_variance
from veriloc_rt.phy.noise import GridNoise, KeptWhiteNoise, WhiteNoise
from veriloc_rt.phy.nr.ofdm import OFDM

#: Boltzmann's constant (J/K, SI 2019 exact) and the reference temperature T0 = 290 K (ITU-R P.372)
K_B, T0 = 1.380649e-23, 290.0
#: sample variance of n complex Gaussian samples: relative std 1 / sqrt(n); n >= 1.6e5 here,
#: 2.5e-3, so 2 % is 8 sigma
VARIANCE_REL = 0.02
#: float64 round-off of an orthonormal FFT pair on O(1e-12) values
ROUNDOFF = 1e-9


def grid_shape(ofdm: OFDM, slots: int, ant: int = 5) -> tuple:
    return (ant, slots, 14, ofdm.num_subcarriers)


def counted_slot_draws(monkeypatch) -> list:
    """A list that grows by one at each call of the noise module's slot-by-slot draw (the
    calls go through, unchanged)."""
    import veriloc_rt.phy.noise as noise_module

    draws = []
    real = noise_module.draw_grid_noise_slots
    monkeypatch.setattr(noise_module, "draw_grid_noise_slots",
                        lambda *a, **k: draws.append(1) or real(*a, **k))
    return draws


@pytest.mark.parametrize("snr_db", [0.0, 20.0])
def test_white_noise_variance_matches_the_configured_snr(snr_db):
    """The UE's variance per RE is k T0 F f_s (F = 9 dB, the UE's noise figure); a signal of
    per-RE power P = var * 10^(SNR/10) plus the source's noise has measured SNR within the
    sample-variance tolerance of the configured one."""
    nr = NRConfig(slots_per_frame=2)
    ofdm = OFDM(nr)
    ch = ChannelConfig()
    var = receiver_noise_variance(ch, ofdm.sample_rate_hz, ch.ue_noise_figure_db)
    assert var == pytest.approx(K_B * T0 * 10 ** (ch.ue_noise_figure_db / 10) * ofdm.sample_rate_hz,
                                rel=1e-12)
    rng = np.random.default_rng(1)
    amp = np.sqrt(var * 10 ** (snr_db / 10))
    phases = np.exp(2j * np.pi * rng.random(grid_shape(ofdm, 2)))
    x = amp * phases
    y = WhiteNoise()(x, var, np.random.default_rng(2))
    n = y - x
    assert np.mean(np.abs(n) ** 2) == pytest.approx(var, rel=VARIANCE_REL)
    measured_snr_db = 10 * np.log10(np.mean(np.abs(x) ** 2) / np.mean(np.abs(n) ** 2))
    assert measured_snr_db == pytest.approx(snr_db, abs=10 * np.log10(1 + VARIANCE_REL))
    # circular: real and imaginary parts carry half each
    assert np.var(n.real) == pytest.approx(var / 2, rel=VARIANCE_REL)


def test_white_noise_draws_a_grid_slot_major():
    """The first slots' noise does not depend on the number of slots (the tags-only call of the
    chain receives the first slots alone): the same generator state gives the same first slot."""
    ofdm = OFDM(NRConfig(slots_per_frame=4))
    one = WhiteNoise()(np.zeros(grid_shape(ofdm, 1)), 1.0, np.random.default_rng(3))
    four = WhiteNoise()(np.zeros(grid_shape(ofdm, 4)), 1.0, np.random.default_rng(3))
    np.testing.assert_array_equal(one[:, 0], four[:, 0])


def test_zero_variance_adds_nothing():
    x = np.ones((2, 7), complex)
    for src in (WhiteNoise(), GridNoise(OFDM(NRConfig(slots_per_frame=1)), range(1))):
        y = src(x, 0.0, np.random.default_rng(0))
        np.testing.assert_array_equal(y, x)
        assert y is not x


def test_grid_noise_reaches_grid_and_iq_alike():
    """The supplied generator's grid is added to a grid as is, and OFDM-modulated into IQ; the
    receiver's demodulation of that IQ gives the same grid back (orthonormal FFT, CP discarded):
    second method, the demodulated IQ against the frequency-domain result."""
    nr = NRConfig(slots_per_frame=2)
    ofdm, slots = OFDM(nr), range(2)
    var = 3e-12
    g = GridNoise(ofdm, slots, np.random.default_rng(5))(np.zeros(grid_shape(ofdm, 2)), var,
                                                          np.random.default_rng(0))
    n_iq = ofdm.num_samples(slots) + 100   # a receive buffer longer than the frame
    iq = GridNoise(ofdm, slots, np.random.default_rng(5))(np.zeros((5, n_iq), complex), var,
                                                           np.random.default_rng(0))
    np.testing.assert_allclose(ofdm.demodulate(iq, slots), g, atol=ROUNDOFF * np.sqrt(var))
    assert np.all(iq[:, ofdm.num_samples(slots):] == 0)   # the tail gets none
    assert np.mean(np.abs(g) ** 2) == pytest.approx(var, rel=VARIANCE_REL)


def test_grid_noise_follows_the_call_generator_only_without_a_supplied_one():
    ofdm = OFDM(NRConfig(slots_per_frame=1))
    src = GridNoise(ofdm, range(1))
    assert src.follows_call_rng
    x = np.zeros(grid_shape(ofdm, 1))
    a = src(x, 1.0, np.random.default_rng(7))
    src.supply(np.random.default_rng(7))
    assert not src.follows_call_rng
    call = np.random.default_rng(99)
    state = call.bit_generator.state
    b = src(x, 1.0, call)
    np.testing.assert_array_equal(a, b)                 # the supplied generator's draws
    assert call.bit_generator.state == state            # the call's generator untouched
    with pytest.raises(TypeError, match="rng"):
        src.supply(7)


def test_kept_white_noise_draws_once_per_generator_state(monkeypatch):
    """KeptWhiteNoise (a run's chains share one thermal noise per point): the first call is
    WhiteNoise's, bit for bit (second method: WhiteNoise on a generator in the same state); a
    call from a generator in the same state, for another signal of the same shape, adds the
    same noise without drawing and leaves the generator where the draws leave it; another
    variance or shape draws anew, and at most ``size`` draws are kept."""
    draws = counted_slot_draws(monkeypatch)
    shape = (2, 3, 14, 12)
    rng = np.random.default_rng(5)
    x1 = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    x2 = 3.0 * x1[::-1]
    kept = KeptWhiteNoise(size=2)
    gens = [np.random.default_rng(9) for _ in range(3)]
    ref = WhiteNoise()(x1, 0.5, gens[0])
    y1 = kept(x1, 0.5, gens[1])
    np.testing.assert_array_equal(y1, ref)
    before = gens[2].bit_generator.state
    y2 = kept(x2, 0.5, gens[2])
    assert len(draws) == 1
    np.testing.assert_array_equal(y2, WhiteNoise()(x2, 0.5, np.random.default_rng(9)))   # the same noise
    assert gens[2].bit_generator.state == gens[0].bit_generator.state != before
    kept(x2, 0.25, np.random.default_rng(9))                        # another variance
    kept(x1[..., :6], 0.5, np.random.default_rng(9))                # another shape
    assert len(draws) == 3
    # two kept (size 2): the first draw was dropped, so it is drawn again, the same values
    again = kept(x1, 0.5, np.random.default_rng(9))
    assert len(draws) == 4
    np.testing.assert_array_equal(again, ref)


@pytest.mark.parametrize("single", [False, True])
@pytest.mark.parametrize("masked", [False, True])
def test_kept_white_noise_gives_the_first_slots_of_a_kept_draw(monkeypatch, single, masked):
    """A grid of the first S' slots from a generator in a kept draw's state gets that draw's
    first S' slots and the generator in the state drawing them leaves it in, without drawing:
    bit for bit what a fresh KeptWhiteNoise draws for the S' slots from the same state (second
    method), and the generator's next draws the same; with the REs read (the shortcut
    ``noise``) and single-precision normals (``noise32``) too. A mask that differs in those
    slots, or more slots than kept, draws anew."""
    draws = counted_slot_draws(monkeypatch)
    shape = (3, 4, 14, 24)
    rng = np.random.default_rng(1)
    x = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    read = None
    if masked:
        read = rng.uniform(size=shape[1:]) < 0.6
        read[0, 3] = False                      # slot 0 with a symbol unread, slot 2 empty
        read[2] = False
        read.flags.writeable = False
    kept = KeptWhiteNoise()
    full = kept.add_on_read(x, 0.7, np.random.default_rng(4), read, single)
    for m in (1, 2, 3, 4):
        g_kept, g_fresh = np.random.default_rng(4), np.random.default_rng(4)
        got = kept.add_on_read(x[:, :m], 0.7, g_kept, read, single)
        want = KeptWhiteNoise().add_on_read(x[:, :m], 0.7, g_fresh, read, single)
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
        np.testing.assert_array_equal(got, full[:, :m])
        assert g_kept.bit_generator.state == g_fresh.bit_generator.state
        np.testing.assert_array_equal(g_kept.standard_normal(5), g_fresh.standard_normal(5))
    assert len(draws) == 1 + 4                  # the fresh ones only
    draws.clear()
    if masked:
        other = read.copy()
        other[1, 0, 0] = not other[1, 0, 0]
        kept.add_on_read(x[:, :2], 0.7, np.random.default_rng(4), other, single)
        assert len(draws) == 1
    bigger = np.concatenate([x, x[:, :1]], axis=1)
    kept.add_on_read(bigger, 0.7, np.random.default_rng(4), None if read is None
                     else np.concatenate([read, read[:1]]), single)
    assert len(draws) == 1 + masked


@pytest.mark.parametrize("single", [False, True])
def test_grid_noise_drawn_slot_by_slot_is_the_one_draws(single):
    """draw_grid_noise_slots: the values of draw_grid_noise_on (REs read) and of draw_noise
    with major_axis 1 (every RE), bit for bit (second method: those, from the same state), and
    after slot s the generator state drawing the first s + 1 slots alone leaves."""
    from veriloc_rt.phy.channel import draw_grid_noise_on, draw_grid_noise_slots, draw_noise

    shape = (2, 3, 14, 36)
    read = np.random.default_rng(2).uniform(size=(4, 14, 36)) < 0.5
    for r in (read, None):
        n, states = draw_grid_noise_slots(shape, r, 1.3, np.random.default_rng(8), single)
        want = (draw_grid_noise_on(shape, r, 1.3, np.random.default_rng(8), single) if r is not None
                else draw_noise(shape, 1.3, np.random.default_rng(8), 1, single))
        np.testing.assert_array_equal(n.view(np.float64), want.view(np.float64))
        for s in range(shape[1]):
            g = np.random.default_rng(8)
            sub = (shape[0], s + 1) + shape[2:]
            if r is not None:
                draw_grid_noise_on(sub, r, 1.3, g, single)
            else:
                draw_noise(sub, 1.3, g, 1, single)
            assert states[s] == g.bit_generator.state


@pytest.mark.parametrize("masked", [False, True])
def test_kept_noise_added_into_the_callers_grid_has_the_new_arrays_bits(masked):
    """KeptWhiteNoise.add_on_read with overwrite_x: the noise added into x's own array, the
    same bits as the new array of the default (second method: that call, from the same
    generator state; complex addition commutes exactly); a read-only x or another dtype gets
    a new array and stays as it was."""
    shape = (2, 3, 14, 24)
    rng = np.random.default_rng(7)
    x = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    read = rng.uniform(size=shape[1:]) < 0.5 if masked else None
    want = KeptWhiteNoise().add_on_read(x.copy(), 0.3, np.random.default_rng(5), read, True)
    mine = x.copy()
    got = KeptWhiteNoise().add_on_read(mine, 0.3, np.random.default_rng(5), read, True,
                                       overwrite_x=True)
    assert got is mine
    np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
    assert not np.array_equal(got, x)                  # the noise is there
    frozen = x.copy()
    frozen.flags.writeable = False
    got = KeptWhiteNoise().add_on_read(frozen, 0.3, np.random.default_rng(5), read, True,
                                       overwrite_x=True)
    assert got is not frozen
    np.testing.assert_array_equal(frozen, x)
    np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
    x64 = x.astype(np.complex64)
    got = KeptWhiteNoise().add_on_read(x64, 0.3, np.random.default_rng(5), read, True,
                                       overwrite_x=True)
    assert got.dtype == np.complex128 and got is not x64
