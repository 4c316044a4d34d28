"""The meaconer's grid: AGC to its transmit power, and what its receive chain adds.

Independent references: the AGC's definition (carrier power P_relay after the gain, with RE
power p meaning carrier power p N_sc / N_fft, the channel module's convention) and the SNR of the
relayed grid measured as rho / (1 - rho) from its correlation rho with the noiseless relay
output; a receive-antenna gain G scales the BSs' signals, not the relay's own noise, so it
multiplies that SNR by G.
"""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.phy.channel import dbm_to_watt, re_amplitude
from veriloc_rt.config import config_from_dict
from veriloc_rt.sim.engine import compute_propagation
from veriloc_rt.sim.run_folder import run_keys
from veriloc_rt.rng import stream
from veriloc_rt.attacks.adversary import AdversarySignal
from veriloc_rt.sim.runner import ScenarioRunner
from veriloc_rt.world.geometry import build_geometry

#: SNR ratio for a 10 dB antenna gain: the noise draw is the same, signal-noise cross terms over
#: ~3e5 REs move the measured SNR by well under 1 %
GAIN_RTOL = 0.02


def _relay(tmp_path, channel=None, **meaconing):
    """(config, AdversarySignal, relayed grid of point 1, the call's arguments)."""
    cfg = config_from_dict({"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
                            "trajectory": {"num_points": 3}, "seed": 2,
                            "threats": {"meaconing": meaconing}, "channel": channel or {},
                            "run": {"evaluate_encrypted": False}})
    geo = build_geometry(cfg, tmp_path)
    prop = compute_propagation(cfg, geo)
    runner = ScenarioRunner(cfg, geo, prop, run_keys(cfg, len(geo.bs_pos)))
    sig = AdversarySignal(cfg, runner.roles["standard"].chain)
    args = ("meaconing", 1, 1, prop.bs_ue, prop.bs_adv, geo.adversary.pos[1], geo.ue.pos[1])
    return cfg, sig, sig(*args, stream(cfg.seed, "adversary", 2, 0, 1)), args


def _snr(y, y0):
    rho = abs(np.vdot(y, y0)) ** 2 / (np.vdot(y, y).real * np.vdot(y0, y0).real)
    return rho / (1 - rho)


def test_relay_agc_power_and_receive_gain(tmp_path):
    cfg, sig, g0, args = _relay(tmp_path)
    # AGC: the grid is in unit-RE normalisation; times the unit it is absolute RE amplitude
    ofdm = sig.ofdm
    p = np.mean(np.abs(g0 * sig.unit) ** 2) * ofdm.num_subcarriers / ofdm.fft_size
    assert p == pytest.approx(float(dbm_to_watt(cfg.threats.meaconing.power_dbm)), rel=1e-9)
    assert sig.unit == pytest.approx(float(re_amplitude(dbm_to_watt(48.0), ofdm)))
    sig.threat("meaconing").noise_var = 0.0
    clean = sig(*args, np.random.default_rng(0)).ravel()
    snr0 = _snr(g0.ravel(), clean)
    g10 = _relay(tmp_path, rx_antenna_gain_dbi=10.0)[2]
    assert _snr(g10.ravel(), clean) / snr0 == pytest.approx(10.0, rel=GAIN_RTOL)
    # a quieter receiver: 9 dB -> 3 dB noise figure is the same 6 dB of SNR
    g3 = _relay(tmp_path, noise_figure_db=3.0)[2]
    assert _snr(g3.ravel(), clean) / snr0 == pytest.approx(10 ** 0.6, rel=GAIN_RTOL)
    # the channel-bandwidth noise convention reaches the relay's receiver: density x B / 122.88 MHz
    g_b = _relay(tmp_path, channel={"noise_bandwidth_hz": 10e6})[2]
    assert _snr(g_b.ravel(), clean) / snr0 == pytest.approx(12.288, rel=GAIN_RTOL)


