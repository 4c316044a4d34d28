"""veriloc_rt.phy.channel_kernels against the NumPy code they replace.

Exact kernels (placements, additions, real products) are compared bit for bit (``view(int64)``:
signed zeros included) on the arrays the chain gives them: a PRS transmitter's grids, masks and
RE plans.
"""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.config.nr import NRConfig
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.phy import channel_kernels as ck
from veriloc_rt.phy.channel import (Links, REPlan, apply_frequency, frequency_response,
                                    occupancy_groups, subcarrier_frequencies, symbol_times)
from veriloc_rt.phy.nr.ofdm import OFDM
from veriloc_rt.phy.transmitter import PRSTransmitter


@pytest.fixture(scope="module")
def prs():
    """Three TRPs' comb-6 PRS with HMAC tags on 2 slots of a 624-subcarrier carrier: grids
    [3, 2, 14, 624] complex128 and their masks."""
    from veriloc_rt.phy.security.keys import simulated_keys

    nr = NRConfig(slots_per_frame=2)
    keys = simulated_keys((1, 2, 3), np.random.default_rng(0))
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme="hmac"), (1, 2, 3), keys)
    return tx(0, range(2)), tx.occupied(range(2))[0]


def _bits(a):
    return np.ascontiguousarray(a).view(np.int64)


def test_scatter_add_is_numpys_indexed_add(prs):
    """scatter_add on a TRP's RE plan: the bits of ``flat[:, idx] += v``, into zeros (the first
    link: 0 + v, which makes -0.0 entries of v +0.0) and into a grid already holding another
    link's values (the REs two TRPs share)."""
    grids, occ = prs
    rng = np.random.default_rng(1)
    plan = REPlan(occupancy_groups(occ[0].reshape(28, -1)), 624)
    n = plan.index.size
    v = rng.standard_normal((4, n)) + 1j * rng.standard_normal((4, n))
    v[:, :7] = -0.0                       # signed zeros: 0 + (-0) is +0
    for start in (np.zeros((4, 28 * 624), complex),
                  rng.standard_normal((4, 28 * 624)) + 1j * rng.standard_normal((4, 28 * 624))):
        want = start.copy()
        want[:, plan.index] += v
        got = start.copy()
        ck.scatter_add(got, plan.index, v)
        np.testing.assert_array_equal(_bits(got), _bits(want))


#: |fused - reference| per RE of apply_frequency, relative to sum_l |a_l H_l X_l| there: each
#: term is a product of 3-4 rounded factors (eps = 2.2e-16 each; NumPy's complex product fuses
#: a multiply and an add, the kernels' does not), and the sum over the 1-4 links adds one
#: rounding each: ~10 eps at most; 1e-14 leaves a factor 4
JIT_RTOL = 1e-14


def _links(rng, num_links, num_paths, num_ant, distinct=True):
    delays = 1e-6 + rng.uniform(0, 2e-6, (num_links, num_paths))
    if not distinct:   # each link's paths share one delay (one cluster): U = 1
        delays[:] = delays[:, :1]
    gains = rng.standard_normal((num_links, num_ant, num_paths)) + 1j * rng.standard_normal(
        (num_links, num_ant, num_paths))
    return Links(delays, gains, rng.uniform(-150, 150, (num_links, num_paths)),
                 np.ones((num_links, num_paths), dtype=bool))


def _scale(links, grids, amps, ofdm, slots, t0):
    """sum_l |a_l H_l X_l| per RE (the reference's terms, by frequency_response)."""
    t = symbol_times(ofdm, slots, t0).ravel()
    h = frequency_response(links, subcarrier_frequencies(ofdm), t, t0)
    terms = np.abs(amps[:, None, None, None] * h * grids.reshape(len(amps), 1, t.size, -1))
    return terms.sum(axis=0).reshape((links.num_ant,) + grids.shape[1:])


@pytest.mark.parametrize("num_paths, distinct", [(1, True), (3, False), (3, True)],
                         ids=["one-path", "one-delay", "three-delays"])
