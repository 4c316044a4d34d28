"""PRS of more TRPs than one slot holds (TS 38.211 7.4.1.7, TS 38.214 5.1.6.1 slot offsets),
against an independent derivation written from the clauses: every RE of every slot of the
transmitter's grids for 9 TRPs (comb 6 with tags, three slot groups) and 12 TRPs (comb 12
without tags, one group)."""

import numpy as np
import pytest

from .nr_oracles import gold_reference
from veriloc_rt.config import config_from_dict
from veriloc_rt.phy.nr.prs import SYMBOLS_PER_SLOT
from veriloc_rt.phy.security.keys import simulated_keys
from veriloc_rt.phy.transmitter import PRSTransmitter

#: TS 38.211 Table 7.4.1.7.3-1, k' per symbol l - l_start, written out here (not read from the
#: package's data file)
K_PRIME = {6: [0, 3, 1, 4, 2, 5] * 2, 12: [0, 6, 3, 9, 1, 7, 4, 10, 2, 8, 5, 11]}


def expected_prs(n_id, k_offset, comb, slot, l, k_count) -> dict[int, complex]:
    """RE k -> r(m) of one PRS symbol: c_init of 7.4.1.7.2, QPSK of 5.1.3, k of 7.4.1.7.3."""
    c_init = (2**22 * (n_id // 1024) + 2**10 * (14 * slot + l + 1) * (2 * (n_id % 1024) + 1)
              + n_id % 1024) % 2**31
    n = k_count // comb
    c = np.array(gold_reference(c_init, 2 * n))
    r = ((1 - 2 * c[0::2]) + 1j * (1 - 2 * c[1::2])) / np.sqrt(2)
    return {m * comb + (k_offset + K_PRIME[comb][l]) % comb: r[m] for m in range(n)}


def slots_of(i: int, n: int, per_slot: int, t_rep: int, num_slots: int = 10) -> list[int]:
    """Slots of TRP i of n by TS 38.211 7.4.1.7.4's condition, a DL PRS resource occupies slot
    n_s of frame n_f when (n_f N_slot + n_s - T_offset - T_offset,res) mod T_per = i' T_gap for
    some i' < T_rep (the condition as OpenAirInterface's UE evaluates it). Here T_per is the
    frame (N_slot = num_slots, n_f = 0), T_offset = 0, T_gap = 1 and TRP i's resource has
    T_offset,res = (i // per_slot) T_rep; with one group (n <= per_slot) every slot."""
    if n <= per_slot:
        return list(range(num_slots))
    t_per, t_offset, t_gap, t_offset_res = num_slots, 0, 1, (i // per_slot) * t_rep
    return [s for s in range(num_slots)
            if (s - t_offset - t_offset_res) % t_per in {r * t_gap for r in range(t_rep)}]


@pytest.mark.parametrize("case", [
    # 9 TRPs, comb 6 with tags: 3 per slot, 3 groups, T_rep 2 (3 x 2 <= 10 < 3 x 4)
    dict(n=9, comb=6, tags="hmac", per_slot=3, t_rep=2,
         offsets=[0, 1, 2] * 3),
    # 12 TRPs, comb 12 without tags: all in one slot, every slot
    dict(n=12, comb=12, tags="none", per_slot=12, t_rep=10, offsets=list(range(12))),
])
def test_grids_of_many_trps_match_the_clauses(case):
    n, comb = case["n"], case["comb"]
    cfg = config_from_dict({"topology": {"num_trps": n},
                            "nr": {"comb": comb, "num_prb": 24},
                            "security": {"tag_scheme": case["tags"]}})
    nr = cfg.nr
    assert list(nr.comb_offsets) == case["offsets"]
    keys = simulated_keys(range(n), np.random.default_rng(0))
    tx = PRSTransmitter(nr, cfg.security, list(range(n)), keys)
    grids = tx(frame=5)                                    # [n, 10, 14, 288]
    k_count = nr.num_subcarriers
    half = comb // 2
    total = np.zeros(grids.shape[1:], dtype=int)
    for i in range(n):
        own = slots_of(i, n, case["per_slot"], case["t_rep"])
        for s in range(10):
            g = grids[i, s]
            if s not in own:
                assert not np.any(g), (i, s)
                continue
            for l in range(SYMBOLS_PER_SLOT):
                if l >= 12:
                    assert not np.any(g[l])
                    continue
                want = expected_prs(nr.prs_ids[i], case["offsets"][i], comb, s, l, k_count)
                ks = np.array(sorted(want))
                np.testing.assert_allclose(g[l, ks], [want[k] for k in ks], atol=1e-12)
                tag_k = np.arange((case["offsets"][i] + half + K_PRIME[comb][l]) % comb, k_count,
                                  comb)
                rest = np.setdiff1d(np.arange(k_count), ks)
                if case["tags"] != "none":
                    assert np.all(g[l, tag_k] != 0)                # the tag follows, own slots
                    rest = np.setdiff1d(rest, tag_k)
                assert not np.any(g[l, rest])
        total += grids[i] != 0
    assert total.max() == 1                                # no RE carries two TRPs
    # the replica each receiver correlates with is the PRS part of the same grid
    for i in (0, n - 1):
        rep = tx.replica(i, 5)
        prs = np.zeros_like(rep, dtype=bool)
        own = slots_of(i, n, case["per_slot"], case["t_rep"])
        for s in own:
            for l in range(12):
                prs[s, l, sorted(expected_prs(nr.prs_ids[i], case["offsets"][i], comb, s, l,
                                              k_count))] = True
        np.testing.assert_array_equal(rep != 0, prs)
        np.testing.assert_array_equal(rep[prs], grids[i][prs])
        # occupied() marks exactly these REs (the receiver reads only them)
        _, reps = tx.occupied()
        np.testing.assert_array_equal(reps[i], prs)
