"""The whole per-point chain on analytic and UMa CIRs.

The analytic CIR is built here independently of every propagation model: one path per link
at the straight-line delay |BS - UE| / c, arriving from the BS's direction, with the plane-wave
phase of each ULA element from the array geometry. On it the chain must recover the ToAs, the
position (DL and UL), the azimuths and the tags.
"""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.phy.channel import dbm_to_watt, thermal_noise_variance
from veriloc_rt.config.channel import ChannelConfig, ReceiverConfig
from veriloc_rt.config import ArrayConfig
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.propagation.cir import CIR, array_response, ula_element_positions
from veriloc_rt.propagation.uma import uma_cir
from veriloc_rt.phy.chain import FIX_ONLY, Adversary, PositioningChain
from veriloc_rt.phy.noise import GridNoise, WhiteNoise
from veriloc_rt.phy.nr.ofdm import OFDM
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.phy.security.keys import simulated_keys

FC = 3.5e9
BS = np.array([[0.0, 289.0, 25.0], [-250.3, -144.5, 25.0], [250.3, -144.5, 25.0]])
#: noiseless bounds of the issue: ToA within 0.1 sample, position within 0.5 m
TOA_SAMPLES = 0.1
POSITION_M = 0.5
#: ESPRIT on one source through the chain at 20 dB per RE and antenna: the issue's 1 degree
AOA_DEG = 1.0


def exact_cir(ue: np.ndarray, amp: float = 1e-6, axis_deg: float = 0.0, doppler=(0.0, 0.0, 0.0)) -> CIR:
    """One point, 3 links, one path each at the geometric delay (see the module docstring)."""
    d = BS - ue[None, :]
    dist = np.linalg.norm(d, axis=1)
    az = np.arctan2(d[:, 1], d[:, 0])
    zen = np.arccos(d[:, 2] / dist)
    ep = ula_element_positions(5, 0.5 * SPEED_OF_LIGHT / FC, np.deg2rad(axis_deg))
    gains = amp * array_response(az[:, None], zen[:, None], ep, SPEED_OF_LIGHT / FC)  # [3, 5, 1]
    z = np.zeros((1, 3, 1))
    return CIR(delays=(dist / SPEED_OF_LIGHT)[None, :, None], gains=gains[None].astype(complex),
               aoa_az=az[None, :, None], aoa_zen=zen[None, :, None], aod_az=z, aod_zen=z,
               doppler=np.asarray(doppler, float)[None, :, None],
               interactions=np.zeros((1, 3, 1, 1), np.uint8), valid=np.ones((1, 3, 1), bool),
               tx_index=np.array([[0, 1, 2]]), tx_pos=BS[None], rx_pos=ue[None], los=np.ones((1, 3), bool),
               carrier_frequency=FC)


def make_chain(domain="frequency", rate=None, noise=True, tags="hmac", encrypted=(False, False, False),
               axis_deg=0.0, **receiver):
    keys = simulated_keys((0, 1, 2), np.random.default_rng(0))
    return PositioningChain(NRConfig(sample_rate_hz=rate, slots_per_frame=4),
                            SecurityConfig(tag_scheme=tags, encrypted=encrypted),
                            ChannelConfig(domain=domain, noise=noise), ReceiverConfig(**receiver),
                            ArrayConfig(axis_azimuth_deg=axis_deg), FC, keys)


@pytest.mark.parametrize("domain,rate", [("frequency", 15.36e6), ("frequency", 122.88e6),
                                         ("time", 15.36e6), ("time", 122.88e6)])
def test_noiseless_chain_recovers_toa_and_position(domain, rate):
    ue = np.array([37.0, -21.0, 1.5])
    cir = exact_cir(ue, doppler=(80.0, -40.0, 10.0))
    chain = make_chain(domain, rate, noise=False, encrypted=(True, False, True))
    res = chain(cir, 0, np.random.default_rng(1))
    assert res.detected.all()
    np.testing.assert_array_less(np.abs(res.toa_s - cir.delays[0, :, 0]) * chain.ofdm.sample_rate_hz, TOA_SAMPLES)
    assert res.position.ok
    assert np.linalg.norm(res.position.position[:2] - ue[:2]) < POSITION_M
    assert res.uplink.position.ok
    assert np.linalg.norm(res.uplink.position.position[:2] - ue[:2]) < POSITION_M
    assert res.tags_checked and res.tags_valid.all()
    np.testing.assert_allclose(res.doppler_hz, [80.0, -40.0, 10.0], atol=1.0)


