"""A mesh scene's buildings rasterised on a horizontal grid: where a UE at a given height is
blocked, and the roof height over each cell (for BS masts).

A cell is *blocked* when its centre lies under an odd number of building surfaces above the UE
height (inside a building, by the ray-parity rule of
:meth:`~veriloc_rt.world.scene.external.MeshScene.inside_building`) or when a building surface
crosses the horizontal plane at the UE height anywhere inside the cell (a wall, also one with no
roof over it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: largest number of (triangle, cell) pairs evaluated at once (bounds the temporaries)
_BATCH = 2_000_000


@dataclass(frozen=True, eq=False)
class FootprintGrid:
    """Cells of side ``res`` whose centres are ``origin + res * (i + 1/2, j + 1/2)``.

    blocked : [nx, ny] bool (building at the UE height)
    inside : [nx, ny] bool (centre under an odd number of building surfaces above the UE height)
    roof_z : [nx, ny] float64, m (highest building surface over the centre; -inf where none)
    """

    origin: np.ndarray
    res: float
    blocked: np.ndarray
    inside: np.ndarray
    roof_z: np.ndarray

    def centres(self, ij: np.ndarray) -> np.ndarray:
        """[..., 2] int cell indices -> [..., 2] float64 centres, m"""
        return self.origin + self.res * (np.asarray(ij) + 0.5)

    def index(self, xy: np.ndarray) -> np.ndarray:
        """[..., 2] float64, m -> [..., 2] int64 cell indices (not clipped)"""
        return np.floor((np.asarray(xy, dtype=float) - self.origin) / self.res).astype(np.int64)


def rasterize(triangles: np.ndarray, bounds: tuple[float, float, float, float], res: float,
              height: float) -> FootprintGrid:
    """Rasterise building triangles over ``bounds`` (x_min, y_min, x_max, y_max) at ``res``.

    :param triangles: [num_triangles, 3, 3] float64, m (buildings only, not the ground)
    :param height: the UE height, m
    """
    x0, y0, x1, y1 = bounds
    nx, ny = max(1, int(np.ceil((x1 - x0) / res))), max(1, int(np.ceil((y1 - y0) / res)))
    origin = np.array([x0, y0], dtype=float)
    count = np.zeros((nx, ny), dtype=np.int64)
    roof = np.full((nx, ny), -np.inf)
    tris = np.asarray(triangles, dtype=float).reshape(-1, 3, 3)
    _cover(tris, origin, res, nx, ny, height, count, roof)
    blocked = count % 2 == 1
    inside = blocked.copy()
    _mark_walls(tris, origin, res, nx, ny, height, blocked)
    return FootprintGrid(origin, res, blocked, inside, roof)


def _cover(tris, origin, res, nx, ny, height, count, roof) -> None:
    """For every non-vertical triangle, the cell centres it covers: count the crossings above
    ``height`` and keep the highest surface (barycentric test, half-open as in
    :func:`~veriloc_rt.world.scene.external._crossings_above`)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    det = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
    keep = np.abs(det) > 1e-12
    a, b, c, det = a[keep], b[keep], c[keep], det[keep]
    if not len(det):
        return
    xy = np.stack([a[:, :2], b[:, :2], c[:, :2]], axis=1)
    lo = np.clip(np.ceil((xy.min(axis=1) - origin) / res - 0.5).astype(np.int64), 0, [nx, ny])
    hi = np.clip(np.floor((xy.max(axis=1) - origin) / res - 0.5).astype(np.int64), -1,
                 [nx - 1, ny - 1])
    size = np.maximum(hi - lo + 1, 0)
    # triangles grouped by window size (powers of two), each group evaluated in batches
    win = np.maximum(1, 2 ** np.ceil(np.log2(np.maximum(size.max(axis=1), 1)))).astype(np.int64)
    for w in np.unique(win):
        sel = np.flatnonzero((win == w) & np.all(size > 0, axis=1))
        di, dj = np.meshgrid(np.arange(w), np.arange(w), indexing="ij")
        di, dj = di.ravel(), dj.ravel()
        step = max(1, _BATCH // (w * w))
        for start in range(0, len(sel), step):
            t = sel[start:start + step]
            i = lo[t, 0, None] + di
            j = lo[t, 1, None] + dj
            valid = (i <= hi[t, 0, None]) & (j <= hi[t, 1, None])
            px = origin[0] + res * (i + 0.5)
            py = origin[1] + res * (j + 0.5)
            at, bt, ct, dt = a[t, None, :], b[t, None, :], c[t, None, :], det[t, None]
            l1 = ((bt[..., 1] - ct[..., 1]) * (px - ct[..., 0])
                  + (ct[..., 0] - bt[..., 0]) * (py - ct[..., 1])) / dt
            l2 = ((ct[..., 1] - at[..., 1]) * (px - ct[..., 0])
                  + (at[..., 0] - ct[..., 0]) * (py - ct[..., 1])) / dt
            l3 = 1.0 - l1 - l2
            hit = valid & (l1 >= 0) & (l2 >= 0) & (l3 > 0)
            z = l1 * at[..., 2] + l2 * bt[..., 2] + l3 * ct[..., 2]
            ii, jj, zz = i[hit], j[hit], z[hit]
            np.add.at(count, (ii, jj), (zz > height).astype(np.int64))
            np.maximum.at(roof, (ii, jj), zz)


def _mark_walls(tris, origin, res, nx, ny, height, blocked) -> None:
    """Block every cell that a triangle's cut with the plane z = ``height`` passes through
    (the cut sampled every res / 4, plus both ends)."""
    d = tris[:, :, 2] - height
    cross = (d.min(axis=1) < 0) & (d.max(axis=1) > 0)
    t, dd = tris[cross], d[cross]
    if not len(t):
        return
    ends = []
    for i, j in ((0, 1), (1, 2), (2, 0)):
        di, dj = dd[:, i], dd[:, j]
        on = (di < 0) != (dj < 0)
        f = np.where(on, di / np.where(on, di - dj, 1.0), 0.0)
        p = t[:, i, :2] + f[:, None] * (t[:, j, :2] - t[:, i, :2])
        ends.append((on, p))
    # exactly two edges cross for a triangle straddling the plane (a vertex on it: one or two)
    first = np.where(ends[0][0][:, None], ends[0][1], ends[1][1])
    second = np.where(ends[2][0][:, None], ends[2][1], ends[1][1])
    length = np.linalg.norm(second - first, axis=1)
    n = np.ceil(length / (res / 4.0)).astype(np.int64) + 1
    idx = np.repeat(np.arange(len(n)), n)
    frac = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(np.maximum(n - 1, 1), n)
    pts = first[idx] + frac[:, None] * (second[idx] - first[idx])
    ij = np.floor((pts - origin) / res).astype(np.int64)
    ok = (ij[:, 0] >= 0) & (ij[:, 0] < nx) & (ij[:, 1] >= 0) & (ij[:, 1] < ny)
    blocked[ij[ok, 0], ij[ok, 1]] = True
