"""The geometry of one run: scene, BS layout, UE and adversary trajectories, serving sets.

Everything here is cheap and exact for a seed; the expensive part (propagation) consumes it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import Config
from ..errors import InputError
from ..fileio import atomic_files
from ..rng import stream
from .scene.canyon import UrbanCanyon
from .scene.export import scene_bounds, write_scene
from .scene.external import MeshScene
from .sources import scene_source
from .sites import candidate_sites, load_sites, nearest_serving, rooftop_sites
from .streets import scene_streets
from .topology import HexLayout, hex_layout
from .trajectory import (Trajectory, check_points, follower, generate_graph_trajectory,
                         generate_street_trajectory, load_csv_trajectory, roof_height)

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Geometry:
    """Scene and positions of one run.

    bs_pos : [num_bs, 3] float64, m (every BS that serves the UE at some point)
    serving : [num_points, num_trps] int64, ids into ``bs_pos``; the first is the RSTD reference
    """

    scene_xml: Path
    scene: UrbanCanyon | MeshScene
    full_canyon: UrbanCanyon | None
    layout: HexLayout | None
    bs_pos: np.ndarray
    serving: np.ndarray
    ue: Trajectory
    adversary: Trajectory
    #: [num_bs] float64, rad: azimuths a sites CSV gives (NaN where none; None: hexagonal layout)
    bs_azimuth: np.ndarray | None = None
    #: the mesh scene as loaded, before the crop (None for the canyon)
    full_mesh: MeshScene | None = None
    #: [num_points, C] int64 ids into ``bs_pos``, -1 padding: the candidate sites of each point
    #: (``topology.selection`` 'traced_power'; None otherwise), of which the strongest serve
    candidates: np.ndarray | None = None

    @property
    def num_points(self) -> int:
        return self.ue.num_points


def build_trajectory(cfg: Config, scene) -> Trajectory:
    """The UE trajectory of ``cfg`` (generated on the canyon's streets or read from CSV)."""
    tcfg = cfg.trajectory
    if tcfg.source == "generator":
        if isinstance(scene, UrbanCanyon):
            ue = generate_street_trajectory(tcfg, scene, stream(cfg.seed, "trajectory"))
        else:
            graph = scene_streets(scene, tcfg.region_m, tcfg.ue_height_m)
            ue = generate_graph_trajectory(tcfg, graph, stream(cfg.seed, "trajectory"))
        source = "trajectory"
    else:
        ue = load_csv_trajectory(tcfg.source, tcfg)
        source = tcfg.source
    check_points(scene, ue.pos, "trajectory", source)
    return ue


def build_geometry(cfg: Config, scene_dir: str | Path) -> Geometry:
    """Build the scene (the source ``scene.source`` names, :mod:`.sources`), the layout and both
    trajectories, and write the cropped scene.

    :param scene_dir: where the cropped scene's XML + PLY files go
    """
    scene = scene_source(cfg).load(cfg, Path(scene_dir))
    full, mesh = (None, scene) if isinstance(scene, MeshScene) else (scene, None)
    ue = build_trajectory(cfg, scene)
    adv = follower(ue, cfg.trajectory.adversary_lag_points,
                   cfg.trajectory.adversary_min_separation_m)
    check_points(scene, adv.pos, "adversary", "trajectory.adversary_lag_points")
    layout, bs_pos, serving, azimuth, candidates = _place_bs(cfg, scene, ue)
    if mesh is not None:
        keep_near = np.concatenate([bs_pos[:, :2], ue.densified_xy(), adv.pos[:, :2]])
        cropped = mesh.crop(keep_near, cfg.scene.margin_m)
        pts = np.concatenate([bs_pos[:, :2], ue.pos[:, :2]] + [s.triangles.reshape(-1, 3)[:, :2]
                                                               for s in cropped.buildings])
        bounds = (float(pts[:, 0].min() - 20.0), float(pts[:, 1].min() - 20.0),
                  float(pts[:, 0].max() + 20.0), float(pts[:, 1].max() + 20.0))
        with atomic_files(scene_dir) as tmp:
            xml = Path(scene_dir) / cropped.write(tmp, bounds).relative_to(tmp)
        log.info("mesh scene: %d of %d building shapes within %.0f m of the BSs and the "
                 "trajectory", cropped.num_buildings, mesh.num_buildings, cfg.scene.margin_m)
        return Geometry(scene_xml=Path(xml), scene=cropped, full_canyon=None, layout=layout,
                        bs_pos=bs_pos, serving=serving, ue=ue, adversary=adv,
                        bs_azimuth=azimuth, full_mesh=mesh, candidates=candidates)
    keep_near = np.concatenate([bs_pos[:, :2], ue.densified_xy(), adv.pos[:, :2]])
    cropped = full.crop(keep_near, cfg.scene.margin_m)
    bounds = scene_bounds(cropped, np.concatenate([bs_pos[:, :2], ue.pos[:, :2]]), pad=20.0)
    # written aside, then each file renamed into place (XML last): a stop leaves no half file
    with atomic_files(scene_dir) as tmp:
        xml = Path(scene_dir) / write_scene(cropped, tmp, bounds).relative_to(tmp)
    log.info("canyon: %d of %d buildings within %.0f m of the BSs and the trajectory",
             cropped.num_buildings, full.num_buildings, cfg.scene.margin_m)
    return Geometry(scene_xml=Path(xml), scene=cropped, full_canyon=full, layout=layout,
                    bs_pos=bs_pos, serving=serving, ue=ue, adversary=adv, bs_azimuth=azimuth,
                    candidates=candidates)


def _place_bs(cfg: Config, scene, ue: Trajectory):
    """BS positions and serving sets: a sites CSV (the num_trps nearest serve), or the
    hexagonal layout (the cell's three, or the num_trps nearest sites, serve) at a fixed height
    or moved onto the nearest roofs. With ``topology.selection`` 'traced_power' the BSs are
    every candidate site and the serving sets the nearest, until the traced powers choose.

    :returns: (layout or None, bs_pos [num_bs, 3] m, serving [num_points, num_trps], azimuths
        or None, candidates [num_points, C] or None)
    :raises InputError: if a BS stands inside a building or off the scene
    """
    topo = cfg.topology
    xy = ue.pos[:, :2]
    if topo.sites:
        sites, az = load_sites(topo.sites)
        candidates = None
        if topo.selection == "traced_power":
            bs_pos, serving, candidates, used = candidate_sites(sites, xy, topo.num_trps,
                                                                topo.candidate_radius_m)
        else:
            bs_pos, serving, used = nearest_serving(sites, xy, topo.num_trps)
        _check_bs(scene, bs_pos, topo.sites, [f"site {u + 1}" for u in used])
        return None, bs_pos, serving, az[used], candidates
    layout = hex_layout(topo, stream(cfg.seed, "topology", topo.iteration))
    bs_pos, serving = (layout.serving(xy) if topo.uses_cell
                       else layout.nearest(xy, topo.num_trps))
    rooftop = topo.placement == "rooftop" or (topo.placement == "auto"
                                              and isinstance(scene, MeshScene))
    if rooftop:
        bs_pos = rooftop_sites(scene, bs_pos[:, :2], topo.mast_height_m)
    elif isinstance(scene, MeshScene):
        _check_bs(scene, bs_pos, "topology.bs_height_m", [f"BS {k}" for k in range(len(bs_pos))])
    return layout, bs_pos, serving, None, None


def _check_bs(scene, bs_pos: np.ndarray, source: str, names: list[str]) -> None:
    """A BS must stand on the scene's ground and outside every building."""
    off = ~scene.inside_extent(bs_pos[:, :2])
    if isinstance(scene, MeshScene):
        inside = scene.inside_building(bs_pos)
    else:
        inside = scene.inside_building(bs_pos[:, :2]) & (bs_pos[:, 2] < roof_height(scene, bs_pos))
    for bad, what in ((off, "outside the scene"), (inside, "inside a building")):
        if np.any(bad):
            k = int(np.argmax(bad))
            hint = (" (topology.placement 'rooftop' puts the BSs on roofs)"
                    if source == "topology.bs_height_m" else "")
            raise InputError(source, f"{names[k]} at ({bs_pos[k, 0]:.1f}, {bs_pos[k, 1]:.1f}, "
                             f"{bs_pos[k, 2]:.1f}) m is {what}{hint}")

