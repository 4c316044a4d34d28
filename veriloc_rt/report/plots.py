"""Result figures: outcome and detection-rate bars, per-point time series, trajectory map.

Inputs are what the engine writes: ``<scenario>_results.csv`` (read with :func:`read_results_csv`)
and the ``metrics.json`` dict ``{"scenarios": {scenario: {"outcomes": .., "outcomes_encrypted": ..,
"correct_decision_rate": .., "position_error_m": ..}}}`` with shares as fractions in [0, 1]
(the figures draw them in percent). The figures follow
the paper's Fig. "encrypted_PRS", Fig. "techniques" and Fig. "all_attacks".
"""

from __future__ import annotations

import csv
import logging
import threading
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

import numpy as np

from veriloc_rt.errors import InputError, bad_value
from veriloc_rt.fileio import atomic_output

from ..attacks.threats import scenario_labels
from ..detectors.outcomes import DETECTORS, OUTCOMES
from .results import CSV_COLUMNS

log = logging.getLogger(__name__)

COLUMNS = CSV_COLUMNS
STR_COLUMNS = ("outcome", "outcome_enc", "bs_excluded")
INT_COLUMNS = ("index", "bs_heard", "bs_used")

_SCENARIO_LABELS = scenario_labels()   # the threat registry's, at import: the built-ins
_DETECTOR_STYLE = {  # display label, colour (the paper's pgfplots colours)
    "HMAC": ("HMAC", (0.0, 0.0, 0.6)), "DigSig": ("DigSig", (0.7, 0.0, 0.0)),
    "ABSA": ("ABSA", (0.3, 0.65, 0.65)), "Handshake": ("Handshake", (1.0, 0.6, 0.2)),
    "Tracking": ("Tracking", (0.3, 0.3, 0.3))}
_OUTCOME_COLOURS = {"success": (0.0, 0.6, 0.0), "large_error": (1.0, 0.3, 0.3),
                    "service_failure": (0.75, 0.75, 0.75)}
#: fixed margins (left, right, bottom, top), inches, of the bar charts: the y tick labels and
#: label, the scenario names (rotated 30 degrees under the outcome bars) and the legend row
#: above the axes, all known in advance
_BAR_MARGINS_IN = {"outcomes": (0.65, 0.1, 0.7, 0.35), "rates": (0.65, 0.1, 0.32, 0.32)}
#: fixed margins of the trajectory map, inches: tick labels of up to five characters and the
#: axis labels (the equal-aspect axes then shrink to fit, centred)
_MAP_MARGINS_IN = (0.8, 0.15, 0.6, 0.15)


#: savefig options by file suffix: PNG at zlib level 1 (the same pixels; encoding takes
#: 15-30 ms instead of 26-58 ms per run figure, files 10-40 % larger)
_SAVE_KW = {".png": {"pil_kwargs": {"compress_level": 1}}}
#: resolution of raster figures (PNG), dots per inch; :func:`figure_dpi` changes it
DEFAULT_DPI = 110
_DPI: ContextVar[int] = ContextVar("figure_dpi", default=DEFAULT_DPI)


@contextmanager
def figure_dpi(dpi: int):
    """Save the figures of the block at ``dpi`` (raster formats; PDF and SVG are vector, their
    fonts and lines do not depend on it)."""
    token = _DPI.set(int(dpi))
    try:
        yield
    finally:
        _DPI.reset(token)


#: height the figure's title (``suptitle``, 'large' font, at 98 % of the figure's height) takes
#: above the margins, inches
TITLE_IN = 0.3


def fixed_margins(fig, margins_in: tuple[float, float, float, float], title: bool,
                  wspace_in: float = 0.0) -> None:
    """Place ``fig``'s subplot grid at fixed margins: ``(left, right, bottom, top)`` inches from
    the figure's edges (``top`` under the title, :data:`TITLE_IN`, when there is one), the
    columns ``wspace_in`` inches apart."""
    w, h = fig.get_size_inches()
    left, right, bottom, top = margins_in
    top += TITLE_IN if title else 0.0
    ncols = fig.axes[0].get_subplotspec().get_gridspec().ncols if fig.axes else 1
    axes_w = (w - left - right - (ncols - 1) * wspace_in) / ncols
    fig.subplots_adjust(left=left / w, right=1.0 - right / w, bottom=bottom / h, top=1.0 - top / h,
                        wspace=wspace_in / axes_w)


@contextmanager
def figure(path: str | Path, title: str | None, nrows: int = 1, figsize=(8.0, 5.0), ncols: int = 1,
           layout: str | None = "constrained", margins_in: tuple | None = None,
           wspace_in: float = 0.0, **kw):
    """Yield ``(fig, axes)`` on the Agg backend; on a clean exit add ``title``, save, log.

    The figure is closed in every case. ``layout`` and ``kw`` go to ``Figure.subplots``: a
    matplotlib ``Figure`` outside pyplot (no pyplot state, and no pyplot import).
    ``margins_in``: fixed margins instead of a layout engine (:func:`fixed_margins`), for the
    figures whose labels are known in advance: a layout engine makes ``savefig`` draw the
    figure twice, once to measure every label and once to render it.
    """
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if margins_in is not None:
        layout = None
    fig = Figure(figsize=figsize, dpi=110, layout=layout)
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, **kw)
    if margins_in is not None:
        fixed_margins(fig, margins_in, bool(title), wspace_in)
    try:
        yield fig, axes
        if title:
            fig.suptitle(title)
        with atomic_output(path) as tmp:   # a stopped run leaves no half-written PNG
            fig.savefig(tmp, dpi=_DPI.get(), **_SAVE_KW.get(Path(path).suffix.lower(), {}))
        log.info("wrote %s", path)
    finally:
        fig.clear()


def _scenarios(metrics: dict, key: str) -> list[tuple[str, dict]]:
    """``(scenario, metrics["scenarios"][scenario][key])`` in the canonical order, present only."""
    if not isinstance(metrics, dict) or not isinstance(metrics.get("scenarios", {}), dict):
        raise TypeError(f"Argument `metrics` must be a dict with a 'scenarios' dict, "
                        f"not {type(metrics).__name__}")
    sc = metrics.get("scenarios", {})
    order = [s for s in _SCENARIO_LABELS if s in sc] + [s for s in sc if s not in _SCENARIO_LABELS]
    return [(s, sc[s][key]) for s in order if isinstance(sc[s], dict) and sc[s].get(key)]


