"""BS sites that respect a mesh scene: the hexagonal layout moved onto the nearest roof, or
sites read from a CSV file; serving sets for CSV sites; the command line of the scripts that
write candidate sites CSVs (:class:`SitesTool`, :func:`write_sites_csv`).

Rooftop placement: the scene's buildings are rasterised at :data:`ROOF_GRID_M`; a site moves
to the centre of the nearest roof cell at least :data:`ROOF_EDGE_M` inside its building's
outline (a mast is not put on the parapet) and its antenna stands ``mast`` above the highest
building surface over that point, so it is above its roof and never inside a building.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..inputs import numeric_csv, read_text
from ..config.world import MIN_ANTENNA_HEIGHT_M
from .scene.raster import rasterize

#: raster resolution of the roof search, m
ROOF_GRID_M = 1.0
#: a rooftop mast stands at least this far inside the building's outline, m
ROOF_EDGE_M = 2.0
#: height at which "under a roof" is probed, m (above a floor slab at the ground)
_PROBE_Z_M = 1.0
#: largest sites CSV read, bytes
MAX_SITES_BYTES = 1 << 20
#: fewest sites a CSV must hold (a 2-D TDOA fix needs three TRPs)
SERVING = 3


def rooftop_sites(scene, sites_xy: np.ndarray, mast: float) -> np.ndarray:
    """Move each site to the nearest roof point of ``scene`` and raise it ``mast`` above it.

    :param scene: a :class:`~veriloc_rt.world.scene.external.MeshScene`
    :param sites_xy: [num_sites, 2] float64, m
    :returns: [num_sites, 3] float64, m
    :raises InputError: if the scene has no roof wide enough for a mast
    """
    from scipy import ndimage
    from scipy.spatial import cKDTree

    grid = rasterize(scene.building_triangles, scene.ground_xy, ROOF_GRID_M, _PROBE_Z_M)
    # cells under a roof, with the building's interior at least ROOF_EDGE_M deep around them
    under = grid.inside & np.isfinite(grid.roof_z)
    depth = ndimage.distance_transform_edt(under) * ROOF_GRID_M
    ok = np.argwhere(depth > ROOF_EDGE_M)
    if not len(ok):
        raise InputError("topology.placement", "the scene has no roof wide enough for a "
                         f"rooftop mast ({2 * ROOF_EDGE_M:g} m across): topology.placement "
                         "'fixed' or topology.sites")
    centres = grid.centres(ok)
    _, k = cKDTree(centres).query(np.asarray(sites_xy, dtype=float).reshape(-1, 2))
    ij = ok[k]
    z = grid.roof_z[ij[:, 0], ij[:, 1]] + mast
    return np.concatenate([centres[k], z[:, None]], axis=1)


def load_sites(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a sites CSV ``x,y,z[,azimuth_deg]`` (header row required; m; z above the ground).

    :returns: positions [num_sites, 3] float64, m; azimuths [num_sites] float64, rad (NaN where
        not given; the BS antennas are isotropic, so an azimuth only marks the plots)
    :raises InputError: naming the file and line of anything unusable
    """
    field = "topology.sites"
    name = str(path)
    text = read_text(path, field, "sites file", MAX_SITES_BYTES)
    _, rows = numeric_csv(text, name, (["x", "y", "z"], ["x", "y", "z", "azimuth_deg"],
                                       ["x", "y", "z", "azimuth"]),
                          "'x,y,z' or 'x,y,z,azimuth_deg'")
    pos, az = [], []
    for i, vals in rows:
        if vals[2] <= MIN_ANTENNA_HEIGHT_M:
            raise InputError(f"{name}:{i}", f"z = {vals[2]:g} m, expected a BS height above "
                             f"{MIN_ANTENNA_HEIGHT_M:g} m (TR 38.901's h_E)")
        if len(vals) == 4 and not -360.0 <= vals[3] <= 360.0:
            raise InputError(f"{name}:{i}", f"azimuth {vals[3]:g} deg, expected -360 to 360")
        pos.append(vals[:3])
        az.append(math.radians(vals[3]) if len(vals) == 4 else math.nan)
    if len(pos) < SERVING:
        raise InputError(name, f"{len(pos)} sites, expected at least {SERVING} (each point is "
                         f"served by its {SERVING} nearest)")
    p = np.array(pos)
    dup = _first_duplicate(p)
    if dup is not None:
        raise InputError(name, f"sites {dup[0] + 1} and {dup[1] + 1} stand at the same position")
    return p, np.array(az)


