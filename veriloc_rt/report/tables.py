"""A finished (or running) run folder as tidy pandas tables, and their Parquet / MATLAB export.

:func:`load_run` reads the files ``veriloc-rt run`` writes (docs/outputs.md) into
:class:`RunTables`, one :class:`pandas.DataFrame` per table (:data:`TABLES`):

* ``points``: every ``<scenario>_results.csv`` row, with ``realisation`` and ``scenario``
  columns first, then the CSV's columns *by name* (a newer CSV's extra columns just appear);
* ``links``: every ``<scenario>_links.csv`` row (per-TRP links) the same way, empty when the
  run wrote none;
* ``metrics``: one row per leaf of ``metrics.json`` (``key`` its dotted path, ``value`` the
  number or NaN, ``text`` the string or ``""``; a ``<key>_ci95`` interval is two leaves,
  ``<key>_ci95.lo`` and ``<key>_ci95.hi``);
* ``scenario_metrics``: the ``scenarios.<name>`` shares and error percentiles, tidy
  (``scenario, metric, item, value, ci95_lo, ci95_hi, unit``: ``fraction`` for the shares, in
  [0, 1], with their 95 % interval, ``m`` for the errors, interval NaN);
* ``roc``: every ``roc.csv`` vertex (``detector, attack, threshold, benign_accept,
  attack_reject``; thresholds ``inf``/``-inf`` at the ends);
* ``operating_points``: ``roc.attacks.<attack>.<decision>`` with the detector's
  ``uninformative`` flag (``auc, threshold, benign_accept, attack_reject,
  pd_at_false_alarm``, fractions, then ``<key>_ci95_lo`` / ``_hi`` of each but the threshold).

A Monte Carlo folder (``realisation_*/`` subfolders) gives every realisation's rows, numbered by
``realisation``; its top-level ``metrics.json`` (means and ``ci95``) is ``realisation`` -1 in
``metrics``. A single run is realisation 0. A CSV's torn last line (a run killed mid-write, or
one still running) is dropped, as ``--resume`` drops it.
"""

from __future__ import annotations

import io
import json
import math
import re
from dataclasses import dataclass, fields
from pathlib import Path

from ..errors import InputError
from ..analysis.intervals import CI_SUFFIX

__all__ = ["RunTables", "TABLES", "load_run", "export_parquet", "export_mat", "EXPORT_FORMATS"]

#: the tables of :class:`RunTables`, in order
TABLES = ("points", "links", "metrics", "scenario_metrics", "roc", "operating_points")
#: ``veriloc-rt export --format``
EXPORT_FORMATS = ("parquet", "mat")

_RESULTS = re.compile(r"^(?P<scenario>.+)_results\.csv$")
_LINKS = re.compile(r"^(?P<scenario>.+)_links\.csv$")
_REALISATION = re.compile(r"^realisation_(\d+)$")
#: the unit of each ``scenarios.<name>`` group ("fraction": a share in [0, 1])
#: the ``operating_points`` columns from each ``roc.attacks.<attack>.<decision>`` entry, and
#: those whose 95 % interval follows (``<key>_ci95_lo``, ``<key>_ci95_hi``)
_OPERATING = ("auc", "threshold", "benign_accept", "attack_reject", "pd_at_false_alarm")
_OPERATING_CI = ("auc", "benign_accept", "attack_reject", "pd_at_false_alarm")
_UNITS = {"outcomes": "fraction", "outcomes_encrypted": "fraction",
          "correct_decision_rate": "fraction", "benign_phase_false_alarm_rate": "fraction",
          "position_error_m": "m"}


