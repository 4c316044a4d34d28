"""A Monte Carlo shows no mean attack rate for a detector flagged uninformative in any
realisation (issue #40): the aggregate lists it, the printed table and the CI bar chart leave
its attack bars out."""

from __future__ import annotations

import pytest

from veriloc_rt.report.summary import format_montecarlo
from veriloc_rt.detectors.outcomes import DETECTORS
from veriloc_rt.report import plots
from veriloc_rt.sim.montecarlo import aggregate


def _metrics(flagged: list[str]) -> dict:
    rates = {d: 1.0 for d in DETECTORS}   # fractions, as metrics.json holds them
    outcomes = {"success": 0.5, "large_error": 0.5, "service_failure": 0.0}
    return {"scenarios": {
        "none": {"num_points": 8, "num_evaluated": 8, "outcomes": outcomes,
                 "correct_decision_rate": {d: 0.9 for d in DETECTORS}},
        "fbs": {"num_points": 8, "num_evaluated": 4, "outcomes": outcomes,
                "correct_decision_rate": rates, "uninformative_detectors": flagged}}}


def test_flag_of_any_realisation_hides_the_mean_attack_rate(tmp_path):
    agg = aggregate([_metrics(["DigSig"]), _metrics([])])
    assert agg["scenarios"]["fbs"]["uninformative_detectors"] == ["DigSig"]
    assert "uninformative_detectors" not in agg["scenarios"]["none"]
    line = next(ln for ln in format_montecarlo(agg).splitlines() if ln.startswith("fbs"))
    # the scenario name in 11 characters and a space, then a 15-character cell per detector
    cells = [line[12 + 16 * k: 27 + 16 * k].strip() for k in range(len(DETECTORS))]
    assert cells[DETECTORS.index("DigSig")] == "uninf."
    assert cells[DETECTORS.index("HMAC")] == "100.0 [100-100]"   # no spread between the two
    # the bar chart: heights as drawn on the caller's axes, in percent (100 x the fractions)
    from matplotlib.figure import Figure

    ax = Figure().subplots()
    assert plots.plot_rates_ci(agg, ax=ax) is ax.figure
    seen = {"bars": {c.get_label(): [p.get_height() for p in c.patches]
                     for c in ax.containers if hasattr(c, "patches")},
            "texts": [t.get_text() for t in ax.texts]}
    assert seen["bars"]["DigSig"] == pytest.approx([90.0, 0.0], abs=1e-12)   # fbs: no bar
    assert seen["bars"]["HMAC"] == pytest.approx([90.0, 100.0], abs=1e-12)
    assert seen["texts"].count("uninf.") == 1