def test_fused_apply_frequency_against_the_reference(prs, monkeypatch, num_paths, distinct):
    """apply_frequency with the shortcut jitchannel (default) against its reference path
    (``VERILOC_RT_REFERENCE=jitchannel``) within JIT_RTOL of sum_l |a_l H_l X_l|, on three
    TRPs' tagged PRS (sparse: each link's REs) and a jammer's dense grid (every RE; first and
    last, so both the write and the add into a grid are taken): links of one delay (one path,
    or three paths sharing it: the response formed RE by RE from its factors; not the
    reference's bits) and of three delays (FUSE_MAX_DELAYS exceeded: the reference path, its
    bits)."""
    from veriloc_rt.phy.channel import add_noise

    grids, occ = prs
    nr = NRConfig(slots_per_frame=2)
    ofdm, slots, t0 = OFDM(nr), range(2), 0.9e-6
    rng = np.random.default_rng(5)
    dense = add_noise(np.zeros((1,) + grids.shape[1:]), 1.0, rng)
    all_grids = np.concatenate([dense, grids, dense])
    all_occ = np.concatenate([np.ones_like(occ[:1]), occ, np.ones_like(occ[:1])])
    links = _links(rng, 5, num_paths, 4, distinct)
    amps = np.array([0.1, 1.0, 0.5, 2.0, 0.2])
    for given in (None, all_occ):
        monkeypatch.setenv("VERILOC_RT_REFERENCE", "jitchannel")
        ref = apply_frequency(links, all_grids, amps, ofdm, slots, t0, given)
        monkeypatch.delenv("VERILOC_RT_REFERENCE")
        got = apply_frequency(links, all_grids, amps, ofdm, slots, t0, given)
        err = np.abs(got - ref)
        bound = JIT_RTOL * _scale(links, all_grids, amps, ofdm, slots, t0)
        assert np.all(err <= bound), (err / np.maximum(bound, 1e-300)).max()
        if distinct and num_paths > 1:
            np.testing.assert_array_equal(_bits(got), _bits(ref))
        else:
            assert not np.array_equal(got, ref)
        # the sparse links alone: the first link of a grid is added into zeros
        monkeypatch.setenv("VERILOC_RT_REFERENCE", "jitchannel")
        sub = Links(links.delays[1:4], links.gains[1:4], links.doppler[1:4], links.valid[1:4])
        ref = apply_frequency(sub, grids, amps[1:4], ofdm, slots, t0, None if given is None else occ)
        monkeypatch.delenv("VERILOC_RT_REFERENCE")
        got = apply_frequency(sub, grids, amps[1:4], ofdm, slots, t0, None if given is None else occ)
        bound = JIT_RTOL * _scale(sub, grids, amps[1:4], ofdm, slots, t0)
        assert np.all(np.abs(got - ref) <= bound)
        assert np.all(got[:, ~np.any(occ, axis=0)] == 0)   # REs no TRP sends on stay 0


def test_fused_apply_frequency_without_paths_adds_nothing(prs):
    """A link without a valid path (H = 0) adds nothing; alone, the grid is zeros."""
    grids, occ = prs
    nr = NRConfig(slots_per_frame=2)
    links = _links(np.random.default_rng(6), 3, 2, 2)
    links = Links(links.delays, links.gains * 0, links.doppler, np.zeros((3, 2), dtype=bool))
    got = apply_frequency(links, grids, np.ones(3), OFDM(nr), range(2), 0.9e-6, occ)
    assert got.shape == (2,) + grids.shape[1:] and not np.any(got)


def test_the_reference_path_calls_no_fused_kernel(prs, monkeypatch):
    """VERILOC_RT_REFERENCE=jitchannel (or all) runs apply_frequency's NumPy products: the fused
    kernels, replaced by ones that raise, are not called; by default they are."""
    from veriloc_rt.phy import channel as ch

    def boom(*args):
        raise AssertionError("fused kernel called")

    for name in ("add_response", "add_response_on"):
        monkeypatch.setattr(ch, name, boom)
    grids, occ = prs
    nr = NRConfig(slots_per_frame=2)
    links = _links(np.random.default_rng(7), 3, 1, 2)
    for value in ("jitchannel", "all", "delays,jitchannel"):
        monkeypatch.setenv("VERILOC_RT_REFERENCE", value)
        apply_frequency(links, grids, np.ones(3), OFDM(nr), range(2), 0.9e-6, occ)
    monkeypatch.delenv("VERILOC_RT_REFERENCE")
    with pytest.raises(AssertionError, match="fused kernel called"):
        apply_frequency(links, grids, np.ones(3), OFDM(nr), range(2), 0.9e-6, occ)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_place_scaled_is_numpys_scaling_and_scatter(prs, dtype):
    """place_scaled: the bits of NumPy's scaling (float64 draws: the complex array times the
    scale in place, a complex product; float32: the float64 product of each part) scattered
    onto the read REs of a zeroed grid, on a chain's read mask (every TRP's PRS REs and two
    whole symbols, 5 antennas), signed zeros among the draws included; ``out`` is written
    everywhere (NaN before)."""
    _, occ = prs
    read = np.logical_or.reduce(occ)
    read[:, [3, 10]] = True
    idx = np.flatnonzero(np.broadcast_to(read[:, None], (2, 5) + read.shape[1:]))
    rng = np.random.default_rng(8)
    z = rng.standard_normal((idx.size, 2)).astype(dtype)
    z[:8] = [[0.0, 1.0], [-0.0, 1.0], [0.0, -1.0], [-0.0, -1.0], [1.0, 0.0], [1.0, -0.0],
             [-1.0, 0.0], [-1.0, -0.0]]
    scale = 0.37
    if dtype == np.float64:
        n = z.copy().view(np.complex128)[:, 0]
        n *= scale
    else:
        n = np.empty(idx.size, dtype=np.complex128)
        np.multiply(z, scale, out=n.view(np.float64).reshape(-1, 2), dtype=np.float64)
    want = np.zeros(2 * 5 * read[0].size, dtype=np.complex128)
    want[idx] = n
    got = np.full(want.shape, np.nan + 0j)
    ck.place_scaled(got, idx, z, scale, dtype == np.float64)
    np.testing.assert_array_equal(_bits(got), _bits(want))


