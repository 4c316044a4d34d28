"""A run folder as tables (issue #40): ``load_run`` against the run's own CSV and JSON files
read independently (``csv``, ``json``), and the Parquet and MATLAB exports read back with
pandas and ``scipy.io``. The run is a tiny UMa run whose handshake threshold (1 mm) no benign
fix meets, so that some detectors are flagged uninformative."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import scipy.io

import veriloc_rt
from veriloc_rt.cli import main
from veriloc_rt.report.tables import TABLES, load_run

CONFIG = {"seed": 2, "propagation": {"model": "uma", "uma_mode": "pathloss_only"},
          "trajectory": {"num_points": 16}, "run": {"evaluate_encrypted": False},
          "detectors": {"handshake": {"threshold_m": 0.001}, "fusion": {"split_block": 4}}}


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("tables")
    (d / "c.json").write_text(json.dumps(CONFIG))
    assert main(["run", str(d / "c.json"), "--out", str(d / "r")]) == 0
    return d / "r"


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_load_run_matches_the_files(run_dir):
    t = veriloc_rt.load_run(run_dir)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    scenarios = list(metrics["scenarios"])
    # points: one row per CSV row, the CSV's columns by name after realisation and scenario
    for s in scenarios:
        rows = _csv(run_dir / f"{s}_results.csv")
        mine = t.points[t.points["scenario"] == s]
        assert len(mine) == len(rows) == 16
        header = list(rows[0])
        assert list(t.points.columns) == ["realisation", "scenario", *header]
        assert (mine["realisation"] == 0).all()
        np.testing.assert_array_equal(mine["HMAC"].to_numpy(), [int(r["HMAC"]) for r in rows])
        err = [float(r["error_m"]) if r["error_m"] else np.nan for r in rows]
        np.testing.assert_array_equal(mine["error_m"].to_numpy(), err)
    assert len(t.points) == 16 * len(scenarios)
    assert len(t.roc) == len(_csv(run_dir / "roc.csv"))
    assert t.links.empty   # this run writes no per-TRP links file
    # every scenario share, with its unit, equals metrics.json's
    sm = t.scenario_metrics
    for s in scenarios:
        for d, v in metrics["scenarios"][s]["correct_decision_rate"].items():
            row = sm[(sm.scenario == s) & (sm.metric == "correct_decision_rate") & (sm.item == d)]
            assert row["value"].item() == v and row["unit"].item() == "%"
    # the flattened metrics: every leaf once, numbers as floats
    assert t.metrics.loc[t.metrics.key == "scenarios.none.num_points", "value"].item() == 16
    uninf = set(metrics["roc"]["uninformative"])
    assert uninf  # the 1 mm handshake
    op = t.operating_points
    assert set(op.loc[op.uninformative, "detector"]) == uninf
    e = metrics["roc"]["attacks"]["fbs"]["ABSA"]
    row = op[(op.attack == "fbs") & (op.detector == "ABSA")]
    assert row["attack_reject"].item() == e["attack_reject"] and row["auc"].item() == e["auc"]


def test_parquet_and_mat_round_trip(run_dir, tmp_path):
    t = load_run(run_dir)
    assert main(["export", str(run_dir), "--format", "parquet", "--out",
                 str(tmp_path / "pq")]) == 0
    assert main(["export", str(run_dir), "--format", "mat", "--out", str(tmp_path / "r.mat")]) == 0
    for name, df in t.tables().items():
        back = pd.read_parquet(tmp_path / "pq" / f"{name}.parquet")
        pd.testing.assert_frame_equal(back, df, check_dtype=False, check_index_type=False)
    mat = scipy.io.loadmat(tmp_path / "r.mat", simplify_cells=True)
    assert set(TABLES) <= set(mat)
    for name, df in t.tables().items():
        assert list(mat[name]) == [str(c) for c in df.columns], name
        for c in df.columns:
            got = np.atleast_1d(mat[name][c])
            assert len(got) == len(df), (name, c)
            col = df[c]
            if pd.api.types.is_numeric_dtype(col) or pd.api.types.is_bool_dtype(col):
                np.testing.assert_array_equal(got.astype(float), col.to_numpy(dtype=float))
            else:
                # MATLAB's '' (0x0 char) reads back as an empty array
                text = ["" if isinstance(v, np.ndarray) and v.size == 0 else str(v) for v in got]
                assert text == ["" if pd.isna(v) else str(v) for v in col], (name, c)


def test_export_bad_input_is_one_line_exit_2(tmp_path, run_dir):
    for args, field in ((["export", str(tmp_path / "none"), "--format", "mat", "--out",
                          str(tmp_path / "x.mat")], str(tmp_path / "none")),
                        (["export", str(run_dir), "--format", "mat", "--out",
                          str(tmp_path / "x.txt")], "--out")):
        r = subprocess.run([sys.executable, "-m", "veriloc_rt.cli", *args], capture_output=True,
                           text=True, cwd=tmp_path)
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: {field}: "), r.stderr
