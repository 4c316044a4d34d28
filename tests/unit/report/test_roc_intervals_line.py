"""The printed detection-at-false-alarm line shows every detector's rate, the uninformative ones
marked: that rate is at a threshold recalibrated on the benign points, so it does not depend on
the configured threshold that made the detector uninformative."""

from veriloc_rt.report.summary import format_roc_intervals


def _roc():
    entry = lambda pd, auc: {"pd_at_false_alarm": pd, "pd_at_false_alarm_ci95": [pd - 0.1, pd + 0.05],
                             "auc": auc, "auc_ci95": [auc - 0.05, auc + 0.02]}
    return {"false_alarm": 0.05, "uninformative": ["ABSA"],
            "attacks": {"fbs": {"HMAC": entry(0.9, 0.97), "ABSA": entry(0.4, 0.89)}}}


def test_uninformative_detector_has_its_recalibrated_rate_marked():
    text = format_roc_intervals(_roc())
    line = [ln for ln in text.splitlines() if ln.strip().startswith("fbs")][0]
    cells = dict(c.strip().split(" ", 1) for c in line.strip()[len("fbs"):].split(";"))
    # the values given, in percent with the interval's bounds (rounded as printed)
    assert cells["HMAC"].startswith("90.0 [80-95] % AUC 0.97 [0.92-0.99]")
    assert cells["ABSA*"].startswith("40.0 [30-45] % AUC 0.89 [0.84-0.91]")
    assert "uninf." not in line
    assert "marked *" in text.splitlines()[0]
