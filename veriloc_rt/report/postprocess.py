"""Post-processing of finished run folders: what ``veriloc-rt diff``, ``veriloc-rt roc`` and
``veriloc-rt paper-table`` compute (the CLI only prints it).

* :func:`diff_runs`: two run folders' ``<scenario>_results.csv``, column by column: the rows
  that differ and the largest absolute and relative differences (numbers compared as floats,
  NaN equal to NaN); the ``exact`` columns (by default :data:`EXACT`: the detectors' decisions,
  the outcomes, the attack flag, the index and the time) must be identical.
* :func:`roc_of_run`: the detection analysis (ROC, AUC, fused decisions) of a run folder from
  its ``run.json`` and results CSVs, with detector settings overridden, written into another
  folder (``roc.csv``, ``roc.png``, ``roc_metrics.json``).
* :func:`paper_table`: a run's ``metrics.json`` beside the paper's figures
  (:mod:`veriloc_rt.report.paper`) as a markdown table, and how many cells are within the
  acceptance band.

Every rate read from ``metrics.json`` goes through :func:`rate_percent`.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path

from ..config import config_from_dict, patch_data
from ..errors import InputError
from ..fileio import atomic_write_text, json_text
from ..analysis.detection import analyse_detection
from .paper import PAPER_OUTCOMES, PAPER_RATES, SCENARIOS, tolerance
from .results import read_rows, results_path
from .roc_report import ROC_TITLE, format_detection, plot_roc, write_roc_csv

__all__ = ["EXACT", "DiffReport", "diff_runs", "roc_of_run", "paper_table", "rate_percent",
           "read_metrics"]

#: columns of the results CSVs that must be identical by default (``veriloc-rt diff --exact``)
EXACT = ("Time", "index", "attack", "HMAC", "DigSig", "ABSA", "Handshake", "Tracking", "outcome",
         "outcome_enc")
#: the detectors and outcomes of the paper's figures, in the table's order
DETECTORS = ("HMAC", "DigSig", "ABSA", "Handshake", "Tracking")
OUTCOMES = ("success", "large_error", "service_failure")


def rate_percent(value) -> float | None:
    """A rate (a share of points or decisions) as ``metrics.json`` holds it, in percent
    (None: absent). The one place that knows the file's unit for rates."""
    return None if value is None else 100.0 * float(value)   # metrics.json: fractions


# -- diff -----------------------------------------------------------------------------------
def _num(v: str) -> float | None:
    try:
        return float(v)
    except ValueError:
        return None


def _rows(path: Path) -> list[list[str]]:
    with open(path, newline="") as fh:
        return list(csv.reader(fh))


def diff_file(a: Path, b: Path, exact: tuple[str, ...]) -> tuple[bool, list[str]]:
    """(identical where it must be, report lines) for one pair of CSVs."""
    ra, rb = _rows(a), _rows(b)
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


@dataclass(frozen=True)
class DiffReport:
    """What :func:`diff_runs` found: ``ok`` when every ``exact`` column is identical (and the
    two runs have the same results files, rows and columns); ``lines`` the report."""

    ok: bool
    lines: tuple[str, ...]


def _results_files(run_dir: Path, field: str) -> list[str]:
    if not run_dir.is_dir():
        raise InputError(field, f"{run_dir}: no such run folder")
    files = sorted(p.name for p in run_dir.glob("*_results.csv"))
    if not files:
        raise InputError(field, f"{run_dir}: no <scenario>_results.csv (not a run folder)")
    return files


def diff_runs(run_a: str | Path, run_b: str | Path, exact: tuple[str, ...] = EXACT) -> DiffReport:
    """Compare the results CSVs of two run folders (see the module docstring).

    :raises InputError: a folder that is missing or holds no results CSV
    """
    run_a, run_b = Path(run_a), Path(run_b)
    files = _results_files(run_a, "RUN_A")
    other = _results_files(run_b, "RUN_B")
    if files != other:
        return DiffReport(False, (f"the runs' results files differ: {', '.join(files)} against "
                                  f"{', '.join(other)}",))
    ok, lines = True, []
    for name in files:
        same, more = diff_file(run_a / name, run_b / name, exact)
        ok &= same
        lines += more
    lines.append("the --exact columns are identical" if ok else "an --exact column DIFFERS")
    return DiffReport(ok, tuple(lines))


# -- roc ------------------------------------------------------------------------------------
def _run_config(run_dir: Path, sets: list[str]):
    path = run_dir / "run.json"
    try:
        data = json.loads(path.read_text())["config"]
    except FileNotFoundError:
        raise InputError("RUN_DIR", f"{run_dir}: no run.json (not a run folder)") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(str(path), f"not a run's run.json ({exc})") from None
    for item in sets:
        key, sep, value = item.partition("=")
        if not sep:
            raise InputError("--set", f"{item!r}: expected FIELD=VALUE (a JSON value)")
        try:
            parsed = json.loads(value)
        except ValueError:
            raise InputError("--set", f"{key}: {value!r} is not a JSON value") from None
        data = patch_data(data, {key: parsed})
    return config_from_dict(data)


