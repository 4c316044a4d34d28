"""TRPs heard, used and excluded in a run folder of a many-TRP run (topology.num_trps > 3).

Reads ``<scenario>_results.csv`` and ``<scenario>_links.csv`` of RUN_DIR and prints, for the
benign scenario, the TRPs heard and used per fix (median, quartiles) and the share of fixes the
integrity test excluded a TRP from (the benign false-exclusion rate, with its exact binomial
95 % interval, beside the test's nominal size ``receiver.integrity_false_alarm``); for the
``fbs`` scenario in ``bias`` mode, over the attack window, the share of points at which each
spoofed TRP (``threats.fbs.spoofed_slots``) was excluded, and the outcomes; and the Integrity
and AuthShare detectors' benign acceptance, AUC and detection rate from ``metrics.json``.

    .venv/bin/python scripts/trps_summary.py RUN_DIR
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
from scipy.stats import binomtest


def _read(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _share(k: int, n: int) -> str:
    if n == 0:
        return "n/a (no points)"
    ci = binomtest(k, n).proportion_ci(0.95, method="exact")
    return f"{100 * k / n:.1f} % ({k}/{n}; 95 % CI {100 * ci.low:.1f}-{100 * ci.high:.1f} %)"


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__)
        return 2
    run = Path(argv[0])
    try:
        cfg = json.loads((run / "run.json").read_text())["config"]
        benign = _read(run / "none_results.csv")
    except (OSError, KeyError, ValueError) as exc:
        print(f"error: {run}: not a finished run folder ({exc})", file=sys.stderr)
        return 2
    if "bs_used" not in (benign[0] if benign else {}):
        print(f"error: {run}: no TRP columns (a run with topology.num_trps > 3 has them)",
              file=sys.stderr)
        return 2
    fixes = [r for r in benign if r["outcome"] != "service_failure"]
    heard = np.array([int(r["bs_heard"]) for r in benign])
    used = np.array([int(r["bs_used"]) for r in fixes])
    print(f"{run}: {cfg['topology']['num_trps']} TRPs, {len(benign)} points, "
          f"{len(fixes)} benign fixes")
    print(f"  heard per point: median {np.median(heard):g} (quartiles "
          f"{np.percentile(heard, 25):g}-{np.percentile(heard, 75):g})")
    if used.size:
        print(f"  used per benign fix: median {np.median(used):g} (quartiles "
              f"{np.percentile(used, 25):g}-{np.percentile(used, 75):g}); "
              f"fixes with >= 6 used: {_share(int(np.sum(used >= 6)), used.size)}")
    excl = sum(r["bs_excluded"] != "" for r in fixes)
    nominal = cfg["receiver"]["integrity_false_alarm"]
    print(f"  benign fixes with an exclusion: {_share(excl, len(fixes))} "
          f"(test size {100 * nominal:g} %)")
    outcomes = {o: sum(r["outcome"] == o for r in benign) for o in
                ("success", "large_error", "service_failure")}
    print(f"  benign outcomes: {outcomes}")
    fbs = run / "fbs_results.csv"
    if fbs.exists() and cfg["threats"]["fbs"]["mode"] == "bias":
        rows = [r for r in _read(fbs) if r["attack"] == "1"]
        idx = {r["index"] for r in rows}
        links = [ln for ln in _read(run / "fbs_links.csv") if ln["index"] in idx]
        for slot in cfg["threats"]["fbs"]["spoofed_slots"]:
            mine = [ln for ln in links if ln["trp"] == str(slot)]
            k = sum(ln["excluded"] == "1" for ln in mine)
            heard_k = sum(ln["heard"] == "1" for ln in mine)
            print(f"  fbs bias on TRP slot {slot}: excluded at {_share(k, len(rows))} of the "
                  f"attack-window points (heard at {heard_k})")
        outcomes = {o: sum(r["outcome"] == o for r in rows) for o in
                    ("success", "large_error", "service_failure")}
        print(f"  fbs attack-window outcomes: {outcomes}")
    try:
        roc = json.loads((run / "metrics.json").read_text()).get("roc") or {}
    except (OSError, ValueError):
        roc = {}
    for d in ("Integrity", "AuthShare"):
        if d in roc.get("detectors", {}):
            per = "; ".join(f"{s}: AUC {e[d]['auc']:.3f}, attack rejected "
                            f"{100 * e[d]['attack_reject']:.1f} %"
                            for s, e in roc["attacks"].items() if d in e)
            print(f"  detector {d}: benign accepted "
                  f"{100 * roc['detectors'][d]['benign_accept']:.1f} %; {per}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
