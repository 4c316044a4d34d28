"""Each stage block of the positioning chain alone, on synthetic inputs with a closed-form answer."""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.config import ArrayConfig
from veriloc_rt.config.channel import ChannelConfig, ReceiverConfig
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.constants import SPEED_OF_LIGHT as C
from veriloc_rt.phy.chain import (FIX_ONLY, AngleStage, ChainPlan, DownlinkChannel, FixStage,
                                  FrameSource, PositioningChain, Timing)
from veriloc_rt.phy.chain.downlink import KeptDraw, SignalKey
from veriloc_rt.phy.chain.frames import DUMMY_ID, ServingSet
from veriloc_rt.phy.chain.receiver import zenith_from_fix
from veriloc_rt.phy.channel import dbm_to_watt
from veriloc_rt.phy.noise import WhiteNoise
from veriloc_rt.phy.nr.ofdm import OFDM
from veriloc_rt.phy.receiver.aoa import AoAEstimator
from veriloc_rt.phy.receiver.toa import ToAEstimate
from veriloc_rt.phy.security.keys import simulated_keys
from veriloc_rt.propagation.cir import CIR, NO_TX, array_response, ula_element_positions

FC = 3.5e9
BS = np.array([[0.0, 289.0, 25.0], [-250.3, -144.5, 25.0], [250.3, -144.5, 25.0]])
UE = np.array([37.0, -21.0, 1.5])
#: the solver stops at its own tolerance, far below a millimetre on exact range differences
FIX_M = 1e-3
#: ESPRIT on noiseless plane-wave snapshots: exact up to round-off
AOA_RAD = 1e-6
#: round-off of the power-control products
REL = 1e-12


def one_path_cir(ue: np.ndarray, amp=(1e-6, 2e-6, 0.5e-6), tx_index=(0, 1, 2)) -> CIR:
    """One point, one line-of-sight path per BS at |BS - UE| / c from the BS's direction."""
    d = BS - ue[None, :]
    dist = np.linalg.norm(d, axis=1)
    az, zen = np.arctan2(d[:, 1], d[:, 0]), np.arccos(d[:, 2] / dist)
    ep = ula_element_positions(5, 0.5 * C / FC, 0.0)
    gains = np.asarray(amp)[:, None, None] * array_response(az[:, None], zen[:, None], ep, C / FC)
    z = np.zeros((1, 3, 1))
    return CIR(delays=(dist / C)[None, :, None], gains=gains[None].astype(complex), aoa_az=az[None, :, None],
               aoa_zen=zen[None, :, None], aod_az=z, aod_zen=z, doppler=z.copy(),
               interactions=np.zeros((1, 3, 1, 1), np.uint8), valid=np.ones((1, 3, 1), bool),
               tx_index=np.array([tx_index]), tx_pos=BS[None], rx_pos=ue[None], los=np.ones((1, 3), bool),
               carrier_frequency=FC)


# -- transmitter stage ------------------------------------------------------------------------
def test_frame_source_replicas_are_the_transmitted_prs_and_the_last_frame_is_kept():
    """Standard PRS: each BS's replica is its own transmitted grid on the replica's REs (the tags
    sit on other REs of the same symbols); comb 6 puts K / 6 REs in each PRS symbol (TS 38.211
    7.4.1.7.3). The last frame is kept: the same key gives the same object."""
    nr = NRConfig(slots_per_frame=2)
    src = FrameSource(nr, SecurityConfig(tag_scheme="hmac"),
                      simulated_keys((0, 1, 2), np.random.default_rng(0)), time_domain=False)
    sig = src((0, 1, 2), 5)
    k = OFDM(nr).num_subcarriers
    for b, rep in enumerate(sig.replicas):
        on = rep != 0
        np.testing.assert_array_equal(sig.grids[b][on], rep[on])
        for l in nr.prs_symbols:
            assert np.count_nonzero(on[0, l]) == k // nr.comb
    assert sig.waveform is None
    assert src((0, 1, 2), 5) is sig
    assert src((0, 1, 2), 6) is not sig
    assert not np.array_equal(src((0, 1, 2), 6).grids, sig.grids)   # the tags carry the frame