@dataclass
class RunTables:
    """The tables of one run folder (:func:`load_run`); ``run`` is its ``run.json``."""

    points: object
    links: object
    metrics: object
    scenario_metrics: object
    roc: object
    operating_points: object
    run: dict

    def tables(self) -> dict:
        """``{name: DataFrame}`` in :data:`TABLES` order."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name in TABLES}


def _read_csv(path: Path, realisation: int, scenario: str | None):
    import pandas as pd

    text = path.read_text(encoding="utf-8")
    if not text.endswith("\n"):  # torn last line
        text = text[: text.rfind("\n") + 1]
    try:
        df = pd.read_csv(io.StringIO(text), keep_default_na=False, na_values=[""])
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(str(path), f"not a readable CSV file ({exc})") from None
    front = {"realisation": realisation} | ({"scenario": scenario} if scenario else {})
    for i, (k, v) in enumerate(front.items()):
        df.insert(i, k, v)
    return df


def _json(path: Path) -> dict:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(str(path), f"not a readable JSON file ({exc})") from None


def _leaves(obj, prefix: str = ""):
    if prefix.endswith(CI_SUFFIX) and isinstance(obj, list) and len(obj) == 2:
        yield f"{prefix}.lo", obj[0]   # a 95 % interval [lo, hi]: two numeric leaves
        yield f"{prefix}.hi", obj[1]
    elif isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaves(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(obj, list) and any(isinstance(v, (dict, list)) for v in obj):
        for i, v in enumerate(obj):
            yield from _leaves(v, f"{prefix}.{i}")
    else:
        yield prefix, obj


def _number(v) -> float:
    """A metrics.json leaf as a float: NaN for null, text and lists; ``"inf"`` -> inf."""
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, (int, float)):
        return float(v)
    if v in ("inf", "-inf"):
        return float(v)
    return math.nan


def _text(v) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, list):
        return ",".join(str(x) for x in v)
    return ""


def _folders(run_dir: Path) -> list[tuple[int, Path]]:
    reals = sorted((int(m.group(1)), p) for p in run_dir.iterdir()
                   if p.is_dir() and (m := _REALISATION.match(p.name)))
    return reals or [(0, run_dir)]


def load_run(run_dir: str | Path) -> RunTables:
    """The tables of the run folder ``run_dir`` (module docstring).

    :raises InputError: ``RUN_DIR: ...`` when it is not a run folder (no ``run.json``), or
        ``<file>: ...`` for a file that does not parse
    """
    import pandas as pd

    run_dir = Path(run_dir)
    if not (run_dir / "run.json").is_file():
        raise InputError(str(run_dir), "not a run folder (no run.json in it)")
    info = _json(run_dir / "run.json")
    points, links, metrics, scen, roc, ops = [], [], [], [], [], []
    top = run_dir / "metrics.json"
    folders = _folders(run_dir)
    if folders[0][1] != run_dir and top.is_file():   # a Monte Carlo's aggregate
        metrics.append((-1, _json(top)))
    for r, folder in folders:
        for path in sorted(folder.glob("*.csv")):
            if m := _RESULTS.match(path.name):
                points.append(_read_csv(path, r, m.group("scenario")))
            elif m := _LINKS.match(path.name):
                links.append(_read_csv(path, r, m.group("scenario")))
        if (folder / "roc.csv").is_file():
            roc.append(_read_csv(folder / "roc.csv", r, None))
        if (folder / "metrics.json").is_file():
            metrics.append((r, _json(folder / "metrics.json")))
    rows = []
    for r, m in metrics:
        rows += [(r, k, _number(v), _text(v)) for k, v in _leaves(m)]
        if r < 0:
            continue
        for s, block in (m.get("scenarios") or {}).items():
            for group, unit in _UNITS.items():
                g = block.get(group) or {}
                for item, v in g.items():
                    if item.endswith(CI_SUFFIX):
                        continue
                    lo, hi = g.get(item + CI_SUFFIX) or (None, None)
                    scen.append((r, s, group, item, _number(v), _number(lo), _number(hi), unit))
        uninf = set((m.get("roc") or {}).get("uninformative") or ())
        for attack, per in ((m.get("roc") or {}).get("attacks") or {}).items():
            for name, e in per.items():
                ops.append((r, attack, name, *(_number(e.get(k)) for k in _OPERATING),
                            *(_number(x) for k in _OPERATING_CI
                              for x in (e.get(k + CI_SUFFIX) or (None, None))),
                            name in uninf))

    def frame(parts, columns):
        return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=columns)

    return RunTables(
        points=frame(points, ["realisation", "scenario"]),
        links=frame(links, ["realisation", "scenario"]),
        metrics=pd.DataFrame(rows, columns=["realisation", "key", "value", "text"]),
        scenario_metrics=pd.DataFrame(scen, columns=["realisation", "scenario", "metric", "item",
                                                     "value", "ci95_lo", "ci95_hi", "unit"]),
        roc=frame(roc, ["realisation", "detector", "attack", "threshold", "benign_accept",
                        "attack_reject"]),
        operating_points=pd.DataFrame(ops, columns=[
            "realisation", "attack", "detector", *_OPERATING,
            *(f"{k}{CI_SUFFIX}_{b}" for k in _OPERATING_CI for b in ("lo", "hi")),
            "uninformative"]),
        run=info)


def export_parquet(tables: RunTables, out_dir: str | Path) -> list[Path]:
    """One ``<table>.parquet`` per table in ``out_dir`` (created), each written atomically;
    the paths written."""
    from ..fileio import atomic_output

    out_dir = Path(out_dir)
    written = []
    for name, df in tables.tables().items():
        path = out_dir / f"{name}.parquet"
        with atomic_output(path) as tmp:
            df.to_parquet(tmp, engine="pyarrow", index=False)
        written.append(path)
    return written


def _mat_column(series):
    import numpy as np
    import pandas as pd

    if pd.api.types.is_bool_dtype(series):
        return series.to_numpy(dtype=bool)
    if pd.api.types.is_numeric_dtype(series):
        return series.to_numpy(dtype=float if series.isna().any() else None)
    # text (missing as ""): a cell array of strings
    return np.array(["" if pd.isna(v) else str(v) for v in series], dtype=object)


def export_mat(tables: RunTables, path: str | Path) -> Path:
    """One MATLAB file (v5, ``scipy.io.savemat``): a struct per table, a field per column (a
    column vector; text columns as cell arrays of strings, missing numbers as NaN)."""
    import numpy as np
    import scipy.io

    from ..fileio import atomic_output

    data = {}
    for name, df in tables.tables().items():
        data[name] = {str(c): np.asarray(_mat_column(df[c])).reshape(-1, 1) for c in df.columns}
    with atomic_output(path) as tmp:
        scipy.io.savemat(tmp, data, long_field_names=True, do_compression=True,
                         oned_as="column")
    return Path(path)
