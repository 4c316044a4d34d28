"""The shortcuts ``ulnoise`` (the BSs' uplink noise drawn only on the REs their receiver reads)
and ``ulnoisevar`` (the receiver's noise estimate drawn from its distribution) are exact: the
uplink receiver reads no RE left without noise, the draws on the read REs are the reference's
order of draws, and the drawn estimate has the distribution of the reference's."""

import numpy as np
import pytest
from scipy import stats

import veriloc_rt.phy.noise as noise_mod
from veriloc_rt.config import config_from_dict
from veriloc_rt.phy.channel import Links, apply_frequency, dbm_to_watt, draw_noise, re_amplitude
from veriloc_rt.phy.noise import WhiteNoise
from veriloc_rt.phy.receiver.uplink import UplinkPositioner
from veriloc_rt.phy.shortcuts import ENV, reference
from veriloc_rt.sim.engine import compute_propagation
from veriloc_rt.sim.run_folder import run_keys
from veriloc_rt.sim.runner import ScenarioRunner
from veriloc_rt.world.geometry import build_geometry

UMA = {"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
       "trajectory": {"num_points": 8}, "seed": 5}
UMA9 = {"propagation": {"model": "uma"}, "topology": {"num_trps": 9},
        "channel": {"power_control": False}, "trajectory": {"num_points": 8}, "seed": 6}


def _positioner(monkeypatch, env: str | None) -> UplinkPositioner:
    if env is None:
        monkeypatch.delenv(ENV, raising=False)
    else:
        monkeypatch.setenv(ENV, env)
    cfg = config_from_dict(UMA)
    return UplinkPositioner(cfg.nr, cfg.channel, cfg.receiver)


def _link() -> Links:
    """One BS's uplink: two paths, one with Doppler (values of no particular meaning)."""
    return Links(np.array([[1.2e-6, 1.9e-6]]), np.array([[[3e-6 - 1e-6j, -1e-6 + 2e-6j]]]),
                 np.array([[40.0, -15.0]]), np.ones((1, 2), dtype=bool))


def test_reference_switch(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)
    assert not reference("ulnoise") and not reference("ulnoisevar")
    for env in ("ulnoise", "noise,ulnoise", "all"):
        monkeypatch.setenv(ENV, env)
        assert reference("ulnoise")
    monkeypatch.setenv(ENV, "noise")   # the UE's shortcut alone: the uplink's stay on
    assert not reference("ulnoise") and not reference("ulnoisevar")
    monkeypatch.setenv(ENV, "ulnoisevar")
    assert reference("ulnoisevar") and not reference("ulnoise")


def test_read_mask_is_the_srs_and_the_noise_estimate_symbols(monkeypatch):
    """The mask, derived independently: on the SRS symbols the comb's REs (``grid != 0``), and,
    with the noise estimate from the grid (``VERILOC_RT_REFERENCE=ulnoisevar``), every RE of the
    symbols outside ``srs_symbols`` (what ``noise_variance`` averages); the estimate drawn
    directly (default), those are not read. The reference path (``ulnoise``) has no mask, nor
    has the time domain."""
    p = _positioner(monkeypatch, "ulnoisevar")
    assert not p.direct_variance
    rx = p.receiver
    s, _, k = p.grid.shape
    srs = np.zeros((s, 14, k), dtype=bool)
    for sym in rx.srs_symbols:   # the comb: every srs_comb-th subcarrier from one offset
        row = p.grid[0, sym] != 0
        off = int(np.flatnonzero(row)[0])
        assert off < rx.srs_comb and np.array_equal(np.flatnonzero(row), np.arange(off, k, rx.srs_comb))
        srs[:, sym, off::rx.srs_comb] = True
    expect = srs.copy()
    expect[:, [sym for sym in range(14) if sym not in rx.srs_symbols]] = True
    assert np.array_equal(p.read, expect) and not p.read.flags.writeable
    assert 0.0 < p.read.mean() < 1.0
    d = _positioner(monkeypatch, None)
    assert d.direct_variance and np.array_equal(d.read, srs) and not d.read.flags.writeable
    assert _positioner(monkeypatch, "ulnoise").read is None
    monkeypatch.setenv(ENV, "all")
    cfg = config_from_dict({**UMA, "channel": {"domain": "time"}})
    assert UplinkPositioner(cfg.nr, cfg.channel, cfg.receiver).read is None   # IQ: every sample
    monkeypatch.delenv(ENV)
    t = UplinkPositioner(cfg.nr, cfg.channel, cfg.receiver)
    assert t.read is None and not t.direct_variance