def test_serving_sets_beyond_the_kept_ones_are_made_again_the_same():
    """A FrameSource keeps the transmitters of its SETUPS_KEPT last serving sets (a drive past
    many sites meets dozens); a set pushed out and asked for again gets a new transmitter whose
    frame is the first one's to the bit (grids, replicas, occupancy): the bound changes no value."""
    from veriloc_rt.phy.chain.frames import SETUPS_KEPT

    nr = NRConfig(slots_per_frame=1)
    sets = [(a, a + 1, a + 2) for a in range(SETUPS_KEPT + 2)]
    src = FrameSource(nr, SecurityConfig(tag_scheme="hmac"),
                      simulated_keys(range(SETUPS_KEPT + 4), np.random.default_rng(0)), time_domain=False)
    first = src(sets[0], 7)
    tx = src.setup(sets[0]).transmitter
    for ids in sets[1:]:
        src(ids, 7)
    again = src(sets[0], 7)
    assert src.setup(sets[0]).transmitter is not tx          # pushed out, made again
    np.testing.assert_array_equal(again.grids, first.grids)
    np.testing.assert_array_equal(again.occupied, first.occupied)
    for r0, r1 in zip(first.replicas, again.replicas):
        np.testing.assert_array_equal(r0, r1)
    assert src.setup(sets[-1]).transmitter is src.setup(sets[-1]).transmitter   # a kept one


def test_an_empty_serving_slot_transmits_under_a_dummy_identity():
    assert ServingSet.of((4, NO_TX, 9)).transmitted_ids == (4, DUMMY_ID + 1, 9)
    src = FrameSource(NRConfig(slots_per_frame=1), SecurityConfig(tag_scheme="hmac"),
                      simulated_keys((4, 9), np.random.default_rng(0)), time_domain=True)
    setup = src.setup((4, NO_TX, 9))
    assert setup.verifier is not None and src.setup([4, NO_TX, 9]) is setup
    assert src((4, NO_TX, 9), 0).waveform.shape[0] == 3


# -- channel stage ----------------------------------------------------------------------------
def test_downlink_power_control_and_timing_reference_in_closed_form():
    """Equal arrival powers: P_b |g_b|^2 is the same for every BS and the weakest link gets the
    maximum power; t0 is the earliest first-path delay less the guard."""
    nr = NRConfig(slots_per_frame=1)
    ofdm = OFDM(nr)
    ch = ChannelConfig(power_control=True)
    dl = DownlinkChannel(ch, ofdm, range(1), 1.0, ofdm.num_samples(range(1)), 1, WhiteNoise(), 0.0)
    amp = np.array([1e-6, 2e-6, 0.5e-6])
    links = dl.links(one_path_cir(UE, amp), 0)
    gain = amp ** 2
    p_max = float(dbm_to_watt(ch.bs_max_power_dbm))
    np.testing.assert_allclose(links.tx_power_w * gain, p_max * gain.min(), rtol=REL)
    assert links.tx_power_w.max() == pytest.approx(p_max, rel=REL)
    dist = np.linalg.norm(BS - UE, axis=1)
    assert links.timing_reference_s == pytest.approx(dist.min() / C - ch.timing_guard_s, rel=REL)


def test_a_points_links_are_taken_from_its_cir_once_per_thread():
    """point_links: Links.from_cir's arrays bit for bit (second method: from_cir itself),
    read-only, the same object for the same CIR and point (every chain and scenario of a point),
    another for another point or another CIR of equal values; at most POINT_LINKS_MAX pairs kept."""
    from veriloc_rt.phy.chain import downlink as dm
    from veriloc_rt.phy.channel import Links

    cir = one_path_cir(UE)
    first = dm.point_links(cir, 0)
    want = Links.from_cir(cir, 0)
    for got, ref in zip((first.delays, first.gains, first.doppler, first.valid),
                        (want.delays, want.gains, want.doppler, want.valid)):
        np.testing.assert_array_equal(got, ref)
        assert not got.flags.writeable
    assert dm.point_links(cir, 0) is first
    twin = one_path_cir(UE)
    assert dm.point_links(twin, 0) is not first
    for k in range(dm.POINT_LINKS_MAX + 1):
        dm.point_links(one_path_cir(UE + k), 0)
    assert dm.point_links(cir, 0) is not first          # pushed out: taken again