def _percent_axis(ax, top: float, ylabel: str, has_data: bool, ncols: int) -> None:
    """0..100 % y axis with head room up to ``top``; legend above the axes, or "no data"."""
    ax.set_ylim(0.0, top)
    ax.set_yticks(np.arange(0, 101, 20))
    ax.set_ylabel(ylabel)
    ax.grid(axis="y", ls="--", alpha=0.3)
    if has_data:
        ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncols=ncols, fontsize=8,
                  frameon=False)
    else:
        ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center", va="center")


def _value(d: dict, key: str) -> float:
    """``d[key]`` as float, NaN when missing or None."""
    v = d.get(key)
    return float("nan") if v is None else float(v)


#: the value metrics.json stores for a rate or share of 1 (all of the points): 100.0 while the
#: scenario rates are percent, 1.0 once they are fractions. The one place the plots take the
#: unit from (:func:`rate_percent`, :func:`rate_interval`)
RATE_FULL_SCALE = 1.0


def rate_percent(v) -> float:
    """A rate or share as metrics.json stores it (:data:`RATE_FULL_SCALE`), in percent (what
    the plots draw); NaN for None."""
    return float("nan") if v is None else 100.0 * float(v) / RATE_FULL_SCALE


def rate_interval(block: dict, key: str, name: str) -> tuple[float, float] | None:
    """The 95 % interval, percent, of the rate ``block[key][name]`` (e.g. ``key``
    'correct_decision_rate', ``name`` a detector; ``key`` 'outcomes', ``name`` an outcome), or
    None when the metrics hold none.

    Read from, in this order: the sibling ``block[key + "_ci95"][name]`` = [lo, hi]; the sibling
    inside the rate's own dict, ``block[key][name + "_ci95"]`` = [lo, hi]; a Monte Carlo
    aggregate's ``block["ci95"][key][name]``, a half-width around the mean (clipped to
    0..100 %: a rate cannot leave it; the t-interval of few realisations can).
    """
    def pair(v):
        if isinstance(v, (list, tuple)) and len(v) == 2 and all(x is not None for x in v):
            lo, hi = rate_percent(v[0]), rate_percent(v[1])
            if np.isfinite(lo) and np.isfinite(hi):
                return min(lo, hi), max(lo, hi)
        return None

    sib = block.get(f"{key}_ci95")
    if isinstance(sib, dict) and pair(sib.get(name)) is not None:
        return pair(sib.get(name))
    own = block.get(key)
    if isinstance(own, dict) and pair(own.get(f"{name}_ci95")) is not None:
        return pair(own.get(f"{name}_ci95"))
    half = ((block.get("ci95") or {}).get(key) or {}).get(name)
    mean = rate_percent((own or {}).get(name)) if isinstance(own, dict) else float("nan")
    if half is None or not np.isfinite(mean):
        return None
    h = rate_percent(half)
    return max(mean - h, 0.0), min(mean + h, 100.0)


def _error_bars(ax, x, v, intervals, **kw) -> None:
    """Error bars at ``x`` from each bar top ``v`` (percent) to its interval (lo, hi), for the
    bars that have a value and an interval (the others get none)."""
    ok = [i for i, (vi, ci) in enumerate(zip(v, intervals)) if ci is not None and np.isfinite(vi)]
    if not ok:
        return
    lo = np.array([intervals[i][0] for i in ok])
    hi = np.array([intervals[i][1] for i in ok])
    vv = np.asarray(v, dtype=float)[ok]
    err = np.array([np.maximum(vv - lo, 0.0), np.maximum(hi - vv, 0.0)])
    ax.errorbar(np.asarray(x, dtype=float)[ok], vv, yerr=err, fmt="none", ecolor="k",
                capsize=2.0, lw=0.8, **kw)


def drawn(path, ax, title, draw, nrows=1, ncols=1, figsize=(8.0, 5.0), **figure_kw):
    """Run ``draw(fig, axes)`` (``axes`` a [nrows, ncols] array) on the caller's ``ax`` or on a
    new Figure (both returned as the Figure; ``title`` the one panel's title, or the figure's
    above several), or, with ``path`` and no ``ax``, on a figure saved to ``path`` (returned).
    ``figure_kw`` to :func:`figure` (margins) when saving."""
    if ax is not None or path is None:
        fig, axes = new_axes(ax, nrows, ncols, figsize=figsize, squeeze=False)
        draw(fig, axes)
        if title:
            if axes.size == 1:
                axes[0, 0].set_title(title)
            else:
                fig.suptitle(title)
        return fig
    with figure(path, title, nrows=nrows, ncols=ncols, figsize=figsize, squeeze=False,
                **figure_kw) as (fig, axes):
        draw(fig, axes)
    return Path(path)


def plot_rates_ci(metrics: dict, path: str | Path | None = None, title: str | None = None,
                  ax=None):
    """Grouped bars of the mean correct-decision rate per scenario and detector, with the
    95 % intervals (:func:`rate_interval`) as error bars; none below two realisations. A
    detector a scenario flags uninformative (in any realisation) gets no bar and an "uninf."
    label.

    :param ax: a matplotlib ``Axes`` to draw on (``path`` unused): the Figure is returned, as
        it is without ``ax`` and ``path``; with ``path`` the figure is saved there, the path
        returned
    """
    sc = metrics["scenarios"]
    names = [s for s in sc if sc[s].get("correct_decision_rate")]
    width = 0.16

    def draw(_, axes):
        ax = axes[0, 0]
        x = np.arange(len(names), dtype=float)
        for k, det in enumerate(DETECTORS):
            xs = x + (k - (len(DETECTORS) - 1) / 2.0) * width
            mean = np.array([np.nan if det in _uninformative(metrics, s)   # no attack bar
                             else rate_percent(sc[s]["correct_decision_rate"].get(det))
                             for s in names])
            ci = [rate_interval(sc[s], "correct_decision_rate", det) for s in names]
            label, colour = _DETECTOR_STYLE[det]
            ax.bar(xs, np.nan_to_num(mean), width, color=colour, label=label)
            _error_bars(ax, xs, mean, ci)
            for xi, m, c, s in zip(xs, mean, ci, names):
                tag = "uninf." if det in _uninformative(metrics, s) else "n/a"
                top = max(np.nan_to_num(m), c[1] if c is not None and np.isfinite(m) else 0.0)
                ax.text(xi, top + 1.0, tag if np.isnan(m) else f"{m:.1f}", rotation=90,
                        ha="center", va="bottom", fontsize=6)
        ax.set_xticks(x, [_SCENARIO_LABELS.get(s, s) for s in names])
        ax.set_xlim(-0.6, max(len(names), 1) - 0.4)
        _percent_axis(ax, 118.0, "Correct decision rate [%]", bool(names), ncols=5)

    return drawn(path, ax, title, draw, figsize=(9.0, 4.5))