def roc_of_run(run_dir: str | Path, out: str | Path, sets: list[str] | tuple[str, ...] = ()) -> dict | None:
    """Write the detection analysis of the run folder ``run_dir`` (its ``run.json`` config
    with the ``FIELD=VALUE`` items of ``sets`` applied; fields the file lacks take their
    defaults) into ``out``: ``roc.csv``, ``roc.png``, ``roc_metrics.json`` (the ``roc`` block
    ``metrics.json`` would hold). Returns that block, or None when the run has no analysis (it
    needs a 'none' scenario, an attack scenario and statistic columns); then nothing is written.

    The verdict columns stay those of the run, so only the analysis fields
    (``detectors.fusion.*``, ``detectors.min_benign_accept``) should be overridden.

    :raises InputError: ``out`` is the run's own folder; a missing or unreadable run.json; a
        bad ``--set`` item
    """
    run_dir, out = Path(run_dir), Path(out)
    if out.resolve() == run_dir.resolve():
        raise InputError("--out", f"{out} is the run's own folder; give another one (the run's "
                         "roc.csv and roc.png stay as the run wrote them)")
    cfg = _run_config(run_dir, list(sets))
    rows = {s: read_rows(results_path(run_dir, s)) for s in cfg.run.scenarios
            if results_path(run_dir, s).exists()}
    analysis = analyse_detection(rows, cfg)
    if analysis is None:
        return None
    out.mkdir(parents=True, exist_ok=True)
    write_roc_csv(out / "roc.csv", analysis)
    plot_roc(analysis, out / "roc.png", title=ROC_TITLE)
    atomic_write_text(out / "roc_metrics.json", json_text(analysis.metrics))
    return analysis.metrics


def format_roc(metrics: dict) -> str:
    """The summary ``veriloc-rt run`` prints of a ``roc`` block."""
    return format_detection(metrics)


# -- paper table ----------------------------------------------------------------------------
def read_metrics(path: str | Path) -> dict:
    """A run's ``metrics.json`` (``path``: the file or its run folder).

    :raises InputError: missing, not JSON, or without per-scenario metrics
    """
    path = Path(path)
    if path.is_dir():
        path = path / "metrics.json"
    try:
        metrics = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError(str(path), "no such file") from None
    except (OSError, ValueError) as exc:
        raise InputError(str(path), f"not a metrics.json ({exc})") from None
    if not isinstance(metrics, dict) or not isinstance(metrics.get("scenarios"), dict):
        raise InputError(str(path), "no 'scenarios' block (not a run's metrics.json; a Monte "
                         "Carlo's is in each realisation_* folder)")
    return metrics


def _cell(paper: float, ours) -> tuple[str, bool]:
    if ours is None:
        return f"{paper:.1f} / n/a", False
    ok = abs(ours - paper) <= tolerance(paper)
    return f"{paper:.1f} / {ours:.1f}{'' if ok else ' ✗'}", ok


def paper_table(metrics: dict) -> tuple[str, int, int]:
    """(markdown table, cells within the acceptance band, cells) of a run's metrics beside the
    paper's: the detectors' correct-decision rates and the outcome shares with the standard
    and the encrypted PRS, in percent (paper / ours; ✗: outside the band)."""
    sc = metrics["scenarios"]
    lines = ["| correct-decision rate, % (paper / ours) | " + " | ".join(SCENARIOS) + " |",
             "| --- |" + " --- |" * len(SCENARIOS)]
    good = total = 0
    for d in DETECTORS:
        row = []
        for s in SCENARIOS:
            ours = rate_percent(sc.get(s, {}).get("correct_decision_rate", {}).get(d))
            txt, ok = _cell(PAPER_RATES[s][d], ours)
            row.append(txt)
            good, total = good + ok, total + 1
        lines.append(f"| {d} | " + " | ".join(row) + " |")
    lines += ["", "| outcome, % (paper / ours) | " + " | ".join(SCENARIOS) + " |",
              "| --- |" + " --- |" * len(SCENARIOS)]
    for key, label in (("outcomes", "standard PRS"), ("outcomes_encrypted", "encrypted PRS")):
        for name in OUTCOMES:
            row = []
            for s in SCENARIOS:
                ours = rate_percent((sc.get(s, {}).get(key) or {}).get(name))
                txt, ok = _cell(PAPER_OUTCOMES[key][s][name], ours)
                row.append(txt)
                good, total = good + ok, total + 1
            lines.append(f"| {label}: {name} | " + " | ".join(row) + " |")
    return "\n".join(lines), good, total