def test_frames_carry_the_checked_slots_tags_and_a_relay_gets_every_tag():
    """With tag_slots (0,) a frame's grids are the whole frame's on every RE but slot 1's tag
    REs, which stay empty (3 BSs' tags: half the REs of each PRS symbol), and the occupancy
    masks say so; asked for every tag, the grids are the whole frame's. The received grid is
    then the whole frame's on every RE the receiver reads (the per-RE channel: one RE's signal
    reaches no other), with the same noise draws."""
    nr = NRConfig(slots_per_frame=2)
    ofdm = OFDM(nr)
    keys = simulated_keys((0, 1, 2), np.random.default_rng(0))
    src = FrameSource(nr, SecurityConfig(tag_scheme="hmac"), keys, time_domain=False, tag_slots=(0,))
    whole = FrameSource(nr, SecurityConfig(tag_scheme="hmac"), keys, time_domain=False)
    sig, full = src((0, 1, 2), 3), whole((0, 1, 2), 3)
    prs = np.any(np.stack(full.replica_occupied), axis=0)                  # [S, 14, K]
    unchecked = np.any(full.occupied, axis=0) & ~prs
    unchecked[0] = False
    assert unchecked[1].sum() == nr.num_symbols * ofdm.num_subcarriers // 2
    np.testing.assert_array_equal(sig.grids[:, ~unchecked], full.grids[:, ~unchecked])
    assert not sig.grids[:, unchecked].any() and np.any(full.grids[:, unchecked] != 0, axis=0).all()
    np.testing.assert_array_equal(sig.occupied, sig.grids != 0)
    relay = src((0, 1, 2), 3, every_tag=True)
    np.testing.assert_array_equal(relay.grids, full.grids)
    np.testing.assert_array_equal(relay.occupied, full.occupied)
    assert src((0, 1, 2), 3) is sig and src((0, 1, 2), 3, every_tag=True) is relay   # both kept
    dl = DownlinkChannel(ChannelConfig(), ofdm, range(2), 1.0, ofdm.num_samples(range(2)), 1,
                         WhiteNoise(), 1e-3)
    links = dl.links(one_path_cir(UE), 0)
    y = dl.benign(links, sig, np.random.default_rng(7), 2)
    y_full = dl.benign(links, full, np.random.default_rng(7), 2)
    np.testing.assert_array_equal(y[:, ~unchecked], y_full[:, ~unchecked])
    with pytest.raises(ValueError, match="frequency domain"):
        FrameSource(nr, SecurityConfig(tag_scheme="hmac"), keys, time_domain=True, tag_slots=(0,))


def test_a_chain_reads_the_same_without_the_unchecked_slots_tags():
    """The chain's results (ToA, Doppler, fix, tag verdicts) are the same, value for value, when
    its frames carry every slot's tags: nothing it reads changes."""
    chain = PositioningChain(NRConfig(slots_per_frame=3), SecurityConfig(tag_scheme="hmac"),
                             ChannelConfig(), ReceiverConfig(uplink=False, tag_slots=(1,)),
                             ArrayConfig(), FC, simulated_keys((0, 1, 2), np.random.default_rng(0)))
    cir = one_path_cir(UE)
    lean = chain(cir, 0, np.random.default_rng(5), frame=9)
    assert chain.frames.tag_slots == (1,)
    chain.frames.tag_slots = None
    every = chain(cir, 0, np.random.default_rng(5), frame=9)
    for f in ("toa_s", "doppler_hz", "peak_snr_db", "tags_valid", "detected"):
        np.testing.assert_array_equal(getattr(lean, f), getattr(every, f))
    np.testing.assert_array_equal(lean.position.position, every.position.position)
    assert lean.tags_valid.all()


def test_kept_draw_gives_the_value_back_only_for_the_same_key_and_generator_state():
    kept, calls = KeptDraw(), []

    def compute(rng):
        calls.append(1)
        return rng.standard_normal(4)

    cir = one_path_cir(UE)
    key = SignalKey(cir, 0, 3, "own", 2)
    r1 = np.random.default_rng(1)
    a = kept(key, r1, lambda: compute(r1))
    r2 = np.random.default_rng(1)
    b = kept(SignalKey(cir, 0, 3, "own", 2), r2, lambda: compute(r2))
    assert b is a and len(calls) == 1
    assert r1.bit_generator.state == r2.bit_generator.state   # moved past the draws
    r3 = np.random.default_rng(1)
    kept(SignalKey(one_path_cir(UE), 0, 3, "own", 2), r3, lambda: compute(r3))   # another CIR object
    assert len(calls) == 2


# -- receiver stages --------------------------------------------------------------------------
def timing_of(rstd_s: np.ndarray, detected: np.ndarray) -> Timing:
    return Timing((), (), detected, np.where(detected, rstd_s, np.nan), np.where(detected, rstd_s, np.nan))