@pytest.mark.parametrize("axis_deg", [0.0, 35.0])
def test_esprit_through_the_chain_within_one_degree_at_20_db(axis_deg):
    ue = np.array([-60.0, 45.0, 1.5])
    chain = make_chain(tags="none", axis_deg=axis_deg, uplink=False)
    # |g|^2 such that the per-RE, per-antenna SNR is 20 dB at 24 dBm (every BS broadcasts at
    # 24 dBm; with power control the three equally strong links would keep it too)
    nv = thermal_noise_variance(chain.ofdm.sample_rate_hz, chain.channel.ue_noise_figure_db)
    g2 = 100.0 * nv * chain.ofdm.num_subcarriers / (float(dbm_to_watt(24.0)) * chain.ofdm.fft_size)
    cir = exact_cir(ue, amp=np.sqrt(g2), axis_deg=axis_deg)
    true_az = cir.aoa_az[0, :, 0]
    # the reference only has to pick the right mirror: give it 20 degrees off
    res = chain(cir, 0, np.random.default_rng(3), reference_azimuth=true_az + np.deg2rad(20.0))
    assert res.detected.all()
    err = np.rad2deg(np.abs(np.angle(np.exp(1j * (res.azimuth - true_az)))))
    np.testing.assert_array_less(err, AOA_DEG)
    assert all(a is not None and a.method == "esprit" for a in res.aoa)


@pytest.mark.parametrize("mode", ["pathloss_only", "fast_fading"])
def test_uma_cir_runs_through_the_chain_without_nan(mode):
    n = 3
    ue = np.stack([np.linspace(-40, 40, n), np.full(n, 10.0), np.full(n, 1.5)], axis=-1)
    vel = np.tile([13.0, 0.0, 0.0], (n, 1))
    ep = ula_element_positions(5, 0.5 * SPEED_OF_LIGHT / FC, 0.0)
    cir = uma_cir(np.broadcast_to(BS, (n, 3, 3)).copy(), ue, vel, np.zeros((n, 3, 3)),
                  np.tile([0, 1, 2], (n, 1)), FC, ep, np.random.default_rng(4), mode)
    chain = make_chain()
    for k in range(n):
        res = chain(cir, k, np.random.default_rng([5, k]))
        assert np.all(np.isfinite(res.position.position))
        assert np.all(np.isfinite(res.toa_s[res.detected]))
        assert np.all(np.isfinite(res.peak_snr_db)) and np.all(np.isfinite(res.doppler_hz))
        assert np.all(np.isfinite(res.uplink.position.position))
        for a in res.aoa:
            assert a is None or np.all(np.isfinite(a.azimuth_candidates))
        if mode == "pathloss_only":
            # one LoS-or-NLoS path per link at the geometric delay: a 10 MHz fix within 2 m
            # (noise: post-correlation SNR >= 25 dB here, sigma_range < 1 m)
            assert res.position.ok
            assert np.linalg.norm(res.position.position[:2] - ue[k, :2]) < 2.0


def test_adversary_grid_and_iq_inputs_agree():
    ue = np.array([10.0, 20.0, 1.5])
    cir = exact_cir(ue)
    adv = exact_cir(ue + np.array([5.0, 0.0, 0.0]))   # any single-path link
    adv = adv.select(slice(0, 1))
    adv = CIR(**{k: getattr(adv, k)[:, :1] for k in ("delays", "gains", "aoa_az", "aoa_zen", "aod_az",
                                                      "aod_zen", "doppler", "interactions", "valid",
                                                      "tx_index", "tx_pos", "los")},
              rx_pos=adv.rx_pos, carrier_frequency=FC)
    chain = make_chain(noise=False, tags="none", uplink=False)
    # the adversary replays BS 1's PRS 48 dBm strong: BS 1's peak is then the adversary's
    grid = chain.frame_signals((0, 1, 2), 0).replicas[1]
    r_grid = chain(cir, 0, np.random.default_rng(0), adversary=Adversary(adv, grid))
    r_iq = chain(cir, 0, np.random.default_rng(0),
                 adversary=Adversary(adv, chain.ofdm.modulate(grid, chain.slots)))
    np.testing.assert_allclose(r_grid.toa_s, r_iq.toa_s, atol=0.05 / chain.ofdm.sample_rate_hz)
    assert abs(r_grid.toa_s[1] - adv.delays[0, 0, 0]) * chain.ofdm.sample_rate_hz < TOA_SAMPLES


#: time domain with the OFDM front end vs the frequency path, paths inside the CP, 80 Hz
#: Doppler: they differ only by inter-carrier leakage ((pi f_D T_u)^2 / 3 ~ -50 dB at 15 kHz SCS)
#: and the CP-OFDM out-of-band leakage; measured 3e-5 sample at 15.36 MHz, 2e-4 at 122.88 MHz
FRONT_END_SAMPLES = 2e-3


