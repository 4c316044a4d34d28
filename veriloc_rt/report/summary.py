"""The run summary the CLI prints: a run's outcome and correct-decision tables with their 95 %
intervals (:func:`format_metrics`), each decision's detection at the target false alarm and AUC
(:func:`format_roc_intervals`), and a Monte Carlo run's means with their intervals over the
realisations (:func:`format_montecarlo`), as text from ``metrics.json``'s dict.
"""

from __future__ import annotations

__all__ = ["format_metrics", "format_montecarlo", "format_roc_intervals"]


def _pm(m: dict, group: str, key: str) -> str:
    """'mean [lo-hi]' of an aggregated share (a fraction in metrics.json) and its interval over
    the realisations (``<key>_ci95``), in percent, 15 characters."""
    g = m.get(group) or {}
    return f"{_cell(g.get(key), g.get(key + '_ci95')):>15s}"


def format_montecarlo(metrics: dict) -> str:
    """Mean and 95 % interval over the realisations of the correct-decision rates and outcomes,
    and of the AUC and detection rate at the target false alarm, as text."""
    from ..detectors.outcomes import DETECTORS, OUTCOMES

    lines = [f"mean [95 % interval: mean -+ Student-t half-width, clipped to 0-100] over "
             f"{metrics['realisations']} realisations"]
    lines.append("scenario    " + " ".join(f"{d:>15s}" for d in DETECTORS)
                 + "  | " + " ".join(f"{o:>15s}" for o in ("success", "large", "DoS"))
                 + " (std PRS)")
    for name, m in metrics["scenarios"].items():
        if not m.get("num_points"):
            continue
        uninf = m.get("uninformative_detectors") or ()
        rates = " ".join(f"{'uninf.':>15s}" if d in uninf else _pm(m, "correct_decision_rate", d)
                         for d in DETECTORS)
        outs = " ".join(_pm(m, "outcomes", k) for k in OUTCOMES)
        lines.append(f"{name:11s} {rates}  | {outs}")
    lines.append("correct-decision rate and outcomes in %, as in a single run; uninf.: flagged "
                 "uninformative in at least one realisation")
    if metrics.get("roc"):
        lines.append(format_roc_intervals(metrics["roc"]))
    if metrics.get("link_budget"):
        from .link_budget import format_link_budget

        lines.append(format_link_budget(metrics["link_budget"]) + " (means over the "
                     "realisations)")
    return "\n".join(lines)


def _cell(v, ci=None) -> str:
    """A share (a fraction in metrics.json) in percent with its 95 % interval, if any:
    ``72.5 [64-80]``."""
    if v is None:
        return "n/a"
    return f"{100 * v:.1f}" + (f" [{100 * ci[0]:.0f}-{100 * ci[1]:.0f}]" if ci else "")


def _share_cell(group: dict | None, key: str, width: int) -> str:
    g = group or {}
    return f"{_cell(g.get(key), g.get(key + '_ci95')):>{width}s}"


def format_roc_intervals(roc: dict) -> str:
    """Each decision's AUC and detection rate at the target false alarm, with their 95 %
    intervals (``roc`` of a run's or a Monte Carlo's metrics.json), one line per attack."""
    alpha = roc.get("false_alarm", (roc.get("fusion") or {}).get("false_alarm"))
    uninf = set(roc.get("uninformative") or ())
    lines = [f"detection at false alarm <= {100 * alpha:g} % and AUC, with 95 % intervals "
             "(bootstrap; the threshold set for that false alarm on the benign points, so a "
             "detector uninformative at its configured threshold, marked *, has a rate too):"]
    for s, per in (roc.get("attacks") or {}).items():
        cells = []
        for n, e in per.items():
            pd, pci = e.get("pd_at_false_alarm"), e.get("pd_at_false_alarm_ci95")
            a, aci = e.get("auc"), e.get("auc_ci95")
            auc = "n/a" if a is None else f"{a:.2f}" + (f" [{aci[0]:.2f}-{aci[1]:.2f}]"
                                                        if aci else "")
            cells.append(f"{n}{'*' if n in uninf else ''} {_cell(pd, pci)} % AUC {auc}")
        lines.append(f"  {s:10s} " + "; ".join(cells))
    return "\n".join(lines)


def format_metrics(metrics: dict) -> str:
    """The run's outcome and correct-decision tables as text, shares in percent with their
    95 % intervals."""
    from ..detectors.outcomes import DETECTORS, OUTCOMES

    sc = metrics["scenarios"]
    w = 15   # "100.0 [100-100]"
    lines = ["scenario     " + " ".join(f"{d:>{w}s}" for d in DETECTORS)
             + "  | " + " ".join(f"{o:>{w}s}" for o in ("success", "large", "DoS"))
             + " (std PRS) | " + " ".join(f"{o:>{w}s}" for o in ("success", "large", "DoS"))
             + " (enc PRS)"]
    for name, m in sc.items():
        if not m.get("num_points"):
            continue
        uninf = m.get("uninformative_detectors") or ()
        rates = " ".join(f"{'uninf.':>{w}s}" if d in uninf
                         else _share_cell(m["correct_decision_rate"], d, w) for d in DETECTORS)
        o = " ".join(_share_cell(m["outcomes"], k, w) for k in OUTCOMES)
        e = m.get("outcomes_encrypted")
        oe = " ".join(_share_cell(e, k, w) for k in OUTCOMES) if e else ""
        lines.append(f"{name:12s} {rates}  | {o}" + (f"            | {oe}" if oe else ""))
    lines.append("correct-decision rate, %: benign = fixes accepted, attack = attack-window points "
                 "rejected; outcomes, %: benign over all points, attack over the attack window; "
                 "[lo-hi]: 95 % Clopper-Pearson interval over the points")
    if "roc" in metrics:
        from .roc_report import format_detection

        lines.append(format_detection(metrics["roc"]))
        lines.append(format_roc_intervals(metrics["roc"]))
    if "link_budget" in metrics:
        from .link_budget import format_link_budget

        lines.append(format_link_budget(metrics["link_budget"]))
    return "\n".join(lines)
