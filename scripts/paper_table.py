"""Side-by-side table of a run's metrics.json and the paper's figures (markdown on stdout).

Paper values: ../shared/reference/veriloc-paper.tex, Fig. "techniques" (correct-decision rate)
and Fig. "encrypted_PRS" (outcomes). Usage:

    python scripts/paper_table.py results/metrics.json [--label ours]
"""

from __future__ import annotations

import argparse
import json
import sys

SCENARIOS = ("none", "fbs", "meaconing", "jamming")
DETECTORS = ("HMAC", "DigSig", "ABSA", "Handshake", "Tracking")
OUTCOMES = ("success", "large_error", "service_failure")
PAPER_RATES = {
    "HMAC": (99.16, 99.5, 31.83, 100.0), "DigSig": (98.75, 100.0, 31.67, 100.0),
    "ABSA": (96.77, 99.37, 99.83, 100.0), "Handshake": (99.39, 99.0, 92.67, 100.0),
    "Tracking": (95.72, 98.33, 39.0, 100.0),
}
PAPER_OUTCOMES = {
    "outcomes": {"none": (98.93, 1.07, 0.0), "fbs": (0.67, 19.8, 79.53),
                 "meaconing": (3.83, 95.51, 0.67), "jamming": (0.0, 0.0, 100.0)},
    "outcomes_encrypted": {"none": (99.0, 1.0, 0.0), "fbs": (49.0, 1.0, 50.0),
                           "meaconing": (2.5, 91.68, 5.82), "jamming": (0.0, 0.0, 100.0)},
}


def tolerance(paper: float) -> float:
    """The acceptance band of issue 5: 10 points where the paper is >= 90 or <= 10, else 20."""
    return 10.0 if paper >= 90.0 or paper <= 10.0 else 20.0


def cell(paper: float, ours) -> tuple[str, bool]:
    if ours is None:
        return f"{paper:.1f} / n/a", False
    ok = abs(ours - paper) <= tolerance(paper)
    return f"{paper:.1f} / {ours:.1f}{'' if ok else ' ✗'}", ok


def table(metrics: dict) -> tuple[str, int, int]:
    sc = metrics["scenarios"]
    lines = ["| correct-decision rate, % (paper / ours) | " + " | ".join(SCENARIOS) + " |",
             "| --- |" + " --- |" * len(SCENARIOS)]
    good = total = 0
    for d in DETECTORS:
        row = []
        for j, s in enumerate(SCENARIOS):
            txt, ok = cell(PAPER_RATES[d][j], sc.get(s, {}).get("correct_decision_rate", {}).get(d))
            row.append(txt)
            good, total = good + ok, total + 1
        lines.append(f"| {d} | " + " | ".join(row) + " |")
    lines += ["", "| outcome, % (paper / ours) | " + " | ".join(SCENARIOS) + " |",
              "| --- |" + " --- |" * len(SCENARIOS)]
    for key, label in (("outcomes", "standard PRS"), ("outcomes_encrypted", "encrypted PRS")):
        for k, name in enumerate(OUTCOMES):
            row = []
            for s in SCENARIOS:
                txt, ok = cell(PAPER_OUTCOMES[key][s][k], (sc.get(s, {}).get(key) or {}).get(name))
                row.append(txt)
                good, total = good + ok, total + 1
            lines.append(f"| {label}: {name} | " + " | ".join(row) + " |")
    return "\n".join(lines), good, total


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("metrics", help="metrics.json of a run")
    a = p.parse_args(argv)
    try:
        metrics = json.loads(open(a.metrics).read())
    except (OSError, ValueError) as exc:
        print(f"error: {a.metrics}: {exc}", file=sys.stderr)
        return 2
    text, good, total = table(metrics)
    print(text)
    print(f"\n{good} of {total} cells within the acceptance band (✗: outside)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
