"""Top view of a run's geometry: buildings, streets, BSs, UE and adversary paths."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .plots import SERVING_LABEL, draw_bs, new_axes, save_figure


def plot_top_view(geometry, path: str | Path | None = None, title: str | None = None,
                  estimated_xy: np.ndarray | None = None, ax=None, serving=None):
    """A top view of ``geometry`` (a :class:`~veriloc_rt.world.geometry.Geometry`).

    Emitted buildings are dark, buildings of the full grid that the crop left out are light,
    streets are white. Serving BSs are triangles (labelled with their id), the UE path is a
    line coloured by time (its colour bar beside the axes), the adversary's positions are
    orange dots.

    :param estimated_xy: [num_points, 2] float64, m, optional estimated positions to overlay
    :param serving: [num_bs] bool, the BSs some point measures
        (:func:`~veriloc_rt.report.plots.serving_mask`): drawn apart from the candidate sites
        no point chose; None: all as serving BSs, or, before a traced-power choice
        (``geometry.candidates`` set), all as candidate sites
    :param ax: a matplotlib ``Axes`` to draw on (``path`` unused): the Figure is returned, as
        it is without ``ax`` and ``path``; with ``path`` the figure is saved there (png, pdf or
        svg by the suffix) and the path returned
    """
    import matplotlib
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.patches import Rectangle

    fig, ax = new_axes(ax, figsize=(8.0, 8.0))
    scene = geometry.scene
    bs, ue = geometry.bs_pos, geometry.ue.pos
    pts = np.concatenate([bs[:, :2], ue[:, :2]])
    lo, hi = pts.min(axis=0) - 40, pts.max(axis=0) + 40   # the view

    def rects(fp, **kw):
        patches = [Rectangle((f[0], f[1]), f[2] - f[0], f[3] - f[1]) for f in fp]
        ax.add_collection(PatchCollection(patches, **kw))

    if geometry.full_canyon is not None:
        rects(geometry.full_canyon.footprints, facecolor="0.88", edgecolor="none")
        rects(scene.footprints, facecolor="0.45", edgecolor="none")
    else:
        # a mesh scene's buildings seen from above: their faces projected (walls project to
        # their outlines, roofs fill the footprints); light: left out by the crop
        full = getattr(geometry, "full_mesh", None)
        for s, colour in (((full or scene), "0.88"), (scene, "0.45")):
            tri = s.building_triangles[:, :, :2]
            # only what the view shows: a city's mesh holds tens of thousands of triangles
            seen = np.all((tri.max(axis=1) >= lo) & (tri.min(axis=1) <= hi), axis=1)
            ax.add_collection(matplotlib.collections.PolyCollection(
                tri[seen], facecolor=colour, edgecolor=colour, linewidths=0.3, rasterized=True))
    seg = np.stack([ue[:-1, :2], ue[1:, :2]], axis=1)
    lc = LineCollection(seg, cmap="viridis", linewidths=2.0)
    lc.set_array(geometry.ue.t[:-1])
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, fraction=0.035, pad=0.02, label="time [s]")
    adv = geometry.adversary.pos
    ax.plot(adv[::5, 0], adv[::5, 1], ".", color="tab:orange", ms=3, label="adversary (every 5th)")
    ax.plot(ue[0, 0], ue[0, 1], "o", color="tab:green", ms=8, label="UE start")
    layout = geometry.layout
    if layout is not None:
        cells = np.unique(layout.cell_of(ue[:, :2]), axis=0)
        ang = np.deg2rad(np.arange(0, 361, 60) + 30.0) + layout.rotation
        for c in layout.cell_centre(cells):
            ax.plot(c[0] + layout.side * np.cos(ang), c[1] + layout.side * np.sin(ang), "--",
                    color="tab:red", lw=0.8, alpha=0.6)
    draw_bs(ax, bs, serving, label="candidate sites (chosen by traced power)"
            if getattr(geometry, "candidates", None) is not None else SERVING_LABEL)
    for i, p in enumerate(bs):
        ax.annotate(f"BS{i} ({p[2]:.0f} m)", p[:2], textcoords="offset points", xytext=(6, 6),
                    fontsize=9)
    az = getattr(geometry, "bs_azimuth", None)
    if az is not None and np.any(np.isfinite(az)):
        on = np.isfinite(az)
        ax.quiver(bs[on, 0], bs[on, 1], np.cos(az[on]), np.sin(az[on]), color="tab:red",
                  scale=25, width=0.004)
    if estimated_xy is not None:
        ax.plot(estimated_xy[:, 0], estimated_xy[:, 1], "x", color="tab:purple", ms=3,
                label="estimated")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (east) [m]")
    ax.set_ylabel("y (north) [m]")
    ax.set_title(title or "Scene top view")
    # below the axes: covers nothing, and needs no search over the drawn buildings (which "best"
    # makes, slow on a city's mesh)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3, fontsize=8, frameon=False)
    if path is None:
        return fig
    return save_figure(fig, path)
