"""The checks of a run's inputs that need the geometry: after the scene and the trajectories are
built, before any propagation is computed.

The config checks itself when it is loaded (:func:`~veriloc_rt.config.load_config`: types,
ranges, cross-section rules); the scene and trajectory files are checked as they are read
(:func:`~veriloc_rt.world.geometry.build_geometry`). What remains needs both: the trajectory's
actual length (a CSV may hold fewer rows than ``trajectory.num_points``) and the key files for
the BSs the layout actually uses. :func:`check_inputs` runs all of it and is what
``veriloc-rt config check`` calls; :func:`~veriloc_rt.sim.engine.run` calls
:func:`check_run_inputs` before tracing.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..config import Config
from ..config.world import itu_material_problem
from ..errors import InputError
from ..phy.security.keys import load_keys
from ..world.geometry import Geometry, build_geometry
from ..world.scene.export import scene_itu_materials

log = logging.getLogger(__name__)

__all__ = ["check_inputs", "check_materials", "check_run_inputs", "warn_unreachable"]


def check_run_inputs(cfg: Config, geometry: Geometry) -> None:
    """Raise :class:`~veriloc_rt.errors.InputError` for inputs that only fail together with
    the geometry; log a warning for a set-up that runs but measures little."""
    n = geometry.num_points
    where = ("trajectory.num_points" if cfg.trajectory.source == "generator"
             else f"the rows of {cfg.trajectory.source}")
    cfg.run.check_trajectory_length(n, where)
    if cfg.propagation.model == "raytrace":
        check_materials(cfg)
    if cfg.security.keys_dir:
        load_keys(cfg.security.keys_dir, range(len(geometry.bs_pos)),
                  aes_bits=cfg.security.aes_key_bits)
    # warnings last: a run that stops at an error prints that one line only
    lag = cfg.trajectory.adversary_lag_points
    if lag >= n:
        log.warning("trajectory.adversary_lag_points: %d is not below the trajectory's %d points, "
                    "so the adversary never starts following the UE: it waits behind the "
                    "start for the whole run", lag, n)


def check_materials(cfg: Config) -> None:
    """Raise :class:`~veriloc_rt.errors.InputError` unless Sionna RT can trace the scene's ITU
    materials at the carrier frequency (ITU-R P.2040-3 Table 3 fits each material over given
    frequency ranges; Sionna refuses others). Checked only for ray tracing: UMa ignores them."""
    f = cfg.propagation.carrier_frequency_hz
    if cfg.scene.is_canyon:
        for name in ("building_material", "ground_material"):
            problem = itu_material_problem(getattr(cfg.scene, name), f)
            if problem:
                raise InputError(f"scene.{name}", f"{problem} (propagation.carrier_frequency_hz)")
        return
    for name in scene_itu_materials(cfg.scene.source):
        problem = itu_material_problem(name, f)
        if problem:
            raise InputError("scene.source", f"{cfg.scene.source}: {problem}")


def check_inputs(cfg: Config, scene_dir: str | Path) -> Geometry:
    """Every check of a run's inputs, without computing propagation.

    :param scene_dir: where the canyon's XML + PLY files are written
    :returns: the run's geometry
    """
    geometry = build_geometry(cfg, scene_dir)
    check_run_inputs(cfg, geometry)
    return geometry


def warn_unreachable(has_path: np.ndarray) -> None:
    """Warn when no serving BS reaches the UE at any point.

    A warning rather than an error: it is known only after the propagation is computed (every
    check of the inputs comes before that), and the run's result, a service failure at every
    point, is a correct outcome of the scene as given (a closed room, BSs below the roofs)
    that the results files then record.

    :param has_path: [num_points, num_bs] bool, the serving link has a path
    """
    if has_path.size and not has_path.any():
        log.warning("no serving BS reaches the UE at any of the %d points (no propagation path "
                    "on any link): every point is a service failure; check the scene (closed "
                    "meshes around the trajectory, BSs inside buildings) and topology.bs_height_m",
                    has_path.shape[0])
