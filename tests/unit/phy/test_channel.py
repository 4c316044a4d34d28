"""Channel application: power and noise bookkeeping, and time- vs frequency-domain agreement.

The time-domain path (exact fractional delay by a phase ramp, per-sample Doppler) is compared
with the per-RE frequency-domain path after OFDM demodulation. They must agree while every
delay relative to the timing reference lies inside the cyclic prefix and Doppler is small, and
must *not* agree beyond the CP (ISI) or with Doppler near the SCS (ICI), which the frequency
path ignores by construction.
"""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.phy.channel import (Links, add_noise, apply_frequency, apply_time, dbm_to_watt,
                                    equal_arrival_powers, frequency_response, re_amplitude,
                                    thermal_noise_variance, timing_reference)
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.phy.nr.ofdm import OFDM
from veriloc_rt.phy.transmitter import PRSTransmitter
from veriloc_rt.propagation.cir import array_response, ula_element_positions
from veriloc_rt.propagation.uma import uma_cir
from veriloc_rt.config.security import SecurityConfig

#: Time vs frequency domain inside the CP with Doppler up to 120 Hz: Doppler ICI
#: (pi f_D T)^2 / 3 = -34 dB at 120 Hz dominates (measured -39.5 dB over a mix of paths). Bound -30 dB.
AGREE_NMSE_DB = -30.0
#: Without Doppler only the band-limited (FFT) interpolation of the CP-OFDM waveform separates
#: them (it rings at symbol boundaries, decaying over the CP). Measured -69 dB (path 4 us into
#: the 4.69 us CP) and -77 dB (2.4 us). Bound -60 dB.
AGREE_STATIC_NMSE_DB = -60.0
#: A delay 2 us beyond the CP puts 2/66.7 of each FFT window into the next symbol: ISI of
#: ~ -15 dB relative plus a phase ramp error; the frequency path cannot see it. Bound: worse than -20 dB.
ISI_NMSE_DB = -20.0
#: Doppler 3 kHz = 0.2 SCS: ICI power (pi 0.2)^2 / 3 = -8.8 dB (measured -8.9 dB). Bound: worse
#: than -20 dB.
ICI_NMSE_DB = -20.0


def _nmse_db(a, b):
    return 10 * np.log10(np.sum(np.abs(a - b) ** 2) / np.sum(np.abs(b) ** 2))


@pytest.fixture(scope="module")
def frame():
    nr = NRConfig(slots_per_frame=2)
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="none"), (1, 2, 3))
    return nr, tx.ofdm, tx(0), tx.waveform(0)


def _links(delays, doppler, num_ant=2, seed=0):
    rng = np.random.default_rng(seed)
    d = np.asarray(delays, dtype=float)
    g = rng.standard_normal((d.shape[0], num_ant, d.shape[1])) + 1j * rng.standard_normal((d.shape[0], num_ant, d.shape[1]))
    return Links(d, g, np.asarray(doppler, dtype=float), np.ones(d.shape, dtype=bool))


def _both(frame, links, guard=0.25e-6):
    nr, ofdm, grids, wave = frame
    slots = range(grids.shape[1])
    t0 = timing_reference(links, guard)
    amps = np.ones(links.num_links)
    y_f = apply_frequency(links, grids, amps, ofdm, slots, t0)
    iq = apply_time(links, wave, amps, ofdm.sample_rate_hz, t0, wave.shape[1])
    return ofdm.demodulate(iq, slots), y_f


def test_thermal_noise_is_minus_174_dbm_per_hz():
    # kT0 at 290 K in dBm/Hz: 10 log10(1.380649e-23 * 290 / 1e-3) = -173.975 (independent arithmetic)
    assert 10 * np.log10(thermal_noise_variance(1.0, 0.0) / 1e-3) == pytest.approx(-173.975, abs=1e-3)
    assert thermal_noise_variance(15.36e6, 9.0) / thermal_noise_variance(15.36e6, 0.0) == pytest.approx(10 ** 0.9)


