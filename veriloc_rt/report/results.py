"""Per-scenario result files and the metrics computed from them.

``<scenario>_results.csv`` (DESIGN.md, "Files written by run"): the first columns are exactly
``Time,HMAC,DigSig,ABSA,Handshake,Tracking`` (1 valid, 0 invalid), as the paper's figures read
them, then ``x_true,y_true,x_est,y_est,error_m,outcome``, then ``index,attack`` and the
encrypted-PRS fix ``x_est_enc,y_est_enc,error_m_enc,outcome_enc``, then each detector's
decision statistic (:data:`~veriloc_rt.detectors.statistics.STAT_COLUMNS`: ``hmac_stat`` ..
``tracking_stat``; ``inf`` where a rule rejects whatever the threshold). Floats are written with
``repr`` (shortest exact round trip), so a resumed run replays the saved fixes bit for bit.
A row is flushed as soon as it exists: an interrupted run keeps every finished point.

Metrics (paper Sec. "Results and Discussion"):

Every share is a fraction in [0, 1] (percent only in printed tables and plot labels), followed
by its 95 % interval ``<key>_ci95`` = ``[lo, hi]`` (Clopper-Pearson over the points it counts:
:mod:`.intervals`; null without points).

* ``outcomes``: success / large_error / service_failure over the *evaluated points*: every
  point for ``none``, the attack window for an attack (the paper's FBS bar, 0.67 % success = 0.0067,
  counts the attack phase only);
* ``correct_decision_rate`` per detector: for ``none`` the share of points *with a fix*
  that the detector accepts (false alarms exclude DoS points, as the paper defines them); for
  an attack the share of attack-window points that the detector rejects;
* ``position_error_m``: p50 / p95 / p99.9 of the horizontal error over the evaluated points
  that have a fix.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from ..fileio import atomic_output, naming
from ..detectors.outcomes import DETECTORS, OUTCOMES, TRP_DETECTORS, PointRow
from ..detectors.statistics import STAT_COLUMNS, TRP_STAT_COLUMNS
from ..errors import short_repr
from ..analysis.intervals import binomial_ci, ci_suffix

__all__ = ["CSV_COLUMNS", "extra_columns", "TRP_COLUMNS", "TRP_DETECTOR_COLUMNS", "LINK_COLUMNS", "ResultsWriter", "read_rows",
           "parse_rows", "detectors_of", "scenario_metrics", "results_path", "links_path"]

CSV_COLUMNS = ("Time", *DETECTORS, "x_true", "y_true", "x_est", "y_est", "error_m", "outcome",
               "index", "attack", "x_est_enc", "y_est_enc", "error_m_enc", "outcome_enc",
               *STAT_COLUMNS)
#: columns a run with more than three TRPs (topology.num_trps) or the weighted fit appends to
#: each row (a three-TRP run with the paper's fit keeps the paper's columns)
TRP_COLUMNS = ("bs_heard", "bs_used", "bs_excluded", "fix_cov_xx", "fix_cov_xy", "fix_cov_yy",
               "auth_share", "x_est_auth", "y_est_auth")
#: the :data:`~veriloc_rt.detectors.outcomes.TRP_DETECTORS`' verdicts and statistics, after
#: :data:`TRP_COLUMNS` in the same runs
TRP_DETECTOR_COLUMNS = (*TRP_DETECTORS, *TRP_STAT_COLUMNS)


def extra_columns(extra: tuple[str, ...]) -> tuple[str, ...]:
    """The columns the plug-in detectors ``extra`` (``detectors.extra``) append to each row,
    after every other: their verdicts, then their statistics ``<name in lower case>_stat``."""
    return (*extra, *(f"{d.lower()}_stat" for d in extra))


#: columns of ``<scenario>_links.csv``: one row per point and TRP
LINK_COLUMNS = ("index", "trp", "bs_id", "distance_m", "rx_power_dbm", "snr_re_db", "heard",
                "toa_error_m", "rstd_error_m", "aoa_error_deg", "tag_verified", "used",
                "excluded", "peak_snr_db", "hmac_margin_db", "ds_margin_db")


def results_path(out_dir: str | Path, scenario: str) -> Path:
    return Path(out_dir) / f"{scenario}_results.csv"


def links_path(out_dir: str | Path, scenario: str) -> Path:
    return Path(out_dir) / f"{scenario}_links.csv"


def _f(x) -> str:
    """Exact float text; '' for NaN/None (no fix)."""
    if x is None:
        return ""
    x = float(x)
    return "" if math.isnan(x) else repr(x)


def _cell(v) -> str:
    """A links-CSV cell: floats as :func:`_f`, booleans as 0/1, the rest as text."""
    if isinstance(v, (bool, np.bool_)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return _f(v)
    return str(v)


def _p(text: str) -> float:
    return float(text) if text not in ("", "nan") else float("nan")


def row_to_fields(r: PointRow) -> list[str]:
    enc = r.est_xy_enc if r.est_xy_enc is not None else (None, None)
    return ([repr(float(r.time_s))] + [str(int(bool(r.verdicts[d]))) for d in DETECTORS]
            + [_f(r.true_xy[0]), _f(r.true_xy[1]), _f(r.est_xy[0]), _f(r.est_xy[1]),
               _f(r.error_m), r.outcome, str(r.index), str(int(r.attack)),
               _f(enc[0]), _f(enc[1]), _f(r.error_m_enc), r.outcome_enc or ""]
            + [_f(r.stats.get(d)) for d in DETECTORS])


def _trp_fields(r: PointRow) -> list[str]:
    heard, used, excluded = r.trps if r.trps is not None else ("", "", "")
    c = r.fix_cov
    cov = [_f(c[0, 0]), _f(c[0, 1]), _f(c[1, 1])] if c is not None else ["", "", ""]
    share, xy = r.auth if r.auth is not None else (None, (None, None))
    return ([str(heard), str(used), str(excluded)] + cov + [_f(share), _f(xy[0]), _f(xy[1])]
            + [str(int(bool(r.verdicts[d]))) if d in r.verdicts else "" for d in TRP_DETECTORS]
            + [_f(r.stats.get(d)) for d in TRP_DETECTORS])


def _extra_fields(r: PointRow, extra: tuple[str, ...]) -> list[str]:
    return ([str(int(bool(r.verdicts[d]))) for d in extra]
            + [_f(r.stats.get(d)) for d in extra])


def fields_to_row(f: dict, extra: tuple[str, ...] = ()) -> PointRow:
    """The row of a CSV line's fields ``f`` (``extra``: the plug-in detectors' names)."""
    enc = f["outcome_enc"] != ""
    row = PointRow(
        index=int(f["index"]), time_s=float(f["Time"]), attack=f["attack"] == "1",
        verdicts={d: f[d] == "1" for d in DETECTORS + TRP_DETECTORS if f.get(d, "") != ""},
        true_xy=np.array([_p(f["x_true"]), _p(f["y_true"])]),
        est_xy=np.array([_p(f["x_est"]), _p(f["y_est"])]), error_m=_p(f["error_m"]),
        outcome=f["outcome"],
        est_xy_enc=np.array([_p(f["x_est_enc"]), _p(f["y_est_enc"])]) if enc else None,
        error_m_enc=_p(f["error_m_enc"]) if enc else None, outcome_enc=f["outcome_enc"] or None,
        stats={d: _p(f[c]) for d, c in zip(DETECTORS + TRP_DETECTORS,
                                            STAT_COLUMNS + TRP_STAT_COLUMNS)
               if f.get(c, "") != ""},
        trps=((int(f["bs_heard"]), int(f["bs_used"]), f["bs_excluded"])
              if f.get("bs_heard", "") != "" else None),
        fix_cov=(np.array([[_p(f["fix_cov_xx"]), _p(f["fix_cov_xy"])],
                           [_p(f["fix_cov_xy"]), _p(f["fix_cov_yy"])]])
                 if f.get("fix_cov_xx", "") != "" else None),
        auth=((_p(f["auth_share"]), np.array([_p(f["x_est_auth"]), _p(f["y_est_auth"])]))
              if "auth_share" in f else None))
    for d in extra:
        row.verdicts[d] = f[d] == "1"
        row.stats[d] = _p(f[f"{d.lower()}_stat"])
    return row


def read_rows(path: str | Path) -> list[PointRow]:
    """The complete rows of a results CSV (a torn last line, from a kill mid-write, is dropped).

    :raises ValueError: if the header is not :data:`CSV_COLUMNS`
    """
    return parse_rows(Path(path).read_text(), path)


def parse_rows(text: str, path: str | Path = "results CSV") -> list[PointRow]:
    """The complete rows of a results CSV's ``text`` (:func:`read_rows`).

    :raises ValueError: ``header ... is not ...`` or ``line N: ...`` (a row that does not parse)
    """
    if not text.endswith("\n"):  # torn last line
        text = text[: text.rfind("\n") + 1]
    reader = csv.DictReader(io.StringIO(text, newline=""))
    try:
        header = tuple(reader.fieldnames or ())
        base = [b for b in (CSV_COLUMNS + TRP_COLUMNS + TRP_DETECTOR_COLUMNS,
                            CSV_COLUMNS + TRP_COLUMNS, CSV_COLUMNS) if header[:len(b)] == b]
        rest = header[len(base[0]):] if base else ()
        extra = rest[:len(rest) // 2]
        if not base or rest != extra_columns(extra):
            raise ValueError(f"header {short_repr(reader.fieldnames)} is not the results "
                             "CSV's")
        rows = []
        for f in reader:
            if None in f or None in f.values():
                raise ValueError(f"line {reader.line_num}: {len(f) - (None in f)} fields "
                                 f"(of {len(reader.fieldnames)})")
            try:
                rows.append(fields_to_row(f, extra))
            except (ValueError, KeyError) as exc:
                raise ValueError(f"line {reader.line_num}: {exc}") from None
    except csv.Error as exc:
        raise ValueError(f"not a readable CSV file ({exc})") from None
    return rows


def _kept_lines(path: Path, indices: set[int]) -> list[list[str]]:
    """The complete rows of an existing CSV whose first field (the point index) is in
    ``indices`` (a torn last line dropped); [] without the file."""
    if not path.exists():
        return []
    # the run folder's checks refused a file that is not regular before the run began; a
    # damaged byte only costs the line it is in (the links are a by-product of the rows)
    text = path.read_text(encoding="utf-8", errors="replace")
    if not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    rows = list(csv.reader(io.StringIO(text)))[1:]
    return [f for f in rows if f and f[0].isdigit() and int(f[0]) in indices]


class ResultsWriter:
    """Appends rows to a scenario's CSV, one flushed line per point, and each row's per-TRP
    links to ``<scenario>_links.csv`` beside it.

    :param keep: rows already on disk to keep (resume); the file is rewritten with exactly these
        first, which also drops a torn last line (the links file keeps these points' lines)
    :param trps: append :data:`TRP_COLUMNS` and :data:`TRP_DETECTOR_COLUMNS` to every row
        (runs with more than three TRPs)
    :param extra: the plug-in detectors (``detectors.extra``), whose :func:`extra_columns` go
        last
    """

    def __init__(self, path: str | Path, keep: list[PointRow] | None = None, trps: bool = False,
                 extra: tuple[str, ...] = ()):
        self.path = Path(path)
        self.trps = bool(trps)
        self.extra = tuple(extra)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.links_path = self.path.with_name(self.path.name.replace("_results.csv", "_links.csv"))
        old_links = _kept_lines(self.links_path, {r.index for r in keep or ()})
        with atomic_output(self.path) as tmp, open(tmp, "w", newline="") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(CSV_COLUMNS + (TRP_COLUMNS + TRP_DETECTOR_COLUMNS if self.trps else ())
                       + extra_columns(self.extra))
            for r in keep or ():
                w.writerow(self._fields(r))
        with atomic_output(self.links_path) as tmp, open(tmp, "w", newline="") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(LINK_COLUMNS)
            w.writerows(old_links)
        with naming(self.path):
            self._fh = open(self.path, "a", newline="")
        self._w = csv.writer(self._fh, lineterminator="\n")
        with naming(self.links_path):
            self._lh = open(self.links_path, "a", newline="")
        self._lw = csv.writer(self._lh, lineterminator="\n")

    def _fields(self, r: PointRow) -> list[str]:
        return (row_to_fields(r) + (_trp_fields(r) if self.trps else [])
                + _extra_fields(r, self.extra))

    def write(self, row: PointRow) -> None:
        """Append ``row`` and its per-TRP links (flushed). A failed write (a full disk) leaves
        the files' complete lines as they were and raises :class:`OSError` naming the file."""
        # the links first: a stop between the two leaves a point's links without its row,
        # which a resume drops (it keeps the links of the rows it keeps)
        with naming(self.links_path):
            for link in row.links or ():
                self._lw.writerow([str(row.index)] + [_cell(v) for v in link])
            self._lh.flush()
        with naming(self.path):
            self._w.writerow(self._fields(row))
            self._fh.flush()

    def close(self) -> None:
        """Close the files; what a failed write left unflushed is dropped (a torn line would be
        dropped by :func:`read_rows` anyway)."""
        for fh in (self._lh, self._fh):
            try:
                fh.close()
            except OSError:
                if not fh.closed:
                    raise

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _shares(masks: dict, of: np.ndarray) -> dict:
    """``{key: share}`` of each mask over the points ``of`` selects, each followed by its
    Clopper-Pearson interval ``key_ci95`` (:func:`~.intervals.binomial_ci`; None without
    points)."""
    n = int(of.sum())
    out: dict = {}
    for k, mask in masks.items():
        hits = int((mask & of).sum())
        out[k] = float(hits / n) if n else None
        out[ci_suffix(k)] = binomial_ci(hits, n)
    return out


def _outcomes(outcome: list[str], sel: np.ndarray) -> dict:
    o = np.asarray(outcome, dtype=object)
    return _shares({k: o == k for k in OUTCOMES}, sel)


def scenario_metrics(rows: list[PointRow], scenario: str) -> dict:
    """Outcomes, correct-decision rates and position-error percentiles of one scenario."""
    if not rows:
        return {"num_points": 0, "num_evaluated": 0}
    attack = np.array([r.attack for r in rows])
    sel = np.ones(len(rows), bool) if scenario == "none" else attack
    fix = np.array([r.outcome != "service_failure" for r in rows])
    out = {"num_points": len(rows), "num_evaluated": int(sel.sum()),
           "outcomes": _outcomes([r.outcome for r in rows], sel)}
    if all(r.outcome_enc is not None for r in rows):
        out["outcomes_encrypted"] = _outcomes([r.outcome_enc for r in rows], sel)
    names = detectors_of(rows)
    valid = {d: np.array([r.verdicts[d] for r in rows]) for d in names}
    out["correct_decision_rate"] = (_shares(valid, sel & fix) if scenario == "none" else
                                    _shares({d: ~v for d, v in valid.items()}, sel))
    err = np.array([r.error_m for r in rows])[sel & fix]
    out["position_error_m"] = ({k: float(np.percentile(err, q)) for k, q in
                                (("p50", 50), ("p95", 95), ("p999", 99.9))} if err.size else
                               {"p50": None, "p95": None, "p999": None})
    if scenario != "none":  # the benign phases of an attack run (false alarms around the attack)
        ben = ~attack & fix
        out["benign_phase_false_alarm_rate"] = _shares({d: ~v for d, v in valid.items()}, ben)
    return out


def detectors_of(rows: list[PointRow]) -> tuple[str, ...]:
    """The detectors every row has a verdict of: :data:`DETECTORS`, then the
    :data:`TRP_DETECTORS` when every row has them (runs with more than three TRPs), then the
    plug-in detectors every row has."""
    known = DETECTORS + TRP_DETECTORS
    extra = tuple(d for d in (rows[0].verdicts if rows else ()) if d not in known)
    return DETECTORS + tuple(d for d in TRP_DETECTORS + extra
                             if rows and all(d in r.verdicts for r in rows))
