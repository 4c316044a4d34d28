"""The run summary the CLI prints: a run's outcome and correct-decision tables
(:func:`format_metrics`) and a Monte Carlo run's means with their 95 % confidence half-widths
(:func:`format_montecarlo`), as text from ``metrics.json``'s dict.
"""

from __future__ import annotations

__all__ = ["format_metrics", "format_montecarlo"]


def _pm(m: dict, group: str, key: str) -> str:
    """'mean±half' of an aggregated metric, 11 characters."""
    v = (m.get(group) or {}).get(key)
    h = (m["ci95"].get(group) or {}).get(key)
    text = "n/a" if v is None else f"{v:.1f}±{h:.1f}" if h is not None else f"{v:.1f}"
    return f"{text:>11s}"


def format_montecarlo(metrics: dict) -> str:
    """Mean ± 95 % CI half-width of the correct-decision rates and outcomes, as text."""
    from ..detectors.outcomes import DETECTORS, OUTCOMES

    lines = [f"mean ± 95 % confidence half-width over {metrics['realisations']} realisations"]
    lines.append("scenario    " + " ".join(f"{d:>11s}" for d in DETECTORS)
                 + "  | " + " ".join(f"{o:>11s}" for o in ("success", "large", "DoS"))
                 + " (std PRS)")
    for name, m in metrics["scenarios"].items():
        if not m.get("num_points"):
            continue
        uninf = m.get("uninformative_detectors") or ()
        rates = " ".join(f"{'uninf.':>11s}" if d in uninf else _pm(m, "correct_decision_rate", d)
                         for d in DETECTORS)
        outs = " ".join(_pm(m, "outcomes", k) for k in OUTCOMES)
        lines.append(f"{name:11s} {rates}  | {outs}")
    lines.append("correct-decision rate and outcomes in %, as in a single run; uninf.: flagged "
                 "uninformative in at least one realisation")
    return "\n".join(lines)


def _cell(v) -> str:
    return "   n/a" if v is None else f"{v:6.1f}"


def format_metrics(metrics: dict) -> str:
    """The run's outcome and correct-decision tables as text."""
    from ..detectors.outcomes import DETECTORS, OUTCOMES

    sc = metrics["scenarios"]
    lines = ["scenario     " + " ".join(f"{d:>9s}" for d in DETECTORS)
             + "  | success  large  DoS (std PRS) | success  large  DoS (enc PRS)"]
    for name, m in sc.items():
        if not m.get("num_points"):
            continue
        uninf = m.get("uninformative_detectors") or ()
        rates = " ".join(f"{'uninf.' if d in uninf else _cell(m['correct_decision_rate'][d]):>9s}"
                         for d in DETECTORS)
        o = " ".join(_cell(m["outcomes"][k]) for k in OUTCOMES)
        e = m.get("outcomes_encrypted")
        oe = " ".join(_cell(e[k]) for k in OUTCOMES) if e else ""
        lines.append(f"{name:12s} {rates}  | {o}  | {oe}")
    lines.append("correct-decision rate, %: benign = fixes accepted, attack = attack-window points "
                 "rejected; outcomes, %: benign over all points, attack over the attack window")
    if "roc" in metrics:
        from .roc_report import format_detection

        lines.append(format_detection(metrics["roc"]))
    return "\n".join(lines)