def plot_outcomes(metrics: dict, path: str | Path | None = None, title: str | None = None,
                  threshold_m: float = 15.0, ax=None):
    """Stacked outcome bars per scenario: standard PRS group, then encrypted PRS group.

    Success green, large error red, service failure gray (paper Fig. "encrypted_PRS"). The
    encrypted group is left out when no scenario has ``outcomes_encrypted``; missing or None
    shares are drawn as 0. A share's 95 % interval (:func:`rate_interval`), where the metrics
    hold one, is an error bar at the top of its segment.

    :param threshold_m: success threshold, m, only used in the legend label
    :param ax: a matplotlib ``Axes`` to draw on (``path`` unused): the Figure is returned, as
        it is without ``ax`` and ``path``; with ``path`` the figure is saved there, the path
        returned
    """
    groups = [(name, key, _scenarios(metrics, key)) for name, key in
              (("Standard PRS", "outcomes"), ("Encrypted PRS", "outcomes_encrypted"))]
    groups = [g for g in groups if g[2]]
    labels = {"success": f"Success (error ≤ {threshold_m:g} m)",
              "large_error": f"Large error / spoofing (> {threshold_m:g} m)",
              "service_failure": "Service failure"}
    sc = metrics.get("scenarios", {})

    def draw(_, axes):
        ax = axes[0, 0]
        ticks, ticklabels, start = [], [], 0.0
        for gi, (name, key, entries) in enumerate(groups):
            x = start + np.arange(len(entries), dtype=float)
            bottom = np.zeros(len(entries))
            for o in OUTCOMES:
                h = np.nan_to_num([rate_percent(e.get(o)) for _, e in entries])
                ax.bar(x, h, 0.7, bottom=bottom, color=_OUTCOME_COLOURS[o], edgecolor="k",
                       label=labels[o] if gi == 0 else None)
                # the share's interval, moved to the top of its segment
                ci = [rate_interval(sc[s], key, o) for s, _ in entries]
                moved = [None if c is None else (c[0] + b, c[1] + b) for c, b in zip(ci, bottom)]
                _error_bars(ax, x, bottom + h, moved)
                bottom += h
            centre = start + (len(entries) - 1) / 2.0
            ax.text(centre, 104.0, name, ha="center", va="bottom", fontweight="bold")
            if gi > 0:
                ax.axvline(start - 0.75, color="k", lw=1.5)
            ticks += list(x)
            ticklabels += [_SCENARIO_LABELS.get(s, s) for s, _ in entries]
            start += len(entries) + 0.5
        ax.set_xticks(ticks, ticklabels, rotation=30, ha="right")
        _percent_axis(ax, 112.0, "Percentage of outcomes [%]", bool(groups), ncols=3)

    return drawn(path, ax, title, draw, figsize=(8.0, 5.0), margins_in=_BAR_MARGINS_IN["outcomes"])


def plot_detection_rates(metrics: dict, path: str | Path | None = None, title: str | None = None,
                         reference: dict | None = None, ax=None):
    """Grouped correct-decision-rate bars: x = scenario, one bar per detector, values written on.

    Undefined (None) rates get no bar and an "n/a" label; a detector a scenario flags
    uninformative (its ``uninformative_detectors``: its rejections are no detections) gets no
    bar and an "uninf." label. A rate's 95 % interval (:func:`rate_interval`), where the
    metrics hold one, is an error bar. ``reference`` ({scenario: {detector: percent}}, e.g. the
    paper's Fig. "techniques") is drawn as dashed black outlines labelled "paper".

    :param ax: a matplotlib ``Axes`` to draw on (``path`` unused): the Figure is returned, as
        it is without ``ax`` and ``path``; with ``path`` the figure is saved there, the path
        returned
    """
    entries = _scenarios(metrics, "correct_decision_rate")
    reference = reference or {}
    if not isinstance(reference, dict):
        raise TypeError(f"Argument `reference` must be a dict or None, "
                        f"not {type(reference).__name__}")
    sc = metrics.get("scenarios", {})
    return drawn(path, ax, title,
                  lambda _, axes: _draw_detection_rates(axes[0, 0], metrics, sc, entries,
                                                        reference),
                  figsize=(9.0, 4.5), margins_in=_BAR_MARGINS_IN["rates"])


def _draw_detection_rates(ax, metrics: dict, sc: dict, entries: list, reference: dict) -> None:
    """The bars of :func:`plot_detection_rates` on ``ax``."""
    width = 0.16
    x = np.arange(len(entries), dtype=float)
    offsets = (np.arange(len(DETECTORS)) - (len(DETECTORS) - 1) / 2.0) * width
    xs = x[None, :] + offsets[:, None]  # [num_detectors, num_scenarios]
    uninf = [_uninformative(metrics, s) for s, _ in entries]
    vals = np.array([[np.nan if d in u else rate_percent(e.get(d))
                      for (_, e), u in zip(entries, uninf)] for d in DETECTORS])
    cis = [[rate_interval(sc[s], "correct_decision_rate", d) for s, _ in entries]
           for d in DETECTORS]
    tags = [["uninf." if d in u else "n/a" for u in uninf] for d in DETECTORS]
    refs = np.array([[_value(reference.get(s) or {}, d) for s, _ in entries]
                     for d in DETECTORS])
    for det, xk, vk, ck in zip(DETECTORS, xs, vals, cis):
        label, colour = _DETECTOR_STYLE[det]
        ax.bar(xk, np.nan_to_num(vk), width, color=colour, label=label)
        _error_bars(ax, xk, vk, ck)
    ref = np.isfinite(refs)
    if ref.any():
        ax.bar(xs[ref], refs[ref], width, fill=False, edgecolor="k", ls="--", lw=0.8,
               label="paper")
    tops = np.array([[c[1] if c is not None else np.nan for c in ck] for ck in cis])
    for xi, v, r, t, tag in zip(xs.ravel(), vals.ravel(), refs.ravel(), tops.ravel(),
                                np.ravel(tags)):
        ax.text(xi, np.nanmax([0.0, v, r, t if np.isfinite(v) else np.nan]) + 1.0,
                tag if np.isnan(v) else f"{v:.1f}", rotation=90, ha="center", va="bottom",
                fontsize=6)
    ax.set_xticks(x, [_SCENARIO_LABELS.get(s, s) for s, _ in entries])
    ax.set_xlim(-0.6, max(len(entries), 1) - 0.4)
    _percent_axis(ax, 118.0, "Correct decision rate [%]", bool(entries), ncols=6)