def write_sites_csv(path: str | Path, xyz: np.ndarray, z_format: str = ".1f") -> int:
    """Write a sites CSV ``x,y,z`` (:func:`load_sites` reads it back), x and y to 0.1 m.

    :param xyz: [num_sites, 3] float, m (z above the ground)
    :param z_format: the format of z (``"g"``: a height given on the command line as typed)
    :returns: the number of sites written
    :raises InputError: ``--out: ...`` when the file cannot be written
    """
    xyz = np.asarray(xyz, dtype=float).reshape(-1, 3)
    lines = ["x,y,z"] + [f"{p[0]:.1f},{p[1]:.1f},{p[2]:{z_format}}" for p in xyz]
    try:
        Path(path).write_text("\n".join(lines) + "\n")
    except OSError as exc:
        raise InputError("--out", f"{path}: {(exc.strerror or str(exc)).lower()}") from None
    return len(xyz)


@dataclass(frozen=True)
class SitesTool:
    """The command line shared by the scripts that write candidate sites for a mesh scene
    (``scripts/street_sites.py``, ``scripts/roof_sites.py``): ``CONFIG --out SITES.csv``, a
    spacing flag, a height flag and ``--region``; :meth:`inputs` checks them and loads the
    config's mesh scene, raising :class:`~veriloc_rt.errors.InputError` for anything unusable
    (the scripts print it as one line, exit code 2).

    :param spacing: the flag of the sites' spacing, m (``--spacing``, ``--isd``), > 0
    :param height: the flag of the antenna's height, m (``--height`` above the ground,
        ``--mast`` above the roof), > ``min_height``
    :param canyon: why the canyon scene is refused (after "a mesh scene is needed")
    """

    spacing: str
    spacing_default: float
    spacing_help: str
    height: str
    height_default: float
    height_help: str
    min_height: float
    canyon: str

    def parser(self, description: str, parser_class: type = argparse.ArgumentParser
               ) -> argparse.ArgumentParser:
        """The shared flags on a new ``parser_class`` (the scripts pass the CLI's, whose
        errors are one line); a script adds its own flags."""
        ap = parser_class(description=description)
        ap.add_argument("config", help="the config whose scene (a mesh) and region are used")
        ap.add_argument("--out", required=True, help="the sites CSV written")
        ap.add_argument(self.spacing, type=float, default=self.spacing_default,
                        help=self.spacing_help)
        ap.add_argument(self.height, type=float, default=self.height_default,
                        help=self.height_help)
        ap.add_argument("--region", type=float, default=None,
                        help="half-side of the square searched, m (default: the config's "
                             f"trajectory.region_m + 2 x {self.spacing})")
        return ap

    def inputs(self, args: argparse.Namespace) -> tuple:
        """(config, its :class:`~veriloc_rt.world.scene.external.MeshScene`, the region's
        half-side in m) of parsed ``args``.

        :raises InputError: a flag out of range, an unreadable config, a canyon scene, a
            scene file that is not a usable mesh
        """
        from ..config import load_config
        from .scene.external import MeshScene

        spacing = getattr(args, self.spacing.lstrip("-"))
        height = getattr(args, self.height.lstrip("-"))
        if not (math.isfinite(spacing) and spacing > 0):
            raise InputError(self.spacing, f"got {spacing:g}, expected a distance > 0 m")
        if not (math.isfinite(height) and height > self.min_height):
            raise InputError(self.height, f"got {height:g}, expected a height > "
                             f"{self.min_height:g} m")
        if args.region is not None and not (math.isfinite(args.region) and args.region > 0):
            raise InputError("--region", f"got {args.region:g}, expected a half-side > 0 m")
        cfg = load_config(args.config)
        if cfg.scene.is_canyon:
            raise InputError("scene.source", f"a mesh scene is needed ({self.canyon})")
        region = (args.region if args.region is not None
                  else cfg.trajectory.region_m + 2 * spacing)
        return cfg, MeshScene.from_xml(cfg.scene.xml_path), region

    def check_count(self, num_sites: int) -> None:
        """:raises InputError: fewer than :data:`SERVING` sites found (a sites CSV needs them)"""
        if num_sites < SERVING:
            raise InputError(self.spacing, f"{num_sites} sites found, a sites file needs at "
                             f"least {SERVING}: a smaller {self.spacing} or a larger --region")


