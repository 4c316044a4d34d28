"""The detection analysis (ROC, AUC, fused decisions) of a finished run folder, from its files.

Reads ``run.json`` (the resolved config; fields it lacks, e.g. from a run made before
``detectors.fusion`` existed, take their defaults) and the ``<scenario>_results.csv`` files
(which must have the statistic columns), and writes ``roc.csv``, ``roc.png`` and
``roc_metrics.json`` (the ``roc`` block ``metrics.json`` would hold) into ``--out``, a folder
other than the run's (the run's own files are never overwritten); prints the summary
``veriloc-rt run`` prints, with the false-alarm target of the overridden config. Detector settings may be overridden
(``--set detectors.fusion.k=2``): the verdict columns stay those of the run, so only the
analysis fields (``detectors.fusion.*``, ``detectors.min_benign_accept``) should be changed.
Usage:

    python scripts/roc_of_run.py RUN_DIR --out DIR [--set FIELD=VALUE ...]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from veriloc_rt.config import config_from_dict, patch_data
from veriloc_rt.errors import InputError
from veriloc_rt.fileio import atomic_write_text, json_text
from veriloc_rt.report.detection import analyse_detection
from veriloc_rt.report.results import read_rows, results_path
from veriloc_rt.report.roc_report import ROC_TITLE, format_detection, plot_roc, write_roc_csv


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path)
    ap.add_argument("--out", type=Path, required=True,
                    help="output folder, not the run's own (its files are never overwritten)")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    args = ap.parse_args(argv)
    out = args.out
    if out.resolve() == args.run_dir.resolve():
        print(f"error: --out: {out} is the run's own folder; give another one (the run's "
              "roc.csv and roc.png stay as the run wrote them)", file=sys.stderr)
        return 2
    data = json.loads((args.run_dir / "run.json").read_text())["config"]
    try:
        for item in args.set:
            key, value = item.split("=", 1)
            data = patch_data(data, {key: json.loads(value)})
        cfg = config_from_dict(data)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    rows = {s: read_rows(results_path(args.run_dir, s)) for s in cfg.run.scenarios
            if results_path(args.run_dir, s).exists()}
    analysis = analyse_detection(rows, cfg)
    if analysis is None:
        print("no analysis: the run needs a 'none' scenario, an attack scenario and statistic "
              "columns", file=sys.stderr)
        return 1
    out.mkdir(parents=True, exist_ok=True)
    write_roc_csv(out / "roc.csv", analysis)
    plot_roc(analysis, out / "roc.png",
             title=ROC_TITLE)
    atomic_write_text(out / "roc_metrics.json", json_text(analysis.metrics))
    print(format_detection(analysis.metrics))
    print(f"wrote {out}/ (roc.csv, roc.png, roc_metrics.json)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
