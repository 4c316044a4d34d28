"""The trajectory map draws the scene's buildings under the paths: on a tiny procedural canyon
the drawn patches are exactly the footprints of the scene's blocks within the view; a mesh
scene's building faces are drawn as their top view, walls (no projected area) left out."""

from types import SimpleNamespace

import numpy as np
from matplotlib.collections import PolyCollection

from veriloc_rt.config import config_from_dict
from veriloc_rt.report.plots import (clear_figure_cache, map_buildings, new_axes,
                                     plot_trajectory_map)
from veriloc_rt.world.geometry import build_geometry

#: a small canyon (12 m blocks, 8 m streets, 120 m half-side) and a short UMa drive: no tracing
TINY = {"propagation": {"model": "uma"},
        "scene": {"block_size_m": 12.0, "street_width_m": 8.0, "extent_m": 120.0,
                  "margin_m": 60.0},
        "trajectory": {"num_points": 6, "region_m": 60.0}}
#: the patches hold the footprints' own floats (copied into corner arrays): exact
EXACT = 0.0


def _rows(geo) -> dict:
    ue = geo.ue.pos
    return {"x_true": ue[:, 0], "y_true": ue[:, 1], "x_est": ue[:, 0] + 1.0,
            "y_est": ue[:, 1], "outcome": np.full(len(ue), "success")}


def test_map_draws_the_canyon_footprints_under_the_paths(tmp_path):
    geo = build_geometry(config_from_dict(TINY), tmp_path / "scene")
    fp = np.asarray(geo.scene.footprints, dtype=float)
    assert len(fp) > 4
    fig, ax = new_axes()
    out = plot_trajectory_map(_rows(geo), geo.bs_pos, adversary_xy=geo.adversary.pos, ax=ax,
                              buildings=map_buildings(geo))
    assert out is fig
    [coll] = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert coll.get_label() == "buildings"
    drawn = np.array([[p.vertices[:, 0].min(), p.vertices[:, 1].min(), p.vertices[:, 0].max(),
                       p.vertices[:, 1].max()] for p in coll.get_paths()])
    # the independent selection: the footprints that reach into the axes' view
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    seen = fp[(fp[:, 2] >= x0) & (fp[:, 0] <= x1) & (fp[:, 3] >= y0) & (fp[:, 1] <= y1)]
    assert len(seen) > 0
    key = lambda a: a[np.lexsort(a.T[::-1])]   # noqa: E731 - rows in one order
    assert drawn.shape == seen.shape
    assert np.max(np.abs(key(drawn) - key(seen))) <= EXACT
    # under the trajectory, the estimates, the BSs and the adversary
    assert all(coll.get_zorder() < line.get_zorder() for line in ax.lines)
    assert "buildings" in [t.get_text() for t in ax.get_legend().get_texts()]


def test_map_of_a_mesh_scene_draws_the_faces_top_view_without_walls():
    roof = [[0, 0, 10], [10, 0, 10], [10, 10, 10]]
    wall = [[0, 0, 0], [10, 0, 0], [10, 0, 10]]     # vertical: no area from above
    far = [[900, 900, 10], [910, 900, 10], [910, 910, 10]]   # outside the view
    geo = SimpleNamespace(scene=SimpleNamespace(building_triangles=np.array(
        [roof, wall, far], dtype=float)))
    tri = map_buildings(geo)
    assert tri.shape == (2, 3, 2)
    rows = {"x_true": np.array([0.0, 5.0]), "y_true": np.array([0.0, 5.0]),
            "x_est": np.array([0.0, 5.0]), "y_est": np.array([0.0, 5.0]),
            "outcome": np.array(["success", "success"])}
    fig = plot_trajectory_map(rows, np.array([[20.0, 20.0]]), buildings=tri)
    [coll] = [c for c in fig.axes[0].collections if isinstance(c, PolyCollection)]
    [p] = coll.get_paths()
    assert np.allclose(p.vertices[:3], np.array(roof)[:, :2], atol=EXACT)


def test_kept_map_figure_drops_the_previous_maps_buildings(tmp_path):
    """The run's map figure is kept from map to map: a map without buildings drawn after one
    with them gives the pixels of a map drawn without them on a new figure."""
    geo = build_geometry(config_from_dict(TINY), tmp_path / "scene")
    clear_figure_cache()
    plot_trajectory_map(_rows(geo), geo.bs_pos, tmp_path / "with.png",
                        buildings=map_buildings(geo))
    plot_trajectory_map(_rows(geo), geo.bs_pos, tmp_path / "after.png")
    clear_figure_cache()
    plot_trajectory_map(_rows(geo), geo.bs_pos, tmp_path / "new.png")
    assert (tmp_path / "after.png").read_bytes() == (tmp_path / "new.png").read_bytes()
    assert (tmp_path / "with.png").read_bytes() != (tmp_path / "new.png").read_bytes()