def _uninformative(metrics: dict, scenario: str) -> set:
    """The detectors ``scenario`` flags uninformative in ``metrics`` (a metrics.json dict or its
    ``scenarios`` block)."""
    sc = metrics.get("scenarios", metrics) if isinstance(metrics, dict) else {}
    return set((sc.get(scenario) or {}).get("uninformative_detectors") or ())


def _columns(rows: dict, names) -> list[np.ndarray]:
    """``rows[name]`` for each name as 1-D arrays of one common length."""
    if not isinstance(rows, dict):
        raise TypeError(f"Argument `rows` must be a dict of column arrays, "
                        f"not {type(rows).__name__}")
    missing = [n for n in names if n not in rows]
    if missing:
        raise InputError("rows", f"missing column(s) {', '.join(missing)}")
    cols = [np.asarray(rows[n]).ravel() for n in names]
    if len({len(c) for c in cols}) > 1:
        raise InputError("rows", f"columns {', '.join(names)} differ in length "
                         f"{[len(c) for c in cols]}")
    return cols


def plot_time_series(rows: dict, path: str | Path | None, attack_window: tuple[int, int] | None,
                     title: str | None = None, threshold_m: float = 15.0, ax=None):
    """Five valid/invalid step panels (one per detector) and an error panel over the trajectory.

    x is the 1-based trajectory point (``index + 1``, paper Fig. "all_attacks"). The error panel
    has a log y axis, gaps where there was no fix, and the success threshold as a dashed line.

    :param rows: column name -> [num_points] array, as from :func:`read_results_csv`
    :param attack_window: ``(start, stop)`` 0-based points, stop excluded (as
        ``RunConfig.attack_points``), shaded red; None for no shading
    :param threshold_m: success threshold, m
    :param ax: six matplotlib ``Axes`` to draw on, top to bottom (a sequence; one step panel
        per detector in :data:`DETECTORS` order, then the error panel); ``path`` unused, the
        first one's Figure returned. Without ``ax`` and ``path`` a new Figure is returned;
        with ``path`` the figure is saved there and the path returned
    """
    *dets, err = _columns(rows, DETECTORS + ("error_m",))
    idx = np.asarray(rows["index"]).ravel() if "index" in rows else np.arange(len(err))
    if len(idx) != len(err):
        raise InputError("rows", f"column index has {len(idx)} entries, expected {len(err)}")
    if attack_window is not None:
        ok = (isinstance(attack_window, (tuple, list)) and len(attack_window) == 2
              and all(isinstance(a, (int, np.integer)) for a in attack_window))
        if not ok or not 0 <= attack_window[0] <= attack_window[1]:
            raise bad_value("attack_window", attack_window, "(start, stop) ints, 0 <= start <= stop")
    x = idx.astype(float) + 1.0
    err = np.maximum(err.astype(float), 1e-2)  # log axis: a zero error sits at 1 cm
    dets = [d.astype(float) for d in dets]
    if ax is not None or path is None:
        if ax is None:
            fig = new_figure((10.0, 9.0))
            axes = fig.subplots(len(DETECTORS) + 1, 1, sharex=True,
                                height_ratios=[1] * len(DETECTORS) + [1.6])
        else:
            fig, axes = new_axes(ax, len(DETECTORS) + 1, 1)
        ts = _TimeSeriesFigure(bool(title), threshold_m, axes=list(np.ravel(axes)))
        ts.show(x, dets, err, attack_window)
        if title:
            fig.suptitle(title)
        return fig
    path = Path(path)
    with _kept_figure(("time series", bool(title), float(threshold_m)),
                      lambda: _TimeSeriesFigure(bool(title), threshold_m)) as ts:
        ts.draw(path, x, dets, err, attack_window, title)
    log.info("wrote %s", path)
    return path


class _KeptFigure:
    """A figure kept from plot to plot (:data:`_KEPT`): saving under a title, clearing."""

    fig = None

    def _save(self, path: Path, title: str | None) -> None:
        if title:
            self.fig.suptitle(title)
        with atomic_output(path) as tmp:   # a stopped run leaves no half-written PNG
            self.fig.savefig(tmp, dpi=_DPI.get(), **_SAVE_KW.get(path.suffix.lower(), {}))

    def close(self) -> None:
        self.fig.clear()


class _TimeSeriesFigure(_KeptFigure):
    """:func:`plot_time_series`' figure, built once per process and layout (title or none,
    threshold) and then updated for each scenario: its data, limits, attack window and title.

    Building the six panels and their ticks was half of each figure's time; the updated figure
    gives the pixels a new one gives (tests/unit/report/test_plots.py). Kept by
    :func:`_kept_figure`, a matplotlib ``Figure`` outside pyplot.
    """

    def __init__(self, titled: bool, threshold_m: float, axes: list | None = None):
        """``axes``: six Axes of another figure to draw on (not kept: :func:`plot_time_series`
        with ``ax=``)."""
        if axes is not None:
            self.fig, self.axes = axes[0].figure, axes
        else:
            import matplotlib
            matplotlib.use("Agg")
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.fig = Figure(figsize=(10.0, 9.0), dpi=110)
            FigureCanvasAgg(self.fig)
            self.axes = self.fig.subplots(6, 1, sharex=True, height_ratios=[1] * 5 + [1.6])
            # fixed margins: the labels are the same on every run ("Invalid", "error [m]", ...)
            self.fig.subplots_adjust(left=0.09, right=0.985, bottom=0.06,
                                     top=0.95 if titled else 0.985, hspace=0.12)
        self.steps = []
        for ax, det in zip(self.axes, DETECTORS):
            label, colour = _DETECTOR_STYLE[det]
            self.steps.append(ax.step([], [], where="post", color=colour, lw=1.8)[0])
            ax.set_ylim(-0.2, 1.2)
            ax.set_yticks([0, 1], ["Invalid", "Valid"])
            ax.set_ylabel(label)
        ax = self.axes[-1]
        self.error = ax.plot([], [], ".-", color="k", ms=2, lw=0.6, label="position error")[0]
        self.threshold_m = threshold_m
        ax.axhline(threshold_m, color="tab:red", ls="--", lw=1.0, label=f"{threshold_m:g} m")
        ax.set_yscale("log")
        _plain_log_labels(ax.yaxis)
        ax.set_ylabel("error [m]")
        ax.set_xlabel("Trajectory point")
        ax.legend(loc="upper right", fontsize=7)
        self.spans: list = []

    def draw(self, path: Path, x: np.ndarray, dets: list, err: np.ndarray,
             attack_window: tuple[int, int] | None, title: str | None) -> None:
        """Show one scenario and save the figure to ``path``."""
        self.show(x, dets, err, attack_window)
        self._save(path, title)

    def show(self, x: np.ndarray, dets: list, err: np.ndarray,
             attack_window: tuple[int, int] | None) -> None:
        """Show one scenario's data, limits and attack window."""
        for line, y in zip(self.steps, dets):
            line.set_data(x, y)
        self.error.set_data(x, err)
        t = self.threshold_m
        finite = err[np.isfinite(err)]
        self.axes[-1].set_ylim(min(finite.min(initial=t), t) / 2.0, max(finite.max(initial=t), t) * 2.0)
        for a in self.axes:   # shared on the kept figure; maybe not on the caller's axes
            a.set_xlim(0.0, max(x.max(initial=1.0), 1.0))
        while self.spans:
            self.spans.pop().remove()
        if attack_window is not None:
            self.spans = [a.axvspan(attack_window[0] + 0.5, attack_window[1] + 0.5, color="red",
                                    alpha=0.15, lw=0) for a in self.axes]


