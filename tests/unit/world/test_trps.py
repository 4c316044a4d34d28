"""N TRPs per point: the num_trps nearest sites of the layout (the brute-force nearest of the
BS lattice), the cell's three under the default selection with three TRPs."""

import math

import numpy as np
import pytest

from veriloc_rt.config import TopologyConfig
from veriloc_rt.world.sites import nearest_serving
from veriloc_rt.world.topology import hex_layout
from veriloc_rt.errors import InputError

#: distances are compared to the millimetre the layout keys its sites by
MM = 1e-3


@pytest.fixture
def layout():
    return hex_layout(TopologyConfig(), np.random.default_rng(11))


def _lattice_sites(layout, reach=14):
    """Every BS of the cells within ``reach`` lattice steps of cell (0, 0), deduplicated."""
    d = np.arange(-reach, reach + 1)
    ij = np.stack(np.meshgrid(d, d, indexing="ij"), -1).reshape(-1, 2)
    pos = layout.cell_bs_positions(ij).reshape(-1, 3)
    _, first = np.unique(np.round(pos[:, :2] / MM).astype(np.int64), axis=0, return_index=True)
    return pos[first]


@pytest.mark.parametrize("n", [3, 6, 9, 18])
def test_nearest_sites_match_brute_force(layout, n):
    pts = np.random.default_rng(n).uniform(-700, 700, (300, 2))
    bs, serving = layout.nearest(pts, n)
    assert serving.shape == (300, n)
    sites = _lattice_sites(layout)
    d_all = np.sort(np.linalg.norm(pts[:, None] - sites[None, :, :2], axis=2), axis=1)
    d_sel = np.linalg.norm(bs[serving][..., :2] - pts[:, None], axis=2)
    # the selected distances are the n smallest of the whole lattice, nearest first
    assert np.allclose(d_sel, d_all[:, :n], atol=MM)
    assert np.all(np.diff(d_sel, axis=1) >= -MM)
    # n distinct sites per point, each a lattice site (spacing ISD from its nearest neighbour)
    assert all(len(set(row)) == n for row in serving.tolist())
    nn = np.sort(np.linalg.norm(bs[:, None, :2] - sites[None, :, :2], axis=2), axis=1)
    assert np.allclose(nn[:, 0], 0.0, atol=MM) and np.allclose(nn[:, 1], 500.0, atol=MM)


def test_auto_selection_is_the_cell_for_three():
    assert TopologyConfig().uses_cell
    assert not TopologyConfig(num_trps=4).uses_cell
    assert not TopologyConfig(selection="power").uses_cell


def test_nearest_three_is_not_cell_membership(layout):
    """Near a hexagon's empty vertex the three nearest sites are not the cell's three."""
    pts = np.random.default_rng(3).uniform(-700, 700, (2000, 2))
    _, cell = layout.serving(pts)
    bs_c, _ = layout.serving(pts)
    bs_n, near = layout.nearest(pts, 3)
    same = [set(map(tuple, np.round(bs_c[c, :2]))) == set(map(tuple, np.round(bs_n[m, :2])))
            for c, m in zip(cell, near)]
    assert 0.5 < np.mean(same) < 1.0


def test_sites_csv_too_few_sites():
    sites = np.array([[0, 0, 25], [100, 0, 25], [0, 100, 25], [100, 100, 25]], float)
    bs, serving, used = nearest_serving(sites, np.array([[10.0, 10.0]]), 4)
    assert serving.shape == (1, 4) and list(used) == [0, 1, 2, 3]
    with pytest.raises(InputError) as e:
        nearest_serving(sites, np.array([[10.0, 10.0]]), 5)
    assert e.value.field == "topology.num_trps"