@pytest.mark.parametrize("reference", ["", "jitchannel"], ids=["jitchannel", "reference"])
def test_apply_frequency_base_is_the_sum_then_the_base(prs, monkeypatch, reference):
    """apply_frequency(..., base=b): the bits of ``y = apply_frequency(...); y += b`` (how the
    downlink added an adversary's signal to the benign one) for one link of a jammer's dense
    grid (under jitchannel: add_response_base, the base added in the link's pass), one link of
    a TRP's sparse grid (add_response_on into ``base + 0``), three links, and a link without a
    path; signed zeros in the base and in the grid included; the base is left as it was and
    the result is a new array."""
    from veriloc_rt.phy import channel as ch
    from veriloc_rt.phy.channel import add_noise

    monkeypatch.setenv("VERILOC_RT_REFERENCE", reference)
    grids, occ = prs
    nr = NRConfig(slots_per_frame=2)
    ofdm, slots, t0 = OFDM(nr), range(2), 0.9e-6
    rng = np.random.default_rng(9)
    dense = add_noise(np.zeros((1,) + grids.shape[1:]), 1.0, rng)
    base = add_noise(np.zeros((4,) + grids.shape[1:]), 1e-3, rng)
    base.reshape(-1)[:6] = [-0.0, 0.0, -0.0 + 0j, complex(-0.0, -0.0), 1.0, complex(0.0, -0.0)]
    base.flags.writeable = False
    one = _links(rng, 1, 1, 4)
    three = _links(rng, 3, 1, 4)
    none = Links(one.delays, one.gains * 0, one.doppler, np.zeros((1, 1), dtype=bool))
    calls = []
    kernel = ch.add_response_base
    monkeypatch.setattr(ch, "add_response_base", lambda *a: calls.append(1) or kernel(*a))
    # signed zeros where they meet: a base of -0 everywhere, and a sparse grid with -0 on some
    # of its REs (the link's product there -0 or +0)
    zeros = np.full(base.shape, complex(-0.0, -0.0))
    zeros.flags.writeable = False
    holed = grids[:1].copy()
    holed[occ[:1]] = np.where(np.arange(np.count_nonzero(occ[:1])) % 7 == 0, -0.0,
                              holed[occ[:1]])
    cases = [(one, dense, None, base), (one, dense, np.ones_like(occ[:1]), base),
             (one, grids[:1], occ[:1], base), (one, holed, occ[:1], zeros),
             (one, dense, None, zeros), (three, grids, occ, base), (none, dense, None, base)]
    for links, x, given, b in cases:
        want = apply_frequency(links, x, np.full(links.num_links, 0.7), ofdm, slots, t0, given)
        want += b
        got = apply_frequency(links, x, np.full(links.num_links, 0.7), ofdm, slots, t0, given,
                              base=b)
        assert got is not b and not np.shares_memory(got, b)
        np.testing.assert_array_equal(_bits(got), _bits(want))
    # the three dense one-link cases by the fused kernel, unless the reference path is asked for
    assert len(calls) == (0 if reference else 3)
    with pytest.raises(ValueError, match="base"):
        apply_frequency(one, dense, [1.0], ofdm, slots, t0, None, base=base[:2])