class _MapFigure(_KeptFigure):
    """:func:`plot_trajectory_map`'s figure and axes, kept like :class:`_TimeSeriesFigure`:
    each map removes the previous one's lines and legend and draws its own on the same axes,
    whose ticks are then made once."""

    def __init__(self, titled: bool):
        import matplotlib
        matplotlib.use("Agg")
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.fig = Figure(figsize=(8.0, 8.0), dpi=110)
        FigureCanvasAgg(self.fig)
        self.ax = self.fig.subplots()
        fixed_margins(self.fig, _MAP_MARGINS_IN, titled)

    def clean_axes(self):
        """The axes without the previous map's lines and legend."""
        for artist in [*self.ax.lines, *self.ax.collections, *self.ax.patches]:
            artist.remove()
        if self.ax.get_legend() is not None:
            self.ax.get_legend().remove()
        return self.ax

    def save(self, path: Path, title: str | None) -> None:
        self._save(path, title)


#: the figures kept for reuse, by kind and layout, and their lock (one is drawn at a time)
_KEPT: dict[tuple, object] = {}
_KEPT_LOCK = threading.Lock()


@contextmanager
def _kept_figure(key: tuple, build):
    """The kept figure ``key`` (``build()`` makes it the first time), held under the lock; one
    left half-updated by an exception is dropped, so that the next call builds anew."""
    with _KEPT_LOCK:
        fig = _KEPT.get(key)
        if fig is None:
            fig = _KEPT[key] = build()
        try:
            yield fig
        except BaseException:
            _KEPT.pop(key).close()
            raise


def clear_figure_cache() -> None:
    """Forget the figures kept for reuse (time series, maps): the next ones are built anew."""
    with _KEPT_LOCK:
        while _KEPT:
            _KEPT.popitem()[1].close()


def _plain_log_labels(axis) -> None:
    """A log axis's tick labels as plain numbers (``0.5``, ``20``, ``1000``) on the ticks the
    default labels (decades; the minor ticks too on an axis spanning about one decade): the
    default ``10^{n}`` labels are mathtext, whose parser and layout cost a tenth of a second
    on the first figure and ~0.03 s on each one after it."""
    from matplotlib.ticker import LogFormatter

    class PlainLogFormatter(LogFormatter):
        def _num_to_string(self, x, vmin, vmax):
            return f"{x:g}"

    axis.set_major_formatter(PlainLogFormatter())
    axis.set_minor_formatter(PlainLogFormatter(labelOnlyBase=False))


def _xy(arr, name: str) -> np.ndarray:
    """[n, 2] float64 from an [n, 2] or [n, 3] array-like named ``name``."""
    a = np.asarray(arr, dtype=float)
    if a.ndim != 2 or a.shape[1] not in (2, 3):
        raise bad_value(name, f"array of shape {a.shape}", "shape [n, 2] or [n, 3]")
    return a[:, :2]


#: face colour of the buildings under the trajectory map (light: the paths drawn over them stay
#: legible)
_BUILDING_COLOUR = "0.82"


def map_buildings(geometry) -> np.ndarray:
    """The buildings of ``geometry``'s scene seen from above, for :func:`plot_trajectory_map`:
    the procedural canyon's footprints as [num_buildings, 4] float64 rectangles, m (x_min,
    y_min, x_max, y_max), or a mesh scene's (OpenStreetMap import, Mitsuba XML) building faces
    projected to the ground as [num_faces, 3, 2] float64 triangles, m, walls (no projected area)
    left out: the roofs fill the footprints.

    :param geometry: a :class:`~veriloc_rt.world.geometry.Geometry` (its ``scene``)
    """
    scene = geometry.scene
    fp = getattr(scene, "footprints", None)
    if fp is not None:
        return np.asarray(fp, dtype=float).reshape(-1, 4)
    tri = np.asarray(scene.building_triangles, dtype=float).reshape(-1, 3, 3)[:, :, :2]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                        - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))
    return tri[area > _MIN_FACE_AREA_M2]


#: projected area below which a mesh face is a wall seen edge-on (not drawn on the map), m^2
_MIN_FACE_AREA_M2 = 1e-6


def _building_collection(buildings, lo: np.ndarray, hi: np.ndarray):
    """A matplotlib collection of the ``buildings`` (:func:`map_buildings`) within the view
    ``lo``..``hi``, or None when there are none there."""
    from matplotlib.collections import PolyCollection

    b = np.asarray(buildings, dtype=float)
    if b.size == 0:
        return None
    if b.ndim == 2 and b.shape[1] == 4:          # rectangles -> their four corners
        x0, y0, x1, y1 = b.T
        b = np.stack([np.stack([x0, y0], -1), np.stack([x1, y0], -1), np.stack([x1, y1], -1),
                      np.stack([x0, y1], -1)], axis=1)
    elif not (b.ndim == 3 and b.shape[2] == 2):
        raise bad_value("buildings", f"array of shape {b.shape}",
                        "[n, 4] rectangles or [n, k, 2] polygons")
    seen = np.all((b.max(axis=1) >= lo) & (b.min(axis=1) <= hi), axis=1)
    if not seen.any():
        return None
    return PolyCollection(b[seen], facecolor=_BUILDING_COLOUR, edgecolor=_BUILDING_COLOUR,
                          linewidths=0.3, zorder=0.5, label="buildings")


