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
from .scene.canyon import UrbanCanyon, urban_canyon
from .scene.export import scene_bounds, write_scene
from .scene.external import MeshScene
from .scene.osm_write import osm_scene
from .topology import HexLayout, hex_layout
from .trajectory import (Trajectory, check_points, follower, generate_street_trajectory,
                         load_csv_trajectory)

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Geometry:
    """Scene and positions of one run.

    bs_pos : [num_bs, 3] float64, m (every BS that serves the UE at some point)
    serving : [num_points, 3] int64, ids into ``bs_pos``; the first is the RSTD reference
    """

    scene_xml: Path
    scene: UrbanCanyon | MeshScene
    full_canyon: UrbanCanyon | None
    layout: HexLayout
    bs_pos: np.ndarray
    serving: np.ndarray
    ue: Trajectory
    adversary: Trajectory

    @property
    def num_points(self) -> int:
        return self.ue.num_points


def build_trajectory(cfg: Config, scene) -> Trajectory:
    """The UE trajectory of ``cfg`` (generated on the canyon's streets or read from CSV)."""
    tcfg = cfg.trajectory
    if tcfg.source == "generator":
        if not isinstance(scene, UrbanCanyon):
            raise InputError("trajectory.source", "the street generator needs the procedural "
                             "canyon; give a CSV trajectory for an external scene")
        ue = generate_street_trajectory(tcfg, scene, stream(cfg.seed, "trajectory"))
        source = "trajectory"
    else:
        ue = load_csv_trajectory(tcfg.source, tcfg)
        source = tcfg.source
    check_points(scene, ue.pos, "trajectory", source)
    return ue


def osm_scene_xml(scfg, scene_dir: str | Path) -> Path:
    """The scene imported from ``scene.osm`` into ``scene_dir`` (reused when already there)."""
    xml, city = osm_scene(scfg.osm, scene_dir, bbox_deg=scfg.osm_bbox_deg or None,
                          radius_m=scfg.osm_radius_m, storey_m=scfg.osm_storey_m,
                          default_height_m=scfg.osm_default_height_m,
                          ground_material=scfg.ground_material,
                          thickness_m=scfg.material_thickness_m)
    if city is not None:
        log.info("OSM: %d buildings, %d street nodes from %s", city.num_buildings,
                 len(city.street_nodes), scfg.osm)
    return xml


def build_geometry(cfg: Config, scene_dir: str | Path) -> Geometry:
    """Build (and write, for the canyon) the scene, the layout and both trajectories.

    :param scene_dir: where the canyon's XML + PLY files go
    """
    full = None
    xml = None
    if cfg.scene.is_canyon:
        full = urban_canyon(cfg.scene, stream(cfg.seed, "scene-heights"))
        scene = full
    elif cfg.scene.osm:
        xml = osm_scene_xml(cfg.scene, scene_dir)
        scene = MeshScene.from_xml(xml, "scene.osm")
    else:
        scene = MeshScene.from_xml(cfg.scene.source)
    ue = build_trajectory(cfg, scene)
    adv = follower(ue, cfg.trajectory.adversary_lag_points,
                   cfg.trajectory.adversary_min_separation_m)
    check_points(scene, adv.pos, "adversary", "trajectory.adversary_lag_points")
    layout = hex_layout(cfg.topology, stream(cfg.seed, "topology", cfg.topology.iteration))
    bs_pos, serving = layout.serving(ue.pos[:, :2])
    if full is not None:
        keep_near = np.concatenate([bs_pos[:, :2], ue.densified_xy(), adv.pos[:, :2]])
        cropped = full.crop(keep_near, cfg.scene.margin_m)
        bounds = scene_bounds(cropped, np.concatenate([bs_pos[:, :2], ue.pos[:, :2]]), pad=20.0)
        # written aside, then each file renamed into place (XML last): a stop leaves no half file
        with atomic_files(scene_dir) as tmp:
            xml = Path(scene_dir) / write_scene(cropped, tmp, bounds).relative_to(tmp)
        log.info("canyon: %d of %d buildings within %.0f m of the BSs and the trajectory",
                 cropped.num_buildings, full.num_buildings, cfg.scene.margin_m)
        scene = cropped
    elif xml is None:
        xml = Path(cfg.scene.source)
    return Geometry(scene_xml=Path(xml), scene=scene, full_canyon=full, layout=layout,
                    bs_pos=bs_pos, serving=serving, ue=ue, adversary=adv)
