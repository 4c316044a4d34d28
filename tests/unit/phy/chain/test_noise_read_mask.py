"""The shortcut ``noise`` (noise drawn only on the REs the receiver reads) is exact: no stage of
any chain reads an RE left without noise, and the draws on the read REs are the reference's
order of draws."""

import numpy as np
import pytest

import veriloc_rt.phy.noise as noise_mod
from veriloc_rt.config import config_from_dict
from veriloc_rt.phy.channel import draw_grid_noise_on, draw_noise
from veriloc_rt.phy.shortcuts import ENV, reference
from veriloc_rt.sim.engine import compute_propagation
from veriloc_rt.sim.run_folder import run_keys
from veriloc_rt.sim.runner import ScenarioRunner
from veriloc_rt.world.geometry import build_geometry

UMA = {"propagation": {"model": "uma", "uma_mode": "pathloss_only"},
       "trajectory": {"num_points": 8}, "seed": 5}
UMA9 = {"propagation": {"model": "uma"}, "topology": {"num_trps": 9},
        "channel": {"power_control": False}, "trajectory": {"num_points": 8}, "seed": 6}


def test_every_re_read_gives_the_reference_draws():
    """With every RE read the values are draw_noise's (slot-major), bit for bit; a mask's draws
    fill its REs in slot, antenna, symbol, subcarrier order and the first slots' noise does not
    depend on the number of slots."""
    shape = (2, 3, 14, 12)
    full = np.ones(shape[1:], dtype=bool)
    a = draw_grid_noise_on(shape, full, 0.5, np.random.default_rng(1))
    b = draw_noise(shape, 0.5, np.random.default_rng(1), major_axis=1)
    assert a.tobytes() == b.tobytes()
    mask = np.random.default_rng(2).random(shape[1:]) < 0.3
    m = draw_grid_noise_on(shape, mask, 0.5, np.random.default_rng(3))
    assert np.all(m[:, ~mask] == 0) and np.all(m[:, mask] != 0)
    # independent derivation of the order: one normal pair per read RE, slot outermost
    z = np.random.default_rng(3).standard_normal((2 * mask.sum(), 2)) * np.sqrt(0.25)
    z = z[:, 0] + 1j * z[:, 1]
    expect = np.zeros(shape, dtype=complex)
    k = 0
    for s in range(3):
        for ant in range(2):
            n = mask[s].sum()
            expect[ant, s][mask[s]] = z[k:k + n]
            k += n
    assert np.array_equal(m, expect)
    first = draw_grid_noise_on((2, 1, 14, 12), mask, 0.5, np.random.default_rng(3))
    assert first.tobytes() == np.ascontiguousarray(m[:, :1]).tobytes()


def test_reference_switch(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)
    assert not reference("noise")
    monkeypatch.setenv(ENV, "noise")
    assert reference("noise")
    monkeypatch.setenv(ENV, "all")
    assert reference("noise")
    with pytest.raises(ValueError):
        reference("nothing")


def _results(cfg_dict, tmp_path, fill):
    """Every scenario's chain results at a benign and an attack point, the REs left without
    noise holding ``fill`` instead of 0."""
    real = noise_mod.draw_grid_noise_slots   # the run's noise source's (KeptWhiteNoise) draws

    def poisoned(shape, read, variance, rng, single=False):
        n, states = real(shape, read, variance, rng, single)
        n = np.array(n)
        n[:, ~np.asarray(read, bool)[:shape[1]]] = fill * np.sqrt(variance)
        return n, states

    noise_mod.draw_grid_noise_slots = poisoned
    try:
        cfg = config_from_dict(cfg_dict)
        geo = build_geometry(cfg, tmp_path / "scene")
        runner = ScenarioRunner(cfg, geo, compute_propagation(cfg, geo),
                                run_keys(cfg, len(geo.bs_pos)))
        window = np.flatnonzero(cfg.run.attack_points(geo.num_points))
        benign = int(np.flatnonzero(~cfg.run.attack_points(geo.num_points))[0])
        out = {}
        for scen in ("none", "fbs", "meaconing", "jamming"):
            for i in (benign, int(window[0])):
                out[scen, i] = runner.compute_chains(scen, i)
                runner.clear_cache()
        return out
    finally:
        noise_mod.draw_grid_noise_slots = real


@pytest.mark.heavy
@pytest.mark.parametrize("cfg", [UMA, UMA9], ids=["uma-3trps", "uma-9trps"])
def test_no_stage_reads_an_re_left_without_noise(cfg, tmp_path, monkeypatch):
    """The results with NaN, or a value 1e4 noise sigmas large, on the unread REs equal the
    results with 0 there bit for bit (any read of such an RE would move a statistic)."""
    monkeypatch.delenv(ENV, raising=False)
    calls = []
    real = noise_mod.draw_grid_noise_slots
    monkeypatch.setattr(noise_mod, "draw_grid_noise_slots",
                        lambda *a: calls.append(np.count_nonzero(a[1]) / a[1].size) or real(*a))
    base = _results(cfg, tmp_path / "zero", 0.0)
    assert calls and max(calls) < 1.0   # the shortcut ran, and left some REs out
    for fill in (np.nan, 1e4 * (1 + 1j)):
        other = _results(cfg, tmp_path / str(fill).replace("(", "").replace(")", ""), fill)
        assert list(other) == list(base)
        for k in base:
            for key in base[k]:
                a, b = base[k][key], other[k][key]
                for f in ("toa_s", "detected", "tags_valid", "peak_snr_db", "doppler_hz", "azimuth"):
                    assert np.asarray(getattr(a, f)).tobytes() == np.asarray(getattr(b, f)).tobytes(), (k, key, f)
                assert (np.asarray(a.position.position).tobytes()
                        == np.asarray(b.position.position).tobytes()), (k, key)