def test_fbs_link_gain_spoofed_bs_scales_each_replica_to_its_bs(tmp_path):
    """``threats.fbs.link_gain`` 'spoofed_bs': after the chain applies the adversary -> UE link,
    replica i arrives with BS i's path gain instead, so on BS i's REs the grid is the physical
    one times sqrt(G_i / G_adv), G the link's power gain summed over paths and averaged over the
    UE antennas (computed here from the CIRs' gains). Exact up to float rounding (1e-9)."""
    grids = {}
    for link in ("adversary", "spoofed_bs"):
        cfg = config_from_dict({"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
                                "trajectory": {"num_points": 3}, "seed": 2,
                                "threats": {"fbs": {"link_gain": link}},
                                "run": {"evaluate_encrypted": False}})
        geo = build_geometry(cfg, tmp_path / link)
        prop = compute_propagation(cfg, geo)
        runner = ScenarioRunner(cfg, geo, prop, run_keys(cfg, len(geo.bs_pos)))
        sig = AdversarySignal(cfg, runner.roles["standard"].chain)
        grids[link] = sig("fbs", 1, 1, prop.bs_ue, prop.bs_adv, geo.adversary.pos[1], geo.ue.pos[1],
                          stream(cfg.seed, "adversary", 1, 0, 1), adv_ue=prop.adv_ue)
    gain = lambda cir: np.sum(np.mean(np.abs(cir.gains[1]) ** 2, axis=1), axis=-1)  # noqa: E731
    expect = np.sqrt(gain(prop.bs_ue) / gain(prop.adv_ue)[0])                         # [num_bs]
    a, b = grids["adversary"], grids["spoofed_bs"]
    sent = np.abs(a) > 0
    assert np.array_equal(sent, np.abs(b) > 0)
    ratio = b[sent] / a[sent]
    np.testing.assert_allclose(ratio.imag, 0.0, atol=1e-9)
    # every RE of the spoofer's grid belongs to one replica: its scale is one of the BSs' ratios,
    # and each BS's ratio occurs (all three serving BSs are spoofed)
    rel = np.abs(ratio.real[:, None] / expect[None, :] - 1.0)                  # [REs, num_bs]
    assert np.all(rel.min(axis=1) < 1e-9)
    assert set(np.argmin(rel, axis=1)) == set(range(expect.size))
    with pytest.raises(ValueError, match="spoofed_bs"):
        sig("fbs", 1, 1, prop.bs_ue, prop.bs_adv, geo.adversary.pos[1], geo.ue.pos[1],
            stream(cfg.seed, "adversary", 1, 0, 1))


def test_relay_stand_in_tags_keep_the_agc_and_every_read_re(tmp_path, monkeypatch):
    """The shortcut ``relaytags``: the relay's received frame carries the stand-in QPSK symbol
    on the tag REs of the slots the UE does not check, instead of their tags, which are not
    computed (the chain's every-tag frame is never asked for). Against the reference
    (``VERILOC_RT_REFERENCE=relaytags``, read when the threat is made): the same occupancy;
    the same values on every RE the chain's own frame fills (PRS, checked tags: bit for bit);
    unit modulus on the others, as the tags' QPSK there. Without the relay's noise its output
    has the same modulus on every RE (the AGC's input power is the same sum of abs(h)^2
    terms): tolerance 1e-9 relative, float rounding of sums over ~3e5 REs."""
    out = {}
    for ref in ("", "relaytags"):
        monkeypatch.setenv("VERILOC_RT_REFERENCE", ref)
        cfg, sig, _, args = _relay(tmp_path / (ref or "default"))
        threat = sig.threat("meaconing")
        assert threat.stand_in is (ref == "")
        asked = []
        frame_signals = sig.chain.frame_signals

        def spy(*a, every_tag=False, **k):
            asked.append(every_tag)
            return frame_signals(*a, every_tag=every_tag, **k)

        monkeypatch.setattr(sig.chain, "frame_signals", spy)
        bs_ids = tuple(int(b) for b in args[3].tx_index[1])
        grids, occ = threat.relayed_frame(bs_ids, 1)
        lean = frame_signals(bs_ids, 1)
        threat.noise_var = 0.0
        out[ref] = (grids, occ, lean, sig(*args, np.random.default_rng(0)), asked)
    (g_s, o_s, lean, y_s, asked_s), (g_r, o_r, _, y_r, asked_r) = out[""], out["relaytags"]
    assert asked_s and not any(asked_s) and asked_r and all(asked_r)
    np.testing.assert_array_equal(o_s, o_r)
    np.testing.assert_array_equal(o_r, g_r != 0)
    mine = lean.occupied
    assert np.any(o_r & ~mine)                         # the check covers stand-in REs
    np.testing.assert_array_equal(g_s[mine], g_r[mine])
    np.testing.assert_allclose(np.abs(g_s[o_r & ~mine]), 1.0, rtol=1e-12)
    np.testing.assert_allclose(np.abs(g_r[o_r & ~mine]), 1.0, rtol=1e-12)
    assert not np.array_equal(g_s[o_r & ~mine], g_r[o_r & ~mine])
    np.testing.assert_allclose(np.abs(y_s), np.abs(y_r), rtol=1e-9, atol=1e-9 * np.abs(y_r).max())


def test_relay_agc_input_power_per_re_does_not_depend_on_the_symbol():
    """Why the stand-in is exact in distribution: abs(h x + n)^2 with n ~ CN(0, sigma^2) has the
    same distribution for every x of modulus 1 (n circularly symmetric). Two symbols, 2e5
    independent noise draws each, a two-sample KS test at 1e-3 (and the mean |h|^2 + sigma^2
    within 5 standard errors)."""
    from scipy.stats import ks_2samp

    rng = np.random.default_rng(3)
    h, sigma2, n = 0.7 - 0.4j, 0.5, 200_000
    x1, x2 = (1 - 1j) / np.sqrt(2), (1 + 1j) / np.sqrt(2)
    draw = lambda: np.sqrt(sigma2 / 2) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))  # noqa: E731
    p1, p2 = np.abs(h * x1 + draw()) ** 2, np.abs(h * x2 + draw()) ** 2
    assert ks_2samp(p1, p2).pvalue > 1e-3
    for p in (p1, p2):
        assert abs(p.mean() - (abs(h) ** 2 + sigma2)) < 5 * p.std() / np.sqrt(n)