def new_axes(ax=None, nrows: int = 1, ncols: int = 1, figsize=(8.0, 5.0),
             squeeze: bool = True, **kw):
    """``(figure, axes)`` to draw on.

    With ``ax``: one matplotlib ``Axes`` for a one-panel figure, or a sequence of
    ``nrows * ncols`` of them (any nesting), returned as an array of that grid (squeezed as
    ``Figure.subplots`` squeezes), and the first one's figure. Without: a new ``Figure``
    outside pyplot (Agg canvas, constrained layout) with that grid of axes (``kw`` to
    ``Figure.subplots``).

    :raises InputError: ``ax`` holds another number of Axes than panels
    """
    if ax is not None:
        axes = np.asarray(ax, dtype=object).ravel()
        if axes.size != nrows * ncols:
            raise bad_value("ax", f"{axes.size} Axes", f"{nrows * ncols} Axes (one per panel)")
        grid = axes.reshape(nrows, ncols)
        return axes[0].figure, (grid.squeeze() if grid.size > 1 else grid[0, 0]) if squeeze \
            else grid
    fig = new_figure(figsize)
    return fig, fig.subplots(nrows, ncols, squeeze=squeeze, **kw)


def new_figure(figsize=(8.0, 5.0), layout: str | None = "constrained"):
    """A matplotlib ``Figure`` outside pyplot (no pyplot state): Agg canvas, ``layout``."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=DEFAULT_DPI, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig, path: str | Path, **kw) -> Path:
    """Save ``fig`` to ``path`` (format from the suffix: png, pdf, svg) at the resolution of
    :func:`figure_dpi`, atomically (a stopped run leaves no half-written file)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".").lower() or None, dpi=_DPI.get(),
                    **{**_SAVE_KW.get(path.suffix.lower(), {}), **kw})
    log.info("wrote %s", path)
    return path


def serving_mask(num_bs: int, serving) -> np.ndarray:
    """[num_bs] bool: the BSs some point measures (ids in ``serving``, any shape; negative
    ids, padding, are ignored)."""
    ids = np.asarray(serving, dtype=np.int64).ravel()
    mask = np.zeros(int(num_bs), bool)
    mask[ids[(ids >= 0) & (ids < num_bs)]] = True
    return mask


#: legend labels of the BS markers: measured by some point, or a candidate site no point chose
SERVING_LABEL, UNUSED_LABEL = "serving BSs", "candidate sites never chosen"


def draw_bs(ax, bs: np.ndarray, serving: np.ndarray | None = None, label: str = "BSs") -> None:
    """BS markers on ``ax``: with ``serving`` ([num_bs] bool) the BSs some point measures as
    filled red triangles (:data:`SERVING_LABEL`, with their count) and the others as hollow
    gray ones (:data:`UNUSED_LABEL`); without it every BS alike, as ``label``."""
    bs = np.asarray(bs)[:, :2]
    if serving is None:
        ax.plot(bs[:, 0], bs[:, 1], "^", color="tab:red", mec="k", ms=11, label=label)
        return
    serving = np.asarray(serving, bool)
    ax.plot(bs[serving, 0], bs[serving, 1], "^", color="tab:red", mec="k", ms=11,
            label=f"{SERVING_LABEL} ({int(serving.sum())})")
    if not serving.all():
        ax.plot(bs[~serving, 0], bs[~serving, 1], "^", color="none", mec="0.35", ms=9,
                label=f"{UNUSED_LABEL} ({int((~serving).sum())})")


def plot_trajectory_map(rows: dict, bs_pos, path: str | Path | None = None, adversary_xy=None,
                        title: str | None = None, margin_m: float = 50.0, buildings=None,
                        ax=None, serving=None):
    """Top view: the buildings (light gray, under everything), true path, estimates coloured
    by outcome, BSs (triangles), adversary (orange).

    The view is the bounding box of the true path, the BSs and the adversary plus ``margin_m``;
    estimates beyond it (spoofed outliers) are drawn on its edge with an "X" marker.

    :param bs_pos: [num_bs, 3] or [num_bs, 2] float, m
    :param adversary_xy: [num_points, 2] or [num_points, 3] float, m, optional
    :param margin_m: view margin, m
    :param buildings: :func:`map_buildings` of the run's geometry ([n, 4] rectangles or
        [n, k, 2] polygons, m), optional
    :param ax: a matplotlib ``Axes`` to draw on (``path`` unused); the Figure is returned.
        Without ``ax`` and ``path`` a new Figure is returned; with ``path`` the map is saved
        there and the path returned
    :param serving: [num_bs] bool, the BSs some point measures (:func:`serving_mask`): drawn
        apart from the candidate sites no point chose (:func:`draw_bs`); None: all alike
    """
    xt, yt, xe, ye, outcome = _columns(rows, ("x_true", "y_true", "x_est", "y_est", "outcome"))
    bs = _xy(bs_pos, "bs_pos")
    adv = _xy(adversary_xy, "adversary_xy") if adversary_xy is not None else np.zeros((0, 2))
    true = np.stack([xt, yt], axis=-1).astype(float)
    est = np.stack([xe, ye], axis=-1).astype(float)
    pts = np.concatenate([true, bs, adv])
    pts = pts[np.isfinite(pts).all(axis=1)]
    lo = (pts.min(axis=0) if len(pts) else np.zeros(2)) - margin_m
    hi = (pts.max(axis=0) if len(pts) else np.zeros(2)) + margin_m
    draw = lambda ax: _draw_map(ax, true, est, outcome, bs, adv, lo, hi, buildings,  # noqa: E731
                                serving)
    if ax is not None or path is None:
        fig, ax = new_axes(ax, figsize=(8.0, 8.0))
        draw(ax)
        if title:
            ax.set_title(title)
        return fig
    path = Path(path)
    with _kept_figure(("map", bool(title)), lambda: _MapFigure(bool(title))) as kept:
        draw(kept.clean_axes())
        kept.save(path, title)
    log.info("wrote %s", path)
    return path


