"""Hexagonal layout: serving BSs are alternate vertices of the hexagon that holds the UE."""

import math

import numpy as np
import pytest

from veriloc_rt.config import TopologyConfig
from veriloc_rt.world.topology import hex_layout


@pytest.fixture
def layout():
    return hex_layout(TopologyConfig(), np.random.default_rng(7))


def test_serving_bs_geometry(layout):
    pts = np.random.default_rng(1).uniform(-800, 800, (3000, 2))
    bs, serving = layout.serving(pts)
    side = 500.0 / math.sqrt(3.0)
    centres = layout.cell_centre(layout.cell_of(pts))
    for j in range(3):
        # each serving BS is a vertex of the UE's hexagon (distance = side from its centre)
        assert np.allclose(np.linalg.norm(bs[serving[:, j], :2] - centres, axis=1), side)
    # the three BSs form an equilateral triangle of side ISD
    for a, b in ((0, 1), (1, 2), (0, 2)):
        assert np.allclose(np.linalg.norm(bs[serving[:, a]] - bs[serving[:, b]], axis=1), 500.0)
    assert np.all(bs[:, 2] == 25.0)


def test_cell_is_the_nearest_centre(layout):
    pts = np.random.default_rng(2).uniform(-1500, 1500, (2000, 2))
    cells = layout.cell_of(pts)
    d_best = np.linalg.norm(pts - layout.cell_centre(cells), axis=1)
    ij = np.stack(np.meshgrid(np.arange(-8, 9), np.arange(-8, 9), indexing="ij"), -1).reshape(-1, 2)
    allc = layout.cell_centre(ij)
    brute = np.linalg.norm(pts[:, None] - allc[None], axis=2).min(1)
    assert np.allclose(d_best, brute)
    # a point in a hexagon of side s is never farther than s from its centre
    assert d_best.max() <= 500.0 / math.sqrt(3.0) + 1e-9


def test_bs_ids_are_shared_between_cells(layout):
    pts = np.random.default_rng(3).uniform(-600, 600, (4000, 2))
    bs, _ = layout.serving(pts)
    d = np.linalg.norm(bs[:, None, :2] - bs[None, :, :2], axis=2)
    off = d[~np.eye(len(bs), dtype=bool)]
    assert off.min() == pytest.approx(500.0)  # distinct BSs are at least one ISD apart


def test_same_seed_same_layout_and_offsets_vary():
    a = hex_layout(TopologyConfig(), np.random.default_rng(11))
    b = hex_layout(TopologyConfig(), np.random.default_rng(11))
    c = hex_layout(TopologyConfig(), np.random.default_rng(12))
    assert np.array_equal(a.offset, b.offset) and a.rotation == b.rotation
    assert not np.array_equal(a.offset, c.offset)
    assert 0.0 <= a.rotation < math.pi / 3
    fixed = hex_layout(TopologyConfig(random_offset=False), np.random.default_rng(0))
    assert np.array_equal(fixed.offset, [0.0, 0.0]) and fixed.rotation == 0.0