def test_power_control_equalises_arrivals_and_caps():
    g = np.array([1e-12, 4e-12, 1e-13, 0.0])
    p = equal_arrival_powers(g, 0.25)
    assert p.max() == pytest.approx(0.25)
    assert p[2] == pytest.approx(0.25)                       # the weakest link at full power
    np.testing.assert_allclose(p[:3] * g[:3], 0.25 * 1e-13)   # all arrive equally strong
    assert p[3] == 0.25                                      # no path: maximum
    np.testing.assert_allclose(equal_arrival_powers(g, 0.25, enabled=False), 0.25)


def test_re_amplitude_gives_the_power_of_a_full_carrier():
    nr = NRConfig()
    ofdm = OFDM(nr)
    rng = np.random.default_rng(1)
    grid = np.exp(2j * np.pi * rng.random((1, 14, nr.num_subcarriers)))
    x = re_amplitude(dbm_to_watt(24.0), ofdm) * ofdm.modulate(grid)
    # mean power of the useful parts = P (unitary IFFT); the CP repeats samples of similar power
    assert np.mean(np.abs(x) ** 2) == pytest.approx(float(dbm_to_watt(24.0)), rel=0.02)


def test_snr_per_re_does_not_depend_on_sample_rate():
    snr = []
    for rate in (15.36e6, 122.88e6):
        ofdm = OFDM(NRConfig(sample_rate_hz=rate))
        sig = re_amplitude(1.0, ofdm) ** 2
        snr.append(sig / thermal_noise_variance(ofdm.sample_rate_hz, 9.0))
    assert snr[0] == pytest.approx(snr[1], rel=1e-12)


def test_frequency_response_of_one_path_is_the_analytic_phasor():
    links = Links(np.array([[1.7e-6]]), np.array([[[0.3 - 0.4j]]]), np.array([[55.0]]), np.ones((1, 1), bool))
    f = np.array([-1e6, 0.0, 2.5e6])
    t = np.array([1e-3, 4e-3])
    h = frequency_response(links, f, t, 1e-6)[0, 0]
    expect = (0.3 - 0.4j) * np.exp(-2j * np.pi * f[None, :] * 0.7e-6) * np.exp(2j * np.pi * 55.0 * t[:, None])
    np.testing.assert_allclose(h, expect, rtol=1e-12)


def test_integer_delay_without_doppler_is_an_exact_shift(frame):
    _, ofdm, _, wave = frame
    fs = ofdm.sample_rate_hz
    links = Links(np.array([[37 / fs]]), np.ones((1, 1, 1), complex), np.zeros((1, 1)), np.ones((1, 1), bool))
    y = apply_time(links, wave[:1], np.ones(1), fs, 0.0, wave.shape[1] + 40)
    np.testing.assert_allclose(y[0, 37:37 + wave.shape[1]], wave[0], atol=1e-9 * np.abs(wave).max())
    assert np.max(np.abs(y[0, :37])) < 1e-9 * np.abs(wave).max()


def test_time_and_frequency_domain_agree_inside_the_cp(frame):
    links = _links([[2.0e-6, 2.9e-6], [2.4e-6, 3.6e-6], [2.2e-6, 2.5e-6]],
                   [[120.0, -80.0], [30.0, 60.0], [-100.0, 10.0]])
    y_t, y_f = _both(frame, links)
    assert _nmse_db(y_t, y_f) < AGREE_NMSE_DB


def test_time_and_frequency_domain_disagree_beyond_the_cp(frame):
    # CP = 4.69 us at mu = 0: BS 2's path arrives 6.7 us after the timing reference
    links = _links([[2.0e-6], [2.4e-6], [2.0e-6 + 6.7e-6]], [[0.0], [0.0], [0.0]], num_ant=1)
    y_t, y_f = _both(frame, links)
    assert _nmse_db(y_t, y_f) > ISI_NMSE_DB  # measured -13.8 dB
    inside = _links([[2.0e-6], [2.4e-6], [2.0e-6 + 4.0e-6]], [[0.0], [0.0], [0.0]], num_ant=1)
    y_t, y_f = _both(frame, inside)
    assert _nmse_db(y_t, y_f) < AGREE_STATIC_NMSE_DB


