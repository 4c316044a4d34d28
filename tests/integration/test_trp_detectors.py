"""The many-TRP detectors (Integrity, AuthShare) on a tiny UMa run with 9 TRPs and a false BS
biasing one TRP, checked against the run's own CSVs.

Independent references: the Integrity verdict of every benign fix against the integrity test's
own record in the CSV (``bs_excluded`` non-empty: the first test failed and a TRP was
excluded), so its benign acceptance in metrics.json is 1 - (share of benign fixes with a
detected fault) counted from the CSV; the AUCs in metrics.json against the Mann-Whitney
probability computed here from the statistic columns (Hanley & McNeil 1982); each verdict
against its statistic and threshold; the roc.csv curves present. A three-TRP run keeps the
paper's columns and detectors.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from veriloc_rt.cli import main
from veriloc_rt.detectors.outcomes import DETECTORS, TRP_DETECTORS
from veriloc_rt.detectors.statistics import TRP_STATISTICS
from veriloc_rt.report.results import CSV_COLUMNS

#: metrics are fractions of at most a few dozen points: exact up to float rounding
TOL = 1e-12


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def mann_whitney(benign: np.ndarray, attack: np.ndarray, attack_large: bool) -> float:
    """P(attack more suspicious than benign) + P(tie) / 2 over every pair."""
    b, a = benign[:, None], attack[None, :]
    if not attack_large:
        b, a = -b, -a
    with np.errstate(invalid="ignore"):     # inf - inf pairs are ties
        more = (a > b).mean()
        tie = (a == b).mean()
    return float(more + tie / 2)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("trp-det")
    data = {"seed": 3, "propagation": {"model": "uma", "uma_mode": "fast_fading"},
            "topology": {"num_trps": 9}, "channel": {"power_control": False},
            "trajectory": {"num_points": 24},
            "run": {"scenarios": ["none", "fbs"], "evaluate_encrypted": False},
            "threats": {"fbs": {"mode": "bias", "bias_s": 2e-6, "spoofed_slots": [1],
                                "link_gain": "spoofed_bs"}},
            "detectors": {"fusion": {"split_block": 2}},
            # the CRLB error model: fast fading's late first arrivals then trip the test at
            # benign points, so both verdicts occur (the 'auto' overbound rarely trips it)
            "receiver": {"range_error_model": "crlb"}}
    (tmp / "c.json").write_text(json.dumps(data))
    assert main(["run", str(tmp / "c.json"), "--out", str(tmp / "r")]) == 0
    return tmp / "r", data


def test_integrity_detector_counts_detected_faults(run):
    out, _ = run
    rows = _csv(out / "none_results.csv")
    assert tuple(rows[0])[-4:] == ("Integrity", "AuthShare", "integrity_stat", "authshare_stat")
    fixes = [r for r in rows if r["outcome"] != "service_failure"]
    assert fixes
    faulted = sum(r["bs_excluded"] != "" for r in fixes)
    accepted = sum(r["Integrity"] == "1" for r in fixes)
    assert accepted == len(fixes) - faulted
    assert 0 < faulted      # fast fading's late first arrivals: the count is not trivial
    m = json.loads((out / "metrics.json").read_text())
    integ = m["roc"]["detectors"]["Integrity"]
    assert integ["benign_accept"] == pytest.approx(1 - faulted / len(fixes), abs=TOL)
    assert integ["threshold"] == pytest.approx(-np.log10(0.01), abs=TOL)


def test_trp_detectors_in_roc_with_their_auc(run):
    out, _ = run
    m = json.loads((out / "metrics.json").read_text())
    ben = [r for r in _csv(out / "none_results.csv") if r["outcome"] != "service_failure"]
    att = [r for r in _csv(out / "fbs_results.csv") if r["attack"] == "1"]
    names = {r["detector"] for r in _csv(out / "roc.csv") if r["attack"] == "fbs"}
    assert set(TRP_DETECTORS) <= names
    for d in TRP_DETECTORS:
        st = TRP_STATISTICS[d]
        b = np.array([float(r[st.column]) for r in ben])
        a = np.array([float(r[st.column]) for r in att])
        want = mann_whitney(b, a, attack_large=st.accept == "<=")
        assert m["roc"]["attacks"]["fbs"][d]["auc"] == pytest.approx(want, abs=TOL)
        # each verdict is its statistic against the configured threshold
        thr = m["roc"]["detectors"][d]["threshold"]
        for r in ben + att:
            s = float(r[st.column])
            assert (r[d] == "1") == bool(s <= thr if st.accept == "<=" else s >= thr)
    # the biased TRP is a fault the test sees: the attack points' statistic is larger
    assert m["roc"]["attacks"]["fbs"]["Integrity"]["attack_reject"] > 0.5
    # the vote counts the rejections of all seven detectors
    k = m["roc"]["fusion"]["k"]
    votes = [sum(r[d] == "0" for d in DETECTORS + TRP_DETECTORS) for r in ben]
    assert m["roc"]["detectors"]["KofN"]["benign_accept"] == pytest.approx(
        np.mean([v <= k - 1 for v in votes]), abs=TOL)


def test_three_trps_keep_the_papers_detectors(tmp_path):
    data = {"seed": 3, "propagation": {"model": "uma", "uma_mode": "pathloss_only"},
            "trajectory": {"num_points": 8}, "run": {"scenarios": ["none", "fbs"],
                                                    "evaluate_encrypted": False}}
    (tmp_path / "c.json").write_text(json.dumps(data))
    assert main(["run", str(tmp_path / "c.json"), "--out", str(tmp_path / "r")]) == 0
    with open(tmp_path / "r" / "none_results.csv", newline="") as fh:
        assert tuple(next(csv.reader(fh))) == CSV_COLUMNS
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    rates = m["scenarios"]["none"]["correct_decision_rate"]
    # each detector's rate and its 95 % interval, nothing of the TRP detectors
    assert set(rates) == set(DETECTORS) | {d + "_ci95" for d in DETECTORS}
    if "roc" in m and m["roc"]:
        assert not set(TRP_DETECTORS) & set(m["roc"]["detectors"])