def test_fix_stage_solves_exact_range_differences():
    """RSTDs of exact geometry (|BS_i - UE| - |BS_0 - UE|) / c, the UE height known: the fix is
    the UE (closed-form multilateration on a synthetic triangle)."""
    d = np.linalg.norm(BS - UE, axis=1)
    fix = FixStage(10.0)(timing_of((d - d[0]) / C, np.ones(3, bool)), BS, UE[2])
    assert fix.ok
    np.testing.assert_allclose(fix.position, UE, atol=FIX_M)


def test_fix_stage_fails_with_two_bss():
    d = np.linalg.norm(BS - UE, axis=1)
    fix = FixStage(10.0)(timing_of((d - d[0]) / C, np.array([True, True, False])), BS, UE[2])
    assert not fix.ok


def test_zenith_from_fix_in_closed_form():
    d = np.linalg.norm(BS - UE, axis=1)
    fix = FixStage(10.0)(timing_of((d - d[0]) / C, np.ones(3, bool)), BS, UE[2])
    np.testing.assert_allclose(zenith_from_fix(BS, fix), np.arccos((BS[:, 2] - UE[2]) / d), atol=1e-5)


def estimate(snapshots: np.ndarray, detected: bool = True) -> ToAEstimate:
    return ToAEstimate(detected, 0.0, 0.0, 30.0, snapshots[:, 0], snapshots, 1.0)


def test_angle_stage_recovers_plane_wave_azimuths_and_skips_undetected_bss():
    """Noiseless snapshots of one plane wave per BS from the UE -> BS direction (ULA along +x,
    half-wavelength spacing): the resolved azimuth is that direction."""
    d = BS - UE
    az, zen = np.arctan2(d[:, 1], d[:, 0]), np.arccos(d[:, 2] / np.linalg.norm(d, axis=1))
    ep = ula_element_positions(5, 0.5 * C / FC, 0.0)
    rng = np.random.default_rng(0)
    ests = []
    for b in range(3):
        a = array_response(np.array([az[b]]), np.array([zen[b]]), ep, C / FC)[:, 0]        # [5]
        s = np.exp(2j * np.pi * rng.random(8))                                           # 8 snapshots
        ests.append(estimate(a[:, None] * s[None, :], detected=b != 2))
    timing = Timing(tuple(ests), (None,) * 3, np.array([True, True, False]), np.zeros(3), np.zeros(3))
    stage = AngleStage(AoAEstimator("esprit", 1, 0.5, 0.0), "peak")
    out = stage(timing, zen, reference_azimuth=az + 0.2)
    np.testing.assert_allclose(out.azimuth[:2], az[:2], atol=AOA_RAD)
    assert out.aoa[2] is None and np.isnan(out.azimuth[2])
    assert np.isnan(stage(timing, zen).azimuth).all()   # no reference: unresolved


# -- the plan -----------------------------------------------------------------------------------
def test_plan_rejects_contradictions():
    with pytest.raises(ValueError, match="replica"):
        ChainPlan(replica="mine")
    with pytest.raises(TypeError, match="timing_from"):
        ChainPlan(angles=False, uplink=False, timing_from="x")


def make_chain(**kw) -> PositioningChain:
    return PositioningChain(NRConfig(slots_per_frame=2), SecurityConfig(tag_scheme="hmac"),
                            ChannelConfig(noise=False), ReceiverConfig(**kw), ArrayConfig(), FC,
                            simulated_keys((0, 1, 2), np.random.default_rng(0)))


def test_tags_on_plan_keeps_the_given_timing_and_checks_only_the_tags():
    """A tags-only call returns the given result with this chain's tag verdicts: the same
    timing and fix objects, the tags checked (noiseless: all valid)."""
    chain = make_chain(uplink=False)
    cir = one_path_cir(UE)
    full = chain(cir, 0, np.random.default_rng(1))
    only = chain(cir, 0, np.random.default_rng(1), plan=ChainPlan.tags_on(full))
    assert only.position is full.position and only.toa_estimates is full.toa_estimates
    assert only.tags_checked and only.tags_valid.all()
    with pytest.raises(ValueError, match="angles"):
        ChainPlan(timing_from=full)
    fix = chain(cir, 0, np.random.default_rng(1), plan=FIX_ONLY)
    assert not fix.tags_checked and all(a is None for a in fix.aoa)
    np.testing.assert_allclose(fix.position.position, UE, atol=0.5)