@pytest.mark.parametrize("rate", [15.36e6, 122.88e6])
def test_time_domain_with_ofdm_front_end_reproduces_the_frequency_path(rate):
    ue = np.array([37.0, -21.0, 1.5])
    one = exact_cir(ue, doppler=(80.0, -40.0, 10.0))
    two = {k: np.concatenate([getattr(one, k)] * 2, axis=2)
           for k in ("aoa_az", "aoa_zen", "aod_az", "aod_zen", "doppler", "interactions", "valid")}
    # a second path per link 0.8 us after the first (inside the 4.7 us CP), half as strong
    cir = CIR(delays=np.concatenate([one.delays, one.delays + 0.8e-6], axis=2),
              gains=np.concatenate([one.gains, 0.5j * one.gains], axis=-1), **two,
              tx_index=one.tx_index, tx_pos=one.tx_pos, rx_pos=one.rx_pos, los=one.los,
              carrier_frequency=FC)
    fast = make_chain("frequency", rate, noise=False)(cir, 0, np.random.default_rng(1))
    ref_chain = PositioningChain(NRConfig(sample_rate_hz=rate, slots_per_frame=4),
                                 SecurityConfig(tag_scheme="hmac"),
                                 ChannelConfig(domain="time", noise=False, time_front_end="ofdm"),
                                 ReceiverConfig(), ArrayConfig(), FC,
                                 simulated_keys((0, 1, 2), np.random.default_rng(0)))
    ref = ref_chain(cir, 0, np.random.default_rng(1))
    fs = ref_chain.ofdm.sample_rate_hz
    np.testing.assert_array_less(np.abs(ref.toa_s - fast.toa_s) * fs, FRONT_END_SAMPLES)
    np.testing.assert_array_less(np.abs(ref.uplink.toa_s - fast.uplink.toa_s) * fs, FRONT_END_SAMPLES)
    assert np.linalg.norm(ref.position.position - fast.position.position) < 0.01
    assert ref.tags_valid.all() and fast.tags_valid.all()


@pytest.mark.parametrize("rate", [15.36e6, 122.88e6])
def test_shared_noise_reaches_time_and_frequency_paths_alike(rate):
    """``benign_chain(shared_noise=True)``'s chain: the same per-RE noise grid, added to the
    grid (frequency) or OFDM-modulated into the IQ (time, OFDM front end), gives the same
    estimates up to the channel's own time/frequency difference (FRONT_END_SAMPLES), here at
    0 dB per RE and antenna where independent noise would move the ToAs by ~0.05 sample."""
    ue = np.array([37.0, -21.0, 1.5])
    nv = thermal_noise_variance(rate, ChannelConfig().ue_noise_figure_db)
    probe = make_chain("frequency", rate)
    g2 = nv * probe.ofdm.num_subcarriers / (float(dbm_to_watt(24.0)) * probe.ofdm.fft_size)
    cir = exact_cir(ue, amp=np.sqrt(g2), doppler=(80.0, -40.0, 10.0))
    out = {}
    for domain in ("frequency", "time"):
        nr = NRConfig(sample_rate_hz=rate, slots_per_frame=4)
        grid_noise = GridNoise(OFDM(nr), range(4), np.random.default_rng(11))
        chain = PositioningChain(nr, SecurityConfig(tag_scheme="none"),
                                 ChannelConfig(domain=domain, time_front_end="ofdm"), ReceiverConfig(),
                                 ArrayConfig(), FC, simulated_keys((0, 1, 2), np.random.default_rng(0)),
                                 noise=grid_noise, uplink_noise=GridNoise(grid_noise.ofdm, range(4)))
        out[domain] = chain(cir, 0, np.random.default_rng(12))
        fs = chain.ofdm.sample_rate_hz
    f, t = out["frequency"], out["time"]
    assert f.detected.all() and t.detected.all()
    np.testing.assert_array_less(np.abs(f.toa_s - t.toa_s) * fs, FRONT_END_SAMPLES)
    # peak over floor: the floors are the same noise; the peaks differ by the time domain's
    # inter-symbol and inter-carrier leakage (measured <= 0.03 dB at 80 Hz Doppler)
    np.testing.assert_allclose(f.peak_snr_db, t.peak_snr_db, atol=0.1)
    # the uplink draws from the point's own generator: the same in both
    np.testing.assert_array_less(np.abs(f.uplink.toa_s - t.uplink.toa_s) * fs, FRONT_END_SAMPLES)