def test_time_and_frequency_domain_disagree_with_large_doppler(frame):
    links = _links([[2.0e-6], [2.4e-6], [2.2e-6]], [[3000.0], [-3000.0], [3000.0]], num_ant=1)
    y_t, y_f = _both(frame, links)
    assert _nmse_db(y_t, y_f) > ICI_NMSE_DB
    static = _links([[2.0e-6], [2.4e-6], [2.2e-6]], [[0.0], [0.0], [0.0]], num_ant=1)
    y_t, y_f = _both(frame, static)
    assert _nmse_db(y_t, y_f) < AGREE_STATIC_NMSE_DB


def test_decimated_time_domain_agrees_inside_the_band():
    nr = NRConfig(slots_per_frame=1, sample_rate_hz=30.72e6)
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="none"), (1, 2, 3))
    wave, ofdm = tx.waveform(0), tx.ofdm
    rng = np.random.default_rng(4)
    links = _links(2e-6 + 2e-6 * rng.random((3, 6)), rng.uniform(-150, 150, (3, 6)), 2)
    t0 = timing_reference(links, 0.25e-6)
    full = apply_time(links, wave, np.ones(3), ofdm.sample_rate_hz, t0, wave.shape[1] + 50)
    dec = apply_time(links, wave, np.ones(3), ofdm.sample_rate_hz, t0, wave.shape[1] + 50, decimation=2)
    # in band (after demodulation) only interpolation ringing differs: measured -100 dB at D = 2
    # (-78 dB at 122.88 MHz, D = 8); bound -60 dB. The IQ itself differs by the CP-OFDM
    # out-of-band leakage that decimation drops: measured -45 dB; must be visible (> -80 dB).
    slots = range(1)
    assert _nmse_db(ofdm.demodulate(dec, slots), ofdm.demodulate(full, slots)) < AGREE_STATIC_NMSE_DB
    assert _nmse_db(dec, full) > -80.0


def test_noise_variance(rng):
    x = add_noise(np.zeros(200_000, dtype=complex), 3e-13, rng)
    # 200k samples: the variance estimate has relative std sqrt(1/200k) = 0.2%; 5 sigma = 1%
    assert np.var(x) == pytest.approx(3e-13, rel=0.01)
    with pytest.raises(TypeError, match="rng"):
        add_noise(x, 1.0, 1)


def test_uplink_gain_is_the_array_centre_coefficient():
    fc = 3.5e9
    ep = ula_element_positions(5, 0.5 * 299_792_458.0 / fc, 0.3)
    bs = np.array([[[200.0, 50.0, 25.0], [-150.0, 120.0, 25.0]]])
    cir = uma_cir(bs, np.array([[0.0, 0.0, 1.5]]), np.zeros((1, 3)), np.zeros((1, 2, 3)),
                  np.array([[0, 1]]), fc, ep, np.random.default_rng(3), "pathloss_only")
    ups = Links.uplink_from_cir(cir, 0, ep)
    for j, up in enumerate(ups):
        # pathloss_only: coefficient 10^(-(PL+SF)/20), real, at every element times a(theta)
        a = array_response(cir.aoa_az[0, j], cir.aoa_zen[0, j], ep, 299_792_458.0 / fc)[:, 0]
        amp = cir.gains[0, j, :, 0] / a
        expect = amp[0] * np.exp(-2j * np.pi * fc * cir.delays[0, j, 0])
        assert up.num_ant == 1
        assert up.gains[0, 0, 0] == pytest.approx(expect, rel=1e-9)
        assert abs(amp[0].imag) < 1e-12 * abs(amp[0])