@pytest.mark.parametrize("env", [None, "ulnoisevar"])
def test_received_grid_draws_in_the_reference_order(monkeypatch, env):
    """With the shortcut, a BS's grid is the signal plus one normal pair per read RE, filled in
    slot, symbol, subcarrier order (derived here from the generator directly), the signal alone
    elsewhere; on the reference path, the signal plus ``draw_noise`` over every RE, slot-major:
    the reference's bits."""
    p = _positioner(monkeypatch, env)
    link, t0 = _link(), 1.0e-6
    amp = re_amplitude([dbm_to_watt(p.channel.ue_power_dbm)], p.ofdm)
    signal = apply_frequency(link, p.grid[None], amp, p.ofdm, p.slots, t0, p.occupied[None])
    y = p.receive(link, t0, np.random.default_rng(11))
    z = np.random.default_rng(11).standard_normal((int(p.read.sum()), 2)) * np.sqrt(p.noise_var / 2)
    expect = signal.copy()
    expect[0][p.read] += z[:, 0] + 1j * z[:, 1]   # boolean indexing: C order, slot outermost
    assert np.array_equal(y, expect)
    assert np.array_equal(y[0][~p.read], signal[0][~p.read])
    ref = _positioner(monkeypatch, "ulnoise")
    y_ref = ref.receive(link, t0, np.random.default_rng(11))
    n = draw_noise(signal.shape, ref.noise_var, np.random.default_rng(11), major_axis=1)
    assert y_ref.tobytes() == (signal + n).tobytes()


def test_a_source_that_overrides_the_call_gets_every_re(monkeypatch):
    """A noise source that records or changes the noise (overrides the call) still gets every
    RE's noise with the shortcut on."""
    class Recording(WhiteNoise):
        def __call__(self, x, variance, rng):
            self.seen = x.shape
            return super().__call__(x, variance, rng)

    monkeypatch.delenv(ENV, raising=False)
    cfg = config_from_dict(UMA)
    src = Recording()
    p = UplinkPositioner(cfg.nr, cfg.channel, cfg.receiver, src)
    y = p.receive(_link(), 1.0e-6, np.random.default_rng(3))
    assert src.seen == y.shape and np.all(y != 0)


def _estimates(p: UplinkPositioner, seed: int, calls: int) -> np.ndarray:
    """The noise estimate the positioner's ToA estimator gets, one BS (no paths: noise alone),
    ``calls`` calls from one generator."""
    seen = []
    real = p.toa

    class Recorder:
        cfg = real.cfg

        def __call__(self, cs, nv):
            seen.append(nv)
            return real(cs, nv)

    p.toa = Recorder()
    empty = Links(np.zeros((1, 1)), np.zeros((1, 1, 1), complex), np.zeros((1, 1)), np.zeros((1, 1), bool))
    rng = np.random.default_rng(seed)
    for _ in range(calls):
        p([empty], np.zeros((1, 3)), 1.5, rng)
    return np.array(seen)


def test_drawn_noise_estimate_follows_the_generator_and_the_reference_distribution(monkeypatch):
    """Directly drawn (default), the estimate is ``Gamma(M, sigma^2 / M)`` from the call's
    generator right after the BS's noise on the SRS REs (derived here from the generator), M the
    REs ``noise_variance`` averages (1 antenna x slots x free symbols x subcarriers). Its
    distribution is the reference's (``noise_variance`` of a drawn grid): 400 estimates of
    each have mean sigma^2 and standard deviation sigma^2 / sqrt(M) within 4 standard errors
    (a factor sqrt(2) in M, e.g. counting the SRS symbols too, moves the deviation 12 of them),
    and a two-sample KS test does not tell them apart at 1 %."""
    d = _positioner(monkeypatch, None)
    r = _positioner(monkeypatch, "ulnoisevar")
    s, _, k = d.grid.shape
    m = s * len(d.free) * k
    assert len(d.free) == 14 - len(d.receiver.srs_symbols) and m == r.read[:, list(d.free)].sum()
    got = _estimates(d, 21, 3)
    rng = np.random.default_rng(21)
    for nv in got:
        rng.standard_normal((int(d.read.sum()), 2))   # the BS's noise on the SRS REs
        assert nv == rng.gamma(m, d.noise_var / m)
    n = 400
    a, b = _estimates(d, 22, n) / d.noise_var, _estimates(r, 23, n) / r.noise_var
    sd = 1 / np.sqrt(m)
    for x in (a, b):
        assert abs(x.mean() - 1) < 4 * sd / np.sqrt(n)
        assert abs(x.std(ddof=1) / sd - 1) < 4 / np.sqrt(2 * (n - 1))
    assert stats.ks_2samp(a, b).pvalue > 0.01


