"""Side-by-side table of a run's metrics.json and the paper's figures (markdown on stdout).

Paper values: veriloc_rt/report/paper.py (the paper of README.md, "How to cite": Fig. "techniques",
correct-decision rate, and Fig. "encrypted_PRS", outcomes). Usage:

    python scripts/paper_table.py results/metrics.json [--label ours]
"""

from __future__ import annotations

import argparse
import json
import sys

from veriloc_rt.report.paper import PAPER_OUTCOMES, PAPER_RATES, SCENARIOS, tolerance

DETECTORS = ("HMAC", "DigSig", "ABSA", "Handshake", "Tracking")
OUTCOMES = ("success", "large_error", "service_failure")


def cell(paper: float, ours) -> tuple[str, bool]:
    """``paper`` in percent (as published); ``ours`` a fraction (metrics.json), compared in
    percent."""
    if ours is None:
        return f"{paper:.1f} / n/a", False
    ours = 100.0 * ours
    ok = abs(ours - paper) <= tolerance(paper)
    return f"{paper:.1f} / {ours:.1f}{'' if ok else ' ✗'}", ok


def table(metrics: dict) -> tuple[str, int, int]:
    sc = metrics["scenarios"]
    lines = ["| correct-decision rate, % (paper / ours) | " + " | ".join(SCENARIOS) + " |",
             "| --- |" + " --- |" * len(SCENARIOS)]
    good = total = 0
    for d in DETECTORS:
        row = []
        for s in SCENARIOS:
            txt, ok = cell(PAPER_RATES[s][d], sc.get(s, {}).get("correct_decision_rate", {}).get(d))
            row.append(txt)
            good, total = good + ok, total + 1
        lines.append(f"| {d} | " + " | ".join(row) + " |")
    lines += ["", "| outcome, % (paper / ours) | " + " | ".join(SCENARIOS) + " |",
              "| --- |" + " --- |" * len(SCENARIOS)]
    for key, label in (("outcomes", "standard PRS"), ("outcomes_encrypted", "encrypted PRS")):
        for name in OUTCOMES:
            row = []
            for s in SCENARIOS:
                txt, ok = cell(PAPER_OUTCOMES[key][s][name], (sc.get(s, {}).get(key) or {}).get(name))
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