def test_slot_major_noise_of_the_first_slots_does_not_depend_on_the_grid_length():
    """add_noise(major_axis=1) on a grid [A, S, 14, K]: the first m slots receive exactly the
    noise they receive in the whole grid (what lets a tag-only receiver draw m slots)."""
    x = np.zeros((5, 10, 14, 48), dtype=complex)
    full = add_noise(x, 2.0, np.random.default_rng(9), major_axis=1)
    part = add_noise(x[:, :2], 2.0, np.random.default_rng(9), major_axis=1)
    np.testing.assert_array_equal(part, full[:, :2])
    assert np.mean(np.abs(full) ** 2) == pytest.approx(2.0, rel=0.02)   # 3.4e4 samples: 0.5 % std
    # the default order is antenna-major: the first slots' noise then depends on S
    assert not np.array_equal(add_noise(x[:, :2], 2.0, np.random.default_rng(9)),
                              add_noise(x, 2.0, np.random.default_rng(9))[:, :2])


@pytest.mark.parametrize("tags", ["hmac", "none"])
def test_apply_frequency_on_occupied_res_equals_the_full_response(tags):
    """apply_frequency evaluates H only on each grid's occupied REs (occupancy_groups: the
    symbols grouped by comb pattern, each occupied RE in one group); second method: sum_l a_l H_l X_l with frequency_response on every
    RE of the grid (exact: the same products; rtol 1e-12 for summation order). A dense grid
    (noise on every RE, like a jammer's) has no groups and takes the full path."""
    from veriloc_rt.phy.security.keys import simulated_keys

    nr = NRConfig(slots_per_frame=2)
    ofdm = OFDM(nr)
    slots = range(2)
    keys = None if tags == "none" else simulated_keys((1, 2, 3), np.random.default_rng(0))
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme=tags), (1, 2, 3), keys)
    rng = np.random.default_rng(4)
    grids = tx(0, slots)
    dense = add_noise(np.zeros((1,) + grids.shape[1:]), 1.0, rng)
    grids = np.concatenate([grids, dense])
    links = Links(1e-6 + rng.uniform(0, 2e-6, (4, 5)), rng.standard_normal((4, 3, 5)) + 1j * rng.standard_normal((4, 3, 5)),
                  rng.uniform(-150, 150, (4, 5)), rng.uniform(size=(4, 5)) < 0.8)
    links = Links(links.delays, links.gains * links.valid[:, None, :], links.doppler, links.valid)
    amps = np.array([1.0, 0.5, 2.0, 0.1])
    from veriloc_rt.phy.channel import occupancy_groups, subcarrier_frequencies, symbol_times

    x0 = grids[0].reshape(-1, ofdm.num_subcarriers)
    cover = np.zeros(x0.shape, dtype=int)
    for sym, sc in occupancy_groups(x0 != 0):
        cover[sym[:, None], sc[None, :]] += 1
    np.testing.assert_array_equal(cover, x0 != 0)          # every occupied RE, once
    assert occupancy_groups(grids[3].reshape(-1, ofdm.num_subcarriers) != 0) is None
    t = symbol_times(ofdm, slots, 0.9e-6)
    h = frequency_response(links, subcarrier_frequencies(ofdm), t.ravel(), 0.9e-6)
    want = np.einsum("l,latk,ltk->atk", amps, h, grids.reshape(4, t.size, -1)).reshape(3, 2, 14, -1)
    got = apply_frequency(links, grids, amps, ofdm, slots, 0.9e-6)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


def test_group_index_selects_the_rows_times_cols_block():
    """group_index: the same [R, C] entries as np.ix_(rows, cols) (second method; exact), a
    slice for a comb's evenly spaced columns, two index arrays otherwise."""
    from veriloc_rt.phy.channel import group_index

    m = np.arange(14 * 60).reshape(14, 60)
    rows = np.array([0, 3, 4, 11])
    for cols, sliced in ((np.arange(2, 60, 6), True), (np.array([7]), True),
                         (np.array([1, 2, 5, 9]), False)):
        ix = group_index(rows, cols)
        assert isinstance(ix[1], slice) == sliced
        np.testing.assert_array_equal(m[ix], m[np.ix_(rows, cols)])