def _uplinks(cfg_dict, tmp_path, fill, masks):
    """Every scenario's uplink results at a benign and an attack point, the uplink's REs left
    without noise holding ``fill`` instead of 0 (the UE's untouched)."""
    real = noise_mod.draw_grid_noise_on
    cfg = config_from_dict(cfg_dict)
    geo = build_geometry(cfg, tmp_path / "scene")
    runner = ScenarioRunner(cfg, geo, compute_propagation(cfg, geo), run_keys(cfg, len(geo.bs_pos)))
    ul_reads = [r.chain.uplink.positioner.read for r in runner.roles.values()
                if r.chain.uplink is not None]
    assert ul_reads and all(m is not None for m in ul_reads)

    def poisoned(shape, read, variance, rng, single=False):
        n = real(shape, read, variance, rng, single)
        if any(read is m for m in ul_reads):
            masks.append(np.count_nonzero(read) / read.size)
            n[:, ~np.asarray(read, bool)[:shape[1]]] = fill * np.sqrt(variance)
        return n

    noise_mod.draw_grid_noise_on = poisoned
    try:
        window = np.flatnonzero(cfg.run.attack_points(geo.num_points))
        benign = int(np.flatnonzero(~cfg.run.attack_points(geo.num_points))[0])
        out = {}
        for scen in ("none", "fbs", "meaconing", "jamming"):
            for i in (benign, int(window[0])):
                for key, res in runner.compute_chains(scen, i).items():
                    if res.uplink is not None:
                        out[scen, i, key] = res.uplink
                runner.clear_cache()
        return out
    finally:
        noise_mod.draw_grid_noise_on = real


@pytest.mark.heavy
@pytest.mark.parametrize("env", [None, "ulnoisevar"], ids=["default", "estimate-from-grid"])
@pytest.mark.parametrize("cfg", [UMA, UMA9], ids=["uma-3trps", "uma-9trps"])
def test_no_uplink_stage_reads_an_re_left_without_noise(cfg, env, tmp_path, monkeypatch):
    """The uplink results (timing, detection, SNR, the UL fix) with NaN, or a value 1e4 noise
    sigmas large, on the REs left without noise equal those with 0 there bit for bit (any read
    of such an RE would move a statistic: NaN propagates through every sum); by default the
    symbols of the noise estimate are among them (its estimate drawn directly)."""
    if env is None:
        monkeypatch.delenv(ENV, raising=False)
    else:
        monkeypatch.setenv(ENV, env)
    masks: list = []
    base = _uplinks(cfg, tmp_path / "zero", 0.0, masks)
    assert base and masks and max(masks) < 1.0   # the shortcut ran on the uplink, left REs out
    assert any(np.any(u.detected) for u in base.values())
    for fill in (np.nan, 1e4 * (1 + 1j)):
        other = _uplinks(cfg, tmp_path / str(fill).replace("(", "").replace(")", ""), fill, [])
        assert list(other) == list(base)
        for k in base:
            a, b = base[k], other[k]
            for f in ("detected", "toa_s", "tdoa_s", "peak_snr_db"):
                assert np.asarray(getattr(a, f)).tobytes() == np.asarray(getattr(b, f)).tobytes(), (k, f)
            for f in ("position", "ok", "status", "residual_rms_m", "chi2", "num_bs"):
                assert (np.asarray(getattr(a.position, f)).tobytes()
                        == np.asarray(getattr(b.position, f)).tobytes()), (k, f)