def _draw_map(ax, true, est, outcome, bs, adv, lo, hi, buildings, serving=None) -> None:
    """The layers of :func:`plot_trajectory_map` on ``ax``."""
    has_fix = np.isfinite(est).all(axis=1)
    inside = has_fix & np.all((est >= lo) & (est <= hi), axis=1)
    if buildings is not None:
        coll = _building_collection(buildings, lo, hi)
        if coll is not None:
            ax.add_collection(coll, autolim=False)
    ax.plot(true[:, 0], true[:, 1], "-", color="tab:blue", lw=1.5, label="true")
    for o in OUTCOMES[:2]:
        sel = outcome == o
        colour = _OUTCOME_COLOURS[o]
        ax.plot(est[sel & inside, 0], est[sel & inside, 1], ".", color=colour, ms=4,
                label=f"estimate: {o.replace('_', ' ')} ({int(np.sum(sel & has_fix))})")
        out = np.clip(est[sel & has_fix & ~inside], lo, hi)
        ax.plot(out[:, 0], out[:, 1], "X", color=colour, mec="k", mew=0.5, ms=7)
    n_out = int(np.sum(has_fix & ~inside))
    if n_out:
        ax.plot([], [], "X", color="w", mec="k", ms=7, label=f"beyond view, at edge ({n_out})")
    if len(adv):
        ax.plot(adv[:, 0], adv[:, 1], ".", color="tab:orange", ms=3, label="adversary")
    draw_bs(ax, bs, serving)
    pad = 0.02 * (hi - lo).max()  # keeps the edge markers inside the axes
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (east) [m]")
    ax.set_ylabel("y (north) [m]")
    ax.legend(loc="best", fontsize=8, framealpha=0.9)