def _scatter_add_reference(links, grids, amps, ofdm, slots, t0):
    """apply_frequency as it was written before: every group of every link added into the grid
    with two index arrays (out[ix] += a H X)."""
    from veriloc_rt.phy.channel import occupancy_groups, subcarrier_frequencies, symbol_times

    t = symbol_times(ofdm, slots, t0).ravel()
    f = subcarrier_frequencies(ofdm)
    out = np.zeros((links.num_ant, t.size, f.size), dtype=np.complex128)
    for li, amp in enumerate(amps):
        x = grids[li].reshape(t.size, f.size)
        one = Links(links.delays[li:li + 1], links.gains[li:li + 1], links.doppler[li:li + 1],
                    links.valid[li:li + 1])
        for sym, sc in occupancy_groups(x != 0):
            h = frequency_response(one, f[sc], t[sym], t0)[0]
            out[:, sym[:, None], sc[None, :]] += amp * h * x[sym[:, None], sc[None, :]][None]
    return out.reshape(links.num_ant, len(slots), 14, f.size)


def test_apply_frequency_equals_the_scatter_add_bit_for_bit(monkeypatch):
    """apply_frequency's reference path (``VERILOC_RT_REFERENCE=jitchannel``: NumPy products,
    the compiled scatter-add) adds into REs no link has touched yet (0 + v) and into the
    others; against the plain scatter-add of every group (second method), bit for bit,
    signed zeros included: links 0 and 1 send on the same REs (the add), link 2 on its own
    (the write), link 3 with zero gain (0 * X = -0.0 on some REs, which 0 + v makes +0.0)."""
    monkeypatch.setenv("VERILOC_RT_REFERENCE", "jitchannel")
    nr = NRConfig(slots_per_frame=2)
    ofdm = OFDM(nr)
    slots = range(2)
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="none"), (1, 2, 3))
    g = tx(0, slots)
    grids = np.stack([g[0], g[0], g[1], -g[2]])
    rng = np.random.default_rng(11)
    gains = rng.standard_normal((4, 3, 2)) + 1j * rng.standard_normal((4, 3, 2))
    gains[3] = 0.0
    links = Links(1e-6 + rng.uniform(0, 2e-6, (4, 2)), gains, rng.uniform(-150, 150, (4, 2)),
                  np.ones((4, 2), dtype=bool))
    amps = np.array([1.0, 0.5, 2.0, 0.3])
    got = apply_frequency(links, grids, amps, ofdm, slots, 0.9e-6)
    want = _scatter_add_reference(links, grids, amps, ofdm, slots, 0.9e-6)
    np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
    # the transmitter's masks in place of the values' comparison: the same bits
    occ = tx.occupied(slots)[0]
    given = apply_frequency(links, grids, amps, ofdm, slots, 0.9e-6, occ[[0, 0, 1, 2]])
    np.testing.assert_array_equal(given.view(np.int64), want.view(np.int64))
    with pytest.raises(ValueError, match="occupied"):
        apply_frequency(links, grids, amps, ofdm, slots, 0.9e-6, occ)


