"""RE layout of three BSs with comb 6 plus tags: no collisions, PRS where Table 7.4.1.7.3-1 says,
and the paper's comb-6 dispersion figure reproduced RE by RE."""

import numpy as np
import pytest

from veriloc_rt.errors import InputError
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.phy.nr.grid import ReLayout

# The paper's Fig. "PRS and signature dispersion", comb 6 (veriloc-paper.tex, tikz cell colours):
# row = subcarrier 0..5 (repeats every 6), column = OFDM symbol 0..11; Pi = PRS of BS i, Si = its tag.
PAPER_COMB6 = """
P1 S1 S3 P3 S2 P2 P1 S1 S3 P3 S2 P2
P2 S2 P1 S1 S3 P3 P2 S2 P1 S1 S3 P3
P3 S3 P2 S2 P1 S1 P3 S3 P2 S2 P1 S1
S1 P1 P3 S3 P2 S2 S1 P1 P3 S3 P2 S2
S2 P2 S1 P1 P3 S3 S2 P2 S1 P1 P3 S3
S3 P3 S2 P2 S1 P1 S3 P3 S2 P2 S1 P1
"""


def _paper_codes() -> np.ndarray:
    rows = [line.split() for line in PAPER_COMB6.strip().splitlines()]
    return np.array([[int(c[1]) * (1 if c[0] == "P" else -1) for c in row] for row in rows])


@pytest.fixture
def layout():
    return ReLayout.from_config(NRConfig(), tags=True)


def test_no_two_signals_share_an_re(layout):
    masks = [layout.prs_mask(b) for b in range(3)] + [layout.tag_mask(b) for b in range(3)]
    total = np.sum(masks, axis=0)
    assert total.max() == 1
    # comb 6 with 3 PRS + 3 tags fills all 12 PRS symbols completely, symbols 12, 13 stay empty
    assert np.all(total[:12] == 1) and np.all(total[12:] == 0)


def test_prs_res_follow_the_offset_table(layout):
    kp = [0, 3, 1, 4, 2, 5] * 2  # Table 7.4.1.7.3-1, comb 6
    for bs, off in enumerate((0, 1, 2)):
        mask = layout.prs_mask(bs)
        for l in range(12):
            expected = np.arange((off + kp[l]) % 6, 624, 6)
            np.testing.assert_array_equal(np.flatnonzero(mask[l]), expected)


def test_layout_reproduces_paper_dispersion_figure(layout):
    occ = layout.occupancy()
    figure = _paper_codes()
    for block in range(0, 624, 6):
        np.testing.assert_array_equal(occ[:12, block:block + 6].T, figure)


def test_without_tags_the_tag_res_stay_empty():
    lay = ReLayout.from_config(NRConfig(), tags=False)
    assert np.count_nonzero(lay.occupancy()) == 3 * 12 * 104
    with pytest.raises(ValueError):
        lay.tag_subcarriers(0)


@pytest.mark.parametrize("offsets", [(0, 3), (1, 4, 2)])
def test_tag_collision_is_an_input_error(offsets):
    # offset 3 is BS 0's tag comb (0 + 6/2)
    cfg = NRConfig(comb_offsets=offsets, prs_ids=tuple(range(len(offsets))))
    with pytest.raises(InputError, match="nr.comb_offsets"):
        ReLayout.from_config(cfg, tags=True)
    ReLayout.from_config(cfg, tags=False)  # fine without tags


def test_more_bs_than_a_slot_holds_take_slot_groups():
    # comb 4 with tags holds two BSs per slot: the third transmits in a second slot group;
    # T_rep = 4, the largest TS 38.214 repetition factor with 2 x T_rep <= 10 slots
    cfg = NRConfig(comb=4, comb_offsets=(0, 1, 2), num_symbols=12)
    lay = ReLayout.from_config(cfg, tags=True)
    assert lay.groups == (0, 0, 1) and lay.repetition == 4
    assert [s for s in range(10) if lay.transmits(2, s)] == [4, 5, 6, 7]
    assert [s for s in range(10) if lay.transmits(0, s)] == [0, 1, 2, 3]


def test_collision_within_a_slot_group_is_an_input_error():
    cfg = NRConfig(comb=4, comb_offsets=(0, 2), prs_ids=(0, 1), num_symbols=12)   # 0's tag is 2
    with pytest.raises(InputError, match="nr.comb_offsets"):
        ReLayout.from_config(cfg, tags=True)
