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
from .plugins import check_plugin_names
from ..world.sources import scene_source

log = logging.getLogger(__name__)

__all__ = ["check_inputs", "check_materials", "check_run_inputs", "warn_adversary",
           "warn_unreachable", "warn_silent_bs"]

#: arc lengths along the path are sums of float64 steps over at most a few hundred km: equal
#: gaps agree to ~1e-10 m; a gap within this of adversary_min_separation_m is that minimum
ARC_TOL_M = 1e-6


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
    warn_adversary(cfg, geometry)


def warn_adversary(cfg: Config, geometry: Geometry) -> str | None:
    """Warn when the adversary does not follow the UE as ``trajectory.adversary_lag_points``
    means it to in the attack window (the points its attacks use); return the warning.

    The adversary (:func:`~veriloc_rt.world.trajectory.follower`) is ``lag`` points behind on
    the UE's path and at least ``adversary_min_separation_m`` behind along it. It *trails off
    the trajectory* where it is still behind the path's start (its first ``lag`` points, or
    more while the UE has not yet covered the minimum separation), and it *coincides with* the
    UE, the lag having no effect, where the UE covered less than the minimum separation in the
    last ``lag`` points, so that the adversary sits at exactly that separation behind it.
    """
    t = cfg.trajectory
    lag, sep = t.adversary_lag_points, t.adversary_min_separation_m
    ue, adv = geometry.ue, geometry.adversary
    n = ue.num_points
    window = cfg.run.attack_points(n)
    off = adv.s < ue.s[0]            # [num_points] bool: behind the start, off the UE's path
    k = np.arange(n)
    lag_gap = np.where(k >= lag, ue.s - ue.s[np.maximum(k - lag, 0)], np.inf)  # m, along path
    glued = ~off & (lag_gap < sep - ARC_TOL_M)   # the separation, not the lag, places it
    head = f"trajectory.adversary_lag_points: {lag} (adversary_min_separation_m {sep:g} m): "
    num_win = int(window.sum())
    if off.all():
        msg = (head + f"the adversary never reaches the UE's path: it waits behind the "
               f"trajectory's start at all {n} points, so the attacks come from there")
    elif (off & window).any():
        msg = (head + f"the adversary is still behind the trajectory's start, off the UE's "
               f"path, at {int((off & window).sum())} of the {num_win} attack-window points "
               f"(it joins the path at point {int(np.argmin(off))})")
    elif num_win and glued[window].all():
        msg = (head + f"the lag places the adversary nowhere: the UE covers less than "
               f"{sep:g} m in {lag} points throughout the attack window, so the adversary "
               f"rides {sep:g} m behind the UE at each of its {num_win} points (the attacks "
               "come from right beside the UE)")
    else:
        return None
    log.warning("%s", msg)
    return msg


def check_materials(cfg: Config) -> None:
    """Raise :class:`~veriloc_rt.errors.InputError` unless Sionna RT can trace the scene's ITU
    materials at the carrier frequency (ITU-R P.2040-3 Table 3 fits each material over given
    frequency ranges; Sionna refuses others). Checked only for ray tracing: UMa ignores them."""
    f = cfg.propagation.carrier_frequency_hz
    for field, name, message in scene_source(cfg).materials(cfg):
        problem = itu_material_problem(name, f)
        if problem:
            raise InputError(field, message.replace("{problem}", problem))


def check_inputs(cfg: Config, scene_dir: str | Path) -> Geometry:
    """Every check of a run's inputs, without computing propagation.

    :param scene_dir: where the canyon's XML + PLY files are written
    :returns: the run's geometry
    """
    check_plugin_names(cfg)
    geometry = build_geometry(cfg, scene_dir)
    check_run_inputs(cfg, geometry)
    return geometry


def warn_unreachable(has_path: np.ndarray) -> int:
    """Warn when no serving BS reaches the UE at some or all points; return how many.

    A warning rather than an error: it is known only after the propagation is computed (every
    check of the inputs comes before that), and the result at those points, a service failure,
    is a correct outcome of the scene as given (a closed room, BSs below the roofs, a street
    the trajectory leaves) that the results files then record.

    :param has_path: [num_points, num_bs] bool, the serving link has a path
    :returns: the number of points at which no serving link has a path
    """
    if not has_path.size:
        return 0
    unreached = ~has_path.any(axis=1)
    n, total = int(unreached.sum()), has_path.shape[0]
    if n:
        where = (f"any of the {total} points" if n == total
                 else f"{n} of the {total} points ({100.0 * n / total:.1f} %)")
        log.warning("no serving BS reaches the UE at %s (no propagation path on any of their "
                    "serving links): %s a service failure; check the scene (closed meshes "
                    "around the trajectory, BSs inside buildings) and topology.bs_height_m",
                    where, "every point is" if n == total else "each is")
    return n


def warn_silent_bs(has_path: np.ndarray, serving: np.ndarray) -> list[int]:
    """Warn about BSs that reach the UE at none of the points they serve (a mast below the
    roofs, behind a building for the whole drive); return their ids.

    :param has_path: [num_points, 3] bool, the serving link has a path
    :param serving: [num_points, 3] int64, BS ids of the serving links
    """
    silent = [int(b) for b in np.unique(serving) if not has_path[serving == b].any()]
    if silent:
        log.warning("BS %s reach%s the UE at none of the points %s: every link from %s has "
                    "no propagation path; check the BS positions (topology.placement, "
                    "topology.sites, topology.bs_height_m)",
                    ", ".join(map(str, silent)), "es" if len(silent) == 1 else "",
                    "it serves" if len(silent) == 1 else "they serve",
                    "it" if len(silent) == 1 else "them")
    return silent