def test_a_links_response_is_computed_once_and_kept_exactly(frame):
    """apply_frequency keeps each link's response on the REs it was evaluated on (phy.channel
    _LinkResponses): a second call with the same links and t0 (another chain's grids on the
    same REs) evaluates no response and gives what a fresh computation gives, bit for bit; a
    link with other paths, or another t0, is evaluated anew."""
    import veriloc_rt.phy.channel as ch

    nr, ofdm, grids, _ = frame
    slots = range(grids.shape[1])
    links = _links([[1e-6, 2.5e-6], [1.7e-6, 3e-6], [2e-6, 2.2e-6]], [[30.0, -80.0], [5.0, 0.0], [60.0, 10.0]], seed=5)
    amps = np.array([1.0, 0.3, 2.0])
    calls = []
    real = ch.frequency_response
    ch.frequency_response = lambda *a: calls.append(1) or real(*a)
    try:
        first = apply_frequency(links, grids, amps, ofdm, slots, 0.5e-6)
        n_first = len(calls)
        again = apply_frequency(links, 0.5 * grids, amps, ofdm, slots, 0.5e-6)
        assert len(calls) == n_first > 0                      # nothing evaluated again
        other = Links(links.delays, 2.0 * links.gains, links.doppler, links.valid)
        apply_frequency(other, grids, amps, ofdm, slots, 0.5e-6)
        assert len(calls) == 2 * n_first                      # other paths: evaluated anew
        apply_frequency(links, grids, amps, ofdm, slots, 0.6e-6)
        assert len(calls) == 3 * n_first                      # another t0 too
    finally:
        ch.frequency_response = real
    # RESPONSES_MAX other links push these out (the oldest first): evaluated afresh
    for seed in range(ch.RESPONSES_MAX):
        apply_frequency(_links([[1e-6]], [[0.0]], seed=100 + seed), grids[:1], amps[:1], ofdm, slots, 0.5e-6)
    calls.clear()
    ch.frequency_response = lambda *a: calls.append(1) or real(*a)
    try:
        fresh = apply_frequency(links, 0.5 * grids, amps, ofdm, slots, 0.5e-6)
    finally:
        ch.frequency_response = real
    assert len(calls) == n_first
    np.testing.assert_array_equal(again, fresh)
    np.testing.assert_array_equal(first, apply_frequency(links, grids, amps, ofdm, slots, 0.5e-6))


def test_re_plan_indexes_each_groups_res_in_their_order(monkeypatch):
    """REPlan: the flat index reads a grid's occupied REs group after group, each group's block
    row-major (second method: the blocks x[group_index(rows, cols)] concatenated; exact), every
    occupied RE once, with its row and column; a link applied through it (apply_frequency's
    reference path, ``VERILOC_RT_REFERENCE=jitchannel``) gives the scatter-add reference's bits,
    on a tagged PRS frame."""
    monkeypatch.setenv("VERILOC_RT_REFERENCE", "jitchannel")
    from veriloc_rt.phy.channel import REPlan, group_index, occupancy_groups
    from veriloc_rt.phy.security.keys import simulated_keys

    nr = NRConfig(slots_per_frame=2)
    ofdm = OFDM(nr)
    slots = range(2)
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="hmac"), (1, 2, 3),
                        simulated_keys((1, 2, 3), np.random.default_rng(0)))
    grids = tx(0, slots)
    x = grids[1].reshape(-1, ofdm.num_subcarriers)
    groups = occupancy_groups(x != 0)
    plan = REPlan(groups, x.shape[1])
    want = np.concatenate([x[group_index(rows, cols)].ravel() for rows, cols in groups])
    np.testing.assert_array_equal(x.ravel()[plan.index], want)
    assert np.array_equal(np.sort(plan.index), np.flatnonzero(x != 0))     # each RE once
    assert not plan.index.flags.writeable
    np.testing.assert_array_equal(plan.rows * x.shape[1] + plan.cols, plan.index)
    assert np.all((plan.cols >= 0) & (plan.cols < x.shape[1]))
    rng = np.random.default_rng(12)
    links = Links(1e-6 + rng.uniform(0, 2e-6, (3, 3)), rng.standard_normal((3, 2, 3)) + 1j * rng.standard_normal((3, 2, 3)),
                  rng.uniform(-150, 150, (3, 3)), np.ones((3, 3), dtype=bool))
    amps = np.array([1.0, 0.5, 2.0])
    got = apply_frequency(links, grids, amps, ofdm, slots, 0.9e-6)
    want = _scatter_add_reference(links, grids, amps, ofdm, slots, 0.9e-6)
    np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))


