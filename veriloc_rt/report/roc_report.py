"""The detection analysis on disk: ``roc.csv``, ``roc.png`` and the text summary of it.

``roc.csv`` (:data:`~veriloc_rt.analysis.detection.ROC_COLUMNS`): one row per ROC vertex of each
decision (the five detectors, then ``Integrity`` and ``AuthShare`` in a run with more than
three TRPs, ``KofN``, ``NPFusion``) and attack, in the order the curve runs
from accept-all to reject-all. ``roc.png``: one panel per attack, false-alarm rate
``1 - benign_accept`` against detection rate ``attack_reject`` (Fawcett 2006's axes), a curve
per decision, the configured threshold's operating point marked; the x axis is linear up to
1 % false alarms and logarithmic above, since the operating points crowd near 0.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..detectors.outcomes import DETECTORS, TRP_DETECTORS
from ..fileio import atomic_output
from ..analysis.detection import FUSED, ROC_COLUMNS, DetectionAnalysis
from .plots import drawn

__all__ = ["LABELS", "ROC_TITLE", "format_detection", "plot_roc", "write_roc_csv"]

#: roc.png's title
ROC_TITLE = ("ROC per attack (o: configured threshold; AUC in the legend; x linear below 0.01, "
             "log above)")

#: display label and colour of each decision (the single detectors' as in the other plots)
LABELS = {"HMAC": ("HMAC", (0.0, 0.0, 0.6)), "DigSig": ("DigSig", (0.7, 0.0, 0.0)),
          "ABSA": ("ABSA", (0.3, 0.65, 0.65)), "Handshake": ("Handshake", (1.0, 0.6, 0.2)),
          "Tracking": ("Tracking", (0.3, 0.3, 0.3)),
          "Integrity": ("Integrity", (0.85, 0.1, 0.55)),
          "AuthShare": ("AuthShare", (0.1, 0.45, 0.95)), "KofN": ("k-of-5 vote", (0.55, 0.2, 0.7)),
          "NPFusion": ("NP fusion (test third)", (0.0, 0.55, 0.0))}


#: false-alarm rate up to which roc.png's x axis is linear (logarithmic above)
_LINEAR_FA = 0.01
#: roc.png's fixed margins (left, right, bottom, top), inches: the tick labels, the axis labels
#: and each panel's title, all known in advance
_MARGINS_IN = (0.58, 0.1, 0.5, 0.32)
#: gap between two panels, inches: the y tick labels and label of the right one
_WSPACE_IN = 0.68


def write_roc_csv(path: str | Path, analysis: DetectionAnalysis) -> Path:
    """Write every curve's vertices (floats exact, ``inf`` for an unbounded threshold)."""
    path = Path(path)
    with atomic_output(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(ROC_COLUMNS)
        for name, attack, t, b, a in analysis.roc_rows():
            w.writerow([name, attack, repr(t), repr(b), repr(a)])
    return path


def plot_roc(analysis: DetectionAnalysis, path: str | Path | None = None,
             title: str | None = None, ax=None):
    """One panel per attack: the ROC of each decision, its configured operating point as a
    marker, the AUC in the legend; uninformative detectors dashed, without an operating point
    (at their configured threshold their rejections are no detections).

    :param ax: one matplotlib ``Axes`` per attack, in ``analysis.metrics["attacks"]`` order (a
        sequence when there are several), ``path`` unused, the Figure returned (as without
        ``ax`` and ``path``); with ``path`` the figure is saved there and the path returned
    """
    m = analysis.metrics
    attacks = list(m["attacks"])
    return drawn(path, ax, title, lambda _, axes: _draw_roc(axes, analysis, attacks),
                 ncols=len(attacks), figsize=(4.2 * len(attacks), 4.4),
                 margins_in=_MARGINS_IN, wspace_in=_WSPACE_IN)


def _draw_roc(axes, analysis: DetectionAnalysis, attacks: list) -> None:
    """The panels of :func:`plot_roc` on ``axes`` [1, len(attacks)]."""
    m = analysis.metrics
    k = m["fusion"]["k"]
    singles = [d for d in (*DETECTORS, *TRP_DETECTORS) if d in m["detectors"]]
    for ax, s in zip(axes[0], attacks):
        for name in (*singles, *FUSED):
            c = analysis.curves.get((name, s))
            if c is None:
                continue
            label, colour = LABELS[name]
            label = label.replace("k-of-5", f"{k}-of-{len(singles)}")
            ls = "--" if name in analysis.uninformative else "-"
            ax.plot(c.false_alarm, c.attack_reject, ls, color=colour, lw=1.4,
                    drawstyle="default",
                    label=f"{label} {m['attacks'][s][name]['auc']:.3f}"
                    + (" (uninf.)" if name in analysis.uninformative else ""))
            if name not in analysis.uninformative:
                _, ba, ar = analysis.operating[(name, s)]
                ax.plot([1.0 - ba], [ar], "o", color=colour, ms=6, mec="k")
        chance = np.linspace(0.0, 1.0, 201)
        ax.plot(chance, chance, ":", color="0.6", lw=0.8)
        # the operating points crowd near P_FA = 0: linear up to 1 %, logarithmic above
        ax.set_xscale("symlog", linthresh=_LINEAR_FA, linscale=0.5)
        ax.set_xticks([0.0, 0.01, 0.1, 1.0], ["0", "0.01", "0.1", "1"])
        ax.set(xlim=(0.0, 1.0), ylim=(-0.02, 1.02),
               xlabel="false alarm = 1 - benign acceptance",
               ylabel="detection (attack rejected)")
        # at its place (y = 1, above the axes): placed automatically, the title measures
        # the axis' tick labels first, to clear any above the axes (there are none)
        ax.set_title(s, y=1.0)
        ax.legend(title="AUC (o: configured threshold)", fontsize=6.5, title_fontsize=7,
                  loc="lower right")


def format_detection(roc: dict) -> str:
    """The ``roc`` block of metrics.json as text: AUC and operating point per decision and
    attack, the uninformative detectors, and the fused decisions against the best single one."""
    names = [n for n in (*DETECTORS, *TRP_DETECTORS, *FUSED) if n in roc["detectors"]]
    singles = len([n for n in names if n not in FUSED])
    short = {**{d: LABELS[d][0] for d in (*DETECTORS, *TRP_DETECTORS)},
             "KofN": f"{roc['fusion']['k']}-of-{singles}",
             "NPFusion": "NP fusion"}
    head = "ROC          " + " ".join(f"{short[n]:>15s}" for n in names)
    lines = [head + "   (AUC  benign-accept/attack-reject % at the configured threshold; "
                    "uninf.: no attack rate for an uninformative detector)"]
    uninf = set(roc["uninformative"])
    for s, per in roc["attacks"].items():
        cells = []
        for n in names:
            e = per.get(n)
            cells.append(f"{'n/a':>15s}" if e is None else
                         f"{e['auc']:5.3f}   uninf.  " if n in uninf else
                         f"{e['auc']:5.3f} {100 * e['benign_accept']:4.0f}/"
                         f"{100 * e['attack_reject']:<4.0f}")
        lines.append(f"{s:12s} " + " ".join(f"{c:>15s}" for c in cells))
    if roc["uninformative"]:
        lines.append(f"uninformative (accept < {100 * roc['min_benign_accept']:.0f} % of benign "
                     "fixes at their threshold; their attack rejections are no detections): "
                     + ", ".join(f"{d} ({100 * roc['detectors'][d]['benign_accept']:.1f} %)"
                                 for d in roc["uninformative"]))
    f = roc["fusion"]
    if "test" in f:
        total = f["fit_indices"] + f["calibration_indices"] + f["test_indices"]
        target = 100 * f["false_alarm"]
        lines.append(f"fused on the test third ({f['test_indices']} of {total} indices; NP "
                     f"fusion fitted on {f['fit_indices']}, its threshold set for false alarm "
                     f"<= {target:g} % on the {f['calibration_indices']} calibration indices "
                     f"({100 * f['np_calibration_false_alarm']:.1f} % there), its false alarm "
                     f"on the test third as measured; the vote and single detectors at their "
                     f"best threshold with test false alarm <= {target:g} %), detection %:")
        for s, t in f["test"].items():
            b = t["best_single"]
            fa = 100 * t["NPFusion"]["false_alarm"]
            over = f" > target {target:g}" if fa > target else ""
            lines.append(f"  {s:11s} NP fusion {100 * t['NPFusion']['attack_reject']:5.1f} "
                         f"(false alarm {fa:4.1f}{over}, AUC "
                         f"{t['NPFusion']['auc']:.3f})  vote at its best k "
                         f"{100 * t['KofN']['attack_reject']:5.1f}  best single {b} "
                         f"{100 * t[b]['attack_reject']:5.1f} (AUC {t[b]['auc']:.3f}, oracle "
                         "threshold)")
    return "\n".join(lines)