class SeenNoise(WhiteNoise):
    """Records the noiseless received grid at the chain's one noise entry point."""

    def __call__(self, x, variance, rng):
        self.seen = x
        return super().__call__(x, variance, rng)


@pytest.mark.parametrize("tags,factor", [("hmac", 3.0), ("none", 6.0)])
def test_occupied_prs_power_raises_the_received_re_energy_by_the_muted_share(tags, factor):
    """channel.prs_power 'occupied': a BS's power is spread over the REs it sends per PRS symbol,
    comb 6 -> 1/6 of the carrier (PRS) or 2/6 (PRS + tag), so every received RE carries 6x or 3x
    the 'carrier' convention's energy (independent: the comb's share of subcarriers). Same CIR,
    linear chain up to the noise: the ratio is exact to rounding."""
    cir = exact_cir(np.array([10.0, 20.0, 1.5]))
    energy = {}
    for mode in ("carrier", "occupied"):
        keys = simulated_keys((0, 1, 2), np.random.default_rng(0))
        seen = SeenNoise()
        ch = PositioningChain(NRConfig(slots_per_frame=2), SecurityConfig(tag_scheme=tags),
                              ChannelConfig(prs_power=mode), ReceiverConfig(), ArrayConfig(), FC, keys,
                              noise=seen)
        ch(cir, 0, np.random.default_rng(1))
        energy[mode] = float(np.sum(np.abs(seen.seen) ** 2))
    assert energy["occupied"] / energy["carrier"] == pytest.approx(factor, rel=1e-9)


class RecordingNoise(WhiteNoise):
    """Records the noise the chain adds (grid or IQ)."""

    def __call__(self, x, variance, rng):
        y = super().__call__(x, variance, rng)
        self.noise = y - x
        return y


@pytest.mark.parametrize("domain,rate", [("frequency", 15.36e6), ("time", 122.88e6)])
@pytest.mark.parametrize("bandwidth", [None, 10e6])
def test_noise_density_and_the_channel_bandwidth_convention(domain, rate, bandwidth):
    """Per sample (= per RE, unitary OFDM) the UE's noise is k T0 F f_s, white over the sampled
    band (independent: Boltzmann's constant, T0 = 290 K, F = 9 dB); with noise_bandwidth_hz B, the
    power k T0 F B spread over 122.88 MHz: the density drops by B / 122.88 MHz at any sample rate.
    Tolerance 2 %: >= 1.7e5 complex samples, std of the variance estimate < 0.3 %."""
    cir = exact_cir(np.array([10.0, 20.0, 1.5]))
    keys = simulated_keys((0, 1, 2), np.random.default_rng(0))
    rec = RecordingNoise()
    ch = PositioningChain(NRConfig(sample_rate_hz=rate, slots_per_frame=4), SecurityConfig(tag_scheme="none"),
                          ChannelConfig(domain=domain, noise_bandwidth_hz=bandwidth),
                          ReceiverConfig(), ArrayConfig(), FC, keys, noise=rec)
    ch(cir, 0, np.random.default_rng(5))
    scale = 1.0 if bandwidth is None else bandwidth / 122.88e6
    expected = 1.380649e-23 * 290.0 * 10 ** 0.9 * rate * scale
    assert np.mean(np.abs(rec.noise) ** 2) == pytest.approx(expected, rel=0.02)
    # the BSs' uplink receivers (F = 5 dB) follow the same convention
    assert ch.uplink.positioner.noise_var == pytest.approx(1.380649e-23 * 290.0 * 10 ** 0.5 * rate * scale, rel=1e-6)


class CountingNoise(WhiteNoise):
    """Counts the draws of downlink noise."""

    draws = 0

    def __call__(self, x, variance, rng):
        self.draws += 1
        return super().__call__(x, variance, rng)