def _first_duplicate(p: np.ndarray) -> tuple[int, int] | None:
    for i in range(len(p)):
        same = np.flatnonzero(np.all(np.abs(p[i + 1:] - p[i]) < 1e-6, axis=1))
        if len(same):
            return i, i + 1 + int(same[0])
    return None


def _site_distances(sites: np.ndarray, xy: np.ndarray, n: int) -> np.ndarray:
    """[num_points, num_sites] horizontal distances, m, of each point to each site.

    :raises InputError: if the file holds fewer than ``n`` sites
    """
    if len(sites) < n:
        raise InputError("topology.num_trps", f"{n} TRPs per point, but the sites file holds "
                         f"{len(sites)} sites")
    return np.linalg.norm(np.asarray(xy)[:, None, :2] - sites[None, :, :2], axis=-1)


def nearest_serving(sites: np.ndarray, xy: np.ndarray, n: int = SERVING
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``n`` nearest sites (horizontal distance, ties by file order) serve each point,
    nearest first; BS ids in order of first use, as the hexagonal layout numbers them.

    :param sites: [num_sites, 3] float64, m; xy: [num_points, 2] float64, m
    :returns: (bs_pos [num_bs, 3] float64 m, serving [num_points, n] int64 ids into bs_pos,
        site index of each BS [num_bs] int64)
    :raises InputError: if the file holds fewer than ``n`` sites
    """
    d = _site_distances(sites, xy, n)
    near = np.argsort(d, axis=1, kind="stable")[:, :n]
    order: dict[int, int] = {}
    serving = np.empty_like(near)
    for k in range(near.shape[0]):
        for j in range(n):
            serving[k, j] = order.setdefault(int(near[k, j]), len(order))
    used = np.array(list(order), dtype=np.int64)
    return sites[used], serving, used


def candidate_sites(sites: np.ndarray, xy: np.ndarray, n: int, radius: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Candidate sites of each point for ``topology.selection`` 'traced_power': the sites within
    ``radius`` (horizontal distance) of the point, and always its ``n`` nearest, nearest first
    (ties by file order); BS ids in order of first use over the candidate lists.

    :param sites: [num_sites, 3] float64, m; xy: [num_points, 2] float64, m
    :returns: (bs_pos [num_bs, 3] float64 m, serving [num_points, n] int64 (the ``n`` nearest,
        a provisional serving set until the traced powers choose), candidates [num_points, C]
        int64 ids into bs_pos, nearest first, rows padded with -1 (C the most any point has),
        site index of each BS [num_bs] int64)
    :raises InputError: if the file holds fewer than ``n`` sites
    """
    d = _site_distances(sites, xy, n)
    near = np.argsort(d, axis=1, kind="stable")
    keep = np.take_along_axis(d, near, axis=1) <= radius
    keep[:, :n] = True
    width = int(keep.sum(axis=1).max())
    order: dict[int, int] = {}
    cand = np.full((len(near), width), -1, dtype=np.int64)
    for k in range(len(near)):
        for j in np.flatnonzero(keep[k]):
            cand[k, j] = order.setdefault(int(near[k, j]), len(order))
    used = np.array(list(order), dtype=np.int64)
    return sites[used], cand[:, :n].copy(), cand, used


def strongest_serving(candidates: np.ndarray, power: np.ndarray, n: int
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The ``n`` candidates of each point with the largest received power, strongest first
    (ties, e.g. candidates without a path, by the candidate order: nearest first).

    :param candidates: [num_points, C] int64 ids, -1 padding (:func:`candidate_sites`)
    :param power: [num_points, C] float64, linear received power of each candidate link
    :returns: (serving [num_points, n] int64 ids, column [num_points, n] int64, the candidate
        column each slot comes from)
    """
    score = np.where(candidates >= 0, np.asarray(power, dtype=float), -np.inf)
    col = np.argsort(-score, axis=1, kind="stable")[:, :n]
    return np.take_along_axis(candidates, col, axis=1), col
