"""The tag channel estimate is kept by the values it reads (a BS's PRS REs of the slot grid and
of its replica): a grid that differs elsewhere (another chain's tags) gets the kept estimate,
which must be the estimate computed afresh, bit for bit; a grid that differs on one pilot
gets its own."""

import numpy as np

from veriloc_rt.config.nr import NRConfig
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.phy.receiver.tag_verifier import ESTIMATES_KEPT, estimate_tag_channel
from veriloc_rt.phy.security.keys import simulated_keys
from veriloc_rt.phy.transmitter import PRSTransmitter

BS_IDS = (21, 22, 23)


def test_estimate_kept_by_the_pilot_values_is_the_fresh_one():
    keys = simulated_keys(BS_IDS, np.random.default_rng(7))
    tx = {s: PRSTransmitter(NRConfig(), SecurityConfig(tag_scheme=s), BS_IDS, keys) for s in ("hmac", "ds")}
    lay = tx["hmac"].layout
    k = np.arange(624)
    h = 0.8 * np.exp(1j * 2.0 - 2j * np.pi * k * 15e3 * 1.3e-6)
    rng = np.random.default_rng(12)
    noise = np.sqrt(0.2) * (rng.standard_normal((14, 624)) + 1j * rng.standard_normal((14, 624)))
    # the same slot with HMAC tags and with signatures: the same PRS REs, other tag REs
    y = {s: t(frame=5, slots=[3]).sum(axis=0)[0] * h + noise for s, t in tx.items()}
    bs = 1
    tags = lay.tag_mask(bs)
    assert not np.array_equal(y["hmac"][tags], y["ds"][tags])
    rep = tx["hmac"].replica(bs, 5, [3])[0]
    h1, nv1 = estimate_tag_channel(y["hmac"], lay, bs, rep)
    h1[:] = 0.0                                   # the caller's copy: the kept one is untouched
    h2, nv2 = estimate_tag_channel(y["ds"], lay, bs, rep)      # kept (the same pilot values)
    # flush the store with other inputs, then compute the same estimate afresh
    for i in range(ESTIMATES_KEPT + 2):
        estimate_tag_channel((1.0 + i) * y["ds"], lay, bs, rep)
    h3, nv3 = estimate_tag_channel(y["ds"], lay, bs, rep)
    np.testing.assert_array_equal(h2, h3)
    assert nv2 == nv3 == nv1
    assert np.any(h3 != 0)
    # one pilot changed: another estimate
    y4 = y["ds"].copy()
    l0, k0 = lay.symbols[0], lay.prs_subcarriers(bs)[0, 0]
    y4[l0, k0] += 1.0
    h4, nv4 = estimate_tag_channel(y4, lay, bs, rep)
    assert nv4 != nv3 and not np.array_equal(h4, h3)
