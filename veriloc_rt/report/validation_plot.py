"""The figure of ``veriloc-rt validate``: traced path loss against distance beside the models."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..propagation.pathloss_models import VALIDITY, RooftopGeometry
from .plots import drawn

_STYLE = {"free_space": "0.35", "p1411": "tab:red", "cost231_wi": "tab:orange",
          "uma_nlos": "tab:green", "umi_nlos": "tab:purple"}


def plot_validation_pathloss(res, path: str | Path | None, models: dict, model_db,
                             title: str | None = None, ax=None):
    """Scatter of the traced links (NLoS dots, LoS triangles), per-bin traced medians with
    p10-p90 bars, and each model's curve at the scene's geometry (median phi and covered
    fraction of the links); a curve is dashed where an input other than the distance lies
    outside the model's stated range, dotted outside its distance range. Log-distance axis.

    :param res: a :class:`veriloc_rt.studies.validate.ValidationResult`
    :param models: ``{name: (label, source)}`` of the models drawn
        (:data:`veriloc_rt.studies.validate.MODELS`)
    :param model_db: ``model_db(name, d_2d, phi, covered, fc, geo)``, a model's path loss, dB
        (:func:`veriloc_rt.studies.validate.model_db`)
    :param ax: a matplotlib ``Axes`` to draw on (``path`` unused): the Figure is returned, as
        it is without ``ax`` and ``path``; with ``path`` the figure is saved there and the path
        returned
    """

    inp, lk = res.inputs, res.links
    geo = RooftopGeometry(inp["h_bs_m"], inp["h_ue_m"], inp["h_roof_m"], inp["street_width_m"],
                          inp["building_separation_m"])
    fc = inp["carrier_frequency_hz"]
    d, has, los = lk["d_2d_m"], lk["has_path"], lk["los"]
    lo = max(10.0, 0.8 * float(d.min())) if d.size else 10.0
    hi = max(1.2 * float(d.max()), 2.0 * lo) if d.size else 1000.0
    grid = np.geomspace(lo, hi, 300)
    phi = np.full_like(grid, np.radians(inp["phi_deg_median"]))
    title = title or (f"path loss: ray tracing vs models (f = {fc / 1e9:g} GHz, median phi "
                      f"{inp['phi_deg_median']:.0f} deg)")

    def draw(_, axes):
        ax = axes[0, 0]
        nl = has & ~los
        ax.scatter(d[nl], lk["pl_db"][nl], s=10, color="0.6", alpha=0.7,
                   label=f"traced NLoS links (n={int(nl.sum())})")
        if np.any(has & los):
            ax.scatter(d[has & los], lk["pl_db"][has & los], s=18, marker="^", color="tab:blue",
                       alpha=0.8, label=f"traced LoS links (n={int((has & los).sum())})")
        for name, (label, _src) in models.items():
            y = model_db(name, grid, phi, inp["covered_fraction_median"] * grid, fc, geo)
            dlo, dhi = VALIDITY[name].get("d_m", (0.0, np.inf))
            inside = (grid >= dlo) & (grid <= dhi)
            flagged = [f for f in res.flags[name] if "links" not in f]   # scene-wide inputs only
            style = "--" if flagged else "-"
            text = label + (f" (outside validity: {flagged[0]})" if flagged else "")
            ax.plot(np.where(inside, grid, np.nan), y, style, color=_STYLE[name], lw=1.6,
                    label=text)
            ax.plot(np.where(inside, np.nan, grid), y, ":", color=_STYLE[name], lw=1.2)
        centres = np.array([b["d_centre_m"] for b in res.bins])
        med = np.array([np.nan if b["traced_db"]["p50"] is None else b["traced_db"]["p50"]
                        for b in res.bins])
        p10 = np.array([np.nan if b["traced_db"]["p10"] is None else b["traced_db"]["p10"]
                        for b in res.bins])
        p90 = np.array([np.nan if b["traced_db"]["p90"] is None else b["traced_db"]["p90"]
                        for b in res.bins])
        ok = np.isfinite(med)
        if ok.any():
            ax.errorbar(centres[ok], med[ok], yerr=[med[ok] - p10[ok], p90[ok] - med[ok]],
                        fmt="s", color="k", ms=5, capsize=3,
                        label=f"traced median per {inp['bin_width_m']:g} m bin (p10-p90)")
        n_none = int((~has).sum())
        if n_none:
            ax.plot([], [], " ", label=f"{n_none} link{'s' if n_none > 1 else ''} without a path "
                    "(not plotted)")
        ax.set_xscale("log")
        from matplotlib.ticker import FixedLocator, NullFormatter
        ticks = [t for t in (10, 20, 50, 100, 200, 500, 1000, 2000, 5000) if lo <= t <= hi]
        ax.xaxis.set_major_locator(FixedLocator(ticks))
        ax.xaxis.set_major_formatter(lambda v, _pos: f"{v:g}")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("2-D BS-UE distance, m")
        ax.set_ylabel("path loss, dB")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="upper left", fontsize=7)

    return drawn(path, ax, title, draw, figsize=(9.0, 6.0))
