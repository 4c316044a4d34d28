"""A tiny UMa run's detection analysis, checked against its own CSVs.

Independent references: the verdict columns (the detectors' rules) against each statistic
column compared with the configured threshold; the ROC's operating point against the
correct-decision rates of metrics.json (the same points: benign fixes of 'none', attack-window
points of an attack) and against the vertices in roc.csv, both exactly; the uninformative flag
for a handshake threshold (1 mm) that no benign fix meets.
"""

from __future__ import annotations

import csv
import json

import pytest

from veriloc_rt.cli import main
from veriloc_rt.config import config_from_dict
from veriloc_rt.detectors.outcomes import DETECTORS
from veriloc_rt.detectors.statistics import STATISTICS, accepts, configured_thresholds
from veriloc_rt.analysis.detection import FUSED

from .strict_json import assert_folder_strict

#: the same fraction computed two ways (metrics.json and the ROC): one rounding of k / n
PCT_TOL = 1e-12


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def check_statistics_and_roc(out, cfg) -> None:
    """Every verdict equals its statistic against the configured threshold; every operating
    point in metrics.json is a vertex of roc.csv and reproduces the correct-decision rates."""
    thr = configured_thresholds(cfg.detectors)
    for s in cfg.run.scenarios:
        for r in _csv(out / f"{s}_results.csv"):
            for d in DETECTORS:
                st = STATISTICS[d]
                ok = bool(accepts(float(r[st.column]), thr[d], st.accept))
                assert (r[d] == "1") == ok, (s, d, r)
    metrics = json.loads((out / "metrics.json").read_text())
    if "none" not in cfg.run.scenarios or len(cfg.run.scenarios) < 2:
        return
    roc = metrics["roc"]
    vertices: dict = {}
    for r in _csv(out / "roc.csv"):
        vertices.setdefault((r["detector"], r["attack"]), set()).add(
            (float(r["threshold"]), float(r["benign_accept"]), float(r["attack_reject"])))
    for attack, per in roc["attacks"].items():
        for name, e in per.items():
            # the configured threshold's point lies on the curve, exactly (threshold of the
            # vertex may be the largest observed value below it)
            assert (e["benign_accept"], e["attack_reject"]) in {
                (b, a) for _, b, a in vertices[(name, attack)]}
            if name in DETECTORS:
                cdr = metrics["scenarios"]
                assert e["benign_accept"] == pytest.approx(
                    cdr["none"]["correct_decision_rate"][name], abs=PCT_TOL)
                assert e["attack_reject"] == pytest.approx(
                    cdr[attack]["correct_decision_rate"][name], abs=PCT_TOL)
    assert (out / "roc.png").stat().st_size > 0


def test_tiny_uma_run_statistics_roc_fusion_and_flag(tmp_path, capsys):
    data = {"seed": 2, "propagation": {"model": "uma", "uma_mode": "pathloss_only"},
            "trajectory": {"num_points": 32}, "run": {"evaluate_encrypted": False},
            "detectors": {"handshake": {"threshold_m": 0.001}, "fusion": {"split_block": 4}}}
    (tmp_path / "c.json").write_text(json.dumps(data))
    assert main(["run", str(tmp_path / "c.json"), "--out", str(tmp_path / "r")]) == 0
    cfg = config_from_dict(data)
    out = tmp_path / "r"
    check_statistics_and_roc(out, cfg)
    assert len(assert_folder_strict(out)) >= 3  # metrics, run, propagation summary
    m = json.loads((out / "metrics.json").read_text())
    roc = m["roc"]
    # the 1 mm handshake accepts no benign fix: flagged, not a detection success
    assert roc["detectors"]["Handshake"]["benign_accept"] == 0.0
    assert "Handshake" in roc["uninformative"]
    assert all("Handshake" in m["scenarios"][s]["uninformative_detectors"]
               for s in ("fbs", "meaconing", "jamming"))
    printed = capsys.readouterr().out
    assert "uninf." in printed and "uninformative" in printed
    # fused decisions beside the single ones, for every attack
    for s in ("fbs", "meaconing", "jamming"):
        assert set(roc["attacks"][s]) == set(DETECTORS) | set(FUSED)
        t = roc["fusion"]["test"][s]
        assert t["best_single"] in DETECTORS
        assert 0.0 <= t["NPFusion"]["false_alarm"] <= 1.0
    f = roc["fusion"]
    assert f["fit_indices"] + f["calibration_indices"] + f["test_indices"] == 32
    assert f["np_calibration_false_alarm"] <= cfg.detectors.fusion.false_alarm
    # the vote's threshold is k - 1 rejections
    assert roc["detectors"]["KofN"]["threshold"] == cfg.detectors.fusion.k - 1
    with open(out / "roc.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["detector", "attack", "threshold", "benign_accept", "attack_reject"]
    assert all(len(r) == 5 for r in rows)