@pytest.mark.parametrize("domain", ["frequency", "time"])
def test_attack_call_after_the_benign_one_reuses_its_signal_and_noise_exactly(domain):
    """A run evaluates a point's scenarios together: the attack call reuses the benign call's
    serving-BS signal plus noise and uplink fix (phy.chain.downlink.KeptDraw), and the timing and
    tag checks of the BSs whose REs the adversary leaves alone (TimingStage, TagStage). Second
    method: a fresh
    chain computing the attack call alone, from the same generator state. Exact equality (the
    same operations on the same numbers), the caller's generator left in the same state, and
    one noise draw for the two calls."""
    ue = np.array([10.0, 20.0, 1.5])
    cir = exact_cir(ue)
    adv = exact_cir(ue + np.array([5.0, 0.0, 0.0]))
    adv = CIR(**{k: getattr(adv, k)[:, :1] for k in ("delays", "gains", "aoa_az", "aoa_zen", "aod_az",
                                                      "aod_zen", "doppler", "interactions", "valid",
                                                      "tx_index", "tx_pos", "los")},
              rx_pos=adv.rx_pos, carrier_frequency=FC)
    keys = simulated_keys((0, 1, 2), np.random.default_rng(0))
    args = (NRConfig(slots_per_frame=2), SecurityConfig(tag_scheme="hmac"),
            ChannelConfig(domain=domain), ReceiverConfig(), ArrayConfig(), FC, keys)
    n_kept, n_fresh = CountingNoise(), CountingNoise()
    kept, fresh = PositioningChain(*args, noise=n_kept), PositioningChain(*args, noise=n_fresh)
    spoof = Adversary(adv, 1e-3 * kept.frame_signals((0, 1, 2), 0).replicas[1])   # a weak replay of BS 1
    benign = kept(cir, 0, np.random.default_rng(7))
    rng_k, rng_f = np.random.default_rng(7), np.random.default_rng(7)
    checked = []
    one = kept.tags.one
    kept.tags.one = lambda verifier, grid, est, bs, *rest: checked.append(bs) or one(verifier, grid, est, bs, *rest)
    a = kept(cir, 0, rng_k, adversary=spoof)
    del kept.tags.one
    # the tags of the BSs whose timing was reused are not checked again either
    assert checked == ([1] if domain == "frequency" else [0, 1, 2])
    b = fresh(cir, 0, rng_f, adversary=spoof)
    assert n_kept.draws == 1 and n_fresh.draws == 1
    assert rng_k.bit_generator.state == rng_f.bit_generator.state
    for f in ("toa_s", "peak_snr_db", "doppler_hz", "tags_valid", "detected"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    np.testing.assert_array_equal(a.uplink.toa_s, b.uplink.toa_s)
    assert a.uplink is benign.uplink
    assert not np.array_equal(a.peak_snr_db, benign.peak_snr_db)   # the attack did arrive
    # frequency domain: the replay reaches BS 1's REs alone, so BSs 0 and 2 keep the benign
    # call's estimates (the same objects; equal to the fresh chain's, above)
    reused = [x is y for x, y in zip(a.toa_estimates, benign.toa_estimates)]
    assert reused == ([True, False, True] if domain == "frequency" else [False] * 3)
    # a signal on a free symbol changes the noise estimates: nothing is reused, and the result is
    # still the fresh chain's
    loud = spoof.signal.copy()
    loud[0, 13, 5] = 1e-3
    loud_adv = Adversary(adv, loud)
    benign = kept(cir, 0, np.random.default_rng(7))
    c = kept(cir, 0, np.random.default_rng(7), adversary=loud_adv)
    d = fresh(cir, 0, np.random.default_rng(7), adversary=loud_adv)
    assert not any(x is y for x, y in zip(c.toa_estimates, benign.toa_estimates))
    for f in ("toa_s", "peak_snr_db", "doppler_hz", "detected"):
        np.testing.assert_array_equal(getattr(c, f), getattr(d, f))
    n_kept.draws = 0
    # another generator state is another noise draw
    kept(cir, 0, np.random.default_rng(8), adversary=spoof)
    assert n_kept.draws == 1


def test_fix_only_chain_gives_the_full_chains_fix_without_aoa_or_tags():
    """The FIX_ONLY plan (a run's encrypted-PRS chain, whose outcomes alone are used): the same timing and
    DL fix as the full chain on the same noise (second method: the full call; exact), no AoA and
    no tag check, while the BSs still transmit their tags."""
    ue = np.array([10.0, 20.0, 1.5])
    keys = simulated_keys((0, 1, 2), np.random.default_rng(0))
    args = (NRConfig(slots_per_frame=2), SecurityConfig(tag_scheme="hmac", encrypted=(True,) * 3),
            ChannelConfig(), ReceiverConfig(uplink=False), ArrayConfig(), FC, keys)
    full = PositioningChain(*args)(exact_cir(ue), 0, np.random.default_rng(3))
    only = PositioningChain(*args)(exact_cir(ue), 0, np.random.default_rng(3), plan=FIX_ONLY)
    np.testing.assert_array_equal(only.toa_s, full.toa_s)
    np.testing.assert_array_equal(only.position.position, full.position.position)
    assert full.tags_checked and full.tags_valid.all() and all(a is not None for a in full.aoa)
    assert not only.tags_checked and not only.tags_valid.any() and all(a is None for a in only.aoa)
