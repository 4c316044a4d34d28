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
from veriloc_rt.phy.channel import REPlan, occupancy_groups
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
