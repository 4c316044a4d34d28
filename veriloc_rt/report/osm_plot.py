"""Top view of an imported OpenStreetMap scene: footprints by material, the street graph."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .plots import new_axes, save_figure

#: face colour per ITU material
COLOURS = {"brick": "tab:brown", "concrete": "0.55", "glass": "tab:cyan", "metal": "tab:blue",
           "wood": "tab:olive"}


def plot_osm_top_view(city, path: str | Path | None = None, title: str | None = None, ax=None):
    """A top view of ``city`` (a :class:`~veriloc_rt.world.scene.osm.OsmCity`): footprints
    (holes left open) coloured by material, streets as lines, the frame's origin as a cross.

    :param ax: a matplotlib ``Axes`` to draw on (``path`` unused): the Figure is returned, as
        it is without ``ax`` and ``path``; with ``path`` the figure is saved there (png, pdf or
        svg by the suffix) and the path returned
    """
    from matplotlib.collections import LineCollection, PathCollection
    from matplotlib.patches import Patch
    from matplotlib.path import Path as MPath

    def poly_path(p):
        rings = [np.asarray(p.exterior.coords)[:, :2]] + [np.asarray(r.coords)[:, :2]
                                                         for r in p.interiors]
        return MPath.make_compound_path(*[MPath(r, closed=True) for r in rings])

    fig, ax = new_axes(ax, figsize=(8.0, 8.0))
    if len(city.street_edges):
        seg = city.street_nodes[city.street_edges]
        ax.add_collection(LineCollection(seg, colors="0.75", linewidths=0.8, zorder=1))
    handles = []
    for mat in sorted(set(city.materials.tolist())):
        paths = [poly_path(p) for p, m in zip(city.footprints, city.materials) if m == mat]
        colour = COLOURS.get(mat, "0.3")
        ax.add_collection(PathCollection(paths, facecolor=colour, edgecolor="k",
                                         linewidths=0.2, zorder=2))
        handles.append(Patch(facecolor=colour, edgecolor="k", label=f"{mat} ({len(paths)})"))
    handles += ax.plot(0, 0, "+", color="tab:red", ms=12, zorder=3, label="frame origin")
    x0, y0, x1, y1 = city.extent()
    ax.set_xlim(x0 - 10, x1 + 10)
    ax.set_ylim(y0 - 10, y1 + 10)
    ax.set_aspect("equal")
    ax.set_xlabel("x east [m]")
    ax.set_ylabel("y north [m]")
    lon0, lat0 = city.origin_lonlat_deg
    ax.set_title(title or f"{city.num_buildings} buildings; origin {lat0:.5f} N, {lon0:.5f} E")
    ax.legend(handles=handles, loc="upper right", fontsize=8)
    if path is None:
        return fig
    return save_figure(fig, path)
