"""The channel's rounding and precision shortcuts (veriloc_rt.phy.shortcuts: ``delays``,
``noise32``) against their reference paths.

``delays``: a link's frequency response summed over its distinct delays is the path-by-path sum
in another order. Both multiply the same per-path factors (the same float64 numbers: each path's
two exponentials are computed by the same expression), so they differ only by the rounding of
the additions and of one extra product per term: each sum of P terms carries at most about
P eps sum_p |g_ap| (eps = 2.2e-16; P ~ 400 rays: ~1e-13). The bound used, 1e-12 sum_p |g_ap|
per entry, leaves that a factor 10; it is relative to sum_p |g_ap| and not to |H| because the
sum may cancel (a fade), where an error relative to |H| is unbounded for either order.

``noise32``: single-precision normals are N(0, 1) draws of another generator path; their sample
moments are checked against the normal's with tolerances from the sample size.
"""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.phy.channel import (Links, apply_frequency, delay_groups, draw_grid_noise_on,
                                    draw_noise, frequency_response, grouped_frequency_response,
                                    standard_normals, subcarrier_frequencies, symbol_times)
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.phy.nr.ofdm import OFDM
from veriloc_rt.phy.transmitter import PRSTransmitter
from veriloc_rt.propagation.cir import ula_element_positions
from veriloc_rt.propagation.uma import uma_cir

#: |grouped - path by path| per entry, relative to sum_p |g_ap| (module doc: float64 rounding of
#: sums of ~400 terms is ~1e-13 of that scale)
GROUPED_RTOL = 1e-12


@pytest.fixture(scope="module")
def uma_links():
    """Three TR 38.901 UMa fast-fading links to a moving 4-element UE (LoS and NLoS, with
    sub-clusters): ~20 clusters of 20 rays, each ray a path."""
    fc = 3.5e9
    ep = ula_element_positions(4, 0.5 * 299_792_458.0 / fc, 0.3)
    bs = np.array([[[200.0, 50.0, 25.0], [-150.0, 120.0, 25.0], [40.0, -300.0, 25.0]]])
    cir = uma_cir(bs, np.array([[0.0, 0.0, 1.5]]), np.array([[10.0, 5.0, 0.0]]),
                  np.zeros((1, 3, 3)), np.array([[0, 1, 2]]), fc, ep, np.random.default_rng(7),
                  "fast_fading", los_state=np.array([[True, False, False]]))
    return Links.from_cir(cir, 0)


def test_uma_rays_share_few_delays(uma_links):
    """delay_groups: every valid path once, ordered by delay, each run of equal delays one group;
    a UMa link has ~20-30 distinct delays for its hundreds of rays (the shortcut's premise)."""
    for li in range(uma_links.num_links):
        d, v = uma_links.delays[li], uma_links.valid[li]
        taus, paths, starts = delay_groups(d, v)
        np.testing.assert_array_equal(np.sort(paths), np.flatnonzero(v))
        np.testing.assert_array_equal(taus, np.unique(d[v]))        # second method: np.unique
        np.testing.assert_array_equal(d[paths][starts], taus)
        ends = np.append(starts[1:], paths.size)
        for u in range(taus.size):
            assert np.all(d[paths[starts[u]:ends[u]]] == taus[u])
        assert paths.size >= 200 and taus.size <= paths.size // 8, (paths.size, taus.size)


def test_grouped_response_equals_the_ray_by_ray_sum(uma_links):
    """The response over distinct delays equals the path-by-path sum within GROUPED_RTOL of
    sum_p |g_ap| (module doc), on every subcarrier of a 624-subcarrier carrier and the symbol
    times of two slots; the rounding does move (not the same bits)."""
    ofdm = OFDM(NRConfig(slots_per_frame=2))
    t0 = float(uma_links.first_delay()[0]) - 0.25e-6
    f = subcarrier_frequencies(ofdm)
    t = symbol_times(ofdm, range(2), t0).ravel()
    ref = frequency_response(uma_links, f, t, t0)
    got = frequency_response(uma_links, f, t, t0, grouped=True)
    scale = np.sum(np.abs(uma_links.gains), axis=-1)[:, :, None, None]    # [L, A, 1, 1]
    err = np.abs(got - ref) / scale
    assert err.max() <= GROUPED_RTOL, err.max()
    assert not np.array_equal(got, ref)
    np.testing.assert_array_equal(got, grouped_frequency_response(uma_links, f, t, t0))


