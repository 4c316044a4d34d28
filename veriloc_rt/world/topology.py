"""Hexagonal BS layout and serving-set selection.

Cells are the hexagons of a honeycomb whose centres form a triangular lattice with spacing
``isd`` (the inter-site distance); the hexagon side is ``isd / sqrt(3)`` (289 m at 500 m).
Each hexagon has BSs at three alternate vertices (polar angles 30, 150 and 270 degrees from its
centre, before rotation). Those vertices form a triangular lattice of their own with spacing
``isd``, and each BS is shared by the three cells around it. A UE is served by the three BSs of
the cell (hexagon) that holds it (``topology.selection`` 'cell'), or by its ``num_trps`` nearest
sites (:meth:`HexLayout.nearest`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import TopologyConfig

_VERTEX_ANGLES = np.deg2rad([30.0, 150.0, 270.0])


@dataclass(frozen=True)
class HexLayout:
    """One realisation of the layout.

    offset : [2] float64, m (centre of cell (0, 0)); rotation : float, rad
    """

    isd: float
    bs_height: float
    offset: np.ndarray
    rotation: float

    @property
    def side(self) -> float:
        """Hexagon side [m]."""
        return self.isd / math.sqrt(3.0)

    def _basis(self) -> np.ndarray:
        c, s = math.cos(self.rotation), math.sin(self.rotation)
        rot = np.array([[c, -s], [s, c]])
        a1 = np.array([self.isd, 0.0])
        a2 = np.array([self.isd / 2.0, self.isd * math.sqrt(3.0) / 2.0])
        return rot @ np.stack([a1, a2], axis=1)  # columns: lattice vectors

    def cell_of(self, xy: np.ndarray) -> np.ndarray:
        """Integer lattice index (i, j) of the cell holding each point (nearest centre).

        :param xy: [num_points, 2] float64, m
        :returns: [num_points, 2] int64
        """
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        basis = self._basis()
        frac = np.linalg.solve(basis, (xy - self.offset).T).T  # lattice coordinates
        base = np.floor(frac).astype(np.int64)
        best = np.zeros_like(base)
        best_d = np.full(len(xy), np.inf)
        for di in (-1, 0, 1, 2):
            for dj in (-1, 0, 1, 2):
                cand = base + np.array([di, dj])
                centre = cand @ basis.T + self.offset
                d = np.sum((xy - centre) ** 2, axis=1)
                better = d < best_d
                best[better], best_d[better] = cand[better], d[better]
        return best

    def cell_centre(self, ij: np.ndarray) -> np.ndarray:
        """[..., 2] int -> [..., 2] float64 centres, m."""
        return np.asarray(ij) @ self._basis().T + self.offset

    def cell_bs_positions(self, ij: np.ndarray) -> np.ndarray:
        """Positions of the three BSs of each cell.

        :returns: [num_points, 3, 3] float64, m
        """
        centre = self.cell_centre(np.asarray(ij).reshape(-1, 2))
        ang = _VERTEX_ANGLES + self.rotation
        verts = centre[:, None, :] + self.side * np.stack([np.cos(ang), np.sin(ang)], -1)[None]
        z = np.full(verts.shape[:2] + (1,), self.bs_height)
        return np.concatenate([verts, z], axis=-1)

    def serving(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Serving BSs along a path, with BS ids shared across cells.

        :param xy: [num_points, 2] float64, m
        :returns: (bs_pos [num_bs, 3] float64 m, serving [num_points, 3] int64 ids into bs_pos),
            BS ids in order of first use
        """
        cells = self.cell_of(xy)
        pos = self.cell_bs_positions(cells)  # [P, 3, 3]
        keys = np.round(pos[..., :2] / (self.side * 1e-3)).astype(np.int64)  # mm-level key
        ids: dict[tuple[int, int], int] = {}
        serving = np.empty(pos.shape[:2], dtype=np.int64)
        bs = []
        for k in range(pos.shape[0]):
            for j in range(3):
                key = (int(keys[k, j, 0]), int(keys[k, j, 1]))
                if key not in ids:
                    ids[key] = len(bs)
                    bs.append(pos[k, j])
                serving[k, j] = ids[key]
        return np.array(bs, dtype=float).reshape(-1, 3), serving


    def nearest(self, xy: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The ``n`` BS sites nearest each point (2-D distance to the millimetre; ties broken by
        the site's position, x then y), nearest first, with BS ids shared across points as :meth:`serving`
        numbers them (in order of first use).

        The sites are the vertices of every cell near the point: the cells within ``reach``
        lattice steps of the point's cell hold more than ``n`` sites at every distance up to
        the ``n``-th nearest (a disc of radius r holds about 2 pi r^2 / (sqrt(3) isd^2) sites).

        :param xy: [num_points, 2] float64, m
        :returns: (bs_pos [num_bs, 3] float64 m, serving [num_points, n] int64 ids into bs_pos)
        """
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        reach = int(math.ceil(math.sqrt(n))) + 2
        d = np.arange(-reach, reach + 1)
        window = np.stack(np.meshgrid(d, d, indexing="ij"), -1).reshape(-1, 2)   # [C, 2]
        cells = self.cell_of(xy)
        unit = self.side * 1e-3                                    # site keys as in serving()
        ids: dict[tuple[int, int], int] = {}
        bs: list[np.ndarray] = []
        serving = np.empty((len(xy), n), dtype=np.int64)
        for k in range(len(xy)):
            pos = self.cell_bs_positions(cells[k] + window).reshape(-1, 3)
            keys, first = np.unique(np.round(pos[:, :2] / unit).astype(np.int64), axis=0,
                                    return_index=True)
            pos = pos[first]
            dist = np.linalg.norm(pos[:, :2] - xy[k], axis=1)
            order = np.lexsort((keys[:, 1], keys[:, 0], np.round(dist * 1e3)))[:n]   # ties: mm
            for j, o in enumerate(order):
                key = (int(keys[o, 0]), int(keys[o, 1]))
                if key not in ids:
                    ids[key] = len(bs)
                    bs.append(pos[o])
                serving[k, j] = ids[key]
        return np.array(bs, dtype=float).reshape(-1, 3), serving


def hex_layout(cfg: TopologyConfig, rng: np.random.Generator) -> HexLayout:
    """Layout for one Monte Carlo iteration: random offset (uniform over a cell's lattice
    parallelogram) and rotation (uniform in [0, 60) degrees, the lattice's symmetry) from ``rng``
    when ``cfg.random_offset``; otherwise a cell centred at the origin, unrotated."""
    if not cfg.random_offset:
        return HexLayout(cfg.isd_m, cfg.bs_height_m, np.zeros(2), 0.0)
    rotation = float(rng.uniform(0.0, math.pi / 3.0))
    u, v = rng.uniform(0.0, 1.0, 2)
    layout = HexLayout(cfg.isd_m, cfg.bs_height_m, np.zeros(2), rotation)
    offset = layout._basis() @ np.array([u, v])
    return HexLayout(cfg.isd_m, cfg.bs_height_m, offset, rotation)