def read_results_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Read ``<scenario>_results.csv`` into ``{column: [num_points] array}``.

    ``outcome`` and ``outcome_enc`` are str arrays, ``index`` int64, every other column float64
    with NaN for an empty or 'nan' cell. A header-only (or empty) file gives length-0 arrays.

    :raises InputError: naming the file and line for a ragged row or a non-numeric cell
    """
    path = Path(path)
    with open(path, newline="") as fh:
        lines = list(csv.reader(fh))
    header = [h.strip() for h in lines[0]] if lines else list(COLUMNS)
    cols: dict[str, list] = {h: [] for h in header}
    for line, row in enumerate(lines[1:], start=2):
        if not any(c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise InputError(f"{path}:{line}", f"{len(row)} columns, expected {len(header)}")
        for h, c in zip(header, row):
            c = c.strip()
            if h in STR_COLUMNS:
                cols[h].append(c)
                continue
            try:
                cols[h].append(float(c) if c else np.nan)
            except ValueError:
                raise InputError(f"{path}:{line}", f"column {h}: non-numeric value {c!r}") from None
    out: dict[str, np.ndarray] = {}
    for h, vals in cols.items():
        if h in STR_COLUMNS:
            out[h] = np.array(vals, dtype=str)
        else:
            a = np.array(vals, dtype=float)
            out[h] = a.astype(np.int64) if h in INT_COLUMNS and np.isfinite(a).all() else a
    return out


def plot_pareto(rows: list[dict], path: str | Path | None, y_axis: dict[str, tuple[str, str]],
                title: str | None = None, ax=None):
    """Time against accuracy of a fidelity sweep (``veriloc-rt bench``), one panel per group.

    :param rows: bench rows (``veriloc_rt.studies.bench``): group, label, role, time_s, time_unit,
        pareto and each group's accuracy metric
    :param y_axis: per group, (the row key of its accuracy metric, the axis label). x:
        seconds per link or point (log); y: that deviation from the reference (log, with the
        reference, 0 by definition, drawn at the axis floor; an infinite deviation, a link lost
        or gained, on a dotted band above the rest); the Pareto front joined by a line, the
        config's setting starred, the noise floor dashed.
    :param ax: one matplotlib ``Axes`` per group present ('raytrace', then 'waveform'; a
        sequence when both are), ``path`` unused, the Figure returned (as without ``ax`` and
        ``path``); with ``path`` the figure is saved there and the path returned
    """
    groups = [g for g in ("raytrace", "waveform") if any(r["group"] == g for r in rows)]
    if not groups:
        raise ValueError("Argument `rows` holds no bench settings")
    return drawn(path, ax, title, lambda _, axes: _draw_pareto(axes, rows, groups, y_axis),
                  ncols=len(groups), figsize=(6.5 * len(groups), 5.0))


def _draw_pareto(axes, rows: list[dict], groups: list[str], y_axis: dict) -> None:
    """The panels of :func:`plot_pareto` on ``axes`` [1, len(groups)]."""
    for ax, g in zip(axes[0], groups):
        grp = [r for r in rows if r["group"] == g]
        key, y_label = y_axis[g]
        dev = np.array([np.nan if r.get(key) is None else r[key] for r in grp], dtype=float)
        t = np.array([r["time_s"] for r in grp], dtype=float)
        pos = dev[np.isfinite(dev) & (dev > 0)]
        floor = max(float(pos.min()) / 3 if pos.size else 1e-2, 1e-4)
        # an infinite deviation (a link lost or gained) is drawn on a band above the rest
        top = float(pos.max()) * 4 if pos.size else 1.0
        y = np.where(np.isfinite(dev), np.maximum(dev, floor), np.where(np.isinf(dev), top, np.nan))
        if np.isinf(dev).any():
            ax.axhline(top, color="tab:red", ls=":", lw=1, label="links lost or gained (infinite)")
        placed: list[tuple[float, float]] = []
        for r, xi, yi, di in zip(grp, t, y, dev):
            if r["role"] == "noise floor" or not np.isfinite(yi):
                continue
            if np.isinf(di):   # the band: labels slanted upwards, side by side
                ax.scatter([xi], [yi], s=140 if r["role"] == "config" else 36,
                           marker="*" if r["role"] == "config" else "^",
                           color="tab:red" if r["role"] == "config" else "0.6", zorder=3)
                ax.annotate(r["label"], (xi, yi), fontsize=6.5, xytext=(0, 6), rotation=60,
                            textcoords="offset points")
                continue
            # stack the labels of nearby points (log axes) instead of overprinting them
            near = sum(abs(np.log10(xi) - px) < 0.35 and abs(np.log10(yi) - py) < 0.08
                       for px, py in placed)
            placed.append((float(np.log10(xi)), float(np.log10(yi))))
            star = r["role"] == "config"
            ax.scatter([xi], [yi], s=140 if star else 36, marker="*" if star else "o",
                       color="tab:red" if star else ("tab:blue" if r["pareto"] else "0.6"),
                       zorder=3)
            text = "reference (0, drawn at the floor)" if r["role"] == "reference" else r["label"]
            ax.annotate(text, (xi, yi), fontsize=7, xytext=(4, 3 + 9 * near),
                        textcoords="offset points")
        front = [(xi, yi) for r, xi, yi, di in zip(grp, t, y, dev)
                 if r["pareto"] and np.isfinite(di)]
        if front:
            fx, fy = zip(*sorted(front))
            ax.step(fx, fy, where="post", color="tab:blue", lw=1.2, label="Pareto front")
        nf = [yi for r, yi in zip(grp, y) if r["role"] == "noise floor" and np.isfinite(yi)]
        if nf:
            ax.axhline(nf[0], color="0.3", ls="--", lw=1, label="noise floor (other noise draws)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        if np.isinf(dev).any():
            ax.set_ylim(top=top * 12)
        unit = grp[0]["time_unit"]
        ax.set_xlabel(f"seconds per {unit}")
        ax.set_ylabel(y_label)
        ax.set_title("ray tracing" if g == "raytrace" else "waveform and receiver")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="lower left", fontsize=8)


def _cdf(ax, x, label: str, **kw) -> None:
    x = np.sort(np.asarray(x, dtype=float).ravel())
    x = x[np.isfinite(x)]
    if x.size:
        ax.plot(x, np.arange(1, x.size + 1) / x.size, label=f"{label} (n={x.size})", **kw)


def plot_comparison_cdfs(benign: dict, path: str | Path | None = None, title: str | None = None,
                         ax=None):
    """CDFs of the benign chain's errors per propagation model (``veriloc-rt compare``).

    :param benign: {model: :class:`veriloc_rt.studies.diagnostics.BenignRun`}
    :param ax: four matplotlib ``Axes`` (a sequence or a 2 x 2 array: position error, ToA
        bias, RSTD error, AoA error), ``path`` unused, the Figure returned (as without ``ax``
        and ``path``); with ``path`` the figure is saved there and the path returned
    """
    panels = (("position_error_m", "DL position error, m"),
              ("toa_bias_m", "ToA bias against the straight-line delay, m"),
              ("rstd_error_m", "RSTD error (BS j - BS 0), m"),
              ("aoa_error_deg", "AoA error against the BS direction, deg"))
    colours = {"raytrace": "tab:blue", "uma": "tab:orange", "umi": "tab:green"}
    names = {"raytrace": "ray tracing", "uma": "TR 38.901 UMa", "umi": "TR 38.901 UMi"}
    def draw(_, axes):
        for ax, (attr, label) in zip(axes.ravel(), panels):
            for model, b in benign.items():
                _cdf(ax, getattr(b, attr), names.get(model, model), color=colours.get(model))
            ax.set_xlabel(label)
            ax.set_ylabel("CDF")
            ax.grid(True, alpha=0.3)
            ax.set_ylim(0, 1.02)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(loc="lower right", fontsize=8)
            if attr in ("position_error_m", "aoa_error_deg"):   # non-negative, wide range
                ax.set_xscale("symlog", linthresh=1.0)
                ax.set_xlim(left=0.0)

    return drawn(path, ax, title or ("benign errors: ray tracing vs " + " vs ".join(
        names.get(m, m) for m in benign if m != "raytrace")), draw, nrows=2, ncols=2,
        figsize=(11.0, 8.0))


def plot_comparison_detectors(detectors: dict, path: str | Path | None = None,
                              title: str | None = None, ax=None):
    """Correct-decision rate per detector and scenario, one bar per propagation model (plain:
    ray tracing, hatched: the stochastic twin), a rate's 95 % interval (:func:`rate_interval`)
    as an error bar where the metrics hold one; a detector a model's scenario flags
    uninformative gets no bar and an "uninf." label.

    :param detectors: {model: metrics.json "scenarios"}
    :param ax: one matplotlib ``Axes`` per evaluated scenario (none, fbs, meaconing, jamming:
        those with points; a sequence), ``path`` unused, the Figure returned (as without ``ax``
        and ``path``); with ``path`` the figure is saved there and the path returned
    """
    models = list(detectors)
    scen = [s for s in _SCENARIO_LABELS if any((detectors[m].get(s) or {}).get("num_points")
                                               for m in models)]
    if not scen:
        raise ValueError("Argument `detectors` holds no evaluated scenario")
    hatches = {"raytrace": "", "uma": "//", "umi": "//"}

    def draw(_, axes):
        for ax, s in zip(axes[0], scen):
            x = np.arange(len(DETECTORS))
            w = 0.8 / len(models)
            for k, m in enumerate(models):
                block = detectors[m].get(s) or {}
                rates = block.get("correct_decision_rate") or {}
                uninf = _uninformative(detectors[m], s)   # no bar: no detection to show
                v = [np.nan if d in uninf else rate_percent(rates.get(d)) for d in DETECTORS]
                xk = x + (k - (len(models) - 1) / 2) * w
                ax.bar(xk, np.nan_to_num(v), w,
                       color=[_DETECTOR_STYLE[d][1] for d in DETECTORS], hatch=hatches.get(m, "xx"),
                       edgecolor="white", label=m)
                _error_bars(ax, xk, v, [rate_interval(block, "correct_decision_rate", d)
                                        for d in DETECTORS])
                for xi, d in zip(xk, DETECTORS):
                    if d in uninf:
                        ax.text(xi, 1.0, "uninf.", rotation=90, ha="center", va="bottom",
                                fontsize=6)
            ax.set_xticks(x, [_DETECTOR_STYLE[d][0] for d in DETECTORS], fontsize=8)
            ax.set_ylim(0, 105)
            ax.set_title(_SCENARIO_LABELS[s])
            ax.grid(True, axis="y", alpha=0.3)
        axes[0][0].set_ylabel("correct decisions, %")

    twins = [m for m in models if m != "raytrace"]
    return drawn(path, ax, title or "correct decisions: ray tracing (plain) vs "
                  f"{' / '.join(twins) or 'none'} (hatched)", draw, ncols=len(scen),
                  figsize=(3.2 * len(scen) + 1.0, 4.2))
