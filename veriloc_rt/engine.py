"""The main job: geometry -> propagation -> results on disk.

At this stage of the product the run builds the scene and the trajectories, ray-traces (or
draws) every link, and writes a propagation summary, ``run.json`` and a top-view plot.
"""

from __future__ import annotations

import json
import logging
import platform
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Callable

import numpy as np

from .config import Config, config_to_dict
from .propagation.raytrace import Propagation
from .scenario import Geometry, build_geometry

log = logging.getLogger(__name__)

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True, eq=False)
class Results:
    """What a run produced."""

    config: Config
    geometry: Geometry
    propagation: Propagation
    summary: dict
    timing_s: dict = field(default_factory=dict)
    out_dir: Path | None = None


def package_versions() -> dict:
    names = ("veriloc-rt", "sionna-rt", "mitsuba", "drjit", "numpy", "scipy", "trimesh",
             "cryptography")
    out = {"python": platform.python_version()}
    for n in names:
        try:
            out[n] = metadata.version(n)
        except metadata.PackageNotFoundError:
            out[n] = None
    return out


def compute_propagation(cfg: Config, geometry: Geometry, progress: Progress | None = None,
                        cache_dir: str | Path | None = "default") -> Propagation:
    """CIRs of every link, from the configured model."""
    if cfg.propagation.model == "uma":
        from .propagation.stochastic import uma_propagation

        return uma_propagation(geometry, cfg.propagation, cfg.seed)
    from .propagation.raytrace import trace

    cb = (lambda d, n: progress("ray tracing", d, n)) if progress else None
    return trace(geometry, cfg.propagation, cfg.seed, progress=cb, cache_dir=cache_dir)


def run(cfg: Config, out_dir: str | Path | None = None, progress: Progress | None = None) -> Results:
    """Run the configured scenario; with ``out_dir``, write the scene, summary and plots there."""
    from .report.propagation_summary import summarize

    timing = {}
    t0 = time.perf_counter()
    out = Path(out_dir) if out_dir is not None else None
    scene_dir = (out / "scene") if out else Path(".veriloc-scene")
    geometry = build_geometry(cfg, scene_dir)
    if cfg.security.keys_dir:  # bad key files fail now, before any tracing
        from .security.keys import load_keys

        load_keys(cfg.security.keys_dir, range(len(geometry.bs_pos)))
    timing["geometry"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    prop = compute_propagation(cfg, geometry, progress)
    timing["propagation"] = time.perf_counter() - t1
    summary = {
        "num_points": geometry.num_points,
        "num_bs": int(len(geometry.bs_pos)),
        "num_buildings": getattr(geometry.scene, "num_buildings", None),
        "num_triangles": int(geometry.scene.box_meshes()[1].shape[0]
                             if hasattr(geometry.scene, "box_meshes")
                             else geometry.scene.triangles.shape[0]),
        "ue_path_length_m": float(geometry.ue.s[-1] - geometry.ue.s[0]),
        "ue_speed_mps_mean": float(np.linalg.norm(geometry.ue.vel, axis=1).mean()),
        "bs_to_ue": summarize(prop.bs_ue),
        "bs_to_adversary": summarize(prop.bs_adv),
        "adversary_to_ue": summarize(prop.adv_ue),
        "raytrace_stats": prop.stats,
    }
    timing["total"] = time.perf_counter() - t0
    if out:
        from .report.scene_plot import plot_top_view

        out.mkdir(parents=True, exist_ok=True)
        plot_top_view(geometry, out / "scene_top_view.png")
        (out / "propagation_summary.json").write_text(json.dumps(summary, indent=2))
        run_info = {"config": config_to_dict(cfg), "seed": cfg.seed,
                    "versions": package_versions(), "timing_s": timing,
                    "scene_xml": str(geometry.scene_xml)}
        (out / "run.json").write_text(json.dumps(run_info, indent=2))
    return Results(cfg, geometry, prop, summary, timing, out)