def test_kept_responses_go_least_recently_used_first_and_within_their_bytes(frame, monkeypatch):
    """The links' kept responses (phy.channel _LinkResponses): a link applied again after more
    than 16 others (a 9-TRP point: serving links, uplinks, the meaconer's links) is not
    evaluated again while fewer than RESPONSES_MAX links came between; a link used again is
    the last to go; over RESPONSES_MAX_BYTES the least recently used links go first and are
    evaluated afresh, bit for bit the same (second method: a fresh computation)."""
    import veriloc_rt.phy.channel as ch

    nr, ofdm, grids, _ = frame
    slots = range(grids.shape[1])
    amps = np.ones(1)
    monkeypatch.setattr(ch, "KEPT_RESPONSES", type(ch.KEPT_RESPONSES)())   # an empty store
    calls = []
    real = ch.frequency_response
    monkeypatch.setattr(ch, "frequency_response", lambda *a: calls.append(1) or real(*a))

    def link(seed):
        return _links([[1e-6 + 1e-8 * seed, 2e-6]], [[30.0, -40.0]], seed=seed)

    first = apply_frequency(link(0), grids[:1], amps, ofdm, slots, 0.5e-6)
    per_link = len(calls)
    for seed in range(1, 30):                          # 29 other links: more than 16
        apply_frequency(link(seed), grids[:1], amps, ofdm, slots, 0.5e-6)
    calls.clear()
    again = apply_frequency(link(0), grids[:1], amps, ofdm, slots, 0.5e-6)
    assert calls == []
    np.testing.assert_array_equal(again, first)
    # the bytes of four links' responses at most: the least recently used go, link 0 (used
    # last but three) stays, link 1 goes
    size = ch.KEPT_RESPONSES.nbytes[next(iter(ch.KEPT_RESPONSES.links))]
    monkeypatch.setattr(ch, "RESPONSES_MAX_BYTES", 4 * size)
    for seed in (30, 31, 32):
        apply_frequency(link(seed), grids[:1], amps, ofdm, slots, 0.5e-6)
    assert len(ch.KEPT_RESPONSES.links) == 4
    assert ch.KEPT_RESPONSES.total == sum(ch.KEPT_RESPONSES.nbytes.values()) <= 4 * size
    calls.clear()
    apply_frequency(link(0), grids[:1], amps, ofdm, slots, 0.5e-6)
    assert calls == []
    fresh = apply_frequency(link(1), grids[:1], amps, ofdm, slots, 0.5e-6)
    assert len(calls) == per_link
    monkeypatch.setattr(ch, "KEPT_RESPONSES", type(ch.KEPT_RESPONSES)())
    np.testing.assert_array_equal(fresh, apply_frequency(link(1), grids[:1], amps, ofdm, slots, 0.5e-6))


def test_a_links_delay_groups_given_give_the_same_response():
    """frequency_response with the links' delay groups given (found once per link by the kept
    responses) is the one that finds them itself, bit for bit (second method), on links with
    shared delays (TR 38.901 rays of a cluster)."""
    from veriloc_rt.phy.channel import delay_groups

    rng = np.random.default_rng(3)
    taus = np.repeat(1e-6 + rng.uniform(0, 2e-6, 6), 4)        # 6 clusters of 4 rays
    links = Links(taus[None], rng.standard_normal((1, 2, 24)) + 1j * rng.standard_normal((1, 2, 24)),
                  rng.uniform(-100, 100, (1, 24)), np.ones((1, 24), dtype=bool))
    f = np.arange(-36, 36) * 15e3
    t = np.arange(14) * 7e-5
    groups = [delay_groups(links.delays[0], links.valid[0])]
    got = frequency_response(links, f, t, 0.9e-6, True, groups)
    want = frequency_response(links, f, t, 0.9e-6, True)
    np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
