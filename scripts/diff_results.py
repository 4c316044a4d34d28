"""Compare two run folders' ``*_results.csv``: which columns differ, and by how much.

    python scripts/diff_results.py RUN_A RUN_B [--exact COL,COL,...]

Per file and column: the rows that differ and the largest absolute and relative differences
(numbers compared as floats, NaN equal to NaN). The ``--exact`` columns (by default the
detectors' decisions, the outcomes, the attack flag, the index and the time) must be identical;
the exit status is 1 when one of them differs or the files' rows or columns do not match.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

EXACT = ("Time", "index", "attack", "HMAC", "DigSig", "ABSA", "Handshake", "Tracking", "outcome",
         "outcome_enc")


def _num(v: str) -> float | None:
    try:
        return float(v)
    except ValueError:
        return None


def diff_file(a: Path, b: Path, exact: tuple[str, ...]) -> tuple[bool, list[str]]:
    """(identical where it must be, report lines) for one pair of CSVs."""
    ra, rb = list(csv.reader(a.open())), list(csv.reader(b.open()))
    if not ra or not rb or ra[0] != rb[0] or len(ra) != len(rb):
        return False, [f"{a.name}: header or row count differs ({len(ra)} vs {len(rb)} lines)"]
    head = ra[0]
    stats = {h: [0, 0.0, 0.0] for h in head}          # rows differing, max abs, max rel
    for xa, xb in zip(ra[1:], rb[1:]):
        for h, va, vb in zip(head, xa, xb):
            if va == vb:
                continue
            fa, fb = _num(va), _num(vb)
            if fa is not None and fb is not None and math.isnan(fa) and math.isnan(fb):
                continue
            s = stats[h]
            s[0] += 1
            if fa is None or fb is None or not (math.isfinite(fa) and math.isfinite(fb)):
                s[1] = s[2] = math.inf
            else:
                d = abs(fa - fb)
                s[1] = max(s[1], d)
                s[2] = max(s[2], d / max(abs(fa), abs(fb)))
    lines = [f"{a.name}: {len(ra) - 1} rows"]
    ok = True
    for h in head:
        n, dabs, drel = stats[h]
        if n:
            must = h in exact
            ok &= not must
            lines.append(f"  {h:16s} {n:5d} rows differ, max abs {dabs:.3g}, max rel {drel:.3g}"
                         + ("  <- must be identical" if must else ""))
    if len(lines) == 1:
        lines[0] += ", identical"
    return ok, lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_a", type=Path)
    ap.add_argument("run_b", type=Path)
    ap.add_argument("--exact", default=",".join(EXACT),
                    help="comma-separated columns that must be identical")
    args = ap.parse_args(argv)
    exact = tuple(c for c in args.exact.split(",") if c)
    files = sorted(p.name for p in args.run_a.glob("*_results.csv"))
    if not files or files != sorted(p.name for p in args.run_b.glob("*_results.csv")):
        print(f"the runs' *_results.csv differ: {files}", file=sys.stderr)
        return 1
    all_ok = True
    for name in files:
        ok, lines = diff_file(args.run_a / name, args.run_b / name, exact)
        all_ok &= ok
        print("\n".join(lines))
    print("the --exact columns are identical" if all_ok else "an --exact column DIFFERS")
    return 0 if all_ok else 1


if __name__ == "__main__":
    sys.exit(main())