def test_grouped_response_without_shared_delays_is_the_reference_to_the_bit():
    """Paths with distinct delays (ray-traced links) are not regrouped: the reference's bits."""
    rng = np.random.default_rng(2)
    links = Links(1e-6 + rng.uniform(0, 2e-6, (2, 6)),
                  rng.standard_normal((2, 3, 6)) + 1j * rng.standard_normal((2, 3, 6)),
                  rng.uniform(-150, 150, (2, 6)), np.ones((2, 6), dtype=bool))
    f = np.linspace(-5e6, 5e6, 50)
    t = np.linspace(1e-3, 2e-3, 7)
    ref = frequency_response(links, f, t, 0.9e-6)
    np.testing.assert_array_equal(frequency_response(links, f, t, 0.9e-6, grouped=True).view(np.int64),
                                  ref.view(np.int64))


def test_apply_frequency_follows_the_delays_switch(uma_links, monkeypatch):
    """apply_frequency sums over distinct delays by default and path by path when
    VERILOC_RT_REFERENCE names ``delays`` (or ``all``): the reference's bits, against the
    per-RE product of frequency_response (second method); the default within GROUPED_RTOL of
    the reference, relative to the received grid's scale (amplitude x sum_p |g_ap| x |X|)."""
    nr = NRConfig(slots_per_frame=2)
    ofdm = OFDM(nr)
    slots = range(2)
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="none"), (1, 2, 3))
    grids = tx(0, slots)
    amps = np.array([1.0, 0.5, 2.0])
    t0 = float(np.nanmin(uma_links.first_delay())) - 0.25e-6
    monkeypatch.setenv("VERILOC_RT_REFERENCE", "delays,jitchannel")   # (the reference's products)
    ref = apply_frequency(uma_links, grids, amps, ofdm, slots, t0)
    t = symbol_times(ofdm, slots, t0).ravel()
    h = frequency_response(uma_links, subcarrier_frequencies(ofdm), t, t0)
    want = np.einsum("l,latk,ltk->atk", amps, h, grids.reshape(3, t.size, -1)).reshape(ref.shape)
    np.testing.assert_allclose(ref, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    monkeypatch.setenv("VERILOC_RT_REFERENCE", "all")
    np.testing.assert_array_equal(apply_frequency(uma_links, grids, amps, ofdm, slots, t0), ref)
    monkeypatch.setenv("VERILOC_RT_REFERENCE", "jitchannel")
    got = apply_frequency(uma_links, grids, amps, ofdm, slots, t0)
    scale = np.sum(amps * np.sum(np.abs(uma_links.gains), axis=-1).max(axis=-1)) * np.abs(grids).max()
    assert np.abs(got - ref).max() <= GROUPED_RTOL * scale
    assert not np.array_equal(got, ref)


def test_single_precision_normals_are_standard_normal():
    """standard_normals(single=True): complex128, real and imaginary parts N(0, scale^2). With
    n = 4e5 draws per part: the sample mean's standard error is scale / sqrt(n) (bound 5 of
    them), the variance's sqrt(2 / n) relative (bound 5), the correlation of the parts
    1 / sqrt(n) (bound 5); the fourth moment (3 for a normal) has standard error
    sqrt(96 / n) = 0.015 (bound 0.08). The float64 path keeps its draws: the same numbers as
    Generator.standard_normal (the reference)."""
    n, scale = 400_000, 0.7
    z = standard_normals(np.random.default_rng(5), n, scale, single=True)
    assert z.dtype == np.complex128 and z.shape == (n,)
    for part in (z.real / scale, z.imag / scale):
        assert abs(part.mean()) < 5 / np.sqrt(n)
        assert abs(part.var() - 1.0) < 5 * np.sqrt(2.0 / n)
        assert abs(np.mean(part ** 4) - 3.0) < 0.08
    assert abs(np.corrcoef(z.real, z.imag)[0, 1]) < 5 / np.sqrt(n)
    # the draws are the float32 ziggurat's, scaled exactly in float64
    z32 = np.random.default_rng(5).standard_normal((n, 2), dtype=np.float32)
    np.testing.assert_array_equal(z.real, z32[:, 0].astype(np.float64) * scale)
    ref = standard_normals(np.random.default_rng(5), 10, scale)
    np.testing.assert_array_equal(ref, np.random.default_rng(5).standard_normal((10, 2)).view(np.complex128)[:, 0] * scale)


def test_single_precision_grid_noise_keeps_the_layout():
    """draw_noise and draw_grid_noise_on with single=True: the reference's layout (noise only on
    the read REs, slot-major draws: the first slots' noise does not depend on the number of
    slots, and every RE read gives draw_noise's values) and variance (2e4 read REs: the
    sample variance within 5 standard errors, sqrt(1 / n) relative)."""
    shape = (2, 3, 14, 48)
    rng = np.random.default_rng(8)
    read = rng.uniform(size=(3, 14, 48)) < 0.5
    var = 3.0
    g = draw_grid_noise_on(shape, read, var, np.random.default_rng(1), single=True)
    assert np.all(g[:, ~read] == 0) and np.all(g[:, read] != 0)
    part = draw_grid_noise_on((2, 2, 14, 48), read, var, np.random.default_rng(1), single=True)
    np.testing.assert_array_equal(part, g[:, :2])
    full = draw_grid_noise_on(shape, np.ones((3, 14, 48), bool), var, np.random.default_rng(1), single=True)
    np.testing.assert_array_equal(full, draw_noise(shape, var, np.random.default_rng(1), 1, single=True))
    big = draw_noise((4, 10, 14, 48), var, np.random.default_rng(2), 1, single=True)
    m = big.size
    assert abs(np.mean(np.abs(big) ** 2) / var - 1.0) < 5 / np.sqrt(m)


def test_the_ue_noise_follows_the_noise32_switch(monkeypatch):
    """KeptWhiteNoise.add_on_read with single=True adds draw_grid_noise_on's single-precision
    draws (second method: the function called directly), with single=False the reference's
    (float64) draws; a kept draw of one precision is not handed to a call of the other. The
    downlink channel asks for single precision unless VERILOC_RT_REFERENCE names noise32 (or
    all) when it is built; the other shortcuts' names leave it on."""
    from veriloc_rt.config.channel import ChannelConfig
    from veriloc_rt.phy.chain.downlink import DownlinkChannel
    from veriloc_rt.phy.noise import KeptWhiteNoise
    from veriloc_rt.phy.shortcuts import ENV, SHORTCUTS, reference

    shape = (2, 2, 14, 24)
    x = np.full(shape, 0.5 + 0.25j)
    read = np.random.default_rng(3).uniform(size=shape[1:]) < 0.4
    src = KeptWhiteNoise()
    got32 = src.add_on_read(x, 2.0, np.random.default_rng(4), read, True)
    np.testing.assert_array_equal(got32, draw_grid_noise_on(shape, read, 2.0, np.random.default_rng(4), True) + x)
    got64 = src.add_on_read(x, 2.0, np.random.default_rng(4), read, False)
    np.testing.assert_array_equal(got64, draw_grid_noise_on(shape, read, 2.0, np.random.default_rng(4)) + x)
    assert not np.array_equal(got32, got64)
    assert set(SHORTCUTS) >= {"noise", "delays", "noise32"}
    ofdm = OFDM(NRConfig(slots_per_frame=2))
    for env, single in ((None, True), ("noise,delays", True), ("noise32", False), ("all", False)):
        if env is None:
            monkeypatch.delenv(ENV, raising=False)
        else:
            monkeypatch.setenv(ENV, env)
        assert reference("noise32") is not single
        ch = DownlinkChannel(ChannelConfig(), ofdm, range(2), 1.0, 0, 1, src, 1.0)
        assert ch.single_noise is single


@pytest.mark.parametrize("single", [False, True])
def test_grid_noise_on_a_kept_mask_equals_the_boolean_scatter(single):
    """draw_grid_noise_on scatters by flat indices (kept for a read-only mask): the same bits as
    a boolean scatter of the same draws (second method, written out here), for a writeable
    mask, a read-only one (twice: the kept indices) and a read-only view of its first slots."""
    shape = (3, 4, 14, 36)
    read = np.random.default_rng(6).uniform(size=(5, 14, 36)) < 0.3
    frozen = read.copy()
    frozen.flags.writeable = False
    scale = np.sqrt(1.5 / 2.0)
    mask = np.broadcast_to(read[:4, None], (4, 3, 14, 36))
    want = np.zeros((4, 3, 14, 36), dtype=np.complex128)
    want[mask] = standard_normals(np.random.default_rng(9), int(mask.sum()), scale, single)
    want = np.moveaxis(want, 0, 1)
    for r in (read, frozen, frozen, frozen[:4]):
        got = draw_grid_noise_on(shape, r, 1.5, np.random.default_rng(9), single)
        assert got.tobytes() == np.ascontiguousarray(want).tobytes()
